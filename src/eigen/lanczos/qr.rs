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
    let mut mw = ops.apply_block(Which::M, w.as_ref());
    let g = gram(w, &mw);
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
    if b > HAND_KERNELS_MAX_BLOCK {
        let q = w * &inv1;
        let mq = &mw * &inv1;
        let r2 = upper_cholesky(&gram(&q, &mq)).ok_or(QrRefusal::Breakdown)?;
        let inv2 = upper_inverse(&r2);
        return Ok((&q * &inv2, &mq * &inv2, &r2 * &r1));
    }
    // Both passes scale the columns in place (`w` stays as it was for the caller's fallback).
    let mut q = w.clone();
    times_upper_in_place(&mut q, &inv1);
    times_upper_in_place(&mut mw, &inv1);
    let r2 = upper_cholesky(&gram(&q, &mw)).ok_or(QrRefusal::Breakdown)?;
    let inv2 = upper_inverse(&r2);
    times_upper_in_place(&mut q, &inv2);
    times_upper_in_place(&mut mw, &inv2);
    Ok((q, mw, &r2 * &r1))
}

/// Block widths up to which [`chol_qr`] scales the block by its triangular factors in place,
/// column by column, and forms its Gram matrices as dot products: faer's general products
/// took packing, dispatch and a fresh matrix each, which on two columns cost more than the
/// arithmetic (the SciPy comparison's bar, blocks of two: 0.95x its class solve). On wider
/// blocks the column passes (`b^2 / 2` of them) lose to the products' register blocking: the
/// default bowl and the brass gong, blocks of four and eight, 1.03x with them, interleaved.
const HAND_KERNELS_MAX_BLOCK: usize = 2;

/// `A^T B` for two tall blocks of the same height: a dot product per entry up to
/// [`HAND_KERNELS_MAX_BLOCK`] columns, faer's product beyond.
pub(super) fn gram(a: &Mat<f64>, b: &Mat<f64>) -> Mat<f64> {
    if a.ncols().max(b.ncols()) > HAND_KERNELS_MAX_BLOCK {
        return a.transpose() * b;
    }
    Mat::from_fn(a.ncols(), b.ncols(), |i, j| {
        dot(a.col_as_slice(i), b.col_as_slice(j))
    })
}

/// `X <- X T` for an upper-triangular `T`, in place: column `j` of the product takes columns
/// `0..=j` of `X`, so the columns are replaced from the last one down.
fn times_upper_in_place(x: &mut Mat<f64>, t: &Mat<f64>) {
    for j in (0..x.ncols()).rev() {
        let (head, tail) = x.as_mut().split_at_col_mut(j);
        let col = tail
            .col_mut(0)
            .try_as_col_major_mut()
            .expect("contiguous column");
        let col = col.as_slice_mut();
        let tjj = t[(j, j)];
        for v in col.iter_mut() {
            *v *= tjj;
        }
        for k in 0..j {
            axpy(
                t[(k, j)],
                head.as_ref()
                    .col(k)
                    .try_as_col_major()
                    .expect("contiguous")
                    .as_slice(),
                col,
            );
        }
    }
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

/// A dot product in four independent sums (the adds of one chain would wait on each other).
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut s = [0.0f64; 4];
    let (ac, bc) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f64 = ac
        .remainder()
        .iter()
        .zip(bc.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in ac.zip(bc) {
        for l in 0..4 {
            s[l] += x[l] * y[l];
        }
    }
    (s[0] + s[1]) + (s[2] + s[3]) + tail
}

fn axpy(alpha: f64, x: &[f64], y: &mut [f64]) {
    for (yi, xi) in y.iter_mut().zip(x) {
        *yi += alpha * xi;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::{test_model, ElementKind};

    /// CholQR2's identities on both of its paths (two columns: in-place scaling and dot
    /// products; four: faer's products): `Q^T M Q = I`, `M Q` is the product of `M` with the
    /// returned `Q`, and `W = Q R` with `R` upper triangular. Every entry is a sum of about
    /// `n` rounded products of unit-sized terms, so rounding leaves ~eps sqrt(n) (1e-14 at
    /// n = 1.5k); the bound, 100 eps sqrt(n), is far below the error of a wrong factor or a
    /// column left unscaled, and a scaling off by 1e-9 already fails it (checked).
    #[test]
    fn chol_qr_is_an_m_orthonormal_factorisation_on_both_paths() {
        let model = test_model("bar:l=16,w=4,h=3", ElementKind::Hex8Incompatible, 0.3);
        let ops = Operators::new(&model);
        let n = ops.dofs();
        let bound = 100.0 * f64::EPSILON * (n as f64).sqrt();
        for b in [HAND_KERNELS_MAX_BLOCK, 4] {
            // Columns of very different M-norms, as a Krylov block's are.
            let mut w = ops.random_block(b, 7);
            for j in 0..b {
                let scale = 10f64.powi(j as i32);
                w.col_mut(j).iter_mut().for_each(|v| *v *= scale);
            }
            let none = Mat::zeros(0, b);
            let Ok((q, mq, r)) = chol_qr(&ops, &w, &none, &none) else {
                panic!("a random block has full rank")
            };
            let mq_exact = ops.apply_block(Which::M, q.as_ref());
            let qmq = q.transpose() * &mq_exact;
            let qr = &q * &r;
            let w_norm = w.norm_max();
            for i in 0..b {
                for j in 0..b {
                    let unit = if i == j { 1.0 } else { 0.0 };
                    assert!(
                        (qmq[(i, j)] - unit).abs() <= bound,
                        "b {b}: (Q^T M Q)[{i},{j}] = {:e}",
                        qmq[(i, j)]
                    );
                    if i > j {
                        assert_eq!(r[(i, j)], 0.0, "b {b}: R is upper triangular");
                    }
                }
            }
            let mq_error = (&mq - &mq_exact).norm_max() / mq_exact.norm_max();
            assert!(mq_error <= bound, "b {b}: M Q off by {mq_error:e}");
            let w_error = (&qr - &w).norm_max() / w_norm;
            assert!(w_error <= bound, "b {b}: W - Q R off by {w_error:e}");
        }
    }
}
