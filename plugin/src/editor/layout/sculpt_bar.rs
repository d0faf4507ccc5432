//! The sculpting bar: the tools, undo and redo, the brush and mirror, the shape operations
//! (New, Hollow, Resample) and the section plane, in wrapping rows of groups that never
//! split; a compact window moves all but the tools to the top of the parameters panel.
//!
//! Where it sits: drawn by [`super::window`] between the file bar and the 3D view; what its
//! controls do lives on [`EditorApp`] and its [`sculptor::Sculptor`].

use super::{tool_key, undo_shortcuts};
use crate::editor::{sculptor, view3d, EditorApp, Tool, PRIMITIVES};

/// The sculpting bar: the tools and undo/redo, then (in a wide window) the brush, mirror
/// and the shape operations; a compact window moves those to the top of the parameters panel
/// ([`sculpt_controls`]), which scrolls. Rows wrap between groups, never inside one.
pub(in crate::editor) fn sculpt_bar(app: &mut EditorApp, ui: &mut egui::Ui, compact: bool) {
    ui.horizontal_wrapped(|ui| {
        ui.selectable_value(&mut app.tool, Tool::Add, "Add")
            .on_hover_text("click the view to add voxels (key A)");
        ui.selectable_value(&mut app.tool, Tool::Remove, "Remove")
            .on_hover_text("click the view to remove voxels (key R)");
        ui.selectable_value(&mut app.tool, Tool::Hit, "Hit")
            .on_hover_text("click the view to set the hit point and strike (key H)");
        ui.separator();
        if !compact {
            let brush = groups(app, true);
            bar_row(app, ui, &brush[..2]);
            ui.separator();
        }
        group(ui, 110.0);
        let undo = ui.add_enabled(app.sculptor.undo_depth() > 0, egui::Button::new("Undo"));
        let redo = ui.add_enabled(app.sculptor.redo_depth() > 0, egui::Button::new("Redo"));
        app.mark("undo", undo.rect);
        app.mark("redo", redo.rect);
        let (undo_key, redo_key) = undo_shortcuts(ui);
        if let Some(tool) = tool_key(ui) {
            app.tool = tool;
        }
        if undo.clicked() || undo_key {
            app.undo();
        }
        if redo.clicked() || redo_key {
            app.redo();
        }
    });
    if !compact {
        let shape = groups(app, false);
        ui.horizontal_wrapped(|ui| bar_row(app, ui, &shape));
    }
}

/// The sculpting controls a compact window shows at the top of the parameters panel, a row
/// per group (a row that still does not fit wraps its button under its slider).
pub(in crate::editor) fn sculpt_controls(app: &mut EditorApp, ui: &mut egui::Ui) {
    ui.heading("Sculpt");
    for (_, g) in groups(app, true) {
        ui.horizontal_wrapped(|ui| {
            ui.spacing_mut().slider_width = COMPACT_SLIDER_PX;
            g(app, ui);
        });
    }
    ui.separator();
}

/// Starts a new row of a wrapping layout unless `width_px` more fit in this one: egui wraps
/// before a single widget that does not fit, but a slider with its value box is laid out as
/// one nested row, which it would let run past the edge (behind the parameters panel).
fn group(ui: &mut egui::Ui, width_px: f32) {
    // (A wrapping row's `available_width` is the whole row's: it could wrap.)
    let left_px = ui.max_rect().max.x - ui.cursor().min.x;
    let row_started = ui.cursor().min.x > ui.max_rect().min.x + 1.0;
    if row_started && left_px < width_px {
        ui.end_row();
    }
}

/// Slider width in the sculpting bar, pixels (the value box comes beside it).
const SLIDER_PX: f32 = 80.0;

/// Slider width in the compact window's sculpting controls, pixels.
const COMPACT_SLIDER_PX: f32 = 60.0;

/// A group of sculpting controls: how wide it is in the sculpting bar (pixels, its value
/// boxes included) and what draws it.
type Group = (f32, fn(&mut EditorApp, &mut egui::Ui));

/// The sculpting groups in order: the brush and mirror (in the bar's first row when wide,
/// `with_brush`), then New, Hollow, Resample and the section plane.
fn groups(app: &EditorApp, with_brush: bool) -> Vec<Group> {
    let section_px = if app.camera.section.is_some() {
        SLIDER_PX + 170.0
    } else {
        100.0
    };
    let brush: [Group; 2] = [(SLIDER_PX + 95.0, brush), (150.0, mirror)];
    let shape: [Group; 4] = [
        (SLIDER_PX + 200.0, new_shape),
        (SLIDER_PX + 140.0, hollow),
        (SLIDER_PX + 160.0, resample),
        (section_px, section_controls),
    ];
    let mut all = Vec::new();
    if with_brush {
        all.extend(brush);
    }
    all.extend(shape);
    all
}

/// Groups in one wrapping row of the sculpting bar, separated, a row break before a group that
/// would not fit.
fn bar_row(app: &mut EditorApp, ui: &mut egui::Ui, groups: &[Group]) {
    ui.spacing_mut().slider_width = SLIDER_PX;
    for (i, (width_px, g)) in groups.iter().enumerate() {
        if i > 0 {
            ui.separator();
        }
        group(ui, *width_px);
        g(app, ui);
    }
}

/// Brush radius.
fn brush(app: &mut EditorApp, ui: &mut egui::Ui) {
    ui.label("Brush");
    ui.add(egui::Slider::new(&mut app.sculptor.brush_radius, 0..=4));
}

/// The mirror planes.
fn mirror(app: &mut EditorApp, ui: &mut egui::Ui) {
    ui.label("Mirror");
    for (a, name) in ["X", "Y", "Z"].iter().enumerate() {
        ui.checkbox(&mut app.sculptor.mirror[a], *name);
    }
}

/// A new primitive of a chosen size.
fn new_shape(app: &mut EditorApp, ui: &mut egui::Ui) {
    egui::ComboBox::from_id_salt("primitive")
        .selected_text(PRIMITIVES[app.primitive].name)
        .width(70.0)
        .show_ui(ui, |ui| {
            for (i, shape) in PRIMITIVES.iter().enumerate() {
                ui.selectable_value(&mut app.primitive, i, shape.name);
            }
        });
    group(ui, SLIDER_PX + 60.0);
    ui.add(egui::Slider::new(&mut app.primitive_side, 4..=32).suffix(" vox"))
        .on_hover_text("longest side of the new shape, voxels");
    group(ui, 45.0);
    if ui.button("New").clicked() {
        let (spec, side) = (PRIMITIVES[app.primitive].name, app.primitive_side);
        app.edit(|s| s.load_primitive(spec, side));
    }
}

/// Hollow with a chosen wall.
fn hollow(app: &mut EditorApp, ui: &mut egui::Ui) {
    ui.add(egui::Slider::new(&mut app.hollow_wall, 1..=4).suffix(" wall"));
    group(ui, 65.0);
    let hollow = ui.button("Hollow");
    app.mark("hollow", hollow.rect);
    if hollow.clicked() {
        let w = app.hollow_wall;
        app.edit(|s| s.hollow(w));
    }
}

/// Resample to a chosen resolution.
fn resample(app: &mut EditorApp, ui: &mut egui::Ui) {
    ui.add(egui::Slider::new(&mut app.resample_side, 2..=32).suffix(" vox"))
        .on_hover_text("resolution: the object's longest side, voxels");
    group(ui, 80.0);
    let resample = ui.button("Resample");
    app.mark("resample", resample.rect);
    if resample.clicked() {
        let n = app.resample_side;
        app.edit(|s| s.resample(n));
    }
}

/// The view's section plane: off, or a cut across x, y or z at a chosen height, so that a
/// hollowed or closed object's inside shows (the view only: the object is unchanged).
fn section_controls(app: &mut EditorApp, ui: &mut egui::Ui) {
    const NAMES: [&str; 4] = ["Cut X", "Cut Y", "Cut Z", "No cut"];
    let mut axis = app.camera.section.map_or(3, |s| s.axis);
    egui::ComboBox::from_id_salt("section")
        .selected_text(NAMES[axis])
        .show_ui(ui, |ui| {
            for (i, name) in NAMES.iter().enumerate() {
                ui.selectable_value(&mut axis, i, *name);
            }
        })
        .response
        .on_hover_text("cut the view open to see inside (the object is not changed)");
    app.camera.section = (axis < 3).then(|| {
        let centre = app
            .sculptor
            .bounds()
            .map_or(16.0, |(lo, d)| lo[axis] as f32 + d[axis] as f32 / 2.0);
        let mut at = app
            .camera
            .section
            .filter(|s| s.axis == axis)
            .map_or(centre, |s| s.at);
        let side = sculptor::BOX_SIDE as f32;
        group(ui, SLIDER_PX + 70.0);
        ui.add(egui::Slider::new(&mut at, 0.0..=side).suffix(" vox"));
        view3d::Section { axis, at }
    });
}
