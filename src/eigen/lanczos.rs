//! Shift-invert block Lanczos with thick restarts, on a sparse Cholesky factorisation.
//!
//! The operator is `(K - sigma M)^-1 M`, self-adjoint in the M-inner product; its largest
//! eigenvalues `theta = 1 / (lambda - sigma)` are the modes nearest the shift. `K` of a free
//! object is singular (rigid-body modes), so the shift is negative, `sigma = -SHIFT_RELATIVE x
//! trace K / trace M`, scaled to the matrices: a fixed shift such as -1 rad^2/s^2 is effectively
//! zero for steel and leaves the factorisation near-singular. Every `lambda >= 0 > sigma`, so the
//! shifted matrix is positive definite and `faer`'s sparse Cholesky factors it.
//!
//! Blocks (default 8 vectors) find repeated eigenvalues, which symmetric objects have, and let
//! the triangular solves work on several right-hand sides at once. The basis is kept fully
//! M-orthogonal (classical Gram-Schmidt, twice); when it is full, the wanted Ritz vectors and the
//! residual block restart it (thick restart: Wu and Simon 2000; Stathopoulos and Saad 1998).

use super::factor::ShiftedCholesky;
use super::{
    random_block, select, solution, sym_eigen, EigenError, EigenOptions, EigenSolution, ModeCount,
    Operators,
};
use crate::fem::FemModel;
use faer::{Mat, Par};
use std::time::Instant;

/// The shift as a fraction of `trace K / trace M`; below the softest mode of most objects, and
/// far enough from zero that `K - sigma M` is well conditioned (condition ~ 1e7).
pub const SHIFT_RELATIVE: f64 = 1e-6;

/// The growing M-orthonormal basis with `M V` kept beside it.
struct Basis {
    v: Mat<f64>,
    mv: Mat<f64>,
    len: usize,
}

impl Basis {
    fn new(n: usize, cap: usize) -> Self {
        Basis {
            v: Mat::zeros(n, cap),
            mv: Mat::zeros(n, cap),
            len: 0,
        }
    }

    fn cap(&self) -> usize {
        self.v.ncols()
    }

    fn grow(&mut self, cap: usize) {
        if cap <= self.cap() {
            return;
        }
        let n = self.v.nrows();
        let mut v = Mat::zeros(n, cap);
        let mut mv = Mat::zeros(n, cap);
        v.as_mut()
            .get_mut(.., ..self.len)
            .copy_from(self.v.get(.., ..self.len));
        mv.as_mut()
            .get_mut(.., ..self.len)
            .copy_from(self.mv.get(.., ..self.len));
        self.v = v;
        self.mv = mv;
    }

    /// Removes the components of `w` along the basis (twice); returns the coefficients.
    fn project_out(&self, w: &mut Mat<f64>) -> Mat<f64> {
        let mut total = Mat::zeros(self.len, w.ncols());
        if self.len == 0 {
            return total;
        }
        let v = self.v.get(.., ..self.len);
        let mv = self.mv.get(.., ..self.len);
        for _ in 0..2 {
            let c = mv.transpose() * &*w;
            *w -= v * &c;
            total += &c;
        }
        total
    }
}

/// `(Q, M Q, R)` of a block M-QR factorisation.
type BlockQr = (Mat<f64>, Mat<f64>, Mat<f64>);

/// M-orthonormalises the columns of `w` (already orthogonal to `basis`) by modified Gram-Schmidt
/// with reorthogonalisation. Returns `(Q, M Q, R)` with `W = Q R`; a column that is (nearly) in
/// the span of the others is replaced by a fresh random direction with a zero row in `R`.
fn block_qr(
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
            let mut fresh_col = random_block(n, 1, *seed);
            basis.project_out(&mut fresh_col);
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

/// Basis size for `nev` wanted pairs with blocks of `b`.
fn basis_cap(nev: usize, b: usize, n: usize) -> usize {
    let want = (2 * nev + 3 * b).max(nev + 4 * b);
    (want.div_ceil(b) * b).min(n.max(b))
}

/// Runs the solver (see the module docs).
pub fn solve(model: &FemModel, options: &EigenOptions) -> Result<EigenSolution, EigenError> {
    let ops = Operators::new(model);
    let t0 = Instant::now();
    let shift = -SHIFT_RELATIVE * ops.scale;
    let b = options.block_size.min(ops.dofs());
    let mut llt = ShiftedCholesky::new(model, shift, b, Par::Seq)?;
    let mut solution = run(&ops, &mut llt, shift, options)?;
    solution.timings.setup_ms = t0.elapsed().as_secs_f64() * 1e3 - solution.timings.iterate_ms;
    Ok(solution)
}

/// The iteration on an existing factorisation `llt` of `K - shift M` (sized for at least
/// `options.block_size` right-hand sides); `setup_ms` of the result is zero.
pub fn run(
    ops: &Operators,
    llt: &mut ShiftedCholesky,
    shift: f64,
    options: &EigenOptions,
) -> Result<EigenSolution, EigenError> {
    let ops = *ops;
    let n = ops.dofs();
    let b = options.block_size.min(n);
    let setup_ms = 0.0;
    let t1 = Instant::now();

    let mut nev = match options.count {
        ModeCount::First(k) => k + 6,
        ModeCount::Below(_) => 26,
    };
    if let ModeCount::First(k) = options.count {
        if k + 6 > n {
            return Err(EigenError::TooFewDofs { dofs: n, wanted: k });
        }
    }
    let mut basis = Basis::new(n, basis_cap(nev, b, n));
    let mut h = Mat::<f64>::zeros(basis.cap(), basis.cap());
    let mut seed = 1u64;
    let (q, mq, _) = block_qr(&ops, &basis, random_block(n, b, seed), &mut seed)?;
    basis.v.as_mut().get_mut(.., 0..b).copy_from(&q);
    basis.mv.as_mut().get_mut(.., 0..b).copy_from(&mq);
    basis.len = b;
    let mut fresh = 0..b; // columns whose operator image is still to be computed
    let mut scratch = vec![0.0; 2 * n];
    let mut worst = f64::INFINITY;
    let mut converged_count = 0;
    for restart in 0..options.max_iterations {
        // Expand until the basis is full; the last block's residual is kept for the restart.
        let (q_res, mq_res, r_res, last) = loop {
            let cols = fresh.clone();
            let mut w = basis.mv.get(.., cols.clone()).to_owned();
            llt.solve_in_place(w.as_mut());
            let c = basis.project_out(&mut w);
            h.as_mut().get_mut(0..basis.len, cols.clone()).copy_from(&c);
            let (q, mq, r) = block_qr(&ops, &basis, w, &mut seed)?;
            if basis.len + q.ncols() > basis.cap() {
                break (q, mq, r, cols);
            }
            let at = basis.len..basis.len + q.ncols();
            h.as_mut().get_mut(at.clone(), cols).copy_from(&r);
            basis.v.as_mut().get_mut(.., at.clone()).copy_from(&q);
            basis.mv.as_mut().get_mut(.., at.clone()).copy_from(&mq);
            basis.len = at.end;
            fresh = at;
        };
        let len = basis.len;
        let (theta, y) = sym_eigen(&h.get(0..len, 0..len).to_owned())?;
        // Descending theta = ascending lambda.
        let order: Vec<usize> = (0..len).rev().filter(|&i| theta[i] > 0.0).collect();
        let check = nev.min(order.len());
        let ysel = Mat::from_fn(len, check, |i, j| y[(i, order[j])]);
        let x = basis.v.get(.., 0..len) * &ysel;
        let mut pairs = Vec::new();
        worst = 0.0;
        for j in 0..check {
            let lambda = shift + 1.0 / theta[order[j]];
            let res = ops.residual(lambda, x.col_as_slice(j), &mut scratch);
            if !res.is_finite() {
                return Err(EigenError::NonFinite);
            }
            if res > options.tolerance {
                worst = res;
                break;
            }
            pairs.push((lambda, j, res));
        }
        converged_count = pairs.len();
        let sel = select(&ops, &pairs, options.count);
        if sel.complete {
            let timings = super::SolveTimings {
                setup_ms,
                iterate_ms: t1.elapsed().as_secs_f64() * 1e3,
            };
            return Ok(solution(
                &pairs,
                &sel,
                x.as_ref(),
                timings,
                restart,
                super::SolverKind::Lanczos,
            ));
        }
        let rigid = sel.rigid;
        // Not done: how many pairs are wanted now that the rigid count is known?
        nev = match options.count {
            ModeCount::First(k) => nev.max(rigid + k),
            ModeCount::Below(_) if converged_count + b >= nev => {
                (nev * 3 / 2 + b).min(super::MAX_MODES + 64)
            }
            ModeCount::Below(_) => nev,
        };
        if nev + 2 * b > n {
            return Err(EigenError::TooFewDofs {
                dofs: n,
                wanted: nev,
            });
        }
        let cap = basis_cap(nev, b, n);
        if cap > basis.cap() {
            basis.grow(cap);
            let mut h2 = Mat::zeros(cap, cap);
            h2.as_mut()
                .get_mut(0..len, 0..len)
                .copy_from(h.get(0..len, 0..len));
            h = h2;
        }
        // Thick restart: keep the best Ritz vectors, continue from the residual block.
        let keep_n = (nev + b)
            .min(order.len())
            .min(basis.cap() - 2 * q_res.ncols());
        let yk = Mat::from_fn(len, keep_n, |i, j| y[(i, order[j])]);
        let xk = basis.v.get(.., 0..len) * &yk;
        let mxk = basis.mv.get(.., 0..len) * &yk;
        // Residual coupling: Op x_j - theta_j x_j = Q (R y_j[last rows]).
        let y_last = Mat::from_fn(last.len(), keep_n, |i, j| y[(last.start + i, order[j])]);
        let coupling = &r_res * &y_last;
        h.fill(0.0);
        for j in 0..keep_n {
            h[(j, j)] = theta[order[j]];
        }
        let qb = q_res.ncols();
        h.as_mut()
            .get_mut(keep_n..keep_n + qb, 0..keep_n)
            .copy_from(&coupling);
        h.as_mut()
            .get_mut(0..keep_n, keep_n..keep_n + qb)
            .copy_from(coupling.transpose());
        basis.v.as_mut().get_mut(.., 0..keep_n).copy_from(&xk);
        basis.mv.as_mut().get_mut(.., 0..keep_n).copy_from(&mxk);
        basis
            .v
            .as_mut()
            .get_mut(.., keep_n..keep_n + qb)
            .copy_from(&q_res);
        basis
            .mv
            .as_mut()
            .get_mut(.., keep_n..keep_n + qb)
            .copy_from(&mq_res);
        basis.len = keep_n + qb;
        fresh = keep_n..keep_n + qb;
    }
    Err(EigenError::NoConvergence {
        converged: converged_count,
        wanted: nev,
        worst_residual: worst,
    })
}
