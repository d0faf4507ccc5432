//! LOBPCG (Knyazev 2001; NeuralSound, Jin et al. 2022, sec. 4.2.4) preconditioned by geometric
//! multigrid ([`super::multigrid`]).
//!
//! Where it sits: the iterative alternative to [`super::lanczos`] behind [`super::solve`]; it
//! needs no factorisation of the fine matrix, only products with `K` and `M` and one V-cycle
//! per residual block, so its memory grows linearly with the object.
//!
//! The method. A block `X` of `m` vectors (the wanted modes, the rigid-body modes and a few
//! guard vectors that speed up the last wanted one) is improved by Rayleigh-Ritz on the span of
//! `[X, W, P]`: `W = T R` the preconditioned residuals `R = K X - M X Theta` and `P` the previous
//! step. Converged columns stop contributing to `W` and `P` (soft locking). The Rayleigh-Ritz
//! step uses both Gram matrices and drops near-dependent directions of the `M`-Gram matrix after
//! a diagonal scaling (Hetmaniuk and Lehoucq 2006; Duersch et al. 2018), which keeps it stable
//! when residuals become tiny.
//!
//! The start is nested: the coarsest multigrid level's Galerkin problem is solved by shift-invert
//! Lanczos (with the factor the V-cycle already holds), its modes are interpolated to the fine
//! grid, and the six rigid-body fields of the object are added exactly. The coarse solution also
//! says how many rigid modes and (for "modes below f_max") how many modes to expect; the block
//! grows if the fine problem turns out to have more.
//!
//! Models too small for a block of `3m` vectors to leave room (fewer than `4m` DOFs) are handed
//! to the direct solver, which is exact and instant at that size.

mod dense;
mod start;

use super::multigrid::Multigrid;
use super::{
    lanczos, random_block, select, solution, to_rows, EigenError, EigenOptions, EigenSolution,
    ModeCount, Operators, SolveTimings, Stop, Which,
};
use crate::buffer::zeroed;
use crate::fem::sparse::RowBlock;
use crate::fem::FemModel;
pub(crate) use dense::{dense_ritz, dense_ritz_by_cholesky};
use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatMut, MatRef, Par};
use start::nested_start;
pub(crate) use start::{rigid_centre, rigid_fields, rigid_row};
use std::time::Instant;

/// Columns per V-cycle (the multigrid scratch is sized for this many).
const MG_WIDTH: usize = 32;

/// `z ~= (K - sigma M)^-1 r` for a block of residuals: what LOBPCG's search directions come
/// from. The multigrid V-cycle ([`Multigrid`]) approximates it for cold solves of large models;
/// a sparse Cholesky factor ([`super::factor::ShiftedCholesky`]) applies it exactly, which
/// makes LOBPCG from a good start ([`super::warm`]) converge in a few iterations.
pub trait Preconditioner {
    /// Applies the preconditioner to the `r_layout.width` columns of `r` into `z` (same width).
    fn apply(&mut self, r: &[f64], r_layout: RowBlock, z: &mut [f64], z_layout: RowBlock);
}

impl Preconditioner for Multigrid {
    fn apply(&mut self, r: &[f64], r_layout: RowBlock, z: &mut [f64], z_layout: RowBlock) {
        Multigrid::apply(self, r, r_layout, z, z_layout)
    }
}

/// A run that has not lowered its worst wanted residual by 10 % in this many iterations has
/// stagnated (LOBPCG's Gram matrices limit its attainable residual to about 1e-8 of `||K||`):
/// it stops with `NoConvergence` instead of spending the whole iteration budget.
const STAGNATION_ITERATIONS: usize = 15;

/// LOBPCG iterates at least to this residual whatever the caller asks. A converged block is not
/// proof that no lower mode was missed; the missing one grows in from the random guard columns
/// over the iterations. At 1e-4 the solver stopped after 3-4 iterations and skipped a thin
/// bowl's 10th mode (48^3 and 64^3, `docs/chart.csv` before this floor); at 1e-6 it matches
/// Lanczos.
pub const MAX_TOLERANCE: f64 = 1e-6;

/// Tolerance of the coarse Lanczos solve that seeds the block: a start, not an answer.
const COARSE_TOLERANCE: f64 = 1e-5;

/// Guard vectors for `need` wanted ones.
pub(crate) fn guard(need: usize) -> usize {
    (need / 4).max(4)
}

/// A block of vectors with their `K` and `M` images, row-major with a fixed row stride `cap`.
/// The block is the columns `first..first + width`; columns before `first` are locked (kept,
/// but no longer part of the search).
struct Images {
    x: Vec<f64>,
    kx: Vec<f64>,
    mx: Vec<f64>,
    rows: usize,
    first: usize,
    width: usize,
    cap: usize,
}

/// Which of an [`Images`]' three buffers.
#[derive(Clone, Copy)]
enum Part {
    X,
    Kx,
    Mx,
}

impl Images {
    fn new(n: usize, cap: usize) -> Self {
        Images {
            x: zeroed(n * cap),
            kx: zeroed(n * cap),
            mx: zeroed(n * cap),
            rows: n,
            first: 0,
            width: 0,
            cap,
        }
    }

    fn layout(&self) -> RowBlock {
        RowBlock {
            width: self.width,
            stride: self.cap,
        }
    }

    fn buf(&self, part: Part) -> &[f64] {
        match part {
            Part::X => &self.x[self.first..],
            Part::Kx => &self.kx[self.first..],
            Part::Mx => &self.mx[self.first..],
        }
    }

    /// The block's columns of one buffer.
    fn view(&self, part: Part) -> MatRef<'_, f64> {
        MatRef::from_row_major_slice_with_stride(self.buf(part), self.rows, self.width, self.cap)
    }

    /// Any columns of one buffer, whatever the block is (locked ones included).
    fn columns(&self, part: Part, cols: std::ops::Range<usize>) -> MatRef<'_, f64> {
        let buf = match part {
            Part::X => &self.x,
            Part::Kx => &self.kx,
            Part::Mx => &self.mx,
        };
        MatRef::from_row_major_slice_with_stride(
            &buf[cols.start..],
            self.rows,
            cols.len(),
            self.cap,
        )
    }

    /// The block's columns of one buffer, writable.
    fn view_mut(&mut self, part: Part) -> MatMut<'_, f64> {
        let (rows, width, cap, first) = (self.rows, self.width, self.cap, self.first);
        let buf = match part {
            Part::X => &mut self.x[first..],
            Part::Kx => &mut self.kx[first..],
            Part::Mx => &mut self.mx[first..],
        };
        // Not `from_row_major_slice_with_stride_mut`: in faer 0.24 it builds a column-major view
        // (row stride 1, column stride `row_stride`). The transposed column-major view is right.
        MatMut::from_column_major_slice_with_stride_mut(buf, width, rows, cap).transpose_mut()
    }

    /// Recomputes `K X` and `M X` for the block's columns.
    fn refresh(&mut self, ops: &Operators) {
        let l = self.layout();
        if l.width == 0 {
            return;
        }
        let f = self.first;
        ops.spmm(Which::K, &self.x[f..], &mut self.kx[f..], l);
        ops.spmm(Which::M, &self.x[f..], &mut self.mx[f..], l);
    }

    /// Copies columns `cols` of all three buffers from `src` (same shape).
    fn copy_columns(&mut self, src: &Images, cols: std::ops::Range<usize>) {
        for (dst, from) in [
            (&mut self.x, &src.x),
            (&mut self.kx, &src.kx),
            (&mut self.mx, &src.mx),
        ] {
            for i in 0..self.rows {
                let r = i * self.cap;
                dst[r + cols.start..r + cols.end]
                    .copy_from_slice(&from[r + cols.start..r + cols.end]);
            }
        }
    }
}

/// Rayleigh-Ritz on the span of `blocks`: the lowest `want` Ritz values and the coefficient
/// matrix (`sum of widths` x `want`).
fn rayleigh_ritz(blocks: &[&Images], want: usize) -> Result<(Vec<f64>, Mat<f64>), EigenError> {
    let widths: Vec<usize> = blocks.iter().map(|b| b.width).collect();
    let s: usize = widths.iter().sum();
    let mut gk = Mat::<f64>::zeros(s, s);
    let mut gm = Mat::<f64>::zeros(s, s);
    let mut r0 = 0;
    for (i, bi) in blocks.iter().enumerate() {
        let mut c0 = r0;
        for bj in &blocks[i..] {
            let (ri, cj) = (r0..r0 + bi.width, c0..c0 + bj.width);
            let xi = bi.view(Part::X);
            let k = xi.transpose() * bj.view(Part::Kx);
            let m = xi.transpose() * bj.view(Part::Mx);
            gk.as_mut().get_mut(ri.clone(), cj.clone()).copy_from(&k);
            gm.as_mut().get_mut(ri.clone(), cj.clone()).copy_from(&m);
            gk.as_mut()
                .get_mut(cj.clone(), ri.clone())
                .copy_from(k.transpose());
            gm.as_mut().get_mut(cj, ri).copy_from(m.transpose());
            c0 += bj.width;
        }
        r0 += bi.width;
    }
    dense_ritz(&gk, &gm, want)
}

/// `dst = sum_i blocks[i] C[rows_i, cols]` (the vectors only; their images are recomputed with
/// two sparse products, cheaper and more accurate than combining them too), into the columns
/// `dst.first..dst.first + C.ncols()`.
fn combine(dst: &mut Images, blocks: &[&Images], c: MatRef<'_, f64>) {
    dst.width = c.ncols();
    let mut r0 = 0;
    for (i, b) in blocks.iter().enumerate() {
        let accum = if i == 0 { Accum::Replace } else { Accum::Add };
        matmul(
            dst.view_mut(Part::X),
            accum,
            b.view(Part::X),
            c.get(r0..r0 + b.width, ..),
            1.0,
            Par::Seq,
        );
        r0 += b.width;
    }
}

/// The converged state of one LOBPCG run.
pub(crate) struct Converged {
    /// Ritz values, ascending.
    pub theta: Vec<f64>,
    x: Images,
    /// Residuals (Jin et al. 2022, eq. 6).
    pub residuals: Vec<f64>,
}

impl Converged {
    /// `(theta, column, residual)` of the leading columns that meet `tolerance`.
    pub fn converged_pairs(&self, tolerance: f64) -> Vec<(f64, usize, f64)> {
        let conv = self
            .residuals
            .iter()
            .take_while(|&&r| r <= tolerance)
            .count();
        (0..conv)
            .map(|j| (self.theta[j], j, self.residuals[j]))
            .collect()
    }

    /// The Ritz vectors, one column each (a view of the row-major block).
    pub fn vectors(&self) -> MatRef<'_, f64> {
        self.x.view(Part::X)
    }
}

/// Per-column residuals of Jin et al. 2022, eq. 6 for the block's columns (`theta` holds their Ritz
/// values).
fn residuals(ops: &Operators, xb: &Images, theta: &[f64]) -> Vec<f64> {
    let (m, f) = (xb.width, xb.first);
    let mut r2 = vec![0.0; m];
    let mut x2 = vec![0.0; m];
    for i in 0..ops.dofs() {
        let row = i * xb.cap + f;
        let (x, kx, mx) = (
            &xb.x[row..row + m],
            &xb.kx[row..row + m],
            &xb.mx[row..row + m],
        );
        for j in 0..m {
            let r = kx[j] - theta[j] * mx[j];
            r2[j] += r * r;
            x2[j] += x[j] * x[j];
        }
    }
    (0..m)
        .map(|j| r2[j].sqrt() / ((ops.k_norm + theta[j].abs() * ops.m_norm) * x2[j].sqrt()))
        .collect()
}

/// Iterates from the block `start` (dense, `n x m`, by rows) until its first `need` columns
/// converge.
///
/// Locking: once the lowest columns have converged, that prefix leaves the search (hard
/// locking): it is no longer part of Rayleigh-Ritz or the block updates, and new directions are
/// kept `M`-orthogonal to it. Converged columns above an unconverged one only stop contributing
/// residual directions (soft locking), so the locked set is always the lowest Ritz pairs.
///
/// Each step: residuals and the stopping tests, [`Search::lock`] the converged prefix,
/// [`Search::directions`] `W`, then [`Search::update`] `X` and `P` by Rayleigh-Ritz.
pub(crate) fn iterate(
    ops: &Operators,
    precond: &mut dyn Preconditioner,
    start: &[f64],
    need: usize,
    options: &EigenOptions,
    iterations: &mut usize,
    stop: Stop,
) -> Result<Converged, EigenError> {
    let m = start.len() / ops.dofs();
    let mut search = Search::start(ops, start, m)?;
    let (mut best, mut best_at) = (f64::INFINITY, *iterations);
    loop {
        stop.check()?;
        let res = search.residuals(ops)?;
        if res[..need].iter().all(|&r| r <= options.tolerance) {
            return Ok(search.converged());
        }
        let worst = res[..need].iter().cloned().fold(0.0, f64::max);
        if worst < 0.9 * best {
            (best, best_at) = (worst, *iterations);
        }
        if *iterations >= options.max_iterations || *iterations - best_at >= STAGNATION_ITERATIONS {
            let converged = res.iter().take_while(|&&r| r <= options.tolerance).count();
            return Err(EigenError::NoConvergence {
                converged: converged.min(need),
                wanted: need,
                worst_residual: worst,
            });
        }
        *iterations += 1;
        search.lock(need, options.tolerance);
        let active: Vec<usize> = (search.locked..m)
            .filter(|&j| search.res[j] > options.tolerance)
            .collect();
        search.directions(ops, precond, &active);
        search.update(ops, &active)?;
    }
}

/// The state of one LOBPCG run: the block `X`, the previous step `P`, the search directions
/// `W` (each with `K` and `M` images), spares for the next `X` and `P`, and the locked prefix.
struct Search {
    xb: Images,
    /// The next `X`; its locked columns hold a copy of the locked modes.
    xt: Images,
    pb: Images,
    pt: Images,
    wb: Images,
    /// The active columns' residuals, dense `n x a`.
    rbuf: Vec<f64>,
    /// Ritz values, ascending.
    theta: Vec<f64>,
    /// Residuals (Jin et al. 2022, eq. 6), kept for the locked columns.
    res: Vec<f64>,
    /// Columns `0..locked` have left the search.
    locked: usize,
}

impl Search {
    /// Rayleigh-Ritz on the start block.
    fn start(ops: &Operators, start: &[f64], m: usize) -> Result<Self, EigenError> {
        let n = ops.dofs();
        let mut xt = Images::new(n, m);
        xt.x.copy_from_slice(start);
        xt.width = m;
        xt.refresh(ops);
        let (theta, c) = rayleigh_ritz(&[&xt], m)?;
        let mut xb = Images::new(n, m);
        combine(&mut xb, &[&xt], c.as_ref());
        xb.refresh(ops);
        Ok(Search {
            xb,
            xt,
            pb: Images::new(n, m),
            pt: Images::new(n, m),
            wb: Images::new(n, m),
            rbuf: zeroed(n * m),
            theta,
            res: vec![0.0; m],
            locked: 0,
        })
    }

    /// Recomputes the residuals of the columns still searched; all of them, checked finite.
    fn residuals(&mut self, ops: &Operators) -> Result<&[f64], EigenError> {
        let locked = self.locked;
        let fresh = residuals(ops, &self.xb, &self.theta[locked..]);
        self.res[locked..].copy_from_slice(&fresh);
        if self.res.iter().chain(&self.theta).any(|v| !v.is_finite()) {
            return Err(EigenError::NonFinite);
        }
        Ok(&self.res)
    }

    /// The whole block, converged.
    fn converged(mut self) -> Converged {
        self.xb.first = 0;
        self.xb.width = self.xb.cap;
        Converged {
            theta: self.theta,
            x: self.xb,
            residuals: self.res,
        }
    }

    /// Locks the converged prefix (up to `need` columns); the spare `X` keeps a copy of the
    /// newly locked columns, and they are projected out of `P`.
    fn lock(&mut self, need: usize, tolerance: f64) {
        let was = self.locked;
        while self.locked < need && self.res[self.locked] <= tolerance {
            self.locked += 1;
        }
        let (locked, m) = (self.locked, self.xb.cap);
        if locked == was {
            return;
        }
        self.xt.copy_columns(&self.xb, was..locked);
        // P was built while the newly locked columns were still searched: remove their
        // M-components (and from P's images), or the active columns keep picking them up
        // and stall near the tolerance.
        if self.pb.width > 0 {
            let coef = self.xb.columns(Part::Mx, was..locked).transpose() * self.pb.view(Part::X);
            for part in [Part::X, Part::Kx, Part::Mx] {
                matmul(
                    self.pb.view_mut(part),
                    Accum::Add,
                    self.xb.columns(part, was..locked),
                    &coef,
                    -1.0,
                    Par::Seq,
                );
            }
        }
        self.xb.first = locked;
        self.xb.width = m - locked;
        self.xt.first = locked;
    }

    /// `W = T R` for the `active` columns' residuals `R`, M-orthogonal to the whole block.
    fn directions(&mut self, ops: &Operators, precond: &mut dyn Preconditioner, active: &[usize]) {
        let (n, m, a) = (ops.dofs(), self.xb.cap, active.len());
        let xb = &self.xb;
        for i in 0..n {
            let (src, dst) = (i * m, i * a);
            for (q, &j) in active.iter().enumerate() {
                self.rbuf[dst + q] = xb.kx[src + j] - self.theta[j] * xb.mx[src + j];
            }
        }
        self.wb.width = a;
        let wl = self.wb.layout();
        precond.apply(&self.rbuf[..n * a], RowBlock::dense(a), &mut self.wb.x, wl);
        // W -= X (M X)^T W over all columns, locked ones included: keeps W M-orthogonal to the
        // locked modes and the Gram matrices well conditioned.
        let coef = xb.columns(Part::Mx, 0..m).transpose() * self.wb.view(Part::X);
        matmul(
            self.wb.view_mut(Part::X),
            Accum::Add,
            xb.columns(Part::X, 0..m),
            &coef,
            -1.0,
            Par::Seq,
        );
        self.wb.refresh(ops);
    }

    /// Rayleigh-Ritz on `[X W P]`; the new `X` and, for the `active` columns, the new `P`.
    fn update(&mut self, ops: &Operators, active: &[usize]) -> Result<(), EigenError> {
        let (n, m, locked, a) = (ops.dofs(), self.xb.cap, self.locked, active.len());
        let blocks: Vec<&Images> = [&self.xb, &self.wb, &self.pb]
            .into_iter()
            .filter(|b| b.width > 0)
            .collect();
        let (theta_new, c) = rayleigh_ritz(&blocks, m - locked)?;
        // The update without its X part, for every column: P_all = [W P] C[k.., :]. Then
        // X' = X C[..k, :] + P_all, and P' = P_all's active columns (Knyazev's form, which
        // spares a product with the whole basis).
        let (k, cols) = (self.xb.width, m - locked);
        let (xt, pt) = (&mut self.xt, &mut self.pt);
        pt.first = 0;
        combine(pt, &blocks[1..], c.get(k.., ..));
        combine(xt, &blocks[..1], c.get(..k, ..));
        for i in 0..n {
            let (row_x, row_p) = (i * m + locked, i * m);
            for j in 0..cols {
                xt.x[row_x + j] += pt.x[row_p + j];
            }
            if a < cols {
                for (q, &j) in active.iter().enumerate() {
                    pt.x[row_p + q] = pt.x[row_p + j - locked];
                }
            }
        }
        pt.width = a;
        xt.refresh(ops);
        pt.refresh(ops);
        std::mem::swap(&mut self.xb, &mut self.xt);
        std::mem::swap(&mut self.pb, &mut self.pt);
        self.theta[locked..].copy_from_slice(&theta_new);
        Ok(())
    }
}

/// Runs the solver (see the module docs).
pub fn solve(model: &FemModel, options: &EigenOptions) -> Result<EigenSolution, EigenError> {
    solve_until(model, options, Stop::NEVER)
}

/// [`solve`], polling `stop` after the multigrid set-up and once per iteration.
pub fn solve_until(
    model: &FemModel,
    options: &EigenOptions,
    stop: Stop,
) -> Result<EigenSolution, EigenError> {
    let options = &EigenOptions {
        tolerance: options.tolerance.min(MAX_TOLERANCE),
        ..*options
    };
    let ops = Operators::new(model);
    let n = ops.dofs();
    if let ModeCount::First(k) = options.count {
        if k + 6 > n {
            return Err(EigenError::TooFewDofs { dofs: n, wanted: k });
        }
    }
    let t0 = Instant::now();
    let mut mg = Multigrid::new(model, MG_WIDTH)?;
    let start = nested_start(model, &mut mg, options)?;
    // A block of 3m vectors must fit well inside the space; tiny models go to the direct solver.
    if 4 * start.m > n {
        return lanczos::solve_until(model, options, stop);
    }
    stop.check()?;
    let setup_ms = t0.elapsed().as_secs_f64() * 1e3;
    let t1 = Instant::now();
    let (mut need, mut m, mut block) = (start.need, start.m, start.block);
    let mut iterations = 0;
    loop {
        let done = iterate(&ops, &mut mg, &block, need, options, &mut iterations, stop)?;
        let pairs = done.converged_pairs(options.tolerance);
        let sel = select(&ops, &pairs, options.count);
        if sel.complete {
            let timings = SolveTimings {
                setup_ms,
                iterate_ms: t1.elapsed().as_secs_f64() * 1e3,
            };
            let x = done.x.view(Part::X);
            return Ok(solution(
                &pairs,
                &sel,
                x,
                timings,
                iterations,
                super::SolverKind::Lobpcg,
            ));
        }
        let rigid = sel.rigid;
        // More rigid modes than the coarse level showed, or more modes below the bound: grow.
        let grown = match options.count {
            ModeCount::First(k) => rigid + k,
            ModeCount::Below(_) => (need * 3 / 2).max(need + 8),
        }
        .min(super::MAX_MODES + 64);
        let m_new = grown + guard(grown);
        if grown <= need || 4 * m_new > n {
            return Err(EigenError::TooFewDofs {
                dofs: n,
                wanted: grown,
            });
        }
        let mut next = vec![0.0; n * m_new];
        let fill = to_rows(random_block(n, m_new - m, 11 + iterations as u64).as_ref());
        for i in 0..n {
            next[i * m_new..i * m_new + m].copy_from_slice(&done.x.x[i * m..i * m + m]);
            next[i * m_new + m..(i + 1) * m_new]
                .copy_from_slice(&fill[i * (m_new - m)..(i + 1) * (m_new - m)]);
        }
        (need, m, block) = (grown, m_new, next);
    }
}
