//! The second extraction method: iterative spectral peak picking with local fits and
//! subtraction (Sterling and Lin 2016, sec. 4).
//!
//! Where it sits: one of the two methods [`super::extract`] can run ([`super::Method`]); it
//! returns modes in the same form as the band-split matrix pencil, and the same
//! post-processing (dynamic range, residual, damping fits) follows.
//!
//! Each round takes the spectrum of the residual's first [`FRAME`] samples from the onset
//! (Hann window, zero-padded 2x), picks its strongest local maxima above the noise, and fits
//! each locally: the frequency by a parabola through the log-magnitudes of the peak's three
//! bins; the decay rate from how the magnitude at that frequency falls over later frames
//! (a least-squares line through its logarithm); the amplitude and phase from the windowed
//! sum at the onset, divided by the window's sum of the fitted decay. The round's modes are
//! subtracted from the residual, and rounds go on until the residual keeps less than
//! [`STOP_RESIDUAL_SHARE`] of the first second's energy, no peak stands out of the noise, or
//! `max_modes` are found. A window `FRAME / fs` long cannot split modes closer than about two
//! bins (2-3 Hz at 48 kHz); the subspace method can.

use super::fft::{fft, hann};
use super::ExtractedMode;
use faer::c64;
use std::f64::consts::TAU;

/// Window length, samples (85 ms at 48 kHz), or the recording after the onset where shorter.
pub const FRAME: usize = 4096;

/// Most peaks taken per round (the strongest first).
const PEAKS_PER_ROUND: usize = 12;

/// Most rounds.
const MAX_ROUNDS: usize = 40;

/// The rounds stop when the residual keeps less than this share of the first second's energy
/// (99.9 % explained).
pub const STOP_RESIDUAL_SHARE: f64 = 1e-3;

/// Peaks must stand this many dB above the noise's expected magnitude in a bin.
const PEAK_SNR_DB: f64 = 12.0;

/// Peaks more than this many dB below the round's strongest wait for a later round (where the
/// strong ones no longer leak over them).
const ROUND_RANGE_DB: f64 = 40.0;

/// Frames the decay is fitted over, at most.
const DECAY_FRAMES: usize = 24;

/// Peaks picked in one round must be this many (zero-padded) bins apart: a Hann main lobe is
/// 4 bins wide at 2x padding, half of it either side.
const MIN_PEAK_SPACING_BINS: usize = 4;

/// The modes of `x` from sample `start` (the onset) at `fs`, between `low_hz` and `high_hz`,
/// given the noise's RMS per sample: at most `max_modes`.
pub fn peaks(
    x: &[f64],
    fs: f64,
    start: usize,
    (low_hz, high_hz): (f64, f64),
    noise_rms: f64,
    max_modes: usize,
) -> Vec<ExtractedMode> {
    let mut residual = x[start.min(x.len())..].to_vec();
    let n = residual.len();
    let frame = FRAME.min(n.next_power_of_two() / 2).max(64);
    if n < frame {
        return Vec::new();
    }
    let window = hann(frame);
    let padded = 2 * frame;
    let bin_hz = fs / padded as f64;
    // White noise of RMS sigma gives a windowed bin of expected magnitude sigma ||w||.
    let noise_magnitude = noise_rms * window.iter().map(|w| w * w).sum::<f64>().sqrt();
    let energy = |r: &[f64]| r.iter().take(fs as usize).map(|v| v * v).sum::<f64>();
    let first = energy(&residual);
    let mut modes = Vec::new();
    let mut spectrum = vec![c64::new(0.0, 0.0); padded];
    for _ in 0..MAX_ROUNDS {
        spectrum.fill(c64::new(0.0, 0.0));
        for (s, (v, w)) in spectrum.iter_mut().zip(residual.iter().zip(&window)) {
            *s = c64::new(v * w, 0.0);
        }
        fft(&mut spectrum);
        let magnitude: Vec<f64> = spectrum[..=frame].iter().map(|c| c.norm()).collect();
        let lo = ((low_hz / bin_hz).ceil() as usize).max(2);
        let hi = ((high_hz / bin_hz).floor() as usize).min(frame - 2);
        let strongest = magnitude[lo..=hi].iter().copied().fold(0.0, f64::max);
        let floor = (noise_magnitude * 10f64.powf(PEAK_SNR_DB / 20.0))
            .max(strongest * 10f64.powf(-ROUND_RANGE_DB / 20.0));
        let mut candidates: Vec<usize> = (lo..=hi)
            .filter(|&k| {
                let m = magnitude[k];
                m > floor && m >= magnitude[k - 1] && m > magnitude[k + 1]
            })
            .collect();
        candidates.sort_by(|&a, &b| magnitude[b].total_cmp(&magnitude[a]));
        let mut picked: Vec<usize> = Vec::new();
        for k in candidates {
            if picked.len() == PEAKS_PER_ROUND {
                break;
            }
            if picked
                .iter()
                .all(|&p| p.abs_diff(k) >= MIN_PEAK_SPACING_BINS)
            {
                picked.push(k);
            }
        }
        let round: Vec<ExtractedMode> = picked
            .iter()
            .filter_map(|&k| fit_peak(&residual, fs, &window, &magnitude, k, noise_magnitude))
            .collect();
        if round.is_empty() {
            break;
        }
        for m in &round {
            subtract(&mut residual, fs, m);
        }
        modes.extend(round);
        if modes.len() >= max_modes || energy(&residual) < STOP_RESIDUAL_SHARE * first {
            break;
        }
    }
    modes
}

/// The mode behind the spectral peak at (zero-padded) bin `k`, or `None` where it does not
/// decay (noise, or a leftover of an earlier subtraction).
fn fit_peak(
    r: &[f64],
    fs: f64,
    window: &[f64],
    magnitude: &[f64],
    k: usize,
    noise_magnitude: f64,
) -> Option<ExtractedMode> {
    let frame = window.len();
    let bin_hz = fs / (2 * frame) as f64;
    // A parabola through the log-magnitudes: the peak's fractional bin.
    let (a, b, c) = (
        magnitude[k - 1].max(1e-300).ln(),
        magnitude[k].max(1e-300).ln(),
        magnitude[k + 1].max(1e-300).ln(),
    );
    let denominator = a - 2.0 * b + c;
    let offset = if denominator < 0.0 {
        (0.5 * (a - c) / denominator).clamp(-0.5, 0.5)
    } else {
        0.0
    };
    let freq_hz = (k as f64 + offset) * bin_hz;
    // The magnitude at that frequency frame by frame (hop a quarter frame).
    let hop = frame / 4;
    let at = |from: usize| -> c64 {
        let step = c64::from_polar(1.0, -TAU * freq_hz / fs);
        let mut phasor = c64::new(1.0, 0.0);
        let mut sum = c64::new(0.0, 0.0);
        for (v, w) in r[from..from + frame].iter().zip(window) {
            sum += phasor * (v * w);
            phasor *= step;
        }
        sum
    };
    let onset = at(0);
    let mut points = vec![(0.0, onset.norm().max(1e-300).ln())];
    let mut from = hop;
    while points.len() < DECAY_FRAMES && from + frame <= r.len() {
        let m = at(from).norm();
        // Stop at the noise, or 60 dB down.
        if m < 2.0 * noise_magnitude || m < 1e-3 * onset.norm() {
            break;
        }
        points.push((from as f64 / fs, m.ln()));
        from += hop;
    }
    if points.len() < 2 {
        return None;
    }
    // Least-squares slope of ln|A| against time: -d.
    let count = points.len() as f64;
    let (mt, ml) = (
        points.iter().map(|p| p.0).sum::<f64>() / count,
        points.iter().map(|p| p.1).sum::<f64>() / count,
    );
    let slope = points.iter().map(|p| (p.0 - mt) * (p.1 - ml)).sum::<f64>()
        / points.iter().map(|p| (p.0 - mt) * (p.0 - mt)).sum::<f64>();
    let decay_per_s = -slope;
    if !(decay_per_s > 0.0 && decay_per_s.is_finite()) {
        return None;
    }
    // The windowed sum of (a / 2) e^(i phi) e^(-d t) over the frame at the onset.
    let weight: f64 = window
        .iter()
        .enumerate()
        .map(|(i, w)| w * (-decay_per_s * i as f64 / fs).exp())
        .sum();
    let complex = onset * (2.0 / weight);
    Some(ExtractedMode {
        freq_hz,
        decay_per_s,
        gain: complex.norm(),
        phase: complex.arg(),
    })
}

/// Subtracts `a e^(-d t) cos(2 pi f t + phi)` from `r`, `t` from its first sample.
fn subtract(r: &mut [f64], fs: f64, m: &ExtractedMode) {
    let step = c64::from_polar((-m.decay_per_s / fs).exp(), TAU * m.freq_hz / fs);
    let mut z = c64::from_polar(m.gain, m.phase);
    for v in r.iter_mut() {
        *v -= z.re;
        z *= step;
        if z.norm_sqr() < 1e-40 {
            break;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two well-separated modes come back to 0.01 % in frequency, 2 % in decay and 0.1 dB in
    /// amplitude (no noise: what is left is the window's and the parabola's bias).
    #[test]
    fn two_clean_modes_come_back() {
        let fs = 48_000.0;
        let truth = [
            ExtractedMode {
                freq_hz: 523.3,
                decay_per_s: 4.0,
                gain: 0.5,
                phase: 0.3,
            },
            ExtractedMode {
                freq_hz: 2011.7,
                decay_per_s: 11.0,
                gain: 0.2,
                phase: -1.2,
            },
        ];
        let x = crate::analysis::synthetic::ring_out(&truth, fs, 48_000);
        let found = peaks(&x, fs, 0, (40.0, 20_000.0), 1e-9, 10);
        for t in &truth {
            let m = found
                .iter()
                .filter(|m| (m.freq_hz / t.freq_hz - 1.0).abs() < 1e-3)
                .max_by(|a, b| a.gain.total_cmp(&b.gain))
                .unwrap_or_else(|| panic!("{t:?} not in {found:?}"));
            assert!((m.freq_hz / t.freq_hz - 1.0).abs() < 1e-4, "{m:?} vs {t:?}");
            assert!(
                (m.decay_per_s / t.decay_per_s - 1.0).abs() < 0.02,
                "{m:?} vs {t:?}"
            );
            assert!(
                (20.0 * (m.gain / t.gain).log10()).abs() < 0.1,
                "{m:?} vs {t:?}"
            );
        }
    }
}
