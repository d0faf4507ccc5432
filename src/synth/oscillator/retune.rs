//! Re-tuning a bank while it rings: a new set of modes ([`OscillatorBank::retune`]), new
//! frequencies and decays for the same modes ([`OscillatorBank::retune_in_place`]), a drop
//! ([`OscillatorBank::retain`]), and the shared-ratio glide of per-note expression
//! ([`OscillatorBank::glide`], its key and settling; the kernel is [`super::glide`]). Every
//! one keeps each continuing mode's phase and amplitude and never allocates.

use super::glide::{self, GlideError};
use super::{constants, rings, OscillatorBank, Tuning, ANCHOR_SAMPLES};
use crate::synth::simd::padded_len;
use num_complex::Complex64;
use std::f64::consts::TAU;

/// Why a retune was refused (the bank is left unchanged).
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum RetuneError {
    /// More modes than the bank was prepared for.
    #[error("{got} modes do not fit a bank prepared for {capacity}")]
    TooMany {
        /// Modes given.
        got: usize,
        /// The bank's capacity.
        capacity: usize,
    },
    /// A mode that cannot ring in this bank.
    #[error(
        "mode {index} ({freq_hz} Hz, decay {decay_per_s} /s) must lie in (0, fs/2) and oscillate"
    )]
    BadMode {
        /// Index in the new modes.
        index: usize,
        /// Its frequency.
        freq_hz: f64,
        /// Its decay.
        decay_per_s: f64,
    },
    /// [`OscillatorBank::retune_in_place`] was given other than one frequency and one decay
    /// per mode.
    #[error("in-place retune got {freqs} frequencies and {decays} decays for {len} modes")]
    LengthMismatch {
        /// Frequencies given.
        freqs: usize,
        /// Decays given.
        decays: usize,
        /// Modes playing now.
        len: usize,
    },
    /// A mode would cross a quarter of the sample rate, where the kernel changes from direct to
    /// mirrored slots: [`OscillatorBank::retune_in_place`] keeps the layout, so use
    /// [`OscillatorBank::retune`].
    #[error("mode {index} crosses fs/4 and needs a full retune")]
    CrossesQuarterRate {
        /// Index of the mode.
        index: usize,
    },
    /// [`OscillatorBank::retain`] was given other than one flag per mode.
    #[error("drop got {got} keep flags for {len} modes")]
    KeepCount {
        /// Flags given.
        got: usize,
        /// Modes playing now.
        len: usize,
    },
    /// `from` names a mode the bank does not have.
    #[error("mode {index} continues mode {from}, but the bank plays {len}")]
    NoSuchMode {
        /// Index in the new modes.
        index: usize,
        /// The missing source mode.
        from: usize,
        /// Modes playing now.
        len: usize,
    },
}

impl OscillatorBank {
    /// Replaces the bank's modes with `modes` at the next sample, without allocating.
    ///
    /// A mode with `from: Some(i)` carries on ringing from the current mode `i`: its exact
    /// complex amplitude now (the value it is about to play, and its phase) is kept and only its
    /// frequency and decay change, so the output stays continuous (no click) and a damping
    /// change acts on notes already ringing. Other modes start silent. The anchor grid restarts
    /// at the next sample.
    pub fn retune(&mut self, modes: &[Tuning]) -> Result<(), RetuneError> {
        if modes.len() > self.capacity {
            return Err(RetuneError::TooMany {
                got: modes.len(),
                capacity: self.capacity,
            });
        }
        let fs = self.sample_rate_hz;
        for (i, t) in modes.iter().enumerate() {
            let valid = rings(t.freq_hz, t.decay_per_s, fs) && t.gain.is_finite();
            if !valid {
                return Err(RetuneError::BadMode {
                    index: i,
                    freq_hz: t.freq_hz,
                    decay_per_s: t.decay_per_s,
                });
            }
            if let Some(from) = t.from.filter(|&f| f >= self.len) {
                return Err(RetuneError::NoSuchMode {
                    index: i,
                    from,
                    len: self.len,
                });
            }
        }
        // Every current mode's exact amplitude at the next sample (at the end of an anchor
        // interval, the anchor's own exact step, with no exponentials; after a glide, from
        // the f32 state).
        if self.glide.active {
            self.anchors_from_glide();
        }
        if self.since_anchor == ANCHOR_SAMPLES {
            self.advance_anchor();
        }
        let dt = self.since_anchor as f64 / fs;
        for i in 0..self.len {
            let k = self.slot[i];
            let z = Complex64::new(self.anchors.z_re[k], self.anchors.z_im[k]);
            self.carried[i] = if self.since_anchor == 0 {
                z
            } else {
                z * (self.lambda[i] * dt).exp()
            };
        }
        // New layout: modes above fs/4 run mirrored (see `kernel`) in the slots after `split`.
        let n_high = modes.iter().filter(|t| t.freq_hz > 0.25 * fs).count();
        let old_used = self.used;
        self.split = padded_len(modes.len() - n_high);
        self.used = self.split + padded_len(n_high);
        // Slots from `used` on are always zero (nothing writes past it), so clearing the
        // slots either layout uses is enough. Clearing the whole capacity instead (256 modes:
        // 17 kB a voice) was the audio thread's largest cost in the soak, whose automation
        // re-voices 64 voices every block (perf: memset 4.4 % of the samples, rendering 1.4).
        let clear = old_used.max(self.used);
        for v in [&mut self.y, &mut self.dy, &mut self.kappa, &mut self.c2] {
            v[..clear].fill(0.0);
        }
        self.anchors.clear_first(clear);
        let (mut next_low, mut next_high) = (0, self.split);
        self.slot.clear();
        self.lambda.clear();
        self.gain.clear();
        for t in modes {
            let slot = if t.freq_hz > 0.25 * fs {
                &mut next_high
            } else {
                &mut next_low
            };
            self.slot.push(*slot);
            *slot += 1;
            self.lambda
                .push(Complex64::new(-t.decay_per_s, TAU * t.freq_hz));
            self.gain.push(t.gain);
        }
        self.len = modes.len();
        // New modes or tunings: the key no longer describes them (a drop keeps it,
        // `retain`).
        self.glide.keyed = false;
        self.write_constants();
        for (i, t) in modes.iter().enumerate() {
            if let Some(from) = t.from {
                // The next sample is an anchor (even on the new grid): no mirror sign.
                let (k, c) = (self.slot[i], self.carried[from]);
                (self.anchors.z_re[k], self.anchors.z_im[k]) = (c.re, c.im);
                self.y[k] = c.im as f32;
                self.dy[k] = self.anchors.second_state(k, c) as f32;
            }
        }
        self.since_anchor = 0;
        Ok(())
    }

    /// Drops the modes whose `keep` is false (in mode order) at the next sample; the rest ring
    /// on untouched: each kept mode's state, constants and glide key move down to its new
    /// slot on the same kernel half, with no arithmetic, so a drop costs no re-tune and
    /// keeps a glide going. Refused, with the bank unchanged, if `keep` is not one flag per
    /// mode. Never allocates.
    pub fn retain(&mut self, keep: &[bool]) -> Result<(), RetuneError> {
        if keep.len() != self.len {
            return Err(RetuneError::KeepCount {
                got: keep.len(),
                len: self.len,
            });
        }
        let (split, old_used) = (self.split, self.used);
        let low = |i: usize| self.slot[i] < split;
        let n_low = (0..self.len).filter(|&i| keep[i] && low(i)).count();
        let n_high = keep.iter().filter(|&&k| k).count() - n_low;
        let new_split = padded_len(n_low);
        let new_used = new_split + padded_len(n_high);
        // Within a half, slots rise with the mode index, so moving in mode order only ever
        // moves a slot down onto one already moved: the low half first, then the high.
        // The next free slot of the half `old_slot` is on.
        let new_slot = |old_slot: usize, next: &mut [usize; 2]| {
            let half = usize::from(old_slot >= split);
            next[half] += 1;
            next[half] - 1
        };
        let mut next = [0, new_split];
        for half_low in [true, false] {
            for (i, _) in keep
                .iter()
                .enumerate()
                .filter(|&(i, &k)| k && low(i) == half_low)
            {
                let from = self.slot[i];
                let to = new_slot(from, &mut next);
                debug_assert!(to <= from);
                self.y[to] = self.y[from];
                self.dy[to] = self.dy[from];
                self.kappa[to] = self.kappa[from];
                self.c2[to] = self.c2[from];
                self.anchors.move_slot(from, to);
                self.glide.move_slot(from, to);
            }
        }
        for (range, mirrored) in [
            (n_low..new_split, false),
            (next[1]..old_used.max(new_used), true),
        ] {
            for v in [&mut self.y, &mut self.dy, &mut self.kappa, &mut self.c2] {
                v[range.clone()].fill(0.0);
            }
            self.anchors.clear(range.clone());
            self.glide.pad(range, mirrored);
        }
        // The same slots again, in mode order.
        let (mut next, mut kept) = ([0, new_split], 0);
        for (i, _) in keep.iter().enumerate().filter(|&(_, &k)| k) {
            // Mode `i`'s entry is read before `kept <= i` is written.
            let to = new_slot(self.slot[i], &mut next);
            self.glide.move_mode(i, kept);
            self.slot[kept] = to;
            self.lambda[kept] = self.lambda[i];
            self.gain[kept] = self.gain[i];
            kept += 1;
        }
        self.slot.truncate(kept);
        self.lambda.truncate(kept);
        self.gain.truncate(kept);
        (self.len, self.split, self.used) = (kept, new_split, new_used);
        Ok(())
    }

    /// Moves every mode to a new frequency and decay in place, at the next sample: what
    /// [`Self::retune`] does with `from: Some(i)` for each mode `i` and the same gains, without
    /// re-laying out the bank, at a quarter of its cost (the constants four modes at a time, no
    /// state cleared). Per-note expression re-tunes a voice this way every block.
    ///
    /// Refused, with the bank unchanged, when the lengths differ from [`Self::len`], a mode
    /// cannot ring ([`RetuneError::BadMode`]), or a mode crosses a quarter of the sample rate
    /// ([`RetuneError::CrossesQuarterRate`]: it changes kernel halves; use [`Self::retune`]).
    /// Never allocates.
    pub fn retune_in_place(
        &mut self,
        freq_hz: &[f64],
        decay_per_s: &[f64],
    ) -> Result<(), RetuneError> {
        if freq_hz.len() != self.len || decay_per_s.len() != self.len {
            return Err(RetuneError::LengthMismatch {
                freqs: freq_hz.len(),
                decays: decay_per_s.len(),
                len: self.len,
            });
        }
        let fs = self.sample_rate_hz;
        for (i, (&f, &d)) in freq_hz.iter().zip(decay_per_s).enumerate() {
            if !rings(f, d, fs) {
                return Err(RetuneError::BadMode {
                    index: i,
                    freq_hz: f,
                    decay_per_s: d,
                });
            }
            if (f > 0.25 * fs) != (self.slot[i] >= self.split) {
                return Err(RetuneError::CrossesQuarterRate { index: i });
            }
        }
        // Every mode's exact amplitude now: a block-sized render ends on an anchor, whose own
        // exact step brings it here; otherwise carried with an exponential; after a glide,
        // recovered from the f32 state.
        if self.glide.active {
            self.anchors_from_glide();
        }
        if self.since_anchor == ANCHOR_SAMPLES {
            self.advance_anchor();
        }
        if self.since_anchor != 0 {
            let dt = self.since_anchor as f64 / fs;
            constants::carry(
                self.backend,
                dt,
                &self.lambda[..self.len],
                &self.slot,
                &mut self.anchors,
            );
        }
        for (l, (&f, &d)) in self.lambda.iter_mut().zip(freq_hz.iter().zip(decay_per_s)) {
            *l = Complex64::new(-d, TAU * f);
        }
        self.glide.keyed = false;
        self.restart_exact();
        Ok(())
    }

    /// New constants from `lambda` and the f32 state restarted from the anchors, which hold
    /// every mode's exact amplitude at the next sample (padded slots stay 0).
    fn restart_exact(&mut self) {
        self.write_constants();
        let n = self.used;
        for k in 0..n {
            let z = Complex64::new(self.anchors.z_re[k], self.anchors.z_im[k]);
            self.y[k] = z.im as f32;
            self.dy[k] = self.anchors.second_state(k, z) as f32;
        }
        self.since_anchor = 0;
    }

    /// Keys the glide ([`Self::glide`]) at the bank's current tuning: per mode (bank order),
    /// the undamped `omega_n^2` (rad^2/s^2), the damping law's decay (1/s, without any extra
    /// decay) and that decay's slope `d ln d / d ln r` in the frequency ratio `r`. The caller
    /// keys right after an exact re-tune, with values that give each mode's current frequency
    /// (`sqrt(omega_n^2 - d^2)`); refused, and no key kept, when the values are invalid or no
    /// glide could keep every mode ringing on its side of fs/4. Never allocates.
    pub fn set_glide_reference(
        &mut self,
        wn2_rad2_s2: &[f64],
        decay_per_s: &[f64],
        slope: &[f64],
    ) -> Result<(), GlideError> {
        let result = self.glide.key(
            self.sample_rate_hz,
            &self.slot,
            self.split,
            self.used,
            wn2_rad2_s2,
            decay_per_s,
            slope,
        );
        if result.is_err() {
            self.glide.keyed = false;
        }
        result
    }

    /// Moves every mode to `ratio` times its keyed frequency (decays by the keyed law) plus
    /// `extra_decay_per_s`, at the next sample, keeping each mode's phase and amplitude: the
    /// cheap re-tune of per-note expression, a few f32 operations per mode ([`glide`]).
    /// Refused, with the bank unchanged, without a key since the last exact re-tune or
    /// outside the key's range ([`super::GLIDE_MAX_LN_RATIO`], no mode crossing fs/4). Never
    /// allocates.
    pub fn glide(&mut self, ratio: f64, extra_decay_per_s: f64) -> Result<(), GlideError> {
        self.glide.check(ratio, extra_decay_per_s)?;
        let used = self.used;
        if !self.glide.active {
            self.glide.enter(&self.anchors, self.split, used);
        }
        self.glide.retune(
            self.backend,
            self.sample_rate_hz,
            self.split,
            ratio,
            extra_decay_per_s,
            glide::KernelState {
                y: &self.y[..used],
                dy: &mut self.dy[..used],
                kappa: &mut self.kappa[..used],
                c2: &mut self.c2[..used],
            },
        );
        Ok(())
    }

    /// Whether a glide owns the state (its anchors are stale until the next exact re-tune).
    pub fn is_gliding(&self) -> bool {
        self.glide.active
    }

    /// Ends a glide: the exact path again at the glide's own tuning (in f64), no audible
    /// change. Never allocates.
    pub fn settle(&mut self) {
        if !self.glide.active {
            return;
        }
        for i in 0..self.len {
            let (f, d) = self.glide.tuning(i);
            self.lambda[i] = Complex64::new(-d, TAU * f);
        }
        self.anchors_from_glide();
        self.restart_exact();
    }

    /// The anchors from a glide's f32 state: every mode's exact amplitude at the next sample,
    /// which becomes an anchor (`since_anchor` 0).
    fn anchors_from_glide(&mut self) {
        let odd = self.since_anchor % 2 == 1;
        for &k in &self.slot[..self.len] {
            let sign = if k >= self.split && odd { -1.0 } else { 1.0 };
            let (re, im) = self
                .glide
                .amplitude(k, self.split, self.y[k], self.dy[k], sign);
            (self.anchors.z_re[k], self.anchors.z_im[k]) = (re, im);
        }
        self.glide.active = false;
        self.since_anchor = 0;
    }

    /// Writes the kernel and anchor constants of every mode from `lambda`.
    fn write_constants(&mut self) {
        constants::write(
            self.backend,
            self.sample_rate_hz,
            &self.lambda[..self.len],
            constants::Slots {
                slot: &self.slot,
                split: self.split,
                kappa: &mut self.kappa,
                c2: &mut self.c2,
                anchors: &mut self.anchors,
            },
        );
    }
}
