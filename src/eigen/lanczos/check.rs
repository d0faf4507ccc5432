//! Convergence checks of the Lanczos iteration: the Ritz pairs of the current basis, their
//! residuals from the Lanczos relation, and the explicit check that confirms them.
//!
//! Where it sits: called by [`super::run`] after a block has been orthogonalised, on the basis
//! and the block that would extend it. It returns either the finished [`EigenSolution`] or how
//! far convergence has got, which schedules the next check.
//!
//! The relation (block Lanczos, e.g. Grimes, Lewis and Simon 1994, sec. 2): with the basis `V`,
//! the projected matrix `H` and the next block `Q` with its coupling `R`,
//! `Op V = V H + Q R E_last^T`, so a Ritz pair `(theta, x = V y)` of `H` has
//! `Op x - theta x = Q c`, `c = R y_last`. Multiplied by `-(K - sigma M) / theta` this is the
//! residual of Jin et al. 2022, eq. 6 itself, `K x - lambda M x = -(1 / theta) Z c` with
//! `Z = (K - sigma M) Q` and `lambda = sigma + 1 / theta`; one product of `K` with the `b`
//! columns of `Q` and the Gram matrix `G = Z^T Z` give every pair's residual norm,
//! `sqrt(c^T G c) / theta`, without forming the pair. Before the Ritz vectors are formed their
//! 2-norm is bounded below by `1 / sqrt(||M||)` (M-unit vectors), which makes the estimate an
//! upper bound; once they are formed their norms are exact.
//!
//! The relation holds to rounding while the basis stays M-orthonormal, which the
//! reorthogonalisation keeps. A sentinel guards it anyway: the pairs with the largest
//! residuals (one block of them) are recomputed explicitly from `K` and `M`; if one of them
//! disagrees with the relation, every pair is checked explicitly (the old, slower way: two
//! block products as wide as the request, two-thirds of a check's cost).

use super::super::{
    select, solution, sym_eigen, EigenError, EigenOptions, EigenSolution, ModeCount, Operators,
    SolveTimings, SolverKind, Stop, Which,
};
use super::qr::gram;
use super::{tall_times_small, Basis};
use crate::eigen::band::{band_eigen, BandEigen};
use faer::Mat;
use std::time::Instant;

/// Converged pairs whose residuals a check recomputes explicitly at least (the sentinel; a
/// block's worth where blocks are larger): a symmetry class's blocks of four keep the whole
/// solve's eight.
const MIN_SENTINELS: usize = 8;

/// Basis length up to which a check on a band projected matrix computes its whole eigenvectors
/// ([`band_eigen`] from row 0: the band reduction and QL with every row accumulated, `O(n^3)`
/// with small constants), not only their last block's rows: at this size that costs about
/// what the rows alone do (118 against 110 us at 40 vectors in blocks of two, one core), and
/// the check that finds the request met needs no dense decomposition (214 us there; 580
/// against 300-350 for the accumulation at 48 vectors in blocks of four, which is why the
/// limit). A 20-mode request's classes end at 30-50 vectors (`symmetric::TINY_BLOCK_SIZE`):
/// the SciPy comparison's bar 0.96x, the 4.9k-DOF sphere 0.98x.
const BAND_VECTORS_MAX_LEN: usize = 40;

/// What a convergence check found.
pub(super) enum Check {
    /// Every wanted pair has converged: the answer, with what its verification found.
    Done(Box<Answer>),
    /// Not yet: how far convergence has got.
    Converged(Progress),
}

/// A met request's answer and the verification it came from.
pub(super) struct Answer {
    /// The answer.
    pub solution: EigenSolution,
    /// Every converged pair the verification found, the answer's and those above it.
    pub verified: Verified,
}

/// The converged pairs a verification found, ascending and contiguous from the lowest, with
/// their Ritz vectors: a later request on the same basis that they meet is answered from them
/// without a check ([`super::iteration::Iteration::run`]). A class asked again below a higher
/// bound often is: its first answer stopped at the first converged pair above the old bound,
/// and that pair is above the new one too.
pub(super) struct Verified {
    /// `(lambda, column of x, residual)` of each converged pair.
    pub pairs: Vec<(f64, usize, f64)>,
    /// The Ritz vectors of the verified pairs and their guards, by column.
    pub x: Mat<f64>,
    /// The tolerance the pairs were verified to.
    pub tolerance: f64,
}

/// How far a check found convergence, which schedules the next one.
#[derive(Clone, Copy, Debug)]
pub(super) struct Progress {
    /// Leading pairs that converged.
    pub converged: usize,
    /// The residual of the first pair that did not.
    pub worst: f64,
    /// Pairs the request needs at least, as the Ritz values tell: for a "below" request, one
    /// more than the Ritz values below its bound (the `j`-th Ritz value bounds the `j`-th
    /// eigenvalue from above, so at least that many eigenvalues lie below, and the request is
    /// met only when a converged pair lies above); zero for a "first k" request.
    pub needed: usize,
}

/// The block that would extend the basis: `Q`, `M Q` and its coupling `R` to the last basis
/// block, which sits at columns `last` of the basis.
pub(super) struct NextBlock<'a> {
    /// `Q`, M-orthonormal and M-orthogonal to the basis.
    pub q: &'a Mat<f64>,
    /// `M Q`.
    pub mq: &'a Mat<f64>,
    /// `R`, `b x b`: `Op V_last = ... + Q R`.
    pub r: &'a Mat<f64>,
    /// The basis columns of the last block.
    pub last: std::ops::Range<usize>,
}

/// The Ritz pairs of a basis with what their residual norms need.
pub(super) struct RitzPairs {
    /// Eigenvalues of the projected matrix, ascending.
    pub theta: Vec<f64>,
    /// Its eigenvectors, by column; `None` when only their last block's rows were computed
    /// (the band path of [`RitzPairs::new`] beyond [`BAND_VECTORS_MAX_LEN`] vectors).
    pub y: Option<Mat<f64>>,
    /// Indices of the positive `theta`, descending: ascending `lambda`.
    pub order: Vec<usize>,
    /// `c_j = R y_last` of the first pairs of `order`, by column.
    coupling: Mat<f64>,
    /// `G = Z^T Z`, `Z = (K - sigma M) Q`.
    gram: Mat<f64>,
}

impl RitzPairs {
    /// The eigen-decomposition of `h` (the basis's projected matrix) and the residual data of
    /// its first `count` pairs in `order`. With `band = Some(kd)`, `h` is block tridiagonal of
    /// half-bandwidth `kd` (a Lanczos basis that has not restarted) and only the eigenvalues
    /// and the last block's eigenvector rows are computed ([`band_eigen`], ~1.5 ms where the
    /// dense decomposition takes ~4 ms at 200 vectors), or the whole eigenvectors up to
    /// [`BAND_VECTORS_MAX_LEN`] vectors; entries beyond the band, which the full
    /// reorthogonalisation records at rounding level, are left out.
    pub fn new(
        ops: &Operators,
        shift: f64,
        h: &Mat<f64>,
        next: &NextBlock<'_>,
        count: usize,
        band: Option<usize>,
    ) -> Result<Self, EigenError> {
        let mut z = ops.apply_block(Which::K, next.q.as_ref());
        z -= shift * next.mq;
        let gram = gram(&z, &z);
        Self::with_gram(gram, h, next, count, band)
    }

    /// The same pairs with their full eigenvectors: from the band path's answer, the dense
    /// decomposition (the Gram matrix, which depends only on the next block, is kept).
    pub fn dense(
        self,
        h: &Mat<f64>,
        next: &NextBlock<'_>,
        count: usize,
    ) -> Result<Self, EigenError> {
        match self.y {
            Some(_) => Ok(self),
            None => Self::with_gram(self.gram, h, next, count, None),
        }
    }

    fn with_gram(
        gram: Mat<f64>,
        h: &Mat<f64>,
        next: &NextBlock<'_>,
        count: usize,
        band: Option<usize>,
    ) -> Result<Self, EigenError> {
        let (theta, y, y_last_of) = match band {
            Some(kd) if h.nrows() > BAND_VECTORS_MAX_LEN => {
                let BandEigen { values, rows } = band_eigen(h, kd, next.last.start)?;
                (values, None, rows)
            }
            Some(kd) => {
                let BandEigen { values, rows } = band_eigen(h, kd, 0)?;
                let last = rows.get(next.last.clone(), ..).to_owned();
                (values, Some(rows), last)
            }
            None => {
                let (theta, y) = sym_eigen(h)?;
                let rows = y.get(next.last.clone(), ..).to_owned();
                (theta, Some(y), rows)
            }
        };
        let order: Vec<usize> = (0..theta.len()).rev().filter(|&i| theta[i] > 0.0).collect();
        let count = count.min(order.len());
        let y_last = Mat::from_fn(next.last.len(), count, |i, j| y_last_of[(i, order[j])]);
        let coupling = next.r * &y_last;
        Ok(RitzPairs {
            theta,
            y,
            order,
            coupling,
            gram,
        })
    }

    /// `lambda` of the `j`-th pair in `order`.
    pub fn lambda(&self, shift: f64, j: usize) -> f64 {
        shift + 1.0 / self.theta[self.order[j]]
    }

    /// `||K x - lambda M x||` of the `j`-th pair in `order` (for an M-unit `x`), from the
    /// Lanczos relation.
    fn residual_norm(&self, j: usize) -> f64 {
        let (c, g) = (self.coupling.col(j), &self.gram);
        let b = c.nrows();
        // `c^T G c` as a double sum: a product through faer took a fresh column per pair.
        let cgc: f64 = (0..b)
            .map(|k| c[k] * (0..b).map(|l| g[(k, l)] * c[l]).sum::<f64>())
            .sum();
        cgc.max(0.0).sqrt() / self.theta[self.order[j]]
    }
}

/// Convergence checks of one solve (see the module docs).
pub(super) struct RitzCheck<'a> {
    /// The matrices.
    pub ops: &'a Operators<'a>,
    /// The factorisation's shift `sigma`.
    pub shift: f64,
    /// The request.
    pub options: &'a EigenOptions,
    /// Pairs wanted now, rigid ones included.
    pub nev: usize,
    /// When the iteration started, for the timings.
    pub started: Instant,
    /// Restarts so far, reported as the solve's iterations.
    pub restarts: usize,
    /// The block size while the projected matrix is block tridiagonal (no restart yet): the
    /// estimates then take the band path of [`RitzPairs::new`].
    pub band: Option<usize>,
    /// The caller's interruption poll, checked once per block.
    pub stop: Stop<'a>,
    /// Projected matrices decomposed so far (checks and restarts).
    pub decompositions: std::cell::Cell<usize>,
}

impl RitzCheck<'_> {
    /// Checks the basis (`h` is its projected matrix) and, when the upper bounds say the request
    /// is met, forms the Ritz vectors and confirms it ([`RitzCheck::verify`]).
    pub fn run(
        &self,
        basis: &Basis,
        h: &Mat<f64>,
        next: &NextBlock<'_>,
    ) -> Result<Check, EigenError> {
        self.decompositions.set(self.decompositions.get() + 1);
        let ritz = RitzPairs::new(self.ops, self.shift, h, next, self.nev, self.band)?;
        let (converged, worst) = self.estimate(&ritz)?;
        if let Some(worst) = worst {
            return Ok(Check::Converged(Progress {
                converged,
                worst,
                needed: self.needed(&ritz),
            }));
        }
        let ritz = ritz.dense(h, next, self.nev)?;
        self.verify(basis, &ritz, converged)
    }

    /// The upper bounds on the residuals of the leading pairs (module docs): how many meet the
    /// tolerance, and the first bound that does not when the request is not met yet.
    fn estimate(&self, ritz: &RitzPairs) -> Result<(usize, Option<f64>), EigenError> {
        let ops = self.ops;
        let check = self.nev.min(ritz.order.len());
        let mut estimated = Vec::with_capacity(check);
        let mut worst = 0.0;
        for j in 0..check {
            let lambda = ritz.lambda(self.shift, j);
            let bound = ritz.residual_norm(j) * ops.m_norm.sqrt() / self.scale(lambda);
            if !bound.is_finite() {
                return Err(EigenError::NonFinite);
            }
            if bound > self.options.tolerance {
                worst = bound;
                break;
            }
            estimated.push((lambda, j, bound));
        }
        let complete = select(ops, &estimated, self.options.count).complete;
        Ok((estimated.len(), (!complete).then_some(worst)))
    }

    /// [`Progress::needed`] of these pairs.
    fn needed(&self, ritz: &RitzPairs) -> usize {
        match self.options.count {
            ModeCount::First(_) => 0,
            ModeCount::Below(limit) => {
                let below = (0..ritz.order.len())
                    .take_while(|&j| ritz.lambda(self.shift, j) <= limit)
                    .count();
                below + 1
            }
        }
    }

    /// `||K|| + |lambda| ||M||`, the residual's scale (Jin et al. 2022, eq. 6).
    fn scale(&self, lambda: f64) -> f64 {
        self.ops.k_norm + lambda.abs() * self.ops.m_norm
    }

    /// Forms the Ritz vectors of the first `check` pairs of `ritz.order` and checks them: by
    /// the relation with their exact norms, confirmed by the sentinel (module docs). The next
    /// pairs up to [`super::super::warm_guard`] are formed too, unchecked, as guard vectors for
    /// a later warm start.
    pub fn verify(
        &self,
        basis: &Basis,
        ritz: &RitzPairs,
        check: usize,
    ) -> Result<Check, EigenError> {
        let len = basis.len;
        let order = &ritz.order;
        let width = (check + super::super::warm_guard(self.nev)).min(order.len());
        let y = ritz.y.as_ref().expect("verify needs the full eigenvectors");
        let ysel = Mat::from_fn(len, width, |i, j| y[(i, order[j])]);
        let x = tall_times_small(basis.v.as_ref().get(.., 0..len), ysel.as_ref());
        let lambdas: Vec<f64> = (0..check).map(|j| ritz.lambda(self.shift, j)).collect();
        let mut res: Vec<f64> = (0..check)
            .map(|j| {
                // Not faer's `norm_l2`, which rescales against overflow and took 12.6 us on a
                // 930-entry column against 0.18 for the sum of squares (3.7 % of the aluminium
                // plate's solve): an M-unit Ritz vector's squares cannot overflow.
                let norm = x.col(j).squared_norm_l2().sqrt();
                ritz.residual_norm(j) / (self.scale(lambdas[j]) * norm)
            })
            .collect();
        // The sentinel: the block of converged pairs with the largest residuals, recomputed
        // explicitly.
        let tolerance = self.options.tolerance;
        let mut by_residual: Vec<usize> = (0..check).filter(|&j| res[j] <= tolerance).collect();
        by_residual.sort_by(|&a, &b| res[b].total_cmp(&res[a]));
        by_residual.truncate(self.options.block_size.max(MIN_SENTINELS));
        let xs = Mat::from_fn(x.nrows(), by_residual.len(), |i, j| x[(i, by_residual[j])]);
        let ls: Vec<f64> = by_residual.iter().map(|&j| lambdas[j]).collect();
        let explicit = self.ops.block_residuals(&ls, xs.as_ref());
        if explicit.iter().any(|&r| r.is_nan() || r > tolerance) {
            // The relation does not hold to the tolerance: trust only explicit residuals.
            res = self.ops.block_residuals(&lambdas, x.get(.., 0..check));
        } else {
            for (&j, &r) in by_residual.iter().zip(&explicit) {
                res[j] = res[j].max(r);
            }
        }
        let mut pairs = Vec::with_capacity(check);
        let mut worst = 0.0;
        for (j, (&lambda, &r)) in lambdas.iter().zip(&res).enumerate() {
            if !r.is_finite() {
                return Err(EigenError::NonFinite);
            }
            if r > tolerance {
                worst = r;
                break;
            }
            pairs.push((lambda, j, r));
        }
        let sel = select(self.ops, &pairs, self.options.count);
        if !sel.complete {
            return Ok(Check::Converged(Progress {
                converged: pairs.len(),
                worst,
                needed: self.needed(ritz),
            }));
        }
        let timings = SolveTimings {
            setup_ms: 0.0,
            iterate_ms: self.started.elapsed().as_secs_f64() * 1e3,
        };
        let solution = solution(
            &pairs,
            &sel,
            x.as_ref(),
            timings,
            self.restarts,
            SolverKind::Lanczos,
        );
        Ok(Check::Done(Box::new(Answer {
            solution,
            verified: Verified {
                pairs,
                x,
                tolerance,
            },
        })))
    }
}

#[cfg(test)]
mod tests {
    use crate::eigen::{lanczos, EigenOptions, ModeCount, Operators};
    use crate::fem::{test_model, ElementKind};

    /// Below this, an explicit residual is rounding: `K x - lambda M x` sums ~80 products per
    /// row of entries up to `||K||`, so it cannot resolve less than ~1e-13 relative (measured
    /// on this bowl: 3e-14 to 3e-13 for pairs the relation puts at 1e-17).
    const ROUNDING: f64 = 1e-12;

    /// The residuals a solve reports come from the Lanczos relation (all but one sentinel
    /// block); recomputed from `K` and `M` they must agree. The relation is exact up to
    /// rounding in the operator and the basis's loss of orthogonality; measured, the two agree
    /// to 7 digits from 1e-11 up. The bound allows a thousandth of the value plus
    /// [`ROUNDING`]: a residual computed from a wrong coupling, Gram matrix or norm is off by
    /// a constant factor or more and fails. Two solves: the bowl's Ritz vectors come from the
    /// dense decomposition of its projected matrix, the small bar's (blocks of two, at most
    /// [`super::BAND_VECTORS_MAX_LEN`] vectors) from the band reduction.
    #[test]
    fn reported_residuals_match_explicit_ones() {
        for (spec, modes, block_size) in [("bowl:d=10,wall=2", 30, 8), ("bar:l=16,w=3,h=3", 4, 2)] {
            let model = test_model(spec, ElementKind::Hex8Incompatible, 0.24);
            let options = EigenOptions {
                count: ModeCount::First(modes),
                block_size,
                ..Default::default()
            };
            let sol = lanczos::solve(&model, &options).expect("solve");
            let ops = Operators::new(&model);
            let explicit = ops.block_residuals(&sol.eigenvalues, sol.vectors.as_ref());
            assert_eq!(explicit.len(), modes);
            for (j, (&reported, &recomputed)) in sol.residuals.iter().zip(&explicit).enumerate() {
                assert!(
                    reported <= options.tolerance,
                    "mode {j}: reported {reported:e}"
                );
                let allowed = ROUNDING + 1e-3 * recomputed;
                assert!(
                    (reported - recomputed).abs() <= allowed,
                    "mode {j}: reported {reported:e}, recomputed {recomputed:e}"
                );
            }
            // Not a vacuous comparison: the pairs are not all converged to rounding level.
            let largest = explicit.iter().cloned().fold(0.0, f64::max);
            assert!(largest > 1e-12, "largest residual {largest:e}");
        }
    }
}
