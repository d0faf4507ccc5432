//! The carried answers to a brush stroke: the chain's instant answer and, on the large
//! objects, its wide second answer.
//!
//! Where it sits: [`super::interactive_solvers`] puts [`CarriedRitzSolver::instant`] and
//! [`CarriedRitzSolver::wide`] between the first answer (neural or coarse) and the exact
//! [`super::IncrementalFemSolver`], whose last answer they carry to the edited shape
//! ([`ModeBasis::carried_ritz_factored`], [`ModeBasis::carried_ritz_wide`]; the method is
//! `eigen/warm.rs`'s, after seed 001 sec. 4).

use super::{
    count_of, elements, lock, predicted_cold_ms, warm_candidate, AnswerSwitch, Answers,
    IncrementalFemSolver, Shared, SharedElements, REFRESH_MAX_PREDICTED_MS,
};
use crate::basis::{BasisError, ModeBasis};
use crate::eigen::warm::Reach;
use crate::eigen::{ModeCount, Stop};
use crate::engine::answers::KeptAnswers;
use crate::engine::object::ObjectModes;
use crate::engine::worker::{ModeSolver, ObjectRequest};
use std::sync::{Arc, Mutex};

/// Typical largest relative frequency error of the carried answer to a one-voxel stroke, for
/// the status line: `cargo bench --bench interactive` measures 1e-5 to 1.3e-2 on the presets
/// (3e-3 at most before curved objects kept partial voxels: a stroke next to cut voxels moves
/// more of the stiffness; a stroke that opens a hole in a one-voxel wall can do worse until
/// the exact answer lands).
pub const CARRIED_EXPECTED_ERROR: f64 = 1e-2;

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
pub(super) fn carried_applies(last: &Shared, r: &ObjectRequest) -> bool {
    matches!(r.options.count, ModeCount::First(_))
        && lock(last)
            .as_ref()
            .is_some_and(|p| warm_candidate(p, r) && p.shape_hash != r.grid.shape_hash())
}
