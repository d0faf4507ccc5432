//! The restart loop of the Lanczos iteration, resumable: a request that was met can be
//! followed by a larger one on the same basis.
//!
//! Where it sits: [`super::run_until`] runs one [`Iteration`] to its end;
//! [`crate::eigen::symmetric`] keeps one per symmetry class and, where a class turns out to
//! need the modes up to a higher bound than it was first asked for, runs it again. The basis,
//! its projected matrix and the block that would have extended it when the first request was
//! met are all still valid for the second (the Krylov space only grows), so the second request
//! costs the blocks it needs beyond the first, not a new solve; one that the first's converged
//! pairs already meet is answered from them without a check ([`Iteration::answered`]).

use super::check::{Answer, Check, Progress, RitzCheck, RitzPairs, Verified};
use super::{basis_cap, Expanded, Krylov, Residual, ShiftedCholesky};
use crate::eigen::{
    select, solution, EigenError, EigenOptions, EigenSolution, ModeCount, Operators, SolveTimings,
    SolverKind, Stop,
};
use std::time::Instant;

/// The pairs a solve first makes room for, before it has counted any (it grows after a
/// restart where they were too few).
#[derive(Clone, Copy, Debug)]
pub(crate) struct FirstRoom {
    /// Pairs of room besides a "first k" request's `k`: its rigid-body modes and slack.
    pub rigid: usize,
    /// Pairs of room of a "below f_max" request.
    pub below: usize,
    /// Rigid-body modes expected besides a "first k" request's `k`: the convergence checks
    /// are scheduled for them and the `k` pairs.
    pub rigid_expected: usize,
    /// Pairs (rigid ones included) a "below f_max" request is expected to hold: the checks
    /// are scheduled for them.
    pub below_expected: usize,
}

/// One Lanczos iteration on one factorisation: its basis and where its schedule stands.
pub(crate) struct Iteration {
    krylov: Krylov,
    /// Pairs checked for convergence, rigid ones included.
    nev: usize,
    /// Thick restarts so far.
    restarts: usize,
    /// The block size while the projected matrix is still block tridiagonal (no restart).
    band: Option<usize>,
    /// The block that would have extended the basis when the last request was met.
    pending: Option<Residual>,
    /// What the verification that met the last request found.
    verified: Option<Verified>,
    /// Projected matrices decomposed by the requests met so far (their checks and restarts):
    /// the work a request cost beyond its blocks, which the tests read.
    decompositions: usize,
}

impl Iteration {
    /// A basis for `options.count` started from a random block: a symmetry class is small,
    /// so its basis needs more slack than six rigid modes' to avoid a restart, and it knows
    /// about how many modes lie below its bound (`room`).
    pub fn start(
        ops: &Operators,
        options: &EigenOptions,
        room: FirstRoom,
    ) -> Result<Self, EigenError> {
        let n = ops.dofs();
        let b = options.block_size.min(n);
        let (nev, aim) = match options.count {
            ModeCount::First(k) if k + room.rigid > n => {
                return Err(EigenError::TooFewDofs { dofs: n, wanted: k })
            }
            ModeCount::First(k) => (k + room.rigid, k + room.rigid_expected),
            ModeCount::Below(_) => (room.below, room.below_expected),
        };
        Ok(Iteration {
            krylov: Krylov::start(
                ops,
                (basis_cap(aim.min(nev), b, n), basis_cap(nev, b, n)),
                b,
                aim.min(nev),
            )?,
            nev,
            restarts: 0,
            band: Some(b),
            pending: None,
            verified: None,
            decompositions: 0,
        })
    }

    /// Checks at least `pairs` pairs (rigid ones included) from now on, letting the basis
    /// grow for them, and schedules the checks for `aim` of them: for a second request that
    /// expects more pairs than the first.
    pub fn make_room(&mut self, ops: &Operators, pairs: usize, aim: usize) {
        self.krylov.aim = self.krylov.aim.max(aim.min(pairs));
        if pairs > self.nev {
            self.nev = pairs;
            let b = self.krylov.block;
            self.krylov.room = self.krylov.room.max(basis_cap(pairs, b, ops.dofs()));
        }
    }

    /// Iterates until `options.count` is met, polling `stop` once per block; `setup_ms` of the
    /// result is zero and `iterate_ms` counts this call only. Steps: a resumed iteration first
    /// checks its basis against the new request with the block it kept; then expand the basis
    /// block by block, checking convergence on the way ([`Krylov::expand`]); when it is full,
    /// verify the Ritz pairs with formed vectors, decide how many pairs are wanted now
    /// ([`wanted_after_restart`]) and restart ([`Krylov::restart`]).
    pub fn run(
        &mut self,
        ops: &Operators,
        llt: &mut ShiftedCholesky,
        shift: f64,
        options: &EigenOptions,
        stop: Stop,
    ) -> Result<EigenSolution, EigenError> {
        let n = ops.dofs();
        let b = self.krylov.block;
        let mut checker = RitzCheck {
            ops,
            shift,
            options,
            nev: self.nev,
            started: Instant::now(),
            restarts: self.restarts,
            band: self.band,
            stop,
            decompositions: std::cell::Cell::new(0),
        };
        if let Some(answer) = self.answered(ops, options) {
            return Ok(answer);
        }
        let krylov = &mut self.krylov;
        let mut full = None;
        if let Some(block) = self.pending.take() {
            match checker.run(&krylov.basis, &krylov.projected(), &block.next())? {
                Check::Done(answer) => return Ok(self.met(&checker, block, *answer)),
                Check::Converged(progress) => krylov.schedule_check(progress),
            }
            if krylov.make_fit(&block) {
                krylov.append(block);
            } else {
                full = Some(block);
            }
        }
        let (mut converged_count, mut worst) = (0, f64::INFINITY);
        while self.restarts < options.max_iterations {
            checker.restarts = self.restarts;
            let full = match full.take() {
                Some(full) => full,
                None => match krylov.expand(ops, llt, &mut checker)? {
                    Expanded::Done(answer, block) => return Ok(self.met(&checker, block, *answer)),
                    Expanded::Full(full) => full,
                },
            };
            checker.decompositions.set(checker.decompositions.get() + 1);
            let ritz = RitzPairs::new(
                ops,
                shift,
                &krylov.projected(),
                &full.next(),
                checker.nev,
                None,
            )?;
            // The estimates can be pessimistic: a full basis is always checked with formed
            // vectors.
            let check = checker.nev.min(ritz.order.len());
            let rigid = match checker.verify(&krylov.basis, &ritz, check)? {
                Check::Done(answer) => return Ok(self.met(&checker, full, *answer)),
                Check::Converged(Progress {
                    converged: c,
                    worst: w,
                    ..
                }) => {
                    (converged_count, worst) = (c, w);
                    (0..c)
                        .filter(|&j| ops.is_rigid(ritz.lambda(shift, j)))
                        .count()
                }
            };
            let nev = wanted_after_restart(options.count, checker.nev, rigid, converged_count, b);
            checker.nev = nev;
            // The restarted projected matrix is an arrow (kept Ritz values, their coupling to
            // the residual block), not a band.
            checker.band = None;
            if nev + 2 * b > n {
                return Err(EigenError::TooFewDofs {
                    dofs: n,
                    wanted: nev,
                });
            }
            krylov.room = krylov.room.max(basis_cap(nev, b, n));
            krylov.grow(krylov.room);
            krylov.restart(&ritz, &full, nev, converged_count);
            self.restarts += 1;
        }
        Err(EigenError::NoConvergence {
            converged: converged_count,
            wanted: checker.nev,
            worst_residual: worst,
        })
    }

    /// Keeps what a met request leaves for a larger one (the pairs checked, whether the
    /// projected matrix is still a band, the block that would have extended the basis) and
    /// hands back its answer.
    fn met(&mut self, checker: &RitzCheck, block: Residual, answer: Answer) -> EigenSolution {
        (self.nev, self.band) = (checker.nev, checker.band);
        self.pending = Some(block);
        self.verified = Some(answer.verified);
        self.decompositions += checker.decompositions.get();
        answer.solution
    }

    /// The answer to `options` from the last verification, where its converged pairs meet the
    /// request (to its tolerance): the basis has not changed since, so a check would find the
    /// same pairs (measured on the aluminium plate preset, 60 modes: three of its four classes
    /// were asked again below a bound their first answers had passed, 2.5 ms each for a check
    /// and a verification that added no vector).
    fn answered(&self, ops: &Operators, options: &EigenOptions) -> Option<EigenSolution> {
        let verified = self.verified.as_ref()?;
        if options.tolerance < verified.tolerance {
            return None;
        }
        let started = Instant::now();
        let sel = select(ops, &verified.pairs, options.count);
        sel.complete.then(|| {
            let timings = SolveTimings {
                setup_ms: 0.0,
                iterate_ms: started.elapsed().as_secs_f64() * 1e3,
            };
            solution(
                &verified.pairs,
                &sel,
                verified.x.as_ref(),
                timings,
                self.restarts,
                SolverKind::Lanczos,
            )
        })
    }
}

/// Pairs wanted after a restart found `rigid` rigid modes among `converged` converged pairs:
/// a "first k" request now knows its rigid count; a "below f_max" request that has converged
/// all it asked for (and so has not reached f_max yet) asks for half as many more, up to
/// [`crate::eigen::MAX_MODES`] and a margin.
fn wanted_after_restart(
    count: ModeCount,
    nev: usize,
    rigid: usize,
    converged: usize,
    b: usize,
) -> usize {
    match count {
        ModeCount::First(k) => nev.max(rigid + k),
        ModeCount::Below(_) if converged + b >= nev => {
            (nev * 3 / 2 + b).min(crate::eigen::MAX_MODES + 64)
        }
        ModeCount::Below(_) => nev,
    }
}

#[cfg(test)]
mod tests {
    use super::{FirstRoom, Iteration};
    use crate::eigen::factor::ShiftedCholesky;
    use crate::eigen::lanczos::{self, SHIFT_RELATIVE};
    use crate::eigen::{EigenOptions, ModeCount, Operators, Stop};
    use crate::fem::{test_model, ElementKind};

    /// A bound midway across the first clear gap from mode `from` on (not inside a degenerate
    /// pair, whose copies may land on either side of a bound between them), and the number of
    /// modes below it.
    fn bound_after(e: &[f64], from: usize) -> (f64, usize) {
        let count = (from..e.len())
            .find(|&i| e[i] - e[i - 1] > 1e-3 * e[i])
            .expect("a gap");
        (0.5 * (e[count - 1] + e[count]), count)
    }

    /// An iteration asked for the modes below a bound, then below a bound its converged pairs
    /// already meet (answered from them, [`Iteration::answered`]), then below a higher one, gives
    /// the second request's answer as a fresh solve does: the same eigenvalues (both converge
    /// to residual 1e-9, so an eigenvalue is good to ~1e-12 relative over this bowl's gaps;
    /// 1e-7 leaves a wide margin, while a missed or doubled mode shifts the ones after it by a
    /// gap, percents) and residuals, recomputed from `K` and `M`, within the tolerance. The
    /// second request must cost less than the first solve's basis again: it goes on from it.
    #[test]
    fn a_resumed_iteration_answers_a_higher_bound() {
        let model = test_model("bowl:d=10,wall=2", ElementKind::Hex8Incompatible, 0.24);
        let ops = Operators::new(&model);
        let options = |count| EigenOptions {
            count,
            tolerance: 1e-9,
            ..Default::default()
        };
        let reference = lanczos::solve(&model, &options(ModeCount::First(40))).expect("solve");
        let e = &reference.eigenvalues;
        let (low, low_count) = bound_after(e, 8);
        let (high, high_count) = bound_after(e, 30);
        let shift = -SHIFT_RELATIVE * ops.scale;
        let mut llt = ShiftedCholesky::new(&model, shift, Stop::NEVER).expect("factor");
        let room = FirstRoom {
            rigid: 12,
            below: 2 * low_count + 12,
            rigid_expected: 6,
            below_expected: low_count + 6,
        };
        let first_options = options(ModeCount::Below(low));
        let mut iteration = Iteration::start(&ops, &first_options, room).expect("start");
        let first = iteration
            .run(&ops, &mut llt, shift, &first_options, Stop::NEVER)
            .expect("first request");
        assert_eq!(first.eigenvalues.len(), low_count);
        let first_len = iteration.krylov.basis.len;
        // A request the first one's converged pairs already meet (above its bound, below the
        // converged pair that passed it) is answered from them: the verification's pairs bit
        // for bit, no vector added, no projected matrix decomposed.
        let passed = (iteration.verified.as_ref().expect("verified").pairs.iter())
            .map(|p| p.0)
            .find(|&l| l > low)
            .expect("a converged pair above the bound");
        let met_options = options(ModeCount::Below(0.5 * (low + passed)));
        let decompositions = iteration.decompositions;
        assert!(decompositions > 0);
        let met = iteration
            .run(&ops, &mut llt, shift, &met_options, Stop::NEVER)
            .expect("a request met");
        assert_eq!(iteration.krylov.basis.len, first_len, "no vector added");
        assert_eq!(iteration.decompositions, decompositions, "no check made");
        assert_eq!(met.eigenvalues, first.eigenvalues);
        assert_eq!(met.residuals, first.residuals);
        assert_eq!(met.vectors, first.vectors);
        let second_options = options(ModeCount::Below(high));
        iteration.make_room(&ops, 2 * high_count + 12, high_count + 6);
        let second = iteration
            .run(&ops, &mut llt, shift, &second_options, Stop::NEVER)
            .expect("second request");
        assert_eq!(second.eigenvalues.len(), high_count);
        for (j, (a, b)) in second.eigenvalues.iter().zip(e).enumerate() {
            assert!((a - b).abs() <= 1e-7 * b, "mode {j}: {a} against {b}");
        }
        let explicit = ops.block_residuals(&second.eigenvalues, second.vectors.as_ref());
        for (j, r) in explicit.iter().enumerate() {
            assert!(*r <= 1e-9, "mode {j}: residual {r:e}");
        }
        // It went on from the first basis: no restart, and no more vectors than a fresh
        // iteration asked the second request alone.
        assert_eq!(second.iterations, 0, "no restart");
        let mut fresh = Iteration::start(&ops, &second_options, room).expect("start");
        fresh.make_room(&ops, 2 * high_count + 12, high_count + 6);
        fresh
            .run(&ops, &mut llt, shift, &second_options, Stop::NEVER)
            .expect("fresh request");
        let (resumed_len, fresh_len) = (iteration.krylov.basis.len, fresh.krylov.basis.len);
        assert!(
            first_len < resumed_len && resumed_len <= fresh_len,
            "basis: first {first_len}, resumed {resumed_len}, fresh {fresh_len}"
        );
    }
}
