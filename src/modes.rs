//! The mode data model: what the synthesis banks play.
//!
//! Where it sits: the output of every mode source (the FEM solution voiced by
//! [`crate::basis::ModeBasis`], JSON files, the analytic demo in [`crate::demo`]) and the input
//! of the banks in [`crate::synth`]. A mode `i` struck at `t = 0` rings as
//! `q_i(t) = g_i e^(-d_i t) sin(2 pi f_i t)` (Deep-Modal, Jin et al. 2020, eq. 3 and 13, with the
//! initial phase zero because the object starts at rest).
//!
//! [`ModeSet`] stores modes structure-of-arrays in `f64`. Before a bank sees them they go through
//! [`ModeSet::playable`], which culls what cannot or need not be played (at or above Nyquist,
//! zero frequency, no resonance, inaudibly quiet) and yields [`PlayableModes`]: the only type the
//! banks accept, so no bank ever sees a culled mode.
//!
//! JSON schema (extra fields are ignored, so richer files stay readable):
//! `{"modes":[{"freq_hz":F,"decay_per_s":D,"gain":G}, ...]}` with `F >= 0` in Hz, `D >= 0` in 1/s
//! and `G` any finite number (its sign is the mode's phase).

use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::{Path, PathBuf};

/// One mode as written in a JSON file.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ModeRecord {
    /// Damped frequency in Hz.
    pub freq_hz: f64,
    /// Exponential amplitude decay rate in 1/s.
    pub decay_per_s: f64,
    /// Amplitude of the mode's damped sine for a unit strike.
    pub gain: f64,
}

#[derive(Serialize, Deserialize)]
struct ModeFile {
    modes: Vec<ModeRecord>,
}

/// What is wrong with a set of modes.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ModeError {
    /// No modes at all.
    #[error("the mode set is empty: give at least one mode")]
    Empty,
    /// The three arrays have different lengths.
    #[error("mode arrays differ in length: {freq} frequencies, {decay} decay rates, {gain} gains")]
    LengthMismatch {
        /// Number of frequencies.
        freq: usize,
        /// Number of decay rates.
        decay: usize,
        /// Number of gains.
        gain: usize,
    },
    /// A NaN or infinite value.
    #[error("mode {index} has {field} = {value}: every value must be a finite number")]
    NonFinite {
        /// Index of the mode (0-based).
        index: usize,
        /// Field name as in the JSON schema.
        field: &'static str,
        /// The offending value.
        value: f64,
    },
    /// A negative frequency.
    #[error("mode {index} has freq_hz = {value}: frequencies are in Hz and must be >= 0")]
    NegativeFrequency {
        /// Index of the mode (0-based).
        index: usize,
        /// The offending value.
        value: f64,
    },
    /// A negative decay rate (a mode that grows without bound).
    #[error(
        "mode {index} has decay_per_s = {value}: a negative decay rate grows without bound; use >= 0"
    )]
    NegativeDecay {
        /// Index of the mode (0-based).
        index: usize,
        /// The offending value.
        value: f64,
    },
    /// The sample rate is not a positive finite number.
    #[error("sample rate {0} Hz is invalid: use a positive rate such as 48000")]
    InvalidSampleRate(f64),
    /// A cull setting is out of range.
    #[error("minimum relative gain {0} is invalid: use a number in [0, 1)")]
    InvalidCullThreshold(f64),
    /// Every mode was culled.
    #[error("no playable modes: {0}")]
    NothingPlayable(CullReport),
}

/// What is wrong with a mode file.
#[derive(Debug, thiserror::Error)]
pub enum ModeFileError {
    /// The file is larger than [`crate::limits::MAX_TEXT_BYTES`].
    #[error(transparent)]
    TooLarge(crate::limits::FileTooLarge),
    /// The file could not be read.
    #[error("cannot read mode file {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The file is not valid JSON of the documented schema.
    #[error("mode file {path} is not valid mode JSON ({source}); expected {{\"modes\":[{{\"freq_hz\":F,\"decay_per_s\":D,\"gain\":G}}, ...]}}")]
    Json {
        /// The file.
        path: PathBuf,
        /// The parse error (with line and column).
        source: serde_json::Error,
    },
    /// The JSON parsed but the values are unusable.
    #[error("mode file {path}: {source}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong with the values.
        source: ModeError,
    },
}

/// A validated set of modes, structure-of-arrays, in `f64`.
///
/// Invariants (checked by every constructor): at least one mode, all values finite,
/// `freq_hz >= 0`, `decay_per_s >= 0`.
#[derive(Clone, Debug, PartialEq)]
pub struct ModeSet {
    freq_hz: Vec<f64>,
    decay_per_s: Vec<f64>,
    gain: Vec<f64>,
}

impl ModeSet {
    /// Builds a mode set from parallel arrays, validating every value.
    pub fn new(
        freq_hz: Vec<f64>,
        decay_per_s: Vec<f64>,
        gain: Vec<f64>,
    ) -> Result<Self, ModeError> {
        if freq_hz.len() != decay_per_s.len() || freq_hz.len() != gain.len() {
            return Err(ModeError::LengthMismatch {
                freq: freq_hz.len(),
                decay: decay_per_s.len(),
                gain: gain.len(),
            });
        }
        if freq_hz.is_empty() {
            return Err(ModeError::Empty);
        }
        for i in 0..freq_hz.len() {
            for (field, value) in [
                ("freq_hz", freq_hz[i]),
                ("decay_per_s", decay_per_s[i]),
                ("gain", gain[i]),
            ] {
                if !value.is_finite() {
                    return Err(ModeError::NonFinite {
                        index: i,
                        field,
                        value,
                    });
                }
            }
            if freq_hz[i] < 0.0 {
                return Err(ModeError::NegativeFrequency {
                    index: i,
                    value: freq_hz[i],
                });
            }
            if decay_per_s[i] < 0.0 {
                return Err(ModeError::NegativeDecay {
                    index: i,
                    value: decay_per_s[i],
                });
            }
        }
        Ok(Self {
            freq_hz,
            decay_per_s,
            gain,
        })
    }

    /// Builds a mode set from records (the JSON rows).
    pub fn from_records(records: &[ModeRecord]) -> Result<Self, ModeError> {
        Self::new(
            records.iter().map(|m| m.freq_hz).collect(),
            records.iter().map(|m| m.decay_per_s).collect(),
            records.iter().map(|m| m.gain).collect(),
        )
    }

    /// Parses the documented JSON schema. `path` only labels errors.
    pub fn from_json_str(json: &str, path: &Path) -> Result<Self, ModeFileError> {
        let file: ModeFile = serde_json::from_str(json).map_err(|source| ModeFileError::Json {
            path: path.to_owned(),
            source,
        })?;
        Self::from_records(&file.modes).map_err(|source| ModeFileError::Invalid {
            path: path.to_owned(),
            source,
        })
    }

    /// Reads and parses a JSON mode file.
    pub fn from_json_file(path: &Path) -> Result<Self, ModeFileError> {
        let text = crate::limits::read_text(path, "mode JSON").map_err(|e| match e {
            crate::limits::TextReadError::TooLarge(e) => ModeFileError::TooLarge(e),
            crate::limits::TextReadError::Io(source) => ModeFileError::Io {
                path: path.to_owned(),
                source,
            },
        })?;
        Self::from_json_str(&text, path)
    }

    /// Serialises to the documented JSON schema.
    pub fn to_json(&self) -> String {
        let file = ModeFile {
            modes: self.records().collect(),
        };
        serde_json::to_string_pretty(&file).expect("plain numbers always serialise")
    }

    /// Number of modes.
    pub fn len(&self) -> usize {
        self.freq_hz.len()
    }

    /// Always false: a `ModeSet` holds at least one mode.
    pub fn is_empty(&self) -> bool {
        self.freq_hz.is_empty()
    }

    /// Damped frequencies in Hz.
    pub fn freq_hz(&self) -> &[f64] {
        &self.freq_hz
    }

    /// Decay rates in 1/s.
    pub fn decay_per_s(&self) -> &[f64] {
        &self.decay_per_s
    }

    /// Gains (amplitude of each mode's damped sine for a unit strike).
    pub fn gain(&self) -> &[f64] {
        &self.gain
    }

    /// The modes as records.
    pub fn records(&self) -> impl Iterator<Item = ModeRecord> + '_ {
        (0..self.len()).map(|i| ModeRecord {
            freq_hz: self.freq_hz[i],
            decay_per_s: self.decay_per_s[i],
            gain: self.gain[i],
        })
    }

    /// Culls what a bank at `sample_rate_hz` cannot or need not play, in this order:
    ///
    /// 1. `freq_hz >= sample_rate_hz / 2`: at or above Nyquist (would alias).
    /// 2. `freq_hz == 0`: no oscillation (rigid-body or static modes).
    /// 3. `decay_per_s >= 2 pi freq_hz`: overdamped for listening. The damping ratio is then
    ///    `zeta = d / sqrt(d^2 + w_d^2) >= 1/sqrt(2)`, where a second-order mode has no resonant
    ///    peak at all and loses 54.6 dB within one period: it thumps, it does not ring.
    /// 4. `|gain| < min_relative_gain * max |gain|` over the modes kept so far: inaudible next to
    ///    the loudest mode.
    pub fn playable(
        &self,
        sample_rate_hz: f64,
        settings: &CullSettings,
    ) -> Result<(PlayableModes, CullReport), ModeError> {
        if !(sample_rate_hz.is_finite() && sample_rate_hz > 0.0) {
            return Err(ModeError::InvalidSampleRate(sample_rate_hz));
        }
        let threshold = settings.min_relative_gain;
        if !(threshold.is_finite() && (0.0..1.0).contains(&threshold)) {
            return Err(ModeError::InvalidCullThreshold(threshold));
        }
        let nyquist_hz = 0.5 * sample_rate_hz;
        let mut report = CullReport {
            total: self.len(),
            ..CullReport::default()
        };
        let mut candidates = Vec::with_capacity(self.len());
        for i in 0..self.len() {
            let (f, d) = (self.freq_hz[i], self.decay_per_s[i]);
            if f >= nyquist_hz {
                report.at_or_above_nyquist += 1;
            } else if f <= 0.0 {
                report.zero_frequency += 1;
            } else if d >= std::f64::consts::TAU * f {
                report.overdamped += 1;
            } else {
                candidates.push(i);
            }
        }
        let loudest = candidates
            .iter()
            .map(|&i| self.gain[i].abs())
            .fold(0.0, f64::max);
        let mut kept = PlayableModes {
            sample_rate_hz,
            freq_hz: Vec::with_capacity(candidates.len()),
            decay_per_s: Vec::with_capacity(candidates.len()),
            gain: Vec::with_capacity(candidates.len()),
            source_index: Vec::with_capacity(candidates.len()),
        };
        for i in candidates {
            let g = self.gain[i];
            if g == 0.0 || g.abs() < threshold * loudest {
                report.too_quiet += 1;
                continue;
            }
            kept.freq_hz.push(self.freq_hz[i]);
            kept.decay_per_s.push(self.decay_per_s[i]);
            kept.gain.push(g);
            kept.source_index.push(i);
        }
        report.kept = kept.len();
        if kept.is_empty() {
            return Err(ModeError::NothingPlayable(report));
        }
        Ok((kept, report))
    }
}

/// Thresholds for [`ModeSet::playable`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CullSettings {
    /// Modes whose `|gain|` is below this fraction of the loudest mode's are dropped.
    /// Default 1e-4 (-80 dB): below the noise floor of 16-bit audio relative to full scale.
    pub min_relative_gain: f64,
}

impl Default for CullSettings {
    fn default() -> Self {
        Self {
            min_relative_gain: 1e-4,
        }
    }
}

/// How many modes each culling rule removed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct CullReport {
    /// Modes in the input set.
    pub total: usize,
    /// Modes kept.
    pub kept: usize,
    /// Dropped: frequency at or above Nyquist.
    pub at_or_above_nyquist: usize,
    /// Dropped: zero frequency.
    pub zero_frequency: usize,
    /// Dropped: decays by more than 54.6 dB per period (no resonance).
    pub overdamped: usize,
    /// Dropped: gain below the relative threshold, or zero.
    pub too_quiet: usize,
}

impl fmt::Display for CullReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "kept {} of {} modes ({} at or above Nyquist, {} at 0 Hz, {} overdamped, {} too quiet)",
            self.kept,
            self.total,
            self.at_or_above_nyquist,
            self.zero_frequency,
            self.overdamped,
            self.too_quiet
        )?;
        if self.kept == 0 && self.at_or_above_nyquist > 0 {
            write!(f, "; a higher sample rate keeps modes above Nyquist")?;
        }
        Ok(())
    }
}

/// Modes that passed [`ModeSet::playable`] for one sample rate: the only input the banks take.
///
/// Invariants: non-empty; `0 < freq_hz < sample_rate_hz / 2`; `0 <= decay_per_s < 2 pi freq_hz`;
/// gains finite and non-zero.
#[derive(Clone, Debug, PartialEq)]
pub struct PlayableModes {
    sample_rate_hz: f64,
    freq_hz: Vec<f64>,
    decay_per_s: Vec<f64>,
    gain: Vec<f64>,
    source_index: Vec<usize>,
}

impl PlayableModes {
    /// The sample rate the modes were culled for.
    pub fn sample_rate_hz(&self) -> f64 {
        self.sample_rate_hz
    }
    /// Number of modes.
    pub fn len(&self) -> usize {
        self.freq_hz.len()
    }
    /// Always false (culling that keeps nothing is an error).
    pub fn is_empty(&self) -> bool {
        self.freq_hz.is_empty()
    }
    /// Damped frequencies in Hz.
    pub fn freq_hz(&self) -> &[f64] {
        &self.freq_hz
    }
    /// Decay rates in 1/s.
    pub fn decay_per_s(&self) -> &[f64] {
        &self.decay_per_s
    }
    /// Gains.
    pub fn gain(&self) -> &[f64] {
        &self.gain
    }
    /// For each kept mode, its index in the source [`ModeSet`].
    pub fn source_index(&self) -> &[usize] {
        &self.source_index
    }
    /// Seconds until the slowest-decaying mode has fallen by `drop_db` (infinite if a mode does
    /// not decay).
    pub fn ring_time_s(&self, drop_db: f64) -> f64 {
        let slowest = self
            .decay_per_s
            .iter()
            .cloned()
            .fold(f64::INFINITY, f64::min);
        drop_db / (20.0 * std::f64::consts::LOG10_E) / slowest
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn set(f: &[f64], d: &[f64], g: &[f64]) -> Result<ModeSet, ModeError> {
        ModeSet::new(f.to_vec(), d.to_vec(), g.to_vec())
    }

    #[test]
    fn json_round_trip_and_extra_fields() {
        let json =
            r#"{"modes":[{"freq_hz":440,"decay_per_s":2.5,"gain":0.5,"note":"A4"}],"source":"x"}"#;
        let m = ModeSet::from_json_str(json, Path::new("t.json")).unwrap();
        assert_eq!(m.freq_hz(), &[440.0]);
        let back = ModeSet::from_json_str(&m.to_json(), Path::new("t.json")).unwrap();
        assert_eq!(m, back);
    }

    #[test]
    fn invalid_values_are_errors_naming_the_mode() {
        assert_eq!(set(&[], &[], &[]), Err(ModeError::Empty));
        let e = set(&[1.0, f64::NAN], &[0.0, 0.0], &[1.0, 1.0]).unwrap_err();
        assert!(matches!(
            e,
            ModeError::NonFinite {
                index: 1,
                field: "freq_hz",
                ..
            }
        ));
        let e = set(&[1.0], &[-1.0], &[1.0]).unwrap_err();
        assert!(e.to_string().contains("decay_per_s = -1"), "{e}");
        let e = set(&[-3.0], &[1.0], &[1.0]).unwrap_err();
        assert!(matches!(e, ModeError::NegativeFrequency { index: 0, .. }));
        let e = ModeSet::from_json_str("{\"modes\":[{\"freq_hz\":1}]}", Path::new("a.json"));
        assert!(e.unwrap_err().to_string().contains("missing field"));
    }

    #[test]
    fn culling_rules() {
        // At 48 kHz: 30 kHz is above Nyquist, 0 Hz is static, 100 Hz decaying at 700/s has
        // d >= 2 pi f (628/s), the 1e-5 gain is 100 dB below the loudest.
        let m = set(
            &[1000.0, 30000.0, 0.0, 100.0, 2000.0, 3000.0],
            &[1.0, 1.0, 1.0, 700.0, 1.0, 1.0],
            &[1.0, 1.0, 1.0, 1.0, 1e-5, -0.5],
        )
        .unwrap();
        let (p, r) = m.playable(48000.0, &CullSettings::default()).unwrap();
        assert_eq!(p.freq_hz(), &[1000.0, 3000.0]);
        assert_eq!(p.source_index(), &[0, 5]);
        assert_eq!(
            (
                r.kept,
                r.at_or_above_nyquist,
                r.zero_frequency,
                r.overdamped,
                r.too_quiet
            ),
            (2, 1, 1, 1, 1)
        );
        // The loudest mode is judged among modes that survive the other rules.
        let only_high = set(&[30000.0], &[1.0], &[1.0]).unwrap();
        let e = only_high
            .playable(48000.0, &CullSettings::default())
            .unwrap_err();
        assert!(e.to_string().contains("higher sample rate"), "{e}");
    }

    #[test]
    fn ring_time_matches_the_slowest_decay() {
        let m = set(&[100.0, 200.0], &[2.0, 4.0], &[1.0, 1.0]).unwrap();
        let (p, _) = m.playable(48000.0, &CullSettings::default()).unwrap();
        // 60 dB = ln(1000) nepers; at 2 /s that is 3.4539 s.
        assert!((p.ring_time_s(60.0) - 1000f64.ln() / 2.0).abs() < 1e-12);
    }
}
