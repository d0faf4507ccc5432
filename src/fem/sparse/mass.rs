//! The mass product `Y = M X` on the mass's own structure: every block of a finite-element mass
//! matrix is a scalar times the 3x3 identity (`M_ab I3`, the consistent mass of a displacement
//! element: `int N_a N_b dV` couples each displacement component only with itself), so a block
//! needs three multiply-adds per vector instead of nine.
//!
//! Where it sits: beside [`super::spmm`], for the eigensolvers' and the instant answer's `M X`
//! ([`crate::eigen::Operators::spmm`], when [`is_scalar_blocks`] holds for its `M`: every model
//! this crate assembles, every element kind, partial voxels included). Each node row
//! accumulates, per column chunk,
//! `m_ab` times the three contiguous-by-column rows of node `b`: the compiler vectorises the
//! fixed-width inner loops (compiled once more for AVX2/FMA and picked at run time).

use super::{BlockPattern, RowBlock};

/// Columns per pass: 3 x 16 accumulators (12 AVX2 registers).
const MASS_CHUNK: usize = 16;

/// Whether every block of `a` is a scalar times the identity, exactly (bit for bit: the
/// assembly adds the same values to the three diagonal entries in the same order).
pub fn is_scalar_blocks(a: &[[f64; 9]]) -> bool {
    a.iter()
        .all(|b| b[4] == b[0] && b[8] == b[0] && [1, 2, 3, 5, 6, 7].iter().all(|&i| b[i] == 0.0))
}

/// `Y = A X` for a block of vectors (see [`RowBlock`]) where every block of `a` is `a_b I3`
/// ([`is_scalar_blocks`]; only `a[b][0]` is read). Same contract as [`super::spmm`]: `x` and
/// `y` start at the block's first column and may be wider.
pub fn spmm_scalar(pattern: &BlockPattern, a: &[[f64; 9]], x: &[f64], y: &mut [f64], l: RowBlock) {
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
    scalar_kernel(pattern, a, x, y, l);
}

/// [`scalar_kernel`] compiled for AVX2/FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn scalar_avx2(
    pattern: &BlockPattern,
    a: &[[f64; 9]],
    x: &[f64],
    y: &mut [f64],
    l: RowBlock,
) {
    scalar_kernel(pattern, a, x, y, l);
}

/// Every node row, in passes of [`MASS_CHUNK`] columns, then 8, 4, 2 and 1.
#[inline(always)]
fn scalar_kernel(pattern: &BlockPattern, a: &[[f64; 9]], x: &[f64], y: &mut [f64], l: RowBlock) {
    for r in 0..pattern.nodes() {
        let span = pattern.row_ptr[r]..pattern.row_ptr[r + 1];
        let (cols, vals) = (&pattern.col[span.clone()], &a[span]);
        let mut j0 = 0;
        while l.width - j0 >= MASS_CHUNK {
            scalar_row::<MASS_CHUNK>(cols, vals, x, y, r, j0, l.stride);
            j0 += MASS_CHUNK;
        }
        for w in [8, 4, 2, 1] {
            if l.width - j0 >= w {
                match w {
                    8 => scalar_row::<8>(cols, vals, x, y, r, j0, l.stride),
                    4 => scalar_row::<4>(cols, vals, x, y, r, j0, l.stride),
                    2 => scalar_row::<2>(cols, vals, x, y, r, j0, l.stride),
                    _ => scalar_row::<1>(cols, vals, x, y, r, j0, l.stride),
                }
                j0 += w;
            }
        }
    }
}

/// Node row `r` for exactly `W` columns from `j0` (fixed trip counts, so the inner loops
/// unroll and vectorise).
#[inline(always)]
fn scalar_row<const W: usize>(
    cols: &[u32],
    vals: &[[f64; 9]],
    x: &[f64],
    y: &mut [f64],
    r: usize,
    j0: usize,
    ld: usize,
) {
    let mut acc = [[0.0f64; W]; 3];
    for (&col, v) in cols.iter().zip(vals) {
        let s = v[0];
        let base = 3 * col as usize * ld + j0;
        for (i, acc_i) in acc.iter_mut().enumerate() {
            let xs: &[f64; W] = x[base + i * ld..base + i * ld + W]
                .try_into()
                .expect("W columns");
            for (a, &xv) in acc_i.iter_mut().zip(xs) {
                *a += s * xv;
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
    fn the_scalar_product_matches_the_block_product() {
        // The partial-voxel bowl's own mass (scalar blocks) against the general block kernel,
        // for widths that exercise every pass (16, 8, 4, 2, 1) and a strided layout. Both sum
        // the same products (the general kernel adds exact zeros besides) in the same order
        // per entry: equal to 1e-14 relative (FMA contraction may differ between the two).
        let grid = Primitive::Bowl {
            diameter: 10.0,
            wall: 2.0,
        }
        .rasterize(1.0, 1.0)
        .unwrap();
        let model = FemModel::assemble(&grid, ElementKind::Hex27Blocks, 0.24).unwrap();
        assert!(is_scalar_blocks(&model.m));
        let n = model.dofs();
        let mut rng = SplitMix64::new(5);
        for (width, stride) in [(31, 31), (5, 9), (1, 1)] {
            let x: Vec<f64> = (0..n * stride).map(|_| rng.unit() - 0.5).collect();
            let (mut want, mut got) = (vec![0.0; n * stride], vec![0.0; n * stride]);
            let l = RowBlock { width, stride };
            spmm(&model.pattern, &model.m, &x, &mut want, l);
            spmm_scalar(&model.pattern, &model.m, &x, &mut got, l);
            let scale = want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for (a, b) in want.iter().zip(&got) {
                assert!(
                    (a - b).abs() <= 1e-14 * scale,
                    "{width}/{stride}: {a} vs {b}"
                );
            }
        }
    }

    #[test]
    fn every_element_kinds_mass_is_scalar_blocks_and_stiffness_is_not() {
        // What lets the eigensolvers take the scalar path: the mass of every element kind,
        // full and partial voxels; the stiffness couples components, so the test can fail.
        let grid = Primitive::Sphere { diameter: 6.0 }
            .rasterize(1.0, 1.0)
            .unwrap();
        assert!(!grid.is_binary());
        for kind in ElementKind::ALL {
            let model = FemModel::assemble(&grid, kind, 0.3).unwrap();
            assert!(is_scalar_blocks(&model.m), "{kind:?}");
            assert!(!is_scalar_blocks(&model.k), "{kind:?}");
        }
    }
}
