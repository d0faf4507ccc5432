//! MIDI to engine events: note-on strikes (velocity sets force and mallet hardness), the two key
//! mappings (pitch: each key's frequency from the tuning's table, [`crate::tuning`]), note-off
//! mute, and expression:
//! - per-note expressions from CLAP and VST3 hosts, always: tuning retunes the note (the object
//!   played at another size, [`Expression::TuningSemitones`]), pressure presses on it
//!   ([`Expression::Pressure`]), volume scales it, brightness sets the key's next strike: by
//!   the "Brightness Moves" parameter its mallet (a brighter note, a shorter contact) or its
//!   hit point ([`brightened_hit`]: from the centre to the edge);
//! - MIDI channel messages, by the "MIDI Expression" parameter: "Classic", pitch bend scales
//!   every note's damping and the mod wheel the contact time; "MPE" (lower zone), the MIDI
//!   Polyphonic Expression specification's mapping: channel 1 is the master, whose pitch bend
//!   moves every note by up to 2 semitones; each of channels 2-16 carries one note, whose
//!   channel pitch bend, channel pressure and CC74 are that note's tuning (up to the bend
//!   range), pressure and brightness. A member channel's controllers sent before its note-on
//!   (as MPE controllers do) apply from the strike.
//!
//! Where it sits: called by [`crate::ModalForge::process`] for every host event; never
//! allocates (events go into a vector with fixed capacity).

use crate::params::{BrightnessTarget, HeldNote, KeyMapping, MidiExpression, ModalForgeParams};
use modalforge::engine::{AudioEngine, Event, Expression, HitPoint, Pitch, TimedEvent};
use nice_plug::midi::{Channel, Key};
use nice_plug::prelude::*;

/// Lowest key of the "positions" mapping (C2); keys below wrap to it.
pub const POSITIONS_FIRST_KEY: u8 = 36;

/// Keys per row of hit points in the "positions" mapping (one octave).
const ROW_KEYS: u8 = 12;

/// Rows of hit points (five octaves).
const ROWS: u8 = 5;

/// Pitch bend spans damping x1/4 .. x4; the mod wheel lengthens the contact up to x10.
const BEND_DAMPING_RANGE: f64 = 4.0;
const WHEEL_HARDNESS_RANGE: f64 = 10.0;

/// MPE's lower-zone master channel (MIDI channel 1).
const MPE_MASTER: u8 = 0;
/// Semitones of the master channel's full pitch bend (the MPE specification's default).
const MPE_MASTER_BEND_SEMITONES: f64 = 2.0;
/// MPE's brightness ("timbre") controller.
const CC_BRIGHTNESS: u8 = 74;
/// Brightness 0 to 1 moves the contact time over x4 .. x1/4 (0.5: as set).
const BRIGHTNESS_HARDNESS_RANGE: f64 = 4.0;

/// The hit point (fractions of the object's box) that `brightness` makes of the set point
/// `set`: along the line from the top view's centre `(0.5, 0.5)` through `set`, at 0 the
/// centre, at 0.5 `set` itself, at 1 the box's edge; linear in between, the height kept. (A
/// plate struck at its centre rings only its symmetric modes; towards a free edge nearly all
/// of them.) A set point at the centre moves along x.
pub fn brightened_hit(set: [f64; 3], brightness: f64) -> [f64; 3] {
    let b = brightness.clamp(0.0, 1.0);
    let (dx, dy) = (set[0] - 0.5, set[1] - 0.5);
    let from_centre = dx.hypot(dy);
    let (ux, uy) = if from_centre > 1e-9 {
        (dx / from_centre, dy / from_centre)
    } else {
        (1.0, 0.0)
    };
    // How far the box's edge is along (ux, uy).
    let edge = [ux, uy]
        .iter()
        .filter(|u| u.abs() > 1e-12)
        .map(|u| 0.5 / u.abs())
        .fold(f64::INFINITY, f64::min);
    let t = if b <= 0.5 {
        from_centre * 2.0 * b
    } else {
        from_centre + (edge - from_centre) * (2.0 * b - 1.0)
    };
    [0.5 + ux * t, 0.5 + uy * t, set[2]]
}

/// Controller state carried between blocks.
#[derive(Clone, Copy, Debug)]
pub struct KeyMap {
    bend: f64,
    wheel: f64,
    /// MPE: the engine key of the note each channel last started.
    channel_key: [Option<u8>; 16],
    /// MPE: each channel's pitch bend, -1 to 1.
    channel_bend: [f64; 16],
    /// MPE: each channel's pressure, 0 to 1.
    channel_pressure: [f64; 16],
    /// MPE: each channel's brightness (CC74), 0 to 1.
    channel_brightness: [f64; 16],
    /// Note expressions: each key's brightness for its next strike, 0 to 1.
    key_brightness: [f64; 128],
}

impl Default for KeyMap {
    fn default() -> Self {
        Self {
            bend: 0.5,
            wheel: 0.0,
            channel_key: [None; 16],
            channel_bend: [0.0; 16],
            channel_pressure: [0.0; 16],
            channel_brightness: [0.5; 16],
            key_brightness: [0.5; 128],
        }
    }
}

/// Appends `event` at `offset` while `out` holds fewer than `cap` (never allocates).
fn emit(out: &mut Vec<TimedEvent>, cap: usize, offset: usize, event: Event) {
    if out.len() < cap {
        out.push(TimedEvent { offset, event });
    }
}

impl KeyMap {
    /// Back to centred controllers.
    pub fn reset(&mut self) {
        *self = Self::default();
    }

    /// Damping multiplier from pitch bend and contact-time multiplier from the mod wheel.
    pub fn controllers(&self) -> (f64, f64) {
        (
            BEND_DAMPING_RANGE.powf(2.0 * self.bend - 1.0),
            WHEEL_HARDNESS_RANGE.powf(self.wheel),
        )
    }

    /// Where key `k` strikes in the "positions" mapping: octaves are rows along y, the twelve
    /// keys of an octave columns along x, on the top face.
    pub fn position_of(key: u8) -> [f64; 3] {
        let k = key.saturating_sub(POSITIONS_FIRST_KEY) % (ROW_KEYS * ROWS);
        let (col, row) = (k % ROW_KEYS, k / ROW_KEYS);
        [
            (col as f64 + 0.5) / ROW_KEYS as f64,
            (row as f64 + 0.5) / ROWS as f64,
            1.0,
        ]
    }

    /// Appends the engine events for one host event (at most `cap` in `out`).
    pub fn translate<S>(
        &mut self,
        event: &NoteEvent<S>,
        params: &ModalForgeParams,
        engine: &AudioEngine,
        out: &mut Vec<TimedEvent>,
        cap: usize,
    ) {
        let offset = event.timing() as usize;
        let mpe = params.expression.midi.value() == MidiExpression::Mpe;
        let engine_key = |k: u8| match params.play.mapping.value() {
            KeyMapping::Pitch => k,
            // One bank for all positions: strikes superpose on the object at its own size.
            KeyMapping::Positions => 0,
        };
        let member = |channel: Channel| {
            channel
                .number()
                .filter(|&c| mpe && c != MPE_MASTER)
                .map(usize::from)
        };
        // CLAP and VST3 note expressions, whatever the MIDI mode.
        let note_expression = match *event {
            NoteEvent::PolyTuning {
                key: Key::Number(k),
                tuning,
                ..
            } => Some((k, Expression::TuningSemitones(tuning as f64))),
            NoteEvent::PolyPressure {
                key: Key::Number(k),
                pressure,
                ..
            } => Some((k, Expression::Pressure(pressure as f64))),
            NoteEvent::PolyVolume {
                key: Key::Number(k),
                gain,
                ..
            } => Some((k, Expression::Volume(gain as f64))),
            _ => None,
        };
        if let Some((k, expression)) = note_expression {
            let key = engine_key(k);
            emit(out, cap, offset, Event::Expression { key, expression });
            return;
        }
        match *event {
            NoteEvent::NoteOn {
                key: Key::Number(k),
                channel,
                velocity,
                ..
            } => {
                let brightness = match member(channel) {
                    Some(c) => self.channel_brightness[c],
                    None => self.key_brightness[k as usize],
                };
                let Some(strike) = Self::strike(k, velocity as f64, brightness, params, engine)
                else {
                    return;
                };
                let strike = match (params.resonator.held.value(), strike) {
                    // A held key scrapes: the same key and pitch, as a contact.
                    (
                        HeldNote::Scrape,
                        Event::Strike {
                            key,
                            pitch,
                            velocity,
                            ..
                        },
                    ) => Event::Contact {
                        key,
                        pitch,
                        velocity: velocity.clamp(0.0, 1.0),
                    },
                    (_, strike) => strike,
                };
                emit(out, cap, offset, strike);
                if let Some(c) = member(channel) {
                    // The channel's controllers, set before the note, apply from its strike.
                    self.channel_key[c] = Some(engine_key(k));
                    let key = engine_key(k);
                    let tuning = self.mpe_semitones(c, params);
                    if tuning != 0.0 {
                        let expression = Expression::TuningSemitones(tuning);
                        emit(out, cap, offset, Event::Expression { key, expression });
                    }
                    if self.channel_pressure[c] > 0.0 {
                        let expression = Expression::Pressure(self.channel_pressure[c]);
                        emit(out, cap, offset, Event::Expression { key, expression });
                    }
                }
            }
            NoteEvent::NoteOff {
                key: Key::Number(k),
                ..
            } if params.resonator.held.value() == HeldNote::Scrape => {
                emit(out, cap, offset, Event::ContactEnd { key: engine_key(k) });
            }
            NoteEvent::NoteOff { key, .. } if params.play.note_off_mute.value() => {
                let event = match key {
                    Key::Number(k) => Event::Mute { key: engine_key(k) },
                    Key::Wildcard => Event::AllOff,
                };
                emit(out, cap, offset, event);
            }
            NoteEvent::Choke { .. } => emit(out, cap, offset, Event::AllOff),
            NoteEvent::PolyBrightness {
                key: Key::Number(k),
                brightness,
                ..
            } => self.key_brightness[k as usize] = (brightness as f64).clamp(0.0, 1.0),
            NoteEvent::MidiPitchBend { value, channel, .. } if mpe => {
                let c = channel as usize % 16;
                self.channel_bend[c] = (2.0 * value as f64 - 1.0).clamp(-1.0, 1.0);
                // The master's bend moves every note; a member's, its own.
                for m in 0..16 {
                    if m == MPE_MASTER as usize || (c != MPE_MASTER as usize && m != c) {
                        continue;
                    }
                    if let Some(key) = self.channel_key[m] {
                        let expression = Expression::TuningSemitones(self.mpe_semitones(m, params));
                        emit(out, cap, offset, Event::Expression { key, expression });
                    }
                }
            }
            NoteEvent::MidiPitchBend { value, .. } => {
                self.bend = (value as f64).clamp(0.0, 1.0);
            }
            NoteEvent::MidiChannelPressure {
                channel, pressure, ..
            } if mpe && channel != MPE_MASTER => {
                let c = channel as usize % 16;
                self.channel_pressure[c] = (pressure as f64).clamp(0.0, 1.0);
                if let Some(key) = self.channel_key[c] {
                    let expression = Expression::Pressure(self.channel_pressure[c]);
                    emit(out, cap, offset, Event::Expression { key, expression });
                }
            }
            NoteEvent::MidiCC {
                cc, channel, value, ..
            } if mpe && cc == CC_BRIGHTNESS => {
                self.channel_brightness[channel as usize % 16] = (value as f64).clamp(0.0, 1.0);
            }
            NoteEvent::MidiCC { cc, value, .. } if cc == control_change::MODULATION_MSB => {
                self.wheel = (value as f64).clamp(0.0, 1.0);
            }
            _ => {}
        }
    }

    /// An MPE member channel's tuning, semitones: the master's bend (2 semitones full) plus
    /// its own (the bend range full).
    fn mpe_semitones(&self, channel: usize, params: &ModalForgeParams) -> f64 {
        self.channel_bend[MPE_MASTER as usize] * MPE_MASTER_BEND_SEMITONES
            + self.channel_bend[channel] * params.expression.bend_range.value() as f64
    }

    /// The strike of key `key`; `None` for a key the tuning leaves silent.
    fn strike(
        key: u8,
        velocity: f64,
        brightness: f64,
        params: &ModalForgeParams,
        engine: &AudioEngine,
    ) -> Option<Event> {
        let v = velocity.clamp(0.0, 1.0);
        let on_mallet = params.expression.brightness.value() == BrightnessTarget::Mallet;
        // Softer presses: a longer, softer contact (up to 2x at velocity 0 with the knob at 1);
        // brightness shortens it (x1/4 at 1) or lengthens it (x4 at 0).
        let base = engine.voicing().hardness_s;
        let mut hardness =
            base * (1.0 + params.strike.velocity_hardness.value() as f64 * (1.0 - v));
        if on_mallet {
            hardness *= BRIGHTNESS_HARDNESS_RANGE.powf(1.0 - 2.0 * brightness);
        }
        let (pitch, mut hit) = match params.play.mapping.value() {
            // Resolved by the engine with the object and voicing in use at the strike; the
            // key's frequency comes from the tuning (12-TET unless a Scala file is loaded).
            KeyMapping::Pitch => {
                let hz = params.key_table.hz(key);
                if hz.is_nan() || hz <= 0.0 {
                    return None;
                }
                (Pitch::Fundamental(hz), None)
            }
            KeyMapping::Positions => (
                Pitch::Ratio(1.0),
                Some(HitPoint {
                    position: Self::position_of(key),
                    direction: engine.voicing().hit.direction,
                }),
            ),
        };
        if !on_mallet && brightness != 0.5 {
            let set = hit.unwrap_or(engine.voicing().hit);
            hit = Some(HitPoint {
                position: brightened_hit(set.position, brightness),
                direction: set.direction,
            });
        }
        Some(Event::Strike {
            key: match params.play.mapping.value() {
                KeyMapping::Pitch => key,
                // One bank for all positions: strikes superpose on the object at its own size.
                KeyMapping::Positions => 0,
            },
            pitch,
            velocity: v,
            hit,
            hardness_s: Some(hardness.min(0.1)),
        })
    }
}
