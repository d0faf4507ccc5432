//! The neural predictor's cost on one core (issue 12): the network on a shape (resampled to
//! the box where it is outside the training sizes, trunk, features back to the CPU, the pitch
//! index's query) and one strike's decode (the struck cell found, its head evaluated, the
//! modal forces written: what the engine does per hit).
//!
//! `cargo bench --bench predictor` (criterion). Shapes: the plugin's default glass bowl
//! (`bowl:d=16,wall=2`, 16 voxels: as it is), a 12-voxel bowl (resampled to 32) and a 32-voxel
//! solid sphere; the shipped weights and pitch index.

use criterion::Criterion;
use modalforge::basis::Hit;
use modalforge::predictor::Predictor;
use modalforge::shape::spec::ShapeSpec;
use std::hint::black_box;

fn grid(spec: &str) -> modalforge::shape::VoxelGrid {
    let ShapeSpec::Primitive { shape, .. } = spec.parse::<ShapeSpec>().expect("shape") else {
        panic!("{spec}: not a primitive")
    };
    shape.rasterize(1.0, 0.01).expect("rasterises")
}

fn main() {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("one thread");
    let predictor = Predictor::shipped().expect("shipped weights");
    let mut c = Criterion::default().configure_from_args();
    {
        for spec in ["bowl:d=16,wall=2", "bowl:d=12,wall=2", "sphere:d=32"] {
            let g = grid(spec);
            // burn's flex backend runs on the calling thread's rayon pool: one thread.
            c.bench_function(&format!("predict {spec} (one core)"), |b| {
                b.iter(|| pool.install(|| predictor.predict(black_box(&g)).expect("predicts")))
            });
            let p = predictor.predict(&g).expect("predicts");
            let [nx, ny, nz] = g.dims();
            let h = g.voxel_size_m();
            let hit = Hit {
                point_m: [0.37 * nx as f64 * h, 0.41 * ny as f64 * h, nz as f64 * h],
                direction: None,
            };
            let mut forces = vec![0.0; p.mode_count()];
            c.bench_function(&format!("strike decode {spec}"), |b| {
                b.iter(|| p.reference_forces_into(black_box(&hit), h, &mut forces))
            });
        }
    }
    c.final_summary();
    edit_to_first_sound();
}

/// Edit to first sound in the engine: from `EngineControl::request` to the audio side playing
/// the predictor's answer (the worker's wake-up, the prediction, the ring, the next audio
/// block), with the chain set to the predictor only (`Answers::PredictorOnly`): in the default
/// chain an edit made while an exact solve runs waits for that solve to end (one worker
/// thread; see ARCHITECTURE.md). Each edit is a different 32-voxel shape. Prints the median and
/// worst of 20 edits per object; the worker's burn runs on rayon's global pool (every core).
fn edit_to_first_sound() {
    use modalforge::eigen::{EigenOptions, ModeCount, SolverKind};
    use modalforge::engine::{
        interactive_solvers, AnswerSwitch, Answers, Engine, EngineConfig, Voicing,
    };
    use modalforge::fem::ElementKind;
    use modalforge::material::Material;
    use std::sync::Arc;
    use std::time::{Duration, Instant};
    let predictor = Arc::new(Predictor::shipped().expect("shipped weights"));
    let glass = Material::preset("glass").expect("glass");
    let voicing = Voicing::from_material(&glass, 0.2).expect("voicing");
    let answers = AnswerSwitch::default();
    answers.set(Answers::PredictorOnly);
    for spec in ["sphere:d=32", "bowl:d=32,wall=2", "cup:d=32,h=32,wall=2"] {
        let (mut audio, control) = Engine::start(
            48_000.0,
            EngineConfig::default(),
            voicing,
            interactive_solvers(
                Some(predictor.clone()),
                answers.clone(),
                &modalforge::engine::KeptAnswers::new(),
            ),
        )
        .expect("engine");
        let base = grid(spec);
        let mut times = Vec::new();
        let mut block = [0.0f32; 64];
        for k in 0..20usize {
            // A different shape each time: one voxel of the top layer removed.
            let mut g = base.clone();
            let [nx, ny, nz] = g.dims();
            g.set(k % nx, ny / 2, nz - 1, false);
            g.set((k * 7) % nx, ny / 3, 0, false);
            let before = audio.object_generation().map_or(0, |(g, _)| g);
            let t0 = Instant::now();
            control.request(modalforge::engine::ObjectRequest {
                grid: g,
                element: ElementKind::Hex8Incompatible,
                poisson_ratio: glass.poisson_ratio,
                solver: SolverKind::Auto,
                options: EigenOptions {
                    count: ModeCount::First(60),
                    ..EigenOptions::default()
                },
                recording: None,
            });
            loop {
                audio.process(&mut block, &[]);
                if let Some((generation, solver)) = audio.object_generation() {
                    if generation > before {
                        assert_eq!(solver, "neural");
                        break;
                    }
                }
                std::thread::sleep(Duration::from_micros(200));
            }
            times.push(t0.elapsed().as_secs_f64() * 1e3);
            control.wait_idle(Duration::from_secs(10));
        }
        times.sort_by(f64::total_cmp);
        println!(
            "edit to first sound, {spec}: median {:.1} ms, worst {:.1} ms (20 edits, predictor only)",
            times[times.len() / 2],
            times[times.len() - 1]
        );
    }
}
