//! The worker's interactive solver chain: exact modes at the speed of sculpting.
//!
//! Where it sits: [`super::worker`] runs a chain of [`ModeSolver`]s for every edit and plays
//! each answer as it arrives. [`interactive_solvers`] builds the chain the plugin uses:
//! 1. [`CoarseFemSolver`], the progressive first answer: when the exact solve is predicted to
//!    take longer than [`PROGRESSIVE_BUDGET_MS`] and the edit cannot be warm-started, the
//!    object resampled to half the resolution with its fills kept ([`coarse_grid`]) is solved
//!    first (4-6x fewer DOFs), its known stiffening divided out ([`solve_coarse`],
//!    `solvers/coarse.rs`), and played, with its expected error in the status
//!    ([`coarse_expected_error`]: larger for one-voxel walls);
//! 2. [`CarriedRitzSolver`], the instant answer to a brush stroke: the last exact modes
//!    carried to the edited shape and re-balanced by one Rayleigh-Ritz step (milliseconds, no
//!    factorisation; frequencies within [`CARRIED_EXPECTED_ERROR`]), its vectors kept as
//!    factors over the last exact answer ([`ModeBasis::carried_ritz_factored`]);
//! 3. [`CarriedRitzSolver::wide`], the second answer to a stroke on a large object (one whose
//!    exact answer a drag never finishes): the same carried answer relaxed over the wide patch
//!    at any size ([`ModeBasis::carried_ritz_wide`]), where the instant one kept to the narrow
//!    patch for its size; several times closer after a drag's strokes, at about twice the
//!    time, and interrupted by the next stroke;
//! 4. [`IncrementalFemSolver`], the exact answer (a cold solve: the warm-started exact solve,
//!    [`ModeBasis::solve_warm`], measured slower; ARCHITECTURE.md); it keeps the answer for
//!    the next stroke's carried answer. A drag interrupts it at every stroke; once it has
//!    been interrupted, its next run on an object it solves within
//!    [`REFRESH_MAX_PREDICTED_MS`] is finished beside the newer strokes
//!    ([`ModeSolver::finish_when_left`]), so their carried answers start from a recent shape.
//!
//! All four share the last exact basis (a coarse or carried answer never becomes the start of
//! another) and the cut element matrices of recent assemblies ([`crate::fem::ElementCache`]).
//! A request whose exact answer is kept ([`KeptAnswers`], shared by every chain the plugin
//! starts) is answered by it at once, and the faster answers step aside.

use super::answers::KeptAnswers;
use super::object::ObjectModes;
use super::worker::{ModeSolver, ObjectRequest};
use crate::basis::{BasisError, ModeBasis, WARM_MIN_OVERLAP};
use crate::eigen::warm::Reach;
use crate::eigen::{ModeCount, Stop};
use crate::fem::{ElementCache, FemModel};
use crate::predictor::Predictor;
use crate::shape::VoxelGrid;
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::{Arc, Mutex};

mod coarse;

use coarse::{solve_coarse_grid, CoarsePlan};

pub use coarse::{
    coarse_expected_error, coarse_grid, coarse_stiffening, grid_mirrors, mean_wall_voxels,
    predicted_cold_ms, solve_coarse, COARSE_EXPECTED_ERROR, COARSE_THIN_EXPECTED_ERROR,
    PROGRESSIVE_BUDGET_MS, THIN_WALL_VOXELS,
};

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
    /// Runs started since one last answered (the others were interrupted by newer edits).
    unanswered_runs: usize,
}

impl IncrementalFemSolver {
    /// A solver with no previous answer.
    pub fn new() -> Self {
        IncrementalFemSolver {
            last: Arc::new(Mutex::new(None)),
            elements: SharedElements::default(),
            kept: KeptAnswers::new(),
            answers: AnswerSwitch::default(),
            unanswered_runs: 0,
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

    /// Its steps that poll no stop (the elimination order, 17 ms on the ceramic cup's whole
    /// object; the assembly; a symmetry class's reduction) take tens of milliseconds at most.
    /// Its factorisation, which polls every few milliseconds since stop 66, was one uncut
    /// step before: 40-95 ms on the default object after a stroke that breaks its mirrors,
    /// 0.5-0.7 s on the ceramic cup (measured in the worker during `cargo bench --bench
    /// interactive -- --drag`).
    fn detachable(&self) -> bool {
        true
    }

    /// A drag keeps interrupting the exact solve, and every carried answer then starts from
    /// the exact answer before the drag, further from it with every stroke (on the default
    /// object a drag of 24 strokes played answers a median 2.1e-2 off in their worst mode,
    /// 36 cents; `cargo bench --bench interactive -- --drag 60`). Once
    /// [`REFRESH_AFTER_INTERRUPTED`] runs in a row were interrupted, a run on an edit of the
    /// last exact answer (one the carried answer serves) whose cold solve is predicted within
    /// [`REFRESH_MAX_PREDICTED_MS`] finishes even when a newer stroke comes: its answer is not
    /// played, but the next strokes' carried answers start from it (the same drag: 7.4-7.7e-3,
    /// and 4.9e-3 since the carried answer also holds the patch's own modes).
    fn finish_when_left(&self, r: &ObjectRequest) -> bool {
        self.unanswered_runs >= REFRESH_AFTER_INTERRUPTED
            && lock(&self.last)
                .as_ref()
                .is_some_and(|p| warm_candidate(p, r))
            && predicted_cold_ms(&r.grid, r.element, r.options.count) <= REFRESH_MAX_PREDICTED_MS
    }

    fn solve(&mut self, r: &ObjectRequest) -> Result<ObjectModes, BasisError> {
        self.solve_until(r, Stop::NEVER)
    }

    fn solve_until(&mut self, r: &ObjectRequest, stop: Stop) -> Result<ObjectModes, BasisError> {
        self.unanswered_runs += 1;
        // A warm-started exact solve (`ModeBasis::solve_warm`) converges in 2-8 LOBPCG
        // iterations, but they cost about as much as the whole Lanczos solve on the same
        // factor: measured slower on most objects of `cargo bench --bench interactive`. The
        // exact answer is solved cold; the instant answer to a stroke comes from
        // `CarriedRitzSolver`.
        let basis = match self.kept.find(r) {
            Some(basis) => basis,
            None => {
                // The element cache is held for the assembly alone: the chain's faster
                // answers to a newer edit assemble beside a run of this solver left to end
                // on the worker's helper thread.
                let t = std::time::Instant::now();
                let model = FemModel::assemble_cached(
                    &r.grid,
                    r.element,
                    r.poisson_ratio,
                    Some(&mut elements(&self.elements)),
                )?;
                let assemble_ms = t.elapsed().as_secs_f64() * 1e3;
                let basis = Arc::new(ModeBasis::solve_assembled(
                    &r.grid,
                    model,
                    assemble_ms,
                    r.solver,
                    &r.options,
                    stop,
                )?);
                // What the strokes carried from this answer read in place of whole products
                // (`eigen/warm/exact_grams.rs`): a few products over the mesh, here rather
                // than in the first stroke's answer.
                if matches!(r.options.count, ModeCount::First(_)) {
                    basis.exact_grams();
                }
                self.kept.keep(r, &basis);
                basis
            }
        };
        *lock(&self.last) = Some(basis.clone());
        self.unanswered_runs = 0;
        Ok(ObjectModes::Fem(basis))
    }
}

/// Interrupted exact runs after which [`IncrementalFemSolver`] finishes one that a newer
/// stroke makes obsolete ([`ModeSolver::finish_when_left`]). Measured on the default object
/// (a drag of 30 strokes every 60 ms, the worst mode's error of the answers played, median):
/// after 0, 1 and 2 interrupted runs 8.7e-3, 7.4e-3 and 7.6e-3 to 1.1e-2, against 2.4e-2
/// with every obsolete run stopped.
pub const REFRESH_AFTER_INTERRUPTED: usize = 1;

/// The longest exact solve ([`predicted_cold_ms`]) that [`IncrementalFemSolver`] finishes
/// beside a drag's newer strokes. A stroke breaks the default object's mirrors, and its
/// whole solve (predicted 0.23 s, measured 0.2-0.26 s) is finished; one on the glass vase or
/// bowl, the bell or the ceramic cup (predicted 0.6-1.4 s) would leave its carried answers
/// as stale when it lands, and beside the drag it slows them (two solves share the memory
/// bus): those runs stop as before.
pub const REFRESH_MAX_PREDICTED_MS: f64 = 500.0;

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
    /// What [`ModeSolver::applies`] found for the last object it offered an answer to, which
    /// `solve` and `expected_error` then read instead of resampling and rescanning the grid
    /// (on the large presets 3-5 ms for [`coarse_grid`] and 2-3 ms for the wall thickness,
    /// each, before the first sound).
    plan: Mutex<Option<CoarsePlan>>,
}

impl CoarseFemSolver {
    fn new(
        last: Shared,
        elements: SharedElements,
        kept: KeptAnswers,
        answers: AnswerSwitch,
    ) -> Self {
        Self {
            last,
            elements,
            kept,
            answers,
            plan: Mutex::new(None),
        }
    }

    /// The plan for `grid`: the kept one where it was made for this grid, else a new one.
    fn plan_for(plan: &mut Option<CoarsePlan>, grid: &VoxelGrid) -> Option<CoarsePlan> {
        match plan.take() {
            Some(p) if p.fine == *grid => Some(p),
            _ => CoarsePlan::new(grid),
        }
    }
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
        if predicted_cold_ms(&r.grid, r.element, r.options.count) <= PROGRESSIVE_BUDGET_MS {
            return false;
        }
        let mut plan = self.plan.lock().unwrap_or_else(|e| e.into_inner());
        *plan = Self::plan_for(&mut plan, &r.grid);
        plan.is_some()
    }

    fn expected_error(&self, r: &ObjectRequest) -> Option<f64> {
        let plan = self.plan.lock().unwrap_or_else(|e| e.into_inner());
        Some(match plan.as_ref() {
            Some(p) if p.fine == r.grid => p.expected_error,
            _ => coarse_expected_error(&r.grid),
        })
    }

    fn solve(&mut self, r: &ObjectRequest) -> Result<ObjectModes, BasisError> {
        self.solve_until(r, Stop::NEVER)
    }

    fn solve_until(&mut self, r: &ObjectRequest, stop: Stop) -> Result<ObjectModes, BasisError> {
        let plan = self.plan.get_mut().unwrap_or_else(|e| e.into_inner());
        *plan = Self::plan_for(plan, &r.grid);
        let p = plan.as_ref().ok_or(BasisError::NoCoarseGrid)?;
        solve_coarse_grid(
            &p.coarse,
            p.stiffening,
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

/// The carried answers to a brush stroke: the last exact modes carried to the edited shape and
/// re-balanced by Rayleigh-Ritz ([`ModeBasis::carried_ritz`]), while the exact solve runs.
/// Two of them in the chain, by how far their relaxation reaches ([`Reach`]):
/// - the instant answer ([`CarriedRitzSolver::instant`], "carried"): every stroke, the patch
///   sized for its time;
/// - the second answer ([`CarriedRitzSolver::wide`], "carried-wide"), played after the
///   instant one where that kept to the narrow patch for its size
///   ([`ModeBasis::carried_ritz_wide`]), on objects whose exact answer a drag never finishes
///   ([`predicted_cold_ms`] over [`REFRESH_MAX_PREDICTED_MS`]: the glass vase, the glass bowl,
///   the bell, the ceramic cup). There every stroke of a drag is carried from the exact answer
///   before the drag, and the narrow patch's error grows with the strokes (the cup's worst
///   mode 2e-4 after one, 3e-2 after twelve), while the wide reach stays several times closer.
///   On a smaller object the exact solver's refresh keeps the carried answers' start recent
///   ([`ModeSolver::finish_when_left`]), and a second answer would only start it later. It
///   polls the worker's stop between its phases, so a newer stroke is answered at once.
pub struct CarriedRitzSolver {
    last: Shared,
    elements: SharedElements,
    kept: KeptAnswers,
    answers: AnswerSwitch,
    reach: Reach,
    /// The shape the instant answer last kept to the narrow patch for, where the wide reach
    /// would relax a wider one ([`ModeBasis::carried_widens`]): the wide answer answers it.
    /// Shared by the chain's two carried answers.
    widens: Arc<Mutex<Option<u64>>>,
}

impl CarriedRitzSolver {
    /// The instant answer, sharing the exact solver's last answer and element cache.
    pub fn instant(exact: &IncrementalFemSolver, answers: AnswerSwitch) -> Self {
        CarriedRitzSolver {
            last: exact.last.clone(),
            elements: exact.elements.clone(),
            kept: exact.kept.clone(),
            answers,
            reach: Reach::Sized,
            widens: Arc::default(),
        }
    }

    /// The second answer to the strokes the `instant` one answers.
    pub fn wide(instant: &CarriedRitzSolver) -> Self {
        CarriedRitzSolver {
            last: instant.last.clone(),
            elements: instant.elements.clone(),
            kept: instant.kept.clone(),
            answers: instant.answers.clone(),
            reach: Reach::Wide,
            widens: instant.widens.clone(),
        }
    }

    fn widens(&self) -> std::sync::MutexGuard<'_, Option<u64>> {
        self.widens.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// Typical largest relative frequency error of the wide carried answer, for the status line.
/// `cargo bench --bench interactive -- --drag 150 --only NAME` (24 strokes, each answer
/// scored by its worst of 60 modes against the exact modes of its shape), median / largest:
/// the ceramic cup 2.9e-3 / 5.7e-3, the glass vase 2.4e-3 / 5.3e-3, the glass bowl 1.4e-3 /
/// 3.9e-3, the bell 1.2e-2 / 1.8e-2 (the instant answers: 2.8e-2, 1.1e-2, 1.4e-2 and 2.1e-2
/// median). A single stroke's is 1e-4 to 1e-3.
pub const WIDE_CARRIED_EXPECTED_ERROR: f64 = 5e-3;

impl ModeSolver for CarriedRitzSolver {
    fn name(&self) -> &'static str {
        match self.reach {
            Reach::Sized => "carried",
            Reach::Wide => "carried-wide",
        }
    }

    /// Cheap for the wide answer's extra conditions: the instant answer has just said whether
    /// a wider patch exists, and the exact solve's prediction reads the grid's voxel count.
    fn applies(&self, r: &ObjectRequest) -> bool {
        let wide_worth_it = || {
            *self.widens() == Some(r.grid.shape_hash())
                && predicted_cold_ms(&r.grid, r.element, r.options.count) > REFRESH_MAX_PREDICTED_MS
        };
        self.answers.get() != Answers::PredictorOnly
            && (self.reach == Reach::Sized || wide_worth_it())
            && carried_applies(&self.last, r)
            && !self.kept.has(r)
    }

    fn expected_error(&self, _request: &ObjectRequest) -> Option<f64> {
        Some(match self.reach {
            Reach::Sized => CARRIED_EXPECTED_ERROR,
            Reach::Wide => WIDE_CARRIED_EXPECTED_ERROR,
        })
    }

    fn solve(&mut self, r: &ObjectRequest) -> Result<ObjectModes, BasisError> {
        self.solve_until(r, Stop::NEVER)
    }

    /// The instant answer polls no stop (it is the quickest answer a stroke has); the wide
    /// one polls between its phases.
    fn solve_until(&mut self, r: &ObjectRequest, stop: Stop) -> Result<ObjectModes, BasisError> {
        let previous = lock(&self.last).clone().ok_or(BasisError::NoPrevious)?;
        let cache = Some(&mut *elements(&self.elements));
        let (grid, element, nu, count) = (&r.grid, r.element, r.poisson_ratio, count_of(r));
        // Its vectors stay factors over the last exact answer: a strike reads a face's rows
        // of them (`basis/carried.rs`).
        let answer = match self.reach {
            Reach::Sized => {
                ModeBasis::carried_ritz_factored(grid, element, nu, count, &previous, cache)
            }
            Reach::Wide => {
                ModeBasis::carried_ritz_wide(grid, element, nu, count, &previous, cache, stop)
            }
        }
        .unwrap_or(Err(BasisError::NoPrevious))?;
        if self.reach == Reach::Sized {
            *self.widens() = answer.carried_widens().then(|| r.grid.shape_hash());
        }
        Ok(ObjectModes::Fem(Arc::new(answer)))
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
/// given (else [`CoarseFemSolver`] for slow cold solves), [`CarriedRitzSolver`]'s two answers
/// (brush strokes: the instant one, and the wide one on the large objects), then
/// [`IncrementalFemSolver`] (exact). `answers` selects among them at run time.
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
        unanswered_runs: 0,
    };
    let first: Box<dyn ModeSolver> = match predictor {
        Some(predictor) => Box::new(NeuralSolver {
            predictor,
            last: exact.last.clone(),
            kept: kept.clone(),
            answers: answers.clone(),
        }),
        None => Box::new(CoarseFemSolver::new(
            exact.last.clone(),
            exact.elements.clone(),
            kept.clone(),
            answers.clone(),
        )),
    };
    let carried = CarriedRitzSolver::instant(&exact, answers);
    let wide = CarriedRitzSolver::wide(&carried);
    vec![first, Box::new(carried), Box::new(wide), Box::new(exact)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eigen::{EigenOptions, SolverKind};
    use crate::fem::ElementKind;
    use crate::shape::primitives::Primitive;
    use crate::shape::VoxelGrid;

    /// A hex27x2 request for the lowest `modes` modes of `grid`.
    fn request(grid: VoxelGrid, poisson_ratio: f64, modes: usize) -> ObjectRequest {
        ObjectRequest {
            grid,
            element: ElementKind::Hex27Blocks,
            poisson_ratio,
            solver: SolverKind::Auto,
            options: EigenOptions {
                count: ModeCount::First(modes),
                ..EigenOptions::default()
            },
            recording: None,
        }
    }

    /// A 12-voxel bowl, walls of 2.
    fn small_bowl() -> VoxelGrid {
        Primitive::Bowl {
            diameter: 12.0,
            wall: 2.0,
        }
        .rasterize(1.0, 1.0)
        .unwrap()
    }

    /// `grid` with its `k`-th partial voxel filled: a one-voxel stroke.
    fn stroked(grid: &VoxelGrid, k: usize) -> VoxelGrid {
        let (i, _) = grid.partial_voxels().nth(k).unwrap();
        let v = crate::shape::lattice_coords(i, grid.dims());
        let mut edited = grid.clone();
        edited.set(v[0], v[1], v[2], true);
        edited
    }

    #[test]
    fn a_strokes_answers_reuse_the_cut_elements_of_the_last_exact_answer() {
        // The chain's wiring: the carried and exact answers to a stroke assemble from the
        // cache the previous exact answer filled, re-integrating only what the stroke touched
        // (at most the 27 elements whose input holds the voxel; `fem::cache` checks that the
        // cached model equals the uncached one). The carried answer copies the rows away from
        // the stroke from the previous model (`fem::assembly::reuse`), so it reads fewer
        // elements than the object has; the exact answer reads them all.
        let grid = small_bowl();
        let request = |grid: VoxelGrid| request(grid, 0.24, 10);
        let mut exact = IncrementalFemSolver::new();
        let mut carried = CarriedRitzSolver::instant(&exact, AnswerSwitch::default());
        exact.solve(&request(grid.clone())).unwrap();
        let cold = elements(&exact.elements).stats();
        assert!(cold.misses > 50, "{cold:?}");
        let stroke = request(stroked(&grid, 0));
        assert!(carried.applies(&stroke));
        carried.solve(&stroke).unwrap();
        let after = elements(&exact.elements).stats();
        assert!(after.misses <= 27, "{after:?}");
        assert!(
            after.hits + after.misses < cold.hits + cold.misses,
            "{after:?} after {cold:?}"
        );
        exact.solve(&stroke).unwrap();
        let whole = elements(&exact.elements).stats();
        assert_eq!(whole.misses, 0);
        assert!(
            whole.hits + 27 >= cold.hits + cold.misses,
            "{whole:?} after {cold:?}"
        );
    }

    #[test]
    fn the_wide_answer_follows_the_instant_one_on_a_large_object_and_gives_way() {
        // The glass vase preset's shape (15.7k DOFs; a stroke's whole exact solve is predicted
        // over `REFRESH_MAX_PREDICTED_MS`), one partial voxel filled: the instant answer keeps
        // to the narrow patch (the wide one is 1,281 DOFs, over `WIDE_PATCH_MAX_DOFS`) and says
        // so, and only then does the wide answer apply. A stop at any of its polls ends it
        // with `Interrupted`; run out, it answers the same stroke with the same mode count.
        // On the small bowl (its exact answer refreshed during drags) it never applies.
        let kind = ElementKind::Hex27Blocks;
        let vase = crate::shape::spec::primitive_voxels(
            &Primitive::Cup {
                diameter: 16.0,
                height: 24.0,
                wall: 1.0,
            },
            None,
            1.0,
            kind.voxels_per_element(),
        )
        .unwrap();
        let solvers = interactive_solvers(None, AnswerSwitch::default(), &KeptAnswers::new());
        let [_, mut carried, mut wide, mut exact]: [Box<dyn ModeSolver>; 4] =
            solvers.try_into().ok().unwrap();
        assert_eq!(wide.name(), "carried-wide");
        for (grid, nu, large) in [(vase, 0.22, true), (small_bowl(), 0.24, false)] {
            exact.solve(&request(grid.clone(), nu, 60)).unwrap();
            let stroke = request(stroked(&grid, 0), nu, 60);
            assert!(!wide.applies(&stroke), "before the instant answer");
            let first = carried.solve(&stroke).unwrap();
            assert_eq!(wide.applies(&stroke), large);
            if !large {
                continue;
            }
            // A stop at each of its polls in turn (the assembly, the Gram matrices, the
            // patch's factor and each step of its modes, the dense problem) ends it there.
            let mut polls_before_stop = 0;
            let second = loop {
                let polls = std::cell::Cell::new(0);
                let stop_at = || {
                    polls.set(polls.get() + 1);
                    polls.get() > polls_before_stop
                };
                match wide.solve_until(&stroke, Stop::when(&stop_at)) {
                    Err(e) => assert!(e.is_interrupted(), "{e} after {polls_before_stop} polls"),
                    Ok(answer) => break answer,
                }
                polls_before_stop += 1;
            };
            assert!(polls_before_stop >= 5, "polled {polls_before_stop} times");
            assert_eq!(second.mode_count(), first.mode_count());
            // A newer stroke: the last one's verdict no longer applies.
            let next = request(stroked(&stroke.grid, 1), nu, 60);
            assert!(!wide.applies(&next));
        }
    }

    #[test]
    fn a_drag_that_keeps_interrupting_the_exact_solve_gets_a_run_finished() {
        // The policy of `finish_when_left`: no run before an exact answer exists; none while
        // the last run answered; after one interrupted run, a run on an edit of the last
        // exact answer is finished, but not one on an unrelated object, nor one predicted
        // over `REFRESH_MAX_PREDICTED_MS`; an answered run resets it.
        let grid = small_bowl();
        let request = |grid: VoxelGrid| request(grid, 0.24, 10);
        let mut exact = IncrementalFemSolver::new();
        let first = request(grid.clone());
        assert!(!exact.finish_when_left(&first), "no exact answer yet");
        exact.solve(&first).unwrap();
        let (a, b) = (request(stroked(&grid, 0)), request(stroked(&grid, 1)));
        assert!(!exact.finish_when_left(&a), "the last run answered");
        let stop = || true;
        let interrupted = exact.solve_until(&a, Stop::when(&stop));
        assert!(interrupted.is_err_and(|e| e.is_interrupted()));
        assert!(exact.finish_when_left(&b));
        let other = request(
            Primitive::Sphere { diameter: 10.0 }
                .rasterize(1.0, 1.0)
                .unwrap(),
        );
        assert!(
            !exact.finish_when_left(&other),
            "not an edit of the last answer"
        );
        // The same edit asked for 400 modes: predicted over the limit.
        let mut many = b.clone();
        many.options.count = ModeCount::First(400);
        assert!(predicted_cold_ms(&many.grid, many.element, many.options.count) > 500.0);
        assert!(
            !exact.finish_when_left(&many),
            "predicted too slow to finish"
        );
        exact.solve(&b).unwrap();
        assert!(
            !exact.finish_when_left(&a),
            "an answered run resets the count"
        );
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
                unanswered_runs: 0,
            };
            let carried = CarriedRitzSolver::instant(&exact, AnswerSwitch::default());
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

    #[test]
    fn the_coarse_answer_reads_its_plan_only_for_the_object_it_was_made_for() {
        // `applies` plans the coarse answer (the halved grid, its stiffening and expected
        // error); `solve` and `expected_error` read the plan for that object and plan afresh
        // for another. Truth: `solve_coarse` on each grid alone, bit for bit.
        let request = |grid: VoxelGrid| request(grid, 0.24, 60);
        // A 32-voxel glass bowl (predicted over the budget at 60 modes, a one-voxel wall) and
        // a small solid sphere (thick: another expected error).
        let large = request(
            Primitive::Bowl {
                diameter: 32.0,
                wall: 1.0,
            }
            .rasterize_on_blocks(1.0, 1.0, 2)
            .unwrap(),
        );
        let small = request(
            Primitive::Sphere { diameter: 10.0 }
                .rasterize_on_blocks(1.0, 1.0, 2)
                .unwrap(),
        );
        let exact = IncrementalFemSolver::new();
        let mut coarse = CoarseFemSolver::new(
            exact.last.clone(),
            exact.elements.clone(),
            exact.kept.clone(),
            AnswerSwitch::default(),
        );
        assert!(coarse.applies(&large));
        let alone = |r: &ObjectRequest| {
            solve_coarse(
                &r.grid,
                r.element,
                r.poisson_ratio,
                r.solver,
                &r.options,
                None,
                Stop::NEVER,
            )
            .unwrap()
            .solution
            .eigenvalues
        };
        let played = |m: ObjectModes| match m {
            ObjectModes::Fem(b) => b.solution.eigenvalues.clone(),
            _ => panic!("FEM"),
        };
        // The planned object, then another without `applies` (the plan is not its own).
        assert_eq!(played(coarse.solve(&large).unwrap()), alone(&large));
        assert_eq!(
            coarse.expected_error(&large),
            Some(COARSE_THIN_EXPECTED_ERROR)
        );
        assert_eq!(played(coarse.solve(&small).unwrap()), alone(&small));
        assert_eq!(
            coarse.expected_error(&small),
            Some(coarse_expected_error(&small.grid))
        );
        assert_eq!(coarse.expected_error(&small), Some(COARSE_EXPECTED_ERROR));
    }
}
