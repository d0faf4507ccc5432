//! The `modes` report: what `modalforge modes --json` prints, for a FEM basis or the
//! predictor's answer.
//!
//! Where it sits: [`super::Object`] builds the object and solves it; [`report`] and
//! [`neural_report`] turn the answer and the strike into [`ModesReport`], which `cli.rs` prints
//! as JSON or as a table.

use super::{Object, ObjectError, SolverChoice};
use modalforge::basis::{Hit, ModeBasis};
use modalforge::material::DampedMode;
use modalforge::shape::ops;
use serde::Serialize;

/// One mode in the `modes` report.
#[derive(Debug, Serialize)]
pub struct ModeReport {
    /// Damped frequency, Hz (0 when overdamped).
    pub freq_hz: f64,
    /// Decay rate, 1/s.
    pub decay_per_s: f64,
    /// Impulse amplitude at the hit.
    pub gain: f64,
    /// Undamped natural frequency, Hz.
    pub natural_hz: f64,
    /// True when the mode does not oscillate (never played).
    pub overdamped: bool,
}

/// Time split of a solve, ms.
#[derive(Debug, Serialize)]
pub struct Timings {
    /// Assembly.
    pub assemble: f64,
    /// Factorisation or preconditioner setup plus iterations.
    pub solve: f64,
    /// Factorisation / preconditioner setup alone.
    pub setup: f64,
    /// Iterations alone.
    pub iterate: f64,
}

/// The `modes --json` document.
#[derive(Debug, Serialize)]
pub struct ModesReport {
    /// Every computed non-rigid mode, ascending.
    pub modes: Vec<ModeReport>,
    /// Zero-frequency modes found numerically and dropped.
    pub rigid_modes: usize,
    /// Face-connected components.
    pub components: usize,
    /// Solid voxels.
    pub voxels: usize,
    /// Degrees of freedom.
    pub dofs: usize,
    /// Residual (NeuralSound eq. 6) per mode.
    pub residuals: Vec<f64>,
    /// Time split, ms.
    pub timings_ms: Timings,
    /// Grid dimensions.
    pub grid: [usize; 3],
    /// Voxel edge, m.
    pub voxel_size_m: f64,
    /// Element used.
    pub element: String,
    /// Solver used.
    pub solver: String,
    /// Material name.
    pub material: String,
    /// Hit point, m, and force direction used.
    pub hit_m: [f64; 3],
    /// `--solver neural --bands`: the predicted band representation at the strike.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bands: Option<Vec<BandReport>>,
}

/// One predicted band at the strike (`modes --solver neural --bands`).
#[derive(Debug, Serialize)]
pub struct BandReport {
    /// Band index (0: lowest).
    pub band: usize,
    /// The band's predicted mode, Hz, for this material and size (`None`: predicted empty).
    pub freq_hz: Option<f64>,
    /// Mask per unit force along x, y, z at the strike cell.
    pub mask: [bool; 3],
    /// Normalised log-amplitude per force direction (0 at -60 dB, 1 for the loudest).
    pub log_amplitude: [f32; 3],
}

/// The `modes` report for the predictor's answer: the modes as FEM's report gives them (one
/// per predicted band; no residuals, no DOFs), the `count` lowest or those below `fmax_hz`.
pub fn neural_report(
    object: &Object,
    predicted: &modalforge::predictor::object::PredictedObject,
    hit: &Hit,
    count: Option<usize>,
    fmax_hz: Option<f64>,
    with_bands: bool,
) -> ModesReport {
    use modalforge::predictor::bands::{self, BANDS, DIRECTIONS};
    let h = object.grid.voxel_size_m();
    let mut voiced = predicted.strike(&object.material, h, hit);
    // The bands this strike excites (a masked-off band has no force here).
    voiced.retain(|m| m.gain != 0.0);
    if let Some(f) = fmax_hz {
        voiced.retain(|m| m.natural_hz <= f);
    }
    voiced.truncate(count.unwrap_or(usize::MAX));
    let bands = with_bands.then(|| {
        let enc = predicted.prediction.to_encoding();
        let c = bands::CELLS_PER_AXIS;
        let cell = predicted
            .strike_cell(hit.point_m, h)
            .map(|q| q[0] + c * (q[1] + c * q[2]));
        let box_voxel_m = h / predicted.box_per_voxel;
        let scale = object.material.youngs_modulus_pa
            / (object.material.density_kg_m3 * box_voxel_m * box_voxel_m);
        (0..BANDS)
            .map(|b| {
                let at = |d: usize| cell.map(|i| (i * DIRECTIONS + d) * BANDS + b);
                BandReport {
                    band: b,
                    freq_hz: enc.band_log_hz[b].map(|lf| {
                        let l = bands::reference_eigenvalue(10f64.powf(lf as f64)) * scale;
                        l.sqrt() / std::f64::consts::TAU
                    }),
                    mask: [0, 1, 2].map(|d| at(d).is_some_and(|i| enc.mask[i])),
                    log_amplitude: [0, 1, 2].map(|d| at(d).map_or(0.0, |i| enc.log_amplitude[i])),
                }
            })
            .collect()
    });
    ModesReport {
        modes: voiced.iter().map(mode_report).collect(),
        rigid_modes: 0,
        components: ops::components(&object.grid).1,
        voxels: object.grid.count(),
        dofs: 0,
        residuals: voiced.iter().map(|m| m.residual).collect(),
        timings_ms: Timings {
            assemble: 0.0,
            solve: predicted.inference_ms,
            setup: 0.0,
            iterate: predicted.inference_ms,
        },
        grid: object.grid.dims(),
        voxel_size_m: h,
        element: "none".into(),
        solver: SolverChoice::Neural.to_string(),
        material: object.material.name.clone(),
        hit_m: hit.point_m,
        bands,
    }
}

fn mode_report(m: &modalforge::basis::StruckMode) -> ModeReport {
    match m.damped {
        DampedMode::Oscillating {
            freq_hz,
            decay_per_s,
        } => ModeReport {
            freq_hz,
            decay_per_s,
            gain: m.gain,
            natural_hz: m.natural_hz,
            overdamped: false,
        },
        DampedMode::Overdamped { decay_per_s } => ModeReport {
            freq_hz: 0.0,
            decay_per_s,
            gain: 0.0,
            natural_hz: m.natural_hz,
            overdamped: true,
        },
    }
}

/// Builds the report for a solved object.
pub fn report(object: &Object, basis: &ModeBasis, hit: &Hit) -> Result<ModesReport, ObjectError> {
    let h = object.grid.voxel_size_m();
    let voiced = basis.strike(&object.material, h, hit)?;
    let sol = &basis.solution;
    Ok(ModesReport {
        modes: voiced.iter().map(mode_report).collect(),
        rigid_modes: sol.rigid_modes,
        components: basis.components,
        voxels: object.grid.count(),
        dofs: basis.model.dofs(),
        residuals: sol.residuals.clone(),
        timings_ms: Timings {
            assemble: basis.assemble_ms,
            solve: sol.timings.setup_ms + sol.timings.iterate_ms,
            setup: sol.timings.setup_ms,
            iterate: sol.timings.iterate_ms,
        },
        grid: object.grid.dims(),
        voxel_size_m: h,
        element: object.element.to_string(),
        solver: sol.solver.to_string(),
        material: object.material.name.clone(),
        hit_m: hit.point_m,
        bands: None,
    })
}
