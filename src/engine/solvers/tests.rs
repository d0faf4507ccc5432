//! The chain's answers against cold solves, and how they hand over to one another.

use super::*;
use crate::eigen::{EigenOptions, SolverKind};
use crate::fem::ElementKind;
use crate::shape::primitives::Primitive;
use crate::shape::VoxelGrid;

/// A hex27x2 request for the lowest `modes` modes of `grid`.
fn request(grid: VoxelGrid, poisson_ratio: f64, modes: usize) -> ObjectRequest {
    ObjectRequest {
        grid,
        element: ElementKind::Hex27Blocks,
        poisson_ratio,
        solver: SolverKind::Auto,
        options: EigenOptions {
            count: ModeCount::First(modes),
            ..EigenOptions::default()
        },
        recording: None,
    }
}

/// A 12-voxel bowl, walls of 2.
fn small_bowl() -> VoxelGrid {
    Primitive::Bowl {
        diameter: 12.0,
        wall: 2.0,
    }
    .rasterize(1.0, 1.0)
    .unwrap()
}

/// `grid` with its `k`-th partial voxel filled: a one-voxel stroke.
fn stroked(grid: &VoxelGrid, k: usize) -> VoxelGrid {
    let (i, _) = grid.partial_voxels().nth(k).unwrap();
    let v = crate::shape::lattice_coords(i, grid.dims());
    let mut edited = grid.clone();
    edited.set(v[0], v[1], v[2], true);
    edited
}

#[test]
fn a_strokes_answers_reuse_the_cut_elements_of_the_last_exact_answer() {
    // The chain's wiring: the carried and exact answers to a stroke assemble from the
    // cache the previous exact answer filled, re-integrating only what the stroke touched
    // (at most the 27 elements whose input holds the voxel; `fem::cache` checks that the
    // cached model equals the uncached one). The carried answer copies the rows away from
    // the stroke from the previous model (`fem::assembly::reuse`), so it reads fewer
    // elements than the object has; the exact answer reads them all.
    let grid = small_bowl();
    let request = |grid: VoxelGrid| request(grid, 0.24, 10);
    let mut exact = IncrementalFemSolver::new();
    let mut carried = CarriedRitzSolver::instant(&exact, AnswerSwitch::default());
    exact.solve(&request(grid.clone())).unwrap();
    let cold = elements(&exact.elements).stats();
    assert!(cold.misses > 50, "{cold:?}");
    let stroke = request(stroked(&grid, 0));
    assert!(carried.applies(&stroke));
    carried.solve(&stroke).unwrap();
    let after = elements(&exact.elements).stats();
    assert!(after.misses <= 27, "{after:?}");
    assert!(
        after.hits + after.misses < cold.hits + cold.misses,
        "{after:?} after {cold:?}"
    );
    exact.solve(&stroke).unwrap();
    let whole = elements(&exact.elements).stats();
    assert_eq!(whole.misses, 0);
    assert!(
        whole.hits + 27 >= cold.hits + cold.misses,
        "{whole:?} after {cold:?}"
    );
}

#[test]
fn the_wide_answer_follows_the_instant_one_on_a_large_object_and_gives_way() {
    // The glass vase preset's shape (15.7k DOFs; a stroke's whole exact solve is predicted
    // over `REFRESH_MAX_PREDICTED_MS`), one partial voxel filled: the instant answer keeps
    // to the narrow patch (the wide one is 1,281 DOFs, over `WIDE_PATCH_MAX_DOFS`) and says
    // so, and only then does the wide answer apply. A stop at any of its polls ends it
    // with `Interrupted`; run out, it answers the same stroke with the same mode count.
    // On the small bowl (its exact answer refreshed during drags) it never applies.
    let kind = ElementKind::Hex27Blocks;
    let vase = crate::shape::spec::primitive_voxels(
        &Primitive::Cup {
            diameter: 16.0,
            height: 24.0,
            wall: 1.0,
        },
        None,
        1.0,
        kind.voxels_per_element(),
    )
    .unwrap();
    let solvers = interactive_solvers(None, AnswerSwitch::default(), &KeptAnswers::new());
    let [_, mut carried, mut wide, mut exact]: [Box<dyn ModeSolver>; 4] =
        solvers.try_into().ok().unwrap();
    assert_eq!(wide.name(), "carried-wide");
    for (grid, nu, large) in [(vase, 0.22, true), (small_bowl(), 0.24, false)] {
        exact.solve(&request(grid.clone(), nu, 60)).unwrap();
        let stroke = request(stroked(&grid, 0), nu, 60);
        assert!(!wide.applies(&stroke), "before the instant answer");
        let first = carried.solve(&stroke).unwrap();
        assert_eq!(wide.applies(&stroke), large);
        if !large {
            continue;
        }
        // A stop at each of its polls in turn (the assembly, the Gram matrices, the
        // patch's factor and each step of its modes, the dense problem) ends it there.
        let mut polls_before_stop = 0;
        let second = loop {
            let polls = std::cell::Cell::new(0);
            let stop_at = || {
                polls.set(polls.get() + 1);
                polls.get() > polls_before_stop
            };
            match wide.solve_until(&stroke, Stop::when(&stop_at)) {
                Err(e) => assert!(e.is_interrupted(), "{e} after {polls_before_stop} polls"),
                Ok(answer) => break answer,
            }
            polls_before_stop += 1;
        };
        assert!(polls_before_stop >= 5, "polled {polls_before_stop} times");
        assert_eq!(second.mode_count(), first.mode_count());
        // A newer stroke: the last one's verdict no longer applies.
        let next = request(stroked(&stroke.grid, 1), nu, 60);
        assert!(!wide.applies(&next));
    }
}

#[test]
fn a_drag_that_keeps_interrupting_the_exact_solve_gets_a_run_finished() {
    // The policy of `finish_when_left`: no run before an exact answer exists; none while
    // the last run answered; after one interrupted run, a run on an edit of the last
    // exact answer is finished, but not one on an unrelated object, nor one predicted
    // over `REFRESH_MAX_PREDICTED_MS`; an answered run resets it.
    let grid = small_bowl();
    let request = |grid: VoxelGrid| request(grid, 0.24, 10);
    let mut exact = IncrementalFemSolver::new();
    let first = request(grid.clone());
    assert!(!exact.finish_when_left(&first), "no exact answer yet");
    exact.solve(&first).unwrap();
    let (a, b) = (request(stroked(&grid, 0)), request(stroked(&grid, 1)));
    assert!(!exact.finish_when_left(&a), "the last run answered");
    let stop = || true;
    let interrupted = exact.solve_until(&a, Stop::when(&stop));
    assert!(interrupted.is_err_and(|e| e.is_interrupted()));
    assert!(exact.finish_when_left(&b));
    let other = request(
        Primitive::Sphere { diameter: 10.0 }
            .rasterize(1.0, 1.0)
            .unwrap(),
    );
    assert!(
        !exact.finish_when_left(&other),
        "not an edit of the last answer"
    );
    // The same edit asked for 400 modes: predicted over the limit.
    let mut many = b.clone();
    many.options.count = ModeCount::First(400);
    assert!(predicted_cold_ms(&many.grid, many.element, many.options.count) > 500.0);
    assert!(
        !exact.finish_when_left(&many),
        "predicted too slow to finish"
    );
    exact.solve(&b).unwrap();
    assert!(
        !exact.finish_when_left(&a),
        "an answered run resets the count"
    );
}

#[test]
fn a_second_chain_sharing_kept_answers_plays_the_same_object_without_a_solve() {
    // Two plugin instances (two chains) with one store of kept answers: the second asks
    // for the first's object and gets the very same answer (no solve: its own element
    // cache stays empty). Undo back to the first shape on the first chain is answered the
    // same way, and the carried answer, which would otherwise serve it, steps aside.
    let kept = KeptAnswers::new();
    let chain = || {
        let exact = IncrementalFemSolver {
            last: Arc::new(Mutex::new(None)),
            elements: SharedElements::default(),
            kept: kept.clone(),
            answers: AnswerSwitch::default(),
            unanswered_runs: 0,
        };
        let carried = CarriedRitzSolver::instant(&exact, AnswerSwitch::default());
        (exact, carried)
    };
    let grid = Primitive::Sphere { diameter: 10.0 }
        .rasterize(1.0, 1.0)
        .unwrap();
    let request = |grid: VoxelGrid| ObjectRequest {
        grid,
        element: ElementKind::Hex8Incompatible,
        poisson_ratio: 0.3,
        solver: SolverKind::Auto,
        options: EigenOptions {
            count: ModeCount::First(20),
            ..EigenOptions::default()
        },
        recording: None,
    };
    let (mut first, mut first_carried) = chain();
    let ObjectModes::Fem(a) = first.solve(&request(grid.clone())).unwrap() else {
        panic!("FEM")
    };
    let (mut second, _) = chain();
    let ObjectModes::Fem(b) = second.solve(&request(grid.clone())).unwrap() else {
        panic!("FEM")
    };
    assert!(Arc::ptr_eq(&a, &b), "the same answer, shared");
    assert_eq!(elements(&second.elements).stats().entries, 0, "no assembly");
    // A stroke on the first chain is new (carried, then exact); undoing it is not.
    let mut edited = grid.clone();
    let (i, _) = grid.partial_voxels().next().unwrap();
    let v = crate::shape::lattice_coords(i, grid.dims());
    edited.set(v[0], v[1], v[2], true);
    assert!(first_carried.applies(&request(edited.clone())));
    first_carried.solve(&request(edited.clone())).unwrap();
    first.solve(&request(edited)).unwrap();
    assert!(!first_carried.applies(&request(grid.clone())), "undo: kept");
    let ObjectModes::Fem(c) = first.solve(&request(grid.clone())).unwrap() else {
        panic!("FEM")
    };
    assert!(Arc::ptr_eq(&a, &c));
}

#[test]
fn the_coarse_answer_reads_its_plan_only_for_the_object_it_was_made_for() {
    // `applies` plans the coarse answer (the halved grid, its stiffening and expected
    // error); `solve` and `expected_error` read the plan for that object and plan afresh
    // for another. Truth: `solve_coarse` on each grid alone, bit for bit.
    let request = |grid: VoxelGrid| request(grid, 0.24, 60);
    // A 32-voxel glass bowl (predicted over the budget at 60 modes, a one-voxel wall) and
    // a small solid sphere (thick: another expected error).
    let large = request(
        Primitive::Bowl {
            diameter: 32.0,
            wall: 1.0,
        }
        .rasterize_on_blocks(1.0, 1.0, 2)
        .unwrap(),
    );
    let small = request(
        Primitive::Sphere { diameter: 10.0 }
            .rasterize_on_blocks(1.0, 1.0, 2)
            .unwrap(),
    );
    let exact = IncrementalFemSolver::new();
    let mut coarse = CoarseFemSolver::new(
        exact.last.clone(),
        exact.elements.clone(),
        exact.kept.clone(),
        AnswerSwitch::default(),
    );
    assert!(coarse.applies(&large));
    let alone = |r: &ObjectRequest| {
        solve_coarse(
            &r.grid,
            r.element,
            r.poisson_ratio,
            r.solver,
            &r.options,
            None,
            Stop::NEVER,
        )
        .unwrap()
        .solution
        .eigenvalues
    };
    let played = |m: ObjectModes| match m {
        ObjectModes::Fem(b) => b.solution.eigenvalues.clone(),
        _ => panic!("FEM"),
    };
    // The planned object, then another without `applies` (the plan is not its own).
    assert_eq!(played(coarse.solve(&large).unwrap()), alone(&large));
    assert_eq!(
        coarse.expected_error(&large),
        Some(COARSE_THIN_EXPECTED_ERROR)
    );
    assert_eq!(played(coarse.solve(&small).unwrap()), alone(&small));
    assert_eq!(
        coarse.expected_error(&small),
        Some(coarse_expected_error(&small.grid))
    );
    assert_eq!(coarse.expected_error(&small), Some(COARSE_EXPECTED_ERROR));
}
