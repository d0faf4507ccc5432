//! "Match recording" and "Play recording" (issue 14): the sculpted object's material and damping
//! fitted to a recorded strike of the real object, or the recording's own modes played as the
//! object, on a background thread so neither the window nor the audio waits.
//!
//! Where it sits: started by the editor's "Match recording" button with the file in the path
//! field; [`run`] does the work with the library ([`modalforge::analysis`]: extraction, the
//! damping-law fits, [`material_fit`]); the editor polls [`Matching::poll`] every frame and
//! sets the parameters from [`Matched`] through the host (so the change is automatable and
//! undoable there). The fitted material is also saved beside the recording as
//! `<name>.material.toml`, a user material `modalforge --material FILE.toml` reads.
//!
//! "Play recording" ([`run_play`]) extracts the modes and the best knob damping law; the editor
//! sets the damping knobs to that law and stores a
//! [`modalforge::engine::recorded::RecordedObject`] made under the knobs then in force, which
//! the worker plays until the next sculpting edit.
//!
//! A recording gives `E/rho`, not `E` and `rho` apart: the density is the nearest preset's
//! ([`material_fit::nearest_preset`]). The plugin's damping knobs hold Rayleigh and power laws:
//! the better of those two fits is used (a Caughey law, which the analysis may prefer, is not
//! a knob setting).

use crate::error::PluginError;
use modalforge::analysis::damping_fit::LawFit;
use modalforge::analysis::material_fit::{self, MaterialFitOptions};
use modalforge::analysis::{self, AnalysisOptions};
use modalforge::basis::Hit;
use modalforge::material::{Damping, DampingLaw, Material};
use modalforge::modes::ModeRecord;
use modalforge::shape::VoxelGrid;
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Instant;

/// What a match found.
#[derive(Clone, Debug)]
pub struct Matched {
    /// The fitted material (`E` from the fitted `E/rho` and the assumed density), with the
    /// fitted damping law.
    pub material: Material,
    /// Where it was saved, when it could be.
    pub saved: Option<PathBuf>,
    /// One line for the editor.
    pub summary: String,
}

/// A recording's modes, ready to play.
#[derive(Clone, Debug)]
pub struct Played {
    /// The recording's file stem.
    pub name: String,
    /// Its modes (gain: the amplitude at the onset, full-scale units).
    pub modes: Vec<ModeRecord>,
    /// The best knob damping law of its modes, `None` when neither knob law fits (too few
    /// modes): the knobs then stay as they are.
    pub damping: Option<(crate::params::DampingChoice, f32, f32)>,
    /// One line for the editor.
    pub summary: String,
}

/// What a job on a recording found.
#[derive(Clone, Debug)]
pub enum Outcome {
    /// "Match recording": a material for the sculpted object.
    Fitted(Matched),
    /// "Play recording": the recording's own modes.
    Played(Played),
}

/// A job on a recording running on its thread.
pub struct Matching {
    rx: mpsc::Receiver<Result<Outcome, PluginError>>,
    started: Instant,
    /// The recording's file name.
    pub file: String,
}

impl Matching {
    /// Starts matching `recording` to `grid` (voxel edge set, cropped) struck at `hit`, from
    /// `start_e_over_rho` (m^2/s^2; the current material's).
    pub fn start(recording: PathBuf, grid: VoxelGrid, hit: Hit, start_e_over_rho: f64) -> Self {
        Self::spawn(recording, move |recording| {
            run(recording, &grid, &hit, start_e_over_rho).map(|mut m| {
                let out = recording.with_extension("material.toml");
                if let Some(text) = m.material.to_toml() {
                    if std::fs::write(&out, text).is_ok() {
                        m.saved = Some(out);
                    }
                }
                Outcome::Fitted(m)
            })
        })
    }

    /// Starts extracting the modes of `recording` to play them ([`run_play`]).
    pub fn start_play(recording: PathBuf) -> Self {
        Self::spawn(recording, |recording| {
            run_play(recording).map(Outcome::Played)
        })
    }

    fn spawn(
        recording: PathBuf,
        job: impl FnOnce(&Path) -> Result<Outcome, PluginError> + Send + 'static,
    ) -> Self {
        let (tx, rx) = mpsc::channel();
        let file = recording.file_name().map_or_else(
            || recording.display().to_string(),
            |n| n.to_string_lossy().into(),
        );
        std::thread::spawn(move || {
            // The editor may have closed: nobody to tell.
            let _ = tx.send(job(&recording));
        });
        Self {
            rx,
            started: Instant::now(),
            file,
        }
    }

    /// The result once the thread is done; `None` while it runs.
    pub fn poll(&self) -> Option<Result<Outcome, PluginError>> {
        match self.rx.try_recv() {
            Ok(r) => Some(r),
            Err(mpsc::TryRecvError::Empty) => None,
            Err(mpsc::TryRecvError::Disconnected) => Some(Err(PluginError::Recording {
                file: self.file.clone(),
                reason: "the analysis stopped unexpectedly".into(),
            })),
        }
    }

    /// Seconds since the match started.
    pub fn elapsed_s(&self) -> f64 {
        self.started.elapsed().as_secs_f64()
    }
}

/// Reads `recording`, finds its modes and damping law, and fits `E/rho` and Poisson's ratio of
/// `grid` struck at `hit` from `start_e_over_rho`.
pub fn run(
    recording: &Path,
    grid: &VoxelGrid,
    hit: &Hit,
    start_e_over_rho: f64,
) -> Result<Matched, PluginError> {
    let Analysed { found, file, name } = analyse(recording)?;
    let refuse = |reason: String| PluginError::Recording {
        file: file.clone(),
        reason,
    };
    let fit = material_fit::fit_material(
        grid,
        grid.voxel_size_m(),
        hit,
        &found.modes,
        &MaterialFitOptions {
            start_e_over_rho,
            ..MaterialFitOptions::default()
        },
    )
    .map_err(|e| refuse(e.to_string()))?;
    let nearest = material_fit::nearest_preset(&fit);
    let law = knob_law(&found.damping.laws).ok_or_else(|| {
        refuse("no Rayleigh or power-law damping fits its modes: too few modes".into())
    })?;
    let mut material = Material::new(
        &format!("matched {name}"),
        fit.e_over_rho * nearest.density_kg_m3,
        nearest.density_kg_m3,
        fit.poisson_ratio,
        law.damping(),
    )
    .map_err(|e| refuse(e.to_string()))?;
    material.source = format!(
        "fitted by ModalForge to {file} ({} modes; E/rho +-{:.1} %, nu +-{:.3}; density of the \
         nearest preset, {})",
        fit.matched,
        100.0 * fit.e_over_rho_rel_sigma,
        fit.poisson_sigma,
        nearest.name
    );
    let summary = format!(
        "matched {name}: E/rho {:.3e} m2/s2, nu {:.3} (like {}), {} damping within {:.0} %",
        fit.e_over_rho,
        fit.poisson_ratio,
        nearest.name,
        law.law,
        100.0 * law.rms_relative_error
    );
    Ok(Matched {
        material,
        saved: None,
        summary,
    })
}

/// A recording read and analysed, with the names its messages use.
struct Analysed {
    /// Its modes and damping-law fits.
    found: analysis::Analysis,
    /// Its path, for errors.
    file: String,
    /// Its file stem, for the summary.
    name: String,
}

/// Reads `recording` and extracts its modes (the default method) and damping fits.
fn analyse(recording: &Path) -> Result<Analysed, PluginError> {
    let file = recording.display().to_string();
    let refuse = |reason: String| PluginError::Recording {
        file: file.clone(),
        reason,
    };
    let (samples, rate) = analysis::wav::read_mono(recording).map_err(|e| refuse(e.to_string()))?;
    let found = analysis::extract(&samples, rate, &AnalysisOptions::default())
        .map_err(|e| refuse(e.to_string()))?;
    let name = recording
        .file_stem()
        .map_or_else(|| "recording".into(), |s| s.to_string_lossy().into_owned());
    Ok(Analysed { found, file, name })
}

/// Reads `recording` and extracts its modes and the best knob damping law.
pub fn run_play(recording: &Path) -> Result<Played, PluginError> {
    let Analysed { found, file, name } = analyse(recording)?;
    let modes: Vec<ModeRecord> = found
        .modes
        .iter()
        .map(|m| ModeRecord {
            freq_hz: m.freq_hz,
            decay_per_s: m.decay_per_s,
            gain: m.gain,
        })
        .collect();
    if modes.is_empty() {
        return Err(PluginError::Recording {
            file,
            reason: "no modes above its noise floor: record a louder strike".into(),
        });
    }
    let law = knob_law(&found.damping.laws);
    let damping = law.and_then(|l| Knobs::damping_of(&l.damping()));
    let law_text = law.map_or("the damping knobs as they are".into(), |l| {
        format!(
            "{} damping within {:.0} %",
            l.law,
            100.0 * l.rms_relative_error
        )
    });
    let summary = format!(
        "playing {name}: {} modes, {:.0}-{:.0} Hz, {law_text}; sculpt to play the shape again",
        modes.len(),
        modes
            .iter()
            .map(|m| m.freq_hz)
            .fold(f64::INFINITY, f64::min),
        modes.iter().map(|m| m.freq_hz).fold(0.0, f64::max),
    );
    Ok(Played {
        name,
        modes,
        damping,
        summary,
    })
}

/// The best-fitting damping law the plugin's knobs can hold (Rayleigh or power law), by BIC.
fn knob_law(laws: &[LawFit]) -> Option<&LawFit> {
    laws.iter()
        .filter(|l| matches!(l.law, DampingLaw::Rayleigh | DampingLaw::PowerLaw))
        .filter(|l| {
            matches!(
                l.damping(),
                Damping::Rayleigh { .. } | Damping::PowerLaw { .. }
            )
        })
        .min_by(|a, b| a.bic.total_cmp(&b.bic))
}

/// A material as the plugin's knob values (plain units: GPa, kg/m^3, microseconds), each
/// clamped to its knob's range; `None` for a damping law no knob holds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Knobs {
    /// Young's modulus, GPa.
    pub youngs_gpa: f32,
    /// Density, kg/m^3.
    pub density: f32,
    /// Poisson's ratio.
    pub poisson: f32,
    /// The damping law and its two knobs (`a1` 1/s and `a2` us, or `mu1` and `mu2`).
    pub damping: (crate::params::DampingChoice, f32, f32),
}

impl Knobs {
    /// The knob values of `m`.
    pub fn of(m: &Material) -> Option<Self> {
        Some(Self {
            youngs_gpa: (m.youngs_modulus_pa * 1e-9).clamp(0.01, 1000.0) as f32,
            density: m.density_kg_m3.clamp(50.0, 25_000.0) as f32,
            poisson: m.poisson_ratio.clamp(0.0, 0.49) as f32,
            damping: Self::damping_of(&m.damping)?,
        })
    }

    /// The damping knobs of a law (clamped to their ranges); `None` for a law no knob holds.
    pub fn damping_of(d: &Damping) -> Option<(crate::params::DampingChoice, f32, f32)> {
        use crate::params::DampingChoice;
        Some(match *d {
            Damping::Rayleigh { alpha1, alpha2 } => (
                DampingChoice::Rayleigh,
                alpha1.clamp(0.0, 2000.0) as f32,
                (alpha2 * 1e6).clamp(0.0, 50.0) as f32,
            ),
            Damping::PowerLaw { mu1, mu2 } => (
                DampingChoice::PowerLaw,
                mu1.clamp(0.0, 1000.0) as f32,
                mu2.clamp(0.0, 1.0) as f32,
            ),
            _ => return None,
        })
    }
}
