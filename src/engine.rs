//! The real-time engine: a wait-free audio side that strikes and voices solved objects, and a
//! worker thread that solves shape edits.
//!
//! Where it sits: between the mode sources ([`ObjectModes`]: a [`crate::basis::ModeBasis`] from
//! FEM or a [`crate::predictor::object::PredictedObject`] from the neural predictor) and the audio callback of the plugin, the standalone app or the CLI.
//!
//! ```text
//! editor / CLI ──ObjectRequest──> EngineControl ─mailbox (newest wins)─> worker thread
//!                                                                          │ ModeSolver chain
//!        audio callback                                    rtrb ring <─────┘ Box<SolvedObject>
//!  set_voicing(Voicing) ─┐                                     │
//!  events (strike, mute) ┴─> AudioEngine::process ─> voices (OscillatorBank each) ─> audio
//!                                    └── replaced objects ──rtrb ring──> worker (freed there)
//! ```
//!
//! The lifecycle contract (fundsp style): [`Engine::start`] allocates everything; afterwards
//! [`AudioEngine::process`], [`AudioEngine::set_voicing`] and [`AudioEngine::reset`] never
//! allocate, free, lock, block or log (`tests/engine_realtime.rs` counts allocations on the
//! audio thread while objects are edited and solved). The expensive shape solve (worker) and
//! the cheap voicing (audio thread, [`voicing`]) are separate types.

pub mod answers;
mod audio;
mod object;
pub mod pitch;
pub mod recorded;
pub mod resonator;
mod solvers;
pub mod spectrum;
mod voice;
pub mod voicing;
mod worker;

pub use answers::KeptAnswers;
pub use audio::{AudioEngine, STEAL_FADE_SAMPLES};
pub use object::{ObjectModes, SolvedObject};
pub use solvers::{
    coarse_expected_error, coarse_grid, coarse_stiffening, grid_mirrors, interactive_solvers,
    mean_wall_voxels, predicted_cold_ms, solve_coarse, AnswerSwitch, Answers, CarriedRitzSolver,
    CoarseFemSolver, IncrementalFemSolver, NeuralSolver, CARRIED_EXPECTED_ERROR,
    COARSE_EXPECTED_ERROR, COARSE_THIN_EXPECTED_ERROR, NEURAL_EXPECTED_ERROR,
    PROGRESSIVE_BUDGET_MS, THIN_WALL_VOXELS, WIDE_CARRIED_EXPECTED_ERROR,
};
pub use voicing::{DampingParams, HitPoint, Voicing, VoicingError};
pub use worker::{
    EngineControl, FemSolver, LatestObject, ModeSolver, ObjectRequest, RequestSource, SolveReport,
    SolveState, StatusWatcher, WorkerStatus,
};

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

/// Longest span the engine renders at once (its scratch buffer); any block size works.
pub const BLOCK_SAMPLES: usize = 64;

/// Sizes fixed at start.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EngineConfig {
    /// Keys that ring at once (more steal the quietest).
    pub voices: usize,
    /// Most modes one voice plays.
    pub modes_per_voice: usize,
    /// Most modes ringing in all voices together (quietest dropped first); changeable live.
    pub mode_budget: usize,
    /// Most modes of an object a strike considers.
    pub max_object_modes: usize,
}

impl Default for EngineConfig {
    fn default() -> Self {
        Self {
            voices: 16,
            modes_per_voice: 256,
            mode_budget: 2048,
            max_object_modes: 1024,
        }
    }
}

/// Live figures from the audio side (atomics: the editor reads them without locking).
#[derive(Debug, Default)]
pub struct EngineStats {
    /// Modes ringing.
    pub active_modes: AtomicU64,
    /// Voices ringing.
    pub active_voices: AtomicU64,
    /// `f64` bits: time in `process` over the block's duration, averaged (1.0 = one core full).
    pub load_bits: AtomicU64,
    /// Strikes refused (no object yet, invalid values, every voice fading).
    pub dropped_strikes: AtomicU64,
    /// Modes dropped by the budget.
    pub dropped_modes: AtomicU64,
    /// Generation of the object strikes use now (0: none yet).
    pub generation: AtomicU64,
}

impl EngineStats {
    /// CPU load: time in `process` over real time (1.0 = one core full).
    pub fn load(&self) -> f64 {
        f64::from_bits(self.load_bits.load(Ordering::Relaxed))
    }
}

/// A note event for [`AudioEngine::process`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Event {
    /// Strike the object. Strikes on a ringing key add to it.
    Strike {
        /// The key (a MIDI note, or any id).
        key: u8,
        /// How high the object sounds: it is scaled by `1 / ratio`.
        pitch: Pitch,
        /// Force multiplier, `0..=100` (1 = the modes' own gains).
        velocity: f64,
        /// Hit point; `None` uses the voicing's.
        hit: Option<HitPoint>,
        /// Mallet contact time, s; `None` uses the voicing's.
        hardness_s: Option<f64>,
    },
    /// Damp the key's ringing modes by the voicing's mute decay (note-off with mute on).
    Mute {
        /// The key.
        key: u8,
    },
    /// Per-note expression on the key's ringing voice (MPE, CLAP and VST3 note expressions),
    /// continuous while it rings; a new strike on the key keeps it.
    Expression {
        /// The key.
        key: u8,
        /// What changes.
        expression: Expression,
    },
    /// Start a continuous contact on the key: a held note scraping the object, noise pushed
    /// through the resonator bank ([`resonator`]) at `pitch` until [`Event::ContactEnd`] on
    /// the key; the key's [`Expression::Pressure`] presses harder and scrapes faster.
    Contact {
        /// The key.
        key: u8,
        /// How high the object sounds (as for a strike).
        pitch: Pitch,
        /// Force, `0..=1` (a MIDI velocity over 127).
        velocity: f64,
    },
    /// End the key's contact (note-off of a scraping key).
    ContactEnd {
        /// The key.
        key: u8,
    },
    /// Silence everything.
    AllOff,
}

/// A per-note expression, mapped physically.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Expression {
    /// Retune by this many semitones from the struck pitch: the object is played smaller or
    /// larger, so every mode moves by the same ratio, continuously, each keeping its phase.
    TuningSemitones(f64),
    /// A hand pressing on the object, 0 (none) to 1: every mode of the note decays faster by
    /// this share of [`Voicing::pressure_decay_per_s`].
    Pressure(f64),
    /// The note's gain, 0 to 4 (1 = as struck), ramped over a block.
    Volume(f64),
}

/// Most semitones [`Expression::TuningSemitones`] moves a note (MPE's largest bend range).
pub const MAX_TUNING_SEMITONES: f64 = 96.0;

/// The size a strike plays the object at.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Pitch {
    /// Frequency ratio to the object's own size (1 = as sculpted).
    Ratio(f64),
    /// Scale the object so that its fundamental (lowest playable mode under the current
    /// voicing) is this frequency, Hz: the "pitch" key mapping. Resolved at the strike, with
    /// the object in use then.
    Fundamental(f64),
}

/// An event at a sample offset within the block.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimedEvent {
    /// Sample offset in the block passed to `process`.
    pub offset: usize,
    /// What happens.
    pub event: Event,
}

/// Why the engine could not start.
#[derive(Debug, thiserror::Error)]
pub enum EngineError {
    /// The initial voicing is invalid.
    #[error(transparent)]
    Voicing(#[from] VoicingError),
    /// Zero voices or modes, or a sample rate that is not positive and finite.
    #[error("the engine needs at least one voice, one mode and a positive sample rate (got {0})")]
    Config(String),
    /// The worker thread could not be spawned.
    #[error("cannot start the solver thread: {0}")]
    Thread(#[from] std::io::Error),
}

/// Starts an engine.
pub struct Engine;

impl Engine {
    /// Prepares the audio side and spawns the worker. Allocates (all of it, here).
    ///
    /// Sets faer's global parallelism to sequential: the solvers are written for the one
    /// worker thread, and faer's dense helpers that take no explicit [`faer::Par`] (the dense
    /// eigendecompositions of Rayleigh-Ritz, products written as operators) would otherwise
    /// run on rayon's pool, a thread per core competing with the host's audio threads, each
    /// reserving a matrix-product workspace sized by the CPU's cache (64 MB each here, 10.7 GB
    /// in all on a 16-core server, measured by the soak's heap count). The setting is this
    /// library's own (the plugin links its own faer).
    pub fn start(
        sample_rate_hz: f64,
        config: EngineConfig,
        voicing: Voicing,
        solvers: Vec<Box<dyn ModeSolver>>,
    ) -> Result<(AudioEngine, EngineControl), EngineError> {
        voicing.validate()?;
        if config.voices == 0
            || config.modes_per_voice == 0
            || config.max_object_modes == 0
            || !(sample_rate_hz.is_finite() && sample_rate_hz > 0.0)
        {
            return Err(EngineError::Config(format!(
                "{config:?} at {sample_rate_hz} Hz"
            )));
        }
        faer::set_global_parallelism(faer::Par::Seq);
        let stats = Arc::new(EngineStats::default());
        // Two slots each way: one object in flight while the audio side holds another.
        let (to_audio, incoming) = rtrb::RingBuffer::new(2);
        let (retire, retired) = rtrb::RingBuffer::new(2);
        let audio = AudioEngine::new(
            sample_rate_hz,
            EngineConfig {
                mode_budget: config.mode_budget.max(1),
                ..config
            },
            voicing,
            incoming,
            retire,
            stats.clone(),
        );
        let control = EngineControl::spawn(solvers, to_audio, retired, stats)?;
        Ok((audio, control))
    }
}

#[cfg(test)]
mod tests;
