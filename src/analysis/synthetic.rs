//! Synthetic strikes with known modes, the truth the extraction is tested and benchmarked
//! against (`tests/analysis.rs`, `benches/analysis.rs`): random sets of modes from 60 Hz to
//! 18 kHz (a fifth of them doubled by a partner 0.5-2 Hz away, as the split pairs of
//! symmetric objects), amplitudes over 30 dB, decays 0.5-200 /s, white noise at a chosen SNR
//! below the strongest mode, a lead-in before the strike.

use super::ExtractedMode;
use crate::rng::SplitMix64;
use std::f64::consts::TAU;

/// The crate's SplitMix64 stream as uniform and normal draws.
struct Rng(SplitMix64);
impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0.unit()
    }
    /// A standard normal draw (Box-Muller).
    fn gauss(&mut self) -> f64 {
        let (u, v) = (self.uniform().max(1e-300), self.uniform());
        (-2.0 * u.ln()).sqrt() * (TAU * v).cos()
    }
}

/// A synthetic strike and its truth.
pub struct Case {
    /// Sample rate, Hz.
    pub fs: f64,
    /// Seconds of silence (noise) before the strike.
    pub lead_s: f64,
    /// The modes it is made of (amplitudes and phases at the strike).
    pub modes: Vec<ExtractedMode>,
    /// The noise's RMS per sample.
    pub noise_rms: f64,
    /// The recording.
    pub signal: Vec<f64>,
}

/// A random strike: `count` modes, log-uniform in frequency, a fifth of them doubled by a
/// partner 0.5-2 Hz away (the split pairs of symmetric objects), amplitudes over 30 dB,
/// decays log-uniform in 0.5-200 /s; noise at `snr_db` below the strongest mode.
pub fn case(seed: u64, count: usize, snr_db: f64, duration_s: f64) -> Case {
    let mut rng = Rng(SplitMix64::new(seed));
    let fs = if seed.is_multiple_of(2) {
        48_000.0
    } else {
        44_100.0
    };
    let mut modes = Vec::new();
    while modes.len() < count {
        let f = 60.0 * (300.0f64).powf(rng.uniform());
        let decay = 0.5 * 400f64.powf(rng.uniform());
        let gain = 10f64.powf(-1.5 * rng.uniform());
        let phase = TAU * rng.uniform();
        modes.push(ExtractedMode {
            freq_hz: f,
            decay_per_s: decay,
            gain,
            phase,
        });
        if rng.uniform() < 0.2 && modes.len() < count {
            let df = 0.5 + 1.5 * rng.uniform();
            modes.push(ExtractedMode {
                freq_hz: f + df,
                decay_per_s: decay * (0.8 + 0.4 * rng.uniform()),
                gain: gain * (0.5 + rng.uniform()),
                phase: TAU * rng.uniform(),
            });
        }
    }
    let lead_s = 0.02 + 0.05 * rng.uniform();
    let noise_rms = 10f64.powf(-snr_db / 20.0);
    let signal = ring(&modes, fs, lead_s, duration_s, noise_rms, &mut rng);
    // The signal was scaled by 0.2 (headroom): so are the amplitudes and the noise.
    for m in &mut modes {
        m.gain *= 0.2;
    }
    Case {
        fs,
        lead_s,
        modes,
        noise_rms: 0.2 * noise_rms,
        signal,
    }
}

/// A strike of given modes (a solved object's, say): scaled so the strongest mode's
/// amplitude is 0.2, with white noise `snr_db` below it and a `lead_s` lead-in of noise.
pub fn strike_of(
    modes: &[ExtractedMode],
    fs: f64,
    lead_s: f64,
    duration_s: f64,
    snr_db: f64,
    seed: u64,
) -> Case {
    let mut rng = Rng(SplitMix64::new(seed));
    let loudest = modes.iter().map(|m| m.gain.abs()).fold(0.0, f64::max);
    let unit: Vec<ExtractedMode> = modes
        .iter()
        .map(|m| ExtractedMode {
            gain: m.gain / loudest,
            ..*m
        })
        .collect();
    let noise_rms = 10f64.powf(-snr_db / 20.0);
    let signal = ring(&unit, fs, lead_s, duration_s, noise_rms, &mut rng);
    Case {
        fs,
        lead_s,
        modes: unit
            .iter()
            .map(|m| ExtractedMode {
                gain: 0.2 * m.gain,
                ..*m
            })
            .collect(),
        noise_rms: 0.2 * noise_rms,
        signal,
    }
}

/// `n` samples at `fs` of the modes rung from `t = 0`, noise-free, in their own units: the
/// exact signal a method is tested against.
pub fn ring_out(modes: &[ExtractedMode], fs: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| {
            let t = i as f64 / fs;
            modes
                .iter()
                .map(|m| {
                    m.gain * (-m.decay_per_s * t).exp() * (TAU * m.freq_hz * t + m.phase).cos()
                })
                .sum()
        })
        .collect()
}

/// A solved object's struck modes as a recording holds them (the oscillating ones below
/// `max_hz` with a non-zero gain): each rings as `g e^(-d t) sin(2 pi f t)`, i.e. phase
/// `-pi/2`. The input of a strike rendered from FEM ([`strike_of`]).
pub fn recorded_modes(struck: &[crate::basis::StruckMode], max_hz: f64) -> Vec<ExtractedMode> {
    struck
        .iter()
        .filter_map(|m| match m.damped {
            crate::material::DampedMode::Oscillating {
                freq_hz,
                decay_per_s,
            } if freq_hz < max_hz && m.gain != 0.0 => Some(ExtractedMode {
                freq_hz,
                decay_per_s,
                gain: m.gain,
                phase: -std::f64::consts::FRAC_PI_2,
            }),
            _ => None,
        })
        .collect()
}

/// `0.2 (sum of the modes from lead_s on + noise)`, `duration_s` at `fs`.
fn ring(
    modes: &[ExtractedMode],
    fs: f64,
    lead_s: f64,
    duration_s: f64,
    noise_rms: f64,
    rng: &mut Rng,
) -> Vec<f64> {
    let n = (duration_s * fs) as usize;
    (0..n)
        .map(|i| {
            let t = i as f64 / fs - lead_s;
            let ring: f64 = if t < 0.0 {
                0.0
            } else {
                modes
                    .iter()
                    .map(|m| {
                        m.gain * (-m.decay_per_s * t).exp() * (TAU * m.freq_hz * t + m.phase).cos()
                    })
                    .sum()
            };
            0.2 * (ring + noise_rms * rng.gauss())
        })
        .collect()
}

/// How one strike's extraction compares with its truth.
#[derive(Clone, Debug, Default)]
pub struct Score {
    /// Resolvable modes 20 dB above the noise.
    pub visible: usize,
    /// Of those, found within 0.1 % in frequency.
    pub found: usize,
    /// Worst relative decay error of the found ones.
    pub worst_decay: f64,
    /// Worst amplitude error of the found ones, dB.
    pub worst_db: f64,
    /// Reported modes that stand for no true mode.
    pub spurious: usize,
    /// Modes reported.
    pub reported: usize,
    /// Every found mode's relative decay error and amplitude error (dB), for percentiles.
    pub errors: Vec<(f64, f64)>,
}

impl Score {
    /// Adds another strike's score (worst cases are the worst of both).
    pub fn add(&mut self, s: &Score) {
        self.visible += s.visible;
        self.found += s.found;
        self.worst_decay = self.worst_decay.max(s.worst_decay);
        self.worst_db = self.worst_db.max(s.worst_db);
        self.spurious += s.spurious;
        self.reported += s.reported;
        self.errors.extend_from_slice(&s.errors);
    }

    /// The `q`-quantile (0-1) of the decay errors and of the amplitude errors.
    pub fn quantile(&self, q: f64) -> (f64, f64) {
        let pick = |mut v: Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v.get(((v.len() as f64 - 1.0) * q).round() as usize)
                .copied()
                .unwrap_or(0.0)
        };
        (
            pick(self.errors.iter().map(|e| e.0).collect()),
            pick(self.errors.iter().map(|e| e.1).collect()),
        )
    }
}

/// A mode the data can tell apart: a quality factor of at least 10 (at Q 5 a "mode" is a
/// thump a few cycles long) and separated from every other mode by more than their mean
/// half-power bandwidth, `(d_1 + d_2) / 2 pi`: closer pairs are one peak whatever the method
/// (the pairs closer than 2 Hz are in the data; they count where their decay rates
/// are below ~6 /s, which real split pairs of bells and bowls are).
pub fn resolvable(m: &ExtractedMode, all: &[ExtractedMode]) -> bool {
    let q = std::f64::consts::PI * m.freq_hz / m.decay_per_s;
    q >= 10.0
        && all.iter().all(|o| {
            o == m || (o.freq_hz - m.freq_hz).abs() > (o.decay_per_s + m.decay_per_s) / TAU
        })
}

/// How `found` compares with the strike's truth (see [`Score`]).
pub fn score(c: &Case, found: &[ExtractedMode]) -> Score {
    let mut s = Score {
        reported: found.len(),
        ..Score::default()
    };
    for m in c
        .modes
        .iter()
        .filter(|m| m.gain / c.noise_rms >= 10.0 && m.freq_hz < 18_000.0 && resolvable(m, &c.modes))
    {
        s.visible += 1;
        let nearest = found.iter().min_by(|x, y| {
            (x.freq_hz - m.freq_hz)
                .abs()
                .total_cmp(&(y.freq_hz - m.freq_hz).abs())
        });
        if let Some(e) = nearest.filter(|e| (e.freq_hz - m.freq_hz).abs() <= 1e-3 * m.freq_hz) {
            s.found += 1;
            let decay = (e.decay_per_s - m.decay_per_s).abs() / m.decay_per_s;
            let db = (20.0 * (e.gain / m.gain).log10()).abs();
            s.worst_decay = s.worst_decay.max(decay);
            s.worst_db = s.worst_db.max(db);
            s.errors.push((decay, db));
        }
    }
    // Spurious: within neither 0.1 % nor the half-power half-bandwidth of any true mode.
    s.spurious = found
        .iter()
        .filter(|e| {
            c.modes.iter().all(|m| {
                (e.freq_hz - m.freq_hz).abs() > (1e-3 * m.freq_hz).max(m.decay_per_s / TAU)
            })
        })
        .count();
    s
}
