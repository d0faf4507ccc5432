//! Files the editor reads and writes: importing a model (a MagicaVoxel `.vox`, an OBJ or STL
//! mesh), previewing one too large for the working box until it is kept, cropped or cancelled,
//! saving the sculpture as `.vox`, and the object presets (read, applied to the host's
//! parameters, written from the current settings).
//!
//! Where it sits: methods of [`EditorApp`] that the layout's file row and Presets menu call
//! (`editor/layout.rs`); what they did goes to the window's message line.

use super::EditorApp;
use crate::error::PluginError;
use crate::materials::MaterialChoice;
use crate::presets::Preset;
use modalforge::shape::VoxelGrid;
use nice_plug::prelude::*;
use std::path::Path;

impl EditorApp {
    /// Imports the model in the path field: a MagicaVoxel `.vox`, or an OBJ or STL mesh
    /// (voxelised with `import_side` voxels along its longest side, partial voxels on its
    /// surface). A model that fits the working box replaces the object at once (one undo
    /// step); a `.vox` larger than the box is previewed, resampled to fit (longest side
    /// `import_side`), until the user keeps it ([`EditorApp::keep_import`]), crops it instead
    /// ([`EditorApp::set_import_fit`]) or cancels ([`EditorApp::cancel_import`]). The message
    /// says what was done.
    pub fn import(&mut self) {
        let path = Path::new(self.path.trim()).to_path_buf();
        self.cancel_import();
        match self.read_model(&path) {
            Ok(Model::Fits(grid, said)) => {
                self.edit(|s| s.replace(&grid));
                if self.message.is_none() {
                    self.message = Some((format!("loaded {}: {said}", path.display()), false));
                }
            }
            Ok(Model::TooLarge(original)) => {
                self.pending_import = Some(PendingImport {
                    original,
                    path,
                    fit: ImportFit::Resample,
                    shown: false,
                });
                self.show_import();
            }
            Err(e) => self.message = Some((e, true)),
        }
    }

    /// The model at `path`: a grid that fits the working box and what was done to it, or a
    /// `.vox` too large for the box, cropped to its solid voxels.
    fn read_model(&self, path: &Path) -> Result<Model, String> {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_lowercase())
            .unwrap_or_default();
        let side = self.import_side.clamp(2, crate::sculpt::MAX_SIDE);
        if ext == "obj" || ext == "stl" {
            let name = path.display().to_string();
            let g = modalforge::shape::mesh::read_mesh(path)
                .and_then(|m| modalforge::shape::mesh::voxelize(&m, side, &name))
                .map_err(|e| e.to_string())?;
            let [x, y, z] = g.dims();
            let said = format!(
                "voxelised to {x}x{y}x{z}, {} voxels; {UNDO_HINT}",
                g.count()
            );
            return Ok(Model::Fits(g, said));
        }
        let g = modalforge::shape::vox::read_vox(path, 1.0)
            .map_err(|e| e.to_string())?
            .cropped();
        if g.dims().into_iter().all(|d| d <= crate::sculpt::MAX_SIDE) {
            let said = describe(&g);
            return Ok(Model::Fits(g, said));
        }
        Ok(Model::TooLarge(g))
    }

    /// Puts the pending import, fitted its chosen way, in the view (not yet solved), in place
    /// of the previous preview if any.
    pub(crate) fn show_import(&mut self) {
        let side = self.import_side.clamp(2, crate::sculpt::MAX_SIDE);
        let Some(p) = &mut self.pending_import else {
            return;
        };
        if std::mem::take(&mut p.shown) {
            self.sculptor.retract();
        }
        let read = describe(&p.original);
        let name = p.path.display().to_string();
        let fitted = fit_model(&p.original, p.fit, side);
        let shown = fitted
            .as_ref()
            .map_err(|e| e.clone())
            .and_then(|(g, _)| self.sculptor.replace(g).map_err(|e| e.to_string()));
        self.message = Some(match (shown, fitted) {
            (Ok(()), Ok((_, said))) => {
                p.shown = true;
                self.framed = false;
                (
                    format!(
                        "{name}: {read}, {said} to fit the {max}^3 box (a preview): Keep \
                         it, try the other fit, or Cancel",
                        max = crate::sculpt::MAX_SIDE
                    ),
                    false,
                )
            }
            (Err(e), _) | (_, Err(e)) => (format!("{name}: {read}; {e}"), true),
        });
    }

    /// The import waiting for a choice: its fit, if one is pending.
    pub fn pending_import(&self) -> Option<ImportFit> {
        self.pending_import.as_ref().map(|p| p.fit)
    }

    /// Fits the pending import the other way (resampled or cropped) and shows it.
    pub fn set_import_fit(&mut self, fit: ImportFit) {
        if let Some(p) = &mut self.pending_import {
            if p.fit != fit {
                p.fit = fit;
                self.show_import();
            }
        }
    }

    /// Keeps the previewed import: it becomes the object (one undo step) and is solved.
    pub fn keep_import(&mut self) {
        let Some(p) = self.pending_import.take() else {
            return;
        };
        if !p.shown {
            return;
        }
        self.publish();
        if let Some((_, modified)) = &mut self.current_preset {
            *modified = true;
        }
        let [x, y, z] = self.sculptor.bounds().map_or([0; 3], |(_, d)| d);
        self.message = Some((
            format!(
                "loaded {}: {x}x{y}x{z}, {} voxels ({}); {UNDO_HINT}",
                p.path.display(),
                self.sculptor.count(),
                match p.fit {
                    ImportFit::Resample => "resampled",
                    ImportFit::Crop => "cropped",
                }
            ),
            false,
        ));
    }

    /// Drops the previewed import; the object before it comes back (nothing to redo).
    pub fn cancel_import(&mut self) {
        let Some(p) = self.pending_import.take() else {
            return;
        };
        if p.shown {
            self.sculptor.retract();
            self.framed = false;
        }
        self.message = Some((format!("import of {} cancelled", p.path.display()), false));
    }

    pub(super) fn save_vox(&mut self) {
        let path = Path::new(self.path.trim()).to_path_buf();
        let result = self
            .sculptor
            .sculpt()
            .and_then(|s| s.to_grid())
            .and_then(|g| Ok(modalforge::shape::vox::write_vox(&g, &path)?));
        self.message = Some(match result {
            Ok(()) => (format!("saved {}", path.display()), false),
            Err(e) => (e.to_string(), true),
        });
    }

    /// The preset the window's current settings describe.
    pub fn current_preset(&self, name: &str) -> Result<Preset, PluginError> {
        let sculpt = self.sculptor.sculpt()?;
        let mut p = Preset::with_object(name, &sculpt);
        let m = self.params.material.preset.value();
        p.material = MaterialChoice::ids()
            .and_then(|ids| ids.get(m.to_index()))
            .unwrap_or(&"glass")
            .to_string();
        if m == MaterialChoice::Custom {
            p.youngs_gpa = Some(self.params.material.youngs_gpa.value());
            p.density_kg_m3 = Some(self.params.material.density.value());
            p.poisson = Some(self.params.material.poisson.value());
        }
        p.size_m = self.params.material.size_m.value();
        p.hardness_ms = self.params.strike.hardness_ms.value();
        p.hit = [
            self.params.strike.hit_x.value(),
            self.params.strike.hit_y.value(),
            self.params.strike.hit_z.value(),
        ];
        Ok(p)
    }

    pub(super) fn save_preset(&mut self) {
        let path = Path::new(self.path.trim()).to_path_buf();
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "preset".into());
        let result = self.current_preset(&name).and_then(|p| {
            std::fs::write(&path, p.to_toml()).map_err(|source| PluginError::Io {
                action: "write",
                path: path.clone(),
                source,
            })
        });
        self.message = Some(match result {
            Ok(()) => (format!("saved {}", path.display()), false),
            Err(e @ PluginError::Io { .. }) => (e.to_string(), true),
            Err(e) => (format!("cannot save {}: {e}", path.display()), true),
        });
    }

    pub(super) fn read_preset(&self) -> Result<Preset, PluginError> {
        let path = Path::new(self.path.trim());
        let text = modalforge::limits::read_text(path, "preset TOML").map_err(|e| match e {
            modalforge::limits::TextReadError::TooLarge(e) => PluginError::FileTooLarge(e),
            modalforge::limits::TextReadError::Io(source) => PluginError::Io {
                action: "read",
                path: path.into(),
                source,
            },
        })?;
        Preset::from_toml(&text, &path.display().to_string())
    }

    /// Applies a preset: its object replaces the sculpture (one undo step) and its settings
    /// go to the host.
    pub(super) fn apply_preset(&mut self, preset: &Preset, setter: &ParamSetter) {
        let sculpt = match preset.sculpt().and_then(|s| s.to_grid()) {
            Ok(g) => g,
            Err(e) => {
                self.message = Some((e.to_string(), true));
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
            setter.begin_set_parameter(&p.material.preset);
            setter.set_parameter(&p.material.preset, m);
            setter.end_set_parameter(&p.material.preset);
        }
        if let (Some(e), Some(rho), Some(nu)) =
            (preset.youngs_gpa, preset.density_kg_m3, preset.poisson)
        {
            set_f(&p.material.youngs_gpa, e);
            set_f(&p.material.density, rho);
            set_f(&p.material.poisson, nu);
        }
        setter.begin_set_parameter(&p.damping.law);
        setter.set_parameter(&p.damping.law, crate::params::DampingChoice::Material);
        setter.end_set_parameter(&p.damping.law);
        set_f(&p.material.size_m, preset.size_m);
        set_f(&p.strike.hardness_ms, preset.hardness_ms);
        set_f(&p.strike.hit_x, preset.hit[0]);
        set_f(&p.strike.hit_y, preset.hit[1]);
        set_f(&p.strike.hit_z, preset.hit[2]);
        self.message = Some(if preset.description.trim().is_empty() {
            (format!("loaded preset {}", preset.name), false)
        } else {
            (format!("{}: {}", preset.name, preset.description), false)
        });
        self.current_preset = Some((preset.name.clone(), false));
    }

    /// The Presets menu's caption: the preset last applied, marked once the object is edited.
    pub fn presets_caption(&self) -> String {
        match &self.current_preset {
            None => "Presets".into(),
            Some((name, false)) => name.clone(),
            Some((name, true)) => format!("{name} (modified)"),
        }
    }
}

/// What an import's message says about undoing it.
const UNDO_HINT: &str = "Ctrl+Z restores the previous object";

/// A model read for import.
enum Model {
    /// It fits the working box: the grid and what was done to it.
    Fits(VoxelGrid, String),
    /// A `.vox` larger than the box, cropped to its solid voxels.
    TooLarge(VoxelGrid),
}

/// How an imported model too large for the working box is made to fit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImportFit {
    /// Resampled so that its longest side is the import size (the whole model, coarser).
    Resample,
    /// Its central box-sized part at full resolution (detail kept, the rest cut off).
    Crop,
}

/// An imported model too large for the box, previewed in the view until kept or cancelled.
pub(super) struct PendingImport {
    /// The model as read, cropped to its solid voxels.
    original: VoxelGrid,
    /// Where it came from.
    path: std::path::PathBuf,
    /// How it is fitted.
    fit: ImportFit,
    /// The sculptor holds the preview as its last undo step.
    shown: bool,
}

/// A grid's size and voxel count, as messages say them: "24x24x25, 2370 voxels".
fn describe(g: &VoxelGrid) -> String {
    let [x, y, z] = g.dims();
    format!("{x}x{y}x{z}, {} voxels", g.count())
}

/// `model` made to fit the working box `fit`'s way (`side`: the resampled longest side), and
/// what was done ("resampled to 32x32x16 (1234 voxels)").
fn fit_model(
    model: &VoxelGrid,
    fit: ImportFit,
    side: usize,
) -> Result<(VoxelGrid, String), String> {
    let max = crate::sculpt::MAX_SIDE;
    let (grid, how) = match fit {
        ImportFit::Resample => (
            modalforge::shape::ops::resampled(model, side).ok_or_else(|| {
                format!("resampled to {side} voxels it vanishes (too thin): raise the import size")
            })?,
            "resampled",
        ),
        ImportFit::Crop => {
            let d = model.dims();
            let lo = [0, 1, 2].map(|a| (d[a] - d[a].min(max)) / 2);
            let g = model.window(lo, [0, 1, 2].map(|a| d[a].min(max))).cropped();
            if g.count() == 0 {
                return Err("its central part is empty: resample it instead".into());
            }
            (g, "cropped")
        }
    };
    let [a, b, c] = grid.dims();
    let said = format!("{how} to {a}x{b}x{c} ({} voxels)", grid.count());
    Ok((grid, said))
}

/// Where file paths start: `~/ModalForge/object.vox`.
pub(super) fn default_dir() -> String {
    let home = std::env::var("HOME").unwrap_or_else(|_| ".".into());
    format!("{home}/ModalForge/object.vox")
}
