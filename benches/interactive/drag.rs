//! `--drag`: edit-to-sound latency of a sculpting drag through the engine's worker (the
//! module docs of `benches/interactive.rs` say what it measures).

use super::{grid_of, max_relative_difference, stroke, MODES};
use modalforge::basis::{BasisError, ModeBasis};
use modalforge::eigen::{EigenOptions, ModeCount, SolverKind, Stop};
use modalforge::engine::{
    interactive_solvers, AnswerSwitch, Engine, EngineConfig, KeptAnswers, ModeSolver, ObjectModes,
    ObjectRequest, Voicing,
};
use modalforge::fem::ElementKind;
use modalforge::material::Material;
use modalforge::shape::VoxelGrid;
use std::time::{Duration, Instant};

/// Strokes in one drag, unless `--strokes K` says otherwise.
pub const STROKES: usize = 24;

/// Strokes after which [`drift`] measures the carried answer from the exact answer before
/// the drag.
const DRIFT_AT: [usize; 3] = [1, 4, 12];

/// A chain solver run one of the older ways ([`Obsolete`], other than the engine's own).
struct Wrapped(Box<dyn ModeSolver>, Obsolete);

impl ModeSolver for Wrapped {
    fn name(&self) -> &'static str {
        self.0.name()
    }
    fn solve(&mut self, r: &ObjectRequest) -> Result<ObjectModes, BasisError> {
        self.0.solve(r)
    }
    /// Run to its end: it ignores the worker's stop, as every solver did before the worker
    /// could interrupt them.
    fn solve_until(&mut self, r: &ObjectRequest, stop: Stop) -> Result<ObjectModes, BasisError> {
        match self.1 {
            Obsolete::RunToEnd => self.0.solve(r),
            _ => self.0.solve_until(r, stop),
        }
    }
    fn applies(&self, r: &ObjectRequest) -> bool {
        self.0.applies(r)
    }
    fn expected_error(&self, request: &ObjectRequest) -> Option<f64> {
        self.0.expected_error(request)
    }
    /// In place: on the worker thread, which waits for the obsolete run's next poll, as it
    /// did before detachable solvers ran apart.
    fn detachable(&self) -> bool {
        self.1 == Obsolete::Stopped && self.0.detachable()
    }
    // `finish_when_left`: never, as before the exact solver finished obsolete runs.
}

/// How the worker treats an exact solve a newer stroke made obsolete.
#[derive(Clone, Copy, PartialEq)]
enum Obsolete {
    /// Left apart on the helper thread, stopped at its next poll or, every few strokes,
    /// finished to refresh the carried answers' start (the engine as it is).
    LeftApart,
    /// Left apart and always stopped at its next poll (the engine before the refresh).
    Stopped,
    /// Interrupted at its next poll, the worker waiting for it.
    InPlace,
    /// Run to its end.
    RunToEnd,
}

/// The drag on `spec` (named `name`, Poisson's ratio `nu`).
pub fn run(interval_ms: u64, strokes: usize, name: &str, spec: &str, nu: f64) {
    let glass = Material::preset("glass").expect("glass");
    println!(
        "\ndrag on {name} ({spec}): {} one-voxel strokes every {interval_ms} ms, \
         {MODES} modes, hex27x2; ms from a stroke to an answer to it (or a later one) playing",
        strokes
    );
    println!(
        "{:<14} {:>7} {:>7} {:>7} {:>7} {:>12} {:>9} {:>7} {:>9} {:>9} {:>6} {:>7} {:>9} {:>9} {:>7}",
        "worker",
        "median",
        "p90",
        "max",
        "total",
        "interrupted",
        "answers",
        "solve",
        "err med",
        "err max",
        "wide",
        "solve",
        "err med",
        "err max",
        "exact"
    );
    // Each stroke's shape and its exact modes, for the error of the answers played and the
    // drift (`DRIFT_AT`).
    let kind = ElementKind::Hex27Blocks;
    let exact_options = EigenOptions {
        count: ModeCount::First(MODES),
        ..Default::default()
    };
    let mut shapes = vec![grid_of(spec, kind)];
    for _ in 0..strokes.max(DRIFT_AT[2]) {
        let next = stroke(shapes.last().expect("a shape"), true);
        shapes.push(next);
    }
    let exact: Vec<ModeBasis> = shapes
        .iter()
        .map(|g| ModeBasis::solve(g, kind, nu, SolverKind::Auto, &exact_options).expect("exact"))
        .collect();
    // The first drag of a process runs slower (its buffers, tables and caches are cold:
    // whichever way ran first lost 5-20 ms of median on the cup in stop 66's runs), so a drag
    // the engine's way warms the process up first and is not printed.
    let ways = [
        Obsolete::LeftApart,
        Obsolete::LeftApart,
        Obsolete::Stopped,
        Obsolete::InPlace,
        Obsolete::RunToEnd,
    ];
    for (drag, obsolete) in ways.into_iter().enumerate() {
        let solvers = interactive_solvers(None, AnswerSwitch::default(), &KeptAnswers::new())
            .into_iter()
            .map(|s| match obsolete {
                Obsolete::LeftApart => s,
                other => Box::new(Wrapped(s, other)) as Box<dyn ModeSolver>,
            })
            .collect();
        let voicing = Voicing::from_material(&glass, nu).expect("voicing");
        let (_audio, control) =
            Engine::start(48_000.0, EngineConfig::default(), voicing, solvers).expect("engine");
        let request = |grid| ObjectRequest {
            grid,
            element: ElementKind::Hex27Blocks,
            poisson_ratio: nu,
            solver: SolverKind::Auto,
            options: EigenOptions {
                count: ModeCount::First(MODES),
                ..Default::default()
            },
            recording: None,
        };
        let mut grid = grid_of(spec, ElementKind::Hex27Blocks);
        control.request(request(grid.clone()));
        assert!(
            control.wait_idle(Duration::from_secs(60)),
            "the first solve"
        );
        let first = control.status().playing.expect("an answer").request;
        let start = Instant::now();
        let mut sent = Vec::new();
        let mut heard = vec![None; strokes];
        let solves_before = control.status().solves;
        // The carried answers' own time in the worker (`SolveReport::ms`: from the solver's
        // start to its answer handed to the audio side), each report once.
        let mut quick_ms = Vec::new();
        let mut last_seen = None;
        // Each carried answer's largest frequency error against the exact modes of the shape
        // it answers; the same for the second, wide answers (`CarriedRitzSolver`, `Reach::Wide`).
        let mut errors = Vec::new();
        let (mut wide_ms, mut wide_errors) = (Vec::new(), Vec::new());
        while heard.iter().any(Option::is_none) {
            let due = start + Duration::from_millis(interval_ms * sent.len() as u64);
            if sent.len() < strokes && Instant::now() >= due {
                grid = stroke(&grid, true);
                control.request(request(grid.clone()));
                sent.push(Instant::now());
            }
            let status = control.status();
            if let Some(last) = status.last.filter(|l| l.error.is_none()) {
                if last_seen != Some((last.request, last.solver)) {
                    last_seen = Some((last.request, last.solver));
                    let scored = match last.solver {
                        "carried" => Some((&mut quick_ms, &mut errors)),
                        "carried-wide" => Some((&mut wide_ms, &mut wide_errors)),
                        _ => None,
                    };
                    if let Some((times, errs)) = scored.filter(|_| last.request > first) {
                        times.push(last.ms);
                        let stroke = (last.request - first) as usize;
                        let played = control
                            .latest_object()
                            .filter(|o| o.generation == last.generation);
                        if let Some(basis) = played.as_ref().and_then(|o| o.basis.fem()) {
                            errs.push(max_relative_difference(basis, &exact[stroke]));
                        }
                    }
                }
            }
            if let Some(playing) = status.playing {
                let answered = (playing.request - first) as usize;
                for (k, h) in heard.iter_mut().enumerate().take(answered.min(sent.len())) {
                    if h.is_none() {
                        *h = Some(sent[k].elapsed().as_secs_f64() * 1e3);
                    }
                }
            }
            assert!(
                start.elapsed() < Duration::from_secs(120),
                "the drag never settled"
            );
            std::thread::sleep(Duration::from_micros(500));
        }
        let total = start.elapsed().as_secs_f64() * 1e3;
        // When the exact answer to the last stroke plays.
        let last_sent = *sent.last().expect("strokes");
        let last_request = first + strokes as u64;
        let mut final_ms = f64::NAN;
        while final_ms.is_nan() && start.elapsed() < Duration::from_secs(120) {
            if let Some(p) = control.status().playing {
                if p.request == last_request && p.solver == "fem" {
                    final_ms = last_sent.elapsed().as_secs_f64() * 1e3;
                }
            }
            std::thread::sleep(Duration::from_micros(500));
        }
        // The last stroke's exact solve may still be running: wait for it, or it would run
        // beside the next way's first strokes.
        assert!(
            control.wait_idle(Duration::from_secs(60)),
            "the drag's last solve"
        );
        let mut ms: Vec<f64> = heard.into_iter().flatten().collect();
        ms.sort_by(f64::total_cmp);
        let at = |q: f64| ms[((ms.len() - 1) as f64 * q).round() as usize];
        for v in [&mut quick_ms, &mut errors, &mut wide_ms, &mut wide_errors] {
            v.sort_by(f64::total_cmp);
        }
        if drag == 0 {
            continue;
        }
        let median = |v: &[f64]| v.get(v.len() / 2).copied().unwrap_or(f64::NAN);
        let largest = |v: &[f64]| v.last().copied().unwrap_or(f64::NAN);
        println!(
            "{:<14} {:>7.0} {:>7.0} {:>7.0} {:>7.0} {:>12} {:>9} {:>7.0} {:>9.1e} {:>9.1e} {:>6} {:>7.0} {:>9.1e} {:>9.1e} {:>7.0}",
            match obsolete {
                Obsolete::LeftApart => "left apart",
                Obsolete::Stopped => "stopped",
                Obsolete::InPlace => "in place",
                Obsolete::RunToEnd => "run to end",
            },
            at(0.5),
            at(0.9),
            at(1.0),
            total,
            control.status().interrupted,
            control.status().solves - solves_before,
            median(&quick_ms),
            median(&errors),
            largest(&errors),
            wide_ms.len(),
            median(&wide_ms),
            median(&wide_errors),
            largest(&wide_errors),
            final_ms
        );
    }
    drift(&shapes, &exact, nu);
}

/// While a drag keeps interrupting the exact solve, each stroke's carried answer starts
/// from the exact answer before the drag: its largest frequency error against a cold solve
/// after 1, 4 and 12 strokes (`shapes[k]` and `exact[k]`: the drag's shape after `k` strokes
/// and its cold solve, which `run` made for the answers played), for the instant answer and
/// the second, wide one (`-` where the instant answer's patch is as wide as it gets).
fn drift(shapes: &[VoxelGrid], exact: &[ModeBasis], nu: f64) {
    let mut line =
        String::from("carried answer from the exact answer before the drag, largest error:");
    let before = std::sync::Arc::new(exact[0].clone());
    let mut wide_line = String::from("  the second, wide answer:");
    for k in DRIFT_AT {
        let instant = ModeBasis::carried_ritz_factored(
            &shapes[k],
            ElementKind::Hex27Blocks,
            nu,
            MODES,
            &before,
            None,
        )
        .expect("comparable")
        .expect("carried");
        wide_line += &if instant.carried_widens() {
            let wide = ModeBasis::carried_ritz_wide(
                &shapes[k],
                ElementKind::Hex27Blocks,
                nu,
                MODES,
                &before,
                None,
                Stop::NEVER,
            )
            .expect("comparable")
            .expect("carried wide");
            format!(" {:.1e}", max_relative_difference(&wide, &exact[k]))
        } else {
            String::from(" -")
        };
        let carried = ModeBasis::carried_ritz(
            &shapes[k],
            ElementKind::Hex27Blocks,
            nu,
            MODES,
            &exact[0],
            None,
        )
        .expect("comparable")
        .expect("carried");
        let e = max_relative_difference(&carried, &exact[k]);
        line += &format!(" {e:.1e} after {k} stroke{}", if k > 1 { "s" } else { "" });
    }
    println!("{line}\n{wide_line}");
}
