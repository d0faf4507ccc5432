//! One voice: an oscillator bank that many strikes of the same key ring on (linear
//! superposition), with the reference eigenvalue of every mode it plays.
//!
//! Where it sits: owned by [`super::audio::AudioEngine`] in a fixed pool. A voice keeps, per bank
//! mode, which solved object (`generation`) and which of its modes it is, and that mode's
//! reference eigenvalue, so it can be re-voiced (damping, E, size) while ringing, and keeps
//! ringing after the object it was struck on has been replaced. Lifecycle: [`Voice::new`]
//! allocates; every other method never allocates (scratch is sized to the capacity).

use super::voicing::{tune, Voicing};
use crate::material::DampedMode;
use crate::synth::{Excitation, GlideError, OscillatorBank, SimdBackend, Tuning};

/// Glides one key serves before an expression re-tunes on the exact path and keys again
/// (512 blocks, 0.68 s at 48 kHz): bounds how long the f32 state runs without its exact
/// anchors (its drift is ~1e-7 of the peak a block, a random walk).
pub(crate) const REKEY_GLIDES: u32 = 512;

/// A key that could not hold this many glides (a mode next to Nyquist or fs/4 bounds its
/// range tightly): the next [`BACKOFF_EXPRESSIONS`] expressions re-tune on the exact path
/// without keying, so that a key is not taken, at the cost of two exact re-tunes, every
/// block.
const SHORT_KEY_GLIDES: u32 = 4;
const BACKOFF_EXPRESSIONS: u32 = 64;

/// A bank mode's identity and reference eigenvalue.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct SlotMode {
    /// The solved object it came from.
    pub generation: u64,
    /// Its index in that object's modes.
    pub index: usize,
    /// Its eigenvalue scaled to an object one voxel long (`lambda_ref extent^2`), so that the
    /// voicing's size alone sets its frequency, whatever grid it was solved on.
    pub unit_eigenvalue: f64,
    /// Its decay over the damping law's (1 but for a recording's modes,
    /// [`super::recorded`]).
    pub decay_ratio: f64,
    /// The gain of its last strike (per unit velocity), kept for re-tuning.
    pub gain: f64,
    /// Amplitude the strike that added it gave it (for the budget's "loudest first").
    pub level: f64,
}

/// One key's ringing modes.
pub(crate) struct Voice {
    pub bank: OscillatorBank,
    /// The key it plays; `None` when free.
    pub key: Option<u8>,
    /// Frequency ratio against the object's own size (the "pitch" key mapping).
    pub pitch: f64,
    /// Per-note tuning ([`super::Expression::TuningSemitones`]) as a frequency ratio on
    /// top of `pitch` (1 = none).
    pub bend: f64,
    /// Per-note pressure, 0 to 1: adds its share of the voicing's pressure decay.
    pub pressure: f64,
    /// `bend` or `pressure` changed since the last [`Self::revoice`]: the engine re-tunes
    /// the voice once before it next renders, however many expressions arrived.
    pub retune_pending: bool,
    /// An expression re-tuned the voice since the engine's last silence sweep (a voice left
    /// gliding without one is settled there, back on its exact anchors).
    pub expressed: bool,
    /// Glides since the bank's glide key, and the sounding pitch the key was taken at.
    glides: u32,
    key_pitch: f64,
    /// The bank refused a key for these modes (a steep damping law, a mode too near fs/4):
    /// expressions re-tune on the exact path until the next strike.
    key_refused: bool,
    /// Expressions left to re-tune on the exact path after a short-lived key.
    key_backoff: u32,
    /// Per-note gain the voice is heading to, and the gain it is at (ramped per span).
    pub volume: f64,
    pub volume_now: f64,
    /// Note-off with mute: the voicing's mute decay is added.
    pub muted: bool,
    /// Samples left of a steal fade-out (0: not fading).
    pub fade_left: usize,
    /// Largest mode amplitude right after its last strike (for the silence test).
    pub peak: f64,
    pub modes: Vec<SlotMode>,
    next_modes: Vec<SlotMode>,
    tunings: Vec<Tuning>,
    // Scratch for [`Self::revoice`]'s in-place path: each mode's new frequency and decay.
    freq_hz: Vec<f64>,
    decay_per_s: Vec<f64>,
    // Scratch for [`Self::key_glide`]: each mode's undamped eigenvalue (rad^2/s^2) and its
    // decay's slope (its law decay goes in `decay_per_s`).
    wn2_rad2_s2: Vec<f64>,
    slope: Vec<f64>,
    pub amps: Vec<f64>,
    /// Scratch for [`Self::strike`] (which struck modes are already ringing) and
    /// [`Self::drop_below`] (which modes stay).
    matched: Vec<bool>,
}

impl Voice {
    /// A free voice for up to `capacity` modes. Allocates.
    pub fn new(capacity: usize, sample_rate_hz: f64, backend: SimdBackend) -> Self {
        Self {
            bank: OscillatorBank::with_capacity(capacity, sample_rate_hz, backend),
            key: None,
            pitch: 1.0,
            bend: 1.0,
            pressure: 0.0,
            retune_pending: false,
            expressed: false,
            glides: 0,
            key_pitch: 1.0,
            key_refused: false,
            key_backoff: 0,
            volume: 1.0,
            volume_now: 1.0,
            muted: false,
            fade_left: 0,
            peak: 0.0,
            modes: Vec::with_capacity(capacity),
            next_modes: Vec::with_capacity(capacity),
            tunings: Vec::with_capacity(capacity),
            freq_hz: vec![0.0; capacity],
            decay_per_s: vec![0.0; capacity],
            wn2_rad2_s2: vec![0.0; capacity],
            slope: vec![0.0; capacity],
            amps: vec![0.0; capacity],
            matched: vec![false; capacity],
        }
    }

    pub fn capacity(&self) -> usize {
        self.bank.capacity()
    }

    /// Frees the voice and silences its bank.
    pub fn release(&mut self) {
        self.key = None;
        self.bend = 1.0;
        self.pressure = 0.0;
        self.retune_pending = false;
        self.expressed = false;
        self.key_refused = false;
        self.key_backoff = 0;
        self.volume = 1.0;
        self.volume_now = 1.0;
        self.muted = false;
        self.fade_left = 0;
        self.peak = 0.0;
        self.modes.clear();
        self.tunings.clear();
        // Cannot fail: no modes.
        let _ = self.bank.retune(&[]);
    }

    /// Re-tunes the voice for a per-note expression (its tuning, pressure or mute changed,
    /// the voicing did not): a glide from the bank's key where one is in range
    /// ([`OscillatorBank::glide`]), a few f32 operations per mode; else an exact
    /// [`Self::revoice`] that keys the next glides. A key serves [`REKEY_GLIDES`] glides, so
    /// a long gesture keeps returning to the exact path and its damping law.
    pub fn express(&mut self, voicing: &Voicing) {
        self.retune_pending = false;
        self.expressed = true;
        if self.key_backoff > 0 {
            self.key_backoff -= 1;
            self.revoice(voicing);
            return;
        }
        if !self.key_refused && self.glides < REKEY_GLIDES {
            let ratio = self.sounding_pitch() / self.key_pitch;
            match self.bank.glide(ratio, self.extra_decay(voicing)) {
                Ok(()) => {
                    self.glides += 1;
                    return;
                }
                Err(GlideError::OutOfRange { .. }) if self.glides < SHORT_KEY_GLIDES => {
                    self.key_backoff = BACKOFF_EXPRESSIONS;
                    self.revoice(voicing);
                    return;
                }
                Err(_) => {}
            }
        }
        self.revoice(voicing);
        if !self.key_refused {
            self.key_refused = self.key_glide(voicing).is_err();
        }
    }

    /// Keys the bank's glides at the voice's current, exact tuning: each mode's undamped
    /// eigenvalue at the sounding size, its law decay and that decay's slope in the log of
    /// the frequency ratio (a central difference, `+-1e-3` in `ln r`: error ~1e-7).
    fn key_glide(&mut self, voicing: &Voicing) -> Result<(), GlideError> {
        const STEP_LN: f64 = 1e-3;
        self.glides = 0;
        self.key_pitch = self.sounding_pitch();
        let scale = voicing.eigen_scale(voicing.voxel_size_m(1, self.key_pitch));
        let law = |w2: f64| match voicing.damping.damp(w2) {
            DampedMode::Oscillating { decay_per_s, .. } => decay_per_s,
            DampedMode::Overdamped { decay_per_s } => decay_per_s,
        };
        let (up, down) = ((2.0 * STEP_LN).exp(), (-2.0 * STEP_LN).exp());
        let n = self.modes.len();
        for (j, m) in self.modes.iter().enumerate() {
            let w2 = m.unit_eigenvalue * scale;
            self.wn2_rad2_s2[j] = w2;
            self.decay_per_s[j] = m.decay_ratio * law(w2);
            let (hi, lo) = (law(w2 * up), law(w2 * down));
            self.slope[j] = if hi > 0.0 && lo > 0.0 {
                (hi / lo).ln() / (2.0 * STEP_LN)
            } else {
                0.0
            };
        }
        self.bank.set_glide_reference(
            &self.wn2_rad2_s2[..n],
            &self.decay_per_s[..n],
            &self.slope[..n],
        )
    }

    /// Re-tunes every ringing mode for `voicing` (kept phase and amplitude); modes that can no
    /// longer ring (above Nyquist, overdamped) are dropped. Exact: ends any glide.
    pub fn revoice(&mut self, voicing: &Voicing) {
        self.retune_pending = false;
        let h = voicing.voxel_size_m(1, self.sounding_pitch());
        let extra = self.extra_decay(voicing);
        let fs = self.bank.sample_rate_hz();
        // Every mode still rings on the same side of fs/4 (an expression's small step): new
        // constants in place, the cheap path.
        let n = self.modes.len();
        let mut all_ring = true;
        for (j, m) in self.modes.iter().enumerate() {
            let Some((f, d)) = tune(voicing, m.unit_eigenvalue, h, m.decay_ratio, extra, fs) else {
                all_ring = false;
                break;
            };
            (self.freq_hz[j], self.decay_per_s[j]) = (f, d);
        }
        if all_ring
            && self
                .bank
                .retune_in_place(&self.freq_hz[..n], &self.decay_per_s[..n])
                .is_ok()
        {
            return;
        }
        self.next_modes.clear();
        self.tunings.clear();
        for (j, m) in self.modes.iter().enumerate() {
            if let Some((freq_hz, decay_per_s)) =
                tune(voicing, m.unit_eigenvalue, h, m.decay_ratio, extra, fs)
            {
                self.next_modes.push(*m);
                self.tunings.push(Tuning {
                    freq_hz,
                    decay_per_s,
                    gain: m.gain,
                    from: Some(j),
                });
            }
        }
        self.apply();
    }

    /// Keeps only the modes whose current amplitude is at least `threshold` (in `amps`, filled
    /// by [`Self::measure`]). Returns how many were dropped.
    pub fn drop_below(&mut self, threshold: f64) -> usize {
        let before = self.modes.len();
        if self.amps[..before].iter().all(|&a| a >= threshold) {
            return 0;
        }
        for (keep, &a) in self.matched[..before].iter_mut().zip(&self.amps[..before]) {
            *keep = a >= threshold;
        }
        // Cannot fail: one flag per mode.
        let _ = self.bank.retain(&self.matched[..before]);
        let mut kept = 0;
        for j in 0..before {
            if self.matched[j] {
                self.modes[kept] = self.modes[j];
                kept += 1;
            }
        }
        self.modes.truncate(kept);
        before - kept
    }

    /// Current amplitude of every mode into `amps`.
    pub fn measure(&mut self) {
        let n = self.modes.len();
        self.bank.amplitudes(&mut self.amps[..n]);
    }

    /// The pitch the voice sounds at: its strike's, times its per-note tuning.
    pub fn sounding_pitch(&self) -> f64 {
        self.pitch * self.bend
    }

    /// Decay added to every mode of this voice: the mute decay once muted, plus the pressed
    /// share of the pressure decay.
    fn extra_decay(&self, voicing: &Voicing) -> f64 {
        let mute = if self.muted {
            voicing.mute_decay_per_s
        } else {
            0.0
        };
        mute + self.pressure * voicing.pressure_decay_per_s
    }

    /// Strikes: `struck` lists one object's modes worth playing, in ascending mode index, at
    /// most [`Self::capacity`] of them; ringing modes carry on, new ones join, up to capacity.
    /// `gains` receives the per-mode gains in the new bank order (scratch owned by the caller).
    /// Matching ringing and struck modes is a binary search: O(n log n) per strike.
    pub fn strike(
        &mut self,
        struck: &[SlotMode],
        voicing: &Voicing,
        excitation: Excitation,
        velocity: f64,
        gains: &mut [f64],
    ) {
        if self.bank.is_gliding() {
            // The ringing modes carry on from their exact tuning, not the glide's.
            self.revoice(voicing);
        }
        self.key_refused = false;
        self.key_backoff = 0;
        let h = voicing.voxel_size_m(1, self.sounding_pitch());
        let fs = self.bank.sample_rate_hz();
        self.next_modes.clear();
        self.tunings.clear();
        let struck = &struck[..struck.len().min(self.matched.len())];
        let matched = &mut self.matched[..struck.len()];
        matched.fill(false);
        let generation = struck.first().map(|s| s.generation);
        // Ringing modes first (they keep their slots' phase), then the struck ones not ringing.
        for (j, m) in self.modes.iter().enumerate() {
            let k = (generation == Some(m.generation))
                .then(|| struck.binary_search_by_key(&m.index, |s| s.index).ok())
                .flatten();
            if let Some(k) = k {
                matched[k] = true;
            }
            let again = k.map(|k| &struck[k]);
            let (f, d) = self.bank.tuning(j);
            let gain = again.map_or(0.0, |s| s.gain);
            self.next_modes.push(SlotMode {
                gain: if again.is_some() { gain } else { m.gain },
                ..*m
            });
            self.tunings.push(Tuning {
                freq_hz: f,
                decay_per_s: d,
                gain,
                from: Some(j),
            });
        }
        let extra = self.extra_decay(voicing);
        for (s, &ringing) in struck.iter().zip(self.matched.iter()) {
            if self.next_modes.len() == self.capacity() {
                break;
            }
            if ringing {
                continue;
            }
            if let Some((freq_hz, decay_per_s)) =
                tune(voicing, s.unit_eigenvalue, h, s.decay_ratio, extra, fs)
            {
                self.next_modes.push(*s);
                self.tunings.push(Tuning {
                    freq_hz,
                    decay_per_s,
                    gain: s.gain,
                    from: None,
                });
            }
        }
        self.apply();
        let n = self.modes.len();
        for (g, t) in gains[..n].iter_mut().zip(&self.tunings) {
            *g = t.gain;
        }
        // Validated by the engine (velocity, hardness, finite gains): cannot fail.
        let _ = self
            .bank
            .strike_with_gains(excitation, velocity, &gains[..n]);
        self.measure();
        self.peak = self.amps[..n].iter().cloned().fold(0.0, f64::max);
    }

    /// Installs `next_modes`/`tunings` in the bank.
    fn apply(&mut self) {
        match self.bank.retune(&self.tunings) {
            Ok(()) => std::mem::swap(&mut self.modes, &mut self.next_modes),
            // Only reachable through a bug (every tuning comes from `tune`): fall silent
            // rather than play something inconsistent.
            Err(_) => self.release(),
        }
    }
}
