//! A recording's own modes as a playable object (issue 14): the modes `modalforge analyze`
//! extracts from a struck real object, struck, pitched, damped and budgeted like a solved
//! shape.
//!
//! Where it sits: built by the plugin's editor ("Play recording") or any caller from
//! [`ModeRecord`]s and the voicing in force at that moment; travels to the audio side as
//! [`super::ObjectModes::Recorded`] through the worker like a solved object
//! ([`super::ObjectRequest::recording`]).
//!
//! A recording has frequencies, decay rates and gains, not a shape; it is put in the engine's
//! reference units so the rest of the engine treats it as any object:
//! - **Pitch and size.** The object is one "voxel" long (`grid_dims = [1, 1, 1]`), and its
//!   reference eigenvalue is `lambda_i = omega_i^2 rho0 L0^2 / E0` with `omega_i^2 = (2 pi
//!   f_i)^2 + d_i^2` (the undamped frequency) and `E0`, `rho0`, `L0` the voicing's at import:
//!   at those settings the scaling law (Jin et al. 2020, eq. 12, [`super::voicing::tune`])
//!   gives back the recorded frequencies; a different size or material moves every mode as it
//!   would move a real object's (any shape scales so); the "pitch" key mapping retunes it like
//!   any object.
//! - **Strength.** A reference modal force `F_i = g_i sqrt(rho0 L0^3) 2 pi f_i`, so that the
//!   engine's strike gain (Jin et al. 2020, eq. 7, [`super::Voicing::modal_gain`]) is the
//!   recorded gain `g_i` at the import settings. The recording was struck at one point: the
//!   hit point does not change a recording's gains (the mallet's hardness and the velocity
//!   still do).
//! - **Damping.** A recording's decay rates scatter around any damping law. Each mode keeps
//!   its ratio to the voicing's law at import, `r_i = d_i / d_law(omega_i^2)`, and plays
//!   `r_i d_law(omega^2)` under the current law and pitch: exactly the recorded decays at the
//!   import settings, and the damping knobs and the pitch act on it as on a solved object.
//!   (Sterling and Lin 2016, sec. 3: the laws are fitted in this eigenvalue-damping space.) A
//!   law with no decay at a mode (all coefficients zero) cannot carry a ratio: that mode
//!   follows the law (`r_i = 1`).

use super::voicing::Voicing;
use crate::material::DampedMode;
use crate::modes::ModeRecord;
use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;

/// Smallest and largest decay ratio a mode keeps against the law (a mode 1000x off the law is
/// an extraction artefact, not a property of the object).
pub const DECAY_RATIO_RANGE: (f64, f64) = (1e-3, 1e3);

/// Most modes a recorded object keeps (the loudest; the engine's budget plays fewer anyway).
pub const MAX_RECORDED_MODES: usize = 512;

/// Why a recording cannot become an object.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RecordedError {
    /// No mode has a positive finite frequency, a finite non-negative decay and a non-zero
    /// finite gain.
    #[error("the recording has no playable modes (all are at 0 Hz, NaN, silent or overdamped); analyse a louder or longer strike")]
    NoModes,
    /// The voicing is invalid (E, rho or size not positive and finite, or a non-finite law).
    #[error("the voicing at import is invalid: {0}")]
    Voicing(#[from] super::VoicingError),
    /// A stored recorded object (a plugin state, a file) does not hold together.
    #[error("the stored recording {name:?} is malformed: {why}; load the recording again")]
    Malformed {
        /// Its name.
        name: String,
        /// What is wrong.
        why: &'static str,
    },
}

/// A recording's modes in reference units (see the module docs), ascending in frequency.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RecordedObject {
    /// A name for the status line (the file name).
    pub name: String,
    /// Reference eigenvalues, ascending (an object one voxel long).
    pub eigenvalues: Vec<f64>,
    /// Reference modal forces (the same at every hit point).
    pub forces: Vec<f64>,
    /// Each mode's decay over the damping law's at import.
    pub decay_ratios: Vec<f64>,
}

impl RecordedObject {
    /// The modes of `modes` that can ring, as an object played exactly as recorded under
    /// `voicing` (E, rho, size and damping law; the rest of it does not matter). Keeps the
    /// [`MAX_RECORDED_MODES`] loudest.
    pub fn new(
        name: impl Into<String>,
        modes: &[ModeRecord],
        voicing: &Voicing,
    ) -> Result<Self, RecordedError> {
        voicing.validate()?;
        let size = voicing.size_m;
        let eigen_scale = voicing.eigen_scale(size);
        let force_scale = (voicing.density_kg_m3 * size * size * size).sqrt();
        let mut kept: Vec<(f64, f64, f64)> = modes
            .iter()
            .filter(|m| {
                m.freq_hz.is_finite()
                    && m.freq_hz > 0.0
                    && m.decay_per_s.is_finite()
                    && m.decay_per_s >= 0.0
                    && m.gain.is_finite()
                    && m.gain != 0.0
            })
            .map(|m| {
                let omega = TAU * m.freq_hz;
                let w2 = omega * omega + m.decay_per_s * m.decay_per_s;
                let ratio = match voicing.damping.damp(w2) {
                    DampedMode::Oscillating { decay_per_s, .. } if decay_per_s > 0.0 => {
                        (m.decay_per_s / decay_per_s)
                            .clamp(DECAY_RATIO_RANGE.0, DECAY_RATIO_RANGE.1)
                    }
                    _ => 1.0,
                };
                (w2 / eigen_scale, m.gain * force_scale * omega, ratio)
            })
            .filter(|(l, f, r)| l.is_finite() && *l > 0.0 && f.is_finite() && r.is_finite())
            .collect();
        if kept.is_empty() {
            return Err(RecordedError::NoModes);
        }
        if kept.len() > MAX_RECORDED_MODES {
            // The loudest by the energy a strike puts in (force squared).
            kept.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
            kept.truncate(MAX_RECORDED_MODES);
        }
        kept.sort_by(|a, b| a.0.total_cmp(&b.0));
        Ok(Self {
            name: name.into(),
            eigenvalues: kept.iter().map(|k| k.0).collect(),
            forces: kept.iter().map(|k| k.1).collect(),
            decay_ratios: kept.iter().map(|k| k.2).collect(),
        })
    }

    /// Checks a stored object (a plugin state is untrusted input): as many forces and ratios
    /// as eigenvalues, at most [`MAX_RECORDED_MODES`] and at least one, eigenvalues positive,
    /// finite and ascending, forces finite, ratios within [`DECAY_RATIO_RANGE`].
    pub fn validate(&self) -> Result<(), RecordedError> {
        let why = if self.eigenvalues.is_empty() {
            Some("no modes")
        } else if self.eigenvalues.len() > MAX_RECORDED_MODES {
            Some("too many modes")
        } else if self.forces.len() != self.eigenvalues.len()
            || self.decay_ratios.len() != self.eigenvalues.len()
        {
            Some("the mode arrays differ in length")
        } else if !self.eigenvalues.iter().all(|l| l.is_finite() && *l > 0.0)
            || !self.eigenvalues.is_sorted()
        {
            Some("an eigenvalue is not positive and finite, or they are not ascending")
        } else if !self.forces.iter().all(|f| f.is_finite()) {
            Some("a force is not finite")
        } else if !self
            .decay_ratios
            .iter()
            .all(|r| (DECAY_RATIO_RANGE.0..=DECAY_RATIO_RANGE.1).contains(r))
        {
            Some("a decay ratio is out of range")
        } else {
            None
        };
        match why {
            Some(why) => Err(RecordedError::Malformed {
                name: self.name.clone(),
                why,
            }),
            None => Ok(()),
        }
    }

    /// A fingerprint of the modes (not the name), to notice a different recording.
    pub fn fingerprint(&self) -> u64 {
        use std::hash::{Hash, Hasher};
        let mut h = std::collections::hash_map::DefaultHasher::new();
        for v in [&self.eigenvalues, &self.forces, &self.decay_ratios] {
            v.len().hash(&mut h);
            v.iter().for_each(|x| x.to_bits().hash(&mut h));
        }
        h.finish()
    }

    /// Modes held.
    pub fn mode_count(&self) -> usize {
        self.eigenvalues.len()
    }

    /// Reference modal forces into `out` (the hit does not matter). Never allocates.
    pub fn reference_forces_into(&self, out: &mut [f64]) {
        let n = out.len().min(self.forces.len());
        out[..n].copy_from_slice(&self.forces[..n]);
        out[n..].fill(0.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::spectrum::spectrum;
    use crate::engine::ObjectModes;
    use crate::material::Material;

    fn voicing() -> Voicing {
        let mut v = Voicing::from_material(&Material::preset("steel").unwrap(), 0.3).unwrap();
        v.hardness_s = 0.0;
        v
    }

    fn record(freq_hz: f64, decay_per_s: f64, gain: f64) -> ModeRecord {
        ModeRecord {
            freq_hz,
            decay_per_s,
            gain,
        }
    }

    /// At the import settings the spectrum the engine would strike is the recording itself:
    /// frequencies, decays and (impulse) gains to rounding (1e-9 relative: a square root and a
    /// few products of f64 values).
    #[test]
    fn plays_back_exactly_as_recorded_at_the_import_settings() {
        let v = voicing();
        let modes = [
            record(1234.5, 3.2, 0.5),
            record(440.0, 1.5, -0.25),
            record(3000.0, 40.0, 0.125),
        ];
        let obj = RecordedObject::new("bell.wav", &modes, &v).unwrap();
        let lines = spectrum(&ObjectModes::Recorded(obj), &v, 48_000.0).unwrap();
        let mut want = modes.to_vec();
        want.sort_by(|a, b| a.freq_hz.total_cmp(&b.freq_hz));
        assert_eq!(lines.len(), 3);
        for (line, m) in lines.iter().zip(&want) {
            let rel = |a: f64, b: f64| ((a - b) / b).abs();
            assert!(rel(line.freq_hz, m.freq_hz) < 1e-9, "{line:?} vs {m:?}");
            assert!(
                rel(line.decay_per_s, m.decay_per_s) < 1e-9,
                "{line:?} vs {m:?}"
            );
            assert!(
                rel(line.amplitude, m.gain.abs()) < 1e-9,
                "{line:?} vs {m:?}"
            );
        }
    }

    /// Half the size doubles every frequency (the scaling law), and a damping law twice as
    /// strong doubles every decay (each mode keeps its ratio to the law).
    #[test]
    fn size_and_damping_act_on_it_as_on_a_solved_object() {
        let v = voicing();
        let modes = [record(500.0, 2.0, 1.0), record(1700.0, 9.0, 0.5)];
        let obj = ObjectModes::Recorded(RecordedObject::new("x", &modes, &v).unwrap());
        let base = spectrum(&obj, &v, 96_000.0).unwrap();
        let mut small = v;
        small.size_m *= 0.5;
        let mut damped = v;
        damped.damping = match v.damping {
            crate::engine::DampingParams::Rayleigh { alpha1, alpha2 } => {
                crate::engine::DampingParams::Rayleigh {
                    alpha1: 2.0 * alpha1,
                    alpha2: 2.0 * alpha2,
                }
            }
            other => panic!("steel is Rayleigh, got {other:?}"),
        };
        let s = spectrum(&obj, &small, 96_000.0).unwrap();
        let d = spectrum(&obj, &damped, 96_000.0).unwrap();
        for ((b, s), d) in base.iter().zip(&s).zip(&d) {
            // Damped frequencies: 2x the undamped one, less a damping term of order
            // (d / omega)^2 ~ 1e-6.
            assert!((s.freq_hz / b.freq_hz - 2.0).abs() < 1e-5, "{s:?} vs {b:?}");
            assert!(
                (d.decay_per_s / b.decay_per_s - 2.0).abs() < 1e-9,
                "{d:?} vs {b:?}"
            );
        }
    }

    #[test]
    fn refuses_a_recording_without_playable_modes_and_keeps_the_loudest() {
        let v = voicing();
        let bad = [
            record(0.0, 1.0, 1.0),
            record(f64::NAN, 1.0, 1.0),
            record(100.0, -1.0, 1.0),
            record(100.0, 1.0, 0.0),
        ];
        assert_eq!(
            RecordedObject::new("x", &bad, &v),
            Err(RecordedError::NoModes)
        );
        let many: Vec<ModeRecord> = (0..MAX_RECORDED_MODES + 10)
            .map(|i| record(100.0 + i as f64, 1.0, 1.0 + i as f64))
            .collect();
        let obj = RecordedObject::new("x", &many, &v).unwrap();
        assert_eq!(obj.mode_count(), MAX_RECORDED_MODES);
        assert_eq!(obj.validate(), Ok(()));
        // A stored object that does not hold together is refused, naming the fault.
        let mut bad = obj.clone();
        bad.forces.pop();
        assert!(bad
            .validate()
            .unwrap_err()
            .to_string()
            .contains("differ in length"));
        let mut bad = obj.clone();
        bad.eigenvalues.swap(0, 1);
        assert!(bad.validate().is_err());
        let mut bad = obj.clone();
        bad.decay_ratios[3] = f64::NAN;
        assert!(bad.validate().is_err());
        assert_ne!(bad.fingerprint(), obj.fingerprint());
        // The 10 quietest (the lowest here) went.
        let lowest = obj.eigenvalues[0] * v.eigen_scale(v.size_m);
        assert!(
            (lowest.sqrt() / TAU - 110.0).abs() < 1e-3,
            "{}",
            lowest.sqrt() / TAU
        );
    }
}
