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
use crate::eigen::{ModeCount, Stop};
use crate::fem::{ElementCache, FemModel};
use crate::predictor::Predictor;
use crate::shape::VoxelGrid;
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::{Arc, Mutex};

mod carried;
mod coarse;
mod neural;

use coarse::{solve_coarse_grid, CoarsePlan};

pub use carried::{CarriedRitzSolver, CARRIED_EXPECTED_ERROR, WIDE_CARRIED_EXPECTED_ERROR};
pub use neural::{NeuralSolver, NEURAL_EXPECTED_ERROR};

pub use coarse::{
    coarse_expected_error, coarse_grid, coarse_stiffening, grid_mirrors, mean_wall_voxels,
    predicted_cold_ms, solve_coarse, COARSE_EXPECTED_ERROR, COARSE_THIN_EXPECTED_ERROR,
    PROGRESSIVE_BUDGET_MS, THIN_WALL_VOXELS,
};

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
mod tests;
