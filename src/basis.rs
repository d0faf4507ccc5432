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
use crate::material::{DampedMode, Material};
use crate::modes::{ModeError, ModeSet};
use crate::shape::lattice_index;
use crate::shape::{ops, ShapeError, VoxelGrid};
use std::sync::Arc;

mod carried;
mod surface;
mod unison;

use surface::{exposed_faces, nearest_face, point_on_face, Face};
pub use surface::{struck_point, StruckPoint};
pub use unison::{strike_align_unisons, UNISON_REL};

/// The nodes of a struck face with their interpolation weights (2x2 for hex8, 3x3 for
/// hex27, up to 3x3x3 for hex27x2, whose element can hold the face inside it), and the face's
/// inward normal.
struct FaceWeights {
    nodes: [(usize, f64); 27],
    len: usize,
    normal: [f64; 3],
}

/// Share of voxels two shapes must have in common (after alignment) for
/// [`ModeBasis::solve_warm`] to start from the earlier one's modes. A sculpting stroke
/// changes a few percent; loading another preset changes most.
pub const WARM_MIN_OVERLAP: f64 = 0.9;

/// What is wrong with a hit (a `Copy` error, so the audio thread can handle it without
/// allocating).
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum HitError {
    /// A coordinate of the hit point is NaN or infinite.
    #[error("hit point {0:?} must be finite")]
    Point([f64; 3]),
    /// The force direction is zero or not finite.
    #[error("force direction {0:?} must be a non-zero finite vector")]
    Direction([f64; 3]),
    /// The shape has no exposed face.
    #[error("the shape has no surface")]
    NoSurface,
}

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

/// A strike: where and in which direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Point in metres from the grid's minimum corner; snapped to the nearest exposed face.
    pub point_m: [f64; 3],
    /// Force direction (normalised internally); `None` pushes into the struck face.
    pub direction: Option<[f64; 3]>,
}

impl Hit {
    /// The default hit of a grid of `dims` voxels of edge `voxel_size_m`: `(0.37, 0.41, 1.0)`
    /// of its bounding box (the top face, off-centre, so that few modes sit on a nodal line;
    /// a solve snaps it to the nearest exposed face), along the face's inward normal.
    pub fn default_for(dims: [usize; 3], voxel_size_m: f64) -> Hit {
        let [nx, ny, nz] = dims;
        Hit {
            point_m: [
                0.37 * nx as f64 * voxel_size_m,
                0.41 * ny as f64 * voxel_size_m,
                nz as f64 * voxel_size_m,
            ],
            direction: None,
        }
    }
}

/// One mode of a struck basis, with everything a caller may report.
#[derive(Clone, Debug, PartialEq)]
pub struct StruckMode {
    /// Undamped natural frequency, Hz.
    pub natural_hz: f64,
    /// Damping outcome.
    pub damped: DampedMode,
    /// Impulse amplitude for the strike.
    pub gain: f64,
    /// Residual of the eigenpair (Jin et al. 2022, eq. 6); `NaN` for an approximate answer
    /// that does not compute it (a predicted or carried one).
    pub residual: f64,
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

    /// Eigenvalue bound in reference units for "every mode below `fmax_hz`" of this material
    /// and voxel size (inverse of the scaling law).
    pub fn reference_bound(material: &Material, voxel_size_m: f64, fmax_hz: f64) -> f64 {
        let w = std::f64::consts::TAU * fmax_hz;
        w * w * material.density_kg_m3 * voxel_size_m * voxel_size_m / material.youngs_modulus_pa
    }

    /// Physical eigenvalues `omega^2` for a material and voxel size (Jin et al. 2020, eq. 12).
    pub fn eigenvalues(&self, material: &Material, voxel_size_m: f64) -> Vec<f64> {
        let s = material.youngs_modulus_pa / (material.density_kg_m3 * voxel_size_m * voxel_size_m);
        self.solution.eigenvalues.iter().map(|l| l * s).collect()
    }

    /// Mass-normalised physical mode values at the hit, dotted with the force direction
    /// (Jin et al. 2020, eq. 7, 10-11), one per mode.
    pub fn modal_forces(
        &self,
        material: &Material,
        voxel_size_m: f64,
        hit: &Hit,
    ) -> Result<Vec<f64>, BasisError> {
        let mut out = vec![0.0; self.mode_count()];
        self.reference_forces_into(hit, voxel_size_m, &mut out)
            .map_err(|e| BasisError::BadHit(e.to_string()))?;
        let scale = 1.0 / (material.density_kg_m3 * voxel_size_m.powi(3)).sqrt();
        out.iter_mut().for_each(|f| *f *= scale);
        Ok(out)
    }

    /// Reference-unit mode values at the hit dotted with the force direction, one per mode,
    /// into `out` (at least as long as the mode count). Multiply by `1 / sqrt(rho h^3)` for
    /// physical units. Never allocates: the engine calls it on the audio thread.
    ///
    /// Modes in unison (eigenvalues within [`UNISON_REL`]: a degenerate pair or multiplet of a
    /// symmetric object) are reported in the basis aligned with the strike
    /// ([`strike_align_unisons`]), so the sound does not depend on which basis of their
    /// eigenspace the solver happened to return.
    pub fn reference_forces_into(
        &self,
        hit: &Hit,
        voxel_size_m: f64,
        out: &mut [f64],
    ) -> Result<(), HitError> {
        self.projected_forces_into(hit, voxel_size_m, out, true)
    }

    /// [`ModeBasis::reference_forces_into`], with unisons merged or (`merge_unisons` false)
    /// each mode's own projection `phi_i(p) . f` in the solver's basis.
    fn projected_forces_into(
        &self,
        hit: &Hit,
        voxel_size_m: f64,
        out: &mut [f64],
        merge_unisons: bool,
    ) -> Result<(), HitError> {
        let face = self.face_weights(hit, voxel_size_m)?;
        let dir = match hit.direction {
            Some(d) => {
                let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                if !(n.is_finite() && n > 0.0) {
                    return Err(HitError::Direction(d));
                }
                [d[0] / n, d[1] / n, d[2] / n]
            }
            None => face.normal,
        };
        let count = self.mode_count().min(out.len());
        match &self.factored {
            Some(factored) => factored.forces_into(&self.model, &face, dir, &mut out[..count]),
            None => {
                let v = &self.solution.vectors;
                for (i, o) in out.iter_mut().take(count).enumerate() {
                    let col = v.col_as_slice(i);
                    *o = face.nodes[..face.len]
                        .iter()
                        .map(|&(node, w)| {
                            w * (0..3).map(|c| col[3 * node + c] * dir[c]).sum::<f64>()
                        })
                        .sum::<f64>();
                }
            }
        }
        if merge_unisons {
            strike_align_unisons(&self.solution.eigenvalues, &mut out[..count]);
        }
        Ok(())
    }

    /// Number of computed (non-rigid) modes.
    pub fn mode_count(&self) -> usize {
        self.solution.eigenvalues.len()
    }

    /// The grid's extent in voxels.
    pub fn grid_dims(&self) -> [usize; 3] {
        self.model.grid_dims()
    }

    /// Applies a material, a voxel size and a strike: every computed mode, damped, with gains.
    pub fn strike(
        &self,
        material: &Material,
        voxel_size_m: f64,
        hit: &Hit,
    ) -> Result<Vec<StruckMode>, BasisError> {
        if (material.poisson_ratio - self.model.poisson_ratio).abs() > 1e-12 {
            return Err(BasisError::PoissonMismatch {
                basis: self.model.poisson_ratio,
                material: material.poisson_ratio,
            });
        }
        let lambdas = self.eigenvalues(material, voxel_size_m);
        let forces = self.modal_forces(material, voxel_size_m, hit)?;
        Ok(lambdas
            .iter()
            .zip(&forces)
            .zip(&self.solution.residuals)
            .map(|((&l, &f), &r)| {
                let damped = material.damping.damp(l);
                let gain = match damped {
                    DampedMode::Oscillating { freq_hz, .. } => {
                        f / (std::f64::consts::TAU * freq_hz)
                    }
                    DampedMode::Overdamped { .. } => 0.0,
                };
                StruckMode {
                    natural_hz: l.sqrt() / std::f64::consts::TAU,
                    damped,
                    gain,
                    residual: r,
                }
            })
            .collect())
    }

    /// The oscillating modes as a [`ModeSet`] for the banks (overdamped ones are left out).
    pub fn mode_set(
        &self,
        material: &Material,
        voxel_size_m: f64,
        hit: &Hit,
    ) -> Result<ModeSet, BasisError> {
        let (mut f, mut d, mut g) = (Vec::new(), Vec::new(), Vec::new());
        for m in self.strike(material, voxel_size_m, hit)? {
            if let DampedMode::Oscillating {
                freq_hz,
                decay_per_s,
            } = m.damped
            {
                f.push(freq_hz);
                d.push(decay_per_s);
                g.push(m.gain);
            }
        }
        Ok(ModeSet::new(f, d, g)?)
    }

    /// Default hit: the exposed face nearest to `(0.37, 0.41, 1.0)` of the bounding box (top,
    /// off-centre, so that few modes sit on a nodal line), struck along its inward normal.
    pub fn default_hit(&self, voxel_size_m: f64) -> Hit {
        Hit::default_for(self.grid_dims(), voxel_size_m)
    }

    /// Nodes and interpolation weights of the exposed face nearest to the hit, and the face's
    /// inward normal. Never allocates.
    fn face_weights(&self, hit: &Hit, voxel_size_m: f64) -> Result<FaceWeights, HitError> {
        if hit.point_m.iter().any(|c| !c.is_finite()) {
            return Err(HitError::Point(hit.point_m));
        }
        let p = hit.point_m.map(|c| c / voxel_size_m);
        let face = nearest_face(&self.surface, p).ok_or(HitError::NoSurface)?;
        let Face {
            voxel: v,
            axis,
            normal,
            ..
        } = face;
        let order = self.model.kind.order();
        let others = [(axis + 1) % 3, (axis + 2) % 3];
        // The struck point on the face, and its coordinates in the element holding the face's
        // voxel (one voxel, or a block of them: then the face may cross the element's inside
        // and every node of the element can carry weight).
        let block = self.model.kind.voxels_per_element();
        let q = point_on_face(&face, p);
        let cell = v.map(|c| c / block);
        let local = |a: usize| ((q[a] - (cell[a] * block) as f64) / block as f64).clamp(0.0, 1.0);
        // Lagrange shape functions along an edge: linear (hex8) or quadratic (hex27).
        let basis = |t: f64| -> [f64; 3] {
            if order == 1 {
                [1.0 - t, t, 0.0]
            } else {
                let x = 2.0 * t - 1.0;
                [x * (x - 1.0) / 2.0, 1.0 - x * x, x * (x + 1.0) / 2.0]
            }
        };
        let (bu, bw, bn) = (
            basis(local(others[0])),
            basis(local(others[1])),
            basis(local(axis)),
        );
        let lattice = self.model.lattice;
        let mut face = FaceWeights {
            nodes: [(0, 0.0); 27],
            len: 0,
            normal: [0.0; 3],
        };
        for (i, &wu) in bu.iter().take(order + 1).enumerate() {
            for (j, &ww) in bw.iter().take(order + 1).enumerate() {
                for (k, &wn) in bn.iter().take(order + 1).enumerate() {
                    if wn == 0.0 {
                        continue;
                    }
                    let mut l = cell.map(|c| order * c);
                    l[others[0]] += i;
                    l[others[1]] += j;
                    l[axis] += k;
                    let node = self.model.lattice_node[lattice_index(l, lattice)];
                    face.nodes[face.len] = (node as usize, wu * ww * wn);
                    face.len += 1;
                }
            }
        }
        face.normal = normal;
        Ok(face)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_strike_inside_a_block_reads_the_element_field_there() {
        // hex27x2: the top face of a one-voxel layer lies halfway up its 2x2x2 block, inside
        // the element. The quadratic shape functions reproduce any linear field exactly, so a
        // "mode" that is the position field (u_c = x_c) read along axis c at a hit gives the
        // struck point's coordinate c: on the face inside the block, and on the bottom face.
        let grid = VoxelGrid::from_fn([4, 4, 3], 1.0, |_, _, z| z < 1.0).unwrap();
        let options = EigenOptions {
            count: eigen::ModeCount::First(3),
            ..Default::default()
        };
        let mut basis = ModeBasis::solve(
            &grid,
            ElementKind::Hex27Blocks,
            0.3,
            SolverKind::Lanczos,
            &options,
        )
        .unwrap();
        let n = basis.model.nodes();
        let mut field = faer::Mat::<f64>::zeros(3 * n, 3);
        for node in 0..n {
            let p = basis.model.node_position(node);
            (0..3).for_each(|c| field[(3 * node + c, c)] = p[c]);
        }
        basis.solution.vectors = field;
        for (aim, lands) in [
            ([1.3, 2.6, 1.7], [1.3, 2.6, 1.0]),
            ([0.7, 3.1, 0.2], [0.7, 3.1, 0.0]),
        ] {
            for c in 0..3 {
                let mut direction = [0.0; 3];
                direction[c] = 1.0;
                let hit = Hit {
                    point_m: aim,
                    direction: Some(direction),
                };
                let mut out = [0.0; 3];
                basis
                    .projected_forces_into(&hit, 1.0, &mut out, false)
                    .unwrap();
                assert!(
                    (out[c] - lands[c]).abs() < 1e-12,
                    "{aim:?} axis {c}: {out:?}"
                );
            }
        }
    }
}
