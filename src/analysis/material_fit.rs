//! Material from a recording: the stiffness-to-density ratio `E/rho` and Poisson's ratio of an
//! object of known shape, size and hit point, from the modes [`super::extract`] found.
//!
//! Where it sits: after [`super::extract`], beside the FEM path it inverts. The forward model
//! is [`ModeBasis`]: a shape solved once in reference units serves every `E/rho` through the
//! scaling law `omega^2 = omega_ref^2 (E/rho) / h^2` (Jin et al. 2020, eq. 12), so in
//! log-frequency `E/rho` is a shift, `s = ln(E/rho) / 2`, and only Poisson's ratio needs
//! re-solves (Sterling and Lin 2016, sec. 4.1.2, fit the same two parameters).
//!
//! The fit runs in two stages, as DiffSound does (Jin et al. 2024, sec. 4.2, eq. 11):
//! 1. **Optimal transport, from a bad start.** The recording's modes and the model's, each a
//!    weighted set of points on the log-frequency axis, are compared by the 1-D Wasserstein
//!    distance `W1 = int |F - G|` of their cumulative weights, over the span both cover. It
//!    varies smoothly as the model slides past the recording, so a scan over `s` finds the
//!    right basin from a start many times off, where a mode-by-mode loss would lock onto the
//!    wrong neighbours. It is repeated at five Poisson's ratios spanning 0.05-0.45; between
//!    them each solution is moved by its eigenvalue gradient (below), and a two-sided trimmed
//!    loss ([`alignment::trimmed_loss`]: recorded modes to model modes and loud model modes to recorded
//!    ones, each residual capped), which a few wrong neighbours cannot pull, picks `(s, nu)`.
//! 2. **Matched modes, by Gauss-Newton.** Each recorded mode is paired with the nearest model
//!    mode, and `(s, nu)` minimise the weighted squared log-frequency error. Its gradient in
//!    `nu` is the eigenvalue gradient `d lambda_i / d nu = phi_i^T (dK/d nu) phi_i` for
//!    mass-normalised modes (DiffSound eq. 7; the mass matrix does not depend on `nu`), with
//!    `dK/d nu` a central difference of two assemblies: no extra eigen-solve.
//!
//! The uncertainty is the Gauss-Newton covariance `sigma^2 (J^T W J)^-1`, with `sigma^2` the
//! weighted residual variance: one standard deviation of each parameter, valid where the
//! matching is right. Density is not observable from frequencies (only `E/rho` is); callers
//! assume one (a named material, or the preset nearest the fit).

mod alignment;

use super::ExtractedMode;
use crate::basis::{BasisError, Hit, ModeBasis};
use crate::eigen::{EigenOptions, ModeCount, SolverKind};
use crate::fem::{sparse, ElementKind, FemModel};
use crate::shape::VoxelGrid;
use alignment::{aligned, matches, transport_scan};
use std::f64::consts::TAU;

/// Settings of [`fit_material`].
#[derive(Clone, Copy, Debug)]
pub struct MaterialFitOptions {
    /// The element the model is solved with.
    pub element: ElementKind,
    /// The starting guess for `E/rho`, m^2/s^2 (a preset's, or the user's).
    pub start_e_over_rho: f64,
    /// Modes the model computes per solve (the recording's modes above the highest of them
    /// are not used).
    pub model_modes: usize,
    /// How far from the start the optimal-transport scan looks, as a factor on `E/rho` either
    /// way.
    pub search_factor: f64,
}

impl Default for MaterialFitOptions {
    fn default() -> Self {
        Self {
            element: ElementKind::Hex8Incompatible,
            start_e_over_rho: 70e9 / 2500.0,
            model_modes: 40,
            search_factor: 16.0,
        }
    }
}

/// What [`fit_material`] found.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct MaterialFit {
    /// Young's modulus over density, m^2/s^2.
    pub e_over_rho: f64,
    /// Poisson's ratio.
    pub poisson_ratio: f64,
    /// One standard deviation of `E/rho`, relative.
    pub e_over_rho_rel_sigma: f64,
    /// One standard deviation of Poisson's ratio; infinite where fewer than [`MIN_MODES`]
    /// recorded modes matched (then only `E/rho` is fitted).
    pub poisson_sigma: f64,
    /// Recorded modes matched to model modes in the final fit.
    pub matched: usize,
    /// Weighted RMS of the matched modes' frequency errors, cents.
    pub rms_cents: f64,
    /// Eigen-solves the fit took.
    pub solves: usize,
}

/// Why a material could not be fitted.
#[derive(Debug, thiserror::Error)]
pub enum MaterialFitError {
    /// Too few modes to fit two parameters.
    #[error(
        "the recording has {found} usable modes, a material fit needs at least {needed}: \
         use a longer or cleaner recording"
    )]
    TooFewModes {
        /// Modes the recording gave.
        found: usize,
        /// Modes the fit needs.
        needed: usize,
    },
    /// The start is not a material.
    #[error("the starting guess E/rho {e_over_rho} is not a positive finite number")]
    BadStart {
        /// The given `E/rho`.
        e_over_rho: f64,
    },
    /// No model mode lies near the recording's at any `E/rho` searched.
    #[error("no E/rho within {factor}x of the start puts the shape's modes on the recording's: check the shape, its size and the starting material")]
    NoMatch {
        /// The search factor.
        factor: f64,
    },
    /// The shape could not be solved.
    #[error(transparent)]
    Solve(#[from] BasisError),
}

/// Fewest recorded modes a fit accepts (two parameters and a residual).
pub const MIN_MODES: usize = 3;

/// Lowest quality factor `pi f / d` of a recorded mode the fit uses.
pub const MIN_QUALITY: f64 = 5.0;

/// Poisson's ratios the first stage solves at; between them it moves each solution by its
/// eigenvalue gradient ([`NU_LOCAL_STEPS`] of [`NU_LOCAL_STEP`] either way).
const POISSON_SCAN: [f64; 5] = [0.05, 0.15, 0.25, 0.35, 0.45];

/// Steps either side of a scanned Poisson's ratio the linearised spectrum is tried at.
const NU_LOCAL_STEPS: usize = 10;

/// Step in Poisson's ratio of the linearised scan (10 steps cover half the scan's spacing).
const NU_LOCAL_STEP: f64 = 0.005;

/// Largest residual [`alignment::trimmed_loss`] counts in full (2 %); beyond it a mode counts `TRIM^2`.
pub(super) const TRIM: f64 = 0.02;

/// Gauss-Newton iterations at most; it stops earlier when `nu` moves less than
/// [`NU_TOLERANCE`].
const MAX_ITERATIONS: usize = 8;

/// Convergence of Poisson's ratio.
const NU_TOLERANCE: f64 = 1e-3;

/// Step of the central difference `dK/d nu`.
const NU_DIFFERENCE: f64 = 1e-4;

/// Largest Poisson's ratio the fit moves to (0.5 is incompressible: the FEM refuses it).
const NU_MAX: f64 = 0.48;

/// A recorded mode as the fit uses it: log-frequency and weight.
#[derive(Clone, Copy, Debug)]
struct Point {
    log_hz: f64,
    weight: f64,
}

/// A model's modes as the losses see them: log-frequencies at `s = 0` (`E/rho = 1`) and
/// weights at the hit.
#[derive(Clone, Debug, Default)]
struct Spectrum {
    /// `ln(omega_ref / (2 pi h))`.
    log_hz: Vec<f64>,
    weights: Vec<f64>,
}

impl Spectrum {
    /// The highest mode's log-frequency at `s = 0`.
    fn top(&self) -> f64 {
        self.log_hz
            .iter()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max)
    }
}

/// The model solved at one Poisson's ratio.
struct Model {
    poisson: f64,
    spectrum: Spectrum,
    /// `d ln f_k / d nu` of every mode (the eigenvalue gradient).
    slopes: Vec<f64>,
}

impl Model {
    /// The spectrum moved to Poisson's ratio `nu` to first order (the eigenvalue gradient):
    /// no re-solve, good for a few hundredths of `nu`.
    fn linearised(&self, nu: f64, out: &mut Spectrum) {
        let dnu = nu - self.poisson;
        out.log_hz.clear();
        out.log_hz.extend(
            self.spectrum
                .log_hz
                .iter()
                .zip(&self.slopes)
                .map(|(l, g)| l + g * dnu),
        );
        out.weights.clone_from(&self.spectrum.weights);
    }
}

/// Fits `E/rho` and Poisson's ratio of `grid` (voxel edge `voxel_size_m`, struck at `hit`) to
/// the modes [`super::extract`] found in its recording.
pub fn fit_material(
    grid: &VoxelGrid,
    voxel_size_m: f64,
    hit: &Hit,
    recorded: &[ExtractedMode],
    options: &MaterialFitOptions,
) -> Result<MaterialFit, MaterialFitError> {
    let e0 = options.start_e_over_rho;
    if !(e0.is_finite() && e0 > 0.0) {
        return Err(MaterialFitError::BadStart { e_over_rho: e0 });
    }
    let points = points_of(recorded);
    if points.len() < MIN_MODES {
        return Err(MaterialFitError::TooFewModes {
            found: points.len(),
            needed: MIN_MODES,
        });
    }
    let no_match = || MaterialFitError::NoMatch {
        factor: options.search_factor,
    };
    let mut solves = 0;
    let mut solve = |nu: f64| -> Result<Model, MaterialFitError> {
        solves += 1;
        model_at(grid, voxel_size_m, hit, nu, options)
    };
    // Stage 1: optimal transport over s finds the basin at each scanned Poisson's ratio; the
    // trimmed mode-by-mode loss, on the spectrum moved by its eigenvalue gradient, then picks
    // nu between the scanned ones.
    let s0 = 0.5 * e0.ln();
    let half_span = 0.5 * options.search_factor.max(1.0).ln();
    let mut best: Option<(f64, f64, f64)> = None;
    let mut moved = Spectrum::default();
    for nu in POISSON_SCAN {
        let model = solve(nu)?;
        let (s, transport) = transport_scan(&points, &model.spectrum, s0, half_span);
        if !transport.is_finite() {
            continue;
        }
        for k in 0..=2 * NU_LOCAL_STEPS {
            let nu = nu + (k as f64 - NU_LOCAL_STEPS as f64) * NU_LOCAL_STEP;
            if !(0.0..=NU_MAX).contains(&nu) {
                continue;
            }
            model.linearised(nu, &mut moved);
            let (s, loss) = aligned(&points, &moved, s);
            if best.is_none_or(|b| loss < b.2) {
                best = Some((s, nu, loss));
            }
        }
    }
    let (mut s, nu, _) = best.ok_or_else(no_match)?;
    // Stage 2: matched modes, Gauss-Newton on (s, nu) with the eigenvalue gradient.
    let mut model = solve(nu)?;
    s = aligned(&points, &model.spectrum, s).0;
    for _ in 0..MAX_ITERATIONS {
        let pairs = matches(&points, &model.spectrum, s);
        if pairs.len() < MIN_MODES {
            break;
        }
        let step = gauss_newton(&points, &model, &pairs, s);
        s += step.ds;
        let nu = (model.poisson + step.dnu).clamp(0.0, NU_MAX);
        if (nu - model.poisson).abs() < NU_TOLERANCE {
            break;
        }
        model = solve(nu)?;
    }
    // The final estimate at the final model: s re-centred, residuals and covariance there.
    let pairs = matches(&points, &model.spectrum, s);
    if pairs.is_empty() {
        return Err(no_match());
    }
    let last = gauss_newton(&points, &model, &pairs, s);
    s += last.ds_only;
    let rms = weighted_rms(&points, &model.spectrum, &pairs, s);
    // With fewer matched pairs than parameters and a residual, Poisson's ratio stays where
    // the first stage put it and is not determined (an infinite sigma; JSON null); E/rho's
    // sigma is then the matched modes' spread, at least the trimmed loss's cap.
    let (sigma_s, sigma_nu) = if pairs.len() >= MIN_MODES {
        (last.sigma_s, last.sigma_nu)
    } else {
        (rms.max(TRIM), f64::INFINITY)
    };
    Ok(MaterialFit {
        e_over_rho: (2.0 * s).exp(),
        poisson_ratio: model.poisson,
        e_over_rho_rel_sigma: 2.0 * sigma_s,
        poisson_sigma: sigma_nu,
        matched: pairs.len(),
        rms_cents: rms * 1200.0 / std::f64::consts::LN_2,
        solves,
    })
}

/// The material preset nearest a fit: in `ln(E/rho)` (a 10 % step) and Poisson's ratio (a
/// 0.05 step) counted alike. Its density is the one to assume, since a recording shows only
/// `E/rho`.
pub fn nearest_preset(fit: &MaterialFit) -> crate::material::Material {
    use crate::material::{self, Material};
    let distance = |m: &Material| {
        let de = ((m.youngs_modulus_pa / m.density_kg_m3) / fit.e_over_rho).ln() / 0.1;
        let dnu = (m.poisson_ratio - fit.poisson_ratio) / 0.05;
        de * de + dnu * dnu
    };
    material::preset_names()
        .into_iter()
        .filter_map(|name| Material::preset(name).ok())
        .min_by(|a, b| distance(a).total_cmp(&distance(b)))
        .expect("the presets are built in")
}

/// The usable recorded modes: finite, positive frequency, non-zero amplitude, and resonant
/// (quality factor `pi f / d` at least [`MIN_QUALITY`]: a strike's click, which extraction
/// reports as a mode dying within a cycle or two, is not one of the object's); weighted by
/// the square root of their amplitude relative to the loudest (loud modes count more, quiet
/// ones still count).
fn points_of(recorded: &[ExtractedMode]) -> Vec<Point> {
    let usable: Vec<(f64, f64)> = recorded
        .iter()
        .filter(|m| {
            let resonant = std::f64::consts::PI * m.freq_hz >= MIN_QUALITY * m.decay_per_s;
            m.freq_hz.is_finite()
                && m.freq_hz > 0.0
                && m.gain.is_finite()
                && m.gain != 0.0
                && resonant
        })
        .map(|m| (m.freq_hz, m.gain.abs()))
        .collect();
    let loudest = usable.iter().map(|p| p.1).fold(0.0, f64::max);
    let mut points: Vec<Point> = usable
        .iter()
        .map(|&(f, a)| Point {
            log_hz: f.ln(),
            weight: (a / loudest).sqrt(),
        })
        .collect();
    points.sort_by(|a, b| a.log_hz.total_cmp(&b.log_hz));
    points
}

/// Solves the shape at Poisson's ratio `nu` and reads its modes at the hit, and their
/// log-frequency slopes in `nu`: `d ln f / d nu = (d lambda / d nu) / (2 lambda)`, with
/// `d lambda / d nu = phi^T (dK/d nu) phi` (Jin et al. 2024, eq. 7; mass-normalised `phi`, and
/// `M` does not depend on `nu`) and `dK/d nu` a central difference of two assemblies of the
/// same grid (so the same node numbering).
fn model_at(
    grid: &VoxelGrid,
    voxel_size_m: f64,
    hit: &Hit,
    nu: f64,
    options: &MaterialFitOptions,
) -> Result<Model, MaterialFitError> {
    let eigen = EigenOptions {
        count: ModeCount::First(options.model_modes.max(MIN_MODES)),
        ..Default::default()
    };
    let basis = ModeBasis::solve(grid, options.element, nu, SolverKind::Lanczos, &eigen)?;
    let mut forces = vec![0.0; basis.mode_count()];
    basis
        .reference_forces_into(hit, voxel_size_m, &mut forces)
        .map_err(|e| BasisError::BadHit(e.to_string()))?;
    let lambdas = &basis.solution.eigenvalues;
    let log_hz: Vec<f64> = lambdas
        .iter()
        .map(|l| (l.max(f64::MIN_POSITIVE).sqrt() / (TAU * voxel_size_m)).ln())
        .collect();
    // A mode's amplitude for a unit impulse is its force over omega (Jin et al. 2020, eq. 7);
    // weighted like the recording's, by the square root relative to the loudest.
    let amps: Vec<f64> = forces
        .iter()
        .zip(lambdas)
        .map(|(f, l)| f.abs() / l.max(f64::MIN_POSITIVE).sqrt())
        .collect();
    let loudest = amps
        .iter()
        .copied()
        .fold(0.0, f64::max)
        .max(f64::MIN_POSITIVE);
    let weights = amps.iter().map(|a| (a / loudest).sqrt()).collect();
    let (lo, hi) = ((nu - NU_DIFFERENCE).max(0.0), nu + NU_DIFFERENCE);
    let reassemble =
        |nu: f64| FemModel::assemble(grid, options.element, nu).map_err(BasisError::from);
    let (k_lo, k_hi) = (reassemble(lo)?, reassemble(hi)?);
    let mut y = vec![0.0; basis.model.dofs()];
    let mut quad = |k: &FemModel, x: &[f64]| {
        sparse::spmv(&k.pattern, k.k(), x, &mut y);
        x.iter().zip(&y).map(|(a, b)| a * b).sum::<f64>()
    };
    let slopes = (0..lambdas.len())
        .map(|i| {
            let phi = basis.solution.vectors.col_as_slice(i);
            let dl = (quad(&k_hi, phi) - quad(&k_lo, phi)) / (hi - lo);
            dl / (2.0 * lambdas[i])
        })
        .collect();
    Ok(Model {
        poisson: nu,
        spectrum: Spectrum { log_hz, weights },
        slopes,
    })
}

/// One Gauss-Newton step and the covariance at the current point.
struct Step {
    ds: f64,
    dnu: f64,
    /// The best `s` change with `nu` held (for the final estimate).
    ds_only: f64,
    sigma_s: f64,
    sigma_nu: f64,
}

/// Weighted least squares on `r_j = ln f_j - (ln f_k(nu) + s)` over the matched pairs, with
/// the Jacobian `(1, d ln f_k / d nu)`.
fn gauss_newton(points: &[Point], model: &Model, pairs: &[(usize, usize)], s: f64) -> Step {
    let (mut a11, mut a12, mut a22, mut b1, mut b2, mut w_sum) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    let mut r2 = 0.0;
    for &(j, k) in pairs {
        let (w, g) = (points[j].weight, model.slopes[k]);
        let r = points[j].log_hz - (model.spectrum.log_hz[k] + s);
        a11 += w;
        a12 += w * g;
        a22 += w * g * g;
        b1 += w * r;
        b2 += w * g * r;
        r2 += w * r * r;
        w_sum += w;
    }
    let det = a11 * a22 - a12 * a12;
    let ds_only = b1 / a11;
    let (ds, dnu) = if det > 1e-12 * a11 * a22.max(f64::MIN_POSITIVE) {
        ((a22 * b1 - a12 * b2) / det, (a11 * b2 - a12 * b1) / det)
    } else {
        (ds_only, 0.0)
    };
    // Residual variance per unit weight, with the weights scaled to sum to the pair count:
    // covariance = sigma^2 (J^T W J)^-1.
    let n = pairs.len() as f64;
    let sigma2 = r2 / w_sum * n / (n - 2.0).max(1.0);
    let scale = w_sum / n;
    let (var_s, var_nu) = if det > 0.0 {
        (sigma2 * a22 / det * scale, sigma2 * a11 / det * scale)
    } else {
        (sigma2 / a11 * scale, f64::INFINITY)
    };
    Step {
        ds,
        dnu,
        ds_only,
        sigma_s: var_s.sqrt(),
        sigma_nu: var_nu.sqrt(),
    }
}

/// Weighted RMS log-frequency error of the matched pairs at `s`.
fn weighted_rms(points: &[Point], model: &Spectrum, pairs: &[(usize, usize)], s: f64) -> f64 {
    let (mut r2, mut w) = (0.0, 0.0);
    for &(j, k) in pairs {
        let r = points[j].log_hz - (model.log_hz[k] + s);
        r2 += points[j].weight * r * r;
        w += points[j].weight;
    }
    (r2 / w).sqrt()
}
