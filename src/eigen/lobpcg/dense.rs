//! The dense Rayleigh-Ritz step: the lowest eigenpairs of the small pencil `(B^T K B, B^T M B)`
//! of a basis `B`, as Ritz values and coefficients.
//!
//! Where it sits: every block method here ends a step with one. LOBPCG's basis `[X, W, P]`
//! ([`super`]) and a relaxed patch's modes (`warm/correction.rs`) go to [`dense_ritz`], which
//! is safe on a basis whose columns become nearly dependent as it converges; the carried
//! answer to a brush stroke (`warm.rs`) to [`dense_ritz_by_cholesky`], one eigendecomposition
//! instead of two where its basis is far from dependent. Both scale the `M`-Gram matrix to a
//! unit diagonal first (Hetmaniuk and Lehoucq 2006; Duersch et al. 2018).

use crate::eigen::{sym_eigen, EigenError};
use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::{Mat, Par};

/// Directions of the scaled `M`-Gram matrix with eigenvalue below this fraction of its largest
/// are dropped from the Rayleigh-Ritz basis.
const GRAM_DROP: f64 = 1e-12;

/// Smallest share of a column's scaled `M`-norm outside the span of the columns before it for
/// which [`dense_ritz_by_cholesky`] trusts its Cholesky factor: a direction that small is
/// amplified `1 / sqrt(share)` (1e5) in the reduced pencil, about what [`GRAM_DROP`]'s
/// decomposition keeps.
const CHOLESKY_MIN_SHARE: f64 = 1e-10;

/// The lowest `want` eigenpairs of the dense pencil `(gk, gm)` (Gram matrices of a basis):
/// Ritz values and coefficients. Scales `gm` to a unit diagonal and keeps its
/// well-conditioned directions (Hetmaniuk and Lehoucq 2006), so a nearly dependent basis does
/// no harm.
pub(crate) fn dense_ritz(
    gk: &Mat<f64>,
    gm: &Mat<f64>,
    want: usize,
) -> Result<(Vec<f64>, Mat<f64>), EigenError> {
    let s = gk.nrows();
    // Scale to unit diagonal, then keep the well-conditioned directions of the M-Gram matrix.
    let (d, scaled) = unit_diagonal(gm);
    let (sigma, u) = sym_eigen(&scaled)?;
    let top = sigma.last().copied().unwrap_or(0.0);
    let keep: Vec<usize> = (0..s).filter(|&j| sigma[j] > GRAM_DROP * top).collect();
    if keep.len() < want {
        return Err(EigenError::Breakdown);
    }
    let z = Mat::from_fn(s, keep.len(), |i, j| {
        d[i] * u[(i, keep[j])] / sigma[keep[j]].sqrt()
    });
    let h = z.transpose() * gk * &z;
    let (theta, y) = sym_eigen(&h)?;
    let c = &z * y.get(.., 0..want);
    Ok((theta[..want].to_vec(), c))
}

/// [`dense_ritz`] by Cholesky, for a basis whose columns are far from dependent: the scaled
/// `M`-Gram matrix is factored (`L L^T`) instead of decomposed, and the pencil becomes
/// `L^-1 K L^-T`, one symmetric eigendecomposition instead of two (stop 68). `L_ii^2` is the
/// share of column `i`'s scaled `M`-norm outside the span of the columns before it; where one
/// is below [`CHOLESKY_MIN_SHARE`] (or the factorisation fails) the basis is nearly dependent
/// and [`dense_ritz`] answers instead, dropping those directions.
///
/// Measured and not kept (stop 69): dropping such columns as a row-by-row (Crout)
/// factorisation reaches them, instead of falling back. Most presets' carried answers fall
/// back (1-21 of their 156-174 columns have shares under 1e-10: corrections of 74 carried
/// modes on a few hundred DOFs; not the default object's, the steel bar's, the aluminium
/// plate's or the plastic crate's),
/// and dropping saved the ceramic cup, the bell and the glass vase a millisecond or two; but
/// on the iron pipe (Poisson's ratio 0.28, one stroke) it played modes up to 11 % low, below
/// the exact ones that Ritz values bound from above, where the fallback and this
/// factorisation with any threshold down to 1e-14 are right (9.8e-5; the cause was not
/// found), and columns dropped below 1e-8 or 1e-6 cost the steel bar accuracy (3.0e-3 ->
/// 3.3e-3 and 5.8e-3). `tests/warm_start.rs` holds the pipe.
pub(crate) fn dense_ritz_by_cholesky(
    gk: &Mat<f64>,
    gm: &Mat<f64>,
    want: usize,
) -> Result<(Vec<f64>, Mat<f64>), EigenError> {
    let s = gk.nrows();
    let (d, scaled) = unit_diagonal(gm);
    let Ok(llt) = scaled.llt(faer::Side::Lower) else {
        return dense_ritz(gk, gm, want);
    };
    let l = llt.L();
    let dependent = (0..s).any(|i| {
        let share = l[(i, i)] * l[(i, i)];
        share.is_nan() || share < CHOLESKY_MIN_SHARE
    });
    if dependent || want > s {
        return dense_ritz(gk, gm, want);
    }
    // `L^-1 (D K D) L^-T`, the second solve on the transpose of the first (`D K D` is
    // symmetric).
    let mut h = Mat::from_fn(s, s, |i, j| d[i] * gk[(i, j)] * d[j]);
    solve_lower_triangular_in_place(l, h.as_mut(), Par::Seq);
    let mut h = h.transpose().to_owned();
    solve_lower_triangular_in_place(l, h.as_mut(), Par::Seq);
    let (theta, y) = sym_eigen(&h)?;
    // The coefficients `D L^-T y`.
    let mut c = y.get(.., 0..want).to_owned();
    solve_upper_triangular_in_place(l.transpose(), c.as_mut(), Par::Seq);
    for (i, &di) in d.iter().enumerate() {
        c.row_mut(i).iter_mut().for_each(|v| *v *= di);
    }
    Ok((theta[..want].to_vec(), c))
}

/// `gm` scaled to a unit diagonal, `D gm D`, and the scaling `D`: `1 / sqrt(gm_ii)`, 0 where
/// that is not a positive number.
fn unit_diagonal(gm: &Mat<f64>) -> (Vec<f64>, Mat<f64>) {
    let s = gm.nrows();
    let d: Vec<f64> = (0..s)
        .map(|i| {
            let g = gm[(i, i)];
            if g > 0.0 && g.is_finite() {
                1.0 / g.sqrt()
            } else {
                0.0
            }
        })
        .collect();
    let scaled = Mat::from_fn(s, s, |i, j| d[i] * gm[(i, j)] * d[j]);
    (d, scaled)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;

    /// The Gram matrices `B^T K B`, `B^T M B` of a random 60 x 20 basis `B` for the diagonal
    /// pencil `K = diag(1..60)`, `M = diag(1 + u)`; with `dependent`, the last column is the
    /// first plus 1e-10 of noise.
    fn grams(dependent: bool) -> (Mat<f64>, Mat<f64>) {
        let (n, s) = (60, 20);
        let mut rng = SplitMix64::new(11);
        let k: Vec<f64> = (1..=n).map(|i| i as f64).collect();
        let m: Vec<f64> = (0..n).map(|_| 1.0 + rng.unit()).collect();
        let mut b = Mat::from_fn(n, s, |_, _| rng.unit() - 0.5);
        if dependent {
            for i in 0..n {
                b[(i, s - 1)] = b[(i, 0)] + 1e-10 * (rng.unit() - 0.5);
            }
        }
        let gram = |w: &[f64]| {
            Mat::from_fn(s, s, |a, c| {
                (0..n).map(|i| b[(i, a)] * w[i] * b[(i, c)]).sum()
            })
        };
        (gram(&k), gram(&m))
    }

    #[test]
    fn the_cholesky_ritz_step_matches_the_decomposition_and_falls_back_on_a_dependent_basis() {
        let want = 6;
        // An independent basis: the same Ritz values to 1e-12 relative (both reduce the same
        // pencil stably; its scaled Gram matrix's condition is ~1e2), and coefficients that
        // are `M`-orthonormal and diagonalise `K` to 1e-12 of the largest Ritz value.
        let (gk, gm) = grams(false);
        let (theta, c) = dense_ritz_by_cholesky(&gk, &gm, want).unwrap();
        let (reference, _) = dense_ritz(&gk, &gm, want).unwrap();
        for (t, r) in theta.iter().zip(&reference) {
            assert!((t - r).abs() <= 1e-12 * r, "{t} against {r}");
        }
        let (ck, cm) = (c.transpose() * &gk * &c, c.transpose() * &gm * &c);
        for i in 0..want {
            for j in 0..want {
                let (k_ij, m_ij) = if i == j { (theta[i], 1.0) } else { (0.0, 0.0) };
                assert!((ck[(i, j)] - k_ij).abs() <= 1e-12 * theta[want - 1]);
                assert!((cm[(i, j)] - m_ij).abs() <= 1e-12);
            }
        }
        // A nearly dependent column (1e-20 of its scaled norm outside the others' span): the
        // decomposition answers, dropping that direction, bit for bit.
        let (gk, gm) = grams(true);
        let fast = dense_ritz_by_cholesky(&gk, &gm, want).unwrap();
        let robust = dense_ritz(&gk, &gm, want).unwrap();
        assert_eq!(fast.0, robust.0);
        assert_eq!(fast.1, robust.1);
    }
}
