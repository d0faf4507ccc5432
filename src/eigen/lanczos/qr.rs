//! The new block's M-orthonormalisation (where it sits: `Krylov::orthogonalise` in [`super`],
//! after the block has been projected out of the basis): Cholesky QR twice in the M-inner
//! product, and modified Gram-Schmidt, which replaces a lost direction, where CholQR refuses.

use super::Basis;
use crate::eigen::{EigenError, Operators, Which};
use faer::Mat;

/// `(Q, M Q, R)` of a block M-QR factorisation.
pub(super) type BlockQr = (Mat<f64>, Mat<f64>, Mat<f64>);

/// A column whose M-norm after projection is below this fraction of its norm before it has
/// (numerically) no new direction: the block QR falls back to [`block_qr`], which replaces it.
const BREAKDOWN_RELATIVE: f64 = 1e-10;

/// Why [`chol_qr`] gave no factorisation.
pub(super) enum QrRefusal {
    /// The last full projection pass removed more than half of a column's M-norm squared:
    /// project once more, then try again.
    Reorthogonalise,
    /// A column has (numerically) no new direction, or the block is nearly dependent: use
    /// [`block_qr`], which replaces such columns.
    Breakdown,
}

/// Cholesky QR in the M-inner product, twice (CholQR2: Yamamoto et al. 2015): one block
/// product `M W` (SpMM), two small Cholesky factorisations, and `M Q` follows from `M W`
/// without another product. `projected` holds every coefficient [`Basis::project_out`]
/// removed, so a column that lost nearly all of its norm there is detected; `last_pass` the
/// coefficients of its last full pass, for the reorthogonalisation test (M-norms by
/// Pythagoras: the basis is M-orthonormal, so a pass that removed `c` leaves `||w||^2_M` of
/// `||w||^2_M + |c|^2`).
pub(super) fn chol_qr(
    ops: &Operators,
    w: &Mat<f64>,
    projected: &Mat<f64>,
    last_pass: &Mat<f64>,
) -> Result<BlockQr, QrRefusal> {
    let b = w.ncols();
    let mw = ops.apply_block(Which::M, w.as_ref());
    let g = w.transpose() * &mw;
    let mut reorthogonalise = false;
    for j in 0..b {
        let squared = |c: &Mat<f64>| c.col(j).iter().map(|c| c * c).sum::<f64>();
        let kept = g[(j, j)];
        let before = squared(projected) + kept;
        if kept.is_nan() || kept <= BREAKDOWN_RELATIVE * BREAKDOWN_RELATIVE * before {
            return Err(QrRefusal::Breakdown);
        }
        reorthogonalise |= kept < squared(last_pass);
    }
    if reorthogonalise {
        return Err(QrRefusal::Reorthogonalise);
    }
    let r1 = upper_cholesky(&g).ok_or(QrRefusal::Breakdown)?;
    let inv1 = upper_inverse(&r1);
    let q = w * &inv1;
    let mq = &mw * &inv1;
    let r2 = upper_cholesky(&(q.transpose() * &mq)).ok_or(QrRefusal::Breakdown)?;
    let inv2 = upper_inverse(&r2);
    Ok((&q * &inv2, &mq * &inv2, &r2 * &r1))
}

/// `R` upper triangular with `R^T R = G`, or `None` if `G` is not safely positive definite
/// (condition above ~1e12, where CholQR loses orthogonality).
fn upper_cholesky(g: &Mat<f64>) -> Option<Mat<f64>> {
    let b = g.nrows();
    let mut r = Mat::<f64>::zeros(b, b);
    let top = (0..b).map(|i| g[(i, i)]).fold(0.0, f64::max);
    for j in 0..b {
        for i in 0..=j {
            let mut s = 0.5 * (g[(i, j)] + g[(j, i)]);
            for k in 0..i {
                s -= r[(k, i)] * r[(k, j)];
            }
            if i == j {
                if s.is_nan() || s <= 1e-12 * top {
                    return None;
                }
                r[(j, j)] = s.sqrt();
            } else {
                r[(i, j)] = s / r[(i, i)];
            }
        }
    }
    Some(r)
}

/// Inverse of a small upper-triangular matrix with a positive diagonal.
fn upper_inverse(r: &Mat<f64>) -> Mat<f64> {
    let b = r.nrows();
    let mut inv = Mat::<f64>::zeros(b, b);
    for j in 0..b {
        inv[(j, j)] = 1.0 / r[(j, j)];
        for i in (0..j).rev() {
            let s: f64 = (i + 1..=j).map(|k| r[(i, k)] * inv[(k, j)]).sum();
            inv[(i, j)] = -s / r[(i, i)];
        }
    }
    inv
}

/// M-orthonormalises the columns of `w` (already orthogonal to `basis`) by modified Gram-Schmidt
/// with reorthogonalisation. Returns `(Q, M Q, R)` with `W = Q R`; a column that is (nearly) in
/// the span of the others is replaced by a fresh random direction with a zero row in `R`.
pub(super) fn block_qr(
    ops: &Operators,
    basis: &Basis,
    mut w: Mat<f64>,
    seed: &mut u64,
) -> Result<BlockQr, EigenError> {
    let (n, b) = (w.nrows(), w.ncols());
    let mut q = Mat::zeros(n, b);
    let mut mq = Mat::zeros(n, b);
    let mut r = Mat::<f64>::zeros(b, b);
    let mut mw = vec![0.0; n];
    for i in 0..b {
        let mut norm0 = {
            ops.apply_m(w.col_as_slice(i), &mut mw);
            dot(w.col_as_slice(i), &mw).max(0.0).sqrt()
        };
        let mut fresh = false;
        for attempt in 0..3 {
            for _ in 0..2 {
                for k in 0..i {
                    let c = dot(mq.col_as_slice(k), w.col_as_slice(i));
                    if !fresh {
                        r[(k, i)] += c;
                    }
                    let (qk, wi) = (q.col_as_slice(k).to_vec(), w.col_as_slice_mut(i));
                    axpy(-c, &qk, wi);
                }
            }
            ops.apply_m(w.col_as_slice(i), &mut mw);
            let norm = dot(w.col_as_slice(i), &mw).max(0.0).sqrt();
            if norm > 1e-10 * norm0 && norm > 0.0 && norm.is_finite() {
                if !fresh {
                    r[(i, i)] = norm;
                }
                let inv = 1.0 / norm;
                for (dst, src) in q.col_as_slice_mut(i).iter_mut().zip(w.col_as_slice(i)) {
                    *dst = src * inv;
                }
                for (dst, src) in mq.col_as_slice_mut(i).iter_mut().zip(&mw) {
                    *dst = src * inv;
                }
                break;
            }
            // Breakdown: the Krylov block lost a direction; continue with a random one.
            if attempt == 2 {
                // Three random directions in a row vanished: the basis spans everything.
                return Err(EigenError::Breakdown);
            }
            *seed += 1;
            let mut fresh_col = ops.random_block(1, *seed);
            for _ in 0..2 {
                basis.project_pass(0..basis.len, &mut fresh_col);
            }
            w.col_as_slice_mut(i)
                .copy_from_slice(fresh_col.col_as_slice(0));
            ops.apply_m(w.col_as_slice(i), &mut mw);
            norm0 = dot(w.col_as_slice(i), &mw).sqrt();
            fresh = true;
        }
    }
    Ok((q, mq, r))
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn axpy(alpha: f64, x: &[f64], y: &mut [f64]) {
    for (yi, xi) in y.iter_mut().zip(x) {
        *yi += alpha * xi;
    }
}
