//! Voicing: the cheap, per-block part of the sound (material constants, size, damping, hit,
//! mallet, gain), applied to a solved shape without re-solving.
//!
//! Where it sits: the audio side of [`crate::engine`] holds one [`Voicing`]; every mode a voice
//! plays is tuned from its reference eigenvalue by [`tune`]: the scaling law
//! `omega^2 = omega_ref^2 E / (rho h^2)` (Jin et al. 2020, eq. 12, [`crate::basis`]) and the
//! damping model's `c(omega^2)` (Sterling and Lin 2016, eq. 10-16). Everything here is `Copy` and
//! allocation-free, so a knob turned in the DAW reaches the ringing modes within one block.

use crate::material::{DampedMode, Damping, Material};
use std::f64::consts::TAU;

/// Peak bound of a normalised velocity-1 strike (-6 dBFS): the sum of its modes' amplitudes.
pub const NORMALISED_PEAK: f64 = 0.5;

/// Most Caughey terms a [`DampingParams`] holds (the measured materials use at most 3).
pub const MAX_CAUGHEY_TERMS: usize = 6;

/// A damping model without heap data (the engine's copy of [`Damping`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DampingParams {
    /// `c = alpha1 + alpha2 omega^2` (Sterling and Lin 2016, eq. 12).
    Rayleigh {
        /// 1/s.
        alpha1: f64,
        /// s.
        alpha2: f64,
    },
    /// `c = sum_j eta_j omega^(2j)`, the first `terms` coefficients (Sterling and Lin 2016, eq.
    /// 13).
    Caughey {
        /// Coefficients `eta_0..`.
        eta: [f64; MAX_CAUGHEY_TERMS],
        /// How many are used.
        terms: usize,
    },
    /// `c = mu1 omega^(2 mu2)` (Sterling and Lin 2016, eq. 16).
    PowerLaw {
        /// Coefficient.
        mu1: f64,
        /// Exponent on `omega^2`.
        mu2: f64,
    },
}

impl DampingParams {
    /// The engine's copy of a material's damping; `None` for a custom function or a Caughey
    /// series longer than [`MAX_CAUGHEY_TERMS`].
    pub fn from_damping(d: &Damping) -> Option<Self> {
        match d {
            Damping::Rayleigh { alpha1, alpha2 } => Some(Self::Rayleigh {
                alpha1: *alpha1,
                alpha2: *alpha2,
            }),
            Damping::PowerLaw { mu1, mu2 } => Some(Self::PowerLaw {
                mu1: *mu1,
                mu2: *mu2,
            }),
            Damping::Caughey { eta } if eta.len() <= MAX_CAUGHEY_TERMS => {
                let mut e = [0.0; MAX_CAUGHEY_TERMS];
                e[..eta.len()].copy_from_slice(eta);
                Some(Self::Caughey {
                    eta: e,
                    terms: eta.len(),
                })
            }
            _ => None,
        }
    }

    /// The damped mode of eigenvalue `omega_n^2` (same rules as [`Damping::damp`]).
    pub fn damp(&self, omega_n_sq: f64) -> DampedMode {
        let d = match *self {
            Self::Rayleigh { alpha1, alpha2 } => Damping::Rayleigh { alpha1, alpha2 },
            Self::PowerLaw { mu1, mu2 } => Damping::PowerLaw { mu1, mu2 },
            Self::Caughey { eta, terms } => {
                let w2 = omega_n_sq.max(0.0);
                let c = eta[..terms.min(MAX_CAUGHEY_TERMS)]
                    .iter()
                    .rev()
                    .fold(0.0, |acc, &e| acc * w2 + e);
                // Rayleigh with alpha1 = c reproduces `damp`'s clamping and overdamping rules.
                Damping::Rayleigh {
                    alpha1: c,
                    alpha2: 0.0,
                }
            }
        };
        d.damp(omega_n_sq)
    }

    fn is_finite(&self) -> bool {
        match *self {
            Self::Rayleigh { alpha1, alpha2 } => alpha1.is_finite() && alpha2.is_finite(),
            Self::PowerLaw { mu1, mu2 } => mu1.is_finite() && mu2.is_finite(),
            Self::Caughey { eta, terms } => {
                terms <= MAX_CAUGHEY_TERMS && eta.iter().all(|e| e.is_finite())
            }
        }
    }
}

/// Where and how the object is struck, in coordinates that survive a size change.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HitPoint {
    /// Point as fractions `0..=1` of the grid's extent along x, y, z (snapped to the nearest
    /// exposed face).
    pub position: [f64; 3],
    /// Force direction; `None` pushes into the struck face.
    pub direction: Option<[f64; 3]>,
}

impl HitPoint {
    /// The hit in reference units (voxel edge 1) on a grid of `dims` voxels.
    pub fn reference_hit(&self, dims: [usize; 3]) -> crate::basis::Hit {
        crate::basis::Hit {
            point_m: [0, 1, 2].map(|a| self.position[a] * dims[a] as f64),
            direction: self.direction,
        }
    }
}

impl Default for HitPoint {
    /// The CLI's default hit: top face, off-centre (see [`crate::basis::ModeBasis::default_hit`]).
    fn default() -> Self {
        Self {
            position: [0.37, 0.41, 1.0],
            direction: None,
        }
    }
}

/// Everything about the sound that needs no re-solve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Voicing {
    /// Young's modulus `E`, Pa.
    pub youngs_modulus_pa: f64,
    /// Density `rho`, kg/m^3.
    pub density_kg_m3: f64,
    /// Object size: the grid's longest side, m (the voxel edge follows from it).
    pub size_m: f64,
    /// Damping model and coefficients.
    pub damping: DampingParams,
    /// Default hit for strikes that name none.
    pub hit: HitPoint,
    /// Mallet contact time, s (0 = an impulse); see [`crate::synth::Excitation::mallet`].
    pub hardness_s: f64,
    /// Output gain (linear).
    pub output_gain: f64,
    /// Level normalisation: scale the output so that a velocity-1 strike at the voicing's hit
    /// peaks at most at [`NORMALISED_PEAK`] whatever the object, material and size (an
    /// instrument's behaviour). Off: physical units (modal displacement, m), as the CLI writes.
    pub normalise: bool,
    /// Extra decay applied to a muted note (note-off with mute on), 1/s.
    pub mute_decay_per_s: f64,
    /// Extra decay of a note under full pressure ([`super::Expression::Pressure`] 1: a hand
    /// pressed on the object), 1/s; partial pressure adds its share.
    pub pressure_decay_per_s: f64,
}

/// What is wrong with a voicing (the engine keeps the previous one).
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum VoicingError {
    /// `E`, `rho` or the size is not a positive finite number.
    #[error("E ({e} Pa), rho ({rho} kg/m^3) and size ({size} m) must be positive and finite")]
    Constants {
        /// E.
        e: f64,
        /// rho.
        rho: f64,
        /// Size.
        size: f64,
    },
    /// A damping coefficient is NaN or infinite.
    #[error("damping coefficients must be finite")]
    Damping,
    /// The hit position or direction is not finite, or the position lies outside `0..=1`.
    #[error("hit position must lie in 0..=1 and the force direction must be finite")]
    Hit,
    /// Hardness, gain or mute decay out of range.
    #[error("hardness must be in 0..=0.1 s, output gain and mute decay finite and >= 0")]
    Range,
}

impl Voicing {
    /// A material's voicing at a size, with the default hit, a 1 ms mallet and unit gain.
    /// `None` if the material's damping has no engine copy (a custom function).
    pub fn from_material(material: &Material, size_m: f64) -> Option<Self> {
        Some(Self {
            youngs_modulus_pa: material.youngs_modulus_pa,
            density_kg_m3: material.density_kg_m3,
            size_m,
            damping: DampingParams::from_damping(&material.damping)?,
            hit: HitPoint::default(),
            hardness_s: 1e-3,
            output_gain: 1.0,
            normalise: false,
            mute_decay_per_s: 40.0,
            pressure_decay_per_s: 40.0,
        })
    }

    /// Checks every field; a voicing that passes never produces NaN.
    pub fn validate(&self) -> Result<(), VoicingError> {
        let pos = |x: f64| x.is_finite() && x > 0.0;
        if !(pos(self.youngs_modulus_pa) && pos(self.density_kg_m3) && pos(self.size_m)) {
            return Err(VoicingError::Constants {
                e: self.youngs_modulus_pa,
                rho: self.density_kg_m3,
                size: self.size_m,
            });
        }
        if !self.damping.is_finite() {
            return Err(VoicingError::Damping);
        }
        let h = &self.hit;
        if !h.position.iter().all(|p| (0.0..=1.0).contains(p))
            || h.direction
                .is_some_and(|d| d.iter().any(|c| !c.is_finite()))
        {
            return Err(VoicingError::Hit);
        }
        let ok = (0.0..=crate::synth::excitation::MAX_HARDNESS_S).contains(&self.hardness_s)
            && self.output_gain.is_finite()
            && self.output_gain >= 0.0
            && self.mute_decay_per_s.is_finite()
            && self.mute_decay_per_s >= 0.0
            && self.pressure_decay_per_s.is_finite()
            && self.pressure_decay_per_s >= 0.0;
        if !ok {
            return Err(VoicingError::Range);
        }
        Ok(())
    }

    /// Voxel edge, m, for a grid whose longest side has `extent` voxels, played `pitch` times
    /// higher than the object's own size (a smaller object: `h / pitch`).
    pub fn voxel_size_m(&self, extent: usize, pitch: f64) -> f64 {
        self.size_m / extent.max(1) as f64 / pitch
    }

    /// Gain of a mode struck with unit impulse (Jin et al. 2020, eq. 7): its reference-unit modal
    /// force made physical (`1 / sqrt(rho h^3)`) over its damped angular frequency.
    pub fn modal_gain(&self, reference_force: f64, voxel_size_m: f64, freq_hz: f64) -> f64 {
        let h = voxel_size_m;
        reference_force / ((self.density_kg_m3 * h * h * h).sqrt() * TAU * freq_hz)
    }

    /// Frequency scale `E / (rho h^2)` from reference eigenvalues to `omega^2` (Jin et al. 2020,
    /// eq. 12).
    pub fn eigen_scale(&self, voxel_size_m: f64) -> f64 {
        self.youngs_modulus_pa / (self.density_kg_m3 * voxel_size_m * voxel_size_m)
    }
}

/// A mode ready for a bank, or `None` where it cannot ring at `sample_rate_hz` (overdamped, at
/// 0 Hz, or at or above Nyquist). The law's decay is multiplied by `decay_ratio` (1 for solved
/// shapes; a recorded mode's own ratio to the law, [`super::recorded`]), and the damped
/// frequency follows from that decay; `extra_decay_per_s` is then added (a muted note).
pub fn tune(
    voicing: &Voicing,
    reference_eigenvalue: f64,
    voxel_size_m: f64,
    decay_ratio: f64,
    extra_decay_per_s: f64,
    sample_rate_hz: f64,
) -> Option<(f64, f64)> {
    let w2 = reference_eigenvalue * voicing.eigen_scale(voxel_size_m);
    match voicing.damping.damp(w2) {
        DampedMode::Oscillating {
            freq_hz,
            decay_per_s,
        } => {
            let (freq_hz, decay_per_s) = if decay_ratio == 1.0 {
                (freq_hz, decay_per_s)
            } else {
                // omega_d^2 = omega_n^2 - d^2 with the scaled decay.
                let d = decay_ratio * decay_per_s;
                let wd2 = w2 - d * d;
                // NaN fails too.
                if wd2.is_nan() || wd2 <= 0.0 {
                    return None;
                }
                (wd2.sqrt() / TAU, d)
            };
            let d = decay_per_s + extra_decay_per_s;
            let playable = freq_hz > 0.0 && freq_hz < 0.5 * sample_rate_hz && d < TAU * freq_hz;
            playable.then_some((freq_hz, d))
        }
        DampedMode::Overdamped { .. } => None,
    }
}
