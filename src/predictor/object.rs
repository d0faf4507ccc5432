//! A shape's predicted modes as the product plays them: the network's answer for a shape scaled
//! to fill the input box, voiced for any material, size, hit and force like a FEM object.
//!
//! Where it sits: [`super::Predictor::predict`] makes a [`PredictedObject`]; its
//! [`PredictedObject::voice`] gives the same [`VoicedMode`]s as [`crate::modal::ModeBasis::voice`]
//! (the material's damping law, gains as impulse amplitudes), so the CLI's `modes` and `render`
//! treat both alike.
//!
//! The physics of the mapping:
//! - **Scale.** The network answers at the reference (steel, the 32-voxel box
//!   [`super::bands::REFERENCE_BOX_M`] across). A shape whose longest side is `n` voxels is
//!   resampled to 32 first, so each box voxel is `h n / 32` of the real object (`h` its voxel
//!   edge). A predicted band frequency `f_ref` is then the reference-unit eigenvalue
//!   `lambda = reference_eigenvalue(f_ref)` (voxel edge 1, E = rho = 1), and the material's
//!   `E / (rho h_box^2)` gives the physical one: Deep-Modal's scaling laws (Jin, Li and
//!   Manocha 2020, eq. 10-12), the same as [`crate::modal::ModeBasis::eigenvalues`].
//! - **Gains.** The network predicts each band's gain relative to the strike's loudest mode.
//!   The absolute level is estimated as for a free-free beam's end, where a mass-normalised
//!   mode's value is `2 / sqrt(m)`: the loudest mode's impulse amplitude is
//!   `2 / (sqrt(m) omega)` with `m` the object's mass. An estimate, so that the predicted and
//!   the exact answers play at similar levels; the spectrum's shape is the network's.
//! - **Strike.** The hit point selects the 2x2x2-voxel strike cell of the box it falls in (the
//!   nearest struck cell when it falls outside the surface); a strike without a force
//!   direction pushes towards the object's centre.

use super::bands::{self, BandMode, CELLS_PER_AXIS, INPUT_SIDE};
use super::Prediction;
use crate::material::DampedMode;
use crate::material::Material;
use crate::modal::{Hit, VoicedMode};

/// A shape's predicted modes (see the module docs).
#[derive(Clone, Debug)]
pub struct PredictedObject {
    /// The network's answer for the shape in the box.
    pub prediction: Prediction,
    /// The shape's grid dimensions, voxels (before resampling).
    pub grid_dims: [usize; 3],
    /// Box voxels per voxel of the shape (32 over its longest side).
    pub box_per_voxel: f64,
    /// Filled volume of the shape, in its voxels.
    pub volume_voxels: f64,
    /// Time the network took, ms.
    pub inference_ms: f64,
}

/// Impulse amplitude of a mass-normalised mode at a free end, times `sqrt(m)`: the level
/// estimate of the module docs.
const FREE_END_MODE_VALUE: f64 = 2.0;

impl PredictedObject {
    /// The strike cell for a hit at `point_m` on a shape with voxel edge `voxel_size_m`: the
    /// cell it falls in, or the nearest struck cell.
    pub fn strike_cell(&self, point_m: [f64; 3], voxel_size_m: f64) -> Option<[usize; 3]> {
        let c = CELLS_PER_AXIS;
        let want = point_m.map(|p| p / voxel_size_m * self.box_per_voxel / 2.0);
        let struck = &self.prediction.struck;
        (0..struck.len())
            .filter(|&i| struck[i])
            .map(|i| [i % c, (i / c) % c, i / (c * c)])
            .min_by(|a, b| {
                let d = |q: &[usize; 3]| {
                    (0..3)
                        .map(|k| (q[k] as f64 + 0.5 - want[k]).powi(2))
                        .sum::<f64>()
                };
                d(a).total_cmp(&d(b))
            })
    }

    /// The band modes a hit plays, at the reference (relative gains).
    pub fn strike(&self, hit: &Hit, voxel_size_m: f64) -> Vec<BandMode> {
        let Some(cell) = self.strike_cell(hit.point_m, voxel_size_m) else {
            return Vec::new();
        };
        let direction = hit.direction.unwrap_or_else(|| {
            // Towards the centre of the shape's box, from the cell's centre.
            let centre = self.grid_dims.map(|d| d as f64 * self.box_per_voxel / 2.0);
            let p = cell.map(|v| 2.0 * v as f64 + 1.0);
            [0, 1, 2].map(|a| centre[a] - p[a])
        });
        self.prediction.strike(cell, direction)
    }

    /// Every predicted mode for a material, a voxel edge and a strike: natural frequency,
    /// damping and impulse amplitude, ascending in frequency (see the module docs).
    pub fn voice(&self, material: &Material, voxel_size_m: f64, hit: &Hit) -> Vec<VoicedMode> {
        let modes = self.strike(hit, voxel_size_m);
        // Reference units: voxel edge 1 in the box, E = rho = 1.
        let box_voxel_m = voxel_size_m / self.box_per_voxel;
        let s = material.youngs_modulus_pa / (material.density_kg_m3 * box_voxel_m * box_voxel_m);
        let mass_kg = material.density_kg_m3 * self.volume_voxels * voxel_size_m.powi(3);
        let loudest_omega = modes
            .iter()
            .max_by(|a, b| a.gain.total_cmp(&b.gain))
            .map(|m| (bands::reference_eigenvalue(m.freq_hz) * s).sqrt());
        let mut voiced: Vec<VoicedMode> = modes
            .iter()
            .map(|m| {
                let lambda = bands::reference_eigenvalue(m.freq_hz) * s;
                let damped = material.damping.damp(lambda);
                let gain = match (damped, loudest_omega) {
                    (DampedMode::Oscillating { .. }, Some(w)) if w > 0.0 && mass_kg > 0.0 => {
                        m.gain * FREE_END_MODE_VALUE / (mass_kg.sqrt() * w)
                    }
                    _ => 0.0,
                };
                VoicedMode {
                    natural_hz: lambda.sqrt() / std::f64::consts::TAU,
                    damped,
                    gain,
                    residual: f64::NAN,
                }
            })
            .collect();
        voiced.sort_by(|a, b| a.natural_hz.total_cmp(&b.natural_hz));
        voiced
    }
}

/// The box side the shape is resampled to.
pub(super) const BOX_SIDE: usize = INPUT_SIDE;
