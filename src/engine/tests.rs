//! Engine tests. Truths: the offline path (`ModeBasis::mode_set` played by a fresh
//! `OscillatorBank`, itself tested against analytic sines), the exponential envelope of
//! Rayleigh mass damping, the scaling law for pitch, and refused input. The worker's solver
//! chain (`worker`), its coarse first answer (`coarse`), recordings (`recordings`), per-note expression (`expression`) and the
//! resonator bank (`resonator`) have their own files.

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

mod coarse;
mod expression;
mod recordings;
mod resonator;
mod worker;

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

/// An engine playing `records` as a recording (no solve: any number of modes, exact values).
fn recorded(records: &[crate::modes::ModeRecord]) -> (AudioEngine, EngineControl) {
    let voicing = steel();
    let (mut audio, control) = Engine::start(
        FS,
        EngineConfig::default(),
        voicing,
        vec![Box::new(FemSolver)],
    )
    .unwrap();
    let recording = recorded::RecordedObject::new("test.wav", records, &voicing).unwrap();
    control.request(ObjectRequest {
        recording: Some(std::sync::Arc::new(recording)),
        ..request(bar(8), 10)
    });
    assert!(control.wait_idle(Duration::from_secs(60)));
    audio.process(&mut [0.0; 16], &[]);
    assert!(audio.has_object());
    (audio, control)
}
