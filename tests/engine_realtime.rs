//! The engine's audio side never allocates or frees (issue #4's wait-free contract), checked
//! with a global allocator that counts calls made on the audio thread, while an editor thread
//! sends shape edits that the worker solves and swaps in, and while 64 notes get per-note
//! expression every block (issue 15).

mod common;

use common::alloc::{self, Counting};
use modalforge::eigen::{EigenOptions, ModeCount, SolverKind};
use modalforge::engine::resonator::ResonatorSettings;
use modalforge::engine::{
    DampingParams, Engine, EngineConfig, Event, Expression, FemSolver, HitPoint, ObjectRequest,
    Pitch, TimedEvent, Voicing,
};
use modalforge::fem::ElementKind;
use modalforge::material::Material;
use modalforge::shape::VoxelGrid;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

#[global_allocator]
static GLOBAL: Counting = Counting;

fn request(len: usize) -> ObjectRequest {
    ObjectRequest {
        grid: VoxelGrid::from_fn([len, 4, 3], 0.01, |_, _, _| true).unwrap(),
        element: ElementKind::Hex8Incompatible,
        poisson_ratio: Material::preset("steel").unwrap().poisson_ratio,
        solver: SolverKind::Lanczos,
        options: EigenOptions {
            count: ModeCount::First(40),
            ..EigenOptions::default()
        },
        recording: None,
    }
}

#[test]
fn the_audio_thread_never_allocates_while_objects_are_edited() {
    let voicing = Voicing::from_material(&Material::preset("steel").unwrap(), 0.2).unwrap();
    let config = EngineConfig {
        voices: 4,
        mode_budget: 60,
        ..EngineConfig::default()
    };
    let (mut audio, control) =
        Engine::start(48000.0, config, voicing, vec![Box::new(FemSolver)]).unwrap();
    control.request(request(12));
    // Preparation may allocate; from here on the test thread is the audio thread.
    let mut out = vec![0f32; 512];
    // The resonator effect's input (issue 15): a loud sawtooth with NaNs in it.
    let input: Vec<f32> = (0..512)
        .map(|i| {
            if i % 97 == 0 {
                f32::NAN
            } else {
                (i % 50) as f32 / 25.0 - 1.0
            }
        })
        .collect();
    let mut events = Vec::with_capacity(8);
    let started = Instant::now();
    let mut edits = 0;
    let mut swaps_heard = 0;
    let mut last_generation = 0;
    let mut block = 0u64;
    let mut loudest = 0f32;
    while (swaps_heard < 4 || block < 3000) && started.elapsed() < Duration::from_secs(120) {
        block += 1;
        // The editor: a new shape every ~40 blocks once the previous one is in.
        let generation = control.stats().generation.load(Ordering::Relaxed);
        if generation != last_generation {
            swaps_heard += 1;
            last_generation = generation;
        }
        if block.is_multiple_of(40)
            && control.status().state == modalforge::engine::SolveState::Idle
        {
            edits += 1;
            control.request(request(12 + edits % 7));
        }
        events.clear();
        let key = (block % 7) as u8;
        if block.is_multiple_of(3) {
            events.push(TimedEvent {
                offset: (block % 61) as usize,
                event: Event::Strike {
                    key,
                    pitch: Pitch::Ratio(1.0 + 0.1 * key as f64),
                    velocity: 0.8,
                    hit: Some(HitPoint {
                        position: [(block % 10) as f64 / 10.0, 0.5, 1.0],
                        direction: None,
                    }),
                    hardness_s: Some(5e-4),
                },
            });
        }
        if block.is_multiple_of(5) {
            events.push(TimedEvent {
                offset: 100,
                event: Event::Mute { key },
            });
        }
        // A held key scraping the object now and then (the resonator's contact noise).
        if block % 13 == 1 {
            events.push(TimedEvent {
                offset: 0,
                event: Event::Contact {
                    key: 99,
                    pitch: Pitch::Ratio(1.2),
                    velocity: 0.7,
                },
            });
        }
        if block % 13 == 9 {
            events.push(TimedEvent {
                offset: 30,
                event: Event::ContactEnd { key: 99 },
            });
        }
        events.sort_by_key(|e| e.offset);
        let len = [64, 128, 37, 512][(block % 4) as usize];
        let mut v = voicing;
        v.size_m = 0.2 + 0.01 * (block % 9) as f64;
        v.damping = DampingParams::Rayleigh {
            alpha1: 1.0 + (block % 4) as f64,
            alpha2: 1e-8,
        };
        v.hit.position[0] = (block % 11) as f64 / 11.0;

        alloc::marked(|| {
            audio.set_voicing(v).unwrap();
            audio.set_mode_budget(40 + (block % 50) as usize);
            audio.process(&mut out[..len], &events);
            // The voicing changes every block, so the resonator retunes every block too.
            let settings = ResonatorSettings {
                input_gain: 1.0,
                mix: (block % 3) as f32 / 2.0,
                low_cut_hz: 20.0 + (block % 5) as f64 * 50.0,
                high_cut_hz: 18_000.0,
            };
            audio.resonate(&input[..len], &mut out[..len], &settings);
        });

        assert!(out[..len].iter().all(|x| x.is_finite()));
        loudest = out[..len].iter().fold(loudest, |m, x| m.max(x.abs()));
        if block.is_multiple_of(8) {
            std::thread::sleep(Duration::from_millis(1));
        }
    }
    assert!(swaps_heard >= 4, "only {swaps_heard} objects arrived");
    assert!(loudest > 0.0, "nothing was heard");
    assert_eq!(alloc::allocations(), 0, "allocations on the audio thread");
    assert_eq!(alloc::frees(), 0, "frees on the audio thread");
    assert!(control.stats().active_modes.load(Ordering::Relaxed) <= 90);
}

/// Issue 15: 64 ringing notes with per-note expression (tuning, pressure, volume) changing on
/// every note every block, notes restruck now and then: the audio thread still allocates and
/// frees nothing. (The load against the same notes without expression is in
/// `cargo bench --bench engine`.)
#[test]
fn per_note_expression_on_64_notes_every_block_does_not_allocate() {
    let voicing = Voicing::from_material(&Material::preset("steel").unwrap(), 0.2).unwrap();
    let config = EngineConfig {
        voices: 64,
        ..EngineConfig::default()
    };
    let (mut audio, control) =
        Engine::start(48000.0, config, voicing, vec![Box::new(FemSolver)]).unwrap();
    control.request(request(12));
    assert!(control.wait_idle(Duration::from_secs(60)));
    let mut out = vec![0f32; 64];
    audio.process(&mut out, &[]);
    let strike = |key: u8| TimedEvent {
        offset: key as usize % 64,
        event: Event::Strike {
            key,
            pitch: Pitch::Ratio(2f64.powf(key as f64 / 64.0 - 0.5)),
            velocity: 1.0,
            hit: None,
            hardness_s: None,
        },
    };
    let strikes: Vec<TimedEvent> = (0..64).map(strike).collect();
    let mut events = Vec::with_capacity(4 * 64);
    let (allocs, frees) = (alloc::allocations(), alloc::frees());
    let mut loudest = 0f32;
    for block in 0..400usize {
        events.clear();
        if block == 0 {
            events.extend_from_slice(&strikes);
        }
        for key in 0..64u8 {
            let wobble = ((block as f64 + key as f64) * 0.37).sin();
            for expression in [
                Expression::TuningSemitones(2.0 * wobble),
                Expression::Pressure(0.5 * (1.0 + wobble)),
                Expression::Volume(1.0 + 0.5 * wobble),
            ] {
                events.push(TimedEvent {
                    offset: (block + 3 * key as usize) % 64,
                    event: Event::Expression { key, expression },
                });
            }
            if (block + key as usize).is_multiple_of(97) {
                events.push(strike(key));
            }
        }
        events.sort_by_key(|e| e.offset);
        alloc::marked(|| audio.process(&mut out, &events));
        assert!(out.iter().all(|x| x.is_finite()), "block {block}");
        loudest = out.iter().fold(loudest, |m, x| m.max(x.abs()));
    }
    assert!(loudest > 0.0, "nothing was heard");
    assert_eq!(
        alloc::allocations() - allocs,
        0,
        "allocations on the audio thread"
    );
    assert_eq!(alloc::frees() - frees, 0, "frees on the audio thread");
}
