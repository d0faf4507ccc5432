//! Resynthesis: the modes found in a recording played back through the product's oscillator
//! bank, and how far that sounds from the recording (a log-mel spectral distance).
//!
//! Where it sits: after [`super::extract`]; `modalforge analyze --resynth OUT.wav` writes
//! [`render`]'s output and reports [`log_mel_distance_db`] for it and for a baseline that keeps
//! only the [`BASELINE_MODES`] loudest modes.
//!
//! The distance follows the mel-spectral loss of Diaz et al. 2023 (eq. 1-4), in decibels so it
//! reads as a level: both signals are cut into Hann frames of [`FRAME`] samples every [`HOP`],
//! each frame's power spectrum is summed into [`MEL_BANDS`] triangular mel bands from
//! [`MEL_LOW_HZ`] to 16 kHz (or Nyquist), the band powers go to dB, both are floored at
//! [`DYNAMIC_RANGE_DB`] below the recording's loudest band (so what neither can hear, the
//! recording's noise floor included, does not count), and the distance is the mean absolute
//! difference over every frame and band from the onset on.
//!
//! The FFT is [`super::fft`]'s.

use super::fft::{hann, stft};
use super::ExtractedMode;
use crate::modes::{CullSettings, ModeError, ModeSet};
use crate::synth::render::{render as render_bank, BankKind, Performance, RenderError};
use crate::synth::Excitation;

/// Modes the baseline keeps (the loudest at the onset).
pub const BASELINE_MODES: usize = 5;

/// Frame length of the distance's spectrogram, samples.
pub const FRAME: usize = 2048;

/// Hop between frames, samples.
pub const HOP: usize = 512;

/// Mel bands of the distance's spectrogram.
pub const MEL_BANDS: usize = 64;

/// Lowest mel band edge, Hz.
pub const MEL_LOW_HZ: f64 = 40.0;

/// Band powers more than this far below the recording's loudest are floored there.
pub const DYNAMIC_RANGE_DB: f64 = 60.0;

/// Why the modes could not be played.
#[derive(Debug, thiserror::Error)]
pub enum ResynthError {
    /// The modes do not make a playable set.
    #[error("the recording's modes cannot be played: {0}")]
    Modes(#[from] ModeError),
    /// The bank refused the strike.
    #[error("the recording's modes cannot be played: {0}")]
    Render(#[from] RenderError<std::convert::Infallible>),
}

/// The modes as a mode set the banks play: each rings as `g e^(-d t) sin(2 pi f t)`, so a
/// mode's phase is kept only as the sign of `g` (the one a velocity-1 impulse can give),
/// chosen so its first swing goes the recorded way (`-sin phi`; `+` at `phi = 0`).
pub fn mode_set(modes: &[ExtractedMode]) -> Result<ModeSet, ModeError> {
    let sign = |phase: f64| if -phase.sin() < 0.0 { -1.0 } else { 1.0 };
    ModeSet::new(
        modes.iter().map(|m| m.freq_hz).collect(),
        modes.iter().map(|m| m.decay_per_s).collect(),
        modes.iter().map(|m| m.gain * sign(m.phase)).collect(),
    )
}

/// `len` samples at `fs`: silence until `onset_s`, then the modes struck once through the
/// oscillator bank (an ideal impulse at velocity 1, in the recording's units).
pub fn render(
    modes: &[ExtractedMode],
    fs: f64,
    onset_s: f64,
    len: usize,
) -> Result<Vec<f64>, ResynthError> {
    let start = ((onset_s * fs).round().max(0.0) as usize).min(len);
    let mut out = vec![0.0; start];
    out.reserve(len - start);
    let (playable, _) = mode_set(modes)?.playable(fs, &CullSettings::default())?;
    render_bank(
        &playable,
        BankKind::Oscillator,
        Performance::Strike {
            excitation: Excitation::Impulse,
            velocity: 1.0,
        },
        len - start,
        0,
        |block: &[f32]| {
            out.extend(block.iter().map(|&v| v as f64));
            Ok::<(), std::convert::Infallible>(())
        },
    )?;
    Ok(out)
}

/// The [`BASELINE_MODES`] loudest modes, by frequency.
pub fn baseline(modes: &[ExtractedMode]) -> Vec<ExtractedMode> {
    let mut loudest = modes.to_vec();
    loudest.sort_by(|a, b| b.gain.abs().total_cmp(&a.gain.abs()));
    loudest.truncate(BASELINE_MODES);
    loudest.sort_by(|a, b| a.freq_hz.total_cmp(&b.freq_hz));
    loudest
}

/// The log-mel spectral distance in dB between `reference` (the recording) and `other`, both
/// at `fs`, from sample `start` on (module docs). Over the frames both cover; 0 for identical
/// signals, infinite when neither holds a whole frame.
pub fn log_mel_distance_db(reference: &[f64], other: &[f64], fs: f64, start: usize) -> f64 {
    let a = log_mel(&reference[start.min(reference.len())..], fs);
    let b = log_mel(&other[start.min(other.len())..], fs);
    let frames = a.len().min(b.len());
    if frames == 0 {
        return f64::INFINITY;
    }
    let floor = a
        .iter()
        .flatten()
        .copied()
        .fold(f64::NEG_INFINITY, f64::max)
        - DYNAMIC_RANGE_DB;
    let mut total = 0.0;
    for (fa, fb) in a.iter().zip(&b).take(frames) {
        for (&x, &y) in fa.iter().zip(fb) {
            total += (x.max(floor) - y.max(floor)).abs();
        }
    }
    total / (frames * MEL_BANDS) as f64
}

/// Each frame's mel band powers in dB.
fn log_mel(x: &[f64], fs: f64) -> Vec<[f64; MEL_BANDS]> {
    let bank = mel_bank(fs);
    stft(x, &hann(FRAME), HOP)
        .iter()
        .map(|spectrum| {
            let mut bands = [0.0; MEL_BANDS];
            for (band, filter) in bands.iter_mut().zip(&bank) {
                let power: f64 = filter
                    .iter()
                    .map(|&(k, w)| w * spectrum[k].norm_sqr())
                    .sum();
                *band = 10.0 * power.max(1e-30).log10();
            }
            bands
        })
        .collect()
}

/// Triangular mel filters: for each band, its FFT bins and weights.
fn mel_bank(fs: f64) -> Vec<Vec<(usize, f64)>> {
    let mel = |f: f64| 2595.0 * (1.0 + f / 700.0).log10();
    let hz = |m: f64| 700.0 * (10f64.powf(m / 2595.0) - 1.0);
    let high = (0.5 * fs).min(16_000.0);
    let edges: Vec<f64> = (0..MEL_BANDS + 2)
        .map(|i| {
            hz(mel(MEL_LOW_HZ) + (mel(high) - mel(MEL_LOW_HZ)) * i as f64 / (MEL_BANDS + 1) as f64)
        })
        .collect();
    let bin_hz = fs / FRAME as f64;
    (0..MEL_BANDS)
        .map(|b| {
            let (lo, mid, hi) = (edges[b], edges[b + 1], edges[b + 2]);
            ((lo / bin_hz).ceil() as usize..=((hi / bin_hz).floor() as usize).min(FRAME / 2))
                .map(|k| {
                    let f = k as f64 * bin_hz;
                    let w = if f <= mid {
                        (f - lo) / (mid - lo)
                    } else {
                        (hi - f) / (hi - mid)
                    };
                    (k, w.max(0.0))
                })
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{PI, TAU};

    /// The distance is 0 for a signal against itself, 6.02 dB for white noise against a copy
    /// at twice the amplitude (every band is above the floor and 20 log10 2 up), and the
    /// resynthesis of a mode set is within 0.5 dB of the same modes summed in f64 (the bank
    /// plays them in f32).
    #[test]
    fn the_distance_reads_as_a_level() {
        let fs = 48_000.0;
        let modes = [
            ExtractedMode {
                freq_hz: 440.0,
                decay_per_s: 3.0,
                gain: 0.3,
                phase: -PI / 2.0,
            },
            ExtractedMode {
                freq_hz: 1234.0,
                decay_per_s: 8.0,
                gain: 0.2,
                phase: -PI / 2.0,
            },
        ];
        let x = render(&modes, fs, 0.0, 24_000).unwrap();
        assert_eq!(log_mel_distance_db(&x, &x, fs, 0), 0.0);
        let mut rng = crate::rng::SplitMix64::new(9);
        let noise: Vec<f64> = (0..24_000).map(|_| rng.unit() - 0.5).collect();
        let louder: Vec<f64> = noise.iter().map(|v| 2.0 * v).collect();
        let d = log_mel_distance_db(&noise, &louder, fs, 0);
        assert!((d - 20.0 * 2f64.log10()).abs() < 1e-9, "{d}");
        let exact: Vec<f64> = (0..24_000)
            .map(|i| {
                let t = i as f64 / fs;
                modes
                    .iter()
                    .map(|m| m.gain * (-m.decay_per_s * t).exp() * (TAU * m.freq_hz * t).sin())
                    .sum()
            })
            .collect();
        let d = log_mel_distance_db(&exact, &x, fs, 0);
        assert!(d < 0.5, "{d}");
    }
}
