//! The plugin window (egui through nice-plug-egui): a 3D view of the voxel object to sculpt
//! and to click hit points on, material and damping controls, the struck spectrum, the
//! solver's status, presets and `.vox` files.
//!
//! Where it sits: on the host's GUI thread. Edits go to the persisted object
//! (`ModalForgeParams::object`), which the engine's worker polls and solves; knob changes go
//! through the host ([`ParamSetter`]) so they are automatable and undoable there; an audition
//! strike (a click with the Hit tool) reaches the audio thread through an atomic counter in
//! [`EditorLink`]. Nothing here blocks the audio thread: the worker and the editor share only
//! the object's lock and the status mutex, neither of which the audio thread touches.
//!
//! The window's logic lives in [`EditorApp`] methods that take no egui context
//! ([`EditorApp::click`], [`EditorApp::undo`], ...) so tests drive it without a window.

pub mod sculptor;
pub mod spectrum_view;
pub mod view3d;

use crate::materials::{MaterialChoice, MaterialTable};
use crate::params::ModalForgeParams;
use crate::presets::Preset;
use crate::sculpt::Sculpt;
use egui::{Color32, Pos2, Sense, Stroke, Vec2};
use modalforge::engine::spectrum::{spectrum, SpectrumLine};
use modalforge::engine::{EngineControl, SolveState, Voicing};
use nice_plug::context::gui::GuiContext;
use nice_plug::prelude::*;
use nice_plug_egui::widgets::ParamSlider;
use nice_plug_egui::{EguiEditorState, NiceEguiApp};
use sculptor::Sculptor;
use std::path::Path;
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use view3d::{Camera, Pick};

/// What the plugin and its window share.
#[derive(Default)]
pub struct EditorLink {
    /// The running engine's control side (set by `activate`).
    pub control: Mutex<Option<Arc<EngineControl>>>,
    /// Audition strikes the editor asked for; `process` takes them (a swap, no lock).
    pub audition: AtomicU32,
    /// Sample rate, Hz, as `f64` bits (0 before `activate`).
    pub sample_rate_bits: AtomicU64,
}

impl EditorLink {
    fn control(&self) -> Option<Arc<EngineControl>> {
        self.control
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }
}

/// Default window size, logical pixels.
pub const WINDOW_SIZE: (f64, f64) = (1000.0, 680.0);

/// The sculpting tools.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tool {
    /// Click a face: add voxels in front of it.
    Add,
    /// Click a voxel: remove it.
    Remove,
    /// Click the surface: move the hit point there and strike.
    Hit,
}

/// Shapes offered by "New" (the CLI's built-in shapes).
pub const PRIMITIVES: &[&str] = &[
    "bowl", "bar", "plate", "box", "sphere", "cylinder", "tube", "cup", "bell",
];

/// The editor's state and logic.
pub struct EditorApp {
    params: Arc<ModalForgeParams>,
    table: Arc<MaterialTable>,
    link: Arc<EditorLink>,
    /// The sculpting model (loaded from the persisted object).
    pub sculptor: Sculptor,
    /// The object last written to or read from the parameters.
    synced: Sculpt,
    /// The view's camera.
    pub camera: Camera,
    framed: bool,
    /// The current tool.
    pub tool: Tool,
    primitive: usize,
    primitive_side: usize,
    hollow_wall: usize,
    resample_side: usize,
    path: String,
    message: Option<(String, bool)>,
    presets: Vec<Preset>,
    spectrum_key: Option<(u64, [u64; 8])>,
    lines: Vec<SpectrumLine>,
}

/// A hit the editor set: the parameter values and whether a strike was queued.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HitSet {
    /// Hit point as fractions of the object's extent (the Hit X/Y/Z parameters).
    pub fractions: [f32; 3],
}

impl EditorApp {
    /// A new editor on the plugin's parameters.
    pub fn new(
        params: Arc<ModalForgeParams>,
        table: Arc<MaterialTable>,
        link: Arc<EditorLink>,
    ) -> Self {
        let synced = params
            .object
            .read()
            .unwrap_or_else(|e| e.into_inner())
            .clone();
        let sculptor = Sculptor::new(&synced)
            .unwrap_or_else(|_| Sculptor::new(&Sculpt::default()).expect("default is valid"));
        Self {
            params,
            table,
            link,
            sculptor,
            synced,
            camera: Camera::default(),
            framed: false,
            tool: Tool::Add,
            primitive: 0,
            primitive_side: 16,
            hollow_wall: 2,
            resample_side: 16,
            path: default_dir(),
            message: None,
            presets: Preset::builtin(),
            spectrum_key: None,
            lines: Vec::new(),
        }
    }

    /// Reloads the object if the host replaced it (a state restore, a preset from the host).
    fn follow_host(&mut self) {
        let now = self
            .params
            .object
            .read()
            .unwrap_or_else(|e| e.into_inner())
            .clone();
        if now != self.synced {
            if let Ok(s) = Sculptor::new(&now) {
                self.sculptor = s;
                self.framed = false;
            }
            self.synced = now;
        }
    }

    /// Writes the sculpted object to the parameters (the worker notices and re-solves).
    fn publish(&mut self) {
        match self.sculptor.sculpt() {
            Ok(s) => {
                *self
                    .params
                    .object
                    .write()
                    .unwrap_or_else(|e| e.into_inner()) = s.clone();
                self.synced = s;
            }
            Err(e) => self.message = Some((e, true)),
        }
    }

    /// A click on the view at `offset` pixels from its centre (y down) with the current tool.
    /// Sculpting tools edit and publish the object; the Hit tool returns the new hit point,
    /// which the caller sets as parameters, and queues an audition strike.
    pub fn click(&mut self, offset: [f32; 2]) -> Option<HitSet> {
        let pick = view3d::pick(&self.sculptor, &self.camera, offset)?;
        match self.tool {
            Tool::Add => {
                if self.sculptor.paint(pick.outside(), true) {
                    self.publish();
                }
                None
            }
            Tool::Remove => {
                if self.sculptor.paint(pick.cell, false) {
                    self.publish();
                } else {
                    self.message = Some(("cannot remove the last voxel".into(), true));
                }
                None
            }
            Tool::Hit => {
                let set = self.hit_fractions(&pick)?;
                self.link.audition.fetch_add(1, Ordering::Relaxed);
                Some(set)
            }
        }
    }

    /// The hit point of a pick as fractions of the solved object's box.
    pub fn hit_fractions(&self, pick: &Pick) -> Option<HitSet> {
        let (lo, dims) = self.sculptor.bounds()?;
        Some(HitSet {
            fractions: [0, 1, 2]
                .map(|a| ((pick.point[a] - lo[a] as f32) / dims[a] as f32).clamp(0.0, 1.0)),
        })
    }

    /// Where the current hit parameters put the hit, world units.
    pub fn hit_point(&self) -> Option<view3d::V3> {
        let (lo, dims) = self.sculptor.bounds()?;
        let f = [
            self.params.hit_x.value(),
            self.params.hit_y.value(),
            self.params.hit_z.value(),
        ];
        Some([0, 1, 2].map(|a| lo[a] as f32 + f[a] * dims[a] as f32))
    }

    /// Undo; publishes the result.
    pub fn undo(&mut self) -> bool {
        let done = self.sculptor.undo();
        if done {
            self.publish();
        }
        done
    }

    /// Redo; publishes the result.
    pub fn redo(&mut self) -> bool {
        let done = self.sculptor.redo();
        if done {
            self.publish();
        }
        done
    }

    /// Runs a sculpting operation that may fail, then publishes or reports.
    fn edit(&mut self, op: impl FnOnce(&mut Sculptor) -> Result<(), String>) {
        match op(&mut self.sculptor) {
            Ok(()) => {
                self.publish();
                self.framed = false;
                self.message = None;
            }
            Err(e) => self.message = Some((e, true)),
        }
    }

    /// The spectrum lines for the newest object and the knobs' voicing (recomputed when
    /// either changes).
    fn refresh_spectrum(&mut self) {
        let Some(control) = self.link.control() else {
            return;
        };
        let Some(latest) = control.latest_object() else {
            return;
        };
        let voicing = self.params.voicing(&self.table, 1.0, 1.0);
        let key = (latest.generation, voicing_key(&voicing));
        if self.spectrum_key == Some(key) {
            return;
        }
        self.spectrum_key = Some(key);
        let fs = f64::from_bits(self.link.sample_rate_bits.load(Ordering::Relaxed));
        let fs = if fs > 0.0 { fs } else { 48_000.0 };
        self.lines = spectrum(&latest.basis, &voicing, fs).unwrap_or_default();
    }

    /// The status line: the solver's state and time, the engine's load.
    pub fn status_line(&self) -> (String, bool) {
        let Some(control) = self.link.control() else {
            return (
                "engine not running (the host has not activated the plugin)".into(),
                false,
            );
        };
        let st = control.status();
        let stats = control.stats();
        let engine = format!(
            "{} modes ringing, {} voices, load {:.1}%",
            stats.active_modes.load(Ordering::Relaxed),
            stats.active_voices.load(Ordering::Relaxed),
            100.0 * stats.load()
        );
        match (&st.state, &st.last) {
            (SolveState::Solving { solver, since }, _) => (
                format!(
                    "solving... {:.1} s ({solver}) · {engine}",
                    since.elapsed().as_secs_f64()
                ),
                false,
            ),
            (SolveState::Idle, Some(last)) if last.error.is_some() => (
                format!(
                    "solve failed: {} (the previous object keeps playing)",
                    last.error.as_deref().unwrap_or("")
                ),
                true,
            ),
            (SolveState::Idle, Some(last)) => (
                format!(
                    "{} modes solved in {:.2} s ({}) · {engine}",
                    last.modes,
                    last.ms / 1e3,
                    last.solver
                ),
                false,
            ),
            (SolveState::Idle, None) => (format!("waiting for the first solve · {engine}"), false),
        }
    }

    fn load_vox(&mut self) {
        let path = Path::new(self.path.trim()).to_path_buf();
        match modalforge::shape::vox::read_vox(&path, 1.0) {
            Ok(grid) => self.edit(|s| s.replace(&grid)),
            Err(e) => self.message = Some((e.to_string(), true)),
        }
    }

    fn save_vox(&mut self) {
        let path = Path::new(self.path.trim()).to_path_buf();
        let result = self
            .sculptor
            .sculpt()
            .and_then(|s| s.to_grid())
            .and_then(|g| modalforge::shape::vox::write_vox(&g, &path).map_err(|e| e.to_string()));
        self.message = Some(match result {
            Ok(()) => (format!("saved {}", path.display()), false),
            Err(e) => (e, true),
        });
    }

    /// The preset the window's current settings describe.
    pub fn current_preset(&self, name: &str) -> Result<Preset, String> {
        let sculpt = self.sculptor.sculpt()?;
        let mut p = Preset::with_object(name, &sculpt);
        let m = self.params.material.value();
        p.material = MaterialChoice::ids()
            .and_then(|ids| ids.get(m.to_index()))
            .unwrap_or(&"glass")
            .to_string();
        if m == MaterialChoice::Custom {
            p.youngs_gpa = Some(self.params.youngs_gpa.value());
            p.density_kg_m3 = Some(self.params.density.value());
            p.poisson = Some(self.params.poisson.value());
        }
        p.size_m = self.params.size_m.value();
        p.hardness_ms = self.params.hardness_ms.value();
        p.hit = [
            self.params.hit_x.value(),
            self.params.hit_y.value(),
            self.params.hit_z.value(),
        ];
        Ok(p)
    }

    fn save_preset(&mut self) {
        let path = Path::new(self.path.trim()).to_path_buf();
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "preset".into());
        let result = self
            .current_preset(&name)
            .and_then(|p| std::fs::write(&path, p.to_toml()).map_err(|e| e.to_string()));
        self.message = Some(match result {
            Ok(()) => (format!("saved {}", path.display()), false),
            Err(e) => (format!("cannot save {}: {e}", path.display()), true),
        });
    }

    fn read_preset(&self) -> Result<Preset, String> {
        let path = Path::new(self.path.trim());
        let text = std::fs::read_to_string(path)
            .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
        Preset::from_toml(&text, &path.display().to_string())
    }

    /// Applies a preset: its object replaces the sculpture (one undo step) and its settings
    /// go to the host.
    fn apply_preset(&mut self, preset: &Preset, setter: &ParamSetter) {
        let sculpt = match preset.sculpt().and_then(|s| s.to_grid()) {
            Ok(g) => g,
            Err(e) => {
                self.message = Some((e, true));
                return;
            }
        };
        self.edit(|s| s.replace(&sculpt));
        let p = &self.params;
        let set_f = |param: &FloatParam, v: f32| {
            setter.begin_set_parameter(param);
            setter.set_parameter(param, v);
            setter.end_set_parameter(param);
        };
        if let Some(m) = preset.material_choice() {
            setter.begin_set_parameter(&p.material);
            setter.set_parameter(&p.material, m);
            setter.end_set_parameter(&p.material);
        }
        if let (Some(e), Some(rho), Some(nu)) =
            (preset.youngs_gpa, preset.density_kg_m3, preset.poisson)
        {
            set_f(&p.youngs_gpa, e);
            set_f(&p.density, rho);
            set_f(&p.poisson, nu);
        }
        setter.begin_set_parameter(&p.damping);
        setter.set_parameter(&p.damping, crate::params::DampingChoice::Material);
        setter.end_set_parameter(&p.damping);
        set_f(&p.size_m, preset.size_m);
        set_f(&p.hardness_ms, preset.hardness_ms);
        set_f(&p.hit_x, preset.hit[0]);
        set_f(&p.hit_y, preset.hit[1]);
        set_f(&p.hit_z, preset.hit[2]);
        self.message = Some((format!("{}: {}", preset.name, preset.description), false));
    }
}

/// Bits of the voicing fields the spectrum depends on.
fn voicing_key(v: &Voicing) -> [u64; 8] {
    let d = match v.damping {
        modalforge::engine::DampingParams::Rayleigh { alpha1, alpha2 } => alpha1 + 7.0 * alpha2,
        modalforge::engine::DampingParams::PowerLaw { mu1, mu2 } => mu1 + 11.0 * mu2,
        modalforge::engine::DampingParams::Caughey { eta, .. } => eta.iter().sum(),
    };
    let dir = v
        .hit
        .direction
        .map_or(0.0, |d| d[0] + 3.0 * d[1] + 5.0 * d[2]);
    [
        v.youngs_modulus_pa,
        v.density_kg_m3,
        v.size_m,
        d,
        v.hit.position[0] + 3.0 * v.hit.position[1] + 9.0 * v.hit.position[2],
        dir,
        v.hardness_s,
        0.0,
    ]
    .map(f64::to_bits)
}

/// Where file paths start: `~/ModalForge/object.vox`.
fn default_dir() -> String {
    let home = std::env::var("HOME").unwrap_or_else(|_| ".".into());
    format!("{home}/ModalForge/object.vox")
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

/// The editor as nice-plug-egui runs it (the GUI context gives the parameter setter).
pub struct EditorWindow {
    app: EditorApp,
    gui: Option<GuiContext>,
}

impl EditorWindow {
    /// Wraps the editor logic.
    pub fn new(app: EditorApp) -> Self {
        Self { app, gui: None }
    }
}

/// The editor for [`crate::ModalForge::editor`].
pub fn create(
    params: Arc<ModalForgeParams>,
    table: Arc<MaterialTable>,
    link: Arc<EditorLink>,
    state: Arc<EguiEditorState>,
) -> Option<nice_plug_egui::EguiEditor<EditorWindow>> {
    let app = EditorApp::new(params, table, link);
    nice_plug_egui::create_egui_editor(
        state,
        nice_plug_egui::RepaintNotifier::new(),
        nice_plug_egui::EguiNiceSettings::new().with_tile("ModalForge"),
        EditorWindow::new(app),
    )
}

impl NiceEguiApp for EditorWindow {
    fn build(
        &mut self,
        _egui_ctx: egui::Context,
        nice_gui_ctx: GuiContext,
        _frame: &mut nice_plug_egui::Frame,
    ) -> Result<(), nice_plug_egui::baseview::HandlerError> {
        self.gui = Some(nice_gui_ctx);
        Ok(())
    }

    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut nice_plug_egui::Frame) {
        let Some(gui) = self.gui.clone() else {
            return;
        };
        let setter = gui.param_setter();
        let app = &mut self.app;
        app.follow_host();
        app.refresh_spectrum();
        // Keep the status line's timer and the spectrum live.
        ui.ctx()
            .request_repaint_after(std::time::Duration::from_millis(100));

        egui::Panel::top("files").show(ui, |ui| top_bar(app, ui, &setter));
        egui::Panel::bottom("spectrum")
            .exact_size(170.0)
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
                spectrum_view::show(ui, &app.lines, 140.0);
            });
        egui::Panel::right("controls")
            .exact_size(300.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| controls(app, ui, &setter));
            });
        egui::CentralPanel::default_margins().show(ui, |ui| {
            sculpt_bar(app, ui);
            view(app, ui, &setter);
        });
    }

    fn editor_closed(&mut self) {
        self.gui = None;
    }
}

fn top_bar(app: &mut EditorApp, ui: &mut egui::Ui, setter: &ParamSetter) {
    ui.horizontal(|ui| {
        ui.strong("ModalForge");
        ui.separator();
        let mut chosen = None;
        egui::ComboBox::from_id_salt("preset")
            .selected_text("Presets")
            .show_ui(ui, |ui| {
                for (i, p) in app.presets.iter().enumerate() {
                    if ui
                        .selectable_label(false, &p.name)
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
        if ui.button("Load .vox").clicked() {
            app.load_vox();
        }
        if ui.button("Save .vox").clicked() {
            app.save_vox();
        }
        if ui.button("Load preset").clicked() {
            match app.read_preset() {
                Ok(p) => app.apply_preset(&p, setter),
                Err(e) => app.message = Some((e, true)),
            }
        }
        if ui.button("Save preset").clicked() {
            app.save_preset();
        }
    });
    if let Some((m, error)) = &app.message {
        let colour = if *error {
            Color32::from_rgb(240, 110, 90)
        } else {
            Color32::from_gray(180)
        };
        ui.colored_label(colour, m);
    }
}

fn sculpt_bar(app: &mut EditorApp, ui: &mut egui::Ui) {
    ui.horizontal(|ui| {
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
        let (z, shift) = ui.input(|i| {
            (
                i.modifiers.command && i.key_pressed(egui::Key::Z),
                i.modifiers.shift,
            )
        });
        if undo.clicked() || (z && !shift) {
            app.undo();
        }
        if redo.clicked() || (z && shift) {
            app.redo();
        }
    });
    ui.horizontal_wrapped(|ui| {
        egui::ComboBox::from_id_salt("primitive")
            .selected_text(PRIMITIVES[app.primitive])
            .show_ui(ui, |ui| {
                for (i, name) in PRIMITIVES.iter().enumerate() {
                    ui.selectable_value(&mut app.primitive, i, *name);
                }
            });
        ui.add(egui::Slider::new(&mut app.primitive_side, 4..=32).suffix(" vox"))
            .on_hover_text("longest side of the new shape, voxels");
        if ui.button("New").clicked() {
            let (spec, side) = (PRIMITIVES[app.primitive], app.primitive_side);
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
    });
}

fn view(app: &mut EditorApp, ui: &mut egui::Ui, setter: &ParamSetter) {
    let size = ui.available_size();
    let (response, painter) = ui.allocate_painter(size, Sense::click_and_drag());
    let rect = response.rect;
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
            app.camera.pixels_per_voxel =
                (app.camera.pixels_per_voxel * (scroll * 0.002).exp()).clamp(1.0, 200.0);
        }
    }
    let centre = rect.center();
    if response.clicked() {
        if let Some(p) = response.interact_pointer_pos() {
            if let Some(hit) = app.click([p.x - centre.x, p.y - centre.y]) {
                let params = app.params.clone();
                for (param, v) in [&params.hit_x, &params.hit_y, &params.hit_z]
                    .into_iter()
                    .zip(hit.fractions)
                {
                    setter.begin_set_parameter(param);
                    setter.set_parameter(param, v);
                    setter.end_set_parameter(param);
                }
            }
        }
    }
    painter.rect_filled(rect, 0.0, Color32::from_gray(28));
    let base = material_colour(app.params.material.value());
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
    if let Some(h) = app.hit_point() {
        let (p, _) = app.camera.project(h);
        let at = Pos2::new(centre.x + p[0], centre.y + p[1]);
        painter.circle_stroke(at, 7.0, Stroke::new(2.0, Color32::from_rgb(255, 60, 60)));
        painter.circle_filled(at, 2.5, Color32::from_rgb(255, 60, 60));
    }
    let dims = app.sculptor.bounds().map(|(_, d)| d).unwrap_or([0; 3]);
    painter.text(
        rect.left_bottom() + Vec2::new(6.0, -6.0),
        egui::Align2::LEFT_BOTTOM,
        format!(
            "{} x {} x {} voxels ({} solid) · drag: rotate · wheel: zoom · click: {}",
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

fn controls(app: &mut EditorApp, ui: &mut egui::Ui, setter: &ParamSetter) {
    let p = app.params.clone();
    ui.heading("Material");
    enum_combo(ui, "Material", &p.material, setter);
    if p.material.value() == MaterialChoice::Custom {
        slider(ui, "E", &p.youngs_gpa, setter);
        slider(ui, "Density", &p.density, setter);
        slider(ui, "Poisson", &p.poisson, setter);
    }
    slider(ui, "Size", &p.size_m, setter);
    ui.separator();
    ui.heading("Damping");
    enum_combo(ui, "Law", &p.damping, setter);
    match p.damping.value() {
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
    ui.heading("Play");
    enum_combo(ui, "Keys", &p.mapping, setter);
    slider(ui, "Note-off mute", &p.note_off_mute, setter);
    slider(ui, "Mute decay", &p.mute_decay, setter);
    slider(ui, "Gain", &p.gain_db, setter);
    slider(ui, "Mode budget", &p.mode_budget, setter);
    ui.separator();
    ui.heading("Solver");
    enum_combo(ui, "Solver", &p.solver, setter);
    enum_combo(ui, "Element", &p.element, setter);
    slider(ui, "Modes", &p.modes, setter);
}

#[cfg(test)]
mod tests;
