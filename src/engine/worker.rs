//! The engine's worker thread: solves shape edits off the audio thread and hands the results
//! over through a lock-free ring.
//!
//! Where it sits: between the editor/CLI (which send [`ObjectRequest`]s through
//! [`EngineControl::request`]) and [`super::audio::AudioEngine`] (which pops solved objects
//! from an `rtrb` ring and pushes the replaced ones back through a second ring, freed here).
//! Requests that arrive during a solve coalesce: only the newest waiting one is solved next.
//! Solvers form a chain ([`ModeSolver`]): fast approximate ones (a coarse grid, the carried
//! modes of the last exact answer, the neural predictor: [`super::solvers`]) answer
//! first and the exact FEM solve replaces them, unless a newer request has arrived. A slow
//! solve that a newer request makes obsolete is interrupted when a faster solver earlier in the
//! chain would answer the newer one ([`ModeSolver::solve_until`]): a stroke made while the
//! last stroke's exact answer is being solved is heard within its own carried answer's time,
//! not after the obsolete solve.
//! Nice-plug's own background executor is deliberately not used (it can abort a host on
//! unload; `../shared/notes/plugin.md`).

pub(super) mod helper;
mod thread;

use thread::Worker;

use super::object::{ObjectModes, SolvedObject};
use super::recorded::RecordedObject;
use super::EngineStats;
use crate::basis::{BasisError, ModeBasis};
use crate::eigen::{EigenError, EigenOptions, SolverKind, Stop};
use crate::fem::ElementKind;

use crate::shape::VoxelGrid;
use rtrb::{Consumer, Producer, PushError};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// How often an idle worker wakes to free retired objects and retry a delivery.
const POLL: Duration = Duration::from_millis(20);

/// A shape edit to solve: everything the expensive solve depends on.
#[derive(Clone, Debug)]
pub struct ObjectRequest {
    /// The voxel object.
    pub grid: VoxelGrid,
    /// Element type.
    pub element: ElementKind,
    /// Poisson's ratio (the one material constant the modes depend on).
    pub poisson_ratio: f64,
    /// Eigensolver.
    pub solver: SolverKind,
    /// Mode count and tolerance, in reference units.
    pub options: EigenOptions,
    /// A recording's modes to play instead of the shape ([`super::recorded`]): delivered as
    /// they are, no solver runs (the status line names the solver "recording").
    pub recording: Option<Arc<RecordedObject>>,
}

/// Something that turns a shape into modes. The worker runs its solvers in order for every
/// request and hands each result to the audio side as it arrives.
pub trait ModeSolver: Send {
    /// Short name for the status line ("fem", "neural").
    fn name(&self) -> &'static str;
    /// Solves the request.
    fn solve(&mut self, request: &ObjectRequest) -> Result<ObjectModes, BasisError>;
    /// [`ModeSolver::solve`], given up where the solver can once `stop` says so (an error for
    /// which [`BasisError::is_interrupted`] holds). The worker calls this; its poll answers
    /// true once a newer request waits that a solver earlier in the chain answers, or the
    /// engine shuts down. Default: [`ModeSolver::solve`], never interrupted (fast solvers).
    fn solve_until(
        &mut self,
        request: &ObjectRequest,
        stop: Stop,
    ) -> Result<ObjectModes, BasisError> {
        let _ = stop;
        self.solve(request)
    }
    /// Whether this solver answers `request` at all (a progressive first answer is skipped
    /// where the exact one is fast anyway). Default: always.
    fn applies(&self, _request: &ObjectRequest) -> bool {
        true
    }
    /// The typical relative frequency error of this solver's answer to `request`, for the
    /// status line (`None`: exact to the solver tolerance).
    fn expected_error(&self, _request: &ObjectRequest) -> Option<f64> {
        None
    }
    /// Whether the worker runs this solver on its helper thread, where a run a newer edit made
    /// obsolete can be left to end by itself (`worker/helper.rs`): for solvers with steps that
    /// poll no stop and are too long to wait for (an exact solve's elimination order and
    /// assembly; its factorisation until stop 66). Such a solver must
    /// not hold a lock the chain's other solvers take for longer than a moment: they run
    /// beside its obsolete run. Default: false, run on the worker thread.
    fn detachable(&self) -> bool {
        false
    }
    /// Whether a run of this detachable solver on `request` that a newer edit makes obsolete
    /// goes on to its end on the helper thread instead of stopping at its next poll: its
    /// answer is not played (the newer edit's answers are), but the solver keeps what it
    /// computed (the exact solver: the basis the carried answers start from). Asked as the
    /// run starts; only the engine's shutdown stops such a run, or the worker giving up on it
    /// when no newer edit comes for a while (`worker/helper.rs`, `PATIENCE`). Default: false.
    fn finish_when_left(&self, _request: &ObjectRequest) -> bool {
        false
    }
}

/// The finite-element modal analysis ([`ModeBasis::solve`]): exact, the reference.
pub struct FemSolver;

impl ModeSolver for FemSolver {
    fn name(&self) -> &'static str {
        "fem"
    }

    fn solve(&mut self, r: &ObjectRequest) -> Result<ObjectModes, BasisError> {
        self.solve_until(r, Stop::NEVER)
    }

    fn solve_until(&mut self, r: &ObjectRequest, stop: Stop) -> Result<ObjectModes, BasisError> {
        let (grid, nu) = (&r.grid, r.poisson_ratio);
        ModeBasis::solve_cached(grid, r.element, nu, r.solver, &r.options, None, stop)
            .map(|b| ObjectModes::Fem(Arc::new(b)))
    }
}

/// What the worker is doing.
#[derive(Clone, Debug, PartialEq)]
pub enum SolveState {
    /// Nothing to do.
    Idle,
    /// Solving with the named solver since the given instant.
    Solving {
        /// Solver name.
        solver: &'static str,
        /// When it started.
        since: Instant,
    },
}

/// The outcome of the last solve.
#[derive(Clone, Debug, PartialEq)]
pub struct SolveReport {
    /// Solver name.
    pub solver: &'static str,
    /// Generation of the object it produced (0 on error).
    pub generation: u64,
    /// Wall time, ms.
    pub ms: f64,
    /// Modes found.
    pub modes: usize,
    /// The error, one line, if it failed (the previous object keeps playing).
    pub error: Option<String>,
    /// The answer's typical relative frequency error ([`ModeSolver::expected_error`]).
    pub expected_error: Option<f64>,
    /// Whether the answer started from the previous edit's modes (a carried or warm-started
    /// answer) rather than from scratch.
    pub warm_start: bool,
    /// Which request it answers: requests are numbered from 1 as the worker receives them
    /// ([`EngineControl::request`], or its request source), so a caller can tell an answer
    /// to its latest edit from one to an earlier edit.
    pub request: u64,
}

/// The worker's state for the editor's status line.
#[derive(Clone, Debug, PartialEq)]
pub struct WorkerStatus {
    /// What it is doing.
    pub state: SolveState,
    /// The last finished solve.
    pub last: Option<SolveReport>,
    /// Requests solved (each solver run counts once; an interrupted run does not).
    pub solves: u64,
    /// Solver runs given up because a newer request made them obsolete
    /// ([`ModeSolver::solve_until`]).
    pub interrupted: u64,
    /// The last successful answer: the one playing (or about to), with its expected error.
    pub playing: Option<SolveReport>,
}

struct Mailbox {
    request: Option<ObjectRequest>,
    /// Requests received so far: the number of the newest ([`SolveReport::request`]).
    serial: u64,
    shutdown: bool,
    /// The worker holds a request it took from here and has not finished solving: set under
    /// this lock as the request is taken, so that [`EngineControl::wait_idle`] never sees an
    /// empty mailbox and an idle worker in between. (An answer the ring has not taken yet is
    /// not "busy": the ring empties only when the audio side runs, which a waiter may not.)
    busy: bool,
}

/// Called by the worker whenever its status changes (see [`EngineControl::watch_status`]).
pub type StatusWatcher = Arc<dyn Fn() + Send + Sync>;

/// Polled by the worker for requests (see [`EngineControl::set_request_source`]).
pub type RequestSource = Box<dyn FnMut() -> Option<ObjectRequest> + Send>;

struct Shared {
    mailbox: Mutex<Mailbox>,
    wake: Condvar,
    status: Mutex<WorkerStatus>,
    source: Mutex<Option<RequestSource>>,
    latest: Mutex<Option<LatestObject>>,
    watcher: Mutex<Option<StatusWatcher>>,
}

impl Shared {
    /// Sets the solver's state and tells the watcher.
    fn set_state(&self, state: SolveState) {
        lock(&self.status).state = state;
        self.status_changed();
    }

    /// Tells the watcher, if any, that the status changed (called with no lock held but the
    /// watcher's own, so a watcher may read the status).
    fn status_changed(&self) {
        let watcher = lock(&self.watcher).clone();
        if let Some(w) = watcher {
            w();
        }
    }
}

/// The newest solved object, for views (the editor's spectrum): its generation and modes.
#[derive(Clone)]
pub struct LatestObject {
    /// Generation (as in [`SolveReport::generation`]).
    pub generation: u64,
    /// The modes in reference units (see [`super::spectrum`]).
    pub basis: Arc<ObjectModes>,
}

/// Locks, recovering from a poisoned lock (a panicking solver must not wedge the editor).
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// The control side of the engine (editor, CLI): sends requests, reads status and statistics.
/// Dropping it stops the worker.
pub struct EngineControl {
    shared: Arc<Shared>,
    stats: Arc<EngineStats>,
    thread: Option<JoinHandle<()>>,
}

impl EngineControl {
    pub(super) fn spawn(
        solvers: Vec<Box<dyn ModeSolver>>,
        to_audio: Producer<Box<SolvedObject>>,
        retired: Consumer<Box<SolvedObject>>,
        stats: Arc<EngineStats>,
    ) -> std::io::Result<Self> {
        let shared = Arc::new(Shared {
            mailbox: Mutex::new(Mailbox {
                request: None,
                serial: 0,
                shutdown: false,
                busy: false,
            }),
            wake: Condvar::new(),
            status: Mutex::new(WorkerStatus {
                state: SolveState::Idle,
                last: None,
                solves: 0,
                interrupted: 0,
                playing: None,
            }),
            source: Mutex::new(None),
            latest: Mutex::new(None),
            watcher: Mutex::new(None),
        });
        let worker = Worker::new(shared.clone(), solvers, to_audio, retired);
        let thread = std::thread::Builder::new()
            .name("modalforge-worker".into())
            .spawn(move || worker.run())?;
        Ok(Self {
            shared,
            stats,
            thread: Some(thread),
        })
    }

    /// Queues a shape to solve; a request still waiting is replaced (coalescing).
    pub fn request(&self, request: ObjectRequest) {
        let mut mb = lock(&self.shared.mailbox);
        mb.request = Some(request);
        mb.serial += 1;
        drop(mb);
        self.shared.wake.notify_one();
    }

    /// Lets the worker ask for requests itself: `source` is called on the worker thread every
    /// poll (20 ms) while no request waits, and what it returns is solved. A plugin uses it to
    /// notice solve-relevant parameter changes (Poisson's ratio, solver, a restored object)
    /// without the audio thread ever touching a lock.
    pub fn set_request_source(&self, source: RequestSource) {
        *lock(&self.shared.source) = Some(source);
        self.shared.wake.notify_one();
    }

    /// Calls `watcher` on the worker thread whenever the status changes (a solve starts or
    /// ends, an answer is delivered), replacing any earlier watcher. A window uses it to
    /// repaint when something changes instead of polling on a timer.
    pub fn watch_status(&self, watcher: StatusWatcher) {
        *lock(&self.shared.watcher) = Some(watcher);
    }

    /// The worker's status.
    pub fn status(&self) -> WorkerStatus {
        lock(&self.shared.status).clone()
    }

    /// The newest solved object (the one the audio side plays, or is about to), if any.
    pub fn latest_object(&self) -> Option<LatestObject> {
        lock(&self.shared.latest).clone()
    }

    /// The audio side's statistics.
    pub fn stats(&self) -> &EngineStats {
        &self.stats
    }

    /// Waits until at least `count` solver runs have finished (successfully or not) and none is
    /// running, at most `timeout`; true if it got there. A plugin's `activate` uses it so that
    /// the first note already has an object.
    pub fn wait_for_solves(&self, count: u64, timeout: Duration) -> bool {
        let end = Instant::now() + timeout;
        while Instant::now() < end {
            let st = lock(&self.shared.status).clone();
            if st.solves >= count && st.state == SolveState::Idle {
                return true;
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        false
    }

    /// Waits until no request is waiting and no solve is running, at most `timeout`; true if
    /// it got there.
    pub fn wait_idle(&self, timeout: Duration) -> bool {
        let end = Instant::now() + timeout;
        while Instant::now() < end {
            let waiting = {
                let mb = lock(&self.shared.mailbox);
                mb.request.is_some() || mb.busy
            };
            if !waiting && lock(&self.shared.status).state == SolveState::Idle {
                return true;
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        false
    }
}

impl Drop for EngineControl {
    fn drop(&mut self) {
        lock(&self.shared.mailbox).shutdown = true;
        self.shared.wake.notify_one();
        if let Some(t) = self.thread.take() {
            // A solve in progress is interrupted where its solver allows, or finishes first.
            let _ = t.join();
        }
    }
}
