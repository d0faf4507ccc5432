//! The editor window's panels: the file bar, the sculpting bar, the 3D view, the parameter
//! controls. Each takes the [`EditorApp`] and draws with egui; the logic they call lives on
//! [`EditorApp`] (tested without a window).

mod file_bar;
mod sculpt_bar;

use super::{view3d, EditorApp, Tool};
use crate::materials::MaterialChoice;
use egui::{Color32, Pos2, Rect, Sense, Stroke, Vec2};
pub(super) use file_bar::{resize_corner, top_bar};
use nice_plug::prelude::*;
use nice_plug_egui::widgets::ParamSlider;
pub(super) use sculpt_bar::{sculpt_bar, sculpt_controls};
use std::sync::atomic::Ordering;

/// The whole window: the file bar on top, status and spectrum at the bottom, the parameters
/// on the right, the sculpting bar and the 3D view in the middle, sized for the window.
pub(super) fn window(app: &mut EditorApp, ui: &mut egui::Ui, setter: &ParamSetter) {
    let sizes = PanelSizes::for_window(ui.available_size().into());
    egui::Panel::top("files").show(ui, |ui| top_bar(app, ui, setter, sizes.compact));
    egui::Panel::bottom("spectrum")
        .exact_size(sizes.spectrum_px)
        .show(ui, |ui| {
            let (status, error) = app.status_line();
            ui.colored_label(
                if error {
                    Color32::from_rgb(240, 110, 90)
                } else {
                    Color32::from_gray(200)
                },
                status,
            );
            super::spectrum_view::show(ui, &app.lines, sizes.spectrum_px - 30.0);
        });
    egui::Panel::right("controls")
        .exact_size(sizes.controls_px)
        .show(ui, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| controls(app, ui, setter, sizes.compact));
        });
    egui::CentralPanel::default_margins().show(ui, |ui| {
        sculpt_bar(app, ui, sizes.compact);
        view(app, ui, setter);
    });
}

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
        // Truncated to its width: a long choice ("Curved (hex27x2)") must not widen a narrow
        // side panel into the 3D view.
        egui::ComboBox::from_id_salt(label)
            .selected_text(T::variants()[current.to_index()])
            .width(90.0)
            .truncate()
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

/// Width of a parameter slider's value box beside the bar, pixels (nice-plug-egui's).
const VALUE_BOX_PX: f32 = 75.0;

/// A labelled parameter slider: label, bar and value on one row, or in a narrow panel the
/// label above a bar that fits (content wider than a side panel would push the panel's edge
/// into the 3D view).
fn slider<P: Param>(ui: &mut egui::Ui, label: &str, param: &P, setter: &ParamSetter) {
    const LABEL_PX: f32 = 84.0;
    const BAR_PX: f32 = 120.0;
    if ui.available_width() >= LABEL_PX + BAR_PX + VALUE_BOX_PX {
        ui.horizontal(|ui| {
            ui.add_sized([LABEL_PX, 18.0], egui::Label::new(label));
            ui.add(ParamSlider::for_param(param, setter).with_width(BAR_PX));
        });
    } else {
        ui.label(label);
        let bar = (ui.available_width() - VALUE_BOX_PX).clamp(40.0, BAR_PX);
        ui.add(ParamSlider::for_param(param, setter).with_width(bar));
    }
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

/// The tool a key pressed this frame picks (A: add, R: remove, H: hit), unless a text field
/// has the keyboard; like the undo shortcut, read from the key events themselves.
fn tool_key(ui: &mut egui::Ui) -> Option<Tool> {
    if ui.ctx().egui_wants_keyboard_input() {
        return None;
    }
    use egui::{Key, Modifiers};
    ui.input_mut(|i| {
        [
            (Key::A, Tool::Add),
            (Key::R, Tool::Remove),
            (Key::H, Tool::Hit),
        ]
        .into_iter()
        .find(|(key, _)| i.consume_key(Modifiers::NONE, *key))
        .map(|(_, tool)| tool)
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
    /// A narrow window: the file actions go into a menu and the brush, mirror and shape
    /// operations into the parameters panel, so the bars keep one row each.
    pub compact: bool,
}

/// Windows narrower than this, pixels, get the compact layout.
pub const COMPACT_BELOW_PX: f32 = 760.0;

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
            compact: window[0] < COMPACT_BELOW_PX,
        }
    }
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
    app.mark("view", rect);
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
    import_choice(app, ui, rect);
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

/// While a large import is previewed: Keep, the other fit and Cancel, over the top of the
/// view (the layout below does not move).
fn import_choice(app: &mut EditorApp, ui: &mut egui::Ui, view: Rect) {
    let Some(fit) = app.pending_import() else {
        return;
    };
    let bar = Rect::from_min_size(
        view.min + Vec2::new(6.0, 6.0),
        Vec2::new(view.width(), 24.0),
    );
    ui.scope_builder(egui::UiBuilder::new().max_rect(bar), |ui| {
        ui.horizontal(|ui| {
            let keep = ui.button("Keep");
            app.mark("import_keep", keep.rect);
            let (other, label) = match fit {
                super::ImportFit::Resample => (super::ImportFit::Crop, "Crop instead"),
                super::ImportFit::Crop => (super::ImportFit::Resample, "Resample instead"),
            };
            let switch = ui.button(label);
            app.mark("import_switch", switch.rect);
            let cancel = ui.button("Cancel");
            app.mark("import_cancel", cancel.rect);
            if keep.clicked() {
                app.keep_import();
            } else if switch.clicked() {
                app.set_import_fit(other);
            } else if cancel.clicked() {
                app.cancel_import();
            }
        });
    });
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

/// The parameters panel (it scrolls): in a compact window the sculpting controls first, then
/// the parameters in the host's five groups and expression.
pub(super) fn controls(
    app: &mut EditorApp,
    ui: &mut egui::Ui,
    setter: &ParamSetter,
    compact: bool,
) {
    if compact {
        sculpt_controls(app, ui);
    }
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
    enum_combo(ui, "Brightness", &p.brightness, setter);
    ui.separator();
    let p = &params.resonator;
    ui.heading("Resonator").on_hover_text(
        "Audio on the side-chain input played through the object (as a force at the hit \
         point, at the pitch of the last key struck)",
    );
    enum_combo(ui, "Held notes", &p.held, setter);
    slider(ui, "Input", &p.input_gain_db, setter);
    slider(ui, "Mix", &p.mix, setter);
    slider(ui, "Low cut", &p.low_cut_hz, setter);
    slider(ui, "High cut", &p.high_cut_hz, setter);
    ui.separator();
    let p = &params.solver;
    ui.heading("Solver");
    enum_combo(ui, "Solver", &p.kind, setter);
    enum_combo(ui, "Element", &p.element, setter);
    slider(ui, "Modes", &p.modes, setter);
}
