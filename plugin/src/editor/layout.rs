//! The editor window's panels: the file bar, the sculpting bar, the 3D view, the parameter
//! controls. Each takes the [`EditorApp`] and draws with egui; the logic they call lives on
//! [`EditorApp`] (tested without a window).

use super::{view3d, EditorApp, Tool, PRIMITIVES};
use crate::materials::MaterialChoice;
use egui::{Color32, Pos2, Rect, Sense, Stroke, Vec2};
use nice_plug::prelude::*;
use nice_plug_egui::widgets::ParamSlider;
use std::sync::atomic::Ordering;

/// A combo box for an enum parameter, set through the host.
fn enum_combo<T: Enum + PartialEq + Copy + 'static>(
    ui: &mut egui::Ui,
    label: &str,
    param: &EnumParam<T>,
    setter: &ParamSetter,
) {
    ui.horizontal(|ui| {
        ui.label(label);
        let current = param.value();
        egui::ComboBox::from_id_salt(label)
            .selected_text(T::variants()[current.to_index()])
            .show_ui(ui, |ui| {
                for (i, name) in T::variants().iter().enumerate() {
                    let v = T::from_index(i);
                    if ui.selectable_label(v == current, *name).clicked() {
                        setter.begin_set_parameter(param);
                        setter.set_parameter(param, v);
                        setter.end_set_parameter(param);
                    }
                }
            });
    });
}

/// A labelled parameter slider.
fn slider<P: Param>(ui: &mut egui::Ui, label: &str, param: &P, setter: &ParamSetter) {
    ui.horizontal(|ui| {
        ui.add_sized([84.0, 18.0], egui::Label::new(label));
        ui.add(ParamSlider::for_param(param, setter).with_width(120.0));
    });
}

pub(super) fn top_bar(app: &mut EditorApp, ui: &mut egui::Ui, setter: &ParamSetter) {
    ui.horizontal_wrapped(|ui| {
        ui.strong("ModalForge");
        ui.separator();
        let mut chosen = None;
        let current = app.current_preset.as_ref().map(|(name, _)| name.clone());
        egui::ComboBox::from_id_salt("preset")
            .selected_text(app.presets_caption())
            .show_ui(ui, |ui| {
                for (i, p) in app.presets.iter().enumerate() {
                    if ui
                        .selectable_label(current.as_ref() == Some(&p.name), &p.name)
                        .on_hover_text(&p.description)
                        .clicked()
                    {
                        chosen = Some(i);
                    }
                }
            });
        if let Some(i) = chosen {
            let p = app.presets[i].clone();
            app.apply_preset(&p, setter);
        }
        ui.separator();
        ui.label("File");
        ui.add(egui::TextEdit::singleline(&mut app.path).desired_width(260.0));
        if ui
            .button("Import")
            .on_hover_text(
                "Load the model in the field: a MagicaVoxel .vox, or an OBJ or STL mesh \
                 (voxelised to the import size); a .vox larger than the 32^3 box is resampled \
                 to the import size. Ctrl+Z restores the previous object",
            )
            .clicked()
        {
            app.import();
        }
        ui.add(
            egui::DragValue::new(&mut app.import_side)
                .range(2..=32)
                .suffix(" vox"),
        )
        .on_hover_text("Import size: voxels along the longest side of an imported mesh");
        if ui.button("Save .vox").clicked() {
            app.save_vox();
        }
        if ui.button("Load preset").clicked() {
            match app.read_preset() {
                Ok(p) => app.apply_preset(&p, setter),
                Err(e) => app.message = Some((e.to_string(), true)),
            }
        }
        if ui.button("Save preset").clicked() {
            app.save_preset();
        }
        if ui
            .add_enabled(app.matching.is_none(), egui::Button::new("Match recording"))
            .on_hover_text(
                "Fit the material and damping of this object to a WAV of the real one struck \
                 at the hit point (the file in the field; the result is also saved as \
                 NAME.material.toml beside it)",
            )
            .clicked()
        {
            app.start_match();
        }
        if ui
            .add_enabled(app.matching.is_none(), egui::Button::new("Play recording"))
            .on_hover_text(
                "Play the modes of a WAV of a struck object (the file in the field) instead of \
                 the sculpted shape: in tune on every key, with the mallet, velocity, damping \
                 and size knobs; the next sculpting edit plays the shape again",
            )
            .clicked()
        {
            app.start_play();
        }
        if ui
            .button("Tuning")
            .on_hover_text(
                "Load a Scala tuning for the pitch key mapping: a .scl scale (the file in the \
                 field), then optionally a .kbm keyboard mapping; saved with the project",
            )
            .clicked()
        {
            app.load_tuning();
        }
        if ui
            .button("12-TET")
            .on_hover_text("Back to standard tuning (A4 = 440 Hz)")
            .clicked()
        {
            app.reset_tuning();
        }
    });
    // The message has a line of its own, there whether or not a message is showing, so
    // nothing below the bar moves when one appears or clears.
    let (text, colour) = match &app.message {
        Some((m, true)) => (m.as_str(), Color32::from_rgb(240, 110, 90)),
        Some((m, false)) => (m.as_str(), Color32::from_gray(180)),
        None => ("", Color32::from_gray(180)),
    };
    ui.add(egui::Label::new(egui::RichText::new(text).color(colour)).truncate())
        .on_hover_text(text);
}

/// Ctrl+Z (undo) and Ctrl+Shift+Z (redo) pressed this frame, unless a text field has the
/// keyboard (the file path). The modifiers are read from each key event (egui's
/// `consume_shortcut`), not from the frame's modifier state: a quick tap releases Ctrl before
/// the frame that sees the Z, and reading the frame's state missed 3 taps in 5. Redo is
/// matched first, since the undo shortcut also matches with Shift held.
fn undo_shortcuts(ui: &mut egui::Ui) -> (bool, bool) {
    if ui.ctx().egui_wants_keyboard_input() {
        return (false, false);
    }
    use egui::{Key, KeyboardShortcut, Modifiers};
    ui.input_mut(|i| {
        let redo = i.consume_shortcut(&KeyboardShortcut::new(
            Modifiers::COMMAND | Modifiers::SHIFT,
            Key::Z,
        ));
        let undo = i.consume_shortcut(&KeyboardShortcut::new(Modifiers::COMMAND, Key::Z));
        (undo, redo)
    })
}

/// The window's panel sizes for its size in pixels: the right panel (the parameters, which
/// scroll) and the bottom one (status line and spectrum) shrink with a small window, so that
/// the 3D view keeps at least half the width and a third of the height down to the stated
/// minimum window of [`MIN_WINDOW_PX`]; at the default size they are 300 and 170 px.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct PanelSizes {
    /// The right panel's width.
    pub controls_px: f32,
    /// The bottom panel's height (the spectrum gets it less the status line).
    pub spectrum_px: f32,
}

/// The smallest window the layout is made for (every control reachable: rows wrap, the
/// parameters scroll).
pub const MIN_WINDOW_PX: [f32; 2] = [480.0, 360.0];

impl PanelSizes {
    /// Sizes for a window of `window` pixels (width, height); a window under the minimum gets
    /// the minimum's.
    pub fn for_window(window: [f32; 2]) -> Self {
        let [w, h] = [0, 1].map(|a| window[a].max(MIN_WINDOW_PX[a]));
        Self {
            controls_px: (0.3 * w).clamp(180.0, 300.0),
            spectrum_px: (0.25 * h).clamp(90.0, 170.0),
        }
    }
}

pub(super) fn sculpt_bar(app: &mut EditorApp, ui: &mut egui::Ui) {
    ui.horizontal_wrapped(|ui| {
        ui.selectable_value(&mut app.tool, Tool::Add, "Add");
        ui.selectable_value(&mut app.tool, Tool::Remove, "Remove");
        ui.selectable_value(&mut app.tool, Tool::Hit, "Hit");
        ui.separator();
        ui.label("Brush");
        ui.add(egui::Slider::new(&mut app.sculptor.brush_radius, 0..=4));
        ui.label("Mirror");
        for (a, name) in ["X", "Y", "Z"].iter().enumerate() {
            ui.checkbox(&mut app.sculptor.mirror[a], *name);
        }
        ui.separator();
        let undo = ui.add_enabled(app.sculptor.undo_depth() > 0, egui::Button::new("Undo"));
        let redo = ui.add_enabled(app.sculptor.redo_depth() > 0, egui::Button::new("Redo"));
        let (undo_key, redo_key) = undo_shortcuts(ui);
        if undo.clicked() || undo_key {
            app.undo();
        }
        if redo.clicked() || redo_key {
            app.redo();
        }
    });
    ui.horizontal_wrapped(|ui| {
        egui::ComboBox::from_id_salt("primitive")
            .selected_text(PRIMITIVES[app.primitive].name)
            .show_ui(ui, |ui| {
                for (i, shape) in PRIMITIVES.iter().enumerate() {
                    ui.selectable_value(&mut app.primitive, i, shape.name);
                }
            });
        ui.add(egui::Slider::new(&mut app.primitive_side, 4..=32).suffix(" vox"))
            .on_hover_text("longest side of the new shape, voxels");
        if ui.button("New").clicked() {
            let (spec, side) = (PRIMITIVES[app.primitive].name, app.primitive_side);
            app.edit(|s| s.load_primitive(spec, side));
        }
        ui.separator();
        ui.add(egui::Slider::new(&mut app.hollow_wall, 1..=4).suffix(" wall"));
        if ui.button("Hollow").clicked() {
            let w = app.hollow_wall;
            app.edit(|s| s.hollow(w));
        }
        ui.separator();
        ui.add(egui::Slider::new(&mut app.resample_side, 2..=32).suffix(" vox"))
            .on_hover_text("resolution: the object's longest side, voxels");
        if ui.button("Resample").clicked() {
            let n = app.resample_side;
            app.edit(|s| s.resample(n));
        }
        ui.separator();
        section_controls(app, ui);
    });
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
        let side = super::sculptor::BOX_SIDE as f32;
        ui.add(egui::Slider::new(&mut at, 0.0..=side).suffix(" vox"));
        view3d::Section { axis, at }
    });
}

/// Height of the 3D view's caption strip, pixels.
const CAPTION_PX: f32 = 18.0;

/// The 3D view's area split into the picture and, below it, the caption's own strip, so the
/// caption is never drawn over the object.
pub(super) fn view_and_caption(area: Rect) -> (Rect, Rect) {
    let split = (area.max.y - CAPTION_PX).max(area.min.y);
    (
        Rect::from_min_max(area.min, Pos2::new(area.max.x, split)),
        Rect::from_min_max(Pos2::new(area.min.x, split), area.max),
    )
}

pub(super) fn view(app: &mut EditorApp, ui: &mut egui::Ui, setter: &ParamSetter) {
    let size = ui.available_size();
    let (response, full_painter) = ui.allocate_painter(size, Sense::click_and_drag());
    let (rect, caption) = view_and_caption(response.rect);
    let painter = full_painter.with_clip_rect(rect);
    if !app.framed {
        app.camera
            .frame(&app.sculptor, [rect.width(), rect.height()]);
        app.framed = true;
    }
    if response.dragged() {
        let d = response.drag_delta();
        app.camera.orbit([d.x, d.y]);
    }
    if response.hovered() {
        let scroll = ui.input(|i| i.smooth_scroll_delta.y);
        if scroll != 0.0 {
            // Towards the cursor: what is under it stays under it.
            let at = response
                .hover_pos()
                .map_or([0.0; 2], |p| [p.x - rect.center().x, p.y - rect.center().y]);
            app.camera.zoom_at(at, (scroll * 0.002).exp());
        }
    }
    let centre = rect.center();
    if response.clicked() {
        if let Some(p) = response
            .interact_pointer_pos()
            .filter(|p| rect.contains(*p))
        {
            if let Some(hit) = app.click([p.x - centre.x, p.y - centre.y]) {
                let params = app.params.clone();
                for (param, v) in params.strike.hit().into_iter().zip(hit.fractions) {
                    setter.begin_set_parameter(param);
                    setter.set_parameter(param, v);
                    setter.end_set_parameter(param);
                }
            }
        }
    }
    painter.rect_filled(rect, 0.0, Color32::from_gray(28));
    let base = material_colour(app.params.material.preset.value());
    let mut mesh = egui::Mesh::default();
    let faces = view3d::visible_faces(&app.sculptor, &app.camera);
    for f in &faces {
        let s = view3d::shade(&app.camera, f.normal);
        let parity = ((f.cell[0] + f.cell[1] + f.cell[2]) & 1) as f32 * 0.06;
        let k = (s - parity).clamp(0.0, 1.0);
        let c = Color32::from_rgb(
            (base[0] as f32 * k) as u8,
            (base[1] as f32 * k) as u8,
            (base[2] as f32 * k) as u8,
        );
        let i0 = mesh.vertices.len() as u32;
        for corner in f.corners {
            let (p, _) = app.camera.project(corner);
            mesh.colored_vertex(Pos2::new(centre.x + p[0], centre.y + p[1]), c);
        }
        mesh.add_triangle(i0, i0 + 1, i0 + 2);
        mesh.add_triangle(i0, i0 + 2, i0 + 3);
    }
    painter.add(egui::Shape::mesh(mesh));
    // The hit marker where the strike lands on the surface, with the force coming in along
    // its direction; faint where the object covers it.
    if let Some(h) = app.hit_marker() {
        let screen = |v: view3d::V3| {
            let (p, _) = app.camera.project(v);
            Pos2::new(centre.x + p[0], centre.y + p[1])
        };
        let at = screen(h.point);
        let tail = screen([0, 1, 2].map(|a| h.point[a] - 3.0 * h.direction[a]));
        if view3d::unoccluded(&app.sculptor, &app.camera, h.point) {
            let red = Color32::from_rgb(255, 60, 60);
            painter.line_segment([tail, at], Stroke::new(2.0, red));
            painter.circle_stroke(at, 7.0, Stroke::new(2.0, red));
            painter.circle_filled(at, 2.5, red);
        } else {
            let faint = Color32::from_rgba_unmultiplied(255, 60, 60, 90);
            painter.line_segment([tail, at], Stroke::new(1.0, faint));
            painter.circle_stroke(at, 7.0, Stroke::new(1.0, faint));
        }
    }
    let dims = app.sculptor.bounds().map(|(_, d)| d).unwrap_or([0; 3]);
    full_painter.rect_filled(caption, 0.0, Color32::from_gray(22));
    full_painter.text(
        caption.left_center() + Vec2::new(6.0, 0.0),
        egui::Align2::LEFT_CENTER,
        format!(
            "{} x {} x {} voxels ({} solid) · drag: rotate · wheel: zoom to the cursor · click: {}",
            dims[0],
            dims[1],
            dims[2],
            app.sculptor.count(),
            match app.tool {
                Tool::Add => "add",
                Tool::Remove => "remove",
                Tool::Hit => "set the hit point and strike",
            }
        ),
        egui::FontId::proportional(11.0),
        Color32::from_gray(170),
    );
}

/// The view's base colour for a material.
fn material_colour(m: MaterialChoice) -> [u8; 3] {
    use MaterialChoice::*;
    match m {
        Glass => [150, 200, 225],
        Wood | SlWood => [190, 140, 90],
        Ceramic | SlPorcelain => [235, 230, 215],
        Brass => [215, 180, 90],
        Plastic | SlPlastic1 | SlPlastic2 | Polycarbonate => [110, 170, 120],
        Steel | Iron | Tin => [180, 185, 195],
        Aluminium | SlAluminum => [200, 205, 210],
        Custom => [200, 160, 200],
    }
}

pub(super) fn controls(app: &mut EditorApp, ui: &mut egui::Ui, setter: &ParamSetter) {
    let params = app.params.clone();
    let p = &params.material;
    ui.heading("Material");
    enum_combo(ui, "Material", &p.preset, setter);
    if p.preset.value() == MaterialChoice::Custom {
        slider(ui, "E", &p.youngs_gpa, setter);
        slider(ui, "Density", &p.density, setter);
        slider(ui, "Poisson", &p.poisson, setter);
    }
    slider(ui, "Size", &p.size_m, setter);
    ui.separator();
    let p = &params.damping;
    ui.heading("Damping");
    enum_combo(ui, "Law", &p.law, setter);
    match p.law.value() {
        crate::params::DampingChoice::Material => {}
        crate::params::DampingChoice::Rayleigh => {
            slider(ui, "Alpha1", &p.alpha1, setter);
            slider(ui, "Alpha2", &p.alpha2_us, setter);
        }
        crate::params::DampingChoice::PowerLaw => {
            slider(ui, "Mu1", &p.mu1, setter);
            slider(ui, "Mu2", &p.mu2, setter);
        }
    }
    ui.separator();
    let p = &params.strike;
    ui.heading("Strike");
    slider(ui, "Hardness", &p.hardness_ms, setter);
    slider(ui, "Vel > Hard", &p.velocity_hardness, setter);
    slider(ui, "Hit X", &p.hit_x, setter);
    slider(ui, "Hit Y", &p.hit_y, setter);
    slider(ui, "Hit Z", &p.hit_z, setter);
    slider(ui, "Normal", &p.force_normal, setter);
    if !p.force_normal.value() {
        slider(ui, "Azimuth", &p.force_azimuth, setter);
        slider(ui, "Elevation", &p.force_elevation, setter);
    }
    if ui.button("Strike").clicked() {
        app.link.audition.fetch_add(1, Ordering::Relaxed);
    }
    ui.separator();
    let p = &params.play;
    ui.heading("Play");
    enum_combo(ui, "Keys", &p.mapping, setter);
    slider(ui, "Note-off mute", &p.note_off_mute, setter);
    slider(ui, "Mute decay", &p.mute_decay, setter);
    slider(ui, "Gain", &p.gain_db, setter);
    slider(ui, "Mode budget", &p.mode_budget, setter);
    ui.separator();
    let p = &params.expression;
    ui.heading("Expression");
    enum_combo(ui, "MIDI", &p.midi, setter);
    if p.midi.value() == crate::params::MidiExpression::Mpe {
        slider(ui, "Bend range", &p.bend_range, setter);
    }
    slider(ui, "Pressure", &p.pressure_decay, setter);
    ui.separator();
    let p = &params.solver;
    ui.heading("Solver");
    enum_combo(ui, "Solver", &p.kind, setter);
    enum_combo(ui, "Element", &p.element, setter);
    slider(ui, "Modes", &p.modes, setter);
}
