//! The numeric supernodal Cholesky factorisation `A = L L^T`, this crate's own so that a
//! caller can stop it every few milliseconds.
//!
//! Where it sits: [`super::ShiftedCholesky`] takes faer's symbolic factorisation (the
//! supernodes and their row patterns, [`SymbolicSupernodalCholesky`]) and fills the numeric
//! values here, in faer's layout (each supernode a column-major block of its columns' rows),
//! before [`super::rows`] packs them for the solves. faer's own numeric factorisation is one
//! call that polls nothing; the exact solve of an object that a stroke made asymmetric is one
//! factorisation of the whole object (the ceramic cup's 0.5-0.7 s in the worker), which a
//! newer stroke could not end: it ran on beside the newer stroke's answer, sharing the memory
//! bus (ARCHITECTURE.md, "An obsolete exact solve gives way"). This one polls a [`Stop`]
//! before each update of a supernode by an earlier one and between panels of a wide
//! supernode ([`PANEL`]): on the cup's whole factor the longest step between two polls is
//! about 15 ms.
//!
//! The algorithm is faer's (`factorize_supernodal_numeric_llt`, left-looking, after CHOLMOD:
//! Chen, Davis, Hager and Rajamanickam, ACM TOMS 35(3), 2008): for each supernode `s` in
//! order, gather `A`'s columns into its block, subtract the update `L_d,mid+bot L_d,mid^T` of
//! every earlier supernode `d` with rows in `s`'s columns (`mid`: those rows; `bot`: `d`'s
//! rows below them), then factor the diagonal block (`L_ss L_ss^T`) and solve the rows below
//! (`L_bs = A_bs L_ss^-T`). faer forms each update and scatters it in one crate-private kernel;
//! here the update is one dense product into a scratch block (faer's public `matmul`)
//! followed by a scatter, and the dense factor and triangular solve are faer's public kernels.

use super::super::stop::Stop;
use crate::buffer;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{cholesky_in_place, cholesky_in_place_scratch, LltError};
use faer::linalg::matmul::triangular::{self, BlockStructure};
use faer::linalg::triangular_solve::solve_lower_triangular_in_place;
use faer::reborrow::{Reborrow, ReborrowMut};
use faer::sparse::linalg::cholesky::supernodal::SymbolicSupernodalCholesky;
use faer::sparse::SparseColMatRef;
use faer::{Accum, MatMut, MatRef, Par};

/// Why [`factorize`] gave no factor.
#[derive(Debug, PartialEq)]
pub(super) enum NumericError {
    /// The matrix is not positive definite: the pivot of this (permuted) column was not
    /// positive.
    NotPositive {
        /// The column, in elimination order.
        column: usize,
    },
    /// The caller's [`Stop`] asked to stop.
    Interrupted,
}

/// For each supernode `s`, the earlier supernodes whose rows reach `s`'s columns (the ones
/// whose updates [`factorize`] subtracts from `s`), ascending: `list[ptr[s]..ptr[s + 1]]`.
struct Descendants {
    ptr: Vec<usize>,
    list: Vec<u32>,
}

impl Descendants {
    fn new(symbolic: &SymbolicSupernodalCholesky<usize>) -> Self {
        let ns = symbolic.n_supernodes();
        let (begin, end) = (symbolic.supernode_begin(), symbolic.supernode_end());
        let mut owner = vec![0u32; symbolic.nrows()];
        for s in 0..ns {
            owner[begin[s]..end[s]].fill(s as u32);
        }
        // Each supernode's pattern is ascending, so its rows' owners come in runs.
        let each = |d: usize, f: &mut dyn FnMut(usize)| {
            let mut last = u32::MAX;
            for &row in symbolic.supernode(d).pattern() {
                let s = owner[row];
                if s != last {
                    f(s as usize);
                    last = s;
                }
            }
        };
        let mut ptr = vec![0usize; ns + 1];
        for d in 0..ns {
            each(d, &mut |s| ptr[s + 1] += 1);
        }
        for s in 0..ns {
            ptr[s + 1] += ptr[s];
        }
        let mut next = ptr.clone();
        let mut list = vec![0u32; ptr[ns]];
        for d in 0..ns {
            each(d, &mut |s| {
                list[next[s]] = d as u32;
                next[s] += 1;
            });
        }
        Descendants { ptr, list }
    }

    fn of(&self, s: usize) -> &[u32] {
        &self.list[self.ptr[s]..self.ptr[s + 1]]
    }
}

/// Fills `values` (faer's layout for `symbolic`, `symbolic.len_val()` entries) with the
/// Cholesky factor of `a_lower` (the lower triangle of a symmetric positive definite matrix,
/// already in elimination order: `symbolic` was made with the identity ordering), polling
/// `stop` before each descendant's update and between the panels of [`factor_block`].
pub(super) fn factorize(
    symbolic: &SymbolicSupernodalCholesky<usize>,
    a_lower: SparseColMatRef<'_, usize, f64>,
    values: &mut [f64],
    stop: Stop,
) -> Result<(), NumericError> {
    let n = symbolic.nrows();
    let ns = symbolic.n_supernodes();
    assert_eq!(values.len(), symbolic.len_val(), "values of another layout");
    assert_eq!(
        (a_lower.nrows(), a_lower.ncols()),
        (n, n),
        "matrix of another size"
    );
    let (begin, end) = (symbolic.supernode_begin(), symbolic.supernode_end());
    let val_ptr = symbolic.col_ptr_for_val();
    let descendants = Descendants::new(symbolic);
    // Where a row below supernode `s`'s diagonal block sits in its block (unset: usize::MAX).
    let mut local = vec![usize::MAX; n];
    let widest = (0..ns).map(|s| end[s] - begin[s]).max().unwrap_or(0);
    let mut stack_buf = MemBuffer::new(cholesky_in_place_scratch::<f64>(
        widest.min(2 * PANEL),
        Par::Seq,
        Default::default(),
    ));
    // The update of one descendant (sized once for the largest), and where each of its rows
    // goes in `s`'s block. Kept between factorisations (`crate::buffer`): the largest is
    // megabytes, which a fresh allocation would fault in page by page.
    let largest = (0..ns)
        .flat_map(|s| descendants.of(s).iter().map(move |&d| (s, d as usize)))
        .map(|(s, d)| {
            let d_pattern = symbolic.supernode(d).pattern();
            let first = d_pattern.partition_point(|&r| r < begin[s]);
            let mid = d_pattern[first..].partition_point(|&r| r < end[s]);
            (d_pattern.len() - first) * mid
        })
        .max()
        .unwrap_or(0);
    let mut update: Vec<f64> = buffer::take(largest);
    update.resize(largest, 0.0);
    let mut to_row: Vec<usize> = Vec::new();
    for s in 0..ns {
        let (s_start, s_end) = (begin[s], end[s]);
        let s_cols = s_end - s_start;
        let s_pattern = symbolic.supernode(s).pattern();
        let s_rows = s_cols + s_pattern.len();
        for (i, &row) in s_pattern.iter().enumerate() {
            local[row] = s_cols + i;
        }
        let (head, tail) = values.split_at_mut(val_ptr[s]);
        let ls = &mut tail[..val_ptr[s + 1] - val_ptr[s]];
        // Each block is cleared as it is reached (one pass over the values, as they are
        // first used), then gathers A's columns.
        ls.fill(0.0);
        for j in s_start..s_end {
            let col = &mut ls[(j - s_start) * s_rows..][..s_rows];
            for (&i, &v) in a_lower
                .row_idx_of_col_raw(j)
                .iter()
                .zip(a_lower.val_of_col(j))
            {
                if i < j {
                    continue;
                }
                col[if i >= s_end { local[i] } else { i - s_start }] += v;
            }
        }
        // The earlier supernodes' updates.
        for &d in descendants.of(s) {
            if stop.check().is_err() {
                buffer::recycle(update);
                return Err(NumericError::Interrupted);
            }
            let d = d as usize;
            let d_cols = end[d] - begin[d];
            let d_pattern = symbolic.supernode(d).pattern();
            let d_rows = d_cols + d_pattern.len();
            let ld =
                MatRef::from_column_major_slice(&head[val_ptr[d]..val_ptr[d + 1]], d_rows, d_cols);
            let first = d_pattern.partition_point(|&r| r < s_start);
            let mid = d_pattern[first..].partition_point(|&r| r < s_end);
            let below = d_pattern.len() - first;
            let ld_mid_bot = ld.subrows(d_cols + first, below);
            let ld_mid = ld_mid_bot.subrows(0, mid);
            let w = MatMut::from_column_major_slice_mut(&mut update[..below * mid], below, mid);
            // The rows in `s`'s columns give the lower triangle of a square block (the upper
            // one is never read); the rows below them a full block.
            let (w_mid, w_bot) = w.split_at_row_mut(mid);
            triangular::matmul(
                w_mid,
                BlockStructure::TriangularLower,
                Accum::Replace,
                ld_mid,
                BlockStructure::Rectangular,
                ld_mid.transpose(),
                BlockStructure::Rectangular,
                1.0,
                Par::Seq,
            );
            faer::linalg::matmul::matmul(
                w_bot,
                Accum::Replace,
                ld_mid_bot.subrows(mid, below - mid),
                ld_mid.transpose(),
                1.0,
                Par::Seq,
            );
            to_row.clear();
            to_row.extend(d_pattern[first..].iter().enumerate().map(|(i, &r)| {
                if i < mid {
                    r - s_start
                } else {
                    local[r]
                }
            }));
            scatter_subtract(ls, s_rows, &update[..below * mid], &to_row, mid);
        }
        let block = MatMut::from_column_major_slice_mut(ls, s_rows, s_cols);
        if let Err(e) = factor_block(block, s_start, MemStack::new(&mut stack_buf), stop) {
            buffer::recycle(update);
            return Err(e);
        }
        for &row in s_pattern {
            local[row] = usize::MAX;
        }
    }
    buffer::recycle(update);
    Ok(())
}

/// Columns factored between two polls in a supernode wider than two of them: the root
/// supernodes of the large presets' whole factors are a thousand columns and more, whose
/// dense factorisation in one call took up to 55 ms (the ceramic cup's), in panels of 64
/// columns a few milliseconds each.
const PANEL: usize = 64;

/// Factors one supernode's block, its descendants' updates subtracted (`s_rows x s_cols`,
/// its diagonal block on top): `L_ss L_ss^T` in place of the diagonal block (its lower
/// triangle), `L_bs = A_bs L_ss^-T` in place of the rows below. A block wider than two
/// [`PANEL`]s is factored panel by panel, left-looking (each panel's columns updated by the
/// columns before, factored, and the rows below solved), polling `stop` between panels.
fn factor_block(
    mut block: MatMut<'_, f64>,
    s_start: usize,
    stack: &mut MemStack,
    stop: Stop,
) -> Result<(), NumericError> {
    let (rows, cols) = (block.nrows(), block.ncols());
    let step = if cols > 2 * PANEL { PANEL } else { cols };
    let mut c0 = 0;
    while c0 < cols {
        let c1 = (c0 + step).min(cols);
        let w = c1 - c0;
        let (left, right) = block.rb_mut().split_at_col_mut(c0);
        let panel = right.subcols_mut(0, w).subrows_mut(c0, rows - c0);
        let (mut top, mut bottom) = panel.split_at_row_mut(w);
        if c0 > 0 {
            let done = left.rb().subrows(c0, rows - c0);
            let (done_top, done_bottom) = done.split_at_row(w);
            triangular::matmul(
                top.rb_mut(),
                BlockStructure::TriangularLower,
                Accum::Add,
                done_top,
                BlockStructure::Rectangular,
                done_top.transpose(),
                BlockStructure::Rectangular,
                -1.0,
                Par::Seq,
            );
            faer::linalg::matmul::matmul(
                bottom.rb_mut(),
                Accum::Add,
                done_bottom,
                done_top.transpose(),
                -1.0,
                Par::Seq,
            );
        }
        if let Err(LltError::NonPositivePivot { index }) = cholesky_in_place(
            top.rb_mut(),
            Default::default(),
            Par::Seq,
            stack,
            Default::default(),
        ) {
            return Err(NumericError::NotPositive {
                column: s_start + c0 + index,
            });
        }
        solve_lower_triangular_in_place(top.rb(), bottom.transpose_mut(), Par::Seq);
        c0 = c1;
        if c0 < cols && stop.check().is_err() {
            return Err(NumericError::Interrupted);
        }
    }
    Ok(())
}

/// Subtracts the lower part of the update `w` (`to_row.len()` rows by `mid` columns, column-
/// major) from the supernode's block `ls` (`s_rows` rows a column): `w[i, j]` goes to row
/// `to_row[i]` of column `to_row[j]`, for `i >= j`. Rows that map to consecutive rows of the
/// block (the common case: a descendant's rows are mostly a run of the supernode's) are
/// subtracted as slices.
fn scatter_subtract(ls: &mut [f64], s_rows: usize, w: &[f64], to_row: &[usize], mid: usize) {
    let below = to_row.len();
    assert!(
        to_row.iter().all(|&r| r < s_rows),
        "a row outside the supernode"
    );
    assert!(to_row[..mid]
        .iter()
        .all(|&c| c * s_rows + s_rows <= ls.len()));
    assert!(w.len() >= below * mid);
    let contiguous = to_row.windows(2).all(|p| p[1] == p[0] + 1);
    for j in 0..mid {
        let col = &mut ls[to_row[j] * s_rows..][..s_rows];
        let wj = &w[j * below..][..below];
        if contiguous {
            let start = to_row[j];
            for (c, &v) in col[start..start + (below - j)].iter_mut().zip(&wj[j..]) {
                *c -= v;
            }
        } else {
            for i in j..below {
                // SAFETY: every `to_row[i]` is below `s_rows` = `col.len()` (asserted above).
                unsafe { *col.get_unchecked_mut(*to_row.get_unchecked(i)) -= *wj.get_unchecked(i) };
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eigen::Operators;
    use crate::fem::sparse::{permuted_shifted_csc, BlockMass};
    use crate::fem::{ordering, ElementKind, FemModel};
    use faer::sparse::linalg::cholesky::SymmetricOrdering;
    use faer::sparse::linalg::cholesky::{SymbolicCholesky, SymbolicCholeskyRaw};
    use faer::sparse::SparseColMat;
    use faer::Side;
    use std::cell::Cell;

    /// A bowl of diameter `d` voxels, wall 2, of `kind` elements.
    fn bowl(d: f64, kind: ElementKind) -> FemModel {
        crate::fem::test_model(&format!("bowl:d={d},wall=2"), kind, 0.3)
    }

    /// `K - shift M` of `model` in nested-dissection order (its lower triangle) and its
    /// supernodal symbolic factorisation, as [`super::super::ShiftedCholesky`] makes them.
    fn problem(
        model: &FemModel,
        shift: f64,
    ) -> (SparseColMat<usize, f64>, SymbolicCholesky<usize>) {
        let nodes = ordering::nested_dissection(model);
        let csc = |side| {
            let mass = BlockMass::Scalar(model.m());
            permuted_shifted_csc(&model.pattern, model.k(), mass, shift, &nodes, side)
        };
        let upper = csc(Side::Upper);
        let symbolic = ordering::supernodal_symbolic(upper.symbolic(), SymmetricOrdering::Identity)
            .expect("symbolic");
        (csc(Side::Lower), symbolic)
    }

    fn supernodal(symbolic: &SymbolicCholesky<usize>) -> &SymbolicSupernodalCholesky<usize> {
        match symbolic.raw() {
            SymbolicCholeskyRaw::Supernodal(s) => s,
            SymbolicCholeskyRaw::Simplicial(_) => panic!("a supernodal structure was forced"),
        }
    }

    #[test]
    fn the_factor_is_faers_to_rounding() {
        // faer's numeric factorisation of the same matrix is the independent reference: the
        // same algorithm with other kernels, so the two differ by rounding in another order.
        // Cholesky is backward stable, and the entries of `L` are bounded by the square roots
        // of `A`'s diagonal, so every entry agrees to a small multiple of `eps sqrt(n)` times
        // the largest (measured: 9e-16 of it on the default object, bit for bit on the hex8i shell). The default object's whole factor has
        // supernodes wider than two panels, so the panel-by-panel path is covered; the hex8i
        // shell has supernodes from 3 columns up.
        for model in [
            bowl(16.0, ElementKind::Hex27Blocks),
            bowl(8.0, ElementKind::Hex8Incompatible),
        ] {
            let shift = -1e-3 * Operators::new(&model).scale;
            let (a, symbolic) = problem(&model, shift);
            let s = supernodal(&symbolic);
            let widest = (0..s.n_supernodes())
                .map(|k| s.supernode_end()[k] - s.supernode_begin()[k])
                .max()
                .unwrap();
            let mut ours = vec![f64::NAN; symbolic.len_val()];
            factorize(s, a.as_ref(), &mut ours, Stop::NEVER).expect("positive definite");
            let mut reference = vec![0.0; symbolic.len_val()];
            let req = symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default());
            let mut mem = MemBuffer::new(req);
            symbolic
                .factorize_numeric_llt(
                    &mut reference,
                    a.as_ref(),
                    Side::Lower,
                    Default::default(),
                    Par::Seq,
                    MemStack::new(&mut mem),
                    Default::default(),
                )
                .expect("faer");
            let largest = reference.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let worst = ours
                .iter()
                .zip(&reference)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0f64, f64::max);
            let n = model.dofs() as f64;
            let bound = 10.0 * f64::EPSILON * n.sqrt() * largest;
            assert!(
                worst <= bound,
                "{} DOFs, widest supernode {widest}: an entry {worst:.2e} off, bound {bound:.2e}",
                model.dofs()
            );
            if model.dofs() > 5000 {
                assert!(widest > 2 * PANEL, "widest supernode {widest}: no panels");
            }
        }
    }

    #[test]
    fn a_stop_ends_the_factorisation_at_its_next_poll() {
        // Polled before every descendant's update and between panels: a poll that says stop
        // at its k-th call ends it there with `Interrupted` (k polls made); a poll that never
        // does leaves the factor bit for bit the unpolled one.
        let model = bowl(16.0, ElementKind::Hex27Blocks);
        let shift = -1e-3 * Operators::new(&model).scale;
        let (a, symbolic) = problem(&model, shift);
        let s = supernodal(&symbolic);
        let mut plain = vec![0.0; symbolic.len_val()];
        factorize(s, a.as_ref(), &mut plain, Stop::NEVER).expect("factor");
        let polls = Cell::new(0usize);
        let count = || {
            polls.set(polls.get() + 1);
            false
        };
        let mut polled = vec![0.0; symbolic.len_val()];
        factorize(s, a.as_ref(), &mut polled, Stop::when(&count)).expect("factor");
        assert!(plain == polled, "a poll changed the factor");
        let steps = polls.get();
        assert!(
            steps > s.n_supernodes(),
            "{steps} polls for {} supernodes",
            s.n_supernodes()
        );
        for k in [1, steps / 2, steps] {
            let calls = Cell::new(0usize);
            let at_k = || {
                calls.set(calls.get() + 1);
                calls.get() >= k
            };
            let mut values = vec![0.0; symbolic.len_val()];
            let got = factorize(s, a.as_ref(), &mut values, Stop::when(&at_k));
            assert_eq!(got, Err(NumericError::Interrupted), "stopped at poll {k}");
            assert_eq!(calls.get(), k, "went on after the poll that said stop");
        }
    }

    #[test]
    fn a_matrix_that_is_not_positive_definite_is_refused() {
        // `K - shift M` with the shift above the lowest non-rigid eigenvalue has negative
        // eigenvalues (and a free body's six rigid modes at zero make `K` alone singular): no
        // factor, and the column whose pivot failed.
        let model = bowl(8.0, ElementKind::Hex8Incompatible);
        let shift = 1e-2 * Operators::new(&model).scale;
        let (a, symbolic) = problem(&model, shift);
        let mut values = vec![0.0; symbolic.len_val()];
        match factorize(supernodal(&symbolic), a.as_ref(), &mut values, Stop::NEVER) {
            Err(NumericError::NotPositive { column }) => assert!(column < model.dofs()),
            other => panic!("expected a refused pivot, got {other:?}"),
        }
    }
}
