//! Node-blocked sparse symmetric matrices (3x3 blocks, one per node pair), as the FEM assembles
//! them, with the products the eigensolvers need and the conversion to `faer` for factoring.
//!
//! Both triangles are stored, so a product is one pass over the blocks; `K` and `M` share one
//! [`BlockPattern`].

use faer::sparse::{SparseColMat, SymbolicSparseColMat};

/// Sparsity of a node-blocked matrix: CSR over nodes, columns sorted.
#[derive(Clone, Debug)]
pub struct BlockPattern {
    /// Row starts, `nodes + 1` entries.
    pub row_ptr: Vec<usize>,
    /// Column node of each block.
    pub col: Vec<u32>,
}

impl BlockPattern {
    /// Number of block rows (nodes).
    pub fn nodes(&self) -> usize {
        self.row_ptr.len() - 1
    }

    /// Position of block `(row, col)`, if present.
    #[inline]
    pub fn find(&self, row: usize, col: u32) -> Option<usize> {
        let s = self.row_ptr[row];
        let cols = &self.col[s..self.row_ptr[row + 1]];
        cols.binary_search(&col).ok().map(|i| s + i)
    }
}

impl BlockPattern {
    /// The pattern of an element mesh: node `a` couples to every node that shares an element
    /// with it. `elements` holds `nodes_per_element` node numbers per element.
    pub fn from_elements(nodes: usize, elements: &[u32], nodes_per_element: usize) -> Self {
        let mut rows: Vec<Vec<u32>> = vec![Vec::new(); nodes];
        for e in elements.chunks_exact(nodes_per_element) {
            for &a in e {
                rows[a as usize].extend_from_slice(e);
            }
        }
        let mut row_ptr = Vec::with_capacity(nodes + 1);
        let mut col = Vec::new();
        row_ptr.push(0);
        for r in rows.iter_mut() {
            r.sort_unstable();
            r.dedup();
            col.extend_from_slice(r);
            row_ptr.push(col.len());
        }
        BlockPattern { row_ptr, col }
    }
}

/// Values of a symmetric node-blocked matrix on a shared pattern: block `b` is row-major 3x3.
pub type Blocks = Vec<[f64; 9]>;

/// Adds element matrices into `k` and `m` (both on `pattern`). Element `e` has the nodes
/// `elements[e * nloc..(e + 1) * nloc]` and the dense matrices `matrices(e)`: `3 nloc` square,
/// row-major, DOFs node-major (`3 a + c`).
pub fn add_elements<'a>(
    pattern: &BlockPattern,
    elements: &[u32],
    nloc: usize,
    matrices: impl Fn(usize) -> (&'a [f64], &'a [f64]),
    k: &mut [[f64; 9]],
    m: &mut [[f64; 9]],
) {
    let ndof = 3 * nloc;
    let mut slots = vec![0usize; nloc * nloc];
    for (index, e) in elements.chunks_exact(nloc).enumerate() {
        let (ke, me) = matrices(index);
        for (i, &a) in e.iter().enumerate() {
            for (j, &b) in e.iter().enumerate() {
                slots[i * nloc + j] = pattern
                    .find(a as usize, b)
                    .expect("pattern holds every element pair");
            }
        }
        for i in 0..nloc {
            for j in 0..nloc {
                let s = slots[i * nloc + j];
                for c in 0..3 {
                    for d in 0..3 {
                        let off = (3 * i + c) * ndof + 3 * j + d;
                        k[s][3 * c + d] += ke[off];
                        m[s][3 * c + d] += me[off];
                    }
                }
            }
        }
    }
}

/// `y = A x` for a node-blocked matrix.
pub fn spmv(pattern: &BlockPattern, a: &[[f64; 9]], x: &[f64], y: &mut [f64]) {
    for r in 0..pattern.nodes() {
        let mut acc = [0.0; 3];
        let span = pattern.row_ptr[r]..pattern.row_ptr[r + 1];
        for (&col, v) in pattern.col[span.clone()].iter().zip(&a[span]) {
            let c = col as usize * 3;
            let (x0, x1, x2) = (x[c], x[c + 1], x[c + 2]);
            acc[0] += v[0] * x0 + v[1] * x1 + v[2] * x2;
            acc[1] += v[3] * x0 + v[4] * x1 + v[5] * x2;
            acc[2] += v[6] * x0 + v[7] * x1 + v[8] * x2;
        }
        y[3 * r..3 * r + 3].copy_from_slice(&acc);
    }
}

/// A block of `width` vectors stored row-major with row stride `stride`: the values of DOF `i`
/// are `data[i * stride..i * stride + width]`. Block methods (LOBPCG, multigrid on a block) keep
/// their vectors this way so one pass over a matrix serves every vector.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RowBlock {
    /// Vectors in the block.
    pub width: usize,
    /// Distance between consecutive DOFs' rows (`>= width`).
    pub stride: usize,
}

impl RowBlock {
    /// A dense block (`stride == width`).
    pub fn dense(width: usize) -> Self {
        RowBlock {
            width,
            stride: width,
        }
    }
}

/// `Y = A X` for a block of vectors (see [`RowBlock`]); `x` and `y` start at the block's first
/// column and may be wider (only `layout.width` columns of each row are read and written).
pub fn spmm(pattern: &BlockPattern, a: &[[f64; 9]], x: &[f64], y: &mut [f64], layout: RowBlock) {
    let need = (3 * pattern.nodes()).saturating_sub(1) * layout.stride + layout.width;
    assert!(layout.width <= layout.stride && x.len() >= need && y.len() >= need);
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx512f") {
        // SAFETY: the CPU supports AVX-512F (checked just above; it implies AVX2 and FMA), the
        // only requirement of a `target_feature` function; the lengths were asserted above.
        unsafe { spmm_avx512(pattern, a, x, y, layout) };
        return;
    }
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU supports AVX2 and FMA (checked just above), the only requirement of a
        // `target_feature` function; the kernel itself is safe code.
        unsafe { spmm_avx2(pattern, a, x, y, layout) };
        return;
    }
    spmm_kernel(pattern, a, x, y, layout);
}

/// The AVX2/FMA kernel: every node row through [`row_avx2`].
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn spmm_avx2(pattern: &BlockPattern, a: &[[f64; 9]], x: &[f64], y: &mut [f64], l: RowBlock) {
    for r in 0..pattern.nodes() {
        // SAFETY: the caller (`spmm`) checked the slice lengths and the CPU features.
        unsafe { row_avx2(pattern, a, x, y, l, r, 0) };
    }
}

/// The AVX-512 kernel: 16 columns per pass (3 rows x 2 registers of accumulators); the last
/// pass of a row masks the columns past the width.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx2,fma")]
unsafe fn spmm_avx512(
    pattern: &BlockPattern,
    a: &[[f64; 9]],
    x: &[f64],
    y: &mut [f64],
    l: RowBlock,
) {
    use std::arch::x86_64::*;
    let (b, ld) = (l.width, l.stride);
    let nodes = pattern.nodes();
    let xp = x.as_ptr();
    let yp = y.as_mut_ptr();
    for r in 0..nodes {
        let span = pattern.row_ptr[r]..pattern.row_ptr[r + 1];
        let cols = &pattern.col[span.clone()];
        let vals = &a[span];
        let mut j0 = 0;
        while j0 < b {
            let w = (b - j0).min(16);
            let lo: __mmask8 = ((1u32 << w.min(8)) - 1) as u8;
            let hi: __mmask8 = ((1u32 << w.saturating_sub(8)) - 1) as u8;
            let mut acc = [_mm512_setzero_pd(); 6];
            for (&col, v) in cols.iter().zip(vals) {
                assert!((col as usize) < nodes, "pattern column out of range");
                // SAFETY: col < nodes, so the three rows 3 col + d start at most at
                // (3 nodes - 1) ld; the masks load only columns j0..j0 + w <= width, and
                // `spmm` asserted that x.len() >= (3 nodes - 1) ld + width: masked-off lanes
                // are not accessed, so every access is in bounds.
                let (x0, x1, x2, x3, x4, x5) = unsafe {
                    let p = xp.add(3 * col as usize * ld + j0);
                    (
                        _mm512_maskz_loadu_pd(lo, p),
                        _mm512_maskz_loadu_pd(hi, p.add(8)),
                        _mm512_maskz_loadu_pd(lo, p.add(ld)),
                        _mm512_maskz_loadu_pd(hi, p.add(ld + 8)),
                        _mm512_maskz_loadu_pd(lo, p.add(2 * ld)),
                        _mm512_maskz_loadu_pd(hi, p.add(2 * ld + 8)),
                    )
                };
                for i in 0..3 {
                    let (a0, a1, a2) = (
                        _mm512_set1_pd(v[3 * i]),
                        _mm512_set1_pd(v[3 * i + 1]),
                        _mm512_set1_pd(v[3 * i + 2]),
                    );
                    acc[2 * i] = _mm512_fmadd_pd(a0, x0, acc[2 * i]);
                    acc[2 * i + 1] = _mm512_fmadd_pd(a0, x1, acc[2 * i + 1]);
                    acc[2 * i] = _mm512_fmadd_pd(a1, x2, acc[2 * i]);
                    acc[2 * i + 1] = _mm512_fmadd_pd(a1, x3, acc[2 * i + 1]);
                    acc[2 * i] = _mm512_fmadd_pd(a2, x4, acc[2 * i]);
                    acc[2 * i + 1] = _mm512_fmadd_pd(a2, x5, acc[2 * i + 1]);
                }
            }
            for i in 0..3 {
                // SAFETY: row 3 r + i < 3 nodes, so its columns j0..j0 + w lie within
                // y.len() >= (3 nodes - 1) ld + width (asserted by `spmm`); the masks store
                // only those columns.
                unsafe {
                    let out = yp.add((3 * r + i) * ld + j0);
                    _mm512_mask_storeu_pd(out, lo, acc[2 * i]);
                    _mm512_mask_storeu_pd(out.add(8), hi, acc[2 * i + 1]);
                }
            }
            j0 += w;
        }
    }
}

/// Node row `r` of `Y = A X` for the columns `j0..width`: 8 columns per pass (3 rows x 2
/// registers of accumulators), then 4, then the portable code for the last 1-3 columns.
///
/// # Safety
/// The CPU supports AVX2 and FMA, and the slices passed the length check of [`spmm`].
#[cfg(target_arch = "x86_64")]
#[inline]
#[target_feature(enable = "avx2,fma")]
unsafe fn row_avx2(
    pattern: &BlockPattern,
    a: &[[f64; 9]],
    x: &[f64],
    y: &mut [f64],
    l: RowBlock,
    r: usize,
    mut j0: usize,
) {
    use std::arch::x86_64::*;
    let (b, ld) = (l.width, l.stride);
    let nodes = pattern.nodes();
    let xp = x.as_ptr();
    let span = pattern.row_ptr[r]..pattern.row_ptr[r + 1];
    let cols = &pattern.col[span.clone()];
    let vals = &a[span];
    while j0 + 8 <= b {
        let mut acc = [_mm256_setzero_pd(); 6];
        for (&col, v) in cols.iter().zip(vals) {
            assert!((col as usize) < nodes, "pattern column out of range");
            // SAFETY: col < nodes, so the three rows 3 col + d start at most at
            // (3 nodes - 1) ld, and j0 + 8 <= width; `spmm` asserted that
            // x.len() >= (3 nodes - 1) ld + width, so every load is in bounds.
            let (x0, x1, x2, x3, x4, x5) = unsafe {
                let p = xp.add(3 * col as usize * ld + j0);
                (
                    _mm256_loadu_pd(p),
                    _mm256_loadu_pd(p.add(4)),
                    _mm256_loadu_pd(p.add(ld)),
                    _mm256_loadu_pd(p.add(ld + 4)),
                    _mm256_loadu_pd(p.add(2 * ld)),
                    _mm256_loadu_pd(p.add(2 * ld + 4)),
                )
            };
            for i in 0..3 {
                let (a0, a1, a2) = (
                    _mm256_set1_pd(v[3 * i]),
                    _mm256_set1_pd(v[3 * i + 1]),
                    _mm256_set1_pd(v[3 * i + 2]),
                );
                acc[2 * i] = _mm256_fmadd_pd(a0, x0, acc[2 * i]);
                acc[2 * i + 1] = _mm256_fmadd_pd(a0, x1, acc[2 * i + 1]);
                acc[2 * i] = _mm256_fmadd_pd(a1, x2, acc[2 * i]);
                acc[2 * i + 1] = _mm256_fmadd_pd(a1, x3, acc[2 * i + 1]);
                acc[2 * i] = _mm256_fmadd_pd(a2, x4, acc[2 * i]);
                acc[2 * i + 1] = _mm256_fmadd_pd(a2, x5, acc[2 * i + 1]);
            }
        }
        for i in 0..3 {
            let out = &mut y[(3 * r + i) * ld + j0..(3 * r + i) * ld + j0 + 8];
            // SAFETY: `out` is a slice of exactly 8 values: both stores are in bounds.
            unsafe {
                _mm256_storeu_pd(out.as_mut_ptr(), acc[2 * i]);
                _mm256_storeu_pd(out.as_mut_ptr().add(4), acc[2 * i + 1]);
            }
        }
        j0 += 8;
    }
    while j0 + 4 <= b {
        let mut acc = [_mm256_setzero_pd(); 3];
        for (&col, v) in cols.iter().zip(vals) {
            assert!((col as usize) < nodes, "pattern column out of range");
            // SAFETY: as above, with j0 + 4 <= width.
            let (x0, x1, x2) = unsafe {
                let p = xp.add(3 * col as usize * ld + j0);
                (
                    _mm256_loadu_pd(p),
                    _mm256_loadu_pd(p.add(ld)),
                    _mm256_loadu_pd(p.add(2 * ld)),
                )
            };
            for (i, acc_i) in acc.iter_mut().enumerate() {
                *acc_i = _mm256_fmadd_pd(_mm256_set1_pd(v[3 * i]), x0, *acc_i);
                *acc_i = _mm256_fmadd_pd(_mm256_set1_pd(v[3 * i + 1]), x1, *acc_i);
                *acc_i = _mm256_fmadd_pd(_mm256_set1_pd(v[3 * i + 2]), x2, *acc_i);
            }
        }
        for (i, acc_i) in acc.iter().enumerate() {
            let out = &mut y[(3 * r + i) * ld + j0..(3 * r + i) * ld + j0 + 4];
            // SAFETY: `out` is a slice of exactly 4 values.
            unsafe { _mm256_storeu_pd(out.as_mut_ptr(), *acc_i) };
        }
        j0 += 4;
    }
    if j0 < b {
        spmm_row(cols, vals, x, y, r, j0..b, ld);
    }
}

/// One node row of `Y = A X` for the columns `js` (the portable path).
#[inline(always)]
fn spmm_row(
    cols: &[u32],
    vals: &[[f64; 9]],
    x: &[f64],
    y: &mut [f64],
    r: usize,
    js: std::ops::Range<usize>,
    ld: usize,
) {
    let mut acc = [[0.0f64; SPMM_CHUNK]; 3];
    let (j0, w) = (js.start, js.len());
    for (&col, v) in cols.iter().zip(vals) {
        let base = 3 * col as usize * ld + j0;
        for (i, acc_i) in acc.iter_mut().enumerate() {
            for d in 0..3 {
                let ad = v[3 * i + d];
                let xs = &x[base + d * ld..base + d * ld + w];
                for (aj, xj) in acc_i.iter_mut().zip(xs) {
                    *aj += ad * xj;
                }
            }
        }
    }
    for (i, acc_i) in acc.iter().enumerate() {
        let at = (3 * r + i) * ld + j0;
        y[at..at + w].copy_from_slice(&acc_i[..w]);
    }
}

/// Columns per pass: 3 x 8 accumulators stay in registers.
const SPMM_CHUNK: usize = 8;

fn spmm_kernel(pattern: &BlockPattern, a: &[[f64; 9]], x: &[f64], y: &mut [f64], l: RowBlock) {
    for r in 0..pattern.nodes() {
        let span = pattern.row_ptr[r]..pattern.row_ptr[r + 1];
        let mut j0 = 0;
        while j0 < l.width {
            let j1 = (j0 + SPMM_CHUNK).min(l.width);
            spmm_row(
                &pattern.col[span.clone()],
                &a[span.clone()],
                x,
                y,
                r,
                j0..j1,
                l.stride,
            );
            j0 = j1;
        }
    }
}

/// Sum of the diagonal.
pub fn trace(pattern: &BlockPattern, a: &[[f64; 9]]) -> f64 {
    (0..pattern.nodes())
        .map(|r| {
            let b = pattern.find(r, r as u32).expect("diagonal block");
            a[b][0] + a[b][4] + a[b][8]
        })
        .sum()
}

/// Largest absolute row sum (the 1- and infinity-norm, an upper bound on the 2-norm).
pub fn norm_inf(pattern: &BlockPattern, a: &[[f64; 9]]) -> f64 {
    let mut worst = 0.0f64;
    for r in 0..pattern.nodes() {
        let mut s = [0.0; 3];
        for blk in &a[pattern.row_ptr[r]..pattern.row_ptr[r + 1]] {
            for (i, si) in s.iter_mut().enumerate() {
                *si += blk[3 * i].abs() + blk[3 * i + 1].abs() + blk[3 * i + 2].abs();
            }
        }
        worst = worst.max(s[0]).max(s[1]).max(s[2]);
    }
    worst
}

/// The upper triangle of `K - shift M` as a DOF-level `faer` CSC matrix (what its sparse
/// Cholesky reads).
pub fn shifted_upper_csc(
    pattern: &BlockPattern,
    k: &[[f64; 9]],
    m: &[[f64; 9]],
    shift: f64,
) -> SparseColMat<usize, f64> {
    let n = pattern.nodes();
    let mut col_ptr = Vec::with_capacity(3 * n + 1);
    let mut row_idx = Vec::new();
    let mut val = Vec::new();
    col_ptr.push(0);
    for a in 0..n {
        for c in 0..3 {
            // Column 3a + c holds A[3b + d, 3a + c] = block(a, b)[c][d] for rows 3b + d <= 3a + c.
            for blk in pattern.row_ptr[a]..pattern.row_ptr[a + 1] {
                let b = pattern.col[blk] as usize;
                if b > a {
                    break;
                }
                let dmax = if b == a { c + 1 } else { 3 };
                for d in 0..dmax {
                    row_idx.push(3 * b + d);
                    val.push(k[blk][3 * c + d] - shift * m[blk][3 * c + d]);
                }
            }
            col_ptr.push(row_idx.len());
        }
    }
    let symbolic = SymbolicSparseColMat::new_checked(3 * n, 3 * n, col_ptr, None, row_idx);
    SparseColMat::new(symbolic, val)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::{ElementKind, FemModel};
    use crate::shape::VoxelGrid;

    /// The block product (the kernel this CPU picks, and the portable one) equals one `spmv` per
    /// column, for dense and strided layouts and widths that do and do not fill the 16-, 8- and
    /// 4-column passes.
    #[test]
    fn spmm_matches_spmv_per_column() {
        let grid = VoxelGrid::from_fn([5, 3, 2], 1.0, |x, y, _| x + y < 6.0).unwrap();
        let model = FemModel::assemble(&grid, ElementKind::Hex8, 0.3).unwrap();
        let n = model.dofs();
        for (width, stride) in [
            (1, 1),
            (8, 8),
            (11, 11),
            (5, 13),
            (16, 20),
            (29, 29),
            (32, 40),
        ] {
            let x: Vec<f64> = (0..n * stride)
                .map(|i| ((i * 31 % 17) as f64) - 8.0)
                .collect();
            let mut y = vec![0.0; n * stride];
            spmm(
                &model.pattern,
                &model.k,
                &x,
                &mut y,
                RowBlock { width, stride },
            );
            // The portable kernel, whatever the CPU picked above.
            let mut y_portable = vec![0.0; n * stride];
            spmm_kernel(
                &model.pattern,
                &model.k,
                &x,
                &mut y_portable,
                RowBlock { width, stride },
            );
            for j in 0..width {
                let col: Vec<f64> = (0..n).map(|i| x[i * stride + j]).collect();
                let mut want = vec![0.0; n];
                spmv(&model.pattern, &model.k, &col, &mut want);
                for i in 0..n {
                    for got in [y[i * stride + j], y_portable[i * stride + j]] {
                        assert!((got - want[i]).abs() <= 1e-12 * want[i].abs().max(1.0));
                    }
                }
            }
        }
    }
}
