//! Damped-oscillator bank: every mode as a free damped sine, struck any number of times.
//!
//! Where it sits: takes [`PlayableModes`] (after culling) and strikes, produces audio. Each strike
//! adds `g_i v F_i(lambda) e^(lambda_i t)` to mode `i`'s complex amplitude and the bank plays the
//! imaginary part, `q_i(t) = Im(...)`, which for an impulse is `g_i v e^(-d_i t) sin(2 pi f_i t)`
//! (Deep-Modal, Jin et al. 2020, eq. 3 and 13). Strikes add up: the system is linear.
//!
//! Drift: a plain f32 recurrence wanders off the analytic sine (rounding of its coefficients
//! detunes it; over 10 s at 440 Hz the error reaches 1e-2 of the peak). The bank keeps each mode's
//! exact complex amplitude in f64 at anchor points every [`ANCHOR_SAMPLES`] samples, advances it
//! there by the exact factor `e^(lambda 64 / fs)`, and restarts the fast f32 recurrence
//! ([`kernel`]) from it. Between anchors the f32 error stays near 1e-7 of the peak; at an anchor
//! it is reset. Anchors sit on a fixed grid of the bank's own sample clock, so rendering in any
//! chunk sizes gives bit-identical output.
//!
//! Lifecycle (fundsp style): [`OscillatorBank::new`] allocates; [`OscillatorBank::strike`],
//! [`OscillatorBank::render`] and [`OscillatorBank::reset`] never allocate, lock or block.

mod anchor;
mod constants;
mod glide;
mod kernel;
mod retune;

pub use glide::{GlideError, GLIDE_MAX_LN_RATIO};
pub use retune::RetuneError;

use super::excitation::{Excitation, ExcitationError};
use super::simd::{padded_len, SimdBackend, PAD};
use crate::modes::PlayableModes;
use num_complex::Complex64;
use std::f64::consts::TAU;

/// Samples between exact re-anchoring of the f32 recurrences (even, so that anchors fall on even
/// samples of the bank's clock, where mirrored modes need no sign).
pub const ANCHOR_SAMPLES: usize = 64;

/// Largest accepted strike velocity (a force multiplier; 1 = the modes' own gains).
pub const MAX_VELOCITY: f64 = 100.0;

/// What is wrong with a strike.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum StrikeError {
    /// The excitation parameters are invalid.
    #[error(transparent)]
    Excitation(#[from] ExcitationError),
    /// A per-strike gain vector of the wrong length.
    #[error("strike has {got} gains but the bank plays {expected} modes")]
    GainCount {
        /// Gains given.
        got: usize,
        /// Modes in the bank.
        expected: usize,
    },
    /// A per-strike gain that is NaN or infinite.
    #[error("strike gain for mode {0} is not finite")]
    NonFiniteGain(usize),
}

/// A bank of damped oscillators playing one [`PlayableModes`].
pub struct OscillatorBank {
    backend: SimdBackend,
    sample_rate_hz: f64,
    len: usize,
    // Slots in use (low modes, then mirrored ones, each padded to PAD); the arrays hold more.
    used: usize,
    // Kernel slot of each mode; slots from `split` on are mirrored (frequency above fs/4).
    slot: Vec<usize>,
    split: usize,
    // f32 kernel state and coefficients by slot, padded to multiples of PAD with zeros.
    y: Vec<f32>,
    dy: Vec<f32>,
    kappa: Vec<f32>,
    c2: Vec<f32>,
    // Exact state by slot: complex amplitude at the current anchor, and the constants to move it.
    anchors: anchor::Anchors,
    // lambda_i = -d_i + i 2 pi f_i in rad/s.
    lambda: Vec<Complex64>,
    gain: Vec<f64>,
    since_anchor: usize,
    acc: Vec<f32>,
    // Most modes `retune` accepts, and its scratch: each old mode's amplitude at the retune.
    capacity: usize,
    carried: Vec<Complex64>,
    // The shared-ratio re-tune (per-note expression) and whether it owns the state now.
    glide: glide::Glide,
}

/// One mode given to [`OscillatorBank::retune`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tuning {
    /// Damped frequency, Hz, in `(0, fs/2)`.
    pub freq_hz: f64,
    /// Amplitude decay rate, 1/s, in `[0, 2 pi freq_hz)` (an oscillating mode).
    pub decay_per_s: f64,
    /// The mode's own gain (used by [`OscillatorBank::strike`]).
    pub gain: f64,
    /// The current mode whose ringing this one continues, or `None` to start silent.
    pub from: Option<usize>,
}

impl OscillatorBank {
    /// Prepares a bank for `modes` on the fastest backend this CPU has. Allocates.
    pub fn new(modes: &PlayableModes) -> Self {
        Self::with_backend(modes, SimdBackend::detect())
    }

    /// Prepares a bank on a given backend (falls back to `Portable` if the CPU lacks it).
    pub fn with_backend(modes: &PlayableModes, backend: SimdBackend) -> Self {
        let mut bank = Self::with_capacity(modes.len(), modes.sample_rate_hz(), backend);
        let tunings: Vec<Tuning> = (0..modes.len())
            .map(|i| Tuning {
                freq_hz: modes.freq_hz()[i],
                decay_per_s: modes.decay_per_s()[i],
                gain: modes.gain()[i],
                from: None,
            })
            .collect();
        bank.retune(&tunings)
            .expect("playable modes are valid oscillator tunings");
        bank
    }

    /// A silent bank with room for `capacity` modes and none tuned yet; [`Self::retune`] gives
    /// it modes without allocating. Allocates.
    pub fn with_capacity(capacity: usize, sample_rate_hz: f64, backend: SimdBackend) -> Self {
        let backend = if backend.is_available() {
            backend
        } else {
            SimdBackend::Portable
        };
        // Low and mirrored modes are padded separately: one extra pad covers both remainders.
        let slots = padded_len(capacity) + PAD;
        Self {
            backend,
            sample_rate_hz,
            len: 0,
            used: 0,
            capacity,
            slot: Vec::with_capacity(capacity),
            split: 0,
            y: vec![0.0; slots],
            dy: vec![0.0; slots],
            kappa: vec![0.0; slots],
            c2: vec![0.0; slots],
            anchors: anchor::Anchors::new(slots),
            lambda: Vec::with_capacity(capacity),
            gain: Vec::with_capacity(capacity),
            since_anchor: 0,
            acc: vec![0.0; 2 * ANCHOR_SAMPLES * PAD],
            carried: vec![Complex64::new(0.0, 0.0); capacity],
            glide: glide::Glide::new(slots, capacity),
        }
    }

    /// Frequency (Hz) and decay (1/s) of mode `i` (while gliding, the glide's, in f64).
    pub fn tuning(&self, i: usize) -> (f64, f64) {
        if self.glide.active {
            return self.glide.tuning(i);
        }
        let l = self.lambda[i];
        (l.im / TAU, -l.re)
    }

    /// Most modes [`Self::retune`] accepts.
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// Each mode's current amplitude `|z|` (bank mode order) into `out[..len]`, for deciding
    /// which modes are quiet enough to drop. Never allocates.
    pub fn amplitudes(&self, out: &mut [f64]) {
        if self.glide.active {
            for (o, &k) in out.iter_mut().zip(&self.slot[..self.len]) {
                *o = self.glide.magnitude(k, self.y[k], self.dy[k]);
            }
            return;
        }
        let dt = self.since_anchor as f64 / self.sample_rate_hz;
        for (i, o) in out.iter_mut().take(self.len).enumerate() {
            let k = self.slot[i];
            let (re, im) = (self.anchors.z_re[k], self.anchors.z_im[k]);
            // Amplitudes are far from overflow: no need for libm's slow `hypot`.
            let z = (re * re + im * im).sqrt();
            *o = z * (self.lambda[i].re * dt).exp();
        }
    }

    /// The backend the kernels run on.
    pub fn backend(&self) -> SimdBackend {
        self.backend
    }

    /// Number of modes.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the bank has no modes (never true for a bank built from `PlayableModes`).
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The sample rate in Hz.
    pub fn sample_rate_hz(&self) -> f64 {
        self.sample_rate_hz
    }

    /// Silences every mode. Never allocates.
    pub fn reset(&mut self) {
        self.glide.active = false;
        self.y.fill(0.0);
        self.dy.fill(0.0);
        self.anchors.reset();
    }

    /// Strikes the object at the next sample to be rendered, with the modes' own gains.
    /// Never allocates. Costs two complex exponentials per mode for a contact pulse.
    pub fn strike(&mut self, excitation: Excitation, velocity: f64) -> Result<(), StrikeError> {
        check_velocity(velocity)?;
        self.settle();
        for i in 0..self.len {
            self.add_strike(i, self.gain[i] * velocity, excitation);
        }
        Ok(())
    }

    /// Strikes with per-mode gains (for example another hit point), in the bank's mode order.
    /// Never allocates.
    pub fn strike_with_gains(
        &mut self,
        excitation: Excitation,
        velocity: f64,
        gains: &[f64],
    ) -> Result<(), StrikeError> {
        check_velocity(velocity)?;
        if gains.len() != self.len {
            return Err(StrikeError::GainCount {
                got: gains.len(),
                expected: self.len,
            });
        }
        if let Some(i) = gains.iter().position(|g| !g.is_finite()) {
            return Err(StrikeError::NonFiniteGain(i));
        }
        self.settle();
        for (i, &g) in gains.iter().enumerate() {
            self.add_strike(i, g * velocity, excitation);
        }
        Ok(())
    }

    fn add_strike(&mut self, i: usize, amplitude: f64, excitation: Excitation) {
        let c = amplitude * excitation.modal_factor(self.lambda[i]);
        // Fast state: the strike starts at the next sample; mirrored slots hold (-1)^n y[n].
        let k = self.slot[i];
        let sign = if k >= self.split && self.since_anchor % 2 == 1 {
            -1.0
        } else {
            1.0
        };
        self.y[k] += (sign * c.im) as f32;
        self.dy[k] += (sign * self.anchors.second_state(k, c)) as f32;
        // Exact state: referred back to the current anchor.
        let back = if self.since_anchor == 0 {
            Complex64::new(1.0, 0.0)
        } else {
            (-self.lambda[i] * (self.since_anchor as f64 / self.sample_rate_hz)).exp()
        };
        let c = c * back;
        self.anchors.z_re[k] += c.re;
        self.anchors.z_im[k] += c.im;
    }

    /// Renders the next `out.len()` samples (overwriting `out`). Never allocates.
    pub fn render(&mut self, out: &mut [f32]) {
        let mut done = 0;
        while done < out.len() {
            if self.since_anchor == ANCHOR_SAMPLES {
                if self.glide.active {
                    // A glide's f32 state runs on (its anchors are stale); the clock keeps
                    // the parity the mirrored slots' sign follows.
                    self.since_anchor = 0;
                } else {
                    self.advance_anchor();
                }
            }
            let n = (out.len() - done).min(ANCHOR_SAMPLES - self.since_anchor);
            kernel::render(
                self.backend,
                kernel::KernelArrays {
                    y: &mut self.y[..self.used],
                    dy: &mut self.dy[..self.used],
                    kappa: &self.kappa[..self.used],
                    c2: &self.c2[..self.used],
                },
                kernel::Mirror {
                    split: self.split,
                    odd_start: self.since_anchor % 2 == 1,
                },
                &mut self.acc,
                &mut out[done..done + n],
            );
            self.since_anchor += n;
            done += n;
        }
    }

    /// Moves the exact state one anchor interval on and restarts the f32 recurrences from it.
    fn advance_anchor(&mut self) {
        // Anchors fall on even samples (ANCHOR_SAMPLES is even): no mirror sign here.
        let n = self.used;
        self.anchors
            .advance(self.backend, &mut self.y[..n], &mut self.dy[..n]);
        self.since_anchor = 0;
    }
}

/// Whether a mode can ring in a bank at `fs`: a frequency in `(0, fs/2)` and a decay in
/// `[0, 2 pi freq_hz)` (it oscillates). NaN fails.
fn rings(freq_hz: f64, decay_per_s: f64, fs: f64) -> bool {
    freq_hz > 0.0 && freq_hz < 0.5 * fs && decay_per_s >= 0.0 && decay_per_s < TAU * freq_hz
}

/// Checks a strike velocity (a force multiplier, finite, `0..=MAX_VELOCITY`), as `strike` does.
pub fn check_velocity(velocity: f64) -> Result<(), ExcitationError> {
    if velocity.is_finite() && (0.0..=MAX_VELOCITY).contains(&velocity) {
        Ok(())
    } else {
        Err(ExcitationError::Velocity(velocity))
    }
}

#[cfg(test)]
mod tests;
