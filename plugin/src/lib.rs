//! ModalForge as a VST3/CLAP instrument: MIDI notes strike a sculpted voxel object whose modes
//! come from the engine's worker (FEM), played by the wait-free engine.
//!
//! Where it sits: the host calls [`ModalForge::process`] on its audio thread; this crate turns
//! parameters into an engine [`Voicing`](modalforge::engine::Voicing) and MIDI into engine
//! events ([`keymap`]), and lets the engine's worker poll the parameters that need a re-solve
//! ([`solve_source`]), so the audio thread never takes a lock. The object persists with the
//! project (`#[persist = "object"]`, [`sculpt`]).
//!
//! Lifecycle: `activate` starts the engine (allocates, spawns the worker) unless one already
//! runs at that sample rate; `process` and `reset` never allocate (debug builds with the
//! `assert_process_allocs` feature abort if they do).
#![deny(missing_docs)]

pub mod editor;
pub mod error;
pub mod keymap;
pub mod materials;
pub mod params;
pub mod presets;
pub mod sculpt;
pub mod tuning;

use editor::{EditorLink, EditorWindow};
use keymap::KeyMap;
use materials::MaterialTable;
use modalforge::eigen::{EigenOptions, ModeCount, SolverKind};
use modalforge::engine::{
    AnswerSwitch, Answers, AudioEngine, Engine, EngineConfig, EngineControl, Event, KeptAnswers,
    ObjectRequest, Pitch, TimedEvent,
};
use modalforge::fem::ElementKind;
use modalforge::predictor::Predictor;
use nice_plug::prelude::*;
use nice_plug_egui::EguiEditorState;
use params::{AnswerChoice, ElementChoice, ModalForgeParams, SolverChoice};
use std::num::NonZeroU32;
use std::sync::atomic::Ordering;
use std::sync::Arc;

/// Most note events taken per block (more are dropped, never allocated for). nice-plug's own
/// input queue is sized the same (`INPUT_EVENT_CAPACITY`): its default of 1024 is a
/// `VecDeque` that grows, allocating on the audio thread, when a host delivers more in one
/// block (4096-sample blocks at 22.05 kHz with 4000 notes/s hold about 1500 events, the
/// host test's torture case). 8192 events at 4000 notes/s is a 1 s block at any rate.
const MAX_EVENTS: usize = 8192;

/// The key an editor audition strike plays on (outside MIDI's 0..=127).
pub const AUDITION_KEY: u8 = 200;

/// How long `activate` waits for the first solve.
const FIRST_SOLVE_WAIT: std::time::Duration = std::time::Duration::from_secs(5);

/// The plugin.
pub struct ModalForge {
    params: Arc<ModalForgeParams>,
    table: Arc<MaterialTable>,
    engine: Option<AudioEngine>,
    control: Option<Arc<EngineControl>>,
    keymap: KeyMap,
    events: Vec<TimedEvent>,
    mono: Vec<f32>,
    /// The side-chain input mixed to mono, for the resonator effect (sized with `mono`).
    side: Vec<f32>,
    link: Arc<EditorLink>,
    editor_state: Arc<EguiEditorState>,
    /// The neural predictor (the shipped weights); `None` when they cannot be loaded, and FEM
    /// answers alone.
    predictor: Option<Arc<Predictor>>,
    /// The Answers parameter as the worker's solvers read it.
    answers: AnswerSwitch,
}

impl Default for ModalForge {
    fn default() -> Self {
        Self {
            params: Arc::new(ModalForgeParams::default()),
            table: Arc::new(MaterialTable::new()),
            engine: None,
            control: None,
            keymap: KeyMap::default(),
            events: Vec::with_capacity(MAX_EVENTS),
            mono: Vec::new(),
            side: Vec::new(),
            link: Arc::new(EditorLink::default()),
            editor_state: EguiEditorState::from_size(
                nice_plug::editor::dpi::LogicalSize::new(
                    editor::WINDOW_SIZE.0,
                    editor::WINDOW_SIZE.1,
                ),
                1.0,
            ),
            predictor: match Predictor::shipped() {
                Ok(p) => Some(Arc::new(p)),
                Err(e) => {
                    nice_log!("{e}");
                    None
                }
            },
            answers: AnswerSwitch::default(),
        }
    }
}

/// The exact answers every instance in this process shares ([`KeptAnswers`]): a second
/// instance with the same object, an undo or a preset chosen again plays at once.
fn kept_answers() -> &'static KeptAnswers {
    static KEPT: std::sync::OnceLock<KeptAnswers> = std::sync::OnceLock::new();
    KEPT.get_or_init(KeptAnswers::new)
}

/// The request the parameters and the persisted object describe, or `None` if the object is
/// malformed (the previous one keeps playing). A persisted recording that is valid rides
/// along and is played instead of the shape; a malformed one is ignored (the shape plays).
pub fn object_request(params: &ModalForgeParams, table: &MaterialTable) -> Option<ObjectRequest> {
    let grid = params
        .object
        .read()
        .unwrap_or_else(|e| e.into_inner())
        .to_grid()
        .ok()?;
    Some(ObjectRequest {
        grid,
        element: match params.solver.element.value() {
            ElementChoice::Hex8i => ElementKind::Hex8Incompatible,
            ElementChoice::Hex27 => ElementKind::Hex27,
            ElementChoice::Hex27x2 => ElementKind::Hex27Blocks,
        },
        poisson_ratio: params.poisson_ratio(table),
        solver: match params.solver.kind.value() {
            SolverChoice::Auto => SolverKind::Auto,
            SolverChoice::Lanczos => SolverKind::Lanczos,
            SolverChoice::Lobpcg => SolverKind::Lobpcg,
        },
        options: EigenOptions {
            count: ModeCount::First(params.solver.modes.value().max(1) as usize),
            ..EigenOptions::default()
        },
        recording: params
            .recording
            .read()
            .unwrap_or_else(|e| e.into_inner())
            .as_ref()
            .filter(|r| r.validate().is_ok())
            .map(|r| Arc::new(r.clone())),
    })
}

/// The worker's request source: a new request whenever the object or a solve-relevant
/// parameter differs from what was last requested (runs on the worker thread).
pub fn solve_source(
    params: Arc<ModalForgeParams>,
    table: Arc<MaterialTable>,
    answers: AnswerSwitch,
) -> modalforge::engine::RequestSource {
    type Key = (
        u64,
        ElementKind,
        u64,
        SolverKind,
        usize,
        Answers,
        Option<u64>,
    );
    let mut last: Option<Key> = None;
    Box::new(move || {
        // A restored project's tuning reaches the audio thread's key table here (off it). A
        // damaged one plays 12-TET; the editor reports why when it loads one.
        let state = params
            .tuning
            .read()
            .unwrap_or_else(|e| e.into_inner())
            .clone();
        let _ = params.key_table.sync(state.as_ref());
        let r = object_request(&params, &table)?;
        let wanted = match params.solver.answers.value() {
            AnswerChoice::Auto => Answers::Auto,
            AnswerChoice::FemOnly => Answers::FemOnly,
            AnswerChoice::PredictorOnly => Answers::PredictorOnly,
        };
        answers.set(wanted);
        let count = match r.options.count {
            ModeCount::First(k) => k,
            ModeCount::Below(_) => 0,
        };
        let key = (
            r.grid.shape_hash(),
            r.element,
            r.poisson_ratio.to_bits(),
            r.solver,
            count,
            wanted,
            r.recording.as_ref().map(|rec| rec.fingerprint()),
        );
        if last == Some(key) {
            return None;
        }
        last = Some(key);
        Some(r)
    })
}

impl Plugin for ModalForge {
    const NAME: &'static str = "ModalForge";
    const VENDOR: &'static str = "ModalForge";
    const URL: &'static str = "https://example.invalid/modalforge";
    const EMAIL: &'static str = "modalforge@example.invalid";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");

    /// Stereo out, and a stereo side-chain input that the resonator effect plays through the
    /// object (hosts that connect nothing there feed silence, which costs nothing).
    const AUDIO_IO_LAYOUTS: &'static [AudioIOLayout] = &[AudioIOLayout {
        main_input_channels: None,
        main_output_channels: NonZeroU32::new(2),
        aux_input_ports: &[new_nonzero_u32(2)],
        names: PortNames {
            aux_inputs: &["Resonator input"],
            ..PortNames::const_default()
        },
        ..AudioIOLayout::const_default()
    }];

    const MIDI_INPUT: MidiConfig = MidiConfig::MidiCCs;
    const SAMPLE_ACCURATE_AUTOMATION: bool = false;
    const INPUT_EVENT_CAPACITY: usize = MAX_EVENTS;

    type Editor = nice_plug_egui::EguiEditor<EditorWindow>;
    type SysExMessage = ();
    type BackgroundTask = ();

    fn params(&self) -> Arc<dyn Params> {
        self.params.clone()
    }

    fn editor(&mut self, _executor: AsyncExecutor<Self>) -> Option<Self::Editor> {
        editor::create(
            self.params.clone(),
            self.table.clone(),
            self.link.clone(),
            self.editor_state.clone(),
        )
    }

    fn activate(
        &mut self,
        _layout: &AudioIOLayout,
        config: &BufferConfig,
        _context: &mut impl ActivateContext<Self>,
    ) -> bool {
        let rate = config.sample_rate as f64;
        self.link
            .sample_rate_bits
            .store(rate.to_bits(), Ordering::Relaxed);
        self.mono = vec![0.0; config.max_buffer_size as usize];
        self.side = vec![0.0; config.max_buffer_size as usize];
        if self
            .engine
            .as_ref()
            .is_some_and(|e| e.sample_rate_hz() == rate)
        {
            return true;
        }
        let voicing = self.params.voicing(&self.table, 1.0, 1.0);
        let started = Engine::start(
            rate,
            EngineConfig::default(),
            voicing,
            modalforge::engine::interactive_solvers(
                self.predictor.clone(),
                self.answers.clone(),
                kept_answers(),
            ),
        );
        match started {
            Ok((audio, control)) => {
                control.set_request_source(solve_source(
                    self.params.clone(),
                    self.table.clone(),
                    self.answers.clone(),
                ));
                // The first object (a fraction of a second for the default shape) is there
                // before the first note; a slow one keeps solving in the background.
                control.wait_for_solves(1, FIRST_SOLVE_WAIT);
                let control = Arc::new(control);
                *self.link.control.lock().unwrap_or_else(|e| e.into_inner()) =
                    Some(control.clone());
                self.engine = Some(audio);
                self.control = Some(control);
                true
            }
            Err(e) => {
                nice_log!("modalforge: cannot start the engine: {e}");
                false
            }
        }
    }

    fn reset(&mut self) {
        if let Some(e) = self.engine.as_mut() {
            e.reset();
        }
        self.keymap.reset();
    }

    fn process(
        &mut self,
        buffer: &mut Buffer,
        aux: &mut AuxiliaryBuffers,
        context: &mut impl ProcessContext<Self>,
    ) -> ProcessStatus {
        let n = buffer.samples();
        let Some(engine) = self.engine.as_mut() else {
            for ch in buffer.as_slice() {
                ch.fill(0.0);
            }
            return ProcessStatus::Normal;
        };
        self.events.clear();
        // Strikes the editor asked for (a click with the Hit tool): at the object's own size.
        if self.link.audition.swap(0, Ordering::Relaxed) > 0 {
            self.events.push(TimedEvent {
                offset: 0,
                event: Event::Strike {
                    key: AUDITION_KEY,
                    pitch: Pitch::Ratio(1.0),
                    velocity: 0.8,
                    hit: None,
                    hardness_s: None,
                },
            });
        }
        while let Some(event) = context.next_event() {
            self.keymap
                .translate(&event, &self.params, engine, &mut self.events, MAX_EVENTS);
        }
        let (bend, wheel) = self.keymap.controllers();
        let voicing = self.params.voicing(&self.table, bend, wheel);
        // A voicing the engine refuses (cannot happen from these ranges) keeps the old one.
        let _ = engine.set_voicing(voicing);
        engine.set_mode_budget(self.params.play.mode_budget.value().max(1) as usize);
        let n = n.min(self.mono.len());
        let mono = &mut self.mono[..n];
        engine.process(mono, &self.events);
        // The resonator effect: the side-chain, mixed to mono, through the object.
        let side = &mut self.side[..n];
        side.fill(0.0);
        if let Some(input) = aux.inputs.first_mut() {
            let channels = input.as_slice();
            let scale = 1.0 / channels.len().max(1) as f32;
            for ch in channels.iter() {
                for (s, x) in side.iter_mut().zip(ch.iter()) {
                    *s += scale * x;
                }
            }
        }
        engine.resonate(side, mono, &self.params.resonator.settings());
        for ch in buffer.as_slice() {
            let len = ch.len().min(n);
            ch[..len].copy_from_slice(&mono[..len]);
        }
        ProcessStatus::KeepAlive
    }
}

impl ClapPlugin for ModalForge {
    const CLAP_ID: &'static str = "org.modalforge.instrument";
    const CLAP_DESCRIPTION: Option<&'static str> =
        Some("Physically based impact sounds: strike a sculpted voxel object");
    const CLAP_MANUAL_URL: Option<&'static str> = None;
    const CLAP_SUPPORT_URL: Option<&'static str> = None;
    const CLAP_FEATURES: &'static [ClapFeature] = &[
        ClapFeature::Instrument,
        ClapFeature::Synthesizer,
        ClapFeature::Stereo,
    ];
}

impl Vst3Plugin for ModalForge {
    const VST3_CLASS_ID: [u8; 16] = *b"ModalForgeStrike";
    const VST3_SUBCATEGORIES: &'static [Vst3SubCategory] =
        &[Vst3SubCategory::Instrument, Vst3SubCategory::Synth];
}

nice_export_clap!(ModalForge);
nice_export_vst3!(ModalForge);

#[cfg(test)]
mod tests;
