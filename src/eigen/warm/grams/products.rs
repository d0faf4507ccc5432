//! The dense kernels of the instant answer's Grams (`warm/grams.rs`): products of `K` and `M`
//! with the carried block on a few rows, local Gram sums, and whole Gram products.
//!
//! Where it sits: under [`super::grams`], which chooses what to multiply; here is how. The
//! carried block `X` is given by rows ([`BlockRows`]: on every node, or only on the nodes
//! near an edit), as the transfer writes it.

use crate::eigen::Which;
use crate::fem::sparse::BlockPattern;
use crate::fma::mul_add;
use faer::{Mat, MatRef, Par};

/// The carried block `X` by rows (`w` wide, its first `fields` columns the rigid fields): on
/// every node of the new mesh, or on some of them only ([`super::rows_read`]), node `v`'s rows at
/// place `slot[v]`.
#[derive(Clone, Copy)]
pub(in crate::eigen::warm) struct BlockRows<'a> {
    /// The rows, three DOF rows of `w` values per node present.
    pub rows: &'a [f64],
    /// Columns.
    pub w: usize,
    /// Each node's place in `rows` (`u32::MAX` where absent); `None` where every node is
    /// present, in order.
    pub slot: Option<&'a [u32]>,
}

impl<'a> BlockRows<'a> {
    /// A block on every node.
    pub(in crate::eigen::warm) fn whole(rows: &'a [f64], w: usize) -> Self {
        BlockRows {
            rows,
            w,
            slot: None,
        }
    }

    /// Node `v`'s three DOF rows, side by side (a node that is not present panics).
    fn node(&self, v: usize) -> &'a [f64] {
        let at = self.slot.map_or(v, |s| s[v] as usize);
        &self.rows[3 * at * self.w..3 * (at + 1) * self.w]
    }
}

/// `X^T Y` (`w x no`) for `X` (`n x w`) and `Y` (`n x no`), both by rows: one pass down the
/// rows, each adding its outer product into a `w x no` accumulator that stays in L1. faer's
/// general product on these shapes (a thin `Y`, `X` read transposed) ran at about a quarter of
/// the speed: 4.5 ms per product on the ceramic cup (29.5k rows, 74 by 6 columns), most of the
/// carried answer's Grams (stop 66).
pub(super) fn cross_rows(x_rows: &[f64], w: usize, y_rows: &[f64], no: usize) -> Mat<f64> {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU supports AVX2 and FMA (checked just above), the only requirement of
        // the `target_feature` function.
        return unsafe { cross_rows_avx2(x_rows, w, y_rows, no) };
    }
    cross_rows_with::<false>(x_rows, w, y_rows, no)
}

/// [`cross_rows`] compiled for AVX2 + FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn cross_rows_avx2(x_rows: &[f64], w: usize, y_rows: &[f64], no: usize) -> Mat<f64> {
    cross_rows_with::<true>(x_rows, w, y_rows, no)
}

#[inline(always)]
fn cross_rows_with<const FMA: bool>(
    x_rows: &[f64],
    w: usize,
    y_rows: &[f64],
    no: usize,
) -> Mat<f64> {
    let mut acc = vec![0.0; w * no];
    if w > 0 && no > 0 {
        for (x, y) in x_rows.chunks_exact(w).zip(y_rows.chunks_exact(no)) {
            for (a, &yc) in acc.chunks_exact_mut(w).zip(y) {
                for (a, &xv) in a.iter_mut().zip(x) {
                    *a = mul_add::<FMA, _>(yc, xv, *a);
                }
            }
        }
    }
    Mat::from_fn(w, no, |i, c| acc[c * w + i])
}

/// A whole model's `K` and `M` blocks (the mass as `M_ab I3` scalars), for products on a few
/// rows.
#[derive(Clone, Copy)]
pub(super) struct Blocks<'a> {
    pattern: &'a BlockPattern,
    k: &'a [[f64; 9]],
    m: &'a [f64],
}

impl<'a> Blocks<'a> {
    pub(super) fn of(pattern: &'a BlockPattern, k: &'a [[f64; 9]], m: &'a [f64]) -> Self {
        Blocks { pattern, k, m }
    }

    /// `A X` on the rows of `nodes` (three DOF rows per node, in that order), `X` given by
    /// rows on (at least) their neighbours.
    pub(super) fn product(&self, which: Which, nodes: &[usize], x: BlockRows) -> Mat<f64> {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: the CPU supports AVX2 and FMA (checked just above), the only requirement
            // of the `target_feature` function.
            return unsafe { self.product_avx2(which, nodes, x) };
        }
        self.product_with::<false>(which, nodes, x)
    }

    /// [`Self::product`] compiled for AVX2 + FMA (the portable build's two-wide multiplies
    /// and adds took about three times as long: the largest part of this answer's Grams).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn product_avx2(&self, which: Which, nodes: &[usize], x: BlockRows) -> Mat<f64> {
        self.product_with::<true>(which, nodes, x)
    }

    #[inline(always)]
    fn product_with<const FMA: bool>(
        &self,
        which: Which,
        nodes: &[usize],
        x: BlockRows,
    ) -> Mat<f64> {
        let (pattern, w) = (self.pattern, x.w);
        let mut out = Mat::<f64>::zeros(3 * nodes.len(), w);
        let mut acc = vec![0.0; 3 * w];
        for (i, &node) in nodes.iter().enumerate() {
            acc.fill(0.0);
            for b in pattern.row_ptr[node]..pattern.row_ptr[node + 1] {
                let s = x.node(pattern.col[b] as usize);
                match which {
                    Which::K => add_block_product::<FMA>(&self.k[b], s, &mut acc),
                    Which::M => {
                        let m = self.m[b];
                        for (a, &v) in acc.iter_mut().zip(s) {
                            *a = mul_add::<FMA, _>(m, v, *a);
                        }
                    }
                }
            }
            for (r, a) in acc.chunks_exact(w).enumerate() {
                for (j, &v) in a.iter().enumerate() {
                    out[(3 * i + r, j)] = v;
                }
            }
        }
        out
    }
}

/// `out += A s` for one node block `A` (3x3, row-major) and the by-rows values of one node
/// `s` (three DOF rows of `w` columns side by side; `out` likewise).
#[inline(always)]
fn add_block_product<const FMA: bool>(block: &[f64; 9], s: &[f64], out: &mut [f64]) {
    let w = s.len() / 3;
    if w == 0 {
        return;
    }
    let (s0, rest) = s.split_at(w);
    let (s1, s2) = rest.split_at(w);
    for (r, o) in out.chunks_exact_mut(w).enumerate() {
        let (a0, a1, a2) = (block[3 * r], block[3 * r + 1], block[3 * r + 2]);
        for j in 0..w {
            let v = mul_add::<FMA, _>(a0, s0[j], o[j]);
            let v = mul_add::<FMA, _>(a1, s1[j], v);
            o[j] = mul_add::<FMA, _>(a2, s2[j], v);
        }
    }
}

/// `sum_i x_i^T y_i` over the DOF rows of `nodes`, whose rows of `y` ([`Blocks::product`]'s
/// layout) are at the node places `at`.
pub(super) fn local_gram(x: BlockRows, nodes: &[usize], y: &Mat<f64>, at: &[usize]) -> Mat<f64> {
    let w = x.w;
    let xs = Mat::<f64>::from_fn(3 * nodes.len(), w, |i, j| {
        x.node(nodes[i / 3])[(i % 3) * w + j]
    });
    let ys = Mat::<f64>::from_fn(3 * nodes.len(), y.ncols(), |i, j| {
        y[(3 * at[i / 3] + i % 3, j)]
    });
    xs.transpose() * ys
}

/// The symmetric Gram matrix `X^T Y` (`Y = A X` for a symmetric `A`) from its lower triangle
/// alone: half the work of the whole product.
pub(in crate::eigen::warm) fn gram(x: MatRef<'_, f64>, y: MatRef<'_, f64>) -> Mat<f64> {
    use faer::linalg::matmul::triangular::{matmul, BlockStructure};
    let w = x.ncols();
    let mut g = Mat::<f64>::zeros(w, w);
    matmul(
        g.as_mut(),
        BlockStructure::TriangularLower,
        faer::Accum::Replace,
        x.transpose(),
        BlockStructure::Rectangular,
        y,
        BlockStructure::Rectangular,
        1.0,
        Par::Seq,
    );
    for j in 0..w {
        for i in 0..j {
            g[(i, j)] = g[(j, i)];
        }
    }
    g
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cross_rows_is_the_transposed_product() {
        // Against the definition, summed in f64 in another order: rounding of a 300-term sum
        // of values under 1 (1e-13 bounds it), for widths that are and are not whole vectors
        // and both builds.
        let n = 300;
        for (w, no) in [(74, 6), (5, 1), (8, 3)] {
            let x: Vec<f64> = (0..n * w)
                .map(|k| ((k * 37 % 101) as f64 / 101.0) - 0.5)
                .collect();
            let y: Vec<f64> = (0..n * no)
                .map(|k| ((k * 53 % 97) as f64 / 97.0) - 0.5)
                .collect();
            for got in [
                cross_rows(&x, w, &y, no),
                cross_rows_with::<false>(&x, w, &y, no),
            ] {
                for i in 0..w {
                    for c in 0..no {
                        let want: f64 = (0..n).map(|r| x[r * w + i] * y[r * no + c]).sum();
                        assert!((got[(i, c)] - want).abs() < 1e-13, "{w}x{no} ({i}, {c})");
                    }
                }
            }
        }
    }
}
