//! LOBPCG (seed 001 sec. 4.2.4). Not yet written: answers with an error.

use super::{EigenError, EigenOptions, EigenSolution};
use crate::fem::FemModel;

/// Placeholder until the multigrid-preconditioned LOBPCG lands.
pub fn solve(_model: &FemModel, _options: &EigenOptions) -> Result<EigenSolution, EigenError> {
    Err(EigenError::BadRequest(
        "the LOBPCG solver is not built yet; use --solver lanczos".into(),
    ))
}
