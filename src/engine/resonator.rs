//! The resonator effect: incoming audio as a force on the sculpted object.
//!
//! Where it sits: on the audio thread, beside the voices of [`super::AudioEngine`]. The plugin
//! feeds its side-chain input through [`super::AudioEngine::resonate`], which drives this bank
//! of the object's modes (as Ableton's Corpus drives its resonator): each mode is a two-pole
//! resonator ([`BiquadCoeffs::modal_resonator`], the same modes the voices play, at the
//! voicing's material, size, damping and hit point, and at the pitch of the last key struck),
//! scaled so that its gain at its own frequency is its modal gain at the hit point relative to
//! the loudest mode's. A sine at the strongest mode's frequency therefore comes out at its own
//! level, whatever the damping (a lightly damped glass would otherwise amplify it by
//! `1 / (1 - r)`, thousands of times).
//!
//! The input is sanitised first (NaN and infinities become silence, samples are clamped to
//! +-[`MAX_INPUT`]), then pre-filtered (a one-pole low cut and a one-pole high cut) and scaled
//! by the input gain. The filters are stable by construction (poles inside the unit circle,
//! [`BiquadBank::retune_modal`] refuses any other), so a bounded input gives a bounded output;
//! a final guard clamps the wet signal to +-[`MAX_WET`] all the same. Zero latency: the output
//! sample depends on the input sample of the same instant.
//!
//! Lifecycle: [`InputResonator::new`] allocates every buffer (room for
//! [`RESONATOR_MODES`] modes); [`InputResonator::retune`] and [`InputResonator::process`]
//! never allocate, lock or block.

use super::object::SolvedObject;
use super::voicing::{tune, Voicing};
use crate::synth::biquad::{BiquadBank, BiquadCoeffs, MIN_RESONATOR_DECAY_PER_S};
use crate::synth::SimdBackend;
use num_complex::Complex64;
use std::f64::consts::TAU;

/// Most modes the resonator plays (the loudest at the hit point).
pub const RESONATOR_MODES: usize = 512;

/// Input samples are clamped to this (+12 dBFS) before anything else.
pub const MAX_INPUT: f32 = 4.0;

/// The wet signal is clamped to this (+24 dBFS): a guard that bounded input and stable
/// filters never reach at unit input gain.
pub const MAX_WET: f32 = 16.0;

/// Modes weaker than this fraction of the loudest at the hit point are left out (-80 dB, as a
/// strike culls them).
const CULL_RATIO: f64 = 1e-4;

/// How the input drives the object: set from the plugin's parameters every block.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ResonatorSettings {
    /// Linear gain on the input before the resonators (0 switches the effect off).
    pub input_gain: f32,
    /// Share of the resonated input in what is added to the output, `0..=1`; the rest is the
    /// (pre-filtered) input itself. A contact's scraping ([`ContactForce`]) is always resonated
    /// in full.
    pub mix: f32,
    /// Corner of the one-pole low cut on the input, Hz.
    pub low_cut_hz: f64,
    /// Corner of the one-pole high cut on the input, Hz.
    pub high_cut_hz: f64,
}

impl Default for ResonatorSettings {
    fn default() -> Self {
        Self {
            input_gain: 0.0,
            mix: 1.0,
            low_cut_hz: 20.0,
            high_cut_hz: 20_000.0,
        }
    }
}

/// A held note scraping the object: band-limited noise pushed through the bank (the CLI's
/// `--scrape`, played from a key). Louder with velocity and pressure; pressure also scrapes
/// faster (brighter noise).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactForce {
    /// Noise level at the bank's input (before the output gain).
    pub level: f32,
    /// Corner of the noise's one-pole low-pass, Hz.
    pub cutoff_hz: f64,
}

/// Noise level of a velocity-1 scrape: the bank passes a narrow band around each mode, so
/// broadband noise needs this gain to sound about as loud as a velocity-1 strike of a
/// normalised object (at rest: -4.5 dB on the engine tests' steel bar, -0.4 dB on the
/// default bowl, against the RMS of the strike's first half second).
pub const CONTACT_LEVEL: f32 = 24.0;

impl ContactForce {
    /// The contact of a key held at `velocity` (`0..=1`) under `pressure` (`0..=1`): level
    /// `CONTACT_LEVEL * velocity * (0.5 + pressure)`, noise corner 1 kHz at rest up to 8 kHz
    /// at full pressure.
    pub fn scrape(velocity: f64, pressure: f64) -> Self {
        let (v, p) = (velocity.clamp(0.0, 1.0), pressure.clamp(0.0, 1.0));
        Self {
            level: CONTACT_LEVEL * (v * (0.5 + p)) as f32,
            cutoff_hz: 1000.0 * 8f64.powf(p),
        }
    }
}

/// Samples over which a contact's level glides to a new value (5 ms at 48 kHz): a key pressed
/// or released, or its pressure moving, never clicks.
const CONTACT_GLIDE_SAMPLES: f32 = 240.0;

/// What the bank was last tuned for.
#[derive(Clone, Copy, Debug, PartialEq)]
struct TunedFor {
    generation: u64,
    voicing: Voicing,
    pitch: f64,
}

/// The object's modes driven by an audio input.
pub struct InputResonator {
    sample_rate_hz: f64,
    bank: BiquadBank,
    /// Sections of the last retune (capacity [`RESONATOR_MODES`]), and each one's frequency,
    /// decay and gain at its frequency (relative to the loudest mode).
    sections: Vec<BiquadCoeffs>,
    tunings: Vec<(f64, f64, f64)>,
    /// Candidate modes of a retune: (frequency, decay, gain), capacity as `sections`.
    candidates: Vec<(f64, f64, f64)>,
    tuned_for: Option<TunedFor>,
    /// The bank's input of one chunk (the pre-filtered, scaled input plus any contact noise),
    /// the dry share (the input alone), and the bank's output.
    input: Vec<f32>,
    dry: Vec<f32>,
    wet: Vec<f32>,
    /// One-pole filter states: the low cut's last input and output, the high cut's output.
    low_cut_x: f32,
    low_cut_y: f32,
    high_cut_y: f32,
    /// The contact noise: its generator, low-pass state and current (gliding) level.
    noise: crate::rng::SplitMix64,
    noise_y: f32,
    contact_level: f32,
}

impl InputResonator {
    /// A silent resonator for `sample_rate_hz`. Allocates.
    pub fn new(sample_rate_hz: f64, backend: SimdBackend) -> Self {
        Self {
            sample_rate_hz,
            bank: BiquadBank::with_capacity(RESONATOR_MODES, backend),
            sections: Vec::with_capacity(RESONATOR_MODES),
            tunings: Vec::with_capacity(RESONATOR_MODES),
            candidates: Vec::with_capacity(RESONATOR_MODES),
            tuned_for: None,
            input: vec![0.0; super::BLOCK_SAMPLES],
            dry: vec![0.0; super::BLOCK_SAMPLES],
            wet: vec![0.0; super::BLOCK_SAMPLES],
            low_cut_x: 0.0,
            low_cut_y: 0.0,
            high_cut_y: 0.0,
            noise: crate::rng::SplitMix64::new(0x5C2A_9E00),
            noise_y: 0.0,
            contact_level: 0.0,
        }
    }

    /// Modes the bank plays now.
    pub fn modes(&self) -> usize {
        self.sections.len()
    }

    /// Each mode the bank plays: frequency (Hz), decay (1/s) and its gain at its own
    /// frequency, relative to the loudest mode's at the hit point.
    pub fn tunings(&self) -> &[(f64, f64, f64)] {
        &self.tunings
    }

    /// Tunes the bank to `obj` under `voicing` at `pitch` (the size ratio of the last key
    /// struck), unless it already is. `obj`'s forces must be those of the voicing's hit
    /// ([`SolvedObject::update_forces`]). Never allocates.
    pub fn retune(&mut self, obj: &SolvedObject, voicing: &Voicing, pitch: f64) {
        let want = TunedFor {
            generation: obj.generation,
            voicing: *voicing,
            pitch,
        };
        if self.tuned_for == Some(want) {
            return;
        }
        self.tuned_for = Some(want);
        let fs = self.sample_rate_hz;
        let h = voicing.voxel_size_m(obj.extent, pitch);
        self.candidates.clear();
        let mut loudest: f64 = 0.0;
        for (i, &lambda) in obj.basis.eigenvalues().iter().enumerate() {
            let Some((f, d)) = tune(voicing, lambda, h, obj.basis.decay_ratio(i), 0.0, fs) else {
                continue;
            };
            let gain = voicing.modal_gain(obj.forces[i], h, f);
            if !gain.is_finite() || f >= 0.45 * fs {
                continue;
            }
            loudest = loudest.max(gain.abs());
            if self.candidates.len() < self.candidates.capacity() {
                self.candidates.push((f, d, gain));
            } else if let Some(weakest) = self
                .candidates
                .iter_mut()
                .min_by(|a, b| a.2.abs().total_cmp(&b.2.abs()))
                .filter(|w| w.2.abs() < gain.abs())
            {
                // Full: the loudest modes stay.
                *weakest = (f, d, gain);
            }
        }
        self.sections.clear();
        self.tunings.clear();
        if loudest > 0.0 {
            for &(f, d, gain) in &self.candidates {
                let relative = gain / loudest;
                if relative.abs() < CULL_RATIO {
                    continue;
                }
                let d = d.max(MIN_RESONATOR_DECAY_PER_S);
                let unit = BiquadCoeffs::modal_resonator(f, d, 1.0, fs);
                // |H(e^{iw})| of the unit-gain resonator at its own frequency.
                let z = Complex64::from_polar(1.0, -TAU * f / fs);
                let peak = (unit.b1 * z / (1.0 + unit.a1 * z + unit.a2 * z * z)).norm();
                if peak.is_finite() && peak > 0.0 {
                    self.sections
                        .push(BiquadCoeffs::modal_resonator(f, d, relative / peak, fs));
                    self.tunings.push((f, d, relative));
                }
            }
        }
        if self.bank.retune_modal(&self.sections).is_err() {
            // Unreachable (every section is a stable modal resonator); silence is the safe
            // answer.
            self.sections.clear();
            self.tunings.clear();
            let _ = self.bank.retune_modal(&[]);
        }
    }

    /// Forgets the tuning: the next [`InputResonator::retune`] rebuilds the sections.
    pub fn invalidate(&mut self) {
        self.tuned_for = None;
    }

    /// Adds the resonated `input` (and the dry share) to `out`, scaled by `output_gain`; `input`
    /// shorter than `out` is padded with silence. A `contact` adds its noise to the bank's
    /// input (not to the dry share). Never allocates.
    pub fn process(
        &mut self,
        input: &[f32],
        out: &mut [f32],
        settings: &ResonatorSettings,
        output_gain: f32,
        contact: Option<ContactForce>,
    ) {
        let fs = self.sample_rate_hz as f32;
        let nyquist = 0.49 * fs;
        // One-pole coefficients (impulse invariant): y += a (x - y).
        let low = (settings.low_cut_hz as f32).clamp(1.0, nyquist);
        let high = (settings.high_cut_hz as f32).clamp(1.0, nyquist);
        let low_pole = (-std::f32::consts::TAU * low / fs).exp();
        let high_a = 1.0 - (-std::f32::consts::TAU * high / fs).exp();
        let gain = if settings.input_gain.is_finite() {
            settings.input_gain.clamp(0.0, 64.0)
        } else {
            0.0
        };
        let mix = if settings.mix.is_finite() {
            settings.mix.clamp(0.0, 1.0)
        } else {
            1.0
        };
        let output_gain = if output_gain.is_finite() {
            output_gain
        } else {
            0.0
        };
        let (contact_target, noise_a) = match contact {
            Some(c) if c.level.is_finite() && c.cutoff_hz.is_finite() => {
                let corner = (c.cutoff_hz as f32).clamp(1.0, nyquist);
                (
                    c.level.clamp(0.0, 4.0 * CONTACT_LEVEL),
                    1.0 - (-std::f32::consts::TAU * corner / fs).exp(),
                )
            }
            _ => (0.0, 1.0),
        };
        for (c, chunk) in out.chunks_mut(super::BLOCK_SAMPLES).enumerate() {
            let n = chunk.len();
            let start = (c * super::BLOCK_SAMPLES).min(input.len());
            let src = &input[start..(start + n).min(input.len())];
            let x = &mut self.input[..n];
            let dry = &mut self.dry[..n];
            x.fill(0.0);
            for (i, xi) in x.iter_mut().enumerate() {
                let s = src.get(i).copied().unwrap_or(0.0);
                let s = if s.is_finite() {
                    s.clamp(-MAX_INPUT, MAX_INPUT)
                } else {
                    0.0
                };
                // Low cut: y = p (y + x - x_prev); high cut: y += a (x - y).
                self.low_cut_y = low_pole * (self.low_cut_y + s - self.low_cut_x);
                self.low_cut_x = s;
                self.high_cut_y += high_a * (self.low_cut_y - self.high_cut_y);
                dry[i] = gain * self.high_cut_y;
                // The bank is linear: feeding it `mix` of the input is the crossfade's wet
                // share, and leaves a contact's noise (added below) at its full level.
                *xi = mix * dry[i];
                if contact_target > 0.0 || self.contact_level > 0.0 {
                    self.contact_level +=
                        (contact_target - self.contact_level) / CONTACT_GLIDE_SAMPLES;
                    if contact_target == 0.0 && self.contact_level < 1e-6 {
                        self.contact_level = 0.0;
                    }
                    let white = self.noise.range(-1.0, 1.0) as f32;
                    self.noise_y += noise_a * (white - self.noise_y);
                    *xi += self.contact_level * self.noise_y;
                }
            }
            for v in [&mut self.low_cut_y, &mut self.high_cut_y, &mut self.noise_y] {
                if v.abs() < 1e-20 {
                    *v = 0.0;
                }
            }
            let wet = &mut self.wet[..n];
            if x.iter().all(|&v| v == 0.0) && self.bank.is_silent() {
                // No input and nothing ringing (no side-chain connected): skip the bank.
                wet.fill(0.0);
            } else {
                self.bank.process(x, wet);
            }
            for ((o, w), d) in chunk.iter_mut().zip(wet.iter()).zip(dry.iter()) {
                let w = w.clamp(-MAX_WET, MAX_WET);
                *o += output_gain * (w + (1.0 - mix) * d);
            }
        }
    }
}
