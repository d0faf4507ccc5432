//! The worker's helper thread, where a detachable solver runs ([`ModeSolver::detachable`]):
//! the worker can stop waiting for a run that a newer edit made obsolete and answer that edit
//! at once, while the obsolete run ends by itself at its next poll.
//!
//! Where it sits: [`super::Worker`] sends the chain's exact solver, the request and a stop
//! flag here ([`Helper::start`]), then waits for the answer while it polls for newer
//! requests ([`Helper::wait`]). Why: a solver polls its stop only between its steps, and
//! some steps cannot be cut. Until stop 66 the sparse Cholesky factorisation was one call into
//! faer: after a stroke that breaks an object's mirrors, 40-95 ms for the default object and
//! 0.5-0.7 s for the ceramic cup, measured in the worker during a drag (`cargo bench --bench
//! interactive -- --drag 100`), and a stroke made during one was heard that much later than
//! its own carried answer. The factorisation now polls every few milliseconds
//! ([`crate::eigen::factor`]), so an obsolete run ends almost at once; what is still uncut (an
//! elimination order, 17 ms on the ceramic cup's whole object; an assembly; a symmetry class's
//! reduction) the worker still does not wait for.
//!
//! The solver travels with the job and comes back with its answer; while it is away its slot
//! in the chain is empty, and the worker brings it back ([`Helper::bring_back`]: the run, told
//! to stop, ends at its next poll) before it runs that solver, or any other detachable one,
//! again. An answer that comes back after the worker stopped waiting is dropped here: a newer
//! edit's answers are already playing. The worker drops the helper (and the thread ends)
//! after [`IDLE`] without a run.
//!
//! A run whose solver asks for it as it starts ([`ModeSolver::finish_when_left`]: the exact
//! solver, once a drag has interrupted it, so that the drag's carried answers start from a
//! recent exact answer) is not stopped when the worker leaves it: it ends by itself, and the
//! solver keeps its answer. Only the engine's shutdown stops it, or the worker giving up on it
//! ([`Helper::abandon`]) after waiting [`PATIENCE`] to run the solver again with no newer
//! stroke coming: the drag has paused, and the answer to what is heard now comes first.

use super::{ModeSolver, ObjectRequest};
use crate::basis::BasisError;
use crate::eigen::Stop;
use crate::engine::object::ObjectModes;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// How often the worker polls for newer requests while a detached run is solving: the delay
/// it adds to a stroke made during the run, against a lock and a compare every interval.
pub(super) const WAIT_POLL: Duration = Duration::from_millis(1);

/// How long the worker waits for a run it left to finish ([`ModeSolver::finish_when_left`])
/// before it gives up on it ([`Helper::abandon`]) to solve the edit it holds: a sculpting
/// drag sends strokes more often than this, so a pause this long ends it.
pub(super) const PATIENCE: Duration = Duration::from_millis(80);

/// How long the helper thread outlives its last run. Every thread that runs faer's matrix
/// products keeps their workspace, twice the L3 cache (`private-gemm-x86`'s thread-local:
/// 64 MB of heap on this project's machine, of which the soak saw about 15 MB resident), so
/// an idle engine (a plugin instance nobody sculpts) hands the helper's back. Sculpting
/// keeps it: strokes come seconds apart at most.
#[cfg(not(test))]
const IDLE: Duration = Duration::from_secs(5);
/// [`IDLE`] in tests, which watch the thread end.
#[cfg(test)]
pub(crate) const IDLE: Duration = Duration::from_millis(300);

/// A solver's answer, and the solver itself, back from the helper.
type Done = (Box<dyn ModeSolver>, Result<ObjectModes, BasisError>);

/// One run for the helper.
struct Job {
    solver: Box<dyn ModeSolver>,
    request: ObjectRequest,
    /// Set when the worker leaves the run (a newer edit made it obsolete).
    left: Arc<AtomicBool>,
    /// The solver's [`ModeSolver::finish_when_left`] for this run: leaving does not stop it.
    finish: bool,
    /// Set when the engine shuts down: stops every run.
    shutdown: Arc<AtomicBool>,
    /// Set when the worker gives up on a run it had left to finish ([`Helper::abandon`]).
    abandoned: Arc<AtomicBool>,
}

/// How a wait for a detached run ended.
pub(super) enum Waited {
    /// The run answered; its solver is back.
    Answered(Box<dyn ModeSolver>, Result<ObjectModes, BasisError>),
    /// The poll said stop: the run was told to stop and is left to end on the helper.
    Left,
    /// The helper thread is gone (the solver panicked): the solver is lost.
    Lost,
}

/// The helper thread and the solver it holds (see the module docs).
pub(super) struct Helper {
    jobs: Option<Sender<Job>>,
    done: Receiver<Done>,
    thread: Option<JoinHandle<()>>,
    /// A run the worker left: its solver's index in the chain.
    away: Option<usize>,
    /// The run in flight's flags: the worker left it; the worker gave up on it.
    left: Arc<AtomicBool>,
    abandoned: Arc<AtomicBool>,
    /// Set on drop: stops the run in flight, whatever it was left to do.
    shutdown: Arc<AtomicBool>,
    /// When a run last started or came back.
    used: Instant,
}

impl Helper {
    /// Starts the helper thread.
    pub(super) fn spawn() -> std::io::Result<Self> {
        let (jobs, inbox) = mpsc::channel::<Job>();
        let (outbox, done) = mpsc::channel::<Done>();
        let thread = std::thread::Builder::new()
            .name("modalforge-solve".into())
            .spawn(move || {
                while let Ok(Job {
                    mut solver,
                    request,
                    left,
                    finish,
                    shutdown,
                    abandoned,
                }) = inbox.recv()
                {
                    let poll = || {
                        shutdown.load(Ordering::Acquire)
                            || abandoned.load(Ordering::Acquire)
                            || (!finish && left.load(Ordering::Acquire))
                    };
                    let answer = solver.solve_until(&request, Stop::when(&poll));
                    if outbox.send((solver, answer)).is_err() {
                        return;
                    }
                }
            })?;
        Ok(Helper {
            jobs: Some(jobs),
            done,
            thread: Some(thread),
            away: None,
            left: Arc::new(AtomicBool::new(false)),
            abandoned: Arc::new(AtomicBool::new(false)),
            shutdown: Arc::new(AtomicBool::new(false)),
            used: Instant::now(),
        })
    }

    /// The index of the solver out on a run the worker left, if any.
    pub(super) fn away(&self) -> Option<usize> {
        self.away
    }

    /// Whether no run has started or ended for [`IDLE`] and none is away: the worker then
    /// drops the helper (the thread ends, and with it its matrix-product workspace).
    pub(super) fn idle(&self) -> bool {
        self.away.is_none() && self.used.elapsed() > IDLE
    }

    /// Runs `solver` on `request` on the helper thread; hands the solver back if the helper
    /// is gone. Bring any solver away back first ([`Helper::bring_back`]).
    pub(super) fn start(
        &mut self,
        solver: Box<dyn ModeSolver>,
        request: &ObjectRequest,
    ) -> Result<(), Box<dyn ModeSolver>> {
        debug_assert!(self.away.is_none(), "one run at a time");
        self.used = Instant::now();
        self.left = Arc::new(AtomicBool::new(false));
        self.abandoned = Arc::new(AtomicBool::new(false));
        let job = Job {
            finish: solver.finish_when_left(request),
            solver,
            request: request.clone(),
            left: self.left.clone(),
            shutdown: self.shutdown.clone(),
            abandoned: self.abandoned.clone(),
        };
        match &self.jobs {
            Some(jobs) => jobs.send(job).map_err(|e| e.0.solver),
            None => Err(job.solver),
        }
    }

    /// Waits for the run started last, calling `superseded` every [`WAIT_POLL`]; once it
    /// answers true the run is left (its solver `index` is then away) and told to stop,
    /// unless its solver asked to finish it ([`ModeSolver::finish_when_left`]).
    pub(super) fn wait(&mut self, index: usize, superseded: impl Fn() -> bool) -> Waited {
        loop {
            match self.done.recv_timeout(WAIT_POLL) {
                Ok((solver, answer)) => {
                    self.used = Instant::now();
                    return Waited::Answered(solver, answer);
                }
                Err(RecvTimeoutError::Timeout) => {
                    if superseded() {
                        self.left.store(true, Ordering::Release);
                        self.away = Some(index);
                        return Waited::Left;
                    }
                }
                Err(RecvTimeoutError::Disconnected) => return Waited::Lost,
            }
        }
    }

    /// Tells the run the worker left to stop at its next poll, even one its solver asked to
    /// finish.
    pub(super) fn abandon(&self) {
        self.abandoned.store(true, Ordering::Release);
    }

    /// Waits up to `timeout` for the run the worker left to end; gives its solver back (its
    /// answer is dropped).
    pub(super) fn bring_back(&mut self, timeout: Duration) -> BroughtBack {
        let Some(index) = self.away else {
            return BroughtBack::Nothing;
        };
        match self.done.recv_timeout(timeout) {
            Ok((solver, _)) => {
                self.away = None;
                self.used = Instant::now();
                BroughtBack::Solver(index, solver)
            }
            Err(RecvTimeoutError::Timeout) => BroughtBack::NotYet,
            Err(RecvTimeoutError::Disconnected) => {
                self.away = None;
                BroughtBack::Nothing
            }
        }
    }
}

/// What [`Helper::bring_back`] found.
pub(super) enum BroughtBack {
    /// The solver at this index in the chain, back.
    Solver(usize, Box<dyn ModeSolver>),
    /// The run has not ended yet.
    NotYet,
    /// No solver was away, or the helper is gone with it.
    Nothing,
}

impl Drop for Helper {
    fn drop(&mut self) {
        // A run in flight was told to stop (the worker's poll answers true on shutdown) and
        // ends at its next poll; the thread then sees its queue closed. Joined, so no solver
        // code runs after the engine is gone (a plugin's library may be unloaded next).
        self.shutdown.store(true, Ordering::Release);
        self.jobs = None;
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::basis::BasisError;
    use crate::eigen::{EigenOptions, ModeCount, SolverKind};
    use crate::engine::worker::FemSolver;
    use crate::fem::ElementKind;
    use crate::shape::VoxelGrid;
    use std::sync::atomic::AtomicU64;

    /// A run with a step that polls no stop: it waits for `gate`, then polls its stop once
    /// and counts how it ended. `finish` is its [`ModeSolver::finish_when_left`].
    struct Gated {
        finish: bool,
        gate: Arc<AtomicBool>,
        finished: Arc<AtomicU64>,
        interrupted: Arc<AtomicU64>,
    }

    impl ModeSolver for Gated {
        fn name(&self) -> &'static str {
            "gated"
        }
        fn detachable(&self) -> bool {
            true
        }
        fn finish_when_left(&self, _request: &ObjectRequest) -> bool {
            self.finish
        }
        fn solve(&mut self, r: &ObjectRequest) -> Result<ObjectModes, BasisError> {
            self.solve_until(r, Stop::NEVER)
        }
        fn solve_until(
            &mut self,
            r: &ObjectRequest,
            stop: Stop,
        ) -> Result<ObjectModes, BasisError> {
            while !self.gate.load(Ordering::SeqCst) {
                std::thread::sleep(Duration::from_millis(1));
            }
            if let Err(e) = stop.check() {
                self.interrupted.fetch_add(1, Ordering::SeqCst);
                return Err(e.into());
            }
            self.finished.fetch_add(1, Ordering::SeqCst);
            FemSolver.solve(r)
        }
    }

    fn request() -> ObjectRequest {
        let mut grid = VoxelGrid::new([6, 2, 2], 0.01).unwrap();
        for [x, y, z] in
            (0..6).flat_map(|x| (0..2).flat_map(move |y| (0..2).map(move |z| [x, y, z])))
        {
            grid.set(x, y, z, true);
        }
        ObjectRequest {
            grid,
            element: ElementKind::Hex8Incompatible,
            poisson_ratio: 0.3,
            solver: SolverKind::Auto,
            options: EigenOptions {
                count: ModeCount::First(4),
                ..EigenOptions::default()
            },
            recording: None,
        }
    }

    #[test]
    fn a_left_run_stops_at_its_next_poll_unless_its_solver_asked_to_finish_it() {
        // Each case: a run is started, left while it is in a step that polls no stop, and
        // its step then ends. `(finish, abandon, drop)`: whether the solver asked to finish
        // left runs, whether the worker gives up on the run, whether the engine shuts down
        // (the helper is dropped) before the step ends. Only a run asked to finish, neither
        // abandoned nor shut down, finishes.
        for (finish, abandon, drop) in [
            (false, false, false),
            (true, false, false),
            (true, true, false),
            (true, false, true),
        ] {
            let gate = Arc::new(AtomicBool::new(false));
            let (finished, interrupted) =
                (Arc::new(AtomicU64::new(0)), Arc::new(AtomicU64::new(0)));
            let mut helper = Helper::spawn().unwrap();
            let solver = Gated {
                finish,
                gate: gate.clone(),
                finished: finished.clone(),
                interrupted: interrupted.clone(),
            };
            assert!(helper.start(Box::new(solver), &request()).is_ok());
            assert!(matches!(helper.wait(3, || true), Waited::Left));
            assert_eq!(helper.away(), Some(3));
            if abandon {
                helper.abandon();
            }
            if drop {
                // The gate opens once the drop has set the shutdown flag and waits to join.
                let opener = {
                    let gate = gate.clone();
                    std::thread::spawn(move || {
                        std::thread::sleep(Duration::from_millis(50));
                        gate.store(true, Ordering::SeqCst);
                    })
                };
                std::mem::drop(helper);
                opener.join().unwrap();
            } else {
                gate.store(true, Ordering::SeqCst);
                let back = helper.bring_back(Duration::from_secs(60));
                assert!(matches!(back, BroughtBack::Solver(3, _)));
                assert_eq!(helper.away(), None);
            }
            let expected = if finish && !abandon && !drop {
                (1, 0)
            } else {
                (0, 1)
            };
            assert_eq!(
                (
                    finished.load(Ordering::SeqCst),
                    interrupted.load(Ordering::SeqCst)
                ),
                expected,
                "finish {finish}, abandon {abandon}, drop {drop}"
            );
        }
    }
}
