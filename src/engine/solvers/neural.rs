//! The neural predictor's answer (issue 12) as the chain's first answer.
//!
//! Where it sits: [`super::interactive_solvers`] puts [`NeuralSolver`] first when the plugin
//! loaded a predictor (`crate::predictor`, after seed 000); it answers what the carried
//! answers do not serve, and the exact answer replaces it.

use super::carried::carried_applies;
use super::{AnswerSwitch, Answers, Shared};
use crate::basis::BasisError;
use crate::engine::answers::KeptAnswers;
use crate::engine::object::ObjectModes;
use crate::engine::worker::{ModeSolver, ObjectRequest};
use crate::predictor::Predictor;
use std::sync::Arc;

/// Typical frequency error of the predictor's answer, for the status line: the held-out median
/// pitch error of the shipped predictor (network and pitch index), 26.2 cents (`modalforge
/// predictor eval`; `assets/predictor/README.md`), as a ratio (`2^(26.2 / 1200) - 1`).
pub const NEURAL_EXPECTED_ERROR: f64 = 0.015;

/// The neural predictor's answer (issue 12): milliseconds for any shape in the 32^3 box. It
/// answers an edit the carried answer does not serve (a new shape, a large edit, the first
/// object); the exact answer replaces it.
pub struct NeuralSolver {
    pub(super) predictor: Arc<Predictor>,
    pub(super) last: Shared,
    pub(super) kept: KeptAnswers,
    pub(super) answers: AnswerSwitch,
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
