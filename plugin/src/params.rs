//! The plugin's automatable parameters (ids are short and frozen: hosts store them) and the
//! conversion of their values into an engine [`Voicing`].
//!
//! Where it sits: read by [`crate::ModalForge::process`] every block (voicing, key mapping)
//! and by the worker's request source (solve-relevant ones: material's Poisson's ratio,
//! element, solver, mode count).

use crate::materials::{MaterialChoice, MaterialTable};
use modalforge::engine::{DampingParams, HitPoint, Voicing};
use nice_plug::prelude::*;
use std::sync::{Arc, RwLock};

mod resonator;
pub use resonator::{HeldNote, ResonatorGroup};

/// How MIDI keys strike the object.
#[derive(Enum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum KeyMapping {
    /// The object is scaled so that its fundamental lands on the played note.
    #[id = "pitch"]
    #[name = "Pitch"]
    Pitch,
    /// Keys select hit points spread over the object (C2 upward), at its own size.
    #[id = "positions"]
    #[name = "Positions"]
    Positions,
}

/// What MIDI channel messages do (per-note expressions from CLAP and VST3 hosts always
/// apply, [`crate::keymap`]).
#[derive(Enum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum MidiExpression {
    /// One controller for every note: pitch bend scales the damping, the mod wheel the
    /// mallet's contact time.
    #[id = "classic"]
    #[name = "Classic"]
    Classic,
    /// MPE, lower zone: channel 1 is the master (its pitch bend moves every note, 2
    /// semitones), channels 2-16 carry one note each; a member channel's pitch bend retunes
    /// its note (by the bend range), its pressure presses on it, its CC74 sets the mallet of
    /// its next strike.
    #[id = "mpe"]
    #[name = "MPE"]
    Mpe,
}

/// What a note's brightness (a CLAP/VST3 note expression, MPE's CC74) changes in its next
/// strike ([`crate::keymap`]).
#[derive(Enum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum BrightnessTarget {
    /// The mallet: brighter is a shorter contact (x1/4 at full), darker a longer one (x4).
    #[id = "mallet"]
    #[name = "Mallet"]
    Mallet,
    /// The hit point: from the centre of the object's box (0) through the set point (0.5) to
    /// the box's edge (1), along the line through the set point; the height is kept.
    #[id = "hit"]
    #[name = "Hit Point"]
    HitPoint,
}

/// Which damping law is used.
#[derive(Enum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum DampingChoice {
    /// The material preset's own model (Rayleigh, Caughey or power law, as published).
    #[id = "material"]
    #[name = "Material"]
    Material,
    /// Rayleigh `c = alpha1 + alpha2 omega^2` with the knobs below.
    #[id = "rayleigh"]
    #[name = "Rayleigh"]
    Rayleigh,
    /// Power law `c = mu1 omega^(2 mu2)` with the knobs below.
    #[id = "power"]
    #[name = "Power law"]
    PowerLaw,
}

/// Eigensolver for shape edits.
#[derive(Enum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum SolverChoice {
    /// LOBPCG for big objects, Lanczos otherwise.
    #[id = "auto"]
    #[name = "Auto"]
    Auto,
    /// Shift-invert Lanczos (exact, factorises).
    #[id = "lanczos"]
    #[name = "Lanczos"]
    Lanczos,
    /// LOBPCG with multigrid.
    #[id = "lobpcg"]
    #[name = "LOBPCG"]
    Lobpcg,
}

/// Which answers a shape edit gets: the neural predictor's instant one and FEM's exact one.
#[derive(Enum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum AnswerChoice {
    /// The predictor answers at once, FEM replaces it when ready.
    #[id = "auto"]
    #[name = "Predictor, then FEM"]
    Auto,
    /// FEM only (carried and coarse answers included): the default while the shipped
    /// predictor is an interim one (held-out recall 49 %, precision 59 %; assets/predictor/README.md), whose
    /// first answer can be far off.
    #[id = "fem"]
    #[name = "FEM only"]
    FemOnly,
    /// The predictor only: no FEM solve.
    #[id = "neural"]
    #[name = "Predictor only"]
    PredictorOnly,
}

/// Finite element.
#[derive(Enum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ElementChoice {
    /// Trilinear with incompatible modes: fast, ~1% on solids and flat walls, 8-11 % sharp on
    /// curved thin walls.
    #[id = "hex8i"]
    #[name = "Fast (hex8i)"]
    Hex8i,
    /// Triquadratic: accurate for thin plates, ~6x the DOFs.
    #[id = "hex27"]
    #[name = "Accurate (hex27)"]
    Hex27,
    /// Triquadratic on 2x2x2-voxel blocks (the default): curved thin walls in tune (pairs
    /// within 0.2 %, frequencies within 2 % of the smooth solid) at 1.3x hex8i's DOFs.
    #[id = "hex27x2"]
    #[name = "Curved (hex27x2)"]
    Hex27x2,
}

/// Float parameter with a formatter that round-trips through text (validators check it).
fn float(
    name: &str,
    default: f32,
    range: FloatRange,
    unit: &'static str,
    digits: usize,
) -> FloatParam {
    FloatParam::new(name, default, range)
        .with_unit(unit)
        .with_value_to_string(formatters::v2s_f32_rounded(digits))
}

/// The range of a fraction, 0..1.
fn unit_range() -> FloatRange {
    FloatRange::Linear { min: 0.0, max: 1.0 }
}

/// A log-skewed range.
fn skewed(min: f32, max: f32) -> FloatRange {
    FloatRange::Skewed {
        min,
        max,
        factor: FloatRange::skew_factor(-2.0),
    }
}

/// Every parameter, plus the persisted object. Hosts see the parameters in seven groups
/// (nice-plug's `#[nested(group = ...)]`, which keeps each parameter's id unchanged, so
/// projects saved before the groups existed still load).
#[derive(Params)]
pub struct ModalForgeParams {
    /// The sculpted object (persisted with the project).
    #[persist = "object"]
    pub object: Arc<RwLock<crate::sculpt::Sculpt>>,
    /// A recording's modes played instead of the sculpted object ("Play recording"; cleared
    /// by the next sculpting edit), persisted with the project. States saved before it existed
    /// have none.
    #[persist = "recording"]
    pub recording: Arc<RwLock<Option<modalforge::engine::recorded::RecordedObject>>>,
    /// The Scala tuning of the "pitch" key mapping (`None`: 12-TET), persisted as its files'
    /// texts.
    #[persist = "tuning"]
    pub tuning: Arc<RwLock<Option<crate::tuning::TuningState>>>,
    /// The editor's scale (1.0 = 100 %, one of [`crate::editor::SCALES`]), persisted with the
    /// project; states saved before it existed open at 100 %.
    #[persist = "ui-scale"]
    pub ui_scale: Arc<RwLock<f32>>,
    /// Each key's frequency under `tuning`, for the audio thread (not a parameter).
    pub key_table: Arc<crate::tuning::KeyTable>,
    /// Material constants and size.
    #[nested(group = "Material")]
    pub material: MaterialGroup,
    /// Damping law.
    #[nested(group = "Damping")]
    pub damping: DampingGroup,
    /// Mallet, hit point and force direction.
    #[nested(group = "Strike")]
    pub strike: StrikeGroup,
    /// Output, polyphony and key mapping.
    #[nested(group = "Play")]
    pub play: PlayGroup,
    /// How shape edits are solved (every change re-solves).
    #[nested(group = "Solver")]
    pub solver: SolverGroup,
    /// Per-note expression: MPE and its mapping.
    #[nested(group = "Expression")]
    pub expression: ExpressionGroup,
    /// The side-chain input played through the object.
    #[nested(group = "Resonator")]
    pub resonator: ResonatorGroup,
}

/// The "Expression" group.
#[derive(Params)]
pub struct ExpressionGroup {
    /// What MIDI channel messages do.
    #[id = "expr"]
    pub midi: EnumParam<MidiExpression>,
    /// Semitones a member channel's full pitch bend moves its note (MPE's default is 48).
    #[id = "bendr"]
    pub bend_range: FloatParam,
    /// Extra decay of a note under full pressure, 1/s.
    #[id = "pdec"]
    pub pressure_decay: FloatParam,
    /// What brightness changes.
    #[id = "brt"]
    pub brightness: EnumParam<BrightnessTarget>,
}

impl Default for ExpressionGroup {
    fn default() -> Self {
        Self {
            midi: EnumParam::new("MIDI Expression", MidiExpression::Classic),
            bend_range: float(
                "MPE Bend Range",
                48.0,
                FloatRange::Linear {
                    min: 1.0,
                    max: 96.0,
                },
                " st",
                0,
            ),
            pressure_decay: float("Pressure Damping", 40.0, skewed(1.0, 500.0), " /s", 1),
            brightness: EnumParam::new("Brightness Moves", BrightnessTarget::Mallet),
        }
    }
}

/// The "Material" group.
#[derive(Params)]
pub struct MaterialGroup {
    /// Material preset; "Custom" uses the E, rho and nu knobs.
    #[id = "mat"]
    pub preset: EnumParam<MaterialChoice>,
    /// Young's modulus for the custom material, GPa.
    #[id = "e"]
    pub youngs_gpa: FloatParam,
    /// Density for the custom material, kg/m^3.
    #[id = "rho"]
    pub density: FloatParam,
    /// Poisson's ratio for the custom material (a change re-solves).
    #[id = "nu"]
    pub poisson: FloatParam,
    /// Object size: its longest side, m.
    #[id = "size"]
    pub size_m: FloatParam,
}

/// The "Damping" group.
#[derive(Params)]
pub struct DampingGroup {
    /// Damping law.
    #[id = "dmod"]
    pub law: EnumParam<DampingChoice>,
    /// Rayleigh mass term, 1/s.
    #[id = "a1"]
    pub alpha1: FloatParam,
    /// Rayleigh stiffness term, microseconds.
    #[id = "a2"]
    pub alpha2_us: FloatParam,
    /// Power-law coefficient.
    #[id = "mu1"]
    pub mu1: FloatParam,
    /// Power-law exponent on omega^2.
    #[id = "mu2"]
    pub mu2: FloatParam,
}

/// The "Strike" group.
#[derive(Params)]
pub struct StrikeGroup {
    /// Mallet contact time, ms (0 = an ideal impulse; longer is softer).
    #[id = "hard"]
    pub hardness_ms: FloatParam,
    /// How much a soft key press lengthens the contact (0 = velocity only changes force).
    #[id = "velh"]
    pub velocity_hardness: FloatParam,
    /// Hit point as fractions of the object's extent.
    #[id = "hx"]
    pub hit_x: FloatParam,
    /// Hit point y.
    #[id = "hy"]
    pub hit_y: FloatParam,
    /// Hit point z.
    #[id = "hz"]
    pub hit_z: FloatParam,
    /// Strike along the struck face's normal (else along azimuth/elevation).
    #[id = "fnrm"]
    pub force_normal: BoolParam,
    /// Force direction azimuth, degrees.
    #[id = "faz"]
    pub force_azimuth: FloatParam,
    /// Force direction elevation, degrees (-90 = straight down).
    #[id = "fel"]
    pub force_elevation: FloatParam,
}

impl StrikeGroup {
    /// The three hit-point parameters, x, y, z.
    pub fn hit(&self) -> [&FloatParam; 3] {
        [&self.hit_x, &self.hit_y, &self.hit_z]
    }

    /// The force direction the knobs describe: `None` (into the struck face) with "Force
    /// Normal to Surface" on, else the unit vector of Force Azimuth and Elevation.
    pub fn force_direction(&self) -> Option<[f64; 3]> {
        if self.force_normal.value() {
            return None;
        }
        let (az, el) = (
            (self.force_azimuth.value() as f64).to_radians(),
            (self.force_elevation.value() as f64).to_radians(),
        );
        Some([el.cos() * az.cos(), el.cos() * az.sin(), el.sin()])
    }
}

/// The "Play" group.
#[derive(Params)]
pub struct PlayGroup {
    /// Output gain, dB.
    #[id = "gain"]
    pub gain_db: FloatParam,
    /// Most modes ringing at once (quietest dropped first).
    #[id = "budget"]
    pub mode_budget: IntParam,
    /// Key mapping.
    #[id = "map"]
    pub mapping: EnumParam<KeyMapping>,
    /// Note-off damps the note.
    #[id = "mute"]
    pub note_off_mute: BoolParam,
    /// Extra decay of a muted note, 1/s.
    #[id = "mdec"]
    pub mute_decay: FloatParam,
}

/// The "Solver" group: every change re-solves.
#[derive(Params)]
pub struct SolverGroup {
    /// Eigensolver.
    #[id = "solver"]
    pub kind: EnumParam<SolverChoice>,
    /// Which answers an edit gets. Without loadable predictor weights, FEM answers whatever
    /// this says.
    #[id = "answer"]
    pub answers: EnumParam<AnswerChoice>,
    /// Element.
    #[id = "elem"]
    pub element: EnumParam<ElementChoice>,
    /// Modes to compute.
    #[id = "modes"]
    pub modes: IntParam,
}

impl Default for ModalForgeParams {
    fn default() -> Self {
        Self {
            object: Arc::new(RwLock::new(crate::sculpt::Sculpt::default())),
            recording: Arc::new(RwLock::new(None)),
            tuning: Arc::new(RwLock::new(None)),
            ui_scale: Arc::new(RwLock::new(1.0)),
            key_table: Arc::new(crate::tuning::KeyTable::default()),
            material: MaterialGroup::default(),
            damping: DampingGroup::default(),
            strike: StrikeGroup::default(),
            play: PlayGroup::default(),
            solver: SolverGroup::default(),
            expression: ExpressionGroup::default(),
            resonator: ResonatorGroup::default(),
        }
    }
}

impl Default for MaterialGroup {
    fn default() -> Self {
        Self {
            preset: EnumParam::new("Material", MaterialChoice::Glass),
            youngs_gpa: float("E", 70.0, skewed(0.01, 1000.0), " GPa", 3),
            density: float("Density", 2500.0, skewed(50.0, 25000.0), " kg/m3", 1),
            poisson: float(
                "Poisson",
                0.25,
                FloatRange::Linear {
                    min: 0.0,
                    max: 0.49,
                },
                "",
                3,
            ),
            size_m: float("Size", 0.2, skewed(0.01, 4.0), " m", 4),
        }
    }
}

impl Default for DampingGroup {
    fn default() -> Self {
        Self {
            law: EnumParam::new("Damping", DampingChoice::Material),
            alpha1: float("Alpha1", 5.0, skewed(0.0, 2000.0), " /s", 3),
            alpha2_us: float("Alpha2", 0.1, skewed(0.0, 50.0), " us", 4),
            mu1: float("Mu1", 5.0, skewed(0.0, 1000.0), "", 3),
            mu2: float("Mu2", 0.2, unit_range(), "", 3),
        }
    }
}

impl Default for StrikeGroup {
    fn default() -> Self {
        Self {
            hardness_ms: float("Hardness", 0.5, skewed(0.0, 20.0), " ms", 3),
            velocity_hardness: float("Vel > Hardness", 0.5, unit_range(), "", 2),
            hit_x: float("Hit X", 0.37, unit_range(), "", 3),
            hit_y: float("Hit Y", 0.41, unit_range(), "", 3),
            hit_z: float("Hit Z", 1.0, unit_range(), "", 3),
            force_normal: BoolParam::new("Force Normal", true),
            force_azimuth: float(
                "Force Azimuth",
                0.0,
                FloatRange::Linear {
                    min: -180.0,
                    max: 180.0,
                },
                " deg",
                1,
            ),
            force_elevation: float(
                "Force Elevation",
                -90.0,
                FloatRange::Linear {
                    min: -90.0,
                    max: 90.0,
                },
                " deg",
                1,
            ),
        }
    }
}

impl Default for PlayGroup {
    fn default() -> Self {
        Self {
            gain_db: float(
                "Gain",
                0.0,
                FloatRange::Linear {
                    min: -60.0,
                    max: 24.0,
                },
                " dB",
                1,
            ),
            mode_budget: IntParam::new(
                "Mode Budget",
                2048,
                IntRange::Linear { min: 16, max: 8192 },
            ),
            mapping: EnumParam::new("Key Mapping", KeyMapping::Pitch),
            note_off_mute: BoolParam::new("Note-off Mute", false),
            mute_decay: float("Mute Decay", 40.0, skewed(1.0, 500.0), " /s", 1),
        }
    }
}

impl Default for SolverGroup {
    fn default() -> Self {
        Self {
            kind: EnumParam::new("Solver", SolverChoice::Auto),
            answers: EnumParam::new("Answers", AnswerChoice::FemOnly),
            element: EnumParam::new("Element", ElementChoice::Hex27x2),
            modes: IntParam::new("Modes", 60, IntRange::Linear { min: 8, max: 200 }),
        }
    }
}

impl ModalForgeParams {
    /// The voicing the knobs describe (no allocation: the presets are a table).
    /// `damping_scale` multiplies the damping (pitch bend), `hardness_scale` the contact time
    /// (mod wheel).
    pub fn voicing(
        &self,
        table: &MaterialTable,
        damping_scale: f64,
        hardness_scale: f64,
    ) -> Voicing {
        let preset = table.get(self.material.preset.value());
        let custom = self.material.preset.value() == MaterialChoice::Custom;
        let (e, rho) = if custom {
            (
                self.material.youngs_gpa.value() as f64 * 1e9,
                self.material.density.value() as f64,
            )
        } else {
            (preset.youngs_modulus_pa, preset.density_kg_m3)
        };
        let damping = match self.damping.law.value() {
            DampingChoice::Material => preset.damping,
            DampingChoice::Rayleigh => DampingParams::Rayleigh {
                alpha1: self.damping.alpha1.value() as f64,
                alpha2: self.damping.alpha2_us.value() as f64 * 1e-6,
            },
            DampingChoice::PowerLaw => DampingParams::PowerLaw {
                mu1: self.damping.mu1.value() as f64,
                mu2: self.damping.mu2.value() as f64,
            },
        };
        let damping = scale_damping(damping, damping_scale);
        let direction = self.strike.force_direction();
        Voicing {
            youngs_modulus_pa: e,
            density_kg_m3: rho,
            size_m: self.material.size_m.value() as f64,
            damping,
            hit: HitPoint {
                position: [
                    self.strike.hit_x.value() as f64,
                    self.strike.hit_y.value() as f64,
                    self.strike.hit_z.value() as f64,
                ],
                direction,
            },
            hardness_s: (self.strike.hardness_ms.value() as f64 * 1e-3 * hardness_scale).min(0.1),
            output_gain: 10f64.powf(self.play.gain_db.value() as f64 / 20.0),
            normalise: true,
            mute_decay_per_s: self.play.mute_decay.value() as f64,
            pressure_decay_per_s: self.expression.pressure_decay.value() as f64,
        }
    }

    /// Poisson's ratio of the selected material.
    pub fn poisson_ratio(&self, table: &MaterialTable) -> f64 {
        if self.material.preset.value() == MaterialChoice::Custom {
            self.material.poisson.value() as f64
        } else {
            table.get(self.material.preset.value()).poisson_ratio
        }
    }
}

/// Multiplies every damping coefficient by `s` (the whole law scales: `c -> s c`).
fn scale_damping(d: DampingParams, s: f64) -> DampingParams {
    match d {
        DampingParams::Rayleigh { alpha1, alpha2 } => DampingParams::Rayleigh {
            alpha1: alpha1 * s,
            alpha2: alpha2 * s,
        },
        DampingParams::PowerLaw { mu1, mu2 } => DampingParams::PowerLaw { mu1: mu1 * s, mu2 },
        DampingParams::Caughey { eta, terms } => DampingParams::Caughey {
            eta: eta.map(|e| e * s),
            terms,
        },
    }
}
