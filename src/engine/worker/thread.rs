//! The worker thread's loop: take the newest request, run the solver chain on it, deliver
//! each answer to the audio thread, and free what the audio thread retired.
//!
//! Where it sits: [`super::EngineControl::spawn`] starts [`Worker::run`] on its own thread;
//! the mailbox, status and latest object it shares with the control are `worker.rs`'s, the
//! helper thread that detachable solvers run on is `worker/helper.rs`.

use super::helper::{BroughtBack, Helper, Waited};
use super::*;

/// The worker thread's state: the chain, the rings to and from the audio thread, and what
/// waits to be delivered.
pub(super) struct Worker {
    shared: Arc<Shared>,
    /// The chain; a slot is empty while its solver is away on the helper thread.
    solvers: Vec<Option<Box<dyn ModeSolver>>>,
    /// Where detachable solvers run, started with the first of them.
    helper: Option<Helper>,
    to_audio: Producer<Box<SolvedObject>>,
    retired: Consumer<Box<SolvedObject>>,
    /// A solved object the full ring could not take yet (a newer one replaces it).
    pending: Option<Box<SolvedObject>>,
    generation: u64,
}

impl Worker {
    /// A worker for `solvers`, delivering to `to_audio` and freeing what comes back on
    /// `retired`; [`Worker::run`] is its thread.
    pub(super) fn new(
        shared: Arc<Shared>,
        solvers: Vec<Box<dyn ModeSolver>>,
        to_audio: Producer<Box<SolvedObject>>,
        retired: Consumer<Box<SolvedObject>>,
    ) -> Self {
        Worker {
            shared,
            solvers: solvers.into_iter().map(Some).collect(),
            helper: None,
            to_audio,
            retired,
            pending: None,
            generation: 0,
        }
    }

    pub(super) fn run(mut self) {
        loop {
            self.housekeeping();
            if self.helper.as_ref().is_some_and(Helper::idle) {
                self.helper = None;
            }
            let request = {
                let mut mb = lock(&self.shared.mailbox);
                mb.busy = false;
                if mb.shutdown {
                    return;
                }
                if mb.request.is_none() {
                    mb = self
                        .shared
                        .wake
                        .wait_timeout(mb, POLL)
                        .map(|(g, _)| g)
                        .unwrap_or_else(|e| e.into_inner().0);
                }
                if mb.shutdown {
                    return;
                }
                let request = mb.request.take().map(|r| (r, mb.serial));
                mb.busy |= request.is_some();
                request
            };
            let request = request.or_else(|| {
                let polled = lock(&self.shared.source).as_mut().and_then(|f| f())?;
                let mut mb = lock(&self.shared.mailbox);
                mb.busy = true;
                mb.serial += 1;
                Some((polled, mb.serial))
            });
            if let Some((request, serial)) = request {
                self.solve(&request, serial);
            }
        }
    }

    /// Frees retired objects; retries a delivery the ring refused.
    fn housekeeping(&mut self) {
        while let Ok(old) = self.retired.pop() {
            drop(old);
        }
        if let Some(obj) = self.pending.take() {
            if let Err(PushError::Full(obj)) = self.to_audio.push(obj) {
                self.pending = Some(obj);
            }
        }
    }

    fn solve(&mut self, request: &ObjectRequest, serial: u64) {
        if let Some(recording) = &request.recording {
            let modes = ObjectModes::Recorded(RecordedObject::clone(recording));
            self.deliver(Ok(modes), "recording", Instant::now(), None, serial);
            self.shared.set_state(SolveState::Idle);
            return;
        }
        for i in 0..self.solvers.len() {
            if i > 0 && lock(&self.shared.mailbox).request.is_some() {
                // A newer edit is waiting: the slower solvers would answer an old question.
                break;
            }
            if self
                .helper
                .as_ref()
                .and_then(Helper::away)
                .is_some_and(|away| away <= i)
                && !self.bring_back_unless_superseded()
            {
                break;
            }
            let Some(solver) = &self.solvers[i] else {
                continue; // lost to a panic on the helper thread
            };
            if !solver.applies(request) {
                continue;
            }
            let name = solver.name();
            let since = Instant::now();
            self.shared.set_state(SolveState::Solving {
                solver: name,
                since,
            });
            let result = self.solve_until_superseded(i, request, serial);
            if result.as_ref().is_err_and(BasisError::is_interrupted) {
                lock(&self.shared.status).interrupted += 1;
                self.shared.status_changed();
                break;
            }
            let expected_error = self.solvers[i]
                .as_ref()
                .and_then(|s| s.expected_error(request));
            self.deliver(result, name, since, expected_error, serial);
        }
        self.shared.set_state(SolveState::Idle);
    }

    /// Puts the solver of a run the worker left back in its slot once the run has ended;
    /// gives up waiting (false) if a newer request arrives first, which the chain then
    /// answers from its start, beside the run still ending.
    fn bring_back_unless_superseded(&mut self) -> bool {
        let waiting = Instant::now();
        loop {
            let Some(helper) = self.helper.as_mut() else {
                return true;
            };
            if waiting.elapsed() >= helper::PATIENCE {
                // No stroke for a while: the drag has paused, and the exact answer to what is
                // heard now matters more than the run finishing for an earlier shape.
                helper.abandon();
            }
            match helper.bring_back(helper::WAIT_POLL) {
                BroughtBack::Solver(i, solver) => {
                    self.solvers[i] = Some(solver);
                    return true;
                }
                BroughtBack::Nothing => return true,
                BroughtBack::NotYet => {
                    let mb = lock(&self.shared.mailbox);
                    if mb.request.is_some() || mb.shutdown {
                        return false;
                    }
                }
            }
        }
    }

    /// Runs solver `i` on `request` (number `serial`), interrupted once the engine shuts down
    /// or a newer request waits that a solver before `i` in the chain answers (it will be
    /// heard sooner that way than after this solve; where none does, this answer is the next
    /// thing to play and is finished). The poll clones a newer request once and remembers
    /// its verdict, so a solver may poll it every few milliseconds. A detachable solver runs
    /// on the helper thread, and an interrupted run of it is left to end there by itself.
    fn solve_until_superseded(
        &mut self,
        i: usize,
        request: &ObjectRequest,
        serial: u64,
    ) -> Result<ObjectModes, BasisError> {
        let detach = self.solvers[i].as_ref().is_some_and(|s| s.detachable());
        if detach && self.helper.is_none() {
            // Without a helper thread (the system refused one) it runs here.
            self.helper = Helper::spawn().ok();
        }
        if detach && !self.bring_back_unless_superseded() {
            // One run at a time on the helper; a newer request came while the last ended.
            return Err(EigenError::Interrupted.into());
        }
        let (earlier, rest) = self.solvers.split_at_mut(i);
        let slot = &mut rest[0];
        let shared = &self.shared;
        let verdict = std::cell::Cell::new((serial, false));
        let poll = || {
            let (newer, request) = {
                let mb = lock(&shared.mailbox);
                if mb.shutdown {
                    return true;
                }
                match &mb.request {
                    None => return false,
                    Some(_) if mb.serial == verdict.get().0 => return verdict.get().1,
                    Some(r) => (mb.serial, r.clone()),
                }
            };
            let answered_sooner = earlier.iter().flatten().any(|s| s.applies(&request));
            verdict.set((newer, answered_sooner));
            answered_sooner
        };
        let Some(solver) = slot.take() else {
            return Err(BasisError::SolverLost);
        };
        let solver = match (detach, self.helper.as_mut()) {
            (true, Some(helper)) => match helper.start(solver, request) {
                Ok(()) => {
                    return match helper.wait(i, poll) {
                        Waited::Answered(solver, answer) => {
                            *slot = Some(solver);
                            answer
                        }
                        Waited::Left => Err(EigenError::Interrupted.into()),
                        Waited::Lost => Err(BasisError::SolverLost),
                    }
                }
                Err(solver) => solver,
            },
            _ => solver,
        };
        let solver = slot.insert(solver);
        solver.solve_until(request, Stop::when(&poll))
    }

    /// Hands a solver's answer (begun at `since`) to the audio side and reports it.
    fn deliver(
        &mut self,
        result: Result<ObjectModes, BasisError>,
        name: &'static str,
        since: Instant,
        expected_error: Option<f64>,
        request: u64,
    ) {
        let ms = since.elapsed().as_secs_f64() * 1e3;
        let report = match result {
            Ok(basis) => {
                self.generation += 1;
                let modes = basis.mode_count();
                let warm_start = basis.fem().is_some_and(|b| b.solution.warm_start);
                let basis = Arc::new(basis);
                *lock(&self.shared.latest) = Some(LatestObject {
                    generation: self.generation,
                    basis: basis.clone(),
                });
                // Replaces (frees, here) an older object still waiting for the audio side.
                self.pending = Some(Box::new(SolvedObject::new(
                    basis,
                    self.generation,
                    name,
                    ms,
                )));
                self.housekeeping();
                SolveReport {
                    solver: name,
                    generation: self.generation,
                    ms,
                    modes,
                    error: None,
                    expected_error,
                    warm_start,
                    request,
                }
            }
            Err(e) => SolveReport {
                solver: name,
                generation: 0,
                ms,
                modes: 0,
                error: Some(e.to_string()),
                expected_error,
                warm_start: false,
                request,
            },
        };
        let mut st = lock(&self.shared.status);
        if report.error.is_none() {
            st.playing = Some(report.clone());
        }
        st.last = Some(report);
        st.solves += 1;
        drop(st);
        self.shared.status_changed();
    }
}
