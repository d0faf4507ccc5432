//! The worker's interactive solver chain: exact modes at the speed of sculpting.
//!
//! Where it sits: [`super::worker`] runs a chain of [`ModeSolver`]s for every edit and plays
//! each answer as it arrives. [`interactive_solvers`] builds the chain the plugin uses:
//! 1. [`CoarseFemSolver`], the progressive first answer: when the exact solve is predicted to
//!    take longer than [`PROGRESSIVE_BUDGET_MS`] and the edit cannot be warm-started, the
//!    object resampled to half the resolution with its fills kept ([`coarse_grid`]) is solved
//!    first (4-6x fewer DOFs) and played, with its expected error in the status
//!    ([`coarse_expected_error`]: larger for one-voxel walls);
//! 2. [`CarriedRitzSolver`], the instant answer to a brush stroke: the last exact modes
//!    carried to the edited shape and re-balanced by one Rayleigh-Ritz step (milliseconds, no
//!    factorisation; frequencies within [`CARRIED_EXPECTED_ERROR`]);
//! 3. [`IncrementalFemSolver`], the exact answer (a cold solve: the warm-started exact solve,
//!    [`ModeBasis::solve_warm`], measured slower; ARCHITECTURE.md); it keeps the answer for
//!    the next stroke's carried answer.
//!
//! All three share the last exact basis (a coarse or carried answer never becomes the start of
//! another) and the cut element matrices of recent assemblies ([`crate::fem::ElementCache`]).
//! A request whose exact answer is kept ([`KeptAnswers`], shared by every chain the plugin
//! starts) is answered by it at once, and the faster answers step aside.

use super::answers::KeptAnswers;
use super::object::ObjectModes;
use super::worker::{ModeSolver, ObjectRequest};
use crate::basis::{BasisError, ModeBasis, WARM_MIN_OVERLAP};
use crate::eigen::{ModeCount, Stop};
use crate::fem::{ElementCache, ElementKind};
use crate::predictor::Predictor;
use crate::shape::fill::{fill_of, FULL, SUBCELLS, SUBCELLS_PER_AXIS};
use crate::shape::{lattice_coords, lattice_index, ops, VoxelFill, VoxelGrid};
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::{Arc, Mutex};

/// An exact solve predicted to take longer than this (ms) gets a coarse answer first.
pub const PROGRESSIVE_BUDGET_MS: f64 = 100.0;

/// Predicted one-core time of a cold exact solve of an object without mirrors, ms per DOF
/// per wanted pair (modes plus six rigid): the default bowl solved whole (hex27x2, 60 modes,
/// as a stroke off its planes leaves it) takes 0.72e-3 ([`predicted_cold_ms`] divides by
/// [`MIRROR_SPEEDUP`] for mirrored ones); an estimate for scheduling, not a promise.
const COLD_MS_PER_DOF_PAIR: f64 = 0.7e-3;

/// How much faster a cold solve is with 0, 1, 2 or 3 mirror planes (solved by symmetry
/// classes, `eigen/symmetric.rs`). Measured side by side with whole solves (hex27x2, 60
/// modes): two mirrors (and the bowls' axis swap) 2.8-3.4x (the bell, the default bowl),
/// three 6.5x (a 16-voxel sphere); but 4 fits the cold times of the three-mirror presets and
/// the 24^3 sphere (`cargo bench --bench interactive`, stop 59: within 0.8-1.3x of the
/// estimate), whose classes are smaller and pay more overhead each. One mirror between.
const MIRROR_SPEEDUP: [f64; 4] = [1.0, 1.7, 3.0, 4.0];

/// Predicted cold solve time of `grid` (ms, one core) for `count` modes with `element`:
/// DOFs estimated from the voxel count, the mirrors from the fills ([`grid_mirrors`]).
/// Against `cargo bench --bench interactive` on the presets (stop 59): the tin can, the
/// glass bowl and vase, the ceramic cup and the bell (0.11-0.36 s cold) are predicted over
/// 100 ms (115-345 ms); the ones solved under 100 ms at 29-75 ms.
pub fn predicted_cold_ms(grid: &VoxelGrid, element: ElementKind, count: ModeCount) -> f64 {
    // Nodes of a voxel object: about the voxel count plus its surface layer.
    let voxels = grid.count() as f64;
    let dofs = 3.0 * (voxels + 2.0 * voxels.powf(2.0 / 3.0) + voxels / 2.0);
    let pairs = match count {
        ModeCount::First(k) => k as f64 + 6.0,
        ModeCount::Below(_) => 66.0,
    };
    COLD_MS_PER_DOF_PAIR * dofs * pairs / MIRROR_SPEEDUP[grid_mirrors(grid, element)]
}

/// How many of the three axes `grid` is mirror-symmetric along, fill for fill (a partial
/// voxel's sub-cells mirrored too), about the centre of its solid voxels' bounding box, with
/// `element`'s blocks mapped onto blocks (hex27x2's start at the grid's origin, so the box's
/// first and last voxel indices must add up to an odd number). The eigensolver finds its
/// mirrors on the assembled matrices (`eigen/symmetric.rs`); this is the cheap look at the
/// voxels that the time estimate needs before any assembly.
pub fn grid_mirrors(grid: &VoxelGrid, element: ElementKind) -> usize {
    let solid = grid.solid_voxels();
    if solid.is_empty() {
        return 0;
    }
    let lo: [usize; 3] = std::array::from_fn(|a| solid.iter().map(|v| v[a]).min().unwrap_or(0));
    let hi: [usize; 3] = std::array::from_fn(|a| solid.iter().map(|v| v[a]).max().unwrap_or(0));
    let block = element.voxels_per_element();
    let sub = [SUBCELLS_PER_AXIS; 3];
    (0..3)
        .filter(|&a| {
            if block > 1 && (lo[a] + hi[a]) % block != block - 1 {
                return false;
            }
            solid.iter().all(|v| {
                let mut m = *v;
                m[a] = lo[a] + hi[a] - v[a];
                let at = |c: [usize; 3]| grid.fill_at(c[0] as isize, c[1] as isize, c[2] as isize);
                match (at(*v), at(m)) {
                    (VoxelFill::Partial(f), VoxelFill::Partial(g)) => (0..SUBCELLS).all(|i| {
                        let mut s = lattice_coords(i, sub);
                        s[a] = sub[a] - 1 - s[a];
                        f.0[i] == g.0[lattice_index(s, sub)]
                    }),
                    (f, g) => f == g,
                }
            })
        })
        .count()
}

/// Mean frequency error of the coarse answer's lowest 10 modes on objects whose walls are
/// thicker than [`THIN_WALL_VOXELS`], for the status line ([`coarse_expected_error`]).
/// Measured by `cargo bench --bench interactive` and a side-by-side harness (hex27x2, 60
/// modes): a 24^3 sphere 0.0 %, a 32-voxel bowl with a 4-voxel wall 0.8 %, a 10x12x16 box
/// 0.4 %, the default bowl and the bell (2-voxel walls, curved) 3.3 % and 3.7 %.
pub const COARSE_EXPECTED_ERROR: f64 = 0.05;

/// [`COARSE_EXPECTED_ERROR`] for walls at most [`THIN_WALL_VOXELS`] thick: the elements of the
/// half-resolution grid are four wall thicknesses across, so bending comes out stiff. The
/// same measurement: the glass bowl 10.5 %, the aluminium plate 8.2 %, the brass gong 8.1 %,
/// the tin can 14.1 %, the glass vase 13.6 %, the ceramic cup 14.2 %, the plastic crate
/// 13.3 %.
pub const COARSE_THIN_EXPECTED_ERROR: f64 = 0.15;

/// Mean wall thickness ([`mean_wall_voxels`]) at or under which [`coarse_expected_error`]
/// says [`COARSE_THIN_EXPECTED_ERROR`]: the one-voxel walls of the presets measure 0.78-1.0,
/// the two-voxel curved ones 1.2-1.3.
pub const THIN_WALL_VOXELS: f64 = 1.1;

/// The coarse answer's expected error for `grid` (see [`COARSE_EXPECTED_ERROR`]).
pub fn coarse_expected_error(grid: &VoxelGrid) -> f64 {
    if mean_wall_voxels(grid) <= THIN_WALL_VOXELS {
        COARSE_THIN_EXPECTED_ERROR
    } else {
        COARSE_EXPECTED_ERROR
    }
}

/// An object's mean wall thickness in voxels, `2 V / A`: twice its filled volume over its
/// surface area, both counted on the voxel fills (the area as the fill's jumps between
/// neighbouring voxels along each axis). A plate or a shell of thickness `t` gives about `t`.
pub fn mean_wall_voxels(grid: &VoxelGrid) -> f64 {
    let d = grid.dims().map(|v| v as isize);
    let f = |x, y, z| grid.fraction(x, y, z);
    let (mut volume, mut area) = (0.0, 0.0);
    for z in -1..=d[2] {
        for y in -1..=d[1] {
            for x in -1..=d[0] {
                let here = f(x, y, z);
                volume += here;
                area += (f(x + 1, y, z) - here).abs()
                    + (f(x, y + 1, z) - here).abs()
                    + (f(x, y, z + 1) - here).abs();
            }
        }
    }
    2.0 * volume / area.max(1.0)
}

/// Typical largest relative frequency error of the carried answer to a one-voxel stroke, for
/// the status line: `cargo bench --bench interactive` measures 1e-5 to 1.3e-2 on the presets
/// (3e-3 at most before curved objects kept partial voxels: a stroke next to cut voxels moves
/// more of the stiffness; a stroke that opens a hole in a one-voxel wall can do worse until
/// the exact answer lands).
pub const CARRIED_EXPECTED_ERROR: f64 = 1e-2;

/// The last exact basis, shared by the chain.
type Shared = Arc<Mutex<Option<Arc<ModeBasis>>>>;

/// The cut element matrices of recent assemblies, shared by the chain's FEM answers: a
/// stroke's carried answer, its exact solve and the next stroke's reuse every cut element the
/// stroke did not touch ([`crate::fem::cache`]).
type SharedElements = Arc<Mutex<ElementCache>>;

fn elements(shared: &SharedElements) -> std::sync::MutexGuard<'_, ElementCache> {
    shared.lock().unwrap_or_else(|e| e.into_inner())
}

/// `grid` resampled to half the resolution (the voxel edge doubles, the extent stays), its
/// fills kept: each coarse voxel's sub-cells ([`SUBCELLS_PER_AXIS`] a side) hold the mean of
/// the `2^3` fine sub-cells they cover, summed in integers so that mirror-image voxels get
/// the same bytes (and the coarse model keeps the object's mirrors). The geometry is the
/// fine grid's at half the sub-cell resolution, so a wall one voxel thick stays one voxel
/// thick (half of a coarse voxel), where thresholding whole voxels would make it two or
/// nothing. `None` where the coarse grid would join parts the fine one keeps apart (its
/// face-connected components, counted on the voxels, differ: the answer would have the wrong
/// rigid-body modes) or is empty.
pub fn coarse_grid(grid: &VoxelGrid) -> Option<VoxelGrid> {
    let d = grid.dims();
    let cd = d.map(|v| v.div_ceil(2));
    let sub = [SUBCELLS_PER_AXIS; 3];
    let mut coarse = VoxelGrid::new(cd, 2.0 * grid.voxel_size_m()).ok()?;
    for c in (0..cd.iter().product()).map(|i| lattice_coords(i, cd)) {
        // Sums of the covered fine sub-cells' bytes (a full voxel's are FULL).
        let mut sums = [0u32; SUBCELLS];
        for o in 0..8 {
            let off = lattice_coords(o, [2; 3]);
            let [x, y, z] = std::array::from_fn(|a| (2 * c[a] + off[a]) as isize);
            let bytes = match grid.fill_at(x, y, z) {
                VoxelFill::Empty => continue,
                VoxelFill::Full => [FULL; SUBCELLS],
                VoxelFill::Partial(f) => f.0,
            };
            for (i, &b) in bytes.iter().enumerate() {
                let s = lattice_coords(i, sub);
                let coarse_cell = std::array::from_fn(|a| (off[a] * sub[a] + s[a]) / 2);
                sums[lattice_index(coarse_cell, sub)] += u32::from(b);
            }
        }
        let fill = fill_of(sums.map(|v| f64::from(v) / (8.0 * f64::from(FULL))));
        coarse.set_fill(c[0], c[1], c[2], fill);
    }
    (coarse.count() > 0 && ops::components(&coarse).1 == ops::components(grid).1).then_some(coarse)
}

/// Whether `request` is an edit of `previous` that the carried answer serves: the same element
/// and Poisson's ratio, and (after alignment) at least [`WARM_MIN_OVERLAP`] of the voxels in
/// common, the criterion [`ModeBasis::carried_ritz`] applies.
fn warm_candidate(previous: &ModeBasis, request: &ObjectRequest) -> bool {
    let old = &previous.model;
    if old.kind != request.element || old.poisson_ratio != request.poisson_ratio {
        return false;
    }
    let next = crate::fem::element_cells(&request.grid, request.element);
    let (_, overlap) = crate::eigen::warm::align_voxels(&old.voxels, old.cell_dims(), &next);
    overlap as f64 >= WARM_MIN_OVERLAP * next.len().max(old.voxels.len()) as f64
}

/// The exact FEM answer, from the kept answers when the same request was solved before; it
/// keeps the last one for the chain's faster answers to start from.
pub struct IncrementalFemSolver {
    last: Shared,
    elements: SharedElements,
    kept: KeptAnswers,
    answers: AnswerSwitch,
}

impl IncrementalFemSolver {
    /// A solver with no previous answer.
    pub fn new() -> Self {
        IncrementalFemSolver {
            last: Arc::new(Mutex::new(None)),
            elements: SharedElements::default(),
            kept: KeptAnswers::new(),
            answers: AnswerSwitch::default(),
        }
    }
}

impl Default for IncrementalFemSolver {
    fn default() -> Self {
        Self::new()
    }
}

fn lock(shared: &Shared) -> std::sync::MutexGuard<'_, Option<Arc<ModeBasis>>> {
    shared.lock().unwrap_or_else(|e| e.into_inner())
}

impl ModeSolver for IncrementalFemSolver {
    fn name(&self) -> &'static str {
        "fem"
    }

    fn applies(&self, _r: &ObjectRequest) -> bool {
        self.answers.get() != Answers::PredictorOnly
    }

    fn solve(&mut self, r: &ObjectRequest) -> Result<ObjectModes, BasisError> {
        self.solve_until(r, Stop::NEVER)
    }

    fn solve_until(&mut self, r: &ObjectRequest, stop: Stop) -> Result<ObjectModes, BasisError> {
        // A warm-started exact solve (`ModeBasis::solve_warm`) converges in 2-8 LOBPCG
        // iterations, but they cost about as much as the whole Lanczos solve on the same
        // factor: measured slower on most objects of `cargo bench --bench interactive`. The
        // exact answer is solved cold; the instant answer to a stroke comes from
        // `CarriedRitzSolver`.
        let basis = match self.kept.find(r) {
            Some(basis) => basis,
            None => {
                let basis = Arc::new(ModeBasis::solve_cached(
                    &r.grid,
                    r.element,
                    r.poisson_ratio,
                    r.solver,
                    &r.options,
                    Some(&mut elements(&self.elements)),
                    stop,
                )?);
                self.kept.keep(r, &basis);
                basis
            }
        };
        *lock(&self.last) = Some(basis.clone());
        Ok(ObjectModes::Fem(basis))
    }
}

fn count_of(r: &ObjectRequest) -> usize {
    match r.options.count {
        ModeCount::First(k) => k,
        ModeCount::Below(_) => 0,
    }
}

/// The progressive first answer: the object at half resolution (see the module docs).
pub struct CoarseFemSolver {
    last: Shared,
    elements: SharedElements,
    kept: KeptAnswers,
    answers: AnswerSwitch,
}

impl ModeSolver for CoarseFemSolver {
    fn name(&self) -> &'static str {
        "coarse"
    }

    fn applies(&self, r: &ObjectRequest) -> bool {
        if self.answers.get() == Answers::PredictorOnly || self.kept.has(r) {
            return false;
        }
        if let Some(p) = lock(&self.last).as_ref() {
            if warm_candidate(p, r) {
                return false;
            }
        }
        predicted_cold_ms(&r.grid, r.element, r.options.count) > PROGRESSIVE_BUDGET_MS
            && coarse_grid(&r.grid).is_some()
    }

    fn expected_error(&self, r: &ObjectRequest) -> Option<f64> {
        Some(coarse_expected_error(&r.grid))
    }

    fn solve(&mut self, r: &ObjectRequest) -> Result<ObjectModes, BasisError> {
        self.solve_until(r, Stop::NEVER)
    }

    fn solve_until(&mut self, r: &ObjectRequest, stop: Stop) -> Result<ObjectModes, BasisError> {
        let grid = coarse_grid(&r.grid).ok_or(BasisError::NoCoarseGrid)?;
        ModeBasis::solve_cached(
            &grid,
            r.element,
            r.poisson_ratio,
            r.solver,
            &r.options,
            Some(&mut elements(&self.elements)),
            stop,
        )
        .map(|b| ObjectModes::Fem(Arc::new(b)))
    }
}

/// The instant answer to a brush stroke: the last exact modes carried to the edited shape and
/// re-balanced by Rayleigh-Ritz ([`ModeBasis::carried_ritz`]), while the exact solve runs.
pub struct CarriedRitzSolver {
    last: Shared,
    elements: SharedElements,
    kept: KeptAnswers,
    answers: AnswerSwitch,
}

impl ModeSolver for CarriedRitzSolver {
    fn name(&self) -> &'static str {
        "carried"
    }

    fn applies(&self, r: &ObjectRequest) -> bool {
        self.answers.get() != Answers::PredictorOnly
            && carried_applies(&self.last, r)
            && !self.kept.has(r)
    }

    fn expected_error(&self, _request: &ObjectRequest) -> Option<f64> {
        Some(CARRIED_EXPECTED_ERROR)
    }

    fn solve(&mut self, r: &ObjectRequest) -> Result<ObjectModes, BasisError> {
        let previous = lock(&self.last).clone().ok_or(BasisError::NoPrevious)?;
        ModeBasis::carried_ritz(
            &r.grid,
            r.element,
            r.poisson_ratio,
            count_of(r),
            &previous,
            Some(&mut elements(&self.elements)),
        )
        .unwrap_or(Err(BasisError::NoPrevious))
        .map(|b| ObjectModes::Fem(Arc::new(b)))
    }
}

/// Whether the carried answer serves `r`: a stroke (a changed shape) on the last exact answer.
fn carried_applies(last: &Shared, r: &ObjectRequest) -> bool {
    matches!(r.options.count, ModeCount::First(_))
        && lock(last)
            .as_ref()
            .is_some_and(|p| warm_candidate(p, r) && p.shape_hash != r.grid.shape_hash())
}

/// Which answers the chain gives ([`AnswerSwitch`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Answers {
    /// The predictor's instant answer (or a carried or coarse one), then the exact FEM answer.
    Auto,
    /// FEM only: carried or coarse answers, then the exact one.
    FemOnly,
    /// The predictor only (no FEM solve at all).
    PredictorOnly,
}

/// The chain's [`Answers`] setting, shared with whoever changes it (the plugin's parameter):
/// the solvers read it in [`ModeSolver::applies`], so it takes effect from the next edit.
#[derive(Clone, Debug, Default)]
pub struct AnswerSwitch(Arc<AtomicU8>);

impl AnswerSwitch {
    /// Sets the answers the chain gives.
    pub fn set(&self, answers: Answers) {
        self.0.store(answers as u8, Ordering::Relaxed);
    }

    /// The current setting.
    pub fn get(&self) -> Answers {
        match self.0.load(Ordering::Relaxed) {
            1 => Answers::FemOnly,
            2 => Answers::PredictorOnly,
            _ => Answers::Auto,
        }
    }
}

/// Typical frequency error of the predictor's answer, for the status line: the held-out median
/// pitch error of the shipped predictor (network and pitch index), 26.2 cents (`modalforge
/// predictor eval`; `assets/predictor/README.md`), as a ratio (`2^(26.2 / 1200) - 1`).
pub const NEURAL_EXPECTED_ERROR: f64 = 0.015;

/// The neural predictor's answer (issue 12): milliseconds for any shape in the 32^3 box. It
/// answers an edit the carried answer does not serve (a new shape, a large edit, the first
/// object); the exact answer replaces it.
pub struct NeuralSolver {
    predictor: Arc<Predictor>,
    last: Shared,
    kept: KeptAnswers,
    answers: AnswerSwitch,
}

impl ModeSolver for NeuralSolver {
    fn name(&self) -> &'static str {
        "neural"
    }

    fn applies(&self, r: &ObjectRequest) -> bool {
        match self.answers.get() {
            Answers::FemOnly => false,
            Answers::PredictorOnly => true,
            Answers::Auto => !carried_applies(&self.last, r) && !self.kept.has(r),
        }
    }

    fn expected_error(&self, _request: &ObjectRequest) -> Option<f64> {
        Some(NEURAL_EXPECTED_ERROR)
    }

    fn solve(&mut self, r: &ObjectRequest) -> Result<ObjectModes, BasisError> {
        self.predictor
            .predict(&r.grid)
            .map(|p| ObjectModes::Predicted(Box::new(p)))
            .map_err(|e| BasisError::Predictor(e.to_string()))
    }
}

/// The plugin's chain, sharing the last exact answer and `kept` (exact answers to earlier
/// requests, [`super::answers`]; the plugin passes one per process): [`NeuralSolver`] when a predictor is
/// given (else [`CoarseFemSolver`] for slow cold solves), [`CarriedRitzSolver`] (brush
/// strokes), then [`IncrementalFemSolver`] (exact). `answers` selects among them at run time.
pub fn interactive_solvers(
    predictor: Option<Arc<Predictor>>,
    answers: AnswerSwitch,
    kept: &KeptAnswers,
) -> Vec<Box<dyn ModeSolver>> {
    let exact = IncrementalFemSolver {
        last: Arc::new(Mutex::new(None)),
        elements: SharedElements::default(),
        kept: kept.clone(),
        answers: answers.clone(),
    };
    let first: Box<dyn ModeSolver> = match predictor {
        Some(predictor) => Box::new(NeuralSolver {
            predictor,
            last: exact.last.clone(),
            kept: kept.clone(),
            answers: answers.clone(),
        }),
        None => Box::new(CoarseFemSolver {
            last: exact.last.clone(),
            elements: exact.elements.clone(),
            kept: kept.clone(),
            answers: answers.clone(),
        }),
    };
    let carried = CarriedRitzSolver {
        last: exact.last.clone(),
        elements: exact.elements.clone(),
        kept: kept.clone(),
        answers,
    };
    vec![first, Box::new(carried), Box::new(exact)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eigen::{EigenOptions, SolverKind};
    use crate::fem::ElementKind;
    use crate::shape::primitives::Primitive;

    #[test]
    fn a_strokes_answers_reuse_the_cut_elements_of_the_last_exact_answer() {
        // The chain's wiring: the carried and exact answers to a stroke assemble from the
        // cache the previous exact answer filled, re-integrating only what the stroke touched
        // (at most the 27 elements whose input holds the voxel; `fem::cache` checks that the
        // cached model equals the uncached one).
        let grid = Primitive::Bowl {
            diameter: 12.0,
            wall: 2.0,
        }
        .rasterize(1.0, 1.0)
        .unwrap();
        let request = |grid: VoxelGrid| ObjectRequest {
            grid,
            element: ElementKind::Hex27Blocks,
            poisson_ratio: 0.24,
            solver: SolverKind::Auto,
            options: EigenOptions {
                count: ModeCount::First(10),
                ..EigenOptions::default()
            },
            recording: None,
        };
        let mut exact = IncrementalFemSolver::new();
        let mut carried = CarriedRitzSolver {
            last: exact.last.clone(),
            elements: exact.elements.clone(),
            kept: exact.kept.clone(),
            answers: AnswerSwitch::default(),
        };
        exact.solve(&request(grid.clone())).unwrap();
        let cold = elements(&exact.elements).stats();
        assert!(cold.misses > 50, "{cold:?}");
        let (i, _) = grid.partial_voxels().next().unwrap();
        let v = crate::shape::lattice_coords(i, grid.dims());
        let mut edited = grid.clone();
        edited.set(v[0], v[1], v[2], true);
        let stroke = request(edited);
        assert!(carried.applies(&stroke));
        carried.solve(&stroke).unwrap();
        let after = elements(&exact.elements).stats();
        assert!(after.misses <= 27, "{after:?}");
        assert!(
            after.hits + 27 >= cold.hits + cold.misses,
            "{after:?} after {cold:?}"
        );
        exact.solve(&stroke).unwrap();
        assert_eq!(elements(&exact.elements).stats().misses, 0);
    }

    #[test]
    fn a_second_chain_sharing_kept_answers_plays_the_same_object_without_a_solve() {
        // Two plugin instances (two chains) with one store of kept answers: the second asks
        // for the first's object and gets the very same answer (no solve: its own element
        // cache stays empty). Undo back to the first shape on the first chain is answered the
        // same way, and the carried answer, which would otherwise serve it, steps aside.
        let kept = KeptAnswers::new();
        let chain = || {
            let exact = IncrementalFemSolver {
                last: Arc::new(Mutex::new(None)),
                elements: SharedElements::default(),
                kept: kept.clone(),
                answers: AnswerSwitch::default(),
            };
            let carried = CarriedRitzSolver {
                last: exact.last.clone(),
                elements: exact.elements.clone(),
                kept: kept.clone(),
                answers: AnswerSwitch::default(),
            };
            (exact, carried)
        };
        let grid = Primitive::Sphere { diameter: 10.0 }
            .rasterize(1.0, 1.0)
            .unwrap();
        let request = |grid: VoxelGrid| ObjectRequest {
            grid,
            element: ElementKind::Hex8Incompatible,
            poisson_ratio: 0.3,
            solver: SolverKind::Auto,
            options: EigenOptions {
                count: ModeCount::First(20),
                ..EigenOptions::default()
            },
            recording: None,
        };
        let (mut first, mut first_carried) = chain();
        let ObjectModes::Fem(a) = first.solve(&request(grid.clone())).unwrap() else {
            panic!("FEM")
        };
        let (mut second, _) = chain();
        let ObjectModes::Fem(b) = second.solve(&request(grid.clone())).unwrap() else {
            panic!("FEM")
        };
        assert!(Arc::ptr_eq(&a, &b), "the same answer, shared");
        assert_eq!(elements(&second.elements).stats().entries, 0, "no assembly");
        // A stroke on the first chain is new (carried, then exact); undoing it is not.
        let mut edited = grid.clone();
        let (i, _) = grid.partial_voxels().next().unwrap();
        let v = crate::shape::lattice_coords(i, grid.dims());
        edited.set(v[0], v[1], v[2], true);
        assert!(first_carried.applies(&request(edited.clone())));
        first_carried.solve(&request(edited.clone())).unwrap();
        first.solve(&request(edited)).unwrap();
        assert!(!first_carried.applies(&request(grid.clone())), "undo: kept");
        let ObjectModes::Fem(c) = first.solve(&request(grid.clone())).unwrap() else {
            panic!("FEM")
        };
        assert!(Arc::ptr_eq(&a, &c));
    }
}
