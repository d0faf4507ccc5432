//! Engine tests. Truths: the offline path (`ModeBasis::mode_set` played by a fresh
//! `OscillatorBank`, itself tested against analytic sines), the exponential envelope of
//! Rayleigh mass damping, the scaling law for pitch, and counted solver calls.

use super::*;
use crate::basis::{BasisError, Hit, ModeBasis};
use crate::eigen::{EigenOptions, ModeCount, SolverKind};
use crate::fem::ElementKind;
use crate::material::Material;
use crate::modes::CullSettings;
use crate::shape::VoxelGrid;
use crate::synth::{Excitation, OscillatorBank};
use std::sync::atomic::AtomicU64;
use std::time::Duration;

mod expression;
mod resonator;

const FS: f64 = 48000.0;

fn steel() -> Voicing {
    let mut v = Voicing::from_material(&Material::preset("steel").unwrap(), 0.24).unwrap();
    v.hardness_s = 0.0;
    v
}

fn bar(len: usize) -> VoxelGrid {
    VoxelGrid::from_fn([len, 3, 3], 0.01, |_, _, _| true).unwrap()
}

fn request(grid: VoxelGrid, modes: usize) -> ObjectRequest {
    ObjectRequest {
        grid,
        element: ElementKind::Hex8Incompatible,
        poisson_ratio: Material::preset("steel").unwrap().poisson_ratio,
        solver: SolverKind::Lanczos,
        options: EigenOptions {
            count: ModeCount::First(modes),
            ..EigenOptions::default()
        },
        recording: None,
    }
}

/// An engine with `grid` solved and received.
fn ready(config: EngineConfig, voicing: Voicing, grid: VoxelGrid) -> (AudioEngine, EngineControl) {
    let (mut audio, control) =
        Engine::start(FS, config, voicing, vec![Box::new(FemSolver)]).unwrap();
    control.request(request(grid, 30));
    assert!(control.wait_idle(Duration::from_secs(60)));
    audio.process(&mut [0.0; 16], &[]);
    assert!(audio.has_object(), "{:?}", control.status());
    (audio, control)
}

fn strike(key: u8, pitch: f64) -> TimedEvent {
    TimedEvent {
        offset: 0,
        event: Event::Strike {
            key,
            pitch: Pitch::Ratio(pitch),
            velocity: 1.0,
            hit: None,
            hardness_s: None,
        },
    }
}

/// Renders `n` samples in 64-sample blocks, `events` in the first block.
fn render(audio: &mut AudioEngine, n: usize, events: &[TimedEvent]) -> Vec<f32> {
    let mut out = vec![0f32; n];
    for (b, chunk) in out.chunks_mut(64).enumerate() {
        audio.process(chunk, if b == 0 { events } else { &[] });
    }
    out
}

fn rms(x: &[f32]) -> f64 {
    (x.iter().map(|&v| (v as f64).powi(2)).sum::<f64>() / x.len() as f64).sqrt()
}

#[test]
fn a_strike_sounds_like_the_offline_voicing() {
    // Truth: ModeBasis::mode_set (the CLI's path) for the same material, size and hit, culled
    // and played by a fresh OscillatorBank. Same modes, gains and culling rule, so the two
    // agree to f32 rendering precision (1e-4 of the peak allows for the anchor grids).
    let voicing = steel();
    let (mut audio, _control) = ready(EngineConfig::default(), voicing, bar(24));
    let out = render(&mut audio, 9600, &[strike(60, 1.0)]);

    let modes = FemSolver.solve(&request(bar(24), 30)).unwrap();
    let basis = modes.fem().unwrap();
    let material = Material::preset("steel").unwrap();
    let h = voicing.size_m / 24.0;
    let dims = basis.grid_dims();
    let hit = Hit {
        point_m: [0, 1, 2].map(|a| voicing.hit.position[a] * dims[a] as f64 * h),
        direction: None,
    };
    let set = basis.mode_set(&material, h, &hit).unwrap();
    assert_plays_like_offline(&out, &set);
}

/// `out` (an engine's velocity-1 impulse strike) is `set` culled and played by a fresh
/// `OscillatorBank` (the CLI's path), to f32 rendering precision: 1e-4 of the peak allows for
/// the anchor grids.
fn assert_plays_like_offline(out: &[f32], set: &crate::modes::ModeSet) {
    let (playable, _) = set.playable(FS, &CullSettings::default()).unwrap();
    let mut bank = OscillatorBank::new(&playable);
    bank.strike(Excitation::Impulse, 1.0).unwrap();
    let mut want = vec![0f32; out.len()];
    bank.render(&mut want);
    let peak = want.iter().fold(0f32, |m, v| m.max(v.abs())) as f64;
    let worst = out
        .iter()
        .zip(&want)
        .map(|(a, b)| (a - b).abs() as f64)
        .fold(0.0, f64::max);
    assert!(peak > 0.0);
    assert!(
        worst < 1e-4 * peak,
        "max difference {worst:e} of peak {peak:e}"
    );
}

#[test]
fn damping_changes_reach_ringing_modes_within_one_block() {
    // Rayleigh mass damping c = alpha1 gives every mode the decay alpha1 / 2. Raising alpha1
    // from 4 to 200 /s at sample t0 multiplies the ringing amplitude by e^(-k (t - t0)), k = 98,
    // against an unchanged twin (frequencies move by d^2 / 2 w^2 < 1e-3 here). RMS ratio over
    // 15-25 ms after the change: sqrt of the mean of e^(-2 k t) over the window (0.1523); 2%
    // covers the beating of the modes inside a 10 ms window.
    let mut voicing = steel();
    voicing.damping = DampingParams::Rayleigh {
        alpha1: 4.0,
        alpha2: 0.0,
    };
    let (mut a, _ca) = ready(EngineConfig::default(), voicing, bar(24));
    let (mut b, _cb) = ready(EngineConfig::default(), voicing, bar(24));
    let t0 = 64 * 40;
    let before_a = render(&mut a, t0, &[strike(1, 1.0)]);
    let before_b = render(&mut b, t0, &[strike(1, 1.0)]);
    assert_eq!(before_a, before_b);
    b.set_voicing(Voicing {
        damping: DampingParams::Rayleigh {
            alpha1: 200.0,
            alpha2: 0.0,
        },
        ..voicing
    })
    .unwrap();
    let after_a = render(&mut a, 4800, &[]);
    let after_b = render(&mut b, 4800, &[]);
    // Continuous: the first sample after the change is the same sample (phase kept).
    assert!(
        (after_a[0] - after_b[0]).abs() <= 1e-4 * before_a.iter().fold(0f32, |m, v| m.max(v.abs()))
    );
    let w = 720..1200;
    let ratio = rms(&after_b[w.clone()]) / rms(&after_a[w]);
    let (k, t1, t2) = (98.0f64, 0.015, 0.025);
    let want = (((-2.0 * k * t1).exp() - (-2.0 * k * t2).exp()) / (2.0 * k * (t2 - t1))).sqrt();
    assert!((ratio / want - 1.0).abs() < 0.02, "ratio {ratio} vs {want}");
}

#[test]
fn pitch_scales_every_mode_and_keys_ring_together() {
    // Pitch p plays the object 1/p the size: by the scaling law every frequency times p (the
    // tiny Rayleigh shift aside: d^2/w^2 < 1e-6 for steel). Two keys ring at once, each in its
    // own voice; re-striking a key adds to its voice (no new voice).
    let (mut audio, _c) = ready(EngineConfig::default(), steel(), bar(24));
    render(&mut audio, 64, &[strike(60, 1.0), strike(67, 1.5)]);
    let low = audio.voice_tunings(60);
    let high = audio.voice_tunings(67);
    assert!(!low.is_empty());
    for (l, h) in low.iter().zip(&high) {
        assert!((h.0 / l.0 / 1.5 - 1.0).abs() < 1e-5, "{l:?} {h:?}");
    }
    render(&mut audio, 64, &[strike(60, 1.0)]);
    assert_eq!(audio.stats_voices(), 2);
}

#[test]
fn the_budget_keeps_the_loudest_modes() {
    // Budget 12 over a 30-mode bar: after two strikes at different points, 12 modes ring and
    // every dropped mode was quieter than every kept one (measured right before the drop).
    let config = EngineConfig {
        mode_budget: 12,
        ..EngineConfig::default()
    };
    let (mut audio, control) = ready(config, steel(), bar(24));
    let mut second = strike(2, 1.0);
    if let Event::Strike { hit, .. } = &mut second.event {
        *hit = Some(HitPoint {
            position: [0.1, 0.5, 1.0],
            direction: Some([0.3, 0.0, -1.0]),
        });
    }
    render(&mut audio, 64, &[strike(1, 1.0)]);
    render(&mut audio, 64, &[second]);
    assert_eq!(audio.active_modes(), 12);
    assert!(control.stats().dropped_modes.load(Ordering::Relaxed) > 0);
    let (kept_min, dropped_max) = audio.last_budget_split();
    assert!(
        kept_min >= dropped_max,
        "kept {kept_min:e} < dropped {dropped_max:e}"
    );
}

#[test]
fn a_shape_swap_is_seamless_and_the_next_strike_uses_the_new_shape() {
    // While a note rings, a new shape is solved and swapped in. The ringing note is untouched:
    // its largest sample-to-sample step around the swap is no larger than before it (5%
    // margin for the envelope). The next strike plays the new object (a longer bar: lower).
    let (mut audio, control) = ready(EngineConfig::default(), steel(), bar(24));
    let before = render(&mut audio, 4800, &[strike(1, 1.0)]);
    let f_old = audio.voice_tunings(1)[0].0;
    control.request(request(bar(32), 30));
    assert!(control.wait_idle(Duration::from_secs(60)));
    let around = render(&mut audio, 960, &[]);
    assert_eq!(control.stats().generation.load(Ordering::Relaxed), 2);
    let step = |x: &[f32]| {
        x.windows(2)
            .map(|w| (w[1] - w[0]).abs())
            .fold(0f32, f32::max)
    };
    assert!(
        step(&around) <= 1.05 * step(&before[3840..]),
        "click at the swap"
    );
    render(&mut audio, 64, &[strike(2, 1.0)]);
    let f_new = audio.voice_tunings(2)[0].0;
    // Same size parameter, longer bar in voxels: thinner relative to its length, so lower.
    assert!(f_new < 0.8 * f_old, "{f_new} vs {f_old}");
}

#[test]
fn mute_damps_only_its_key() {
    let (mut audio, _c) = ready(EngineConfig::default(), steel(), bar(24));
    render(&mut audio, 64, &[strike(1, 1.0), strike(2, 1.25)]);
    let d1 = audio.voice_tunings(1)[0].1;
    render(
        &mut audio,
        64,
        &[TimedEvent {
            offset: 3,
            event: Event::Mute { key: 1 },
        }],
    );
    let muted = audio.voice_tunings(1)[0].1;
    assert!(
        (muted - d1 - steel().mute_decay_per_s).abs() < 1e-9,
        "{d1} -> {muted}"
    );
    let other = audio.voice_tunings(2)[0].1;
    assert!(other < muted);
}

#[test]
fn bad_input_is_refused_and_never_reaches_the_audio() {
    let (mut audio, control) = ready(EngineConfig::default(), steel(), bar(24));
    let good = *audio.voicing();
    for bad in [
        Voicing {
            youngs_modulus_pa: f64::NAN,
            ..good
        },
        Voicing {
            density_kg_m3: -1.0,
            ..good
        },
        Voicing {
            size_m: 0.0,
            ..good
        },
        Voicing {
            hardness_s: 1.0,
            ..good
        },
        Voicing {
            damping: DampingParams::PowerLaw {
                mu1: f64::INFINITY,
                mu2: 1.0,
            },
            ..good
        },
    ] {
        assert!(audio.set_voicing(bad).is_err());
        assert_eq!(*audio.voicing(), good);
    }
    let nan_strike = TimedEvent {
        offset: 0,
        event: Event::Strike {
            key: 3,
            pitch: Pitch::Ratio(f64::NAN),
            velocity: 1.0,
            hit: None,
            hardness_s: None,
        },
    };
    let out = render(&mut audio, 256, &[nan_strike]);
    assert!(out.iter().all(|&v| v == 0.0));
    assert_eq!(control.stats().dropped_strikes.load(Ordering::Relaxed), 1);
    // A shape that cannot be solved reports one line and keeps the old object playing.
    // (One voxel has 18 non-rigid modes; 30 are asked for.)
    let one = VoxelGrid::from_fn([1, 1, 1], 0.01, |_, _, _| true).unwrap();
    control.request(request(one, 30));
    assert!(control.wait_idle(Duration::from_secs(60)));
    let err = control.status().last.unwrap().error.unwrap();
    assert!(!err.contains('\n'), "{err}");
    let out = render(&mut audio, 256, &[strike(4, 1.0)]);
    assert!(out.iter().all(|v| v.is_finite()) && out.iter().any(|&v| v != 0.0));
}

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

#[test]
fn normalised_strikes_peak_near_the_target_level() {
    // A velocity-1 impulse at the voicing's hit peaks at most NORMALISED_PEAK (the sum of
    // mode amplitudes bounds the peak) and, for a bar dominated by a few modes, within 12 dB
    // of it; a 10x stiffer material changes the physical level but not the normalised one
    // by more than the 12 dB window.
    for e_scale in [1.0, 10.0] {
        let mut v = steel();
        v.normalise = true;
        v.youngs_modulus_pa *= e_scale;
        let (mut audio, _c) = ready(EngineConfig::default(), v, bar(24));
        let out = render(&mut audio, 9600, &[strike(1, 1.0)]);
        let peak = out.iter().fold(0f32, |m, x| m.max(x.abs())) as f64;
        let target = voicing::NORMALISED_PEAK;
        assert!(
            peak <= target * 1.0001 && peak > target / 4.0,
            "E x{e_scale}: peak {peak}"
        );
    }
}

/// An engine at `rate` with a solved 24-voxel bar (30 modes); the solve is not yet received
/// by the audio side (the first block takes it).
fn solved_bar(rate: f64, voicing: Voicing) -> AudioEngine {
    let (audio, control) = Engine::start(
        rate,
        EngineConfig::default(),
        voicing,
        vec![Box::new(FemSolver)],
    )
    .unwrap();
    control.request(request(bar(24), 30));
    assert!(control.wait_idle(Duration::from_secs(60)));
    audio
}

/// A full-velocity strike of `key` in the "pitch" mapping, its fundamental at `hz`.
fn pitched_strike(key: u8, hz: f64) -> TimedEvent {
    TimedEvent {
        offset: 0,
        event: Event::Strike {
            key,
            pitch: Pitch::Fundamental(hz),
            velocity: 1.0,
            hit: None,
            hardness_s: None,
        },
    }
}

#[test]
fn a_fundamental_pitch_puts_the_lowest_mode_on_the_note() {
    // The "pitch" mapping: A4 scales the bar so that its lowest mode rings at 440 Hz, resolved
    // in the same block the object arrives in (the first strike after a solve is not lost).
    let mut audio = solved_bar(FS, steel());
    render(&mut audio, 64, &[pitched_strike(69, 440.0)]);
    let f0 = audio.voice_tunings(69)[0].0;
    // Steel's Rayleigh damping lowers the damped frequency by d^2 / 2 w^2 ~ 1e-9.
    assert!((f0 / 440.0 - 1.0).abs() < 1e-6, "{f0}");
}

#[test]
fn a_small_object_plays_its_key_at_any_sample_rate() {
    // A 3 cm steel bar rings above 24 kHz at its own size (its lowest mode near 30 kHz): at
    // 22.05 and 48 kHz none of its own partials is below Nyquist. The "pitch" mapping must
    // still put its fundamental on the key, the same at every rate (it was silent below 64
    // kHz: the pitch reference counted only the partials playable at the object's own size),
    // at the same level.
    let (mut tunings, mut levels) = (Vec::new(), Vec::new());
    for rate in [96000.0, 48000.0, 22050.0] {
        let mut voicing = steel();
        voicing.size_m = 0.03;
        let mut audio = solved_bar(rate, voicing);
        let out = render(&mut audio, 4096, &[pitched_strike(67, 392.0)]);
        levels.push(rms(&out));
        tunings.push(audio.voice_tunings(67)[0].0);
    }
    // Within 1e-5 (0.02 cents): Rayleigh damping's d^2 / 2 w^2 between the damped and the
    // natural frequency changes with the size the key plays (1.4e-6 here).
    for f0 in &tunings {
        assert!((f0 / 392.0 - 1.0).abs() < 1e-5, "{tunings:?}");
    }
    // As loud at every rate: the same modes below 11 kHz ring, and the level reference is
    // the same (a factor of 2 allows for the few modes culled at the lower rates).
    for level in &levels {
        assert!(
            *level > 0.5 * levels[0] && *level < 2.0 * levels[0],
            "{levels:?}"
        );
    }
}

#[test]
fn the_spectrum_view_lists_what_the_offline_voicing_plays() {
    // Truth: ModeBasis::mode_set for the same material, size and hit (impulse strike). The
    // view's frequencies and decays equal it to rounding (1e-9 relative); its amplitudes are
    // the mode set's gains (the same formula, 1e-9 relative). The latest object the control
    // reports is the one just solved.
    let voicing = steel();
    let (_audio, control) = ready(EngineConfig::default(), voicing, bar(24));
    let latest = control.latest_object().expect("a solved object");
    assert_eq!(latest.generation, 1);
    let lines = spectrum::spectrum(&latest.basis, &voicing, FS).unwrap();

    let material = Material::preset("steel").unwrap();
    let h = voicing.size_m / 24.0;
    let dims = latest.basis.grid_dims();
    let hit = Hit {
        point_m: [0, 1, 2].map(|a| voicing.hit.position[a] * dims[a] as f64 * h),
        direction: None,
    };
    let set = latest
        .basis
        .fem()
        .unwrap()
        .mode_set(&material, h, &hit)
        .unwrap();
    let below_nyquist = set.freq_hz().iter().filter(|&&f| f < FS / 2.0).count();
    assert!(lines.len() >= 10, "{} lines", lines.len());
    assert_eq!(lines.len(), below_nyquist);
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * b.abs().max(1e-30);
    for (i, line) in lines.iter().enumerate() {
        assert!(close(line.freq_hz, set.freq_hz()[i]), "mode {i}");
        assert!(close(line.decay_per_s, set.decay_per_s()[i]), "mode {i}");
        assert!(close(line.amplitude, set.gain()[i].abs()), "mode {i}");
        assert!(line.t60_s() > 0.0);
    }
}

#[test]
fn the_output_never_holds_subnormal_samples() {
    // A strike at velocity 1e-37 rings at about 1e-38 and below, under f32's smallest normal
    // (1.18e-38): every sample must be flushed to zero or be normal (CLAP validators reject
    // subnormal output). The same strike at velocity 1 is audible, so the test is not empty.
    let (mut audio, _control) = ready(EngineConfig::default(), steel(), bar(24));
    let mut quiet = strike(1, 1.0);
    if let Event::Strike { velocity, .. } = &mut quiet.event {
        *velocity = 1e-37;
    }
    let out = render(&mut audio, 4800, &[quiet]);
    assert!(out.iter().all(|x| *x == 0.0 || x.is_normal()));
    let loud = render(&mut audio, 4800, &[strike(2, 1.0)]);
    assert!(loud.iter().any(|x| x.abs() > 1e-6));
}

/// A hollow box, walls two voxels thick (survives halving its resolution).
fn thick_box(side: usize) -> VoxelGrid {
    let solid = VoxelGrid::from_fn([side, side, side], 0.01, |_, _, _| true).unwrap();
    crate::shape::ops::hollow(&solid, 2)
}

#[test]
fn coarse_grid_halves_thick_objects_and_refuses_thin_walls() {
    let grid = thick_box(16);
    let coarse = coarse_grid(&grid).expect("a 2-voxel wall survives halving");
    assert_eq!(coarse.dims(), [8, 8, 8]);
    assert_eq!(coarse.voxel_size_m(), 0.02);
    // Volume kept within the stated 25 % (here exactly: the walls are aligned to 2).
    assert_eq!(8 * coarse.count(), grid.count());
    let thin = crate::shape::ops::hollow(
        &VoxelGrid::from_fn([16, 16, 16], 0.01, |_, _, _| true).unwrap(),
        1,
    );
    assert!(
        coarse_grid(&thin).is_none(),
        "a 1-voxel wall does not survive"
    );
    // The cost model orders objects by size.
    let count = ModeCount::First(60);
    assert!(predicted_cold_ms(&thick_box(24), count) > predicted_cold_ms(&grid, count));
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

/// Eight modes of a made-up bell: a near-degenerate lowest pair, decays off any law.
fn recorded_bell() -> Vec<crate::modes::ModeRecord> {
    [
        (523.0, 1.2, 0.8),
        (524.5, 1.4, 0.5),
        (1210.0, 3.5, -0.4),
        (1987.0, 2.0, 0.3),
        (2630.0, 9.0, 0.25),
        (3480.0, 6.5, -0.2),
        (4400.0, 20.0, 0.1),
        (6100.0, 35.0, 0.05),
    ]
    .map(|(freq_hz, decay_per_s, gain)| crate::modes::ModeRecord {
        freq_hz,
        decay_per_s,
        gain,
    })
    .to_vec()
}

#[test]
fn a_recording_plays_as_recorded_and_follows_the_pitch_mapping() {
    // Truth for the sound: the recorded modes played directly by a fresh OscillatorBank (the
    // CLI's `render --modes` path); the engine strikes the recording as an object and must
    // agree to f32 rendering precision (1e-4 of the peak, as for solved shapes). Then a
    // pitch-mapped strike on C4: the cluster centre of the lowest pair on 261.63 Hz
    // (`pitch::cluster_pitch_hz` on the recorded weights), every mode scaled by the same ratio.
    let voicing = steel();
    let (mut audio, control) = Engine::start(
        FS,
        EngineConfig::default(),
        voicing,
        vec![Box::new(FemSolver)],
    )
    .unwrap();
    let bell = recorded_bell();
    let recording = recorded::RecordedObject::new("bell.wav", &bell, &voicing).unwrap();
    control.request(ObjectRequest {
        recording: Some(std::sync::Arc::new(recording)),
        ..request(bar(8), 10)
    });
    assert!(control.wait_idle(Duration::from_secs(60)));
    assert_eq!(
        control.status().playing.map(|p| p.solver),
        Some("recording")
    );
    let out = render(&mut audio, 9600, &[strike(60, 1.0)]);
    assert_plays_like_offline(&out, &crate::modes::ModeSet::from_records(&bell).unwrap());

    let c4 = TimedEvent {
        offset: 0,
        event: Event::Strike {
            key: 48,
            pitch: Pitch::Fundamental(261.63),
            velocity: 1.0,
            hit: None,
            hardness_s: None,
        },
    };
    render(&mut audio, 64, &[c4]);
    let tuned = audio.voice_tunings(48);
    assert_eq!(tuned.len(), bell.len());
    let centre = super::pitch::cluster_pitch_hz(
        tuned[..2]
            .iter()
            .zip(&bell)
            .map(|(t, m)| (t.0, (m.gain * m.freq_hz).powi(2))),
    )
    .unwrap();
    assert!((centre / 261.63 - 1.0).abs() < 1e-6, "{centre}");
    let ratio = tuned[0].0 / bell[0].freq_hz;
    for (t, m) in tuned.iter().zip(&bell) {
        // Steel's Rayleigh law and the decays of these modes move a damped frequency by
        // (d / omega)^2 / 2 < 2e-6 relative.
        assert!((t.0 / m.freq_hz / ratio - 1.0).abs() < 1e-5, "{t:?} {m:?}");
    }
    // A shape request replaces the recording.
    control.request(request(bar(24), 10));
    assert!(control.wait_idle(Duration::from_secs(60)));
    assert_eq!(control.status().playing.map(|p| p.solver), Some("fem"));
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
