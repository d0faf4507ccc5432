//! The window's file bar (presets, the path field, Import, the file actions, the scale menu)
//! and its resize corner.

use super::*;

/// The file bar: presets, the path field, Import and the file actions. In a compact window
/// the file actions go into a *File* menu so the bar keeps one row.
pub(in crate::editor) fn top_bar(
    app: &mut EditorApp,
    ui: &mut egui::Ui,
    setter: &ParamSetter,
    compact: bool,
) {
    ui.horizontal_wrapped(|ui| {
        if !compact {
            ui.strong("ModalForge");
            ui.separator();
        }
        let mut chosen = None;
        let current = app.current_preset.as_ref().map(|(name, _)| name.clone());
        egui::ComboBox::from_id_salt("preset")
            .selected_text(app.presets_caption())
            .width(if compact { 90.0 } else { 120.0 })
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
        if compact {
            let menu = ui.menu_button("File", |ui| {
                file_actions(app, ui, setter);
                scale_menu(app, ui);
            });
            app.mark("file_menu", menu.response.rect);
        } else {
            ui.label("File");
        }
        let path = ui.add(
            egui::TextEdit::singleline(&mut app.path).desired_width(if compact {
                120.0
            } else {
                260.0
            }),
        );
        app.mark("path", path.rect);
        let import = ui.button("Import");
        app.mark("import", import.rect);
        if import
            .on_hover_text(
                "Load the model in the field: a MagicaVoxel .vox, or an OBJ or STL mesh \
                 (voxelised to the import size); a .vox larger than the 32^3 box is previewed \
                 resampled to the import size (or cropped) until you keep it. Ctrl+Z \
                 restores the previous object",
            )
            .clicked()
        {
            app.import();
        }
        let import_side = ui
            .add(
                egui::DragValue::new(&mut app.import_side)
                    .range(2..=32)
                    .suffix(" vox"),
            )
            .on_hover_text(
                "Import size: voxels along the longest side of an imported mesh, or of a .vox \
                 resampled to fit the box",
            );
        // Re-fit a previewed import once the value settles, not at every step of a drag.
        let settled =
            (import_side.changed() && !import_side.dragged()) || import_side.drag_stopped();
        if settled && app.pending_import() == Some(super::super::ImportFit::Resample) {
            app.show_import();
        }
        if !compact {
            file_actions(app, ui, setter);
            scale_menu(app, ui);
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

/// The window's scale, 75-200 % ([`super::super::SCALES`]), saved with the project.
fn scale_menu(app: &mut EditorApp, ui: &mut egui::Ui) {
    let current = app.scale();
    let percent = |s: f32| format!("{:.0} %", s * 100.0);
    let mut chosen = None;
    let combo = egui::ComboBox::from_id_salt("scale")
        .selected_text(percent(current))
        .width(64.0)
        .show_ui(ui, |ui| {
            for (s, name) in super::super::SCALES.into_iter().zip(SCALE_NAMES) {
                let item = ui.selectable_label((s - current).abs() < 1e-3, percent(s));
                app.mark(name, item.rect);
                if item.clicked() {
                    chosen = Some(s);
                }
            }
        });
    app.mark("scale", combo.response.rect);
    combo
        .response
        .on_hover_text("Scale of the whole window (Ctrl+Plus / Ctrl+Minus)");
    if let Some(s) = chosen {
        app.set_scale(ui.ctx(), s);
    }
}

/// The scale menu's entries as the state dump names them.
const SCALE_NAMES: [&str; 6] = [
    "scale_75",
    "scale_100",
    "scale_125",
    "scale_150",
    "scale_175",
    "scale_200",
];

/// A handle in the window's bottom-right corner that resizes it, for hosts that draw no
/// frame of their own around a plugin window (the host or the window manager resizes it
/// otherwise; either way the layout follows, down to [`MIN_WINDOW_PX`]).
pub(in crate::editor) fn resize_corner(ui: &mut egui::Ui) {
    let window = ui.ctx().content_rect();
    let corner = egui::Vec2::splat(ui.visuals().resize_corner_size);
    let rect = egui::Rect::from_min_size(window.max - corner, corner);
    let id = egui::Id::unique("modalforge-resize-corner");
    let response = ui.interact(rect, id, egui::Sense::drag());
    if response.dragged() {
        if let Some(delta) = response.total_drag_delta() {
            let start = ui.data_mut(|d| *d.get_temp_mut_or_insert_with(id, || window.size()));
            let size = (start + delta).max(MIN_WINDOW_PX.into());
            ui.send_viewport_cmd(egui::ViewportCommand::InnerSize(size));
        }
    } else if response.drag_stopped() {
        ui.data_mut(|d| d.remove::<egui::Vec2>(id));
    }
    nice_plug_egui::resizable_window::paint_resize_corner(ui, &response);
}

/// Save .vox, the presets, the recordings and the tuning: inline in a wide top bar, or in
/// the *File* menu of a compact one.
fn file_actions(app: &mut EditorApp, ui: &mut egui::Ui, setter: &ParamSetter) {
    if ui.button("Save .vox").clicked() {
        app.save_vox();
    }
    if ui.button("Load preset").clicked() {
        match app.read_preset() {
            Ok(p) => app.apply_preset(&p, setter),
            Err(e) => app.message = Some((e.to_string(), true)),
        }
    }
    let save_preset = ui.button("Save preset");
    app.mark("save_preset", save_preset.rect);
    if save_preset.clicked() {
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
}
