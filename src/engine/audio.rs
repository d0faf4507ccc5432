//! The audio side of the engine: voices, strikes, voicing changes, the mode budget, object
//! swaps. Wait-free: [`AudioEngine::process`] never allocates, frees, locks, blocks or logs.
//!
//! Where it sits: the plugin's (or the CLI's) audio callback owns the [`AudioEngine`]; solved
//! objects arrive from [`super::worker`] through an `rtrb` ring and the replaced ones go back
//! through a second ring, to be freed on the worker. Lifecycle: [`super::Engine::start`]
//! allocates everything (voices with their banks at full capacity, all scratch); `process`,
//! `set_voicing` and `reset` never allocate.
//!
//! Voices: a strike on a key that is ringing adds to the same bank (linear superposition, seed
//! 000 eq. 3); a new key takes a free voice, or steals the quietest one, which fades out over
//! [`STEAL_FADE_SAMPLES`] in a spare voice. A voicing change re-tunes every ringing mode at the
//! start of the next block, keeping its phase and amplitude: damping and E/rho/size act on notes
//! already ringing, without a click; a hit position or mallet applies from the next strike (a
//! strike that has happened cannot move). Per-note expression ([`super::Expression`]) does the
//! same to one key's voice: a tuning plays it at another size, pressure adds decay, volume
//! scales it (ramped over a span). A new object is used from the next strike on; modes
//! struck on the old one ring out unchanged, so a swap is seamless.
//!
//! Budget: at most `mode_budget` modes ring in all voices together. When a strike exceeds it,
//! the quietest modes across all voices are dropped first; modes 100 dB below their voice's
//! peak are dropped as they decay, and a voice with no mode left is freed.

mod allocation;

use super::object::SolvedObject;
use super::resonator::{ContactForce, InputResonator, ResonatorSettings};
use super::voice::{SlotMode, Voice};
use super::voicing::{tune, Voicing, VoicingError};
use super::{
    EngineConfig, EngineStats, Event, Expression, Pitch, TimedEvent, MAX_TUNING_SEMITONES,
};
use crate::synth::SimdBackend;
use rtrb::{Consumer, Producer};
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Instant;

/// Samples over which a stolen voice fades out.
pub const STEAL_FADE_SAMPLES: usize = 64;

/// Voices beyond the configured count, where new strikes play while stolen voices fade.
const STEAL_SPARES: usize = 4;

/// Modes whose amplitude falls this far below their voice's peak are dropped (-100 dB).
const SILENCE_RATIO: f64 = 1e-5;

/// Blocks between silence sweeps.
const SWEEP_BLOCKS: u32 = 8;

/// The audio thread's engine.
pub struct AudioEngine {
    sample_rate_hz: f64,
    config: EngineConfig,
    voicing: Voicing,
    pending_voicing: bool,
    object: Option<Box<SolvedObject>>,
    incoming: Consumer<Box<SolvedObject>>,
    retired: Producer<Box<SolvedObject>>,
    voices: Vec<Voice>,
    // Per key, the voice that last sounded it: checked before use, so never trusted stale
    // (`sounding_voice`). An MPE controller sends an expression per note and dimension, 192 a
    // block in the engine bench; a scan of every voice for each was 25k checks a block.
    key_hint: [u16; 256],
    // Scratch, sized at start.
    struck: Vec<SlotMode>,
    gains: Vec<f64>,
    all_amps: Vec<f64>,
    render: Vec<f32>,
    gain_now: f64,
    /// Level normalisation factor (1 when off).
    level_scale: f64,
    /// The resonator effect ([`AudioEngine::resonate`]) and the size ratio it plays at: the
    /// last key struck's.
    resonator: InputResonator,
    last_pitch: f64,
    /// The held key scraping the object, its velocity and pressure ([`Event::Contact`]).
    contact: Option<(u8, f64, f64)>,
    blocks: u32,
    stats: Arc<EngineStats>,
    #[cfg(test)]
    budget_split: (f64, f64),
}

impl AudioEngine {
    pub(super) fn new(
        sample_rate_hz: f64,
        config: EngineConfig,
        voicing: Voicing,
        incoming: Consumer<Box<SolvedObject>>,
        retired: Producer<Box<SolvedObject>>,
        stats: Arc<EngineStats>,
    ) -> Self {
        let backend = SimdBackend::detect();
        let voices = (0..config.voices + STEAL_SPARES)
            .map(|_| Voice::new(config.modes_per_voice, sample_rate_hz, backend))
            .collect::<Vec<_>>();
        Self {
            sample_rate_hz,
            voicing,
            pending_voicing: false,
            object: None,
            incoming,
            retired,
            struck: Vec::with_capacity(config.max_object_modes),
            gains: vec![0.0; config.modes_per_voice],
            all_amps: vec![0.0; (config.voices + STEAL_SPARES) * config.modes_per_voice],
            render: vec![0.0; super::BLOCK_SAMPLES],
            gain_now: voicing.output_gain,
            level_scale: 1.0,
            resonator: InputResonator::new(sample_rate_hz, backend),
            last_pitch: 1.0,
            contact: None,
            blocks: 0,
            #[cfg(test)]
            budget_split: (0.0, 0.0),
            voices,
            key_hint: [0; 256],
            config,
            stats,
        }
    }

    /// The sample rate the engine was started at.
    pub fn sample_rate_hz(&self) -> f64 {
        self.sample_rate_hz
    }

    /// The voicing in use (or about to be, at the next block).
    pub fn voicing(&self) -> &Voicing {
        &self.voicing
    }

    /// Sets the voicing; ringing modes follow at the start of the next block. An invalid voicing
    /// is refused and the previous one kept. Never allocates.
    pub fn set_voicing(&mut self, voicing: Voicing) -> Result<(), VoicingError> {
        voicing.validate()?;
        if voicing != self.voicing {
            self.pending_voicing = true;
            self.voicing = voicing;
        }
        Ok(())
    }

    /// The mode budget: most modes ringing in all voices together (at least 1).
    pub fn set_mode_budget(&mut self, modes: usize) {
        self.config.mode_budget = modes.max(1);
    }

    /// The pitch the object sounds at its own size under the current voicing, Hz: the
    /// energy-weighted centre of its lowest cluster of partials ([`super::pitch`]), the
    /// reference of the "pitch" key mapping. Weights are the modes' energies at the last
    /// strike's hit point (equal before the first strike). Never allocates.
    ///
    /// (A pitch-mode strike first makes the forces its own hit's.) The partials count whatever
    /// the sample rate: a small object whose own modes all lie above Nyquist still has its
    /// pitch, and a key transposes them down to where they play (at 22.05 kHz a 2 cm steel
    /// bowl rang nothing in pitch mode, and the key's pitch depended on the rate).
    pub fn fundamental_hz(&self) -> Option<f64> {
        let obj = self.object.as_ref()?;
        let partials = own_size_partials(&self.voicing, obj, f64::INFINITY)
            .map(|(f, force)| (f, force * force));
        super::pitch::cluster_pitch_hz(partials)
    }

    /// Modes ringing now.
    pub fn active_modes(&self) -> usize {
        self.voices.iter().map(|v| v.modes.len()).sum()
    }

    /// Whether a solved object has arrived.
    pub fn has_object(&self) -> bool {
        self.object.is_some()
    }

    /// The generation of the object being played (it increases with every answer the worker
    /// delivers), and the solver that made it.
    pub fn object_generation(&self) -> Option<(u64, &'static str)> {
        self.object.as_ref().map(|o| (o.generation, o.solver))
    }

    /// Silences every voice (the object stays).
    pub fn reset(&mut self) {
        self.voices.iter_mut().for_each(Voice::release);
    }

    /// Renders `out.len()` samples (overwriting `out`), applying `events` (sorted by offset,
    /// offsets within `out`): strikes, mutes and contacts sample-accurately, expressions at the
    /// start of the span they fall in (at most 64 samples early; see the loop). Never
    /// allocates, frees, locks or blocks.
    pub fn process(&mut self, out: &mut [f32], events: &[TimedEvent]) {
        let started = Instant::now();
        let arrived = self.receive();
        let revoiced = std::mem::take(&mut self.pending_voicing);
        if revoiced {
            for v in self.voices.iter_mut().filter(|v| v.key.is_some()) {
                v.revoice(&self.voicing);
            }
        }
        if arrived || revoiced {
            self.update_level_reference();
        }
        if self.active_modes() == 0 {
            // Nothing rings: a gain change needs no ramp (a ramp would soften this block's
            // strikes instead).
            self.gain_now = self.voicing.output_gain * self.level_scale;
        }
        out.fill(0.0);
        let mut done = 0;
        let mut next_event = 0;
        let is_expression = |e: &TimedEvent| matches!(e.event, Event::Expression { .. });
        while done < out.len() {
            // A span runs to the next event other than an expression. Expressions do not
            // split the block: one that falls inside a span takes effect at its start (at
            // most a span, 1.3 ms at 48 kHz, early; a retune keeps every mode's phase), and a
            // voice's expressions in a span re-tune it once. An MPE controller sends one per
            // note and dimension every few milliseconds; splitting at each cost a render call
            // per event and a re-tune of every mode per event.
            let until = events[next_event..]
                .iter()
                .find(|e| e.offset > done && !is_expression(e))
                .map_or(out.len(), |e| e.offset.min(out.len()));
            let end = until
                .max(done + 1)
                .min(out.len())
                .min(done + super::BLOCK_SAMPLES);
            while let Some(e) = events.get(next_event) {
                if e.offset > done && !(is_expression(e) && e.offset < end) {
                    break;
                }
                self.apply_event(&e.event);
                next_event += 1;
            }
            self.retune_expressed();
            self.render_span(&mut out[done..end]);
            done = end;
        }
        // Events at or past the end of the block still happen (at its last sample).
        for e in &events[next_event..] {
            self.apply_event(&e.event);
        }
        self.retune_expressed();
        // No subnormal output: hosts and validators reject it, and it is slow downstream.
        for x in out.iter_mut() {
            if x.abs() < f32::MIN_POSITIVE {
                *x = 0.0;
            }
        }
        self.finish_block(out, started);
    }

    /// The resonator effect: adds `input` (mono, e.g. a side-chain) driving the object's modes
    /// to `out`, at the voicing's material, damping and hit point and the pitch of the last key
    /// struck ([`super::resonator`]). Call after [`AudioEngine::process`] on the same block.
    /// Never allocates, locks or blocks.
    pub fn resonate(&mut self, input: &[f32], out: &mut [f32], settings: &ResonatorSettings) {
        if let Some(obj) = self.object.as_mut() {
            if obj.update_forces(&self.voicing.hit).is_ok() {
                self.resonator.retune(obj, &self.voicing, self.last_pitch);
            }
        }
        let gain = self.voicing.output_gain as f32;
        let contact = self
            .contact
            .map(|(_, velocity, pressure)| ContactForce::scrape(velocity, pressure));
        self.resonator.process(input, out, settings, gain, contact);
        for x in out.iter_mut() {
            if x.abs() < f32::MIN_POSITIVE {
                *x = 0.0;
            }
        }
    }

    /// The resonator effect's bank (what it plays, for tests and the editor).
    pub fn resonator(&self) -> &InputResonator {
        &self.resonator
    }

    /// Takes newly solved objects while the retire ring has room for the one each replaces;
    /// true if one arrived.
    fn receive(&mut self) -> bool {
        let mut arrived = false;
        while self.retired.slots() > 0 {
            let Ok(obj) = self.incoming.pop() else { break };
            self.stats
                .generation
                .store(obj.generation, Ordering::Relaxed);
            arrived = true;
            if let Some(old) = self.object.replace(obj) {
                if let Err(rtrb::PushError::Full(old)) = self.retired.push(old) {
                    // Unreachable (a slot was free and only this thread fills it). Leaking is
                    // the lesser evil: freeing here would break the audio thread's contract.
                    std::mem::forget(old);
                }
            }
        }
        arrived
    }

    /// The output scale of level normalisation: `NORMALISED_PEAK` over the summed mode
    /// amplitudes of a velocity-1 impulse at the voicing's hit (an upper bound of its peak).
    fn update_level_reference(&mut self) {
        self.level_scale = 1.0;
        if !self.voicing.normalise {
            return;
        }
        let Some(obj) = self.object.as_mut() else {
            return;
        };
        if obj.update_forces(&self.voicing.hit).is_err() {
            return;
        }
        let h = self.voicing.voxel_size_m(obj.extent, 1.0);
        let summed = |rate: f64| -> f64 {
            own_size_partials(&self.voicing, obj, rate)
                .map(|(f, force)| self.voicing.modal_gain(force, h, f).abs())
                .sum()
        };
        // An object that rings only above Nyquist at its own size (heard through the pitch
        // mapping, transposed down) is levelled by all its partials.
        let mut sum = summed(self.sample_rate_hz);
        if sum == 0.0 {
            sum = summed(f64::INFINITY);
        }
        if sum.is_finite() && sum > 0.0 {
            self.level_scale = super::voicing::NORMALISED_PEAK / sum;
        }
    }

    /// Re-tunes the voices whose tuning or pressure an expression changed (once each).
    fn retune_expressed(&mut self) {
        let voicing = self.voicing;
        for v in self.voices.iter_mut().filter(|v| v.retune_pending) {
            v.express(&voicing);
        }
    }

    fn apply_event(&mut self, event: &Event) {
        if !matches!(event, Event::Expression { .. }) {
            // A strike or a mute acts on voices at their expressed tuning.
            self.retune_expressed();
        }
        match *event {
            Event::Strike {
                key,
                pitch,
                velocity,
                hit,
                hardness_s,
            } => {
                let ratio = match pitch {
                    Pitch::Ratio(r) => Some(r),
                    Pitch::Fundamental(f) => {
                        // The pitch's energy weights are this strike's (cached per hit point;
                        // a bad hit is refused by `strike` below).
                        let at = hit.unwrap_or(self.voicing.hit);
                        if let Some(o) = self.object.as_mut() {
                            let _ = o.update_forces(&at);
                        }
                        self.fundamental_hz().map(|f0| f / f0)
                    }
                };
                match ratio {
                    Some(r) => self.strike(key, r, velocity, hit, hardness_s),
                    None => {
                        self.stats.dropped_strikes.fetch_add(1, Ordering::Relaxed);
                    }
                }
            }
            Event::Mute { key } => {
                for v in self.voices.iter_mut().filter(|v| v.key == Some(key)) {
                    v.muted = true;
                    v.revoice(&self.voicing);
                }
            }
            Event::Expression { key, expression } => self.express(key, expression),
            Event::Contact {
                key,
                pitch,
                velocity,
            } => {
                let ratio = match pitch {
                    Pitch::Ratio(r) => Some(r),
                    Pitch::Fundamental(f) => {
                        let hit = self.voicing.hit;
                        if let Some(o) = self.object.as_mut() {
                            let _ = o.update_forces(&hit);
                        }
                        self.fundamental_hz().map(|f0| f / f0)
                    }
                };
                match ratio {
                    Some(r) if r.is_finite() && r > 0.0 && velocity.is_finite() => {
                        self.last_pitch = r;
                        self.contact = Some((key, velocity.clamp(0.0, 1.0), 0.0));
                    }
                    _ => {
                        self.stats.dropped_strikes.fetch_add(1, Ordering::Relaxed);
                    }
                }
            }
            Event::ContactEnd { key } => {
                if self.contact.is_some_and(|(k, _, _)| k == key) {
                    self.contact = None;
                }
            }
            Event::AllOff => {
                self.contact = None;
                self.reset();
            }
        }
    }

    /// A per-note expression on `key`'s sounding voice (not one fading out after a steal).
    /// Out-of-range values are clamped; a NaN is ignored.
    fn express(&mut self, key: u8, expression: Expression) {
        if let (Some((k, _, pressure)), Expression::Pressure(p)) = (&mut self.contact, expression) {
            if *k == key && p.is_finite() {
                *pressure = p.clamp(0.0, 1.0);
            }
        }
        if let Some(v) = self.sounding_voice(key) {
            let v = &mut self.voices[v];
            match expression {
                Expression::TuningSemitones(st) if st.is_finite() => {
                    let st = st.clamp(-MAX_TUNING_SEMITONES, MAX_TUNING_SEMITONES);
                    v.bend = (st / 12.0).exp2();
                    v.retune_pending = true;
                }
                Expression::Pressure(p) if p.is_finite() => {
                    v.pressure = p.clamp(0.0, 1.0);
                    v.retune_pending = true;
                }
                Expression::Volume(g) if g.is_finite() => v.volume = g.clamp(0.0, 4.0),
                _ => {}
            }
        }
    }

    /// Renders every voice into `out` (at most one block).
    fn render_span(&mut self, out: &mut [f32]) {
        let n = out.len();
        let tmp = &mut self.render[..n];
        for v in self.voices.iter_mut().filter(|v| !v.modes.is_empty()) {
            v.bank.render(tmp);
            // The note's volume, ramped over the span from where it was.
            let (from, to) = (v.volume_now as f32, v.volume as f32);
            v.volume_now = v.volume;
            let step = (to - from) / n as f32;
            if v.fade_left > 0 {
                for (k, (o, &x)) in out.iter_mut().zip(tmp.iter()).enumerate() {
                    let g = v.fade_left as f32 / STEAL_FADE_SAMPLES as f32;
                    *o += g * (from + step * (k + 1) as f32) * x;
                    v.fade_left = v.fade_left.saturating_sub(1);
                }
                if v.fade_left == 0 {
                    v.release();
                }
            } else if from == 1.0 && to == 1.0 {
                for (o, &x) in out.iter_mut().zip(tmp.iter()) {
                    *o += x;
                }
            } else {
                for (k, (o, &x)) in out.iter_mut().zip(tmp.iter()).enumerate() {
                    *o += (from + step * (k + 1) as f32) * x;
                }
            }
        }
    }

    /// Output gain (ramped over the block), silence sweep, statistics.
    fn finish_block(&mut self, out: &mut [f32], started: Instant) {
        let target = self.voicing.output_gain * self.level_scale;
        let n = out.len().max(1) as f64;
        for (k, o) in out.iter_mut().enumerate() {
            let g = self.gain_now + (target - self.gain_now) * (k + 1) as f64 / n;
            *o = (*o as f64 * g) as f32;
            if !o.is_finite() {
                *o = 0.0;
            }
        }
        self.gain_now = target;
        self.blocks = self.blocks.wrapping_add(1);
        if self.blocks.is_multiple_of(SWEEP_BLOCKS) {
            for v in self.voices.iter_mut().filter(|v| !v.modes.is_empty()) {
                // A glide no expression has moved since the last sweep settles on its
                // exact anchors (the glide's f32 state has none).
                if v.bank.is_gliding() && !v.expressed {
                    v.revoice(&self.voicing);
                }
                v.expressed = false;
                v.measure();
                v.drop_below(SILENCE_RATIO * v.peak);
                if v.modes.is_empty() {
                    v.release();
                }
            }
        }
        let s = &self.stats;
        s.active_modes
            .store(self.active_modes() as u64, Ordering::Relaxed);
        s.active_voices.store(
            self.voices.iter().filter(|v| !v.modes.is_empty()).count() as u64,
            Ordering::Relaxed,
        );
        let busy = started.elapsed().as_secs_f64();
        let span = out.len() as f64 / self.sample_rate_hz;
        if span > 0.0 {
            // Exponential average over ~16 blocks.
            let old = f64::from_bits(s.load_bits.load(Ordering::Relaxed));
            let load = old + (busy / span - old) / 16.0;
            s.load_bits.store(load.to_bits(), Ordering::Relaxed);
        }
    }

    /// Test access: (frequency, decay) of every mode of the voice playing `key`.
    #[cfg(test)]
    pub(super) fn voice_tunings(&self, key: u8) -> Vec<(f64, f64)> {
        self.voices
            .iter()
            .find(|v| v.key == Some(key) && v.fade_left == 0)
            .map(|v| (0..v.modes.len()).map(|j| v.bank.tuning(j)).collect())
            .unwrap_or_default()
    }

    /// Test access: whether the voice playing `key` is gliding (its last re-tune was the
    /// cheap shared-ratio one, [`crate::synth::OscillatorBank::glide`]).
    #[cfg(test)]
    pub(super) fn voice_glides(&self, key: u8) -> bool {
        self.voices
            .iter()
            .any(|v| v.key == Some(key) && v.fade_left == 0 && v.bank.is_gliding())
    }

    /// Test access: voices ringing.
    #[cfg(test)]
    pub(super) fn stats_voices(&self) -> usize {
        self.voices.iter().filter(|v| !v.modes.is_empty()).count()
    }

    /// Test access: grid extent of the object in use.
    #[cfg(test)]
    pub(super) fn object_extent(&self) -> Option<usize> {
        self.object.as_ref().map(|o| o.extent)
    }

    /// Test access: the quietest kept and the loudest dropped amplitude of the last budget cut.
    #[cfg(test)]
    pub(super) fn last_budget_split(&self) -> (f64, f64) {
        self.budget_split
    }
}

/// The playable modes of `obj` at its own size under `voicing`: (damped frequency in Hz, the
/// reference modal force at the cached hit). Never allocates.
fn own_size_partials<'a>(
    voicing: &'a Voicing,
    obj: &'a SolvedObject,
    sample_rate_hz: f64,
) -> impl Iterator<Item = (f64, f64)> + 'a {
    let h = voicing.voxel_size_m(obj.extent, 1.0);
    obj.basis
        .eigenvalues()
        .iter()
        .zip(&obj.forces)
        .enumerate()
        .filter_map(move |(i, (&l, &force))| {
            let ratio = obj.basis.decay_ratio(i);
            let (f, _) = tune(voicing, l, h, ratio, 0.0, sample_rate_hz)?;
            Some((f, force))
        })
}
