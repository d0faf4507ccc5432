//! Biquad resonator bank: modes as two-pole filters that any force signal can drive.
//!
//! Where it sits: takes [`PlayableModes`] (or any set of biquads) and a force signal (a strike's
//! [`ForcePulse`](super::ForcePulse), scraping or rolling [`NoiseForce`](super::NoiseForce), or
//! the user's own), produces audio. It is a filter bank in the arrangement of Diaz et al. (2023,
//! eq. 3): `L` parallel branches, each a cascade of `M` biquads,
//! `H(z) = sum_l prod_m H_lm(z)`, with each section
//! `H(z) = (b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2)` (Diaz et al. 2023, eq. 2 in
//! pole/zero form: [`BiquadCoeffs::from_pole_zero`]).
//!
//! A mode is the impulse-invariant resonator [`BiquadCoeffs::modal_resonator`]: its impulse
//! response is exactly the oscillator bank's `g r^n sin(w n)`, so an impulse through this bank
//! reproduces the oscillator bank sample for sample (up to rounding), and a force pulse reproduces
//! it up to the quadrature of the force.
//!
//! Lifecycle: [`BiquadBank::new`] and [`BiquadBank::from_modes`] allocate; [`BiquadBank::process`]
//! and [`BiquadBank::reset`] never allocate, lock or block.

mod kernel;

use super::simd::{padded_len, SimdBackend};
use crate::modes::PlayableModes;
use num_complex::Complex64;
use std::f64::consts::TAU;

/// Samples processed per kernel call (the bank's scratch size).
pub const CHUNK_SAMPLES: usize = 64;

/// Filter states below this magnitude are set to exactly zero after every chunk. A decaying
/// filter's state otherwise sinks into f64 denormals after minutes of silence (e^(-d t) < 1e-308),
/// where x86 arithmetic is ~50x slower; one chunk can shrink a state by at most e^(-pi 64), so from
/// 1e-30 it never reaches the denormal range before the next flush. 1e-30 is -600 dB.
const SILENCE_FLOOR: f64 = 1e-30;

/// Smallest decay a resonator is built with, in 1/s. A mode with zero decay has its poles on the
/// unit circle: fine for a struck oscillator, but a driven filter would grow without bound when a
/// force (a long scrape) holds its frequency. 1e-3 /s is a 60 dB ring time of 6900 s.
pub const MIN_RESONATOR_DECAY_PER_S: f64 = 1e-3;

/// Coefficients of one section, `H(z) = (b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BiquadCoeffs {
    /// Numerator, z^0.
    pub b0: f64,
    /// Numerator, z^-1.
    pub b1: f64,
    /// Numerator, z^-2.
    pub b2: f64,
    /// Denominator, z^-1.
    pub a1: f64,
    /// Denominator, z^-2.
    pub a2: f64,
}

/// What is wrong with a filter bank.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum BiquadError {
    /// A coefficient is NaN or infinite.
    #[error("biquad {index} has a non-finite coefficient")]
    NonFinite {
        /// Section index (branch-major).
        index: usize,
    },
    /// The poles are on or outside the unit circle.
    #[error("biquad {index} is unstable (a1 = {a1}, a2 = {a2}): its poles must lie inside the unit circle")]
    Unstable {
        /// Section index (branch-major).
        index: usize,
        /// Denominator z^-1 coefficient.
        a1: f64,
        /// Denominator z^-2 coefficient.
        a2: f64,
    },
    /// Zero stages, zero sections, or a section count that is not a multiple of the stage count.
    #[error("a bank needs at least one branch of at least one stage; got {sections} sections for {stages} stages per branch")]
    Shape {
        /// Sections given.
        sections: usize,
        /// Stages per branch.
        stages: usize,
    },
    /// More resonators than [`BiquadBank::with_capacity`] made room for.
    #[error(
        "{sections} resonators do not fit a bank built for {capacity}; build it with room for more"
    )]
    Capacity {
        /// Sections given.
        sections: usize,
        /// The bank's room.
        capacity: usize,
    },
    /// A section given to [`BiquadBank::retune_modal`] that is not a modal resonator.
    #[error("biquad {index} is not a modal resonator (b0 and b2 must be 0)")]
    NotModal {
        /// Which section.
        index: usize,
    },
}

impl BiquadCoeffs {
    /// The resonator of one mode, designed in f64: poles `r e^(+-iw)` with `r = e^(-d/fs)`,
    /// `w = 2 pi f / fs`, and numerator `g r sin(w) z^-1`, so that its impulse response is
    /// `g r^n sin(w n) = g e^(-d n/fs) sin(2 pi f n / fs)`.
    pub fn modal_resonator(freq_hz: f64, decay_per_s: f64, gain: f64, sample_rate_hz: f64) -> Self {
        let r = (-decay_per_s / sample_rate_hz).exp();
        let w = TAU * freq_hz / sample_rate_hz;
        Self {
            b0: 0.0,
            b1: gain * r * w.sin(),
            b2: 0.0,
            a1: -2.0 * r * w.cos(),
            a2: r * r,
        }
    }

    /// Seed 002 eq. 2: `k (1 - 2 Re(q) z^-1 + |q|^2 z^-2) / (1 - 2 Re(p) z^-1 + |p|^2 z^-2)` for a
    /// pole `p` and zero `q` (with their conjugates) and gain `k`.
    pub fn from_pole_zero(pole: Complex64, zero: Complex64, gain: f64) -> Self {
        Self {
            b0: gain,
            b1: -2.0 * gain * zero.re,
            b2: gain * zero.norm_sqr(),
            a1: -2.0 * pole.re,
            a2: pole.norm_sqr(),
        }
    }

    /// Seed 002 eq. 1: maps any complex number into the unit disc, `h(p) = tanh|p| / |p| * p`,
    /// the stable pole parameterisation for learned filters.
    pub fn constrain_pole(p: Complex64) -> Complex64 {
        let m = p.norm();
        if m == 0.0 {
            p
        } else {
            p * (m.tanh() / m)
        }
    }

    fn check(&self, index: usize) -> Result<(), BiquadError> {
        if ![self.b0, self.b1, self.b2, self.a1, self.a2]
            .iter()
            .all(|c| c.is_finite())
        {
            return Err(BiquadError::NonFinite { index });
        }
        // Jury's test for a real second-order denominator.
        if !(self.a2.abs() < 1.0 && self.a1.abs() < 1.0 + self.a2) {
            return Err(BiquadError::Unstable {
                index,
                a1: self.a1,
                a2: self.a2,
            });
        }
        Ok(())
    }
}

/// A bank of `branches` parallel cascades of `stages` biquads each.
pub struct BiquadBank {
    backend: SimdBackend,
    branches: usize,
    stages: usize,
    padded: usize,
    modal: bool,
    b0: Vec<f64>,
    b1: Vec<f64>,
    b2: Vec<f64>,
    na1: Vec<f64>,
    na2: Vec<f64>,
    s1: Vec<f64>,
    s2: Vec<f64>,
    x: Vec<f64>,
    scratch: Vec<f64>,
}

impl BiquadBank {
    /// A bank from sections in branch-major order: branch `l`'s cascade is
    /// `sections[l * stages .. (l + 1) * stages]`. Allocates.
    pub fn new(stages: usize, sections: &[BiquadCoeffs]) -> Result<Self, BiquadError> {
        Self::with_backend(stages, sections, SimdBackend::detect())
    }

    /// As [`BiquadBank::new`] on a given backend (falls back to `Portable` if unavailable).
    pub fn with_backend(
        stages: usize,
        sections: &[BiquadCoeffs],
        backend: SimdBackend,
    ) -> Result<Self, BiquadError> {
        if stages == 0 || sections.is_empty() || !sections.len().is_multiple_of(stages) {
            return Err(BiquadError::Shape {
                sections: sections.len(),
                stages,
            });
        }
        for (i, c) in sections.iter().enumerate() {
            c.check(i)?;
        }
        let backend = if backend.is_available() {
            backend
        } else {
            SimdBackend::Portable
        };
        let branches = sections.len() / stages;
        let padded = padded_len(branches);
        let mut bank = Self {
            backend,
            branches,
            stages,
            padded,
            modal: sections.iter().all(|c| c.b0 == 0.0 && c.b2 == 0.0),
            b0: vec![0.0; stages * padded],
            b1: vec![0.0; stages * padded],
            b2: vec![0.0; stages * padded],
            na1: vec![0.0; stages * padded],
            na2: vec![0.0; stages * padded],
            s1: vec![0.0; stages * padded],
            s2: vec![0.0; stages * padded],
            x: vec![0.0; CHUNK_SAMPLES],
            scratch: vec![0.0; (kernel_group() + 1) * 4 * CHUNK_SAMPLES],
        };
        for (i, c) in sections.iter().enumerate() {
            let (branch, stage) = (i / stages, i % stages);
            let o = stage * padded + branch;
            bank.b0[o] = c.b0;
            bank.b1[o] = c.b1;
            bank.b2[o] = c.b2;
            bank.na1[o] = -c.a1;
            bank.na2[o] = -c.a2;
        }
        Ok(bank)
    }

    /// A silent bank of one-section branches with room for `capacity` modal resonators, to be
    /// (re)tuned in place by [`BiquadBank::retune_modal`] (the resonator effect,
    /// [`crate::engine::resonator`]). Allocates.
    pub fn with_capacity(capacity: usize, backend: SimdBackend) -> Self {
        let backend = if backend.is_available() {
            backend
        } else {
            SimdBackend::Portable
        };
        let room = padded_len(capacity.max(1));
        Self {
            backend,
            branches: 0,
            stages: 1,
            padded: padded_len(1),
            modal: true,
            b0: vec![0.0; room],
            b1: vec![0.0; room],
            b2: vec![0.0; room],
            na1: vec![0.0; room],
            na2: vec![0.0; room],
            s1: vec![0.0; room],
            s2: vec![0.0; room],
            x: vec![0.0; CHUNK_SAMPLES],
            scratch: vec![0.0; (kernel_group() + 1) * 4 * CHUNK_SAMPLES],
        }
    }

    /// Whether every filter state is zero (nothing rings: silence in gives silence out).
    pub fn is_silent(&self) -> bool {
        self.s1.iter().chain(&self.s2).all(|&s| s == 0.0)
    }

    /// Replaces the sections of a one-stage bank by `sections` (modal resonators: `b0 = b2 =
    /// 0`), at most as many as its capacity. Branches that stay keep their filter state, so a
    /// retune of a driven bank glides instead of restarting; the others are cleared. Never
    /// allocates. A section that is not finite or not stable, too many sections, or a bank with
    /// several stages is refused and leaves the bank unchanged.
    pub fn retune_modal(&mut self, sections: &[BiquadCoeffs]) -> Result<(), BiquadError> {
        let room = self.b1.len();
        if self.stages != 1 || sections.len() > room {
            return Err(BiquadError::Capacity {
                sections: sections.len(),
                capacity: if self.stages == 1 { room } else { 0 },
            });
        }
        for (i, c) in sections.iter().enumerate() {
            c.check(i)?;
            if c.b0 != 0.0 || c.b2 != 0.0 {
                return Err(BiquadError::NotModal { index: i });
            }
        }
        for (i, c) in sections.iter().enumerate() {
            self.b1[i] = c.b1;
            self.na1[i] = -c.a1;
            self.na2[i] = -c.a2;
        }
        let n = sections.len();
        for v in [
            &mut self.b1,
            &mut self.na1,
            &mut self.na2,
            &mut self.s1,
            &mut self.s2,
        ] {
            v[n..].fill(0.0);
        }
        self.branches = n;
        self.padded = padded_len(n.max(1));
        self.modal = true;
        Ok(())
    }

    /// One modal resonator per mode (one stage per branch) on the fastest backend.
    pub fn from_modes(modes: &PlayableModes) -> Self {
        Self::from_modes_with_backend(modes, SimdBackend::detect())
    }

    /// One modal resonator per mode on a given backend.
    pub fn from_modes_with_backend(modes: &PlayableModes, backend: SimdBackend) -> Self {
        let fs = modes.sample_rate_hz();
        let sections: Vec<BiquadCoeffs> = (0..modes.len())
            .map(|i| {
                BiquadCoeffs::modal_resonator(
                    modes.freq_hz()[i],
                    modes.decay_per_s()[i].max(MIN_RESONATOR_DECAY_PER_S),
                    modes.gain()[i],
                    fs,
                )
            })
            .collect();
        // Culled modes have 0 < f < fs/2 and finite values, and decay >= MIN_RESONATOR_DECAY_PER_S
        // puts both poles strictly inside the unit circle, so every resonator is stable.
        Self::with_backend(1, &sections, backend).expect("playable modes give stable resonators")
    }

    /// The backend the kernels run on.
    pub fn backend(&self) -> SimdBackend {
        self.backend
    }

    /// Number of parallel branches.
    pub fn branches(&self) -> usize {
        self.branches
    }

    /// Biquads per branch.
    pub fn stages(&self) -> usize {
        self.stages
    }

    /// Clears every filter's state. Never allocates.
    pub fn reset(&mut self) {
        self.s1.fill(0.0);
        self.s2.fill(0.0);
    }

    /// Filters `input` (force samples) and writes the bank's output to `out`
    /// (`out.len()` samples; a shorter `input` is padded with zeros). Never allocates.
    pub fn process(&mut self, input: &[f32], out: &mut [f32]) {
        for (c, chunk) in out.chunks_mut(CHUNK_SAMPLES).enumerate() {
            let n = chunk.len();
            let start = (c * CHUNK_SAMPLES).min(input.len());
            let src = &input[start..(start + n).min(input.len())];
            let x = &mut self.x[..n];
            x.fill(0.0);
            for (xi, &s) in x.iter_mut().zip(src) {
                *xi = if s.is_finite() { s as f64 } else { 0.0 };
            }
            kernel::process(
                self.backend,
                kernel::BankArrays {
                    stages: self.stages,
                    padded: self.padded,
                    modal: self.modal,
                    b0: &self.b0,
                    b1: &self.b1,
                    b2: &self.b2,
                    na1: &self.na1,
                    na2: &self.na2,
                    s1: &mut self.s1,
                    s2: &mut self.s2,
                },
                x,
                &mut self.scratch,
                chunk,
            );
            for s in self.s1.iter_mut().chain(self.s2.iter_mut()) {
                if s.abs() < SILENCE_FLOOR {
                    *s = 0.0;
                }
            }
        }
    }
}

fn kernel_group() -> usize {
    kernel::GROUP_VECTORS
}

#[cfg(test)]
mod tests;
