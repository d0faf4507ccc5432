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
use std::time::{Duration, Instant};

/// Strokes in one drag.
const STROKES: usize = 12;

/// A chain solver that ignores the worker's stop, as every solver did before the worker
/// could interrupt them: the comparison.
struct Uninterrupted(Box<dyn ModeSolver>);

impl ModeSolver for Uninterrupted {
    fn name(&self) -> &'static str {
        self.0.name()
    }
    fn solve(&mut self, r: &ObjectRequest) -> Result<ObjectModes, BasisError> {
        self.0.solve(r)
    }
    fn solve_until(&mut self, r: &ObjectRequest, _: Stop) -> Result<ObjectModes, BasisError> {
        self.0.solve(r)
    }
    fn applies(&self, r: &ObjectRequest) -> bool {
        self.0.applies(r)
    }
    fn expected_error(&self, request: &ObjectRequest) -> Option<f64> {
        self.0.expected_error(request)
    }
}

/// A chain solver interrupted where it polls its stop, on the worker thread: the worker waits
/// for the obsolete run's next poll, as it did before detachable solvers ran apart.
struct InPlace(Box<dyn ModeSolver>);

impl ModeSolver for InPlace {
    fn name(&self) -> &'static str {
        self.0.name()
    }
    fn solve(&mut self, r: &ObjectRequest) -> Result<ObjectModes, BasisError> {
        self.0.solve(r)
    }
    fn solve_until(&mut self, r: &ObjectRequest, stop: Stop) -> Result<ObjectModes, BasisError> {
        self.0.solve_until(r, stop)
    }
    fn applies(&self, r: &ObjectRequest) -> bool {
        self.0.applies(r)
    }
    fn expected_error(&self, request: &ObjectRequest) -> Option<f64> {
        self.0.expected_error(request)
    }
}

/// How the worker treats an exact solve a newer stroke made obsolete.
#[derive(Clone, Copy, PartialEq)]
enum Obsolete {
    /// Left to end by itself on the helper thread (the engine as it is).
    LeftApart,
    /// Interrupted at its next poll, the worker waiting for it.
    InPlace,
    /// Run to its end.
    RunToEnd,
}

/// The drag on `spec` (named `name`, Poisson's ratio `nu`).
pub fn run(interval_ms: u64, name: &str, spec: &str, nu: f64) {
    let glass = Material::preset("glass").expect("glass");
    println!(
        "\ndrag on {name} ({spec}): {STROKES} one-voxel strokes every {interval_ms} ms, \
         {MODES} modes, hex27x2; ms from a stroke to an answer to it (or a later one) playing"
    );
    println!(
        "{:<14} {:>7} {:>7} {:>7} {:>7} {:>12} {:>9} {:>7}",
        "worker", "median", "p90", "max", "total", "interrupted", "answers", "solve"
    );
    // The first drag of a process runs slower (its buffers, tables and caches are cold:
    // whichever way ran first lost 5-20 ms of median on the cup in stop 66's runs), so a drag
    // the engine's way warms the process up first and is not printed.
    let ways = [
        Obsolete::LeftApart,
        Obsolete::LeftApart,
        Obsolete::InPlace,
        Obsolete::RunToEnd,
    ];
    for (drag, obsolete) in ways.into_iter().enumerate() {
        let solvers = interactive_solvers(None, AnswerSwitch::default(), &KeptAnswers::new())
            .into_iter()
            .map(|s| match obsolete {
                Obsolete::LeftApart => s,
                Obsolete::InPlace => Box::new(InPlace(s)) as Box<dyn ModeSolver>,
                Obsolete::RunToEnd => Box::new(Uninterrupted(s)) as Box<dyn ModeSolver>,
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
        let mut heard = vec![None; STROKES];
        let solves_before = control.status().solves;
        // The carried answers' own time in the worker (`SolveReport::ms`: from the solver's
        // start to its answer handed to the audio side), each report once.
        let mut quick_ms = Vec::new();
        let mut last_seen = None;
        while heard.iter().any(Option::is_none) {
            let due = start + Duration::from_millis(interval_ms * sent.len() as u64);
            if sent.len() < STROKES && Instant::now() >= due {
                grid = stroke(&grid, true);
                control.request(request(grid.clone()));
                sent.push(Instant::now());
            }
            let status = control.status();
            if let Some(last) = status.last.filter(|l| l.error.is_none()) {
                if last_seen != Some((last.request, last.solver)) {
                    last_seen = Some((last.request, last.solver));
                    if last.solver == "carried" && last.request > first {
                        quick_ms.push(last.ms);
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
        // The last stroke's exact solve is still running: wait for it, or it would run beside
        // the next way's first strokes.
        assert!(
            control.wait_idle(Duration::from_secs(60)),
            "the drag's last solve"
        );
        let mut ms: Vec<f64> = heard.into_iter().flatten().collect();
        ms.sort_by(f64::total_cmp);
        let at = |q: f64| ms[((ms.len() - 1) as f64 * q).round() as usize];
        quick_ms.sort_by(f64::total_cmp);
        if drag == 0 {
            continue;
        }
        println!(
            "{:<14} {:>7.0} {:>7.0} {:>7.0} {:>7.0} {:>12} {:>9} {:>7.0}",
            match obsolete {
                Obsolete::LeftApart => "left apart",
                Obsolete::InPlace => "in place",
                Obsolete::RunToEnd => "run to end",
            },
            at(0.5),
            at(0.9),
            at(1.0),
            total,
            control.status().interrupted,
            control.status().solves - solves_before,
            quick_ms
                .get(quick_ms.len() / 2)
                .copied()
                .unwrap_or(f64::NAN)
        );
    }
    drift(spec, nu);
}

/// While a drag keeps interrupting the exact solve, each stroke's carried answer starts
/// from the exact answer before the drag: its largest frequency error against a cold solve
/// after 1, 4 and 12 strokes.
fn drift(spec: &str, nu: f64) {
    let options = EigenOptions {
        count: ModeCount::First(MODES),
        ..Default::default()
    };
    let kind = ElementKind::Hex27Blocks;
    let solve = |g: &_| ModeBasis::solve(g, kind, nu, SolverKind::Auto, &options);
    let mut grid = grid_of(spec, kind);
    let before = solve(&grid).expect("cold");
    let mut line =
        String::from("carried answer from the exact answer before the drag, largest error:");
    for k in 1..=STROKES {
        grid = stroke(&grid, true);
        if [1, 4, STROKES].contains(&k) {
            let carried = ModeBasis::carried_ritz(&grid, kind, nu, MODES, &before, None)
                .expect("comparable")
                .expect("carried");
            let exact = solve(&grid).expect("cold");
            let e = max_relative_difference(&carried, &exact);
            line += &format!(" {e:.1e} after {k} stroke{}", if k > 1 { "s" } else { "" });
        }
    }
    println!("{line}");
}
