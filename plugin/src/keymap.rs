//! MIDI to engine events: note-on strikes (velocity sets force and mallet hardness), the two key
//! mappings (pitch: each key's frequency from the tuning's table, [`crate::tuning`]), note-off
//! mute, pitch bend (damping) and the mod wheel (hardness).
//!
//! Where it sits: called by [`crate::ModalForge::process`] for every host event; never
//! allocates (events go into a vector with fixed capacity).

use crate::params::{KeyMapping, ModalForgeParams};
use modalforge::engine::{AudioEngine, Event, HitPoint, Pitch, TimedEvent};
use nice_plug::midi::Key;
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

/// Controller state carried between blocks.
#[derive(Clone, Copy, Debug)]
pub struct KeyMap {
    bend: f64,
    wheel: f64,
}

impl Default for KeyMap {
    fn default() -> Self {
        Self {
            bend: 0.5,
            wheel: 0.0,
        }
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
        let e = match *event {
            NoteEvent::NoteOn { key, velocity, .. } => {
                let Key::Number(k) = key else { return };
                Self::strike(k, velocity as f64, params, engine)
            }
            NoteEvent::NoteOff { key, .. } if params.play.note_off_mute.value() => match key {
                Key::Number(k) => Some(Event::Mute { key: k }),
                Key::Wildcard => Some(Event::AllOff),
            },
            NoteEvent::Choke { .. } => Some(Event::AllOff),
            NoteEvent::MidiPitchBend { value, .. } => {
                self.bend = (value as f64).clamp(0.0, 1.0);
                None
            }
            NoteEvent::MidiCC { cc, value, .. } if cc == control_change::MODULATION_MSB => {
                self.wheel = (value as f64).clamp(0.0, 1.0);
                None
            }
            _ => None,
        };
        if let Some(event) = e {
            if out.len() < cap {
                out.push(TimedEvent { offset, event });
            }
        }
    }

    /// The strike of key `key`; `None` for a key the tuning leaves silent.
    fn strike(
        key: u8,
        velocity: f64,
        params: &ModalForgeParams,
        engine: &AudioEngine,
    ) -> Option<Event> {
        let v = velocity.clamp(0.0, 1.0);
        // Softer presses: a longer, softer contact (up to 2x at velocity 0 with the knob at 1).
        let base = engine.voicing().hardness_s;
        let hardness = base * (1.0 + params.strike.velocity_hardness.value() as f64 * (1.0 - v));
        let (pitch, hit) = match params.play.mapping.value() {
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
