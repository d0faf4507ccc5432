//! A radix-2 FFT, the Hann window and the short-time spectra the analysis uses (the log-mel
//! distance of [`super::resynth`], the spectral peaks of [`super::peaks`], the loss of
//! [`super::refine`]).
//!
//! Written here (40 lines) rather than taken from an FFT crate: a crate would add its build to
//! every clean build of the test suite, which is at its time budget, for two non-real-time
//! uses whose frames are powers of two.

use faer::c64;
use std::f64::consts::{PI, TAU};

/// In-place iterative radix-2 FFT (`x.len()` a power of two): `X_k = sum_n x_n e^(-2 pi i kn/N)`.
pub fn fft(x: &mut [c64]) {
    let n = x.len();
    debug_assert!(n.is_power_of_two());
    let bits = n.trailing_zeros();
    for i in 0..n {
        let j = i.reverse_bits() >> (usize::BITS - bits);
        if i < j {
            x.swap(i, j);
        }
    }
    let mut len = 2;
    while len <= n {
        let step = c64::from_polar(1.0, -2.0 * PI / len as f64);
        for chunk in x.chunks_mut(len) {
            let mut w = c64::new(1.0, 0.0);
            let (lo, hi) = chunk.split_at_mut(len / 2);
            for (a, b) in lo.iter_mut().zip(hi.iter_mut()) {
                let t = *b * w;
                *b = *a - t;
                *a += t;
                w *= step;
            }
        }
        len *= 2;
    }
}

/// A periodic Hann window of `n` samples.
pub fn hann(n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| 0.5 - 0.5 * (TAU * i as f64 / n as f64).cos())
        .collect()
}

/// The frames' half spectra (bins `0..=size/2`) of `x`.
pub fn stft(x: &[f64], window: &[f64], hop: usize) -> Vec<Vec<c64>> {
    let size = window.len();
    let mut buf = vec![c64::new(0.0, 0.0); size];
    let mut out = Vec::new();
    let mut at = 0;
    while at + size <= x.len() {
        for (b, (v, w)) in buf.iter_mut().zip(x[at..at + size].iter().zip(window)) {
            *b = c64::new(v * w, 0.0);
        }
        fft(&mut buf);
        out.push(buf[..=size / 2].to_vec());
        at += hop;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The FFT against the DFT's definition on a random vector (rounding grows like
    /// `eps log2 N`; 1e-9 of the norm is far above it and far below any indexing error).
    #[test]
    fn fft_matches_the_dft() {
        let n = 64;
        let mut rng = crate::rng::SplitMix64::new(3);
        let x: Vec<c64> = (0..n)
            .map(|_| c64::new(rng.unit() - 0.5, rng.unit() - 0.5))
            .collect();
        let mut y = x.clone();
        fft(&mut y);
        for (k, yk) in y.iter().enumerate() {
            let want: c64 = x
                .iter()
                .enumerate()
                .map(|(j, &v)| v * c64::from_polar(1.0, -TAU * (j * k) as f64 / n as f64))
                .sum();
            assert!((yk - want).norm() < 1e-9, "bin {k}: {yk} vs {want}");
        }
    }
}
