//! The worker's solver chain. Truths: counted solver calls (an edit during a solve is
//! coalesced to the newest, an obsolete slow answer gives way), the thread each solve runs
//! on, and the chain's answers checked against cold solves of the same grid.

use super::*;

/// Counts calls and sleeps, to see coalescing.
struct Slow {
    calls: Arc<AtomicU64>,
}

impl ModeSolver for Slow {
    fn name(&self) -> &'static str {
        "slow"
    }
    fn solve(&mut self, r: &ObjectRequest) -> Result<ObjectModes, BasisError> {
        self.calls.fetch_add(1, Ordering::SeqCst);
        std::thread::sleep(Duration::from_millis(300));
        FemSolver.solve(r)
    }
}

#[test]
fn the_engine_solves_on_its_worker_thread_alone() {
    // faer's default global parallelism is a rayon pool over every core, which its dense
    // helpers without an explicit `Par` use: an engine makes it sequential, so a solve keeps
    // to the worker thread (and no pool thread reserves a gemm workspace).
    faer::set_global_parallelism(faer::Par::rayon(0));
    let (_audio, _control) = Engine::start(
        FS,
        EngineConfig::default(),
        steel(),
        vec![Box::new(FemSolver)],
    )
    .unwrap();
    assert!(matches!(faer::get_global_parallelism(), faer::Par::Seq));
}

#[test]
fn edits_during_a_solve_coalesce_to_the_newest() {
    // Five edits while the first is being solved: the worker solves the first and the last
    // only, and the audio side ends up with the last shape.
    let calls = Arc::new(AtomicU64::new(0));
    let (mut audio, control) = Engine::start(
        FS,
        EngineConfig::default(),
        steel(),
        vec![Box::new(Slow {
            calls: calls.clone(),
        })],
    )
    .unwrap();
    for len in [10, 11, 12, 13, 14] {
        control.request(request(bar(len), 10));
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(control.wait_idle(Duration::from_secs(60)));
    assert_eq!(calls.load(Ordering::SeqCst), 2);
    audio.process(&mut [0.0; 64], &[]);
    assert_eq!(audio.object_extent(), Some(14));
}

/// A first answer that applies to every request or to none.
struct Quick {
    applies: bool,
}

impl ModeSolver for Quick {
    fn name(&self) -> &'static str {
        "quick"
    }
    fn applies(&self, _r: &ObjectRequest) -> bool {
        self.applies
    }
    fn solve(&mut self, r: &ObjectRequest) -> Result<ObjectModes, BasisError> {
        FemSolver.solve(r)
    }
}

/// A slow exact answer (300 ms) that polls its stop every 2 ms, counting how it ended.
struct Patient {
    finished: Arc<AtomicU64>,
    interrupted: Arc<AtomicU64>,
}

impl ModeSolver for Patient {
    fn name(&self) -> &'static str {
        "patient"
    }
    fn solve(&mut self, r: &ObjectRequest) -> Result<ObjectModes, BasisError> {
        self.solve_until(r, crate::eigen::Stop::NEVER)
    }
    fn solve_until(
        &mut self,
        r: &ObjectRequest,
        stop: crate::eigen::Stop,
    ) -> Result<ObjectModes, BasisError> {
        let start = std::time::Instant::now();
        while start.elapsed() < Duration::from_millis(300) {
            if let Err(e) = stop.check() {
                self.interrupted.fetch_add(1, Ordering::SeqCst);
                return Err(e.into());
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        self.finished.fetch_add(1, Ordering::SeqCst);
        FemSolver.solve(r)
    }
}

#[test]
fn a_slow_answer_made_obsolete_gives_way_to_a_faster_one() {
    // An edit arrives while the slow exact answer to the one before is being solved. Where a
    // faster solver earlier in the chain answers the new edit, the obsolete solve is given up
    // (the new edit is heard at once, not after it); where none does, it is finished (it is
    // the next thing to play). Either way the newest edit ends up playing, answered last.
    for first_applies in [true, false] {
        let (finished, interrupted) = (Arc::new(AtomicU64::new(0)), Arc::new(AtomicU64::new(0)));
        let (mut audio, control) = Engine::start(
            FS,
            EngineConfig::default(),
            steel(),
            vec![
                Box::new(Quick {
                    applies: first_applies,
                }),
                Box::new(Patient {
                    finished: finished.clone(),
                    interrupted: interrupted.clone(),
                }),
            ],
        )
        .unwrap();
        control.request(request(bar(10), 10));
        let t = std::time::Instant::now();
        while !matches!(
            control.status().state,
            SolveState::Solving {
                solver: "patient",
                ..
            }
        ) {
            assert!(
                t.elapsed() < Duration::from_secs(60),
                "the first solve never started"
            );
            std::thread::sleep(Duration::from_millis(1));
        }
        std::thread::sleep(Duration::from_millis(30));
        control.request(request(bar(14), 10));
        assert!(control.wait_idle(Duration::from_secs(60)));
        let status = control.status();
        let (done, given_up) = (
            finished.load(Ordering::SeqCst),
            interrupted.load(Ordering::SeqCst),
        );
        if first_applies {
            assert_eq!((done, given_up, status.interrupted), (1, 1, 1));
        } else {
            assert_eq!((done, given_up, status.interrupted), (2, 0, 0));
        }
        let last = status.last.unwrap();
        assert_eq!((last.solver, last.request), ("patient", 2));
        audio.process(&mut [0.0; 64], &[]);
        assert_eq!(audio.object_extent(), Some(14));
    }
}

/// A detachable exact answer with a step that cannot be cut: it waits for `gate` to open
/// before its first poll of the stop, then counts how it ended and the thread it ran on.
struct Stubborn {
    gate: Arc<std::sync::atomic::AtomicBool>,
    finished: Arc<AtomicU64>,
    interrupted: Arc<AtomicU64>,
    threads: Arc<std::sync::Mutex<Vec<String>>>,
}

impl ModeSolver for Stubborn {
    fn name(&self) -> &'static str {
        "stubborn"
    }
    fn detachable(&self) -> bool {
        true
    }
    fn solve(&mut self, r: &ObjectRequest) -> Result<ObjectModes, BasisError> {
        self.solve_until(r, crate::eigen::Stop::NEVER)
    }
    fn solve_until(
        &mut self,
        r: &ObjectRequest,
        stop: crate::eigen::Stop,
    ) -> Result<ObjectModes, BasisError> {
        let name = std::thread::current().name().unwrap_or("").to_string();
        self.threads.lock().unwrap().push(name);
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

#[test]
fn an_edit_is_answered_while_an_obsolete_solve_finishes_an_uncut_step_apart() {
    // The exact answer to the first edit is stuck in a step that polls no stop (as a
    // factorisation is) when a second edit arrives. The faster solver's answer to the second
    // is delivered while that step still runs, on the worker's helper thread; once the step
    // ends the run sees its stop and gives up, and the exact answer to the second edit is
    // solved and plays last. In place, the worker would wait for the step: the quick answer
    // could not arrive while the gate is shut, and this test would fail on it.
    let gate = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let (finished, interrupted) = (Arc::new(AtomicU64::new(0)), Arc::new(AtomicU64::new(0)));
    let threads = Arc::new(std::sync::Mutex::new(Vec::new()));
    let (mut audio, control) = Engine::start(
        FS,
        EngineConfig::default(),
        steel(),
        vec![
            Box::new(Quick { applies: true }),
            Box::new(Stubborn {
                gate: gate.clone(),
                finished: finished.clone(),
                interrupted: interrupted.clone(),
                threads: threads.clone(),
            }),
        ],
    )
    .unwrap();
    let wait_for = |what: &dyn Fn(&WorkerStatus) -> bool| {
        let t = std::time::Instant::now();
        while !what(&control.status()) {
            if t.elapsed() > Duration::from_secs(30) {
                return false;
            }
            std::thread::sleep(Duration::from_millis(1));
        }
        true
    };
    control.request(request(bar(10), 10));
    let stuck = wait_for(&|st| {
        matches!(
            st.state,
            SolveState::Solving {
                solver: "stubborn",
                ..
            }
        )
    });
    control.request(request(bar(14), 10));
    let answered_beside = stuck
        && wait_for(&|st| {
            st.playing
                .as_ref()
                .is_some_and(|p| (p.solver, p.request) == ("quick", 2))
        });
    // Whatever happened, let the stuck step end so the engine can shut down.
    let still_stuck = interrupted.load(Ordering::SeqCst) + finished.load(Ordering::SeqCst) == 0;
    gate.store(true, Ordering::SeqCst);
    assert!(stuck, "the exact solve never started");
    assert!(answered_beside, "the second edit waited for the stuck step");
    assert!(
        still_stuck,
        "the stuck step ended before the quick answer was checked"
    );
    assert!(control.wait_idle(Duration::from_secs(60)));
    let status = control.status();
    assert_eq!(
        (
            finished.load(Ordering::SeqCst),
            interrupted.load(Ordering::SeqCst),
            status.interrupted
        ),
        (1, 1, 1)
    );
    let last = status.last.unwrap();
    assert_eq!((last.solver, last.request), ("stubborn", 2));
    assert!(
        threads
            .lock()
            .unwrap()
            .iter()
            .all(|t| t == "modalforge-solve"),
        "{:?}",
        threads.lock().unwrap()
    );
    audio.process(&mut [0.0; 64], &[]);
    assert_eq!(audio.object_extent(), Some(14));
}

/// A detachable solver that records the thread each run is on.
struct Recorded {
    threads: Arc<std::sync::Mutex<Vec<(std::thread::ThreadId, String)>>>,
}

impl ModeSolver for Recorded {
    fn name(&self) -> &'static str {
        "recorded"
    }
    fn detachable(&self) -> bool {
        true
    }
    fn solve(&mut self, r: &ObjectRequest) -> Result<ObjectModes, BasisError> {
        let thread = std::thread::current();
        let name = thread.name().unwrap_or("").to_string();
        self.threads.lock().unwrap().push((thread.id(), name));
        FemSolver.solve(r)
    }
}

#[test]
fn the_helper_thread_serves_runs_in_a_row_and_ends_when_idle() {
    // Two edits in a row run on one helper thread; after the helper's idle time with nothing
    // to do the thread has ended (and its matrix-product workspace with it), and the next
    // edit runs on a new one.
    let threads = Arc::new(std::sync::Mutex::new(Vec::new()));
    let (_audio, control) = Engine::start(
        FS,
        EngineConfig::default(),
        steel(),
        vec![Box::new(Recorded {
            threads: threads.clone(),
        })],
    )
    .unwrap();
    for len in [10, 11] {
        control.request(request(bar(len), 10));
        assert!(control.wait_idle(Duration::from_secs(60)));
    }
    std::thread::sleep(crate::engine::worker::helper::IDLE * 2 + Duration::from_millis(100));
    control.request(request(bar(12), 10));
    assert!(control.wait_idle(Duration::from_secs(60)));
    let ids = threads.lock().unwrap().clone();
    assert_eq!(ids.len(), 3);
    assert!(
        ids.iter().all(|(_, name)| name == "modalforge-solve"),
        "{ids:?}"
    );
    assert_eq!(ids[0].0, ids[1].0, "runs in a row share the helper");
    assert_ne!(ids[1].0, ids[2].0, "an idle helper ends");
}

/// A hollow box, walls two voxels thick (survives halving its resolution).
fn thick_box(side: usize) -> VoxelGrid {
    let solid = VoxelGrid::from_fn([side, side, side], 0.01, |_, _, _| true).unwrap();
    crate::shape::ops::hollow(&solid, 2)
}

#[test]
fn a_brush_stroke_plays_the_carried_answer_then_the_exact_one() {
    // The interactive chain on a stroke: the carried answer is delivered first, within its
    // stated error of the exact one, and the exact answer (solved cold) replaces it.
    let (mut audio, control) = Engine::start(
        FS,
        EngineConfig::default(),
        steel(),
        interactive_solvers(None, AnswerSwitch::default(), &KeptAnswers::new()),
    )
    .unwrap();
    let grid = thick_box(10);
    control.request(request(grid.clone(), 20));
    assert!(control.wait_idle(Duration::from_secs(60)));
    let first = control.status();
    assert_eq!(first.last.as_ref().unwrap().solver, "fem");
    let mut edited = grid.clone();
    edited.set(5, 5, 9, false);
    control.request(request(edited, 20));
    assert!(control.wait_idle(Duration::from_secs(60)));
    let st = control.status();
    assert_eq!(st.solves, first.solves + 2, "carried, then exact: {st:?}");
    assert_eq!(st.last.as_ref().unwrap().solver, "fem");
    assert_eq!(st.playing.as_ref().unwrap().expected_error, None);
    let exact = control.latest_object().unwrap();
    // Both answers went to the audio side; the newest is the exact one.
    audio.process(&mut [0.0; 16], &[]);
    assert!(audio.has_object());
    let carried = ModeBasis::carried_ritz(
        &exact_grid(&exact),
        ElementKind::Hex8Incompatible,
        Material::preset("steel").unwrap().poisson_ratio,
        20,
        FemSolver.solve(&request(grid, 20)).unwrap().fem().unwrap(),
        None,
    )
    .unwrap()
    .unwrap();
    for (c, e) in carried
        .solution
        .eigenvalues
        .iter()
        .zip(exact.basis.eigenvalues())
    {
        let err = (c.sqrt() - e.sqrt()).abs() / e.sqrt();
        assert!(err < CARRIED_EXPECTED_ERROR, "{err:.1e}");
    }
}

/// The grid a basis was solved for, rebuilt from its voxels.
fn exact_grid(latest: &crate::engine::LatestObject) -> VoxelGrid {
    let dims = latest.basis.grid_dims();
    let mut g = VoxelGrid::new(dims, 0.01).unwrap();
    for v in &latest.basis.fem().unwrap().model.voxels {
        g.set(v[0], v[1], v[2], true);
    }
    g
}

#[test]
fn the_predictor_answers_first_and_the_answers_switch_selects() {
    // Auto: a new object gets the neural answer, then the exact one; FEM only: no neural
    // answer; Predictor only: no FEM solve, and the predicted modes reach the audio side and
    // play finite audio. Any weights exercise the chain (a randomly initialised network).
    use crate::predictor::network::{ModeNet, Widths};
    use crate::predictor::Predictor;
    let predictor = Predictor::from_model(
        ModeNet::new(Widths::SHIPPED, &burn::tensor::Device::flex()),
        None,
    );
    let answers = AnswerSwitch::default();
    let (mut audio, control) = Engine::start(
        FS,
        EngineConfig::default(),
        steel(),
        interactive_solvers(
            Some(std::sync::Arc::new(predictor)),
            answers.clone(),
            &KeptAnswers::new(),
        ),
    )
    .unwrap();
    control.request(request(thick_box(8), 20));
    assert!(control.wait_idle(Duration::from_secs(60)));
    let st = control.status();
    assert_eq!(st.solves, 2, "neural, then exact: {st:?}");
    assert_eq!(st.last.as_ref().unwrap().solver, "fem");
    answers.set(Answers::FemOnly);
    control.request(request(bar(20), 20));
    assert!(control.wait_idle(Duration::from_secs(60)));
    let fem_only = control.status();
    assert_eq!(fem_only.solves, st.solves + 1, "{fem_only:?}");
    answers.set(Answers::PredictorOnly);
    control.request(request(thick_box(10), 20));
    assert!(control.wait_idle(Duration::from_secs(60)));
    let neural = control.status();
    assert_eq!(neural.solves, fem_only.solves + 1, "{neural:?}");
    assert_eq!(neural.last.as_ref().unwrap().solver, "neural");
    assert_eq!(
        neural.playing.as_ref().unwrap().expected_error,
        Some(NEURAL_EXPECTED_ERROR)
    );
    let latest = control.latest_object().unwrap();
    assert!(latest.basis.fem().is_none());
    let out = render(&mut audio, 4800, &[strike(60, 1.0)]);
    assert!(out.iter().all(|s| s.is_finite()));
}

/// A status watcher hears every change a window shows: the solve starting, the answer
/// delivered, the worker idle again (three calls for one solve), each seen with the status
/// already changed; a replaced watcher is no longer called.
#[test]
fn a_status_watcher_hears_each_change_of_a_solve() {
    use std::sync::atomic::AtomicUsize;
    let (_audio, control) = Engine::start(
        FS,
        EngineConfig::default(),
        steel(),
        vec![Box::new(FemSolver)],
    )
    .unwrap();
    let control = Arc::new(control);
    let calls = Arc::new(AtomicUsize::new(0));
    let seen = Arc::new(std::sync::Mutex::new(Vec::new()));
    {
        let (calls, seen) = (calls.clone(), seen.clone());
        let weak = Arc::downgrade(&control);
        control.watch_status(Arc::new(move || {
            calls.fetch_add(1, Ordering::SeqCst);
            if let Some(c) = weak.upgrade() {
                let st = c.status();
                let solving = matches!(st.state, SolveState::Solving { .. });
                seen.lock().unwrap().push((solving, st.solves));
            }
        }));
    }
    // The last call comes just after the worker turns idle, so wait_idle may return first.
    let settle = |calls: &AtomicUsize, want: usize| {
        let t0 = std::time::Instant::now();
        while calls.load(Ordering::SeqCst) < want && t0.elapsed() < Duration::from_secs(5) {
            std::thread::sleep(Duration::from_millis(5));
        }
    };
    control.request(request(bar(12), 10));
    assert!(control.wait_idle(Duration::from_secs(60)));
    settle(&calls, 3);
    assert_eq!(calls.load(Ordering::SeqCst), 3);
    assert_eq!(
        *seen.lock().unwrap(),
        vec![(true, 0), (true, 1), (false, 1)]
    );
    let later = Arc::new(AtomicUsize::new(0));
    let l = later.clone();
    control.watch_status(Arc::new(move || {
        l.fetch_add(1, Ordering::SeqCst);
    }));
    control.request(request(bar(14), 10));
    assert!(control.wait_idle(Duration::from_secs(60)));
    settle(&later, 3);
    assert_eq!(
        (calls.load(Ordering::SeqCst), later.load(Ordering::SeqCst)),
        (3, 3)
    );
}
