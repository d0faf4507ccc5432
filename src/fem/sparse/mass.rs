//! The mass matrix's storage and its product `Y = M X`: every block of a finite-element mass
//! matrix is a scalar times the 3x3 identity (`M_ab I3`, the consistent mass of a displacement
//! element: `int N_a N_b dV` couples each displacement component only with itself), so `M`
//! keeps one number per node pair ([`MassBlocks`], 8 bytes where a 3x3 block takes 72) and a
//! block of the product needs three multiply-adds per vector instead of nine.
//!
//! Where it sits: [`crate::fem::FemModel::m`] and the multigrid's coarse masses are
//! [`MassBlocks`] on the stiffness's [`BlockPattern`]; the assembly adds `m_ab` into them
//! ([`super::scatter`]); the eigensolvers' and the instant answer's `M X`
//! ([`crate::eigen::Operators::spmm`]) is [`spmm_mass`]. Each node row accumulates, per column
//! chunk, `m_ab` times the three contiguous-by-column rows of node `b`: the compiler vectorises
//! the fixed-width inner loops (compiled once more for AVX2/FMA and picked at run time; there
//! the sums are fused multiply-adds, which took the default bowl's solve to 0.97x).

use super::{BlockPattern, RowBlock};
use crate::fma::mul_add;

/// Columns per pass: 3 x 16 accumulators (12 AVX2 registers).
const MASS_CHUNK: usize = 16;

/// Values of a mass matrix on a [`BlockPattern`]: entry `b` is the scalar `m_ab` of the block
/// `m_ab I3` at pattern position `b`.
pub type MassBlocks = Vec<f64>;

/// The mass written out as 3x3 blocks `m_ab I3` (for the general block kernels, a matrix file,
/// a comparison).
pub fn mass_as_blocks(m: &[f64]) -> Vec<[f64; 9]> {
    m.iter()
        .map(|&s| [s, 0.0, 0.0, 0.0, s, 0.0, 0.0, 0.0, s])
        .collect()
}

/// Largest absolute row sum of the mass (each of a block row's three DOF rows sums the same
/// `|m_ab|`): the 1- and infinity-norm.
pub fn mass_norm_inf(pattern: &BlockPattern, m: &[f64]) -> f64 {
    (0..pattern.nodes())
        .map(|r| {
            m[pattern.row_ptr[r]..pattern.row_ptr[r + 1]]
                .iter()
                .map(|v| v.abs())
                .sum::<f64>()
        })
        .fold(0.0, f64::max)
}

/// Sum of the mass's diagonal (three DOFs per diagonal block).
pub fn mass_trace(pattern: &BlockPattern, m: &[f64]) -> f64 {
    (0..pattern.nodes())
        .map(|r| 3.0 * m[pattern.find(r, r as u32).expect("diagonal block")])
        .sum()
}

/// `Y = M X` for a block of vectors (see [`RowBlock`]), `M` given by its scalars `a`
/// ([`MassBlocks`]). Same contract as [`fn@super::spmm`]: `x` and `y` start at the block's first
/// column and may be wider.
pub fn spmm_mass(pattern: &BlockPattern, a: &[f64], x: &[f64], y: &mut [f64], l: RowBlock) {
    spmm_component_diagonal(pattern, a, x, y, l);
}

/// `Y = M X` for a mass whose blocks are diagonal but differ by component (`diag(a[b])`): a
/// symmetry class's reduced mass ([`crate::eigen::symmetric`]). Same contract as
/// [`spmm_mass`].
pub fn spmm_mass_diagonal(
    pattern: &BlockPattern,
    a: &[[f64; 3]],
    x: &[f64],
    y: &mut [f64],
    l: RowBlock,
) {
    spmm_component_diagonal(pattern, a, x, y, l);
}

/// A mass block's factor for component `i`: one scalar for every component ([`MassBlocks`]),
/// or one each.
pub trait ComponentScale: Copy {
    /// The factor of component `i` (0, 1 or 2).
    fn at(self, i: usize) -> f64;
}

impl ComponentScale for f64 {
    #[inline(always)]
    fn at(self, _: usize) -> f64 {
        self
    }
}

impl ComponentScale for [f64; 3] {
    #[inline(always)]
    fn at(self, i: usize) -> f64 {
        self[i]
    }
}

/// The product for either kind of diagonal block, dispatched to the AVX2/FMA build.
fn spmm_component_diagonal<T: ComponentScale>(
    pattern: &BlockPattern,
    a: &[T],
    x: &[f64],
    y: &mut [f64],
    l: RowBlock,
) {
    let need = (3 * pattern.nodes()).saturating_sub(1) * l.stride + l.width;
    assert!(l.width <= l.stride && x.len() >= need && y.len() >= need);
    assert_eq!(a.len(), pattern.col.len(), "one block per pattern entry");
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU supports AVX2 and FMA (checked just above), the only requirement of
        // the `target_feature` function; it is the same safe code compiled for them.
        unsafe { scalar_avx2(pattern, a, x, y, l) };
        return;
    }
    scalar_kernel::<false, T>(pattern, a, x, y, l);
}

/// [`scalar_kernel`] compiled for AVX2/FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn scalar_avx2<T: ComponentScale>(
    pattern: &BlockPattern,
    a: &[T],
    x: &[f64],
    y: &mut [f64],
    l: RowBlock,
) {
    scalar_kernel::<true, T>(pattern, a, x, y, l);
}

/// Every node row, in passes of [`MASS_CHUNK`] columns, then 8, 4, 2 and 1.
#[inline(always)]
fn scalar_kernel<const FMA: bool, T: ComponentScale>(
    pattern: &BlockPattern,
    a: &[T],
    x: &[f64],
    y: &mut [f64],
    l: RowBlock,
) {
    for r in 0..pattern.nodes() {
        let span = pattern.row_ptr[r]..pattern.row_ptr[r + 1];
        let (cols, vals) = (&pattern.col[span.clone()], &a[span]);
        let mut j0 = 0;
        while l.width - j0 >= MASS_CHUNK {
            scalar_row::<MASS_CHUNK, FMA, T>(cols, vals, x, y, r, j0, l.stride);
            j0 += MASS_CHUNK;
        }
        for w in [8, 4, 2, 1] {
            if l.width - j0 >= w {
                match w {
                    8 => scalar_row::<8, FMA, T>(cols, vals, x, y, r, j0, l.stride),
                    4 => scalar_row::<4, FMA, T>(cols, vals, x, y, r, j0, l.stride),
                    2 => scalar_row::<2, FMA, T>(cols, vals, x, y, r, j0, l.stride),
                    _ => scalar_row::<1, FMA, T>(cols, vals, x, y, r, j0, l.stride),
                }
                j0 += w;
            }
        }
    }
}

/// Node row `r` for exactly `W` columns from `j0` (fixed trip counts, so the inner loops
/// unroll and vectorise).
#[inline(always)]
fn scalar_row<const W: usize, const FMA: bool, T: ComponentScale>(
    cols: &[u32],
    vals: &[T],
    x: &[f64],
    y: &mut [f64],
    r: usize,
    j0: usize,
    ld: usize,
) {
    let mut acc = [[0.0f64; W]; 3];
    for (&col, v) in cols.iter().zip(vals) {
        // One bounds check for the node's three rows; the rows within it are checked against
        // its known length, which the compiler proves once.
        let base = 3 * col as usize * ld + j0;
        let node = &x[base..base + 2 * ld + W];
        for (i, acc_i) in acc.iter_mut().enumerate() {
            let s = v.at(i);
            let xs = &node[i * ld..i * ld + W];
            for (a, &xv) in acc_i.iter_mut().zip(xs) {
                *a = mul_add::<FMA, _>(s, xv, *a);
            }
        }
    }
    for (i, acc_i) in acc.iter().enumerate() {
        let at = (3 * r + i) * ld + j0;
        y[at..at + W].copy_from_slice(acc_i);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::sparse::spmm;
    use crate::fem::{ElementKind, FemModel};
    use crate::rng::SplitMix64;
    use crate::shape::primitives::Primitive;

    #[test]
    fn a_diagonal_mass_scales_each_component_by_its_own_factor() {
        // Against the 3x3 block product of `diag(a, 2a, 3a)`, which shares no code with it.
        let grid = Primitive::Bowl {
            diameter: 8.0,
            wall: 2.0,
        }
        .rasterize(1.0, 1.0)
        .unwrap();
        let model = FemModel::assemble(&grid, ElementKind::Hex8, 0.3).unwrap();
        let diag: Vec<[f64; 3]> = model.m.iter().map(|&a| [a, 2.0 * a, 3.0 * a]).collect();
        let blocks: Vec<[f64; 9]> = diag
            .iter()
            .map(|d| [d[0], 0.0, 0.0, 0.0, d[1], 0.0, 0.0, 0.0, d[2]])
            .collect();
        let n = model.dofs();
        let mut rng = SplitMix64::new(5);
        for w in [1, 3, 8, 31] {
            let x: Vec<f64> = (0..n * w).map(|_| rng.unit() - 0.5).collect();
            let (mut y, mut want) = (vec![0.0; n * w], vec![0.0; n * w]);
            spmm_mass_diagonal(&model.pattern, &diag, &x, &mut y, RowBlock::dense(w));
            spmm(&model.pattern, &blocks, &x, &mut want, RowBlock::dense(w));
            for (a, b) in y.iter().zip(&want) {
                // Both sum the same products, in different orders: rounding only.
                assert!((a - b).abs() <= 1e-14 * (1.0 + b.abs()), "{a} against {b}");
            }
        }
    }

    #[test]
    fn the_mass_product_matches_the_block_product() {
        // The partial-voxel bowl's mass against the general 3x3 block kernel on the same mass
        // written out as `m_ab I3` blocks, for widths that exercise every pass (16, 8, 4, 2,
        // 1) and a strided layout. Both sum the same products (the general kernel adds exact
        // zeros besides) in the same order per entry: equal to 1e-14 relative (FMA
        // contraction may differ between the two).
        let grid = Primitive::Bowl {
            diameter: 10.0,
            wall: 2.0,
        }
        .rasterize(1.0, 1.0)
        .unwrap();
        let model = FemModel::assemble(&grid, ElementKind::Hex27Blocks, 0.24).unwrap();
        let blocks = mass_as_blocks(&model.m);
        let n = model.dofs();
        let mut rng = SplitMix64::new(5);
        for (width, stride) in [(31, 31), (5, 9), (1, 1)] {
            let x: Vec<f64> = (0..n * stride).map(|_| rng.unit() - 0.5).collect();
            let (mut want, mut got) = (vec![0.0; n * stride], vec![0.0; n * stride]);
            let l = RowBlock { width, stride };
            spmm(&model.pattern, &blocks, &x, &mut want, l);
            spmm_mass(&model.pattern, &model.m, &x, &mut got, l);
            // And the portable build (multiplies and adds), whatever this CPU picked above.
            let mut plain = vec![0.0; n * stride];
            scalar_kernel::<false, f64>(&model.pattern, &model.m, &x, &mut plain, l);
            let scale = want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for ((a, b), c) in want.iter().zip(&got).zip(&plain) {
                assert!(
                    (a - b).abs() <= 1e-14 * scale && (a - c).abs() <= 1e-14 * scale,
                    "{width}/{stride}: {a} vs {b} (portable {c})"
                );
            }
        }
    }

    #[test]
    fn the_mass_norm_and_trace_are_those_of_the_whole_matrix() {
        // Against the 3x3-block versions on the same mass written out as blocks (exact: the
        // same sums of the same numbers).
        let grid = Primitive::Sphere { diameter: 6.0 }
            .rasterize(1.0, 1.0)
            .unwrap();
        let model = FemModel::assemble(&grid, ElementKind::Hex8Incompatible, 0.3).unwrap();
        let blocks = mass_as_blocks(&model.m);
        let p = &model.pattern;
        assert_eq!(
            mass_norm_inf(p, &model.m),
            crate::fem::sparse::norm_inf(p, &blocks)
        );
        let trace = crate::fem::sparse::trace(p, &blocks);
        assert!((mass_trace(p, &model.m) - trace).abs() <= 1e-15 * trace);
        // Summed over every pair, the scalars are the integral of (sum N_a)(sum N_b) = 1: the
        // filled volume in voxel units (density 1), which partial voxels make the sphere's to
        // within the sub-cells' resolution.
        let total: f64 = model.m.iter().sum();
        let volume = std::f64::consts::PI / 6.0 * 216.0;
        assert!(
            (total - volume).abs() < 0.02 * volume,
            "{total} vs {volume}"
        );
    }
}
