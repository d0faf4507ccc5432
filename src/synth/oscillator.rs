//! Damped-oscillator bank: every mode as a free damped sine, struck any number of times.
//!
//! Where it sits: takes [`PlayableModes`] (after culling) and strikes, produces audio. Each strike
//! adds `g_i v F_i(lambda) e^(lambda_i t)` to mode `i`'s complex amplitude and the bank plays the
//! imaginary part, `q_i(t) = Im(...)`, which for an impulse is `g_i v e^(-d_i t) sin(2 pi f_i t)`
//! (Deep-Modal, seed 000 eq. 3 and 13). Strikes add up: the system is linear.
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
mod kernel;

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
}

impl OscillatorBank {
    /// Prepares a bank for `modes` on the fastest backend this CPU has. Allocates.
    pub fn new(modes: &PlayableModes) -> Self {
        Self::with_backend(modes, SimdBackend::detect())
    }

    /// Prepares a bank on a given backend (falls back to `Portable` if the CPU lacks it).
    pub fn with_backend(modes: &PlayableModes, backend: SimdBackend) -> Self {
        let backend = if backend.is_available() {
            backend
        } else {
            SimdBackend::Portable
        };
        let fs = modes.sample_rate_hz();
        let len = modes.len();
        // Modes above fs/4 run mirrored (see `kernel`): they take the slots after `split`.
        let mirrored: Vec<bool> = modes.freq_hz().iter().map(|&f| f > 0.25 * fs).collect();
        let n_high = mirrored.iter().filter(|&&m| m).count();
        let split = padded_len(len - n_high);
        let padded = split + padded_len(n_high);
        let (mut next_low, mut next_high) = (0, split);
        let mut slot = Vec::with_capacity(len);
        let mut kappa = vec![0f32; padded];
        let mut c2 = vec![0f32; padded];
        let mut lambda = Vec::with_capacity(len);
        let mut anchors = anchor::Anchors::new(padded);
        for (i, &is_mirrored) in mirrored.iter().enumerate() {
            let (f, d) = (modes.freq_hz()[i], modes.decay_per_s()[i]);
            let l = Complex64::new(-d, TAU * f);
            let r_minus_1 = (-d / fs).exp_m1();
            let r = 1.0 + r_minus_1;
            // The recurrence runs at w, or mirrored at pi - w; both kept in (0, pi/2].
            let (k, w) = if is_mirrored {
                next_high += 1;
                (next_high - 1, TAU * (0.5 * fs - f) / fs)
            } else {
                next_low += 1;
                (next_low - 1, TAU * f / fs)
            };
            slot.push(k);
            // kappa = (1 - r)^2 + 4 r sin^2(w/2): no cancellation, full relative precision.
            kappa[k] = (r_minus_1 * r_minus_1 + 4.0 * r * (0.5 * w).sin().powi(2)) as f32;
            c2[k] = (r * r) as f32;
            lambda.push(l);
            let step = (l * (ANCHOR_SAMPLES as f64 / fs)).exp();
            (anchors.step_re[k], anchors.step_im[k]) = (step.re, step.im);
            // Maps a complex amplitude to the kernel's second state variable: y[n] - y[n-1]
            // (1 - e^(-lambda/fs)), or mirrored z[n] - z[n-1] = +-(y[n] + y[n-1])
            // (1 + e^(-lambda/fs) = -expm1(-lambda/fs + i pi), small near Nyquist).
            let back = if is_mirrored {
                -(-l / fs + Complex64::new(0.0, std::f64::consts::PI)).exp_m1_complex()
            } else {
                -(-l / fs).exp_m1_complex()
            };
            (anchors.back_re[k], anchors.back_im[k]) = (back.re, back.im);
        }
        Self {
            backend,
            sample_rate_hz: fs,
            len,
            slot,
            split,
            y: vec![0.0; padded],
            dy: vec![0.0; padded],
            kappa,
            c2,
            anchors,
            lambda,
            gain: modes.gain().to_vec(),
            since_anchor: 0,
            acc: vec![0.0; 2 * ANCHOR_SAMPLES * PAD],
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
        self.y.fill(0.0);
        self.dy.fill(0.0);
        self.anchors.reset();
    }

    /// Strikes the object at the next sample to be rendered, with the modes' own gains.
    /// Never allocates. Costs two complex exponentials per mode for a contact pulse.
    pub fn strike(&mut self, excitation: Excitation, velocity: f64) -> Result<(), StrikeError> {
        check_velocity(velocity)?;
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
                self.advance_anchor();
            }
            let n = (out.len() - done).min(ANCHOR_SAMPLES - self.since_anchor);
            kernel::render(
                self.backend,
                kernel::KernelArrays {
                    y: &mut self.y,
                    dy: &mut self.dy,
                    kappa: &self.kappa,
                    c2: &self.c2,
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
        self.anchors
            .advance(self.backend, &mut self.y, &mut self.dy);
        self.since_anchor = 0;
    }
}

pub(crate) fn check_velocity(velocity: f64) -> Result<(), ExcitationError> {
    if velocity.is_finite() && (0.0..=MAX_VELOCITY).contains(&velocity) {
        Ok(())
    } else {
        Err(ExcitationError::Velocity(velocity))
    }
}

/// `e^x - 1` for complex `x`, accurate for small `|x|`.
trait ExpM1Complex {
    fn exp_m1_complex(self) -> Self;
}

impl ExpM1Complex for Complex64 {
    fn exp_m1_complex(self) -> Self {
        // e^(a+ib) - 1 = (e^a - 1) cos b + (cos b - 1) + i e^a sin b, with cos b - 1 = -2 sin^2(b/2).
        let (a, b) = (self.re, self.im);
        let em1 = a.exp_m1();
        let cm1 = -2.0 * (0.5 * b).sin().powi(2);
        Complex64::new(em1 * b.cos() + cm1, (em1 + 1.0) * b.sin())
    }
}

#[cfg(test)]
mod tests;
