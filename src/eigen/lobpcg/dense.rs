//! The dense Rayleigh-Ritz step: the lowest eigenpairs of the small pencil `(B^T K B, B^T M B)`
//! of a basis `B`, as Ritz values and coefficients.
//!
//! Where it sits: every block method here ends a step with one. LOBPCG's basis `[X, W, P]`
//! ([`super`]) and a relaxed patch's modes (`warm/correction.rs`) go to [`dense_ritz`], which
//! is safe on a basis whose columns become nearly dependent as it converges; the carried
//! answer to a brush stroke (`warm.rs`) to [`dense_ritz_by_cholesky`], one eigendecomposition
//! instead of two. Both scale the `M`-Gram matrix to a unit diagonal first (Hetmaniuk and
//! Lehoucq 2006; Duersch et al. 2018).

use crate::eigen::{sym_eigen, EigenError};
use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::{Mat, Par};

/// Directions of the scaled `M`-Gram matrix with eigenvalue below this fraction of its largest
/// are dropped from the Rayleigh-Ritz basis.
const GRAM_DROP: f64 = 1e-12;

/// Smallest share of a column's scaled `M`-norm outside the span of the columns before it for
/// which [`dense_ritz_by_cholesky`] keeps it: a direction that small is amplified
/// `1 / sqrt(share)` (1e5) in the reduced pencil, about what [`GRAM_DROP`]'s decomposition
/// keeps.
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

/// [`dense_ritz`] by Cholesky: the scaled `M`-Gram matrix is factored (`L L^T`) instead of
/// decomposed, and the pencil becomes `L^-1 K L^-T`, one symmetric eigendecomposition instead
/// of two. `L_ii^2` is the share of column `i`'s scaled `M`-norm outside the span of the
/// columns kept before it; a column whose share is below [`CHOLESKY_MIN_SHARE`] is dropped
/// (its coefficients are zero), as [`dense_ritz`] drops a direction. The carried answer's
/// basis has such columns where the relaxed patch is narrow: its corrections of the carried
/// modes span a small space (10-16 of 156 columns on the ceramic cup, the bell, the glass bowl
/// and vase, one stroke each). Falls back on [`dense_ritz`] where fewer than `want` columns
/// are kept.
pub(crate) fn dense_ritz_by_cholesky(
    gk: &Mat<f64>,
    gm: &Mat<f64>,
    want: usize,
) -> Result<(Vec<f64>, Mat<f64>), EigenError> {
    let s = gk.nrows();
    let (d, scaled) = unit_diagonal(gm);
    let (kept, l) = cholesky_dropping(&scaled);
    if kept.len() < want {
        return dense_ritz(gk, gm, want);
    }
    // `L^-1 (D K D) L^-T` on the kept columns, the second solve on the transpose of the first
    // (`D K D` is symmetric).
    let k = kept.len();
    let mut h = Mat::from_fn(k, k, |i, j| {
        let (a, b) = (kept[i], kept[j]);
        d[a] * gk[(a, b)] * d[b]
    });
    solve_lower_triangular_in_place(l.as_ref(), h.as_mut(), Par::Seq);
    let mut h = h.transpose().to_owned();
    solve_lower_triangular_in_place(l.as_ref(), h.as_mut(), Par::Seq);
    let (theta, y) = sym_eigen(&h)?;
    // The coefficients `D L^-T y`, zero on the dropped columns.
    let mut ck = y.get(.., 0..want).to_owned();
    solve_upper_triangular_in_place(l.transpose(), ck.as_mut(), Par::Seq);
    let mut c = Mat::zeros(s, want);
    for (r, &a) in kept.iter().enumerate() {
        for j in 0..want {
            c[(a, j)] = d[a] * ck[(r, j)];
        }
    }
    Ok((theta[..want].to_vec(), c))
}

/// The Cholesky factor of the unit-diagonal `a` over its columns whose share (`L_ii^2`)
/// reaches [`CHOLESKY_MIN_SHARE`], the others dropped as they come (a row-by-row Crout
/// factorisation, whose row `i` depends only on the rows kept before it). Returns the kept
/// columns, ascending, and their factor (lower triangular).
fn cholesky_dropping(a: &Mat<f64>) -> (Vec<usize>, Mat<f64>) {
    let s = a.nrows();
    // Row `p` of the factor (kept order) in `rows[p * s..p * s + p + 1]`.
    let mut rows = vec![0.0; s * s];
    let mut kept = Vec::with_capacity(s);
    let mut row = vec![0.0; s];
    for i in 0..s {
        let k = kept.len();
        for p in 0..k {
            let lp = &rows[p * s..p * s + p];
            let dot = dot(lp, &row[..p]);
            // `a` is symmetric: column `i` is read down, in memory order.
            row[p] = (a[(kept[p], i)] - dot) / rows[p * s + p];
        }
        let share = a[(i, i)] - dot(&row[..k], &row[..k]);
        // NaN fails the comparison and is dropped too.
        if share >= CHOLESKY_MIN_SHARE {
            rows[k * s..k * s + k].copy_from_slice(&row[..k]);
            rows[k * s + k] = share.sqrt();
            kept.push(i);
        }
    }
    let l = Mat::from_fn(kept.len(), kept.len(), |i, j| {
        if j <= i {
            rows[i * s + j]
        } else {
            0.0
        }
    });
    (kept, l)
}

/// `x . y` in four running sums (a sum in one would be a chain the compiler may not reorder
/// into SIMD lanes).
fn dot(x: &[f64], y: &[f64]) -> f64 {
    let mut acc = [0.0; 4];
    let (xc, yc) = (x.chunks_exact(4), y.chunks_exact(4));
    let tail: f64 = (xc.remainder().iter().zip(yc.remainder()))
        .map(|(a, b)| a * b)
        .sum();
    for (a, b) in xc.zip(yc) {
        for l in 0..4 {
            acc[l] += a[l] * b[l];
        }
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
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
    /// pencil `K = diag(1..60)`, `M = diag(1 + u)`; with `dependent`, column 10 is column 0
    /// plus 1e-10 of noise and column 15 is zero.
    fn grams(dependent: bool) -> (Mat<f64>, Mat<f64>) {
        let (n, s) = (60, 20);
        let mut rng = SplitMix64::new(11);
        let k: Vec<f64> = (1..=n).map(|i| i as f64).collect();
        let m: Vec<f64> = (0..n).map(|_| 1.0 + rng.unit()).collect();
        let mut b = Mat::from_fn(n, s, |_, _| rng.unit() - 0.5);
        if dependent {
            for i in 0..n {
                b[(i, 10)] = b[(i, 0)] + 1e-10 * (rng.unit() - 0.5);
                b[(i, 15)] = 0.0;
            }
        }
        let gram = |w: &[f64]| {
            Mat::from_fn(s, s, |a, c| {
                (0..n).map(|i| b[(i, a)] * w[i] * b[(i, c)]).sum()
            })
        };
        (gram(&k), gram(&m))
    }

    /// `c` is `M`-orthonormal and diagonalises `K` to `theta`, to 1e-12 (of the largest Ritz
    /// value for `K`).
    fn assert_ritz_coefficients(gk: &Mat<f64>, gm: &Mat<f64>, theta: &[f64], c: &Mat<f64>) {
        let want = theta.len();
        let (ck, cm) = (c.transpose() * gk * c, c.transpose() * gm * c);
        for i in 0..want {
            for j in 0..want {
                let (k_ij, m_ij) = if i == j { (theta[i], 1.0) } else { (0.0, 0.0) };
                assert!((ck[(i, j)] - k_ij).abs() <= 1e-12 * theta[want - 1]);
                assert!((cm[(i, j)] - m_ij).abs() <= 1e-12);
            }
        }
    }

    #[test]
    fn the_cholesky_ritz_step_matches_the_decomposition_and_drops_dependent_columns() {
        let want = 6;
        // An independent basis: the same Ritz values to 1e-12 relative (both reduce the same
        // pencil stably; its scaled Gram matrix's condition is ~1e2), and coefficients that
        // are `M`-orthonormal and diagonalise `K`. With the dependent columns, to 1e-9: the
        // decomposition keeps the direction of the sum of columns 0 and 10, which is 1e-10 off
        // column 0's, and a Ritz value of a random basis moves to first order with its span
        // (9e-12 measured).
        for dependent in [false, true] {
            let (gk, gm) = grams(dependent);
            let (theta, c) = dense_ritz_by_cholesky(&gk, &gm, want).unwrap();
            let (reference, _) = dense_ritz(&gk, &gm, want).unwrap();
            let tolerance = if dependent { 1e-9 } else { 1e-12 };
            for (t, r) in theta.iter().zip(&reference) {
                assert!((t - r).abs() <= tolerance * r, "{t} against {r}");
            }
            assert_ritz_coefficients(&gk, &gm, &theta, &c);
            // A nearly dependent column (1e-20 of its scaled norm outside the span of the
            // ones before it) and a zero one are dropped: their coefficients are zero, and
            // the Ritz values are the decomposition's, which drops those directions.
            let (kept, _) = cholesky_dropping(&unit_diagonal(&gm).1);
            let dropped: Vec<usize> = (0..20).filter(|j| !kept.contains(j)).collect();
            assert_eq!(dropped, if dependent { vec![10, 15] } else { vec![] });
            for &j in &dropped {
                assert!(c.row(j).iter().all(|&v| v == 0.0));
            }
        }
    }
}
