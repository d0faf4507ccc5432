//! The matrix pencil method: the damped complex exponentials in a short complex signal.
//!
//! Where it sits: [`super::extract`] runs it on each band's demodulated, decimated signal
//! ([`super::bands`]). A sum of `K` damped exponentials `y[m] = sum_k c_k z_k^m` makes a Hankel
//! matrix `Y[i][j] = y[i + j]` of rank `K` whose column space is spanned by the vectors
//! `(z_k^i)_i`; the `K` leading left singular vectors `U` span it too, and since shifting those
//! vectors by one row multiplies them by `z_k`, the eigenvalues of `U_1^+ U_2` (`U` without its
//! last, and without its first, row) are the poles `z_k` (Hua and Sarkar 1990; in this
//! singular-vector form it is also ESPRIT, Roy and Kailath 1989). Noise fills the other
//! singular values at a flat level; the model order is the number above it. The amplitudes
//! `c_k` then follow by least squares on the Vandermonde matrix of the poles.

use faer::c64;
use faer::linalg::solvers::SolveLstsqCore;
use faer::{Conj, Mat};

/// A pole and its complex amplitude at the first sample: the term `c z^m`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Term {
    /// The pole `z` (per sample).
    pub pole: c64,
    /// The amplitude `c`.
    pub amplitude: c64,
}

/// Largest pencil parameter (Hankel columns - 1).
const MAX_PENCIL: usize = 160;

/// Singular values above this many times the noise level count as signal.
const ORDER_THRESHOLD: f64 = 4.0;

/// The terms of `y` (at most `max_order`), and the noise level: the RMS per sample of what
/// the model leaves. `None` if `y` is too short to say anything (under 8 samples).
pub fn pencil(y: &[c64], max_order: usize) -> Option<(Vec<Term>, f64)> {
    let len = y.len();
    if len < 8 {
        return None;
    }
    // Pencil parameter: a third of the length is the variance-optimal choice for one mode in
    // noise (Hua and Sarkar 1990); capped, since the SVD costs `len p^2` and a band holds far
    // fewer than `MAX_PENCIL / 2` modes.
    let p = (len / 3).min(MAX_PENCIL);
    let rows = len - p;
    let hankel = Mat::<c64>::from_fn(rows, p + 1, |i, j| y[i + j]);
    // The right singular vectors and singular values from the Hermitian eigenproblem of the
    // Gram matrix `Y^H Y` (a matrix product and a (p+1)-sized eigensolver: half the time of
    // the SVD). Squaring the singular values costs accuracy only below 1e-8 of the largest,
    // far under any noise floor a recording has.
    let gram = hankel.adjoint() * &hankel;
    let evd = gram.self_adjoint_eigen(faer::Side::Lower).ok()?;
    let values = evd.S().column_vector();
    // Descending singular values.
    let order: Vec<usize> = (0..=p).rev().collect();
    let s: Vec<f64> = order
        .iter()
        .map(|&k| values[k].re.max(0.0).sqrt())
        .collect();
    // The noise level of the singular values: the median of the lower half, where no signal
    // is for any model order the pencil can resolve.
    let mut lower: Vec<f64> = s[s.len() / 2..].to_vec();
    lower.sort_by(f64::total_cmp);
    let noise_sv = lower[lower.len() / 2];
    let top = s[0];
    if top.is_nan() || top <= 0.0 || !top.is_finite() {
        return Some((Vec::new(), 0.0));
    }
    let order_count = s
        .iter()
        .take(max_order.min(p / 2))
        .take_while(|&&v| v > ORDER_THRESHOLD * noise_sv && v > 1e-7 * top)
        .count();
    // The singular values of a noise-only Hankel matrix are ~sigma sqrt(rows) (sigma per
    // sample), which gives the noise level without a model.
    let noise_rms = noise_sv / (rows as f64).sqrt();
    if order_count == 0 {
        return Some((Vec::new(), noise_rms));
    }
    // Y = A C B^T with B[j][k] = z_k^j: the leading right singular vectors span conj(B), so
    // their conjugates shift by one row into themselves times the poles.
    let u = evd.U();
    let w = |i: usize, k: usize| u[(i, order[k])].conj();
    let w1 = Mat::<c64>::from_fn(p, order_count, &w);
    let mut w2 = Mat::<c64>::from_fn(p, order_count, |i, k| w(i + 1, k));
    w1.qr()
        .solve_lstsq_in_place_with_conj(Conj::No, w2.as_mut());
    let phi = Mat::<c64>::from_fn(order_count, order_count, |i, j| w2[(i, j)]);
    let poles = phi.eigenvalues().ok()?;
    let amplitudes = amplitudes_of(y, &poles)?;
    let terms = poles
        .into_iter()
        .zip(amplitudes)
        .map(|(pole, amplitude)| Term { pole, amplitude })
        .collect();
    Some((terms, noise_rms))
}

/// The least-squares amplitudes `c` of `y[m] = sum_k c_k z_k^m` for the poles `z`.
pub fn amplitudes_of(y: &[c64], poles: &[c64]) -> Option<Vec<c64>> {
    let (len, k) = (y.len(), poles.len());
    if k == 0 || len < k {
        return Some(Vec::new());
    }
    let mut v = Mat::<c64>::zeros(len, k);
    for (j, &z) in poles.iter().enumerate() {
        let mut power = c64::new(1.0, 0.0);
        for i in 0..len {
            v[(i, j)] = power;
            power *= z;
        }
    }
    let mut rhs = Mat::<c64>::from_fn(len, 1, |i, _| y[i]);
    v.qr()
        .solve_lstsq_in_place_with_conj(Conj::No, rhs.as_mut());
    let c: Vec<c64> = (0..k).map(|j| rhs[(j, 0)]).collect();
    c.iter()
        .all(|c| c.re.is_finite() && c.im.is_finite())
        .then_some(c)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three damped exponentials, two of them 0.4 % of the sample rate apart, without noise:
    /// the poles come back to rounding (1e-9), the amplitudes to 1e-7.
    #[test]
    fn finds_exact_poles_of_a_clean_signal() {
        let truth = [
            (c64::from_polar(0.999, 0.3), c64::new(1.0, 0.5)),
            (c64::from_polar(0.995, 0.325), c64::new(-0.3, 0.2)),
            (c64::from_polar(0.98, -1.1), c64::new(0.05, 0.0)),
        ];
        let y: Vec<c64> = (0..90)
            .map(|m| {
                truth
                    .iter()
                    .map(|(z, c)| c * z.powi(m))
                    .fold(c64::new(0.0, 0.0), |a, b| a + b)
            })
            .collect();
        let (terms, _) = pencil(&y, 10).expect("long enough");
        assert_eq!(terms.len(), 3, "{terms:?}");
        for (z, c) in truth {
            let t = terms
                .iter()
                .min_by(|a, b| (a.pole - z).norm().total_cmp(&(b.pole - z).norm()))
                .unwrap();
            assert!((t.pole - z).norm() < 1e-9, "{t:?} vs {z}");
            assert!(
                (t.amplitude - c).norm() < 1e-7 * (1.0 + c.norm()),
                "{t:?} vs {c}"
            );
        }
    }
}
