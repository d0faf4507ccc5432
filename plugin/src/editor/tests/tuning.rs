//! Scala tunings and the scale parameter through the editor and the project state.

use super::*;
/// Scala tuning through the plugin (issue 15). Truth: 19-TET from its definition,
/// `261.6256 * 2^((k - 60) / 19)` Hz (the default mapping puts degree 0 on middle C). The
/// editor loads the `.scl`, the key table holds every key within 0.1 cent, a note-on in the
/// pitch mapping asks the engine for exactly that fundamental, and a project restored with
/// the tuning gets the same table from the worker's poll; a `.kbm` with an `x` silences its
/// key; 12-TET is back with one click.
#[test]
fn a_scala_tuning_tunes_every_key_and_is_restored_with_the_project() {
    use modalforge::engine::{Engine, EngineConfig, Event, Pitch};
    let dir = std::env::temp_dir().join(format!("mf-tuning-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scl = dir.join("19edo.scl");
    let mut text = String::from("! 19edo.scl\n19-EDO\n19\n");
    for i in 1..19 {
        text += &format!("{:.5}\n", 1200.0 * i as f64 / 19.0);
    }
    text += "2/1\n";
    std::fs::write(&scl, text).unwrap();
    let params = Arc::new(ModalForgeParams::default());
    let table = Arc::new(MaterialTable::new());
    let mut app = EditorApp::new(
        params.clone(),
        table.clone(),
        Arc::new(EditorLink::default()),
    );
    app.path = scl.display().to_string();
    app.load_tuning();
    let (m, error) = app.message.clone().unwrap();
    assert!(
        !error && m.starts_with("tuning: 19-EDO (19 notes a period)"),
        "{m}"
    );
    let c4 = 440.0 * 2f64.powf(-9.0 / 12.0);
    let want = |k: u8| c4 * 2f64.powf((k as f64 - 60.0) / 19.0);
    let cents = |a: f64, b: f64| 1200.0 * (a / b).log2();
    for k in 0..128u8 {
        let got = params.key_table.hz(k);
        assert!(
            cents(got, want(k)).abs() < 0.1,
            "key {k}: {got} vs {}",
            want(k)
        );
    }
    // A note-on in the pitch mapping strikes at the table's frequency.
    let (engine, _control) = Engine::start(
        48_000.0,
        EngineConfig::default(),
        params.voicing(&table, 1.0, 1.0),
        Vec::new(),
    )
    .unwrap();
    let mut keymap = crate::keymap::KeyMap::default();
    let mut events = Vec::with_capacity(4);
    let on = |k: u8| NoteEvent::<()>::NoteOn {
        timing: 0,
        voice_id: nice_plug::midi::VoiceID::Wildcard,
        channel: nice_plug::midi::Channel::Number(0),
        key: nice_plug::midi::Key::Number(k),
        velocity: 0.8,
    };
    keymap.translate(&on(79), &params, &engine, &mut events, 4);
    match events[0].event {
        Event::Strike {
            pitch: Pitch::Fundamental(f),
            ..
        } => assert!(cents(f, 2.0 * c4).abs() < 1e-3, "{f}"),
        ref e => panic!("{e:?}"),
    }
    // A project saved with it and restored into fresh parameters: the worker's poll builds
    // the same table.
    let restored = Arc::new(ModalForgeParams::default());
    restored.deserialize_fields(&params.serialize_fields());
    let mut source = crate::solve_source(restored.clone(), table.clone(), Default::default());
    let _ = source();
    assert_eq!(restored.key_table.hz(41), params.key_table.hz(41));
    // A mapping that silences C#: that key strikes nothing.
    let kbm = dir.join("no-sharp.kbm");
    std::fs::write(&kbm, "2\n0\n127\n60\n60\n261.6256\n0\n0\nx\n").unwrap();
    app.path = kbm.display().to_string();
    app.load_tuning();
    assert_eq!(params.key_table.hz(61), 0.0);
    events.clear();
    keymap.translate(&on(61), &params, &engine, &mut events, 4);
    assert!(events.is_empty());
    app.reset_tuning();
    assert!((params.key_table.hz(69) - 440.0).abs() < 1e-9);
    assert!(params.tuning.read().unwrap().is_none());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn the_scale_is_clamped_saved_with_the_project_and_applied() {
    // 75-200 %: a choice from the menu is saved and applied; out-of-range values (egui's
    // zoom keys step by 10 % without a limit, a state edited by hand) are clamped, NaN is 100 %.
    // egui applies a zoom at the start of the next frame.
    let frame = |ctx: &egui::Context| {
        let _ = ctx.run_ui(egui::RawInput::default(), |_| {});
    };
    let mut app = app_with(block([4, 4, 4]));
    let ctx = egui::Context::default();
    assert_eq!(app.scale(), 1.0);
    app.set_scale(&ctx, 1.5);
    frame(&ctx);
    assert_eq!((app.scale(), ctx.zoom_factor()), (1.5, 1.5));
    for (asked, got) in [(5.0, 2.0), (0.1, 0.75), (f32::NAN, 1.0)] {
        app.set_scale(&ctx, asked);
        frame(&ctx);
        assert_eq!((app.scale(), ctx.zoom_factor()), (got, got), "{asked}");
    }
    // Ctrl+Minus below the range: the saved scale and the window stop at 75 %.
    ctx.set_zoom_factor(0.6);
    frame(&ctx);
    app.follow_zoom_keys(&ctx);
    frame(&ctx);
    assert_eq!((app.scale(), ctx.zoom_factor()), (0.75, 0.75));
    // Saved with the project; states from before the scale existed open at 100 %.
    app.set_scale(&ctx, 1.25);
    let restored = ModalForgeParams::default();
    restored.deserialize_fields(&app.params.serialize_fields());
    assert_eq!(*restored.ui_scale.read().unwrap(), 1.25);
    let mut old = app.params.serialize_fields();
    old.remove("ui-scale");
    let restored = ModalForgeParams::default();
    restored.deserialize_fields(&old);
    assert_eq!(*restored.ui_scale.read().unwrap(), 1.0);
}
