//! Eigensolvers for the lowest modes of `K u = lambda M u`.
//!
//! Where it sits: after [`crate::fem`] assembly, before [`crate::basis`] turns eigenpairs into
//! modes. Two solvers share one contract ([`EigenOptions`] in, [`EigenSolution`] or a typed
//! [`EigenError`] out): shift-invert block Lanczos on a sparse Cholesky factorisation
//! ([`lanczos`]), and LOBPCG ([`lobpcg`], Jin et al. 2022, sec. 4.2.4) preconditioned by geometric
//! multigrid on the voxel grid ([`multigrid`]); and, for sculpting edits, LOBPCG with the exact
//! shift-invert preconditioner from the previous shape's modes ([`warm`]). All stop on the
//! residual criterion of
//! NeuralSound (Jin et al. 2022, eq. 6, left term) and report it per mode:
//! `||K v - lambda M v|| / ((||K|| + |lambda| ||M||) ||v||)`, with the matrix 2-norms bounded by
//! their infinity norms (symmetric matrices), which makes the test slightly stricter.
//!
//! A free object has zero-frequency rigid-body modes: 6 per connected part, more where parts
//! touch only along an edge or at a corner. They are found numerically (eigenvalue below
//! [`RIGID_RELATIVE`] times the matrices' scale `trace K / trace M`), never by counting parts,
//! and dropped from the solution.

pub mod band;
pub mod factor;
pub mod lanczos;
pub mod lobpcg;
pub mod multigrid;
mod operators;
mod stop;
pub mod symmetric;
pub mod warm;

pub(crate) use operators::{from_rows, to_rows};
pub use operators::{Operators, Which};
pub use stop::Stop;

use crate::fem::FemModel;
use faer::Mat;

/// Eigenvalues below this fraction of `trace K / trace M` are rigid-body modes. A shift-invert
/// solve returns them at ~1e-16 of that scale; the softest real mode of a 256-voxel-long bar sits
/// near 1e-8 of it.
pub const RIGID_RELATIVE: f64 = 1e-10;

/// Default residual tolerance (Jin et al. 2022, eq. 6): the papers' 32^3 benchmark uses 1e-6.
pub const DEFAULT_TOLERANCE: f64 = 1e-6;

/// Hard cap on the number of modes one solve returns.
pub const MAX_MODES: usize = 4000;

/// How many modes to compute.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ModeCount {
    /// The lowest `k` non-rigid modes.
    First(usize),
    /// Every non-rigid mode with eigenvalue (reference units) at or below this.
    Below(f64),
}

/// Which eigensolver (command-line names from the `clap::ValueEnum` derive; `Display` prints
/// the same name).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SolverKind {
    /// Shift-invert block Lanczos on a sparse Cholesky factorisation.
    Lanczos,
    /// LOBPCG with a geometric multigrid preconditioner.
    Lobpcg,
    /// LOBPCG for models of at least [`AUTO_LOBPCG_DOFS`] DOFs asked for at most
    /// [`AUTO_LOBPCG_MAX_MODES`] modes at a residual it reaches (>= 1e-7); Lanczos otherwise.
    /// Measured by `cargo bench --bench eigen -- --table` (figures in the README's Benchmarks
    /// section): LOBPCG is about 3x faster on a solid 32^3 sphere, where Lanczos' factor
    /// dominates, and slower on shells and for many modes. Where LOBPCG stalls (`NoConvergence`: its multigrid
    /// coarsens cut voxels as whole ones, and about one generated object in twenty stalled at a
    /// residual of 1e-3), Auto solves again by Lanczos.
    /// A mirror-symmetric model up to [`AUTO_CLASSES_MAX_DOFS`] goes to Lanczos class by class
    /// instead of LOBPCG.
    #[value(
        help = "LOBPCG from 30k DOFs for up to 100 modes, else Lanczos; Lanczos by symmetry classes for mirror-symmetric objects (measured)"
    )]
    Auto,
}

/// [`SolverKind::Auto`] picks LOBPCG from this many DOFs up.
pub const AUTO_LOBPCG_DOFS: usize = 30_000;

/// Where [`SolverKind::Auto`] would pick LOBPCG, a mirror-symmetric model up to this many
/// DOFs is solved by Lanczos class by class instead ([`symmetric`]). Measured (stop 46, hex8i
/// solid spheres, residual 1e-6, one core): 32^3 (65k DOFs) 1.3 s against LOBPCG's 3.1 s for
/// 20 modes and 2.1 against 16.9 s for 60; 40^3 (122k DOFs) 4.1 against 5.4 s for 20. Larger
/// solids were not measured: LOBPCG's cost grows more slowly than the classes' factors.
pub const AUTO_CLASSES_MAX_DOFS: usize = 125_000;

/// [`SolverKind::Auto`] picks Lanczos above this many modes (LOBPCG's Rayleigh-Ritz grows with
/// the square of the block).
pub const AUTO_LOBPCG_MAX_MODES: usize = 100;

impl std::fmt::Display for SolverKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        crate::cli_name(self, f)
    }
}

impl SolverKind {
    /// The solver `Auto` stands for on a model of `dofs` DOFs (the others stand for themselves).
    /// "Modes below f_max" counts as many modes unless the model is large.
    pub fn resolve(self, dofs: usize, options: &EigenOptions) -> SolverKind {
        if self != SolverKind::Auto {
            return self;
        }
        let few_modes = match options.count {
            ModeCount::First(k) => k <= AUTO_LOBPCG_MAX_MODES,
            ModeCount::Below(_) => true,
        };
        if dofs >= AUTO_LOBPCG_DOFS && few_modes && options.tolerance >= 1e-7 {
            SolverKind::Lobpcg
        } else {
            SolverKind::Lanczos
        }
    }
}

/// Solver settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EigenOptions {
    /// How many modes.
    pub count: ModeCount,
    /// Residual tolerance (Jin et al. 2022, eq. 6).
    pub tolerance: f64,
    /// Block size (vectors advanced together).
    pub block_size: usize,
    /// Cap on restarts (Lanczos) or iterations (LOBPCG).
    pub max_iterations: usize,
}

impl Default for EigenOptions {
    fn default() -> Self {
        EigenOptions {
            count: ModeCount::First(20),
            tolerance: DEFAULT_TOLERANCE,
            block_size: 8,
            max_iterations: 200,
        }
    }
}

/// Where a solve spent its time, in milliseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SolveTimings {
    /// Factorisation (Lanczos) or preconditioner setup (LOBPCG).
    pub setup_ms: f64,
    /// Iterations.
    pub iterate_ms: f64,
}

/// The lowest non-rigid eigenpairs.
#[derive(Clone, Debug)]
pub struct EigenSolution {
    /// Eigenvalues `omega^2` (reference units), ascending.
    pub eigenvalues: Vec<f64>,
    /// M-orthonormal eigenvectors, one column each; none where a carried answer keeps them
    /// as factors ([`warm::ritz_factored`]).
    pub vectors: Mat<f64>,
    /// Residual (Jin et al. 2022, eq. 6) of each pair; `NaN` where it was not computed (the
    /// instant carried answer, [`warm::ritz`]).
    pub residuals: Vec<f64>,
    /// Number of zero-frequency (rigid-body) modes found and dropped.
    pub rigid_modes: usize,
    /// Time split.
    pub timings: SolveTimings,
    /// Restarts (Lanczos) or iterations (LOBPCG) used.
    pub iterations: usize,
    /// The solver that produced it (LOBPCG hands tiny models to Lanczos).
    pub solver: SolverKind,
    /// Whether it was refined from a previous shape's modes ([`warm`]) rather than solved
    /// from scratch.
    pub warm_start: bool,
    /// The solver's next Ritz vectors above the returned modes (not converged; may be empty):
    /// a warm start of the next edit starts its guard columns from them ([`warm`]), so the
    /// highest wanted modes converge as fast as the lowest.
    pub guard_vectors: Mat<f64>,
    /// Each guard vector's eigenvalue where it is a converged eigenpair too (solved to the
    /// solve's tolerance, beyond the request: a symmetry class's modes above the lowest `k`),
    /// `NaN` where it is a Ritz vector only: the instant answer takes a converged guard's
    /// products from its eigen relation instead of multiplying it out ([`warm`]).
    pub guard_eigenvalues: Vec<f64>,
    /// The same guards' residuals (eq. 6), `NaN` where not converged.
    pub guard_residuals: Vec<f64>,
    /// The rigid-body modes found (M-orthonormal, one column each; `rigid_modes` of them): a
    /// warm start carries them for objects whose parts touch only along edges or corners,
    /// which have more than the six rigid motions of a whole. None where a carried answer
    /// keeps its vectors as factors ([`warm::ritz_factored`]): it is never a warm start.
    pub rigid_vectors: Mat<f64>,
}

/// Frees the work buffers the solvers keep between solves (Cholesky factors, their scratch,
/// Lanczos bases: 64 MB at most for each element type unless [`keep_buffers_up_to`] raised
/// it). Nothing needs to call it: the next solve reuses them. A memory measurement that must
/// not depend on which objects were solved last does (the soak).
pub fn free_kept_buffers() {
    crate::buffer::free_kept();
}

/// Keeps up to `bytes` of the solvers' work buffers for each element type between solves,
/// instead of 64 MB: for a process of its own that solves large objects one after another
/// (`modalforge dataset`), whose whole factors would otherwise come back as fresh memory each
/// time (`buffer.rs`, `set_kept_bytes`). A plugin keeps the default.
pub fn keep_buffers_up_to(bytes: usize) {
    crate::buffer::set_kept_bytes(bytes);
}

/// Guard vectors a solution keeps for warm starts, for `need` wanted pairs (rigid included).
pub fn warm_guard(need: usize) -> usize {
    (need / 2).max(8)
}

/// Why a solve failed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum EigenError {
    /// The shifted matrix could not be factored.
    #[error("sparse Cholesky factorisation failed: {0}")]
    Factorization(String),
    /// The iteration ran out before the wanted modes converged.
    #[error(
        "eigensolver did not converge: {converged} of {wanted} modes reached the residual \
         tolerance (worst {worst_residual:.2e}); ask for fewer modes or a looser --tolerance"
    )]
    NoConvergence {
        /// Modes converged.
        converged: usize,
        /// Modes wanted.
        wanted: usize,
        /// Worst residual among the wanted.
        worst_residual: f64,
    },
    /// Too few degrees of freedom for the request.
    #[error("the object has only {dofs} degrees of freedom, too few for {wanted} modes plus its rigid-body modes")]
    TooFewDofs {
        /// Degrees of freedom.
        dofs: usize,
        /// Modes wanted.
        wanted: usize,
    },
    /// A non-finite number appeared.
    #[error("the eigensolver produced a non-finite value: the model is ill-conditioned")]
    NonFinite,
    /// The Krylov basis kept losing rank (it spans nearly the whole space).
    #[error("the Krylov basis lost rank repeatedly; ask for fewer modes (the object has few degrees of freedom)")]
    Breakdown,
    /// The request itself is invalid.
    #[error("invalid eigen request: {0}")]
    BadRequest(String),
    /// A carried answer needs rows of `K` and `M` that its model, assembled only near the edit
    /// ([`crate::fem::FemModel::assemble_near_edit`]), does not hold: assemble the whole model.
    #[error("the model holds K and M only near the edit, and this answer reads rows beyond it")]
    RowsNotHeld,
    /// The caller's [`Stop`] asked the solve to give up (a newer edit superseded it).
    #[error("the solve was interrupted: a newer request superseded it")]
    Interrupted,
}

/// Solves with the chosen solver.
pub fn solve(
    model: &FemModel,
    solver: SolverKind,
    options: &EigenOptions,
) -> Result<EigenSolution, EigenError> {
    solve_until(model, solver, options, Stop::NEVER)
}

/// [`solve`], giving up with [`EigenError::Interrupted`] once `stop` says so.
pub fn solve_until(
    model: &FemModel,
    solver: SolverKind,
    options: &EigenOptions,
    stop: Stop,
) -> Result<EigenSolution, EigenError> {
    if options.block_size == 0 || !(options.tolerance > 0.0 && options.tolerance < 1.0) {
        return Err(EigenError::BadRequest(format!(
            "block size {} and tolerance {} (tolerance must lie in (0, 1))",
            options.block_size, options.tolerance
        )));
    }
    match options.count {
        ModeCount::First(0) => {
            return Err(EigenError::BadRequest("ask for at least one mode".into()))
        }
        ModeCount::First(k) if k > MAX_MODES => {
            return Err(EigenError::BadRequest(format!(
                "{k} modes is over the limit of {MAX_MODES}"
            )))
        }
        ModeCount::Below(l) if !(l.is_finite() && l > 0.0) => {
            return Err(EigenError::BadRequest(format!(
                "eigenvalue bound {l} must be positive"
            )))
        }
        _ => {}
    }
    // hex27x2: LOBPCG's multigrid (its first coarse level is hex8 on the blocks, twice the
    // voxel) preconditions it poorly: the 24^3 sphere, 34k DOFs, 60 modes took 16.6 s against
    // Lanczos' 5.5 s. Auto answers it by Lanczos, and by LOBPCG only where the factor is
    // refused for its size.
    if solver == SolverKind::Auto && model.kind == crate::fem::ElementKind::Hex27Blocks {
        return match lanczos_solve(model, options, stop) {
            Err(EigenError::Factorization(_)) => lobpcg::solve_until(model, options, stop),
            answer => answer,
        };
    }
    match solver.resolve(model.dofs(), options) {
        // Auto's LOBPCG can stall where its multigrid (built from whole voxels) preconditions a
        // cut object badly; Auto then answers by Lanczos rather than fail. A mirror-symmetric
        // model goes to Lanczos class by class first: its classes' factors are small.
        SolverKind::Lobpcg if solver == SolverKind::Auto => {
            if model.dofs() <= AUTO_CLASSES_MAX_DOFS {
                match symmetric::solve_until(model, options, stop) {
                    Some(Ok(answer)) => return Ok(answer),
                    Some(Err(EigenError::Interrupted)) => return Err(EigenError::Interrupted),
                    // Not symmetric, or its classes failed (a factor refused): LOBPCG.
                    _ => {}
                }
            }
            match lobpcg::solve_until(model, options, stop) {
                Err(EigenError::NoConvergence { .. }) => lanczos_solve(model, options, stop),
                answer => answer,
            }
        }
        SolverKind::Lobpcg => lobpcg::solve_until(model, options, stop),
        _ => lanczos_solve(model, options, stop),
    }
}

/// Lanczos, class by class where the model is mirror-symmetric ([`symmetric`]), else on the
/// whole model.
fn lanczos_solve(
    model: &FemModel,
    options: &EigenOptions,
    stop: Stop,
) -> Result<EigenSolution, EigenError> {
    symmetric::solve_until(model, options, stop)
        .unwrap_or_else(|| lanczos::solve_until(model, options, stop))
}

/// A deterministic pseudo-random start block, entries uniform in `[-0.5, 0.5)`, so solves are
/// reproducible.
pub(crate) fn random_block(n: usize, b: usize, seed: u64) -> Mat<f64> {
    let mut rng = crate::rng::SplitMix64::new(seed);
    Mat::from_fn(n, b, |_, _| rng.unit() - 0.5)
}

/// Dense symmetric eigendecomposition, eigenvalues ascending.
pub(crate) fn sym_eigen(h: &Mat<f64>) -> Result<(Vec<f64>, Mat<f64>), EigenError> {
    let n = h.nrows();
    let sym = Mat::from_fn(n, n, |i, j| 0.5 * (h[(i, j)] + h[(j, i)]));
    if sym.col_iter().any(|c| c.iter().any(|v| !v.is_finite())) {
        return Err(EigenError::NonFinite);
    }
    let evd = sym
        .self_adjoint_eigen(faer::Side::Lower)
        .map_err(|_| EigenError::NonFinite)?;
    let s = evd.S().column_vector();
    Ok(((0..n).map(|i| s[i]).collect(), evd.U().to_owned()))
}

/// Which converged pairs a solve returns.
pub(crate) struct Selection {
    /// Indices into the pairs: non-rigid, within the count.
    pub keep: Vec<usize>,
    /// Rigid-body modes among the pairs.
    pub rigid: usize,
    /// Whether the request is met: `k` non-rigid modes, or a converged mode above the bound.
    pub complete: bool,
}

/// Picks the converged pairs to return: drops rigid modes, applies the count.
pub(crate) fn select(
    ops: &Operators,
    pairs: &[(f64, usize, f64)], // (lambda, column, residual), ascending, all converged
    count: ModeCount,
) -> Selection {
    let rigid = pairs.iter().filter(|p| ops.is_rigid(p.0)).count();
    let keep: Vec<usize> = pairs
        .iter()
        .enumerate()
        .filter(|(_, p)| !ops.is_rigid(p.0))
        .filter(|(_, p)| match count {
            ModeCount::First(_) => true,
            ModeCount::Below(l) => p.0 <= l,
        })
        .map(|(i, _)| i)
        .collect();
    let (keep, complete) = match count {
        ModeCount::First(k) => (keep.into_iter().take(k).collect::<Vec<_>>(), false),
        ModeCount::Below(limit) => {
            let above = pairs.iter().any(|p| p.0 > limit && !ops.is_rigid(p.0));
            (keep, above)
        }
    };
    let complete = complete || matches!(count, ModeCount::First(k) if keep.len() >= k);
    Selection {
        keep,
        rigid,
        complete,
    }
}

/// The solution made of the selected pairs; `x` holds the pairs' vectors by column.
pub(crate) fn solution(
    pairs: &[(f64, usize, f64)],
    selection: &Selection,
    x: faer::MatRef<'_, f64>,
    timings: SolveTimings,
    iterations: usize,
    solver: SolverKind,
) -> EigenSolution {
    let keep = &selection.keep;
    // Guards: the columns after the last kept pair's, at most `warm_guard` of them.
    let after = keep.iter().map(|&i| pairs[i].1 + 1).max().unwrap_or(0);
    let guards = x
        .ncols()
        .saturating_sub(after)
        .min(warm_guard(selection.rigid + keep.len()));
    // The guards that are converged pairs (beyond the request) keep their eigenvalues.
    let guard_pairs: Vec<(f64, f64)> = (after..after + guards)
        .map(|c| {
            let pair = pairs.iter().find(|p| p.1 == c);
            pair.map_or((f64::NAN, f64::NAN), |p| (p.0, p.2))
        })
        .collect();
    // Pairs are ascending, so the rigid ones (eigenvalue ~0) come first.
    let rigid_columns: Vec<usize> = pairs.iter().take(selection.rigid).map(|p| p.1).collect();
    EigenSolution {
        rigid_vectors: Mat::from_fn(x.nrows(), rigid_columns.len(), |i, j| {
            x[(i, rigid_columns[j])]
        }),
        guard_vectors: x.get(.., after..after + guards).to_owned(),
        guard_eigenvalues: guard_pairs.iter().map(|p| p.0).collect(),
        guard_residuals: guard_pairs.iter().map(|p| p.1).collect(),
        eigenvalues: keep.iter().map(|&i| pairs[i].0).collect(),
        vectors: Mat::from_fn(x.nrows(), keep.len(), |i, j| x[(i, pairs[keep[j]].1)]),
        residuals: keep.iter().map(|&i| pairs[i].2).collect(),
        rigid_modes: selection.rigid,
        timings,
        iterations,
        solver,
        warm_start: false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_picks_lobpcg_only_for_large_models_few_modes_and_reachable_tolerances() {
        let opts = |count, tolerance| EigenOptions {
            count,
            tolerance,
            ..Default::default()
        };
        let auto = |dofs, o: &EigenOptions| SolverKind::Auto.resolve(dofs, o);
        let twenty = opts(ModeCount::First(20), 1e-6);
        assert_eq!(auto(59_367, &twenty), SolverKind::Lobpcg);
        assert_eq!(auto(15_501, &twenty), SolverKind::Lanczos);
        assert_eq!(
            auto(59_367, &opts(ModeCount::First(200), 1e-6)),
            SolverKind::Lanczos
        );
        assert_eq!(
            auto(59_367, &opts(ModeCount::First(20), 1e-9)),
            SolverKind::Lanczos
        );
        assert_eq!(
            auto(59_367, &opts(ModeCount::Below(1.0), 1e-6)),
            SolverKind::Lobpcg
        );
        assert_eq!(
            SolverKind::Lanczos.resolve(1 << 30, &twenty),
            SolverKind::Lanczos
        );
    }
}
