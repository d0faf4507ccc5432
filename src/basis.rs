//! From a solved shape to the modes the banks play: the size- and material-independent
//! [`ModeBasis`], the scaling laws, and hit-point gains.
//!
//! Where it sits: after [`crate::eigen`], before [`crate::modes::ModeSet`]. The expensive part,
//! [`ModeBasis::solve`], depends only on the voxel pattern, the element and Poisson's ratio; it
//! is solved once in reference units (`E = 1`, `rho = 1`, voxel edge 1) and cached by shape hash.
//! The cheap part, [`ModeBasis::strike`], applies a material, a size and a strike.
//!
//! Scaling (Deep-Modal, Jin et al. 2020, eq. 10-12, in the exact form the FEM gives): the physical
//! matrices are `K = E h K_ref` and `M = rho h^3 M_ref`, so `omega^2 = omega_ref^2 E / (rho h^2)`
//! (eq. 12: `omega ~ sigma1^(1/2) sigma2^(-1/2) sigma3^(-1)`) and the mass-normalised modes are
//! `phi = phi_ref / sqrt(rho h^3)` (eq. 10-11's `sigma2^(-1/2) sigma3^(-3/2)`).
//!
//! Gains (Jin et al. 2020, eq. 7): a unit impulse `f` at a surface point excites mode `i` with
//! amplitude `a_i = phi_i(p) . f / omega_d,i` (the displacement impulse response of a
//! mass-normalised mode), where `phi_i(p)` interpolates the mode over the struck voxel face with
//! the element's own shape functions. By linearity any force is the sum of three unit forces (eq.
//! 7, 9).

use crate::eigen::{self, EigenError, EigenOptions, EigenSolution, SolverKind};
use crate::fem::{ElementCache, ElementKind, FemModel};
use crate::modes::ModeError;
use crate::shape::{ops, ShapeError, VoxelGrid};
use std::sync::Arc;

mod carried;
mod surface;
mod unison;
mod voicing;

use surface::{exposed_faces, Face};
pub use surface::{struck_point, StruckPoint};
pub use unison::{strike_align_unisons, UNISON_REL};
pub use voicing::{Hit, HitError, StruckMode};

/// Share of voxels two shapes must have in common (after alignment) for
/// [`ModeBasis::solve_warm`] to start from the earlier one's modes. A sculpting stroke
/// changes a few percent; loading another preset changes most.
pub const WARM_MIN_OVERLAP: f64 = 0.9;

/// A shape's modes in reference units, reusable for any material (same `nu`), size and strike.
#[derive(Clone, Debug)]
pub struct ModeBasis {
    /// [`VoxelGrid::shape_hash`] of the solved grid.
    pub shape_hash: u64,
    /// The FEM model (node numbering and positions for hit interpolation). An engine's carried
    /// answer's ([`ModeBasis::carried_ritz_factored`]) holds `K` and `M` only near its edit
    /// ([`FemModel::is_whole`]).
    pub model: FemModel,
    /// The eigen-solution in reference units.
    pub solution: EigenSolution,
    /// Face-connected components of the shape.
    pub components: usize,
    /// Assembly time, ms.
    pub assemble_ms: f64,
    /// Solver that produced the solution (`Auto` resolved).
    pub solver: SolverKind,
    /// The shape's exposed voxel faces, found once so that voicing a strike does not rescan
    /// the grid.
    surface: Vec<Face>,
    /// A carried answer's Ritz vectors as factors over the answer it was carried from
    /// ([`ModeBasis::carried_ritz_factored`]); `solution.vectors` then has no columns.
    factored: Option<Arc<carried::Factored>>,
    /// The whole Gram columns the strokes carried from this answer cannot relate
    /// ([`eigen::warm::ExactGrams`]), kept once for them all.
    exact_grams: std::sync::OnceLock<Option<eigen::warm::ExactGrams>>,
    /// A carried answer that kept to the narrow patch where the wide reach would not
    /// ([`ModeBasis::carried_widens`]).
    widens: bool,
}

/// Why a shape could not be solved.
#[derive(Debug, thiserror::Error)]
pub enum BasisError {
    /// The shape is unusable.
    #[error(transparent)]
    Shape(#[from] ShapeError),
    /// The eigensolver failed.
    #[error(transparent)]
    Eigen(#[from] EigenError),
    /// The material is not the one the basis was solved for.
    #[error(
        "the basis was solved for Poisson's ratio {basis}, the material has {material}: re-solve"
    )]
    PoissonMismatch {
        /// Basis nu.
        basis: f64,
        /// Material nu.
        material: f64,
    },
    /// The resulting mode set is invalid (every mode overdamped, say).
    #[error("no playable mode: {0}")]
    Modes(#[from] ModeError),
    /// Bad strike.
    #[error("{0}")]
    BadHit(String),
    /// A progressive coarse answer was asked of an object that halving its resolution would
    /// change too much (walls one voxel thick).
    #[error("the object does not survive halving its resolution; wait for the exact answer")]
    NoCoarseGrid,
    /// An answer that refines an earlier one was asked for with no comparable earlier one.
    #[error("no earlier solution of a similar shape to start from")]
    NoPrevious,
    /// The neural predictor could not answer.
    #[error("{0}")]
    Predictor(String),
    /// A solver panicked on the engine's helper thread and is gone from the chain (a bug:
    /// the other answers still play).
    #[error("the solver stopped unexpectedly; the previous answer keeps playing")]
    SolverLost,
}

impl BasisError {
    /// Whether this is a solve given up at its caller's request
    /// ([`ModeBasis::solve_cached`]), not a failure.
    pub fn is_interrupted(&self) -> bool {
        matches!(self, BasisError::Eigen(EigenError::Interrupted))
    }
}

impl ModeBasis {
    /// Assembles and solves `grid` in reference units.
    pub fn solve(
        grid: &VoxelGrid,
        element: ElementKind,
        poisson_ratio: f64,
        solver: SolverKind,
        options: &EigenOptions,
    ) -> Result<Self, BasisError> {
        let never = eigen::Stop::NEVER;
        Self::solve_cached(grid, element, poisson_ratio, solver, options, None, never)
    }

    /// [`ModeBasis::solve`], assembling with the cut elements kept in `cache`
    /// ([`FemModel::assemble_cached`]) and given up with [`EigenError::Interrupted`] once
    /// `stop` says so (polled after the assembly and between the solver's steps): the
    /// interactive chain's exact answer to an edit, which a newer edit can make obsolete.
    pub fn solve_cached(
        grid: &VoxelGrid,
        element: ElementKind,
        poisson_ratio: f64,
        solver: SolverKind,
        options: &EigenOptions,
        cache: Option<&mut ElementCache>,
        stop: eigen::Stop,
    ) -> Result<Self, BasisError> {
        let t = std::time::Instant::now();
        let model = FemModel::assemble_cached(grid, element, poisson_ratio, cache)?;
        let assemble_ms = t.elapsed().as_secs_f64() * 1e3;
        Self::solve_assembled(grid, model, assemble_ms, solver, options, stop)
    }

    /// The solve of [`ModeBasis::solve_cached`] on a `model` of `grid` assembled already
    /// (in `assemble_ms`): a caller that shares its element cache holds it for the assembly
    /// alone.
    pub fn solve_assembled(
        grid: &VoxelGrid,
        model: FemModel,
        assemble_ms: f64,
        solver: SolverKind,
        options: &EigenOptions,
        stop: eigen::Stop,
    ) -> Result<Self, BasisError> {
        stop.check()?;
        let solution = eigen::solve_until(&model, solver, options, stop)?;
        Ok(Self::from_parts(grid, model, solution, assemble_ms))
    }

    /// Like [`ModeBasis::solve`], refined from `previous` (an earlier edit of the same object)
    /// when the two shapes share at least [`WARM_MIN_OVERLAP`] of their voxels, the element and
    /// Poisson's ratio ([`eigen::warm`]); solved cold otherwise. The result says which
    /// (`solution.warm_start`).
    pub fn solve_warm(
        grid: &VoxelGrid,
        element: ElementKind,
        poisson_ratio: f64,
        solver: SolverKind,
        options: &EigenOptions,
        previous: &ModeBasis,
    ) -> Result<Self, BasisError> {
        let t = std::time::Instant::now();
        let model = FemModel::assemble(grid, element, poisson_ratio)?;
        let assemble_ms = t.elapsed().as_secs_f64() * 1e3;
        let old = &previous.model;
        let comparable = old.kind == element && old.poisson_ratio == poisson_ratio;
        let (offset, overlap) = if comparable {
            eigen::warm::align(old, &model)
        } else {
            ([0; 3], 0)
        };
        let most = model.voxels.len().max(old.voxels.len()) as f64;
        let solution = if comparable && overlap as f64 >= WARM_MIN_OVERLAP * most {
            eigen::warm::solve(&model, old, &previous.solution, offset, options)?
        } else {
            eigen::solve(&model, solver, options)?
        };
        Ok(Self::from_parts(grid, model, solution, assemble_ms))
    }

    /// The instant approximate answer to an edit of `previous` ([`eigen::warm::ritz`]): the
    /// previous modes carried to the new shape and re-balanced by Rayleigh-Ritz, without a
    /// solve. `None` when the shapes are not comparable (see [`ModeBasis::solve_warm`]).
    /// `cache`, when given, keeps cut element matrices between edits
    /// ([`FemModel::assemble_cached`]).
    pub fn carried_ritz(
        grid: &VoxelGrid,
        element: ElementKind,
        poisson_ratio: f64,
        count: usize,
        previous: &ModeBasis,
        cache: Option<&mut ElementCache>,
    ) -> Option<Result<Self, BasisError>> {
        let from = carried::CarriedFrom::Formed(previous);
        Self::carried_with(grid, (element, poisson_ratio), count, from, cache)
    }

    /// [`ModeBasis::carried_ritz`] of `grid` with an element and a Poisson's ratio, its vectors
    /// formed or factored as `from` says.
    fn carried_with(
        grid: &VoxelGrid,
        (element, poisson_ratio): (ElementKind, f64),
        count: usize,
        from: carried::CarriedFrom,
        mut cache: Option<&mut ElementCache>,
    ) -> Option<Result<Self, BasisError>> {
        let previous = from.basis();
        let old = &previous.model;
        if old.kind != element || old.poisson_ratio != poisson_ratio {
            return None;
        }
        let t = std::time::Instant::now();
        // The factored answer reads `K` and `M` only near the edit where the previous answer's
        // whole Gram columns stand for the ones it cannot relate: its model holds no more. (A
        // shape of several parts has none, and is read whole.)
        let near = match &from {
            carried::CarriedFrom::Factored { from, .. }
                if from.exact_grams().is_some_and(|g| g.fits(&from.solution)) =>
            {
                Some(eigen::warm::rows_read_radius_cells(element))
            }
            _ => None,
        };
        let assembled = match near {
            None => FemModel::assemble_after_edit(
                grid,
                element,
                poisson_ratio,
                old,
                cache.as_deref_mut(),
            ),
            Some(r) => FemModel::assemble_near_edit(
                grid,
                element,
                poisson_ratio,
                old,
                cache.as_deref_mut(),
                r,
            ),
        };
        let mut model = match assembled {
            Ok(m) => m,
            Err(e) => return Some(Err(e.into())),
        };
        let assemble_ms = t.elapsed().as_secs_f64() * 1e3;
        let (offset, overlap) = eigen::warm::align(old, &model);
        let most = model.voxels.len().max(old.voxels.len()) as f64;
        if (overlap as f64) < WARM_MIN_OVERLAP * most {
            return None;
        }
        let answer = match from {
            carried::CarriedFrom::Formed(_) => {
                eigen::warm::ritz(&model, old, &previous.solution, offset, count)
                    .map(|solution| (solution, None, false))
            }
            carried::CarriedFrom::Factored { from, reach, stop } => {
                if let Err(e) = stop.check() {
                    return Some(Err(e.into()));
                }
                let how = eigen::warm::Carrying {
                    max_width: carried::MAX_FACTORED_WIDTH,
                    kept: from.exact_grams(),
                    reach,
                    stop,
                };
                let ritz = |model: &FemModel| {
                    eigen::warm::ritz_factored(model, old, &previous.solution, offset, count, &how)
                };
                let mut answer = ritz(&model);
                if matches!(answer, Err(eigen::EigenError::RowsNotHeld)) {
                    // The answer reads beyond the rows held (an edit that is not local, or
                    // no kept Gram columns): the whole model.
                    model = match FemModel::assemble_after_edit(
                        grid,
                        element,
                        poisson_ratio,
                        old,
                        cache,
                    ) {
                        Ok(m) => m,
                        Err(e) => return Some(Err(e.into())),
                    };
                    answer = ritz(&model);
                }
                answer.map(|a| {
                    let rows = a.rows.map(|r| carried::Factored::new(from, r));
                    (a.solution, rows, a.widens)
                })
            }
        };
        Some(
            answer
                .map(|(solution, factored, widens)| {
                    let mut basis =
                        Self::from_parts_with(grid, model, solution, assemble_ms, factored);
                    basis.widens = widens;
                    basis
                })
                .map_err(BasisError::from),
        )
    }

    fn from_parts(
        grid: &VoxelGrid,
        model: FemModel,
        solution: EigenSolution,
        assemble_ms: f64,
    ) -> Self {
        Self::from_parts_with(grid, model, solution, assemble_ms, None)
    }

    fn from_parts_with(
        grid: &VoxelGrid,
        model: FemModel,
        solution: EigenSolution,
        assemble_ms: f64,
        factored: Option<carried::Factored>,
    ) -> Self {
        let mut basis = ModeBasis {
            shape_hash: grid.shape_hash(),
            components: ops::components(grid).1,
            model,
            solver: solution.solver,
            solution,
            assemble_ms,
            surface: exposed_faces(grid),
            factored: factored.map(Arc::new),
            exact_grams: std::sync::OnceLock::new(),
            widens: false,
        };
        basis.orient_to_default_hit();
        basis
    }

    /// An eigenvector has no sign of its own, but a strike's voicing gives each mode the sign
    /// of its modal force, so two close modes ring in or out of phase depending on the signs
    /// the solver happened to return (a whole solve and a class-by-class one,
    /// [`eigen::symmetric`], gave the default bowl's lowest pair, 1.6 Hz apart, opposite
    /// relative signs, which moved its perceived pitch by 0.3 cents). Every mode is turned so
    /// its own modal force at the default hit is positive: there, every mode starts in phase,
    /// as a pickup at the strike point hears them. A mode silent there keeps its sign.
    fn orient_to_default_hit(&mut self) {
        let hit = self.default_hit(1.0);
        let mut forces = vec![0.0; self.mode_count()];
        if self
            .projected_forces_into(&hit, 1.0, &mut forces, false)
            .is_err()
        {
            return;
        }
        for (j, f) in forces.iter().enumerate() {
            if *f < 0.0 {
                match self.factored.as_mut().and_then(Arc::get_mut) {
                    Some(factored) => factored.negate(j),
                    None => (self.solution.vectors.col_mut(j).iter_mut()).for_each(|v| *v = -*v),
                }
            }
        }
    }
}
