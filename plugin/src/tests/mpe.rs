//! MPE and note expressions into engine events (issue 15). Truths: the MPE specification
//! (lower zone: channel 1 master with a 2-semitone bend, member channels one note each, their
//! bend scaled by the bend range, channel pressure and CC74 per note) and the nice-plug note
//! expression events' units (tuning in semitones, pressure 0-1, gain as a ratio).

use super::*;
use crate::params::MidiExpression;
use modalforge::engine::{Engine, EngineConfig, Event, Expression};
use nice_plug::midi::{Channel, Key, VoiceID};

fn on(channel: u8, key: u8) -> NoteEvent<()> {
    NoteEvent::NoteOn {
        timing: 5,
        voice_id: VoiceID::Wildcard,
        channel: Channel::Number(channel),
        key: Key::Number(key),
        velocity: 0.8,
    }
}

fn bend(channel: u8, value: f32) -> NoteEvent<()> {
    NoteEvent::MidiPitchBend {
        timing: 9,
        channel,
        value,
    }
}

/// A CLAP/VST3 brightness note expression on `key`.
fn brighten(key: u8, brightness: f32) -> NoteEvent<()> {
    NoteEvent::PolyBrightness {
        timing: 0,
        voice_id: VoiceID::Wildcard,
        channel: Channel::Number(0),
        key: Key::Number(key),
        brightness,
    }
}

fn engine_for(params: &ModalForgeParams) -> modalforge::engine::AudioEngine {
    let table = MaterialTable::new();
    let (engine, control) = Engine::start(
        48_000.0,
        EngineConfig::default(),
        params.voicing(&table, 1.0, 1.0),
        Vec::new(),
    )
    .unwrap();
    drop(control);
    engine
}

/// The events one host event becomes.
fn run(
    keymap: &mut KeyMap,
    params: &ModalForgeParams,
    engine: &modalforge::engine::AudioEngine,
    event: NoteEvent<()>,
) -> Vec<TimedEvent> {
    let mut out = Vec::with_capacity(32);
    keymap.translate(&event, params, engine, &mut out, 32);
    out
}

fn tunings(events: &[TimedEvent]) -> Vec<(u8, f64)> {
    events
        .iter()
        .filter_map(|e| match e.event {
            Event::Expression {
                key,
                expression: Expression::TuningSemitones(s),
            } => Some((key, s)),
            _ => None,
        })
        .collect()
}

fn hardness(events: &[TimedEvent]) -> f64 {
    match events[0].event {
        Event::Strike {
            hardness_s: Some(h),
            ..
        } => h,
        ref e => panic!("{e:?}"),
    }
}

/// Sets an enum parameter to its last choice, as a host would (normalised 1).
fn choose_last<T: Enum + PartialEq>(param: &EnumParam<T>) {
    // SAFETY: each test owns its parameters; nothing else reads them while one is set.
    unsafe { param.as_ptr()._internal_set_normalized_value(1.0) };
}

fn mpe_params() -> ModalForgeParams {
    let params = ModalForgeParams::default();
    choose_last(&params.expression.midi);
    assert_eq!(params.expression.midi.value(), MidiExpression::Mpe);
    params
}

#[test]
fn mpe_member_channels_bend_press_and_brighten_their_own_note() {
    let params = mpe_params();
    let range = params.expression.bend_range.value() as f64;
    assert_eq!(range, 48.0, "MPE's default member bend range");
    let engine = engine_for(&params);
    let mut keymap = KeyMap::default();
    // A bend sent before the note (as MPE controllers do) applies from its strike, at the
    // strike's offset: a quarter of full up is 12 semitones at the 48-semitone range.
    assert!(run(&mut keymap, &params, &engine, bend(1, 0.625)).is_empty());
    let events = run(&mut keymap, &params, &engine, on(1, 60));
    assert!(matches!(events[0].event, Event::Strike { key: 60, .. }));
    assert_eq!(tunings(&events), vec![(60, 0.25 * range)]);
    assert!(events.iter().all(|e| e.offset == 5));
    // A second note on another channel; each channel's bend moves only its note.
    run(&mut keymap, &params, &engine, on(2, 64));
    let moved = run(&mut keymap, &params, &engine, bend(2, 0.0));
    assert_eq!(tunings(&moved), vec![(64, -range)]);
    assert_eq!(moved[0].offset, 9);
    // The master channel's bend (2 semitones full) moves both, on top of their own.
    let master = run(&mut keymap, &params, &engine, bend(0, 1.0));
    let mut got = tunings(&master);
    got.sort_by_key(|t| t.0);
    assert_eq!(got, vec![(60, 0.25 * range + 2.0), (64, -range + 2.0)]);
    // Channel pressure presses on the channel's note.
    let pressed = run(
        &mut keymap,
        &params,
        &engine,
        NoteEvent::MidiChannelPressure {
            timing: 0,
            channel: 1,
            pressure: 0.75,
        },
    );
    assert!(matches!(
        pressed[..],
        [TimedEvent {
            event: Event::Expression {
                key: 60,
                expression: Expression::Pressure(p)
            },
            ..
        }] if p == 0.75
    ));
    // CC74 sets the channel's next strike: full brightness a quarter of the contact time,
    // none four times it (the knobs and velocity as before).
    let plain = hardness(&run(&mut keymap, &params, &engine, on(3, 67)));
    for (value, ratio) in [(1.0, 0.25), (0.0, 4.0)] {
        run(
            &mut keymap,
            &params,
            &engine,
            NoteEvent::MidiCC {
                timing: 0,
                channel: 3,
                cc: 74,
                value,
            },
        );
        let h = hardness(&run(&mut keymap, &params, &engine, on(3, 67)));
        assert!((h / plain - ratio).abs() < 1e-12, "{h} vs {plain}");
    }
}

#[test]
fn classic_mode_keeps_bend_on_damping_and_note_expressions_always_apply() {
    let params = ModalForgeParams::default();
    assert_eq!(params.expression.midi.value(), MidiExpression::Classic);
    let engine = engine_for(&params);
    let mut keymap = KeyMap::default();
    run(&mut keymap, &params, &engine, on(1, 60));
    // Pitch bend is the damping controller, not a note's tuning.
    assert!(run(&mut keymap, &params, &engine, bend(1, 1.0)).is_empty());
    assert_eq!(keymap.controllers().0, 4.0);
    // CLAP/VST3 note expressions, in their units.
    let key = Key::Number(60);
    let (voice_id, channel) = (VoiceID::Wildcard, Channel::Number(0));
    let cases = [
        (
            NoteEvent::PolyTuning {
                timing: 0,
                voice_id,
                channel,
                key,
                tuning: -3.5,
            },
            Expression::TuningSemitones(-3.5),
        ),
        (
            NoteEvent::PolyPressure {
                timing: 0,
                voice_id,
                channel,
                key,
                pressure: 0.5,
            },
            Expression::Pressure(0.5),
        ),
        (
            NoteEvent::PolyVolume {
                timing: 0,
                voice_id,
                channel,
                key,
                gain: 0.25,
            },
            Expression::Volume(0.25),
        ),
    ];
    for (event, want) in cases {
        let got = run(&mut keymap, &params, &engine, event);
        assert!(
            matches!(got[..], [TimedEvent { event: Event::Expression { key: 60, expression }, .. }] if expression == want),
            "{got:?}"
        );
    }
    // Brightness sets that key's next strike.
    let plain = hardness(&run(&mut keymap, &params, &engine, on(0, 62)));
    run(&mut keymap, &params, &engine, brighten(62, 1.0));
    let bright = hardness(&run(&mut keymap, &params, &engine, on(0, 62)));
    assert!((bright / plain - 0.25).abs() < 1e-12);
}

#[test]
fn held_notes_scrape_from_note_on_to_note_off_when_asked() {
    // "Held Notes: Scrape": a note-on becomes a contact on the same key at the same pitch
    // (the key's 12-TET frequency) with the MIDI velocity, its note-off ends it, and its
    // poly pressure reaches it as the key's pressure; "Strike" (the default) strikes.
    let params = ModalForgeParams::default();
    let engine = engine_for(&params);
    let mut keymap = KeyMap::default();
    let struck = run(&mut keymap, &params, &engine, on(0, 69));
    assert!(matches!(struck[0].event, Event::Strike { key: 69, .. }));
    choose_last(&params.resonator.held);
    assert_eq!(
        params.resonator.held.value(),
        crate::params::HeldNote::Scrape
    );
    let held = run(&mut keymap, &params, &engine, on(0, 69));
    match held[0].event {
        Event::Contact {
            key: 69,
            pitch: modalforge::engine::Pitch::Fundamental(hz),
            velocity,
        } => {
            assert!((hz - 440.0).abs() < 1e-9, "{hz}");
            assert!((velocity - 0.8).abs() < 1e-6, "{velocity}");
        }
        ref other => panic!("{other:?}"),
    }
    let pressed = NoteEvent::PolyPressure {
        timing: 3,
        voice_id: VoiceID::Wildcard,
        channel: Channel::Number(0),
        key: Key::Number(69),
        pressure: 0.5,
    };
    let pressure = run(&mut keymap, &params, &engine, pressed);
    assert!(matches!(
        pressure[0].event,
        Event::Expression {
            key: 69,
            expression: Expression::Pressure(p)
        } if (p - 0.5).abs() < 1e-6
    ));
    let off = NoteEvent::NoteOff {
        timing: 7,
        voice_id: VoiceID::Wildcard,
        channel: Channel::Number(0),
        key: Key::Number(69),
        velocity: 0.0,
    };
    let released = run(&mut keymap, &params, &engine, off);
    assert!(matches!(released[0].event, Event::ContactEnd { key: 69 }));
}

/// "Brightness Moves: Hit Point": a note's brightness moves its next strike's hit point from
/// the centre of the object's box (0) through the set point (0.5) to the box's edge (1), and
/// leaves the mallet alone. Truth: the geometry of that line (the default hit point is off
/// every symmetry line, so the line is a diagonal one).
#[test]
fn brightness_can_move_the_hit_point_instead_of_the_mallet() {
    let params = ModalForgeParams::default();
    choose_last(&params.expression.brightness);
    assert_eq!(
        params.expression.brightness.value(),
        crate::params::BrightnessTarget::HitPoint
    );
    let engine = engine_for(&params);
    let set = engine.voicing().hit.position;
    let mut keymap = KeyMap::default();
    let mut strike_at = |brightness: f32| {
        run(&mut keymap, &params, &engine, brighten(64, brightness));
        let events = run(&mut keymap, &params, &engine, on(0, 64));
        let hit = match events[0].event {
            Event::Strike { hit, .. } => hit.map(|h| h.position),
            ref e => panic!("{e:?}"),
        };
        (hit.unwrap_or(set), hardness(&events))
    };
    let (centre, h0) = strike_at(0.0);
    let (plain, h_half) = strike_at(0.5);
    let (edge, h1) = strike_at(1.0);
    let (between, _) = strike_at(0.75);
    assert_eq!(plain, set);
    assert!(
        h0 == h_half && h1 == h_half,
        "the mallet moved: {h0} {h_half} {h1}"
    );
    let close = |a: f64, b: f64| (a - b).abs() < 1e-12;
    assert!(close(centre[0], 0.5) && close(centre[1], 0.5) && close(centre[2], set[2]));
    // On the edge: one coordinate at 0 or 1, on the ray from the centre through the set point.
    let on_edge = [edge[0], edge[1]]
        .iter()
        .any(|&c| close(c, 0.0) || close(c, 1.0));
    let cross = (edge[0] - 0.5) * (set[1] - 0.5) - (edge[1] - 0.5) * (set[0] - 0.5);
    let along = (edge[0] - 0.5) * (set[0] - 0.5) + (edge[1] - 0.5) * (set[1] - 0.5);
    assert!(
        on_edge && close(cross, 0.0) && along > 0.0,
        "{edge:?} from {set:?}"
    );
    // Halfway between the set point and the edge at 0.75.
    for a in 0..2 {
        assert!(close(between[a], 0.5 * (set[a] + edge[a])), "{between:?}");
    }
}
