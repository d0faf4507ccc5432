//! Recordings without a window: matching a recording's material, and playing a recording's modes.

use super::*;
/// "Match recording" without a window: a brass bowl (10 voxels, 0.15 m, struck at the editor's
/// default hit) is solved, struck and written as a WAV with noise 40 dB down; matching it from
/// a glass start gives back brass's E/rho within 2 % and nu within 0.05 (the fit's own test
/// reaches far better; this one checks the plumbing: the grid at the Size parameter, the hit
/// from the Hit parameters), a damping law that gives the lowest ten modes brass's damping
/// within 15 % RMS (measured 10 %: the extraction merges the 11 kHz group, whose modes die in
/// 2-3 ms, into one mode 40 % too damped, and the law follows it; the fit may pick a power
/// law that matches brass's Rayleigh law over the band), knob values in range, and a material file that loads back. A text
/// file is one clear error.
#[test]
fn matching_a_recording_gives_back_the_material() {
    use modalforge::analysis::{synthetic, wav};
    use modalforge::basis::ModeBasis;
    use modalforge::eigen::{EigenOptions, ModeCount, SolverKind};
    use modalforge::engine::HitPoint;
    use modalforge::fem::ElementKind;
    use modalforge::material::Material;
    let dir = std::env::temp_dir().join(format!("modalforge-match-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let grid = Sculpt::from_spec("bowl:d=10,wall=2")
        .unwrap()
        .to_grid()
        .unwrap()
        .cropped();
    let h = 0.15 / *grid.dims().iter().max().unwrap() as f64;
    let grid = grid.with_voxel_size(h).unwrap();
    let mut hit = HitPoint::default().reference_hit(grid.dims());
    hit.point_m = hit.point_m.map(|c| c * h);
    let brass = Material::preset("brass").unwrap();
    let basis = ModeBasis::solve(
        &grid,
        ElementKind::Hex8Incompatible,
        brass.poisson_ratio,
        SolverKind::Lanczos,
        &EigenOptions {
            count: ModeCount::First(30),
            ..Default::default()
        },
    )
    .unwrap();
    let modes = synthetic::recorded_modes(&basis.strike(&brass, h, &hit).unwrap(), 20_000.0);
    let strike = synthetic::strike_of(&modes, 48_000.0, 0.02, 0.6, 40.0, 5);
    let path = dir.join("brass-bowl.wav");
    wav::write_mono(&path, strike.fs, &strike.signal).unwrap();
    let glass = Material::preset("glass").unwrap();
    let matched = super::matching::run(
        &path,
        &grid,
        &hit,
        glass.youngs_modulus_pa / glass.density_kg_m3,
    )
    .unwrap();
    let m = &matched.material;
    let e_over_rho = m.youngs_modulus_pa / m.density_kg_m3;
    let want = brass.youngs_modulus_pa / brass.density_kg_m3;
    assert!(
        (e_over_rho / want - 1.0).abs() < 0.02,
        "{}",
        matched.summary
    );
    assert!(
        (m.poisson_ratio - brass.poisson_ratio).abs() < 0.05,
        "{}",
        matched.summary
    );
    // The law the fit picks may be Rayleigh or a power law that matches it over the band
    // (BIC decides between near-equals): what must hold is the damping it gives the modes.
    let errors: Vec<f64> = modes
        .iter()
        .take(10)
        .map(|mode| {
            let w2 = (std::f64::consts::TAU * mode.freq_hz).powi(2);
            m.damping.coefficient(w2) / brass.damping.coefficient(w2) - 1.0
        })
        .collect();
    let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
    assert!(rms < 0.15, "{errors:?} ({:?})", m.damping);
    let knobs = super::matching::Knobs::of(m).unwrap();
    assert!(
        (knobs.youngs_gpa as f64 - m.youngs_modulus_pa * 1e-9).abs()
            < 1e-3 * knobs.youngs_gpa as f64
    );
    let back = Material::from_toml(&m.to_toml().unwrap(), "matched").unwrap();
    assert_eq!(back.poisson_ratio, m.poisson_ratio);
    // The same through the editor: "Match recording" on the file in the path field, polled
    // frame by frame, sets the Custom material and the damping knobs through the host.
    let host = TestHost::default();
    let setter = ParamSetter { raw_context: &host };
    let mut app = app_with(Sculpt::from_spec("bowl:d=10,wall=2").unwrap());
    setter.set_parameter(&app.params.material.size_m, 0.15);
    app.path = path.display().to_string();
    app.start_match();
    let started = std::time::Instant::now();
    while app.matching.is_some() {
        assert!(
            started.elapsed().as_secs() < 120,
            "the match never finished"
        );
        std::thread::sleep(std::time::Duration::from_millis(20));
        app.poll_match(&setter);
    }
    let (message, error) = app.message.clone().unwrap();
    assert!(
        !error && message.starts_with("matched brass-bowl"),
        "{message}"
    );
    let p = &app.params;
    assert_eq!(p.material.preset.value(), MaterialChoice::Custom);
    assert!((p.material.youngs_gpa.value() / knobs.youngs_gpa - 1.0).abs() < 1e-3);
    assert!((p.material.poisson.value() - knobs.poisson).abs() < 1e-3);
    assert_eq!(p.damping.law.value(), knobs.damping.0);
    assert!(host.gestures.load(Ordering::Relaxed) >= 6);
    assert!(dir.join("brass-bowl.material.toml").exists());
    let text = dir.join("notes.wav");
    std::fs::write(&text, "not audio").unwrap();
    let e = super::matching::run(&text, &grid, &hit, want)
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("cannot use recording") && !e.contains('\n'),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// "Play recording" without a window: a synthetic strike of six known modes (noise 40 dB
/// down) written as a WAV; the editor extracts it, sets the damping knobs to its law and
/// stores the recording, which the worker's request carries and the project state keeps.
/// Truth: the known modes. At the knobs then in force the spectrum the engine would strike is
/// those modes (frequency within 0.1 %, decay within 5 %: the extraction's own accuracy
/// goals). The next sculpting edit plays the shape again; a text file is one clear error.
#[test]
fn playing_a_recording_plays_its_modes_until_the_next_edit() {
    use modalforge::analysis::{synthetic, wav, ExtractedMode};
    use modalforge::engine::recorded::RecordedObject;
    use modalforge::engine::spectrum::spectrum;
    use modalforge::engine::ObjectModes;
    let dir = std::env::temp_dir().join(format!("modalforge-play-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let known: Vec<ExtractedMode> = [
        (440.0, 2.0, 0.3),
        (1131.0, 4.5, 0.2),
        (2012.0, 7.0, 0.15),
        (3318.0, 11.0, 0.1),
        (4874.0, 16.0, 0.08),
        (6402.0, 24.0, 0.05),
    ]
    .map(|(freq_hz, decay_per_s, gain)| ExtractedMode {
        freq_hz,
        decay_per_s,
        gain,
        phase: -std::f64::consts::FRAC_PI_2,
    })
    .to_vec();
    let strike = synthetic::strike_of(&known, 48_000.0, 0.02, 1.0, 40.0, 9);
    let path = dir.join("bell.wav");
    wav::write_mono(&path, strike.fs, &strike.signal).unwrap();

    let host = TestHost::default();
    let setter = ParamSetter { raw_context: &host };
    let mut app = app_with(block([4, 4, 4]));
    app.path = path.display().to_string();
    app.start_play();
    let started = std::time::Instant::now();
    while app.matching.is_some() {
        assert!(
            started.elapsed().as_secs() < 60,
            "the analysis never finished"
        );
        std::thread::sleep(std::time::Duration::from_millis(20));
        app.poll_match(&setter);
    }
    let (message, error) = app.message.clone().unwrap();
    assert!(
        !error && message.starts_with("playing bell: 6 modes"),
        "{message}"
    );
    assert!(
        host.gestures.load(Ordering::Relaxed) >= 3,
        "damping knobs set"
    );
    let recording = app.params.recording.read().unwrap().clone().unwrap();
    assert_eq!(recording.name, "bell");
    let voicing = app.params.voicing(&app.table, 1.0, 1.0);
    let lines = spectrum(
        &ObjectModes::Recorded(recording.clone()),
        &voicing,
        48_000.0,
    )
    .unwrap();
    assert_eq!(lines.len(), known.len());
    for (line, m) in lines.iter().zip(&known) {
        assert!(
            (line.freq_hz / m.freq_hz - 1.0).abs() < 1e-3,
            "{line:?} vs {m:?}"
        );
        assert!(
            (line.decay_per_s / m.decay_per_s - 1.0).abs() < 0.05,
            "{line:?} vs {m:?}"
        );
    }
    // The worker's request carries it, and the project state keeps it.
    let request = crate::object_request(&app.params, &app.table).unwrap();
    assert_eq!(request.recording.as_deref(), Some(&recording));
    let state = app.params.serialize_fields();
    let restored = ModalForgeParams::default();
    restored.deserialize_fields(&state);
    assert_eq!(
        restored.recording.read().unwrap().as_ref(),
        Some(&recording)
    );
    // A sculpting edit plays the shape again.
    app.camera = front_camera();
    app.tool = super::Tool::Add;
    assert!(app.click([0.0, 0.0]).is_none());
    assert!(app.params.recording.read().unwrap().is_none());
    assert!(crate::object_request(&app.params, &app.table)
        .unwrap()
        .recording
        .is_none());

    // A real recording (the committed cowbell, 0.17 s): every extracted mode plays, as
    // extracted, under its fitted law (power law, as `tests/analysis.rs` finds).
    let cowbell = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../tests/data/recordings/cowbell.wav"
    );
    let played = super::matching::run_play(std::path::Path::new(cowbell)).unwrap();
    assert!(played.modes.len() >= 20, "{} modes", played.modes.len());
    let (law, mu1, mu2) = played.damping.unwrap();
    assert_eq!(law, crate::params::DampingChoice::PowerLaw);
    let mut v = voicing;
    v.damping = modalforge::engine::DampingParams::PowerLaw {
        mu1: mu1 as f64,
        mu2: mu2 as f64,
    };
    let object = RecordedObject::new("cowbell", &played.modes, &v).unwrap();
    let lines = spectrum(&ObjectModes::Recorded(object), &v, 48_000.0).unwrap();
    assert_eq!(lines.len(), played.modes.len());
    let mut want = played.modes.clone();
    want.sort_by(|a, b| a.freq_hz.total_cmp(&b.freq_hz));
    for (line, m) in lines.iter().zip(&want) {
        assert!(
            (line.freq_hz / m.freq_hz - 1.0).abs() < 1e-9,
            "{line:?} vs {m:?}"
        );
        // Unless the mode is more than 1000x off the law (the ratio's clamp).
        assert!(
            (line.decay_per_s / m.decay_per_s - 1.0).abs() < 1e-6,
            "{line:?} vs {m:?}"
        );
    }

    let text = dir.join("notes.wav");
    std::fs::write(&text, "not audio").unwrap();
    let e = super::matching::run_play(&text).unwrap_err().to_string();
    assert!(
        e.starts_with("cannot use recording") && !e.contains('\n'),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).ok();
}
