//! The sparse Cholesky factorisation of the shifted stiffness `K - sigma M` (supernodal),
//! ordered by geometric nested dissection or minimum degree ([`crate::fem::ordering`]): faer's
//! symbolic factorisation, this crate's numeric one ([`numeric`]: faer's algorithm, polling
//! the caller's [`Stop`] every few milliseconds), and this crate's solves ([`rows`]: row-major
//! blocks, a multiply-add per factor entry), with their scratch allocated once and reused (a
//! solve allocates nothing).

mod numeric;
mod rows;

use super::stop::Stop;
use super::EigenError;
use crate::buffer;
use crate::fem::memo::Memo;
use crate::fem::sparse::RowBlock;
use crate::fem::sparse::{BlockMass, BlockPattern};
use crate::fem::{ordering, sparse, FemModel};
use faer::sparse::linalg::cholesky::{SymbolicCholesky, SymbolicCholeskyRaw, SymmetricOrdering};
use faer::{MatMut, Side};
use rows::SupernodalRows;
use std::sync::Arc;

/// Right-hand sides solved together: one row of a chunk is `[f64; CHUNK]` (64 bytes, a cache
/// line); wider blocks are solved in chunks of this many columns.
const CHUNK: usize = 8;

/// Largest Cholesky factor accepted, in bytes (the factorisation's values and the solves'
/// packed copy, both held while the copy is made): beyond it the solve would exhaust memory or
/// take minutes; the error suggests LOBPCG or a coarser grid.
pub const MAX_FACTOR_BYTES: usize = 6 << 30;

/// Patterns whose symbolic factorisation [`ShiftedCholesky::new`] keeps: the last object's
/// and the one before (an undo).
pub const KEPT_PATTERNS: usize = 2;

/// Largest pattern (node blocks) whose symbolic factorisation is kept: 1M blocks is a 60k-DOF
/// hex27x2 object or a 150k-DOF hex8i one, whose key and symbolic structure take tens of MB;
/// larger objects are not sculpted interactively, and theirs would hold hundreds.
pub const MAX_KEPT_BLOCKS: usize = 1 << 20;

/// What a symbolic factorisation depends on: the block pattern and the elimination order.
#[derive(PartialEq)]
struct PatternKey {
    row_ptr: Vec<usize>,
    col: Vec<u32>,
    nodes: Vec<usize>,
}

/// Symbolic factorisations by pattern and order.
type SymbolicMemo = Memo<PatternKey, SymbolicCholesky<usize>, KEPT_PATTERNS>;

/// The symbolic factorisations [`ShiftedCholesky::new`] keeps, shared by the process.
static KEPT: SymbolicMemo = Memo::new();

/// The symbolic factorisations of symmetry classes ([`ShiftedCholesky::for_class`]), apart
/// from [`KEPT`] so an object's classes do not push out its whole pattern (which its next
/// stroke's exact answer may reuse).
static KEPT_CLASSES: SymbolicMemo = Memo::new();

/// `K - sigma M = L L^T`, ready to solve.
pub struct ShiftedCholesky {
    /// The factor's values, packed in panels for the solves (`rows::SupernodalRows::new`).
    values: Vec<f64>,
    /// Its supernodes, for the row-major solves.
    layout: SupernodalRows,
    /// `fwd[k]`: the DOF eliminated `k`-th; `inv` its inverse.
    fwd: Vec<usize>,
    inv: Vec<usize>,
    /// One chunk of right-hand sides, permuted, by rows (`dofs x CHUNK`).
    scratch: Vec<f64>,
    dofs: usize,
    /// The symbolic factorisation it was made with (tests check that it is shared).
    #[cfg(test)]
    symbolic: Arc<SymbolicCholesky<usize>>,
}

impl ShiftedCholesky {
    /// Factors `K - shift M` of `model`. The symbolic factorisation is kept for the
    /// [`KEPT_PATTERNS`] patterns factored last ([`crate::fem::memo`]): a model with the same
    /// pattern and elimination order (a stroke inside a hex27x2 block that stays occupied,
    /// another Poisson's ratio, a shift) reuses it: the symbolic part is about 8 ms of the
    /// default object's 76-100 ms factorisation (`cargo bench --bench eigen -- factor_bowl16`).
    /// `stop` is polled after the elimination order, after the matrix is permuted into it,
    /// and through the numeric factorisation (every few milliseconds: [`numeric`]); a stop
    /// returns [`EigenError::Interrupted`].
    pub fn new(model: &FemModel, shift: f64, stop: Stop) -> Result<Self, EigenError> {
        let nodes = ordering::fill_reducing_for(model);
        stop.check()?;
        let kept = (model.pattern.col.len() <= MAX_KEPT_BLOCKS).then_some(&KEPT);
        let mass = BlockMass::Scalar(model.m());
        Self::factor(
            &model.pattern,
            model.k(),
            mass,
            &[],
            shift,
            &nodes,
            stop,
            kept,
        )
    }

    /// Factors `K - shift M` given as node blocks, eliminating nodes in the order `nodes`
    /// (`nodes[k]` is the node eliminated `k`-th).
    pub fn from_blocks(
        pattern: &BlockPattern,
        k: &[[f64; 9]],
        m: &[f64],
        shift: f64,
        nodes: &[usize],
    ) -> Result<Self, EigenError> {
        Self::factor(
            pattern,
            k,
            BlockMass::Scalar(m),
            &[],
            shift,
            nodes,
            Stop::NEVER,
            None,
        )
    }

    /// Factors one symmetry class's `K - shift M` (its mass a diagonal a block, `m`, and the
    /// entries off the blocks' diagonals, `extra`, as `(row DOF, column DOF, value)` in both
    /// triangles: [`super::symmetric`]), eliminating nodes in the order `nodes`. Every class
    /// of a model has the same pattern, and the halves of the classes one swap splits
    /// another, so all but the first of each reuse its symbolic factorisation (two patterns
    /// are kept: the classes' and one swap's halves, or a sphere's halves split by two
    /// different swaps).
    pub fn for_class(
        pattern: &BlockPattern,
        k: &[[f64; 9]],
        m: &[[f64; 3]],
        extra: &[(u32, u32, f64)],
        shift: f64,
        nodes: &[usize],
        stop: Stop,
    ) -> Result<Self, EigenError> {
        let kept = (pattern.col.len() <= MAX_KEPT_BLOCKS).then_some(&KEPT_CLASSES);
        let mass = BlockMass::Diagonal(m);
        Self::factor(pattern, k, mass, extra, shift, nodes, stop, kept)
    }

    /// [`ShiftedCholesky::from_blocks`], the symbolic factorisation taken from (and kept in)
    /// `kept` where given.
    #[allow(clippy::too_many_arguments)]
    fn factor(
        pattern: &BlockPattern,
        k: &[[f64; 9]],
        mass: BlockMass<'_>,
        extra: &[(u32, u32, f64)],
        shift: f64,
        nodes: &[usize],
        stop: Stop,
        kept: Option<&SymbolicMemo>,
    ) -> Result<Self, EigenError> {
        let fail = |e: &dyn std::fmt::Debug| EigenError::Factorization(format!("{e:?}"));
        // The matrix comes permuted into the elimination order (`nodes`), so faer factors it
        // as it is instead of permuting a copy first. fwd[k] = the DOF eliminated k-th; inv
        // is its inverse.
        let fwd: Vec<usize> = nodes
            .iter()
            .flat_map(|&v| [3 * v, 3 * v + 1, 3 * v + 2])
            .collect();
        let n = fwd.len();
        let mut inv = vec![0usize; n];
        for (k, &d) in fwd.iter().enumerate() {
            inv[d] = k;
        }
        let mut a = sparse::permuted_shifted_csc(pattern, k, mass, shift, nodes, Side::Lower);
        subtract_extra(&mut a, extra, shift, &inv);
        if let Err(e) = stop.check() {
            recycle_csc(a);
            return Err(e);
        }
        let analyse = || {
            // The symbolic analysis reads the upper triangle.
            let upper = sparse::permuted_shifted_csc(pattern, k, mass, shift, nodes, Side::Upper);
            let symbolic =
                ordering::supernodal_symbolic(upper.symbolic(), SymmetricOrdering::Identity)
                    .map_err(|e| fail(&e));
            recycle_csc(upper);
            symbolic
        };
        let symbolic = match kept {
            Some(memo) => {
                let key = PatternKey {
                    row_ptr: pattern.row_ptr.clone(),
                    col: pattern.col.clone(),
                    nodes: nodes.to_vec(),
                };
                memo.try_get_or_make(key, analyse)?
            }
            None => Arc::new(analyse()?),
        };
        let SymbolicCholeskyRaw::Supernodal(supernodal) = symbolic.raw() else {
            return Err(EigenError::Factorization(
                "faer returned a simplicial factor where a supernodal one was asked for".into(),
            ));
        };
        // The factorisation's values and their packed copy (`rows`) are both held while it is
        // made.
        let bytes = symbolic
            .len_val()
            .saturating_add(rows::packed_total(supernodal))
            .saturating_mul(std::mem::size_of::<f64>());
        if bytes > MAX_FACTOR_BYTES {
            return Err(EigenError::Factorization(format!(
                "the factor would need {:.1} GB, over the {} GB limit; use --solver lobpcg or a coarser --resolution",
                bytes as f64 / 1e9,
                MAX_FACTOR_BYTES >> 30
            )));
        }
        let out_of_memory =
            |_| EigenError::Factorization("out of memory for the Cholesky factor".into());
        // The values come from the process's kept buffers where it has them (`crate::buffer`:
        // a worker's next solve does not fault them in again); the factorisation clears each
        // supernode's block before it fills it.
        let mut values = buffer::take_unfilled::<f64>(symbolic.len_val()).map_err(out_of_memory)?;
        let factored =
            numeric::factorize(supernodal, a.as_ref(), &mut values, stop).map_err(|e| match e {
                numeric::NumericError::Interrupted => EigenError::Interrupted,
                numeric::NumericError::NotPositive { column } => EigenError::Factorization(
                    format!("K - shift M is not positive definite (pivot {column} of {n})"),
                ),
            });
        recycle_csc(a);
        if let Err(e) = factored {
            buffer::recycle(values);
            return Err(e);
        }
        let (layout, packed) =
            SupernodalRows::new(supernodal, &values).map_err(|e| EigenError::Factorization(e.0))?;
        buffer::recycle(values);
        Ok(ShiftedCholesky {
            dofs: n,
            values: packed,
            layout,
            fwd,
            inv,
            scratch: {
                let mut scratch = buffer::take(n * CHUNK);
                scratch.resize(n * CHUNK, 0.0);
                scratch
            },
            #[cfg(test)]
            symbolic: Arc::clone(&symbolic),
        })
    }

    /// Values the factor keeps: its nonzeros, with the zeros that fill its panels' last rows
    /// and diagonal triangles.
    pub fn factor_nnz(&self) -> usize {
        self.values.len()
    }

    /// Overwrites `rhs` with `(K - sigma M)^-1 rhs`.
    pub fn solve_in_place(&mut self, mut rhs: MatMut<'_, f64>) {
        assert_eq!(rhs.nrows(), self.dofs, "one right-hand-side row per DOF");
        let width = rhs.ncols();
        self.solve_chunks(width, &mut rhs);
    }

    /// `z = (K - sigma M)^-1 r` for row-major blocks of any width (`r` and `z` may be wider
    /// than the block: only `width` columns of each row are read and written).
    pub fn solve_rows(&mut self, r: &[f64], r_layout: RowBlock, z: &mut [f64], z_layout: RowBlock) {
        assert_eq!(r_layout.width, z_layout.width, "blocks of one width");
        self.solve_chunks(r_layout.width, &mut (r, r_layout, z, z_layout));
    }

    /// Solves `width` right-hand sides held by `block` in chunks of up to [`CHUNK`] columns.
    fn solve_chunks(&mut self, width: usize, block: &mut impl RightHandSides) {
        let n = self.dofs;
        let mut c0 = 0;
        while c0 < width {
            let w = chunk_width(width - c0);
            let (fwd, x) = (&self.fwd, &mut self.scratch[..n * w]);
            for (k, row) in x.chunks_exact_mut(w).enumerate() {
                block.read(fwd[k], c0, row);
            }
            self.solve_scratch(w);
            let x = &self.scratch[..n * w];
            for (i, &k) in self.inv.iter().enumerate() {
                block.write(i, c0, &x[k * w..(k + 1) * w]);
            }
            c0 += w;
        }
    }

    /// Solves the permuted chunk in `scratch[..dofs * w]` in place.
    fn solve_scratch(&mut self, w: usize) {
        let x = &mut self.scratch[..self.dofs * w];
        let (layout, values) = (&self.layout, &self.values);
        match w {
            8 => layout.solve::<8>(values, x.as_chunks_mut::<8>().0),
            4 => layout.solve::<4>(values, x.as_chunks_mut::<4>().0),
            2 => layout.solve::<2>(values, x.as_chunks_mut::<2>().0),
            _ => layout.solve::<1>(values, x.as_chunks_mut::<1>().0),
        }
    }
}

/// Subtracts `shift` times the mass entries `extra` (`(row DOF, column DOF, value)`, both
/// triangles, none on the diagonal) from the permuted lower triangle `a`, whose DOF `d` sits
/// at `inv[d]`: a symmetry class's mass entries off its blocks' diagonals, a few next to a
/// swap's diagonal plane, which [`sparse::permuted_shifted_csc`] leaves out. Each lies in
/// `K`'s pattern, so in `a`'s.
fn subtract_extra(
    a: &mut faer::sparse::SparseColMat<usize, f64>,
    extra: &[(u32, u32, f64)],
    shift: f64,
    inv: &[usize],
) {
    let (symbolic, values) = a.parts_mut();
    for &(i, j, v) in extra {
        let (row, col) = (inv[i as usize], inv[j as usize]);
        if row < col {
            continue;
        }
        let range = symbolic.col_range(col);
        let at = symbolic.row_idx()[range.clone()]
            .iter()
            .position(|&r| r == row)
            .expect("K's pattern holds M's");
        values[range.start + at] -= shift * v;
    }
}

/// Hands a matrix's row indices and values back to the process's kept buffers.
fn recycle_csc(a: faer::sparse::SparseColMat<usize, f64>) {
    let (pattern, values) = a.into_parts();
    buffer::recycle(values);
    buffer::recycle(pattern.into_parts().4);
}

/// Where a solve's right-hand sides come from and its solution goes: DOF `i`'s entries in
/// the columns `c0..c0 + row.len()`.
trait RightHandSides {
    fn read(&self, i: usize, c0: usize, row: &mut [f64]);
    fn write(&mut self, i: usize, c0: usize, row: &[f64]);
}

/// A column-major block, solved in place.
impl RightHandSides for MatMut<'_, f64> {
    fn read(&self, i: usize, c0: usize, row: &mut [f64]) {
        for (j, v) in row.iter_mut().enumerate() {
            *v = self[(i, c0 + j)];
        }
    }
    fn write(&mut self, i: usize, c0: usize, row: &[f64]) {
        for (j, v) in row.iter().enumerate() {
            self[(i, c0 + j)] = *v;
        }
    }
}

/// Row-major right-hand sides and solution, each with its layout.
impl RightHandSides for (&[f64], RowBlock, &mut [f64], RowBlock) {
    fn read(&self, i: usize, c0: usize, row: &mut [f64]) {
        let at = i * self.1.stride + c0;
        row.copy_from_slice(&self.0[at..at + row.len()]);
    }
    fn write(&mut self, i: usize, c0: usize, row: &[f64]) {
        let at = i * self.3.stride + c0;
        self.2[at..at + row.len()].copy_from_slice(row);
    }
}

/// The widest chunk (8, 4, 2 or 1 columns) that fits in `left` columns.
fn chunk_width(left: usize) -> usize {
    [CHUNK, 4, 2, 1]
        .into_iter()
        .find(|&w| w <= left)
        .expect("left >= 1")
}

/// The values and the solve's scratch go back to the process's kept buffers.
impl Drop for ShiftedCholesky {
    fn drop(&mut self) {
        buffer::recycle(std::mem::take(&mut self.values));
        buffer::recycle(std::mem::take(&mut self.scratch));
    }
}

impl super::lobpcg::Preconditioner for ShiftedCholesky {
    /// The exact inverse `(K - sigma M)^-1`, in chunks of up to 8 columns.
    fn apply(&mut self, r: &[f64], r_layout: RowBlock, z: &mut [f64], z_layout: RowBlock) {
        self.solve_rows(r, r_layout, z, z_layout);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eigen::{random_block, Operators, Which};
    use crate::fem::ElementKind;
    use crate::shape::spec::ShapeSpec;
    use faer::Mat;

    /// A bowl of diameter `d` voxels with curved, partial voxels, of `kind` elements.
    fn shell(d: f64, kind: ElementKind) -> FemModel {
        let spec: ShapeSpec = format!("bowl:d={d},wall=2").parse().expect("spec");
        let ShapeSpec::Primitive { shape, .. } = spec else {
            panic!("a primitive")
        };
        let grid = shape.rasterize(1.0, 1.0).expect("grid");
        FemModel::assemble(&grid, kind, 0.3).expect("model")
    }

    /// A hex8i shell: supernodes of every size from 3 columns up.
    fn bowl() -> FemModel {
        shell(8.0, ElementKind::Hex8Incompatible)
    }

    /// A shell of hex27 blocks: supernodes of hundreds of rows, in panels of every remainder.
    fn hex27_bowl() -> FemModel {
        shell(10.0, ElementKind::Hex27Blocks)
    }

    /// `||A X - B|| / (||A|| ||X||)` per column, `A = K - shift M`.
    fn backward_errors(model: &FemModel, shift: f64, x: &Mat<f64>, b: &Mat<f64>) -> Vec<f64> {
        let ops = Operators::new(model);
        let ax =
            ops.apply_block(Which::K, x.as_ref()) - shift * ops.apply_block(Which::M, x.as_ref());
        let a_norm = ops.k_norm + shift.abs() * ops.m_norm;
        (0..x.ncols())
            .map(|j| (ax.col(j) - b.col(j)).norm_l2() / (a_norm * x.col(j).norm_l2()))
            .collect()
    }

    #[test]
    fn a_pattern_factored_before_reuses_its_symbolic_factorisation() {
        // The same pattern and order with another shift takes the kept symbolic
        // factorisation and gives the factor a fresh one gives, bit for bit; another pattern
        // gets its own. (A memo of its own: the process-wide one is shared with every test.)
        let memo = SymbolicMemo::new();
        let model = bowl();
        let nodes = ordering::nested_dissection(&model);
        let factor = |m: &FemModel, nodes: &[usize], shift: f64, kept| {
            ShiftedCholesky::factor(
                &m.pattern,
                m.k(),
                BlockMass::Scalar(m.m()),
                &[],
                shift,
                nodes,
                Stop::NEVER,
                kept,
            )
            .expect("factor")
        };
        let first = factor(&model, &nodes, -1e-3, Some(&memo));
        let second = factor(&model, &nodes, -2e-3, Some(&memo));
        assert!(Arc::ptr_eq(&first.symbolic, &second.symbolic));
        let fresh = factor(&model, &nodes, -2e-3, None);
        assert!(!Arc::ptr_eq(&fresh.symbolic, &second.symbolic));
        assert!(fresh.values == second.values && fresh.fwd == second.fwd);
        assert!(first.values != second.values);
        let spec: ShapeSpec = "bowl:d=10,wall=2".parse().expect("spec");
        let ShapeSpec::Primitive { shape, .. } = spec else {
            panic!("a primitive")
        };
        let other = FemModel::assemble(
            &shape.rasterize(1.0, 1.0).expect("grid"),
            ElementKind::Hex8Incompatible,
            0.3,
        )
        .expect("model");
        let other_nodes = ordering::nested_dissection(&other);
        let third = factor(&other, &other_nodes, -1e-3, Some(&memo));
        assert!(!Arc::ptr_eq(&third.symbolic, &second.symbolic));
    }

    /// The packed solve's two builds (AVX2 + FMA where the CPU has them, portable) agree to
    /// rounding: fused and unfused multiply-adds differ by an ulp per entry, which the solve
    /// can amplify by up to the shifted matrix's condition (~1e7 here); measured 2e-15 and
    /// 5e-15 of the solution's largest entry, so 1e-9 leaves that growth room, while a kernel
    /// reading a wrong entry or row is off by order one. (The factor's packing, which both
    /// builds share, is checked by the backward-error test below.) On both test bowls.
    #[test]
    fn packed_solves_agree_between_builds() {
        for model in [bowl(), hex27_bowl()] {
            let n = model.dofs();
            let shift = -1e-6 * Operators::new(&model).scale;
            let llt = ShiftedCholesky::new(&model, shift, Stop::NEVER).expect("factor");
            let b = random_block(n, 8, 3);
            let rows = |b: &Mat<f64>| -> Vec<[f64; 8]> {
                (0..n).map(|i| std::array::from_fn(|j| b[(i, j)])).collect()
            };
            let (mut fast, mut portable) = (rows(&b), rows(&b));
            llt.layout.solve::<8>(&llt.values, &mut fast);
            llt.layout.solve_portable::<8>(&llt.values, &mut portable);
            let largest = portable
                .iter()
                .flatten()
                .fold(0.0f64, |m, v| m.max(v.abs()));
            for (f, p) in fast.iter().flatten().zip(portable.iter().flatten()) {
                assert!(
                    (f - p).abs() <= 1e-9 * largest,
                    "{f} against {p} (largest {largest:.3e})"
                );
            }
        }
    }

    /// The packed copy of a factor writes every entry it holds, zeros included, so a kept
    /// buffer that still holds an earlier solve's numbers packs the same factor as fresh
    /// memory: kept buffers full of NaN are offered to the packing and the factor must come
    /// out bit for bit. (The pool is the process's, shared with other tests; the test asks
    /// until the packing took one of its buffers.)
    #[test]
    fn a_factor_packed_into_a_used_buffer_is_the_factor_packed_into_fresh_memory() {
        let model = hex27_bowl();
        let shift = -1e-6 * Operators::new(&model).scale;
        let fresh = ShiftedCholesky::new(&model, shift, Stop::NEVER).expect("factor");
        let len = fresh.values.len();
        let mut took_a_used_one = false;
        for _ in 0..5 {
            let used: Vec<Vec<f64>> = (0..3).map(|_| vec![f64::NAN; len]).collect();
            let at: Vec<*const f64> = used.iter().map(|v| v.as_ptr()).collect();
            used.into_iter().for_each(buffer::recycle);
            let again = ShiftedCholesky::new(&model, shift, Stop::NEVER).expect("factor");
            if at.contains(&again.values.as_ptr()) {
                took_a_used_one = true;
                assert_eq!(again.values.len(), len);
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert!(bits(&fresh.values) == bits(&again.values));
                break;
            }
        }
        assert!(took_a_used_one, "the packing never took a kept buffer");
    }

    /// Cholesky is backward stable: the residual relative to `||A|| ||x||` is a small multiple
    /// of the unit roundoff times the factor's row lengths, whatever `A`'s condition (~1e7
    /// here), for every chunk width (11 columns = 8 + 2 + 1) and both layouts.
    #[test]
    fn row_major_solves_are_backward_stable_for_every_width() {
        for model in [bowl(), hex27_bowl()] {
            let n = model.dofs();
            let shift = -1e-6 * Operators::new(&model).scale;
            let mut llt = ShiftedCholesky::new(&model, shift, Stop::NEVER).expect("factor");
            // eps * sqrt(n) * a few hundred (the factor's longest columns): ~1e-11 (measured
            // on the hex8i bowl: 5e-17).
            let bound = f64::EPSILON * (n as f64).sqrt() * 500.0;
            for width in [1, 2, 3, 4, 7, 8, 11] {
                let b = random_block(n, width, width as u64);
                let mut x = b.clone();
                llt.solve_in_place(x.as_mut());
                for e in backward_errors(&model, shift, &x, &b) {
                    assert!(
                        e < bound,
                        "width {width}: backward error {e:.2e} over {bound:.2e}"
                    );
                }
                // The row-major path, in a wider buffer, gives the same numbers.
                let stride = width + 3;
                let rows: Vec<f64> = (0..n * stride)
                    .map(|i| {
                        if i % stride < width {
                            b[(i / stride, i % stride)]
                        } else {
                            0.0
                        }
                    })
                    .collect();
                let mut z = vec![f64::NAN; n * stride];
                let layout = RowBlock { width, stride };
                llt.solve_rows(&rows, layout, &mut z, layout);
                for i in 0..n {
                    for j in 0..width {
                        assert_eq!(z[i * stride + j], x[(i, j)], "row {i} column {j}");
                    }
                    assert!(
                        z[i * stride + width].is_nan(),
                        "columns past the block untouched"
                    );
                }
            }
        }
    }
}
