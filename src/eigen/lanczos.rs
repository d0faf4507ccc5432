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
//! M-orthogonal (classical Gram-Schmidt against the last two blocks, then once against the
//! whole basis, a second time where the DGKS test asks; within the new block, Cholesky QR twice
//! in the M-inner product, [`qr`]); when it is full, the wanted Ritz vectors and the residual
//! block restart it (thick restart: Wu and Simon 2000; Stathopoulos and Saad 1998).
//! Convergence is checked from the Lanczos relation ([`check`]) at lengths scheduled from the
//! observed convergence rate, so the solve stops soon after the wanted pairs meet the
//! tolerance.

mod check;
mod iteration;
mod qr;

pub(crate) use iteration::{FirstRoom, Iteration};

use super::factor::ShiftedCholesky;
use super::{EigenError, EigenOptions, EigenSolution, Operators, Stop};
use crate::buffer::KeptColumns;
use crate::fem::FemModel;
use check::{Answer, Check, NextBlock, Progress, RitzCheck, RitzPairs};
use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};
use qr::{block_qr, chol_qr, QrRefusal};
use std::time::Instant;

/// The shift as a fraction of `trace K / trace M`; below the softest mode of most objects, and
/// far enough from zero that `K - sigma M` is well conditioned (condition ~ 1e7).
pub const SHIFT_RELATIVE: f64 = 1e-6;

/// The growing M-orthonormal basis with `M V` kept beside it.
/// Its columns live in the process's kept buffers ([`crate::buffer`]): a worker's next solve
/// does not fault them in again.
struct Basis {
    v: KeptColumns,
    mv: KeptColumns,
    len: usize,
}

impl Basis {
    fn new(n: usize, cap: usize) -> Self {
        Basis {
            v: KeptColumns::unfilled(n, cap),
            mv: KeptColumns::unfilled(n, cap),
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
        let mut v = KeptColumns::unfilled(n, cap);
        let mut mv = KeptColumns::unfilled(n, cap);
        v.as_mut()
            .get_mut(.., ..self.len)
            .copy_from(self.v.as_ref().get(.., ..self.len));
        mv.as_mut()
            .get_mut(.., ..self.len)
            .copy_from(self.mv.as_ref().get(.., ..self.len));
        self.v = v;
        self.mv = mv;
    }

    /// One classical Gram-Schmidt pass of `w` against the basis columns `cols` in the
    /// M-inner product; returns the coefficients removed (`cols.len() x w.ncols()`).
    fn project_pass(&self, cols: std::ops::Range<usize>, w: &mut Mat<f64>) -> Mat<f64> {
        let v = self.v.as_ref().get(.., cols.clone());
        let mv = self.mv.as_ref().get(.., cols);
        // In transposed form (`C^T = W^T (M V)`, `W^T -= C^T V^T`) the small block is the
        // left operand, which the matrix product packs; the basis is read in place.
        let mut ct = Mat::<f64>::zeros(w.ncols(), v.ncols());
        matmul(
            ct.as_mut(),
            Accum::Replace,
            w.transpose(),
            mv,
            1.0,
            Par::Seq,
        );
        matmul(
            w.as_mut().transpose_mut(),
            Accum::Add,
            ct.as_ref(),
            v.transpose(),
            -1.0,
            Par::Seq,
        );
        ct.transpose().to_owned()
    }

    /// Removes the components of `w` along the basis: first along its last `local` columns,
    /// where a Lanczos block's components lie in exact arithmetic (the three-term block
    /// recurrence), then along the whole basis once, which removes what rounding left along
    /// the older vectors. Returns every coefficient removed (`len x w.ncols()`) and the full
    /// pass's alone: [`chol_qr`] asks for a second full pass where that pass removed more
    /// than half of a column's M-norm squared (the "twice is enough" test of Daniel, Gragg,
    /// Kaufman and Stewart 1976), which after the local pass only happens when
    /// orthogonality was really lost.
    fn project_out(&self, w: &mut Mat<f64>, local: usize) -> (Mat<f64>, Mat<f64>) {
        let len = self.len;
        let mut total = Mat::zeros(len, w.ncols());
        if len == 0 {
            return (total, Mat::zeros(0, w.ncols()));
        }
        let recent = len.saturating_sub(local)..len;
        let c = self.project_pass(recent.clone(), w);
        total.as_mut().get_mut(recent, ..).copy_from(&c);
        let full = self.project_pass(0..len, w);
        total += &full;
        (total, full)
    }
}

/// `V Y` for a tall basis `V` (`n x len`) and a small `Y`, computed as `(Y^T V^T)^T` so the
/// matrix product packs the small operand and reads the basis in place (packing the basis
/// on every product cost a tenth of a solve).
fn tall_times_small(v: MatRef<'_, f64>, y: MatRef<'_, f64>) -> Mat<f64> {
    let mut out = Mat::<f64>::zeros(v.nrows(), y.ncols());
    matmul(
        out.as_mut().transpose_mut(),
        Accum::Replace,
        y.transpose(),
        v.transpose(),
        1.0,
        Par::Seq,
    );
    out
}

/// Requests of up to this many pairs get a basis of about three vectors per pair.
const ROOMY_BASIS_MAX_PAIRS: usize = 200;

/// Basis size for `nev` wanted pairs with blocks of `b`. Up to [`ROOMY_BASIS_MAX_PAIRS`] it
/// holds about three vectors per pair, which is what 66 pairs of the default bowl needed: such
/// requests converge without a restart (a thick restart keeps the wanted Ritz vectors and
/// drops the rest of the Krylov space; with room for two per pair the default object took 240
/// vectors and a restart, with three 208 and none). Larger requests restart at two per pair
/// (the basis and `M V` take `2 n cap` doubles).
fn basis_cap(nev: usize, b: usize, n: usize) -> usize {
    let per_pair = if nev <= ROOMY_BASIS_MAX_PAIRS { 3 } else { 2 };
    let want = (per_pair * nev + 3 * b).max(nev + 4 * b);
    (want.div_ceil(b) * b).min(n.max(b))
}

/// Runs the solver (see the module docs).
pub fn solve(model: &FemModel, options: &EigenOptions) -> Result<EigenSolution, EigenError> {
    solve_until(model, options, Stop::NEVER)
}

/// [`solve`], polling `stop` after the factorisation and once per block.
pub fn solve_until(
    model: &FemModel,
    options: &EigenOptions,
    stop: Stop,
) -> Result<EigenSolution, EigenError> {
    let ops = Operators::new(model);
    let t0 = Instant::now();
    let shift = -SHIFT_RELATIVE * ops.scale;
    let mut llt = ShiftedCholesky::new(model, shift, stop)?;
    stop.check()?;
    let mut solution = run_until(&ops, &mut llt, shift, options, stop)?;
    solution.timings.setup_ms = t0.elapsed().as_secs_f64() * 1e3 - solution.timings.iterate_ms;
    Ok(solution)
}

/// Basis length of the first convergence check: the wanted pairs plus two blocks (fewer
/// vectors cannot hold `nev` converged pairs of a block method), and in blocks of at most
/// [`LATE_FIRST_CHECK_MAX_BLOCK`] a quarter of the pairs again.
fn first_check(nev: usize, b: usize) -> usize {
    if b <= LATE_FIRST_CHECK_MAX_BLOCK {
        nev + 2 * b + nev / 4
    } else {
        nev + 2 * b
    }
}

/// Block sizes up to which the first convergence check waits for a quarter of the wanted
/// pairs beyond [`first_check`]'s minimum. At `nev + 2b` vectors a block Krylov space holds
/// about a fifth of its wanted pairs converged (the presets' classes: 2-8 of 20-50 at their
/// first check, and none met its request there), so that check only schedules the next; in
/// blocks of two (the classes of a 20-mode request, `symmetric::TINY_BLOCK_SIZE`), where a
/// check costs more than a block, skipping it pays. Cold solves with assembly, the later
/// check against `nev + 2b` in one build, rounds interleaved: the SciPy comparison's 1.5k-DOF
/// bar at 20 modes 0.92x (6.0 against 6.5 ms), the tin can preset (whose small parts iterate
/// in blocks of two) 0.94x. With blocks of four and eight too the wider classes did no better
/// (the aluminium plate 1.02x, the brass gong 1.01x, the default bowl 0.99x).
const LATE_FIRST_CHECK_MAX_BLOCK: usize = 2;

/// Vectors to add before the next convergence check, after one found `converged` of `nev`
/// wanted pairs converged in a basis of `len`: half of what a linear extrapolation (`len /
/// converged` vectors per pair) gives the missing pairs, in whole blocks, at least one block
/// and at most `nev`. A check costs about what a block does (a dense eigendecomposition of the
/// projected matrix, ~4 ms at 200 vectors); pairs converge faster as the basis grows, so the
/// extrapolation overestimates and half of it seldom overshoots (by a block when it does).
/// The default object went from 20 checks to 6.
fn vectors_before_next_check(len: usize, converged: usize, nev: usize, b: usize) -> usize {
    let missing = nev.saturating_sub(converged) as f64;
    let per_pair = len as f64 / converged.max(1) as f64;
    let gap = ((0.5 * missing * per_pair) as usize).min(nev);
    (gap / b * b).max(b)
}

/// Rigid-body modes of one free component (3 translations, 3 rotations): a request for `k`
/// modes starts by asking for `k + RIGID_BODY_MODES` pairs, and grows once the rigid count is
/// known (an object of several components has more).
const RIGID_BODY_MODES: usize = 6;

/// Pairs asked for first by a "modes below f_max" request, before any is known: 20 modes and
/// the rigid ones.
const BELOW_FIRST_PAIRS: usize = 20 + RIGID_BODY_MODES;

/// The iteration on an existing factorisation `llt` of `K - shift M`; `setup_ms` of the
/// result is zero. Its steps: [`Iteration::run`].
pub fn run(
    ops: &Operators,
    llt: &mut ShiftedCholesky,
    shift: f64,
    options: &EigenOptions,
) -> Result<EigenSolution, EigenError> {
    run_until(ops, llt, shift, options, Stop::NEVER)
}

/// [`run`], polling `stop` once per block.
pub fn run_until(
    ops: &Operators,
    llt: &mut ShiftedCholesky,
    shift: f64,
    options: &EigenOptions,
    stop: Stop,
) -> Result<EigenSolution, EigenError> {
    let room = FirstRoom {
        rigid: RIGID_BODY_MODES,
        below: BELOW_FIRST_PAIRS,
        rigid_expected: RIGID_BODY_MODES,
        below_expected: BELOW_FIRST_PAIRS,
    };
    Iteration::start(ops, options, room)?.run(ops, llt, shift, options, stop)
}

/// The residual block that did not fit in a full basis, kept for the restart.
struct Residual {
    q: Mat<f64>,
    mq: Mat<f64>,
    r: Mat<f64>,
    last: std::ops::Range<usize>,
}

impl Residual {
    fn next(&self) -> NextBlock<'_> {
        NextBlock {
            q: &self.q,
            mq: &self.mq,
            r: &self.r,
            last: self.last.clone(),
        }
    }
}

/// How [`Krylov::expand`] ended.
enum Expanded {
    /// Every wanted pair converged; the block that would have extended the basis is kept for
    /// a later, larger request ([`Iteration::run`]).
    Done(Box<Answer>, Residual),
    /// The basis is full.
    Full(Residual),
}

/// The basis, its projected matrix `H = V^T M Op V` and the schedule of one `run`.
struct Krylov {
    basis: Basis,
    h: Mat<f64>,
    /// Columns whose operator image is still to be computed.
    fresh: std::ops::Range<usize>,
    /// Basis length of the next convergence check.
    next_check: usize,
    /// Pairs the checks are scheduled for: those a request is expected to hold, which for a
    /// symmetry class is far fewer than the room its basis keeps.
    aim: usize,
    /// The capacity the basis grows to, a block at a time, before it restarts: it starts at
    /// what `aim` pairs need, so a class's basis sized for its worst case is not all mapped.
    room: usize,
    /// State of the random blocks that replace a block lost to breakdown.
    seed: u64,
    /// The block size asked for (a block can come out narrower after a breakdown).
    block: usize,
}

impl Krylov {
    /// A basis of capacity `cap` (to grow up to `room`) started from an M-orthonormalised
    /// random block of `b`, its checks scheduled for `aim` pairs.
    fn start(
        ops: &Operators,
        (cap, room): (usize, usize),
        b: usize,
        aim: usize,
    ) -> Result<Self, EigenError> {
        let n = ops.dofs();
        let mut basis = Basis::new(n, cap);
        let mut seed = 1u64;
        // A random block is well conditioned: CholQR2 (one block product with M) does, and
        // the column-wise fallback is for a block that lost its rank.
        let w = ops.random_block(b, seed);
        let nothing = Mat::zeros(0, w.ncols());
        let (q, mq, _) = match chol_qr(ops, &w, &nothing, &nothing) {
            Ok(qr) => qr,
            Err(_) => block_qr(ops, &basis, w, &mut seed)?,
        };
        basis.v.as_mut().get_mut(.., 0..b).copy_from(&q);
        basis.mv.as_mut().get_mut(.., 0..b).copy_from(&mq);
        basis.len = b;
        Ok(Krylov {
            h: Mat::zeros(cap, cap),
            basis,
            fresh: 0..b,
            next_check: first_check(aim, b),
            aim,
            room: room.max(cap),
            seed,
            block: b,
        })
    }

    /// The projected matrix of the basis so far.
    fn projected(&self) -> Mat<f64> {
        let len = self.basis.len;
        self.h.get(0..len, 0..len).to_owned()
    }

    /// Adds blocks `Q` of `Op V_fresh` (M-orthogonalised against the basis) until the wanted
    /// pairs converge or the basis is full, checking convergence at the scheduled lengths.
    fn expand(
        &mut self,
        ops: &Operators,
        llt: &mut ShiftedCholesky,
        checker: &mut RitzCheck,
    ) -> Result<Expanded, EigenError> {
        loop {
            checker.stop.check()?;
            let cols = self.fresh.clone();
            let mut w = self.basis.mv.as_ref().get(.., cols.clone()).to_owned();
            llt.solve_in_place(w.as_mut());
            let (c, q, mq, r) = self.orthogonalise(ops, w)?;
            self.h
                .as_mut()
                .get_mut(0..self.basis.len, cols.clone())
                .copy_from(&c);
            let block = Residual {
                q,
                mq,
                r,
                last: cols,
            };
            if self.basis.len >= self.next_check {
                match checker.run(&self.basis, &self.projected(), &block.next())? {
                    Check::Done(answer) => return Ok(Expanded::Done(answer, block)),
                    Check::Converged(progress) => self.schedule_check(progress),
                }
            }
            if !self.make_fit(&block) {
                return Ok(Expanded::Full(block));
            }
            self.append(block);
        }
    }

    /// Schedules the next convergence check after one found `progress`; the pairs aimed at
    /// rise to what the Ritz values say the request needs.
    fn schedule_check(&mut self, progress: Progress) {
        let len = self.basis.len;
        self.aim = self.aim.max(progress.needed);
        self.next_check =
            len + vectors_before_next_check(len, progress.converged, self.aim, self.block);
    }

    /// Whether the basis has room for `block`, growing it by half (within `room`) where it
    /// has not.
    fn make_fit(&mut self, block: &Residual) -> bool {
        let need = self.basis.len + block.q.ncols();
        if need > self.basis.cap() && need <= self.room {
            let cap = (self.basis.cap() * 3 / 2).next_multiple_of(self.block);
            self.grow(cap.clamp(need, self.room));
        }
        need <= self.basis.cap()
    }

    /// Appends the next block (its coefficients along the basis are in `h` already): it
    /// becomes the block whose operator image is computed next.
    fn append(&mut self, block: Residual) {
        let at = self.basis.len..self.basis.len + block.q.ncols();
        self.h
            .as_mut()
            .get_mut(at.clone(), block.last)
            .copy_from(&block.r);
        self.basis
            .v
            .as_mut()
            .get_mut(.., at.clone())
            .copy_from(&block.q);
        self.basis
            .mv
            .as_mut()
            .get_mut(.., at.clone())
            .copy_from(&block.mq);
        self.basis.len = at.end;
        self.fresh = at;
    }

    /// M-orthogonalises a new block `w` against the basis (the last two blocks, then the
    /// whole basis once or twice) and within itself: the coefficients `C`, the block `Q`, `M Q`
    /// and `R` with `w = V C + Q R`. A block that loses its rank is replaced by a random one.
    #[allow(clippy::type_complexity)]
    fn orthogonalise(
        &mut self,
        ops: &Operators,
        mut w: Mat<f64>,
    ) -> Result<(Mat<f64>, Mat<f64>, Mat<f64>, Mat<f64>), EigenError> {
        let (mut c, mut last_pass) = self.basis.project_out(&mut w, 2 * self.block);
        let mut passes = 1;
        let (q, mq, r) = loop {
            match chol_qr(ops, &w, &c, &last_pass) {
                Ok(qr) => break qr,
                Err(QrRefusal::Reorthogonalise) if passes < 2 => {
                    last_pass = self.basis.project_pass(0..self.basis.len, &mut w);
                    c += &last_pass;
                    passes += 1;
                }
                Err(_) => break block_qr(ops, &self.basis, w, &mut self.seed)?,
            }
        };
        Ok((c, q, mq, r))
    }

    /// Makes room for a basis of `cap` vectors.
    fn grow(&mut self, cap: usize) {
        if cap <= self.basis.cap() {
            return;
        }
        let len = self.basis.len;
        self.basis.grow(cap);
        let mut h = Mat::zeros(cap, cap);
        h.as_mut()
            .get_mut(0..len, 0..len)
            .copy_from(self.h.get(0..len, 0..len));
        self.h = h;
    }

    /// Thick restart: keeps the best `nev + b` Ritz vectors (as many as fit beside the residual
    /// block) and continues from the residual block; the projected matrix becomes an arrow.
    fn restart(&mut self, ritz: &RitzPairs, residual: &Residual, nev: usize, converged: usize) {
        let (len, b) = (self.basis.len, self.block);
        let (theta, order) = (&ritz.theta, &ritz.order);
        let y = ritz.y.as_ref().expect("the dense decomposition");
        let qb = residual.q.ncols();
        let keep_n = (nev + b).min(order.len()).min(self.basis.cap() - 2 * qb);
        let yk = Mat::from_fn(len, keep_n, |i, j| y[(i, order[j])]);
        let xk = tall_times_small(self.basis.v.as_ref().get(.., 0..len), yk.as_ref());
        let mxk = tall_times_small(self.basis.mv.as_ref().get(.., 0..len), yk.as_ref());
        // Residual coupling: Op x_j - theta_j x_j = Q (R y_j[last rows]).
        let last = &residual.last;
        let y_last = Mat::from_fn(last.len(), keep_n, |i, j| y[(last.start + i, order[j])]);
        let coupling = &residual.r * &y_last;
        let h = &mut self.h;
        h.fill(0.0);
        for j in 0..keep_n {
            h[(j, j)] = theta[order[j]];
        }
        h.as_mut()
            .get_mut(keep_n..keep_n + qb, 0..keep_n)
            .copy_from(&coupling);
        h.as_mut()
            .get_mut(0..keep_n, keep_n..keep_n + qb)
            .copy_from(coupling.transpose());
        let (v, mv) = (&mut self.basis.v, &mut self.basis.mv);
        v.as_mut().get_mut(.., 0..keep_n).copy_from(&xk);
        mv.as_mut().get_mut(.., 0..keep_n).copy_from(&mxk);
        v.as_mut()
            .get_mut(.., keep_n..keep_n + qb)
            .copy_from(&residual.q);
        mv.as_mut()
            .get_mut(.., keep_n..keep_n + qb)
            .copy_from(&residual.mq);
        self.basis.len = keep_n + qb;
        self.fresh = keep_n..keep_n + qb;
        self.next_check = self.basis.len + vectors_before_next_check(len, converged, nev, b);
    }
}
