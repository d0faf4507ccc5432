//! Band splitting: a recording cut into narrow frequency bands, each shifted to zero
//! frequency and decimated, so the matrix pencil ([`super::pencil`]) works on a few hundred
//! samples holding a few modes instead of the whole recording holding all of them.
//!
//! Where it sits: between the onset ([`super::extract`]) and the pencil. Band `k` owns the
//! frequencies `[edges[k], edges[k + 1])` (its core; the cores tile the analysed range, so
//! each mode is reported by exactly one band). Its signal is the recording times
//! `e^(-i 2 pi f_c t)` (`f_c` the core's centre), low-passed by a Blackman-windowed sinc whose
//! passband is flat over the core and half a core beyond it, evaluated only at the decimated
//! instants (`rate = 2 x core width`): `y[m] = sum_j h[j] x[n_m + j] e^(-i 2 pi f_c t_(n_m + j))`.
//! A mode `a e^(-d t) cos(2 pi f t + phi)` becomes `(a / 2) e^(i phi) e^((-d + i 2 pi (f - f_c)) t)`
//! at the same instants: decay rates are unchanged, frequencies shift by `f_c`.

use faer::c64;
use std::f64::consts::TAU;

/// One band's core and its decimated baseband signal.
#[derive(Clone, Debug)]
pub struct Band {
    /// The core's lower edge, Hz.
    pub low_hz: f64,
    /// The core's upper edge, Hz.
    pub high_hz: f64,
    /// The shift, Hz: the core's centre.
    pub centre_hz: f64,
    /// The decimated sample rate, Hz.
    pub rate_hz: f64,
    /// Seconds from the analysis start to `samples[0]`.
    pub start_s: f64,
    /// The baseband signal.
    pub samples: Vec<c64>,
}

/// Band edges from `low_hz` to `high_hz`: each band `relative` times its lower edge wide, at
/// least `min_width_hz` and at most `max_width_hz`. The cap keeps the decimated rate low, so a
/// band's few hundred samples span long enough to tell modes 2 Hz apart.
pub fn edges(low_hz: f64, high_hz: f64, relative: f64, width_hz: (f64, f64)) -> Vec<f64> {
    let (min_width_hz, max_width_hz) = width_hz;
    let mut e = vec![low_hz];
    while *e.last().expect("one edge") < high_hz {
        let last = *e.last().expect("one edge");
        let width = (last * relative).clamp(min_width_hz, max_width_hz);
        let next = (last + width).min(high_hz);
        e.push(next);
        if high_hz - next < 0.1 * (next - last) {
            *e.last_mut().expect("one edge") = high_hz;
            break;
        }
    }
    e
}

/// Filter half-length in units of `sample_rate / core width`: the Blackman window's transition
/// is ~5.5 / (2 H + 1) of the sample rate, so 6 makes it ~0.45 core widths, between the flat
/// passband (the core plus half a core) and the alias-free stopband. The band's first sample
/// is therefore `6 / width` seconds after the onset ([`Band::start_s`]).
pub const HALF_LENGTH_PER_INVERSE_WIDTH: f64 = 6.0;

/// At most this many decimated samples per band: enough to resolve modes 2 Hz apart in the
/// bands where that matters, few enough that the pencil's SVD stays small.
pub const MAX_BAND_SAMPLES: usize = 480;

/// The band `[low_hz, high_hz)` of `x` (sample rate `fs`), from sample `start` on.
pub fn band(x: &[f64], fs: f64, start: usize, low_hz: f64, high_hz: f64) -> Band {
    let width = high_hz - low_hz;
    let centre = 0.5 * (low_hz + high_hz);
    let decimation = ((fs / (2.0 * width)).floor() as usize).max(1);
    let rate = fs / decimation as f64;
    let half = ((HALF_LENGTH_PER_INVERSE_WIDTH * fs / width).ceil() as usize).max(4);
    // Low-pass with its -6 dB point at the core's half-width plus half a core.
    let cutoff = width / fs; // one-sided, in cycles per sample
    let taps: Vec<f64> = (0..=2 * half)
        .map(|j| {
            let k = j as f64 - half as f64;
            let sinc = if k == 0.0 {
                2.0 * cutoff
            } else {
                (TAU * cutoff * k).sin() / (std::f64::consts::PI * k)
            };
            let w = j as f64 / (2 * half) as f64;
            let blackman = 0.42 - 0.5 * (TAU * w).cos() + 0.08 * (2.0 * TAU * w).cos();
            sinc * blackman
        })
        .collect();
    let gain: f64 = taps.iter().sum();
    // The recording shifted by -f_c once (phase relative to the analysis start keeps the
    // numbers small), over the samples the decimated outputs read.
    let outputs = (x.len().saturating_sub(start + 2 * half) / decimation + 1).min(MAX_BAND_SAMPLES);
    let end = (start + 2 * half + (outputs - 1) * decimation + 1).min(x.len());
    let omega = TAU * centre / fs;
    // Real and imaginary parts apart, so the filter below is two real dot products the
    // compiler vectorises. The phasor advances by one multiplication a sample and is
    // recomputed exactly every 1024 to keep rounding from accumulating.
    let step = c64::from_polar(1.0, -omega);
    let (mut re, mut im) = (
        Vec::with_capacity(end - start),
        Vec::with_capacity(end - start),
    );
    let mut phasor = c64::new(1.0, 0.0);
    for (k, &v) in x[start..end].iter().enumerate() {
        if k % 1024 == 0 {
            phasor = c64::from_polar(1.0, -omega * k as f64);
        }
        re.push(v * phasor.re);
        im.push(v * phasor.im);
        phasor *= step;
    }
    let dot = |a: &[f64]| -> f64 {
        // Eight partial sums: a sum in one accumulator cannot be vectorised (its rounding
        // order is fixed); eight can.
        let mut acc = [0.0f64; 8];
        let (hc, ac) = (taps.chunks_exact(8), a.chunks_exact(8));
        let (hr, ar) = (hc.remainder(), ac.remainder());
        for (h, v) in hc.zip(ac) {
            for l in 0..8 {
                acc[l] += h[l] * v[l];
            }
        }
        acc.iter().sum::<f64>() + hr.iter().zip(ar).map(|(h, v)| h * v).sum::<f64>()
    };
    let samples: Vec<c64> = (0..outputs)
        .map(|m| m * decimation)
        .take_while(|&k| k + 2 * half < re.len())
        .map(|k| {
            let span = k..=k + 2 * half;
            c64::new(dot(&re[span.clone()]), dot(&im[span])) / gain
        })
        .collect();
    Band {
        low_hz,
        high_hz,
        centre_hz: centre,
        rate_hz: rate,
        start_s: half as f64 / fs,
        samples,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edges_tile_the_range_with_growing_bands() {
        let e = edges(40.0, 20_000.0, 0.25, (12.0, 400.0));
        assert_eq!(e[0], 40.0);
        assert_eq!(*e.last().unwrap(), 20_000.0);
        for w in e.windows(2) {
            assert!(w[1] > w[0]);
        }
        assert!(e.windows(2).all(
            |w| (w[1] - w[0] >= 12.0 - 1e-9 && w[1] - w[0] <= 400.0 + 1e-9) || w[1] == 20_000.0
        ));
    }

    /// A mode inside the core comes out as `(a / 2) e^(i phi)` times its baseband exponential,
    /// to the filter's passband ripple (Blackman: ~1e-4 in amplitude); one a core width away
    /// from the core is suppressed below 1e-3.
    #[test]
    fn a_core_mode_passes_and_a_far_one_is_stopped() {
        let fs = 48_000.0;
        let (f, d, a, phi) = (1_030.0, 3.0, 0.8, 0.4);
        let x: Vec<f64> = (0..48_000)
            .map(|n| {
                let t = n as f64 / fs;
                a * (-d * t).exp() * (TAU * f * t + phi).cos()
            })
            .collect();
        let b = band(&x, fs, 0, 1_000.0, 1_100.0);
        assert!(b.samples.len() > 100);
        for (m, y) in b.samples.iter().enumerate().take(50) {
            let t = b.start_s + m as f64 / b.rate_hz;
            let want = c64::from_polar(0.5 * a * (-d * t).exp(), phi + TAU * (f - b.centre_hz) * t);
            assert!((y - want).norm() < 2e-4 * a, "sample {m}: {y} vs {want}");
        }
        let far = band(&x, fs, 0, 1_200.0, 1_300.0);
        let peak = far.samples.iter().map(|y| y.norm()).fold(0.0, f64::max);
        assert!(peak < 1e-3 * a, "leak {peak}");
    }
}
