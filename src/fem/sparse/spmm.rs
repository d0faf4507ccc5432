//! Block sparse-matrix products `Y = A X` (a block of vectors at once), the inner loop of
//! LOBPCG and the multigrid V-cycle.
//!
//! Where it sits: [`super`] holds the node-blocked matrices; these kernels multiply them with a
//! [`RowBlock`] of vectors. One pass over the matrix serves every vector, so the matrix is read
//! once per block instead of once per vector. Kernels are picked at run time: AVX-512 (16 f64 or
//! 32 f32 columns per pass, masked tail), AVX2/FMA (f64, 8 columns per pass), else portable code.
//! f64 serves the eigensolvers' own products; f32 the multigrid preconditioner, whose result
//! only has to be a good approximation and which is bound by memory traffic.

use super::{BlockPattern, RowBlock};
use std::ops::{AddAssign, Mul};

/// A block kernel `Y = A X` whose caller has checked the slice lengths and the CPU features
/// the kernel was compiled for.
#[doc(hidden)]
pub type Kernel<T> = unsafe fn(&BlockPattern, &[[T; 9]], &[T], &mut [T], RowBlock);

/// A precision the block kernels run in (`f64` or `f32`), with its SIMD kernels.
pub trait Scalar: Copy + Default + Mul<Output = Self> + AddAssign + Send + Sync + 'static {
    /// Rounds an `f64` to this precision.
    fn from_f64(v: f64) -> Self;
    /// The kernel for CPUs with AVX-512F.
    #[cfg(target_arch = "x86_64")]
    #[doc(hidden)]
    const AVX512: Kernel<Self>;
    /// The kernel for CPUs with AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[doc(hidden)]
    const AVX2: Kernel<Self>;
}

impl Scalar for f64 {
    fn from_f64(v: f64) -> Self {
        v
    }
    #[cfg(target_arch = "x86_64")]
    const AVX512: Kernel<f64> = spmm_avx512;
    #[cfg(target_arch = "x86_64")]
    const AVX2: Kernel<f64> = spmm_avx2;
}

impl Scalar for f32 {
    fn from_f64(v: f64) -> Self {
        v as f32
    }
    #[cfg(target_arch = "x86_64")]
    const AVX512: Kernel<f32> = spmm_avx512_f32;
    // No hand-written f32 AVX2 kernel: the portable one, compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    const AVX2: Kernel<f32> = spmm_portable_avx2::<f32>;
}

/// `Y = A X` for a block of vectors (see [`RowBlock`]); `x` and `y` start at the block's first
/// column and may be wider (only `layout.width` columns of each row are read and written).
pub fn spmm<T: Scalar>(
    pattern: &BlockPattern,
    a: &[[T; 9]],
    x: &[T],
    y: &mut [T],
    layout: RowBlock,
) {
    let need = (3 * pattern.nodes()).saturating_sub(1) * layout.stride + layout.width;
    assert!(layout.width <= layout.stride && x.len() >= need && y.len() >= need);
    assert_eq!(a.len(), pattern.col.len(), "one block per pattern entry");
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx512f") {
        // SAFETY: the CPU supports AVX-512F (checked just above; it implies AVX2 and FMA), the
        // only requirement of the `target_feature` kernel; the lengths were asserted above.
        unsafe { T::AVX512(pattern, a, x, y, layout) };
        return;
    }
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU supports AVX2 and FMA (checked just above); lengths as above.
        unsafe { T::AVX2(pattern, a, x, y, layout) };
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

/// Generates an AVX-512 kernel: `2 x LANES` columns per pass (3 rows x 2 registers of
/// accumulators); the last pass of a row masks the columns past the width.
macro_rules! avx512_kernel {
    ($(#[$doc:meta])* $name:ident, $t:ty, $lanes:expr, $mask:ty,
     $zero:ident, $load:ident, $set1:ident, $fma:ident, $store:ident) => {
        $(#[$doc])*
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx512f,avx2,fma")]
        unsafe fn $name(pattern: &BlockPattern, a: &[[$t; 9]], x: &[$t], y: &mut [$t], l: RowBlock) {
            use std::arch::x86_64::*;
            const LANES: usize = $lanes;
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
                    let w = (b - j0).min(2 * LANES);
                    let lo = ((1u64 << w.min(LANES)) - 1) as $mask;
                    let hi = ((1u64 << w.saturating_sub(LANES)) - 1) as $mask;
                    let mut acc = [$zero(); 6];
                    for (&col, v) in cols.iter().zip(vals) {
                        assert!((col as usize) < nodes, "pattern column out of range");
                        // SAFETY: col < nodes, so the three rows 3 col + d start at most at
                        // (3 nodes - 1) ld; the masks load only columns j0..j0 + w <= width,
                        // and `spmm` asserted that x.len() >= (3 nodes - 1) ld + width:
                        // masked-off lanes are not accessed, so every access is in bounds.
                        let xs = unsafe {
                            let p = xp.add(3 * col as usize * ld + j0);
                            [
                                $load(lo, p),
                                $load(hi, p.add(LANES)),
                                $load(lo, p.add(ld)),
                                $load(hi, p.add(ld + LANES)),
                                $load(lo, p.add(2 * ld)),
                                $load(hi, p.add(2 * ld + LANES)),
                            ]
                        };
                        for i in 0..3 {
                            for d in 0..3 {
                                let ad = $set1(v[3 * i + d]);
                                acc[2 * i] = $fma(ad, xs[2 * d], acc[2 * i]);
                                acc[2 * i + 1] = $fma(ad, xs[2 * d + 1], acc[2 * i + 1]);
                            }
                        }
                    }
                    for i in 0..3 {
                        // SAFETY: row 3 r + i < 3 nodes, so its columns j0..j0 + w lie within
                        // y.len() >= (3 nodes - 1) ld + width (asserted by `spmm`); the masks
                        // store only those columns.
                        unsafe {
                            let out = yp.add((3 * r + i) * ld + j0);
                            $store(out, lo, acc[2 * i]);
                            $store(out.add(LANES), hi, acc[2 * i + 1]);
                        }
                    }
                    j0 += w;
                }
            }
        }
    };
}

avx512_kernel!(
    /// The f64 AVX-512 kernel: 16 columns per pass.
    spmm_avx512, f64, 8, u8,
    _mm512_setzero_pd, _mm512_maskz_loadu_pd, _mm512_set1_pd, _mm512_fmadd_pd, _mm512_mask_storeu_pd
);

avx512_kernel!(
    /// The f32 AVX-512 kernel: 32 columns per pass.
    spmm_avx512_f32, f32, 16, u16,
    _mm512_setzero_ps, _mm512_maskz_loadu_ps, _mm512_set1_ps, _mm512_fmadd_ps, _mm512_mask_storeu_ps
);

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

/// The portable kernel compiled for AVX2/FMA (the compiler vectorises its inner loops).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn spmm_portable_avx2<T: Scalar>(
    pattern: &BlockPattern,
    a: &[[T; 9]],
    x: &[T],
    y: &mut [T],
    l: RowBlock,
) {
    spmm_kernel(pattern, a, x, y, l);
}

/// One node row of `Y = A X` for the columns `js` (the portable path): passes of 8 columns,
/// then 4, 2 and 1 for the rest, each with a fixed width ([`spmm_row_full`]).
#[inline(always)]
fn spmm_row<T: Scalar>(
    cols: &[u32],
    vals: &[[T; 9]],
    x: &[T],
    y: &mut [T],
    r: usize,
    js: std::ops::Range<usize>,
    ld: usize,
) {
    let mut j0 = js.start;
    while js.end - j0 >= SPMM_CHUNK {
        spmm_row_full::<T, SPMM_CHUNK>(cols, vals, x, y, r, j0, ld);
        j0 += SPMM_CHUNK;
    }
    if js.end - j0 >= 4 {
        spmm_row_full::<T, 4>(cols, vals, x, y, r, j0, ld);
        j0 += 4;
    }
    if js.end - j0 >= 2 {
        spmm_row_full::<T, 2>(cols, vals, x, y, r, j0, ld);
        j0 += 2;
    }
    if js.end > j0 {
        spmm_row_full::<T, 1>(cols, vals, x, y, r, j0, ld);
    }
}

/// One node row for exactly `W` columns from `j0`. The fixed trip counts let the compiler
/// unroll and vectorise the inner loops whatever else it inlines around them; with a run-time
/// width, building this crate as one codegen unit left the f32 multigrid product (the AVX2
/// path) about 2.5x slower.
#[inline(always)]
fn spmm_row_full<T: Scalar, const W: usize>(
    cols: &[u32],
    vals: &[[T; 9]],
    x: &[T],
    y: &mut [T],
    r: usize,
    j0: usize,
    ld: usize,
) {
    let mut acc = [[T::default(); W]; 3];
    for (&col, v) in cols.iter().zip(vals) {
        let base = 3 * col as usize * ld + j0;
        for (i, acc_i) in acc.iter_mut().enumerate() {
            for d in 0..3 {
                let ad = v[3 * i + d];
                let xs: &[T; W] = x[base + d * ld..base + d * ld + W]
                    .try_into()
                    .expect("a pass of W columns");
                for j in 0..W {
                    acc_i[j] += ad * xs[j];
                }
            }
        }
    }
    for (i, acc_i) in acc.iter().enumerate() {
        let at = (3 * r + i) * ld + j0;
        y[at..at + W].copy_from_slice(acc_i);
    }
}

/// Columns per pass: 3 x 8 accumulators stay in registers.
const SPMM_CHUNK: usize = 8;

#[inline(always)]
fn spmm_kernel<T: Scalar>(pattern: &BlockPattern, a: &[[T; 9]], x: &[T], y: &mut [T], l: RowBlock) {
    for r in 0..pattern.nodes() {
        let span = pattern.row_ptr[r]..pattern.row_ptr[r + 1];
        spmm_row(
            &pattern.col[span.clone()],
            &a[span],
            x,
            y,
            r,
            0..l.width,
            l.stride,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::super::spmv;
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

    /// The f32 product (the kernel this CPU picks, and the portable one) equals the f64 one to
    /// single precision: within 1e-5 of each row's absolute sum (f32 rounding, 6e-8 per
    /// operation, over at most 81 terms per row).
    #[test]
    fn f32_spmm_matches_f64() {
        let grid = VoxelGrid::from_fn([6, 4, 3], 1.0, |x, y, _| x + y < 8.0).unwrap();
        let model = FemModel::assemble(&grid, ElementKind::Hex8, 0.3).unwrap();
        let n = model.dofs();
        let a32: Vec<[f32; 9]> = model.k.iter().map(|b| b.map(|v| v as f32)).collect();
        for (width, stride) in [(1, 1), (7, 9), (16, 16), (29, 29), (32, 40), (45, 45)] {
            let x: Vec<f64> = (0..n * stride)
                .map(|i| ((i * 31 % 17) as f64) - 8.0)
                .collect();
            let x32: Vec<f32> = x.iter().map(|&v| v as f32).collect();
            let mut y = vec![0.0; n * stride];
            spmm(
                &model.pattern,
                &model.k,
                &x,
                &mut y,
                RowBlock { width, stride },
            );
            let mut y32 = vec![0.0f32; n * stride];
            spmm(
                &model.pattern,
                &a32,
                &x32,
                &mut y32,
                RowBlock { width, stride },
            );
            let mut y32p = vec![0.0f32; n * stride];
            spmm_kernel(
                &model.pattern,
                &a32,
                &x32,
                &mut y32p,
                RowBlock { width, stride },
            );
            let scale = super::super::norm_inf(&model.pattern, &model.k) * 8.0;
            for i in 0..n {
                for j in 0..width {
                    let want = y[i * stride + j];
                    for got in [y32[i * stride + j], y32p[i * stride + j]] {
                        assert!((got as f64 - want).abs() <= 1e-5 * scale, "{got} vs {want}");
                    }
                }
            }
        }
    }
}
