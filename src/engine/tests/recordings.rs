//! A recording's modes played as recorded. Truths: the recorded modes played directly by a
//! fresh `OscillatorBank`, and the pitch mapping's cluster centre on the note with every mode
//! scaled by one ratio.

use super::*;

/// Eight modes of a made-up bell: a near-degenerate lowest pair, decays off any law.
fn recorded_bell() -> Vec<crate::modes::ModeRecord> {
    [
        (523.0, 1.2, 0.8),
        (524.5, 1.4, 0.5),
        (1210.0, 3.5, -0.4),
        (1987.0, 2.0, 0.3),
        (2630.0, 9.0, 0.25),
        (3480.0, 6.5, -0.2),
        (4400.0, 20.0, 0.1),
        (6100.0, 35.0, 0.05),
    ]
    .map(|(freq_hz, decay_per_s, gain)| crate::modes::ModeRecord {
        freq_hz,
        decay_per_s,
        gain,
    })
    .to_vec()
}

#[test]
fn a_recording_plays_as_recorded_and_follows_the_pitch_mapping() {
    // Truth for the sound: the recorded modes played directly by a fresh OscillatorBank (the
    // CLI's `render --modes` path); the engine strikes the recording as an object and must
    // agree to f32 rendering precision (1e-4 of the peak, as for solved shapes). Then a
    // pitch-mapped strike on C4: the cluster centre of the lowest pair on 261.63 Hz
    // (`pitch::cluster_pitch_hz` on the recorded weights), every mode scaled by the same ratio.
    let bell = recorded_bell();
    let (mut audio, control) = recorded(&bell);
    assert_eq!(
        control.status().playing.map(|p| p.solver),
        Some("recording")
    );
    let out = render(&mut audio, 9600, &[strike(60, 1.0)]);
    assert_plays_like_offline(&out, &crate::modes::ModeSet::from_records(&bell).unwrap());

    let c4 = TimedEvent {
        offset: 0,
        event: Event::Strike {
            key: 48,
            pitch: Pitch::Fundamental(261.63),
            velocity: 1.0,
            hit: None,
            hardness_s: None,
        },
    };
    render(&mut audio, 64, &[c4]);
    let tuned = audio.voice_tunings(48);
    assert_eq!(tuned.len(), bell.len());
    let centre = super::pitch::cluster_pitch_hz(
        tuned[..2]
            .iter()
            .zip(&bell)
            .map(|(t, m)| (t.0, (m.gain * m.freq_hz).powi(2))),
    )
    .unwrap();
    assert!((centre / 261.63 - 1.0).abs() < 1e-6, "{centre}");
    let ratio = tuned[0].0 / bell[0].freq_hz;
    for (t, m) in tuned.iter().zip(&bell) {
        // Steel's Rayleigh law and the decays of these modes move a damped frequency by
        // (d / omega)^2 / 2 < 2e-6 relative.
        assert!((t.0 / m.freq_hz / ratio - 1.0).abs() < 1e-5, "{t:?} {m:?}");
    }
    // A shape request replaces the recording.
    control.request(request(bar(24), 10));
    assert!(control.wait_idle(Duration::from_secs(60)));
    assert_eq!(control.status().playing.map(|p| p.solver), Some("fem"));
}
