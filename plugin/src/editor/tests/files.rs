//! Files and state: presets saved and loaded, a state the host restores, `.vox` and mesh imports
//! and what each file action says.

use super::*;
#[test]
fn the_editor_follows_a_state_the_host_restores() {
    let mut app = app_with(block([4, 4, 4]));
    *app.params.object.write().unwrap() = block([6, 2, 2]);
    app.follow_host();
    assert_eq!(app.sculptor.bounds().unwrap().1, [6, 2, 2]);
    assert_eq!(app.sculptor.count(), 24);
}

#[test]
fn presets_save_and_load_through_files() {
    // The window's settings as a preset file, read back: same object and settings.
    let app = app_with(block([5, 3, 2]));
    let p = app.current_preset("mine").unwrap();
    let dir = std::env::temp_dir().join(format!("mf-preset-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("mine.toml");
    std::fs::write(&path, p.to_toml()).unwrap();
    let back = Preset::from_toml(&std::fs::read_to_string(&path).unwrap(), "mine.toml").unwrap();
    assert_eq!(back, p);
    assert_eq!(back.sculpt().unwrap(), block([5, 3, 2]));
    assert_eq!(back.material, "glass");
    // A damaged file is refused with the file's name and what is wrong.
    let bad = p.to_toml().replace("glass", "unobtainium");
    let e = Preset::from_toml(&bad, "bad.toml").unwrap_err().to_string();
    assert!(e.contains("bad.toml") && e.contains("unobtainium"), "{e}");
    let e = Preset::from_toml("name = 3", "x.toml")
        .unwrap_err()
        .to_string();
    assert!(e.contains("x.toml"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
    // A sculpted curved object keeps its partial voxels through a preset file; a file
    // without `fill` (saved before partial voxels) loads as the binary object it was.
    let bowl = Sculpt::default();
    assert!(!bowl.fill.is_empty());
    let p = Preset::with_object("bowl", &bowl);
    let back = Preset::from_toml(&p.to_toml(), "bowl.toml").unwrap();
    assert_eq!(back.sculpt().unwrap(), bowl);
    let old = p.to_toml().replace(
        &format!("fill = \"{}\"", p.object.as_ref().unwrap().fill),
        "",
    );
    assert!(!old.contains("fill"));
    let binary = Preset::from_toml(&old, "old.toml")
        .unwrap()
        .sculpt()
        .unwrap();
    assert!(binary.fill.is_empty() && binary.bits == bowl.bits);
}

/// Honest feedback through the host: applying a preset names it (its description, or
/// "loaded preset NAME" when it has none) and marks it current; an edit clears the message and
/// marks the preset modified; loading a `.vox` says what it loaded; a file that is not a
/// `.vox` is one error that does not repeat itself and says what to do.
#[test]
fn file_actions_say_what_they_did() {
    let host = TestHost::default();
    let setter = ParamSetter { raw_context: &host };
    let mut app = app_with(block([4, 4, 4]));
    assert_eq!(app.presets_caption(), "Presets");
    let mut preset = app.current_preset("plain").unwrap();
    preset.description = String::new();
    app.apply_preset(&preset, &setter);
    assert_eq!(
        app.message.clone().unwrap(),
        ("loaded preset plain".into(), false)
    );
    assert_eq!(app.presets_caption(), "plain");
    preset.description = "a plain block".into();
    app.apply_preset(&preset, &setter);
    assert_eq!(app.message.clone().unwrap().0, "plain: a plain block");
    app.edit(|s| s.load_primitive("box", 5));
    assert_eq!(app.message, None);
    assert_eq!(app.presets_caption(), "plain (modified)");

    let dir = std::env::temp_dir().join(format!("mf-feedback-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let vox = dir.join("block.vox");
    let grid = modalforge::shape::VoxelGrid::from_fn([6, 5, 3], 1.0, |_, _, _| true).unwrap();
    modalforge::shape::vox::write_vox(&grid, &vox).unwrap();
    app.path = vox.display().to_string();
    app.import();
    let (m, error) = app.message.clone().unwrap();
    assert!(
        !error && m == format!("loaded {}: 6x5x3, 90 voxels", vox.display()),
        "{m}"
    );
    let bad = dir.join("notes.vox");
    std::fs::write(&bad, "not a model").unwrap();
    app.path = bad.display().to_string();
    app.import();
    let (m, error) = app.message.clone().unwrap();
    assert!(
        error && m.contains("export it from MagicaVoxel again"),
        "{m}"
    );
    assert_eq!(
        m.to_lowercase().matches("not a valid magicavoxel").count(),
        1,
        "{m}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// Any model can be imported (issue 18): a MagicaVoxel model larger than the 32^3 box is
/// resampled to the import size (48x24x12 -> 32x16x8, the proportions kept exactly, the
/// solid block staying solid: 4096 voxels), an OBJ mesh (a 2 x 1 x 1 box) is voxelised to it
/// (32x16x16, full: 8192), each says what it did, and undo restores the object before.
#[test]
fn models_larger_than_the_box_are_fitted_and_meshes_voxelised() {
    let mut app = app_with(block([4, 4, 4]));
    let dir = std::env::temp_dir().join(format!("mf-import-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let vox = dir.join("big.vox");
    let big = modalforge::shape::VoxelGrid::from_fn([48, 24, 12], 1.0, |_, _, _| true).unwrap();
    modalforge::shape::vox::write_vox(&big, &vox).unwrap();
    app.path = vox.display().to_string();
    let before = app.params.object.read().unwrap().clone();
    app.import();
    // Previewed, resampled to fit, and not yet the object the engine solves.
    let (m, error) = app.message.clone().unwrap();
    assert!(!error, "{m}");
    assert!(
        m.contains("48x24x12, 13824 voxels, resampled to 32x16x8 (4096 voxels)")
            && m.contains("(a preview): Keep it, try the other fit, or Cancel"),
        "{m}"
    );
    assert_eq!(app.pending_import(), Some(ImportFit::Resample));
    assert_eq!(app.sculptor.bounds().unwrap().1, [32, 16, 8]);
    assert_eq!(app.sculptor.count(), 4096);
    assert_eq!(*app.params.object.read().unwrap(), before);
    // Cropped instead: the central 32 of the 48 along x, the rest whole (32 * 24 * 12).
    app.set_import_fit(ImportFit::Crop);
    let (m, _) = app.message.clone().unwrap();
    assert!(m.contains("cropped to 32x24x12 (9216 voxels)"), "{m}");
    assert_eq!(app.sculptor.count(), 9216);
    assert_eq!(app.sculptor.undo_depth(), 1);
    // Cancelled: the object before is back, with nothing to redo and nothing solved.
    app.cancel_import();
    assert_eq!(app.pending_import(), None);
    assert_eq!(app.sculptor.bounds().unwrap().1, [4, 4, 4]);
    assert_eq!(
        (app.sculptor.undo_depth(), app.sculptor.redo_depth()),
        (0, 0)
    );
    assert_eq!(*app.params.object.read().unwrap(), before);
    // Kept: it becomes the object, one undo step.
    app.import();
    app.keep_import();
    let (m, error) = app.message.clone().unwrap();
    assert!(
        !error && m.contains("32x16x8, 4096 voxels (resampled)") && m.contains("Ctrl+Z"),
        "{m}"
    );
    assert_eq!(app.pending_import(), None);
    let published = app.params.object.read().unwrap().to_grid().unwrap();
    assert_eq!((published.dims(), published.count()), ([32, 16, 8], 4096));
    assert!(app.undo());
    assert_eq!(app.sculptor.bounds().unwrap().1, [4, 4, 4]);
    // A sculpting edit on a preview keeps it.
    app.import();
    app.camera = front_camera();
    app.tool = Tool::Add;
    app.click([0.0, 0.0]);
    assert_eq!(app.pending_import(), None);
    assert!(app.sculptor.count() > 4096);

    let obj = dir.join("brick.obj");
    let v = [
        [0., 0., 0.],
        [2., 0., 0.],
        [2., 1., 0.],
        [0., 1., 0.],
        [0., 0., 1.],
        [2., 0., 1.],
        [2., 1., 1.],
        [0., 1., 1.],
    ];
    // Outward-facing quads, as two triangles each (OBJ indices from 1).
    let quads = [
        [1, 4, 3, 2],
        [5, 6, 7, 8],
        [1, 2, 6, 5],
        [2, 3, 7, 6],
        [3, 4, 8, 7],
        [4, 1, 5, 8],
    ];
    let mut text = String::new();
    for p in v {
        text += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    for q in quads {
        text += &format!(
            "f {} {} {}\nf {} {} {}\n",
            q[0], q[1], q[2], q[0], q[2], q[3]
        );
    }
    std::fs::write(&obj, text).unwrap();
    app.path = obj.display().to_string();
    app.import();
    let (m, error) = app.message.clone().unwrap();
    assert!(
        !error && m.contains("voxelised to 32x16x16, 8192 voxels"),
        "{m}"
    );
    assert_eq!(app.sculptor.count(), 8192);
    std::fs::remove_dir_all(&dir).ok();
}
