//! A shape's predicted modes as the product plays them: the network's answer for a shape scaled
//! to fill the input box, voiced for any material, size, hit and force like a FEM object.
//!
//! Where it sits: [`super::Predictor::predict`] makes a [`PredictedObject`]; its
//! [`PredictedObject::strike`] gives the same [`StruckMode`]s as [`crate::basis::ModeBasis::strike`]
//! (the material's damping law, gains as impulse amplitudes), so the CLI's `modes` and `render`
//! treat both alike.
//!
//! The physics of the mapping:
//! - **Scale.** The network answers at the reference (steel, the 32-voxel box
//!   [`super::bands::REFERENCE_BOX_M`] across). A shape whose longest side `n` is within the
//!   training sizes ([`MIN_UNSCALED_SIDE`] to 32 voxels) goes in as it is; any other is
//!   resampled to 32 first ([`input_side`]), so each box voxel is `h n / 32` of the real object
//!   (`h` its voxel edge). A predicted band frequency `f_ref` is then the reference-unit eigenvalue
//!   `lambda = reference_eigenvalue(f_ref)` (voxel edge 1, E = rho = 1), and the material's
//!   `E / (rho h_box^2)` gives the physical one: Deep-Modal's scaling laws (Jin, Li and
//!   Manocha 2020, eq. 10-12), the same as [`crate::basis::ModeBasis::eigenvalues`].
//! - **Gains.** The network predicts each band's gain relative to the strike's loudest mode.
//!   The absolute level is estimated as for a free-free beam's end, where a mass-normalised
//!   mode's value is `2 / sqrt(m)`: the loudest mode's impulse amplitude is
//!   `2 / (sqrt(m) omega)` with `m` the object's mass. An estimate, so that the predicted and
//!   the exact answers play at similar levels; the spectrum's shape is the network's.
//! - **Strike.** The hit point selects the 2x2x2-voxel strike cell of the box it falls in (the
//!   nearest struck cell when it falls outside the surface); a strike without a force
//!   direction pushes towards the object's centre.
//! - **Above the bands.** A compact shape ringing at the top of the band range or above it has
//!   Ritz modes ([`super::ritz`]) from their lowest up, in place of the network's bands there.
//!   They are voiced as FEM modes are: the mass-normalised mode shape at the hit point, along
//!   the force (`phi . f`), moved from the box's voxels to the shape's (`lambda ~ h^-2`, and
//!   `phi ~ h^-3/2` from `int rho phi^2 dV = 1`).

use super::bands::{self, BANDS, CELLS_PER_AXIS, INPUT_SIDE};
use super::network::MASK_CHANNELS;
use super::ritz::RitzModes;
use super::Prediction;
use crate::basis::{Hit, StruckMode};
use crate::material::DampedMode;
use crate::material::Material;

/// A shape's predicted modes (see the module docs).
#[derive(Clone, Debug)]
pub struct PredictedObject {
    /// The network's answer for the shape in the box.
    pub prediction: Prediction,
    /// The shape's grid dimensions, voxels (before resampling).
    pub grid_dims: [usize; 3],
    /// Box voxels per voxel of the shape (1, or 32 over its longest side: [`input_side`]).
    pub box_per_voxel: f64,
    /// Filled volume of the shape, in its voxels.
    pub volume_voxels: f64,
    /// Time the prediction took (the network, the pitch index and the Ritz modes), ms.
    pub inference_ms: f64,
    /// One mode per band predicted to hold one, then the Ritz modes, ascending: reference-unit
    /// eigenvalues with the shape's own voxel edge as the unit (as
    /// [`crate::basis::ModeBasis`] keeps them).
    pub eigenvalues: Vec<f64>,
    /// The band of each of the network's modes (the first `bands.len()` eigenvalues).
    bands: Vec<usize>,
    /// The Ritz modes that follow them (on the network's input grid), if the shape has any.
    ritz: Option<RitzModes>,
}

/// Value of a mass-normalised mode at a free end, times `sqrt(m)`: the level estimate of the
/// module docs.
const FREE_END_MODE_VALUE: f64 = 2.0;

impl PredictedObject {
    /// Wraps the network's answer for a shape of `grid_dims` voxels that was resampled by
    /// `box_per_voxel` (1 where it went in as it is), with the Ritz modes of its input grid
    /// where it has them (they replace the network's bands from their lowest one up).
    pub fn new(
        prediction: Prediction,
        ritz: Option<RitzModes>,
        grid_dims: [usize; 3],
        box_per_voxel: f64,
        volume_voxels: f64,
        inference_ms: f64,
    ) -> Self {
        // A box voxel is 1 / box_per_voxel of the shape's: lambda scales with h^-2.
        let to_shape = box_per_voxel * box_per_voxel;
        let below = ritz.as_ref().map_or(BANDS, RitzModes::first_band);
        let (bands, mut eigenvalues): (Vec<usize>, Vec<f64>) = prediction
            .band_log_hz
            .iter()
            .enumerate()
            .take(below)
            .filter_map(|(b, lf)| {
                let hz = 10f64.powf((*lf)? as f64);
                Some((b, bands::reference_eigenvalue(hz) * to_shape))
            })
            .unzip();
        if let Some(r) = &ritz {
            eigenvalues.extend(r.eigenvalues.iter().map(|l| l * to_shape));
        }
        Self {
            prediction,
            grid_dims,
            box_per_voxel,
            volume_voxels,
            inference_ms,
            eigenvalues,
            bands,
            ritz,
        }
    }

    /// Number of predicted modes.
    pub fn mode_count(&self) -> usize {
        self.eigenvalues.len()
    }

    /// The band of each of the network's modes, the first of
    /// [`PredictedObject::eigenvalues`]; the Ritz modes follow them.
    pub fn bands(&self) -> &[usize] {
        &self.bands
    }

    /// The strike cell for a hit at `point_m` on a shape with voxel edge `voxel_size_m`: the
    /// cell it falls in, or the nearest struck cell. Never allocates.
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

    /// Reference-unit modal forces at the hit (shape voxel edge `voxel_size_m`), one per mode
    /// into `out`, as [`crate::basis::ModeBasis::reference_forces_into`] gives them: multiply
    /// by `1 / sqrt(rho h^3)` for physical units. The network's relative gains at the struck
    /// cell, levelled by the free-end estimate of the module docs. A hit without a force
    /// direction pushes towards the shape's centre. Never allocates (the engine calls it on
    /// the audio thread).
    pub fn reference_forces_into(&self, hit: &Hit, voxel_size_m: f64, out: &mut [f64]) {
        out.iter_mut().for_each(|f| *f = 0.0);
        let Some(cell) = self.strike_cell(hit.point_m, voxel_size_m) else {
            return;
        };
        let direction = hit.direction.unwrap_or_else(|| {
            let centre = self.grid_dims.map(|d| d as f64 * self.box_per_voxel / 2.0);
            let p = cell.map(|v| 2.0 * v as f64 + 1.0);
            [0, 1, 2].map(|a| centre[a] - p[a])
        });
        let norm = direction.iter().map(|d| d * d).sum::<f64>().sqrt();
        if !(norm.is_finite() && norm > 0.0) {
            return;
        }
        let unit = direction.map(|d| d / norm);
        let (network, ritz) = out.split_at_mut(self.bands.len().min(out.len()));
        self.network_forces_into(cell, unit, network);
        if let Some(modes) = &self.ritz {
            // The hit in the box's voxels; phi from the box's voxel units to the shape's.
            let at = hit.point_m.map(|p| p / voxel_size_m * self.box_per_voxel);
            let to_shape = self.box_per_voxel.powf(1.5);
            modes.forces_into(at, unit, ritz);
            ritz.iter_mut().for_each(|f| *f *= to_shape);
            // A compact solid's multiplets, voiced as one as FEM's are.
            crate::basis::strike_align_unisons(&modes.eigenvalues, ritz);
        }
    }

    /// The network's modes' forces for a strike at `cell` along `unit`: its relative gains,
    /// levelled by the free-end estimate of the module docs.
    fn network_forces_into(&self, cell: [usize; 3], unit: [f64; 3], out: &mut [f64]) {
        let c = CELLS_PER_AXIS;
        let outputs = self
            .prediction
            .cell_outputs(cell[0] + c * (cell[1] + c * cell[2]));
        // Relative gains (loudest axis strike's loudest mode: 1), as BandEncoding::strike.
        let gain = |b: usize| {
            bands::band_gain(
                unit,
                std::array::from_fn(|d| {
                    let ch = d * BANDS + b;
                    (outputs[ch] > super::MASK_LOGIT_THRESHOLD)
                        .then_some(outputs[MASK_CHANNELS + ch].clamp(0.0, 1.0))
                }),
            )
        };
        let Some((loud, _)) = self
            .bands
            .iter()
            .enumerate()
            .map(|(i, &b)| (i, gain(b)))
            .filter(|(_, g)| *g > 0.0)
            .max_by(|a, b| a.1.total_cmp(&b.1))
        else {
            return;
        };
        let loudest_gain = gain(self.bands[loud]);
        let loudest_value = FREE_END_MODE_VALUE / self.volume_voxels.max(1e-9).sqrt();
        let loudest_omega = self.eigenvalues[loud].sqrt();
        for (i, o) in out.iter_mut().take(self.bands.len()).enumerate() {
            // gain = value / omega: value_i = (g_i / g_L) value_L omega_i / omega_L.
            *o = gain(self.bands[i]) / loudest_gain * loudest_value * self.eigenvalues[i].sqrt()
                / loudest_omega;
        }
    }

    /// Every predicted mode for a material, a voxel edge and a strike: natural frequency,
    /// damping and impulse amplitude, ascending (as [`crate::basis::ModeBasis::strike`]).
    pub fn strike(&self, material: &Material, voxel_size_m: f64, hit: &Hit) -> Vec<StruckMode> {
        let mut forces = vec![0.0; self.mode_count()];
        self.reference_forces_into(hit, voxel_size_m, &mut forces);
        let s = material.youngs_modulus_pa / (material.density_kg_m3 * voxel_size_m * voxel_size_m);
        let physical = 1.0 / (material.density_kg_m3 * voxel_size_m.powi(3)).sqrt();
        self.eigenvalues
            .iter()
            .zip(&forces)
            .map(|(&l, &f)| {
                let lambda = l * s;
                let damped = material.damping.damp(lambda);
                let gain = match damped {
                    DampedMode::Oscillating { freq_hz, .. } => {
                        f * physical / (std::f64::consts::TAU * freq_hz)
                    }
                    DampedMode::Overdamped { .. } => 0.0,
                };
                StruckMode {
                    natural_hz: lambda.sqrt() / std::f64::consts::TAU,
                    damped,
                    gain,
                    residual: f64::NAN,
                }
            })
            .collect()
    }
}

/// The box side a shape outside the training sizes is resampled to.
pub(super) const BOX_SIDE: usize = INPUT_SIDE;

/// The shortest longest side, in voxels, at which the network sees a shape as it is. The
/// training shapes' longest sides are 16 to 32 voxels (`modalforge dataset --seed 2`: 5,000
/// shapes, 73 of them at 12-15), and the network and the pitch index read the absolute size (a
/// frequency goes as `1 / L`): a held-out shape given at its own size is 26.6 cents off
/// (`modalforge predictor eval`), resampled to fill the box 49.3 (measured through the pitch
/// index on the same 500 shapes, with the truth moved by the size law).
pub const MIN_UNSCALED_SIDE: usize = 16;

/// The longest side, in voxels, a shape whose longest side is `longest` is given to the
/// network at: its own within the training sizes ([`MIN_UNSCALED_SIDE`] to the box), else the
/// box's (a larger shape must shrink to fit; a smaller one would ring above the top band).
pub fn input_side(longest: usize) -> usize {
    if (MIN_UNSCALED_SIDE..=BOX_SIDE).contains(&longest) {
        longest
    } else {
        BOX_SIDE
    }
}
