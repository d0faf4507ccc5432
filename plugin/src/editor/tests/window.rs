//! The window headless (egui, the real panels): layout down to the minimum size, the caption and
//! message strips, the status line, the self-redraw rate and the state dump a scripted window
//! test reads.

use super::*;
/// The whole window laid out headless (egui, the real panels) at the stated minimum, a
/// mid size and the default: every control the scripted window test clicks lies inside the
/// window and inside its own panel (nothing runs behind the parameters panel, as the Resample
/// value did at the default size), and the 3D view keeps room (at least 200 x 100 px at the
/// minimum). A compact window keeps the file actions in a File menu.
#[test]
fn every_control_is_inside_the_window_down_to_the_minimum() {
    use super::layout::{PanelSizes, MIN_WINDOW_PX};
    let host = TestHost::default();
    let setter = ParamSetter { raw_context: &host };
    let default = PanelSizes::for_window([WINDOW_SIZE.0 as f32, WINDOW_SIZE.1 as f32]);
    assert_eq!((default.controls_px, default.spectrum_px), (300.0, 170.0));
    for [w, h] in [
        MIN_WINDOW_PX,
        [800.0, 500.0],
        [WINDOW_SIZE.0 as f32, WINDOW_SIZE.1 as f32],
    ] {
        let mut app = app_with(block([6, 6, 6]));
        app.dump = Some(super::dump::Dump::to(std::env::temp_dir().join("unused")));
        let ctx = egui::Context::default();
        let sizes = PanelSizes::for_window([w, h]);
        let mut rects = Vec::new();
        // Two frames: panels and wrapped rows settle on the second.
        for _ in 0..2 {
            let input = egui::RawInput {
                screen_rect: Some(egui::Rect::from_min_size(egui::Pos2::ZERO, [w, h].into())),
                ..Default::default()
            };
            let _ = ctx.run_ui(input, |ui| super::layout::window(&mut app, ui, &setter));
            rects = app.dump.as_ref().unwrap().rects().to_vec();
            app.dump = Some(super::dump::Dump::to(std::env::temp_dir().join("unused")));
        }
        let get = |name: &str| {
            rects
                .iter()
                .find(|(n, _)| *n == name)
                .map(|(_, r)| *r)
                .unwrap_or_else(|| panic!("{w}x{h}: {name} not drawn: {rects:?}"))
        };
        let central_right = w - sizes.controls_px;
        let window = egui::Rect::from_min_size(egui::Pos2::ZERO, [w, h].into());
        for name in [
            "path", "import", "undo", "redo", "hollow", "resample", "view",
        ] {
            let r = get(name);
            assert!(
                window.contains_rect(r),
                "{w}x{h}: {name} at {r:?}; {rects:?}"
            );
        }
        for name in ["undo", "redo", "view"] {
            let r = get(name);
            assert!(
                r.max.x <= central_right + 1.0,
                "{w}x{h}: {name} at {r:?} runs behind the panel"
            );
        }
        let (hollow, resample) = (get("hollow"), get("resample"));
        if sizes.compact {
            get("file_menu");
            assert!(rects.iter().all(|(n, _)| *n != "save_preset"));
            // The shape operations sit in the parameters panel.
            assert!(hollow.min.x >= central_right && resample.min.x >= central_right);
        } else {
            get("save_preset");
            assert!(hollow.max.x <= central_right && resample.max.x <= central_right);
        }
        let view = get("view");
        assert!(
            view.width() >= 200.0 && view.height() >= 100.0,
            "{w}x{h}: view {view:?}"
        );
    }
}

#[test]
fn the_caption_has_its_own_strip_below_the_picture() {
    // The caption is never drawn over the object: its strip and the picture do not overlap,
    // and together they fill the view's area; an area shorter than the strip gives the strip
    // all of it.
    use egui::{Pos2, Rect};
    let area = Rect::from_min_max(Pos2::new(10.0, 20.0), Pos2::new(410.0, 320.0));
    let (picture, caption) = super::layout::view_and_caption(area);
    assert_eq!(picture.max.y, caption.min.y);
    assert_eq!((picture.min, caption.max), (area.min, area.max));
    assert!(caption.height() > 10.0 && picture.height() > 250.0);
    let tiny = Rect::from_min_max(Pos2::new(0.0, 0.0), Pos2::new(50.0, 5.0));
    let (picture, caption) = super::layout::view_and_caption(tiny);
    assert_eq!((picture.height(), caption), (0.0, tiny));
}

/// A stand-in approximate answer (the exact modes, labelled approximate) and a slow exact one,
/// so the status line can be read while the exact answer is still being solved.
struct Labelled {
    name: &'static str,
    error: Option<f64>,
    delay_ms: u64,
}

impl modalforge::engine::ModeSolver for Labelled {
    fn name(&self) -> &'static str {
        self.name
    }
    fn expected_error(&self, _request: &modalforge::engine::ObjectRequest) -> Option<f64> {
        self.error
    }
    fn solve(
        &mut self,
        r: &modalforge::engine::ObjectRequest,
    ) -> Result<modalforge::engine::ObjectModes, modalforge::basis::BasisError> {
        std::thread::sleep(std::time::Duration::from_millis(self.delay_ms));
        modalforge::engine::FemSolver.solve(r)
    }
}

#[test]
fn the_status_line_says_which_answer_plays_and_its_error() {
    use modalforge::engine::{Engine, EngineConfig, ModeSolver};
    let app = app_with(block([6, 3, 3]));
    let material = modalforge::material::Material::preset("steel").unwrap();
    let voicing = Voicing::from_material(&material, 0.2).unwrap();
    let solvers: Vec<Box<dyn ModeSolver>> = vec![
        Box::new(Labelled {
            name: "carried",
            error: Some(modalforge::engine::CARRIED_EXPECTED_ERROR),
            delay_ms: 0,
        }),
        Box::new(Labelled {
            name: "fem",
            error: None,
            delay_ms: 1500,
        }),
    ];
    let (_audio, control) =
        Engine::start(48_000.0, EngineConfig::default(), voicing, solvers).expect("engine");
    let control = Arc::new(control);
    *app.link.control.lock().unwrap() = Some(control.clone());
    let grid = modalforge::shape::VoxelGrid::from_fn([6, 3, 3], 0.01, |_, _, _| true).unwrap();
    control.request(modalforge::engine::ObjectRequest {
        grid,
        element: modalforge::fem::ElementKind::Hex8Incompatible,
        poisson_ratio: material.poisson_ratio,
        solver: modalforge::eigen::SolverKind::Lanczos,
        options: modalforge::eigen::EigenOptions {
            count: modalforge::eigen::ModeCount::First(10),
            ..Default::default()
        },
        recording: None,
    });
    // The approximate answer lands first; the status says so while the exact one is solved.
    let start = std::time::Instant::now();
    let mut seen = None;
    while start.elapsed() < std::time::Duration::from_secs(20) {
        let (line, _) = app.status_line();
        if line.contains("solving") && line.contains("playing") {
            seen = Some(line);
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    let seen = seen.expect("a status line naming the approximate answer");
    assert!(
        seen.starts_with("playing the carried answer (within ~1 %) · solving..."),
        "{seen}"
    );
    assert!(control.wait_idle(std::time::Duration::from_secs(20)));
    let (line, error) = app.status_line();
    assert!(!error);
    assert!(line.starts_with("10 modes solved in"), "{line}");
    assert!(
        line.contains("(fem)") && !line.contains("playing"),
        "{line}"
    );
}

/// The state dump a scripted window test reads: the object, undo depth, tool, hit and
/// message as the app holds them, one `key=value` per line (a message's line break would
/// start a bogus key, so it is flattened).
#[test]
fn the_state_dump_says_what_the_app_holds() {
    let mut app = app_with(block([4, 3, 2]));
    app.camera = front_camera();
    app.tool = Tool::Add;
    app.click([0.0, 0.0]);
    app.message = Some(("two\nlines".into(), true));
    let state = app.dump_state([480.0, 360.0]);
    let get = |k: &str| {
        state
            .iter()
            .find(|(key, _)| *key == k)
            .map(|(_, v)| v.clone())
    };
    assert_eq!(get("voxels"), Some(app.sculptor.count().to_string()));
    assert_eq!(get("undo").as_deref(), Some("1"));
    assert_eq!(get("tool").as_deref(), Some("add"));
    assert_eq!(get("window").as_deref(), Some("480,360"));
    assert_eq!(get("message_is_error").as_deref(), Some("true"));
    assert_eq!(get("import_pending").as_deref(), Some("no"));
    let p = &app.params.strike;
    let hit = format!(
        "{},{},{}",
        p.hit_x.value(),
        p.hit_y.value(),
        p.hit_z.value()
    );
    assert_eq!(get("hit"), Some(hit));

    let file = std::env::temp_dir().join(format!("mf-dump-{}.txt", std::process::id()));
    let mut dump = super::dump::Dump::to(file.clone());
    dump.mark(
        "view",
        egui::Rect::from_min_max([1.0, 2.0].into(), [30.0, 40.0].into()),
    );
    dump.write(&state);
    let text = std::fs::read_to_string(&file).unwrap();
    assert!(text.contains("message=two lines\n"), "{text}");
    assert!(text.ends_with("rect.view=1,2,30,40\n"), "{text}");
    assert_eq!(text.lines().count(), state.len() + 1);
    std::fs::remove_file(&file).ok();
}

/// The message under the top bar has a line of its own: the bar is as tall with a message
/// as without, so nothing below it moves when one appears or clears (it moved by 18 px).
#[test]
fn a_message_does_not_move_the_window() {
    let host = TestHost::default();
    let setter = ParamSetter { raw_context: &host };
    let mut app = app_with(block([4, 4, 4]));
    let ctx = egui::Context::default();
    let height = |app: &mut EditorApp| {
        let mut h = 0.0;
        let _ = ctx.run_ui(egui::RawInput::default(), |ui| {
            let r = ui
                .scope(|ui| super::layout::top_bar(app, ui, &setter, false))
                .response;
            h = r.rect.height();
        });
        h
    };
    let quiet = height(&mut app);
    app.message = Some(("saved /tmp/x.toml".into(), false));
    let told = height(&mut app);
    app.message = Some(("cannot read /tmp/y.vox: no such file".into(), true));
    let error = height(&mut app);
    assert!(quiet > 0.0);
    assert_eq!((quiet, quiet), (told, error));
}

/// An idle window does not redraw ten times a second: without an engine, a solve, a match or
/// ringing notes it asks for a redraw every 2 s (solves repaint it through the engine's status
/// watcher); while a match runs, every 0.1 s.
#[test]
fn an_idle_window_redraws_slowly() {
    let mut app = app_with(block([4, 4, 4]));
    assert_eq!(app.redraw_after(), std::time::Duration::from_secs(2));
    let missing = std::env::temp_dir().join("modalforge-no-such-recording.wav");
    app.path = missing.display().to_string();
    app.start_match();
    assert!(app.matching.is_some());
    assert_eq!(app.redraw_after(), std::time::Duration::from_millis(100));
}

#[test]
fn the_window_resizes_down_to_the_layouts_minimum() {
    use nice_plug::editor::SizeConstraints;
    let hint = super::resize_hint();
    assert!(hint.can_resize && hint.can_resize_horizontally && hint.can_resize_vertically);
    let SizeConstraints::Logical {
        min_size: Some(min),
        max_size: None,
    } = hint.size_constraints
    else {
        panic!("{:?}", hint.size_constraints)
    };
    assert_eq!([min.width, min.height], super::layout::MIN_WINDOW_PX);
}
