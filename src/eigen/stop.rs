//! Interrupting a running solve: the engine's worker drops an exact solve that a newer edit
//! has made obsolete.
//!
//! Where it sits: [`super::solve_until`] and the solvers' `solve_until` take a [`Stop`] and
//! poll it between their steps; [`crate::basis::ModeBasis::solve_cached`] polls it after the
//! assembly too; the worker's poll is [`crate::engine::ModeSolver::solve_until`]'s.

use super::EigenError;

/// A caller's way to interrupt a running solve: polled between the solvers' steps (through the
/// sparse factorisation, before each supernode's update and panel, then after the set-up and
/// once per Lanczos block or LOBPCG iteration, each a few milliseconds on interactive
/// objects; the longest steps left are an elimination order's, 17 ms on the ceramic cup's whole
/// object, and an assembly's), a solve whose poll answers true returns
/// [`EigenError::Interrupted`]. The engine's worker uses it to drop an exact solve that a
/// newer edit has made obsolete ([`crate::engine::ModeSolver::solve_until`]).
#[derive(Clone, Copy)]
pub struct Stop<'a>(Option<&'a dyn Fn() -> bool>);

impl<'a> Stop<'a> {
    /// Never interrupts.
    pub const NEVER: Stop<'static> = Stop(None);

    /// Interrupts once `poll` returns true.
    pub fn when(poll: &'a dyn Fn() -> bool) -> Self {
        Stop(Some(poll))
    }

    /// `Err(Interrupted)` once the caller asks to stop.
    pub fn check(&self) -> Result<(), EigenError> {
        match self.0 {
            Some(poll) if poll() => Err(EigenError::Interrupted),
            _ => Ok(()),
        }
    }
}

impl std::fmt::Debug for Stop<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(if self.0.is_some() {
            "Stop(poll)"
        } else {
            "Stop::NEVER"
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::*;

    #[test]
    fn a_stopped_solve_gives_up_at_its_next_poll_and_an_unstopped_one_is_unchanged() {
        // Both solvers poll once after their set-up and then once per step: a poll that says
        // stop at its k-th call ends the solve there (k polls made, `Interrupted`), and a poll
        // that never says stop gives bit for bit the uninterrupted answer.
        use crate::fem::ElementKind;
        use crate::shape::VoxelGrid;
        use std::cell::Cell;
        let grid = VoxelGrid::from_fn([10, 6, 3], 1.0, |x, y, _| x + y < 13.0).unwrap();
        let model = FemModel::assemble(&grid, ElementKind::Hex8Incompatible, 0.3).unwrap();
        let options = EigenOptions {
            count: ModeCount::First(30),
            block_size: 4,
            ..Default::default()
        };
        for solver in [SolverKind::Lanczos, SolverKind::Lobpcg] {
            let plain = solve(&model, solver, &options).unwrap();
            let polls = Cell::new(0usize);
            let never = || {
                polls.set(polls.get() + 1);
                false
            };
            let polled = solve_until(&model, solver, &options, Stop::when(&never)).unwrap();
            assert_eq!(plain.eigenvalues, polled.eigenvalues, "{solver:?}");
            let steps = polls.get();
            assert!(steps >= 3, "{solver:?}: polled {steps} times");
            for k in [1, 2, steps] {
                let calls = Cell::new(0usize);
                let at_k = || {
                    calls.set(calls.get() + 1);
                    calls.get() >= k
                };
                let stopped = solve_until(&model, solver, &options, Stop::when(&at_k));
                assert_eq!(
                    stopped.unwrap_err(),
                    EigenError::Interrupted,
                    "{solver:?} {k}"
                );
                assert_eq!(calls.get(), k, "{solver:?}");
            }
        }
    }
}
