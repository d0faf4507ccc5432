//! The engine's audio side under load: `process()` CPU time at 48 kHz in 64-sample blocks for
//! 1, 16 and 64 simultaneous strikes on a 200-mode object, and the mode count at which one
//! core runs out.
//!
//! `cargo bench --bench engine` solves a 200-mode steel plate once (FEM, not timed), strikes
//! `n` keys at once (pitch mapping: one voice per key, spread over an octave), renders two
//! seconds and prints per-block time, real-time load and ringing modes. One core runs out where
//! load reaches 1: `modes / load` from the busiest run (the cost is linear in ringing modes).
//!
//! With 64 strikes it also plays the same notes on two engines, one with per-note expression
//! (tuning, pressure, volume) changing on every note every block, rendered alternately, and
//! prints the load against none (issue 15).
//!
//! Then the resonator effect ([`modalforge::engine::resonator`]): a 500-mode object (a
//! made-up recording, so no solve) driven by full-scale noise, per-block time of
//! `AudioEngine::resonate` on top of an idle `process`.

use modalforge::eigen::{EigenOptions, ModeCount, SolverKind};
use modalforge::engine::{
    AudioEngine, Engine, EngineConfig, Event, Expression, FemSolver, ObjectRequest, Pitch,
    TimedEvent, Voicing,
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
        if strikes == 64 {
            // A twin engine for the expression run: the two play the same notes block by
            // block, timed alternately, so that the machine's drift falls on both alike.
            let (mut twin, twin_control) =
                Engine::start(RATE_HZ, config, voicing, vec![Box::new(FemSolver)]).unwrap();
            twin_control.request(request.clone());
            assert!(twin_control.wait_idle(Duration::from_secs(300)));
            twin.process(&mut out, &[]);
            expression_load(&mut audio, &mut twin, &events);
        }
    }
    println!("one core runs out at about {capacity:.0} ringing modes (64-sample blocks, 48 kHz)");
    resonator(voicing);
}

/// Issue 15: the same 64 notes, struck again on two engines, one of them with per-note
/// expression changing every block on every note (tuning, pressure and volume: 192 events a
/// block, an MPE controller's worst case; the pressure stays light so that it does not
/// silence modes early and make the run cheaper). The two render block by block, timed
/// alternately (which goes first swaps every block). Printed, not asserted (the goal is
/// within 20 %).
fn expression_load(plain: &mut AudioEngine, expressive: &mut AudioEngine, strikes: &[TimedEvent]) {
    let mut out = vec![0f32; BLOCK];
    let all_off = [TimedEvent {
        offset: 0,
        event: Event::AllOff,
    }];
    for audio in [&mut *plain, &mut *expressive] {
        audio.process(&mut out, &all_off);
        audio.process(&mut out, strikes);
    }
    let blocks = (2.0 * RATE_HZ) as usize / BLOCK;
    let mut events = Vec::with_capacity(3 * strikes.len());
    let (mut busy_plain, mut busy_expressive) = (Duration::ZERO, Duration::ZERO);
    for b in 0..blocks {
        events.clear();
        let phase = b as f64 / blocks as f64;
        for k in 0..strikes.len() as u8 {
            let wobble = (std::f64::consts::TAU * (4.0 * phase + k as f64 / 64.0)).sin();
            for expression in [
                Expression::TuningSemitones(0.5 * wobble),
                Expression::Pressure(0.01 * (1.0 + wobble)),
                Expression::Volume(1.0 + 0.2 * wobble),
            ] {
                events.push(TimedEvent {
                    offset: (b + k as usize) % BLOCK,
                    event: Event::Expression { key: k, expression },
                });
            }
        }
        events.sort_by_key(|e| e.offset);
        for turn in 0..2 {
            let t = Instant::now();
            if (b + turn) % 2 == 0 {
                plain.process(&mut out, &[]);
                busy_plain += t.elapsed();
            } else {
                expressive.process(&mut out, &events);
                busy_expressive += t.elapsed();
            }
        }
    }
    let per_block = |busy: Duration| busy.as_secs_f64() / blocks as f64;
    let (plain_us, expressive_us) = (per_block(busy_plain), per_block(busy_expressive));
    let load = expressive_us / (BLOCK as f64 / RATE_HZ);
    println!(
        "64 notes, expression on every note every block: {:.1} us/block, load {load:.3} \
         ({:+.1} % against the same notes without, {:.1} us/block, rendered alternately)",
        expressive_us * 1e6,
        100.0 * (expressive_us / plain_us - 1.0),
        plain_us * 1e6
    );
}

/// The resonator effect on 500 modes: microseconds per 64-sample block and load.
fn resonator(voicing: Voicing) {
    use modalforge::engine::recorded::RecordedObject;
    use modalforge::engine::resonator::ResonatorSettings;
    use modalforge::modes::ModeRecord;
    let records: Vec<ModeRecord> = (0..500)
        .map(|i| {
            let t = i as f64 / 499.0;
            ModeRecord {
                freq_hz: 60.0 * 300f64.powf(t),
                decay_per_s: 0.5 + 40.0 * ((i * 7919) % 101) as f64 / 100.0,
                gain: 1.0 - 0.8 * t,
            }
        })
        .collect();
    let (mut audio, control) = Engine::start(
        RATE_HZ,
        EngineConfig::default(),
        voicing,
        vec![Box::new(FemSolver)],
    )
    .unwrap();
    let recording = RecordedObject::new("bench", &records, &voicing).unwrap();
    control.request(ObjectRequest {
        grid: VoxelGrid::from_fn([4, 1, 1], 0.01, |_, _, _| true).unwrap(),
        element: ElementKind::Hex8Incompatible,
        poisson_ratio: 0.3,
        solver: SolverKind::Auto,
        options: EigenOptions::default(),
        recording: Some(std::sync::Arc::new(recording)),
    });
    assert!(control.wait_idle(Duration::from_secs(60)));
    let settings = ResonatorSettings {
        input_gain: 1.0,
        ..ResonatorSettings::default()
    };
    let mut out = vec![0f32; BLOCK];
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    let mut noise = vec![0f32; BLOCK];
    let mut fill = |noise: &mut [f32]| {
        for x in noise.iter_mut() {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            *x = (state >> 40) as f32 / (1u64 << 23) as f32 - 1.0;
        }
    };
    fill(&mut noise);
    audio.process(&mut out, &[]);
    audio.resonate(&noise, &mut out, &settings);
    let modes = audio.resonator().modes();
    let blocks = (4.0 * RATE_HZ) as usize / BLOCK;
    let mut busy = Duration::ZERO;
    for _ in 0..blocks {
        fill(&mut noise);
        let t = Instant::now();
        audio.process(&mut out, &[]);
        audio.resonate(&noise, &mut out, &settings);
        busy += t.elapsed();
    }
    let per_block = busy.as_secs_f64() / blocks as f64;
    let load = per_block / (BLOCK as f64 / RATE_HZ);
    println!(
        "resonator effect, {modes} modes, full-scale noise in: {:.1} us/block, load {load:.3}",
        per_block * 1e6
    );
}
