//! The engine's audio side under load: `process()` CPU time at 48 kHz in 64-sample blocks for
//! 1, 16 and 64 simultaneous strikes on a 200-mode object, and the mode count at which one
//! core runs out.
//!
//! `cargo bench --bench engine` solves a 200-mode steel plate once (FEM, not timed), strikes
//! `n` keys at once (pitch mapping: one voice per key, spread over an octave), renders two
//! seconds and prints per-block time, real-time load and ringing modes. One core runs out where
//! load reaches 1: `modes / load` from the busiest run (the cost is linear in ringing modes).

use modalforge::eigen::{EigenOptions, ModeCount, SolverKind};
use modalforge::engine::{
    Engine, EngineConfig, Event, FemSolver, ObjectRequest, Pitch, TimedEvent, Voicing,
};
use modalforge::fem::ElementKind;
use modalforge::material::Material;
use modalforge::shape::VoxelGrid;
use std::time::{Duration, Instant};

const RATE_HZ: f64 = 48000.0;
const BLOCK: usize = 64;

fn main() {
    let steel = Material::preset("steel").unwrap();
    let grid = VoxelGrid::from_fn([24, 20, 2], 0.01, |_, _, _| true).unwrap();
    let request = ObjectRequest {
        grid,
        element: ElementKind::Hex8Incompatible,
        poisson_ratio: steel.poisson_ratio,
        solver: SolverKind::Auto,
        options: EigenOptions {
            count: ModeCount::First(200),
            ..EigenOptions::default()
        },
        recording: None,
    };
    let mut voicing = Voicing::from_material(&steel, 1.2).unwrap();
    voicing.hardness_s = 2e-4;
    println!("strikes  modes  us/block  load (1 = one core)");
    let mut capacity: f64 = 0.0;
    for strikes in [1usize, 16, 64] {
        let config = EngineConfig {
            voices: 64,
            modes_per_voice: 256,
            mode_budget: 64 * 256,
            max_object_modes: 256,
        };
        let (mut audio, control) =
            Engine::start(RATE_HZ, config, voicing, vec![Box::new(FemSolver)]).unwrap();
        control.request(request.clone());
        assert!(control.wait_idle(Duration::from_secs(300)));
        let mut out = vec![0f32; BLOCK];
        audio.process(&mut out, &[]);
        let events: Vec<TimedEvent> = (0..strikes)
            .map(|k| TimedEvent {
                offset: 0,
                event: Event::Strike {
                    key: k as u8,
                    pitch: Pitch::Ratio(2f64.powf(k as f64 / 64.0 - 0.5)),
                    velocity: 1.0,
                    hit: None,
                    hardness_s: None,
                },
            })
            .collect();
        audio.process(&mut out, &events);
        let modes = audio.active_modes();
        let blocks = (2.0 * RATE_HZ) as usize / BLOCK;
        let t = Instant::now();
        for _ in 0..blocks {
            audio.process(&mut out, &[]);
        }
        let per_block = t.elapsed().as_secs_f64() / blocks as f64;
        let load = per_block / (BLOCK as f64 / RATE_HZ);
        capacity = capacity.max(modes as f64 / load);
        println!(
            "{strikes:>7}  {modes:>5}  {:>8.1}  {load:.3}",
            per_block * 1e6
        );
    }
    println!("one core runs out at about {capacity:.0} ringing modes (64-sample blocks, 48 kHz)");
}
