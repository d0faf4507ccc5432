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

pub mod dump;
mod files;
mod layout;
pub mod matching;
mod recording;
pub mod sculptor;
pub mod spectrum_view;
mod status;
mod tuning;
pub mod view3d;

use crate::error::PluginError;
use crate::materials::MaterialTable;
use crate::params::ModalForgeParams;
use crate::presets::Preset;
use crate::sculpt::Sculpt;
pub use files::ImportFit;
use files::{default_dir, PendingImport};
use modalforge::engine::spectrum::{spectrum, SpectrumLine};
use modalforge::engine::{EngineControl, SolveState, Voicing};
use nice_plug::context::gui::GuiContext;
use nice_plug_egui::{EguiEditorState, NiceEguiApp};
use sculptor::Sculptor;
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

/// `scale` within [`SCALES`]' range (100 % for a value that is not a number).
fn clamp_scale(scale: f32) -> f32 {
    if scale.is_finite() {
        scale.clamp(SCALES[0], SCALES[SCALES.len() - 1])
    } else {
        1.0
    }
}

/// The scales the editor offers (egui's zoom factor: the whole interface grows, and the
/// window with it, so the layout in points is the same at every scale).
pub const SCALES: [f32; 6] = [0.75, 1.0, 1.25, 1.5, 1.75, 2.0];

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

/// Shapes offered by "New": the CLI's built-in shapes, one list for both.
pub use modalforge::shape::spec::BUILT_INS as PRIMITIVES;

/// The shape "New" offers first: the default object's.
const FIRST_PRIMITIVE: &str = "bowl";

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
    /// The object generation and voicing the spectrum lines were computed for.
    spectrum_key: Option<(u64, Voicing)>,
    lines: Vec<SpectrumLine>,
    /// A "Match recording" running in the background.
    matching: Option<matching::Matching>,
    /// The preset last applied, and whether the object was edited since.
    current_preset: Option<(String, bool)>,
    /// Voxels along the longest side of an imported mesh, or of a `.vox` too large for the
    /// working box.
    import_side: usize,
    /// The hit marker, for the object hash, hit parameters and force direction it was found for.
    hit_marker: Option<(HitMarkerKey, Option<HitMarker>)>,
    /// The state dump for scripted window tests (see [`dump`]); `None` unless asked for.
    dump: Option<dump::Dump>,
    /// A `.vox` too large for the box, previewed until kept or cancelled.
    pending_import: Option<PendingImport>,
    /// Repaints the window from other threads (the engine's worker, when a solve starts or
    /// ends); `None` in tests.
    repaint: Option<nice_plug_egui::RepaintNotifier>,
    /// The engine control whose status repaints the window (its address), once watched.
    watched: Option<usize>,
}

/// What the hit marker depends on: the object's hash, the Hit X/Y/Z values and the force
/// direction (`None`: into the face).
type HitMarkerKey = (u64, [u32; 3], Option<[u64; 3]>);

/// Where a strike lands, for the view: on the object's surface, as the solver snaps it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HitMarker {
    /// The struck point, world (box voxel) units.
    pub point: view3d::V3,
    /// The force's unit direction: the struck face's inward normal, or the Force Azimuth and
    /// Elevation when "Force Normal to Surface" is off.
    pub direction: view3d::V3,
}

/// A hit point the editor picked (the caller sets it as the Hit X/Y/Z parameters).
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
            primitive: PRIMITIVES
                .iter()
                .position(|p| p.name == FIRST_PRIMITIVE)
                .unwrap_or(0),
            primitive_side: 16,
            hollow_wall: 2,
            resample_side: 16,
            path: default_dir(),
            message: None,
            presets: Preset::builtin(),
            spectrum_key: None,
            lines: Vec::new(),
            matching: None,
            current_preset: None,
            import_side: crate::sculpt::MAX_SIDE,
            hit_marker: None,
            dump: dump::Dump::from_env(),
            pending_import: None,
            repaint: None,
            watched: None,
        }
    }

    /// Notes where a control a script may click was drawn (for the state dump).
    fn mark(&mut self, name: &'static str, rect: egui::Rect) {
        if let Some(d) = &mut self.dump {
            d.mark(name, rect);
        }
    }

    /// The editor's scale, as saved with the project (clamped to [`SCALES`]' range: a state
    /// edited by hand cannot make the window vanish or explode).
    pub fn scale(&self) -> f32 {
        clamp_scale(
            *self
                .params
                .ui_scale
                .read()
                .unwrap_or_else(|e| e.into_inner()),
        )
    }

    /// Sets the editor's scale (clamped to [`SCALES`]' range): saved with the project, applied
    /// to `ctx` (egui-baseview then resizes the window by the same factor).
    pub fn set_scale(&mut self, ctx: &egui::Context, scale: f32) {
        let scale = clamp_scale(scale);
        *self
            .params
            .ui_scale
            .write()
            .unwrap_or_else(|e| e.into_inner()) = scale;
        ctx.set_zoom_factor(scale);
    }

    /// Keeps the saved scale in step with egui's own zoom keys (Ctrl+Plus, Ctrl+Minus,
    /// Ctrl+0), within [`SCALES`]' range.
    fn follow_zoom_keys(&mut self, ctx: &egui::Context) {
        let zoom = ctx.zoom_factor();
        if (zoom - self.scale()).abs() > 1e-3 {
            self.set_scale(ctx, zoom);
        }
    }

    /// The state a scripted window test checks, as `(key, value)` pairs (see [`dump`]):
    /// the object, the tool, the hit parameters, the message line, the solver, the window's
    /// size in points and the scale.
    pub fn dump_state(&self, window_px: [f32; 2]) -> Vec<(&'static str, String)> {
        let (lo, dims) = self.sculptor.bounds().unwrap_or(([0; 3], [0; 3]));
        let s = &self.params.strike;
        let (message, error) = self
            .message
            .as_ref()
            .map_or(("", false), |(m, e)| (m.as_str(), *e));
        let status = self.link.control().map(|c| c.status());
        let mut state = vec![
            ("box", format!("{},{},{}", dims[0], dims[1], dims[2])),
            ("box_min", format!("{},{},{}", lo[0], lo[1], lo[2])),
            ("voxels", self.sculptor.count().to_string()),
            ("shape_hash", format!("{:016x}", self.sculptor.shape_hash())),
            ("undo", self.sculptor.undo_depth().to_string()),
            ("redo", self.sculptor.redo_depth().to_string()),
            ("tool", format!("{:?}", self.tool).to_lowercase()),
            (
                "hit",
                format!(
                    "{},{},{}",
                    s.hit_x.value(),
                    s.hit_y.value(),
                    s.hit_z.value()
                ),
            ),
            ("path", self.path.clone()),
            ("message", message.to_string()),
            ("message_is_error", error.to_string()),
            ("preset", self.presets_caption()),
            (
                "import_pending",
                self.pending_import()
                    .map_or("no".into(), |f| format!("{f:?}").to_lowercase()),
            ),
            ("status", self.status_line().0),
            ("window", format!("{:.0},{:.0}", window_px[0], window_px[1])),
            ("scale", format!("{:.2}", self.scale())),
        ];
        if let Some(st) = status {
            let solving = matches!(st.state, SolveState::Solving { .. });
            state.push(("solves", st.solves.to_string()));
            state.push(("solving", solving.to_string()));
            if let Some(p) = &st.playing {
                state.push(("playing_modes", p.modes.to_string()));
                state.push(("playing_solver", p.solver.to_string()));
            }
        }
        state
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
                self.pending_import = None;
            }
            self.synced = now;
        }
    }

    /// Writes the sculpted object to the parameters (the worker notices and re-solves); a
    /// recording playing instead of the shape stops.
    fn publish(&mut self) {
        // Whatever the sculptor holds now is the object: a previewed import is kept.
        self.pending_import = None;
        match self.sculptor.sculpt() {
            Ok(s) => {
                let mut recording = self
                    .params
                    .recording
                    .write()
                    .unwrap_or_else(|e| e.into_inner());
                if recording.is_some() {
                    *recording = None;
                }
                drop(recording);
                *self
                    .params
                    .object
                    .write()
                    .unwrap_or_else(|e| e.into_inner()) = s.clone();
                self.synced = s;
            }
            Err(e) => self.message = Some((e.to_string(), true)),
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

    /// Where the current hit parameters aim, world units: Hit X/Y/Z of the object's bounding
    /// box (inside it, not necessarily on the object).
    pub fn hit_aim(&self) -> Option<view3d::V3> {
        let (lo, dims) = self.sculptor.bounds()?;
        let f = [
            self.params.strike.hit_x.value(),
            self.params.strike.hit_y.value(),
            self.params.strike.hit_z.value(),
        ];
        Some([0, 1, 2].map(|a| lo[a] as f32 + f[a] * dims[a] as f32))
    }

    /// Where a strike lands and which way it pushes (see [`HitMarker`]); cached until the
    /// object or the strike parameters change.
    pub fn hit_marker(&mut self) -> Option<HitMarker> {
        let s = &self.params.strike;
        let direction = s.force_direction();
        let key: HitMarkerKey = (
            self.sculptor.shape_hash(),
            [s.hit_x.value(), s.hit_y.value(), s.hit_z.value()].map(f32::to_bits),
            direction.map(|d| d.map(f64::to_bits)),
        );
        if let Some((k, marker)) = &self.hit_marker {
            if *k == key {
                return *marker;
            }
        }
        let marker = self.hit_aim().and_then(|aim| {
            let struck = self.sculptor.struck_point(aim.map(f64::from))?;
            let d = direction.unwrap_or(struck.inward_normal);
            let norm = d.iter().map(|x| x * x).sum::<f64>().sqrt();
            (norm > 0.0).then(|| HitMarker {
                point: struck.point_voxels.map(|x| x as f32),
                direction: d.map(|x| (x / norm) as f32),
            })
        });
        self.hit_marker = Some((key, marker));
        marker
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
    fn edit(&mut self, op: impl FnOnce(&mut Sculptor) -> Result<(), PluginError>) {
        match op(&mut self.sculptor) {
            Ok(()) => {
                self.publish();
                self.framed = false;
                self.message = None;
                if let Some((_, modified)) = &mut self.current_preset {
                    *modified = true;
                }
            }
            Err(e) => self.message = Some((e.to_string(), true)),
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
        let key = (latest.generation, voicing);
        if self.spectrum_key == Some(key) {
            return;
        }
        self.spectrum_key = Some(key);
        let fs = f64::from_bits(self.link.sample_rate_bits.load(Ordering::Relaxed));
        let fs = if fs > 0.0 { fs } else { 48_000.0 };
        self.lines = spectrum(&latest.basis, &voicing, fs).unwrap_or_default();
    }

    /// Has the running engine's worker repaint the window when its status changes (a solve
    /// starts, an answer arrives), so an idle window need not poll for solves the host starts.
    fn watch_engine(&mut self) {
        let (Some(control), Some(repaint)) = (self.link.control(), &self.repaint) else {
            return;
        };
        let address = Arc::as_ptr(&control) as usize;
        if self.watched != Some(address) {
            let repaint = repaint.clone();
            control.watch_status(Arc::new(move || repaint.request_repaint()));
            self.watched = Some(address);
        }
    }
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
    let mut app = EditorApp::new(params, table, link);
    let repaint = nice_plug_egui::RepaintNotifier::new();
    app.repaint = Some(repaint.clone());
    nice_plug_egui::create_egui_editor(
        state,
        repaint,
        nice_plug_egui::EguiNiceSettings::new()
            .with_tile("ModalForge")
            .with_resize_hint(resize_hint()),
        EditorWindow::new(app),
    )
}

/// The editor is resizable down to [`layout::MIN_WINDOW_PX`] (in points: at 200 % the
/// smallest window is twice as large in pixels).
pub fn resize_hint() -> nice_plug::editor::ResizeHint {
    let [w, h] = layout::MIN_WINDOW_PX;
    nice_plug::editor::ResizeHint::RESIZABLE
        .with_min_logical_size(nice_plug::editor::dpi::LogicalSize::new(w, h))
}

impl NiceEguiApp for EditorWindow {
    fn build(
        &mut self,
        egui_ctx: egui::Context,
        nice_gui_ctx: GuiContext,
        _frame: &mut nice_plug_egui::Frame,
    ) -> Result<(), nice_plug_egui::baseview::HandlerError> {
        self.gui = Some(nice_gui_ctx);
        // The project's scale; egui-baseview resizes the window to it on the first frame.
        egui_ctx.set_zoom_factor(self.app.scale());
        Ok(())
    }

    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut nice_plug_egui::Frame) {
        let Some(gui) = self.gui.clone() else {
            return;
        };
        let setter = gui.param_setter();
        let app = &mut self.app;
        app.follow_host();
        app.follow_zoom_keys(ui.ctx());
        app.watch_engine();
        app.poll_match(&setter);
        app.refresh_spectrum();
        // Keep the status line's timer and counters live while they change.
        ui.ctx().request_repaint_after(app.redraw_after());

        layout::window(app, ui, &setter);
        layout::resize_corner(ui);
        if app.dump.is_some() {
            let size = ui.ctx().content_rect().size();
            let state = app.dump_state([size.x, size.y]);
            if let Some(d) = &mut app.dump {
                d.write(&state);
            }
        }
    }

    fn editor_closed(&mut self) {
        self.gui = None;
    }
}

#[cfg(test)]
mod tests;
