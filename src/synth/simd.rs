//! SIMD lanes for the synthesis kernels, with runtime CPU dispatch.
//!
//! Where it sits: below [`super::oscillator`] and [`super::biquad`]. Their kernels are written once,
//! generic over [`Lanes`], and instantiated for each [`SimdBackend`]:
//!
//! - [`SimdBackend::Avx2Fma`]: 256-bit `std::arch` intrinsics inside `#[target_feature(enable =
//!   "avx2,fma")]` functions, chosen at run time when the CPU has them.
//! - [`SimdBackend::Portable`]: the `wide` crate's `f32x8` / `f64x4`, which compile to whatever the
//!   build target guarantees (SSE2 pairs on baseline x86-64, NEON on aarch64).
//! - [`SimdBackend::Scalar`]: plain one-mode-at-a-time loops: the baseline the benchmarks compare
//!   against and the second rendering path the tests compare with.
//!
//! The `Lanes` implementations are `#[inline(always)]` so that, once inlined into a
//! `#[target_feature]` function, the intrinsics compile to single instructions.

#[cfg(target_arch = "x86_64")]
use std::arch::x86_64::*;

/// Which instruction set the synthesis kernels run on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SimdBackend {
    /// 256-bit AVX2 with fused multiply-add (x86-64 only, detected at run time).
    Avx2Fma,
    /// The `wide` crate's portable 8 x f32 / 4 x f64 vectors.
    Portable,
    /// One mode at a time, no explicit SIMD: the reference and benchmark baseline.
    Scalar,
}

impl SimdBackend {
    /// The fastest backend this CPU supports.
    pub fn detect() -> Self {
        if Self::Avx2Fma.is_available() {
            Self::Avx2Fma
        } else {
            Self::Portable
        }
    }

    /// Every backend this CPU can run, fastest first.
    pub fn all_available() -> Vec<Self> {
        [Self::Avx2Fma, Self::Portable, Self::Scalar]
            .into_iter()
            .filter(|b| b.is_available())
            .collect()
    }

    /// Whether this CPU can run the backend.
    pub fn is_available(self) -> bool {
        match self {
            Self::Avx2Fma => avx2_fma_available(),
            Self::Portable | Self::Scalar => true,
        }
    }

    /// Short lowercase name, as printed by benchmarks and `--json` output.
    pub fn name(self) -> &'static str {
        match self {
            Self::Avx2Fma => "avx2-fma",
            Self::Portable => "portable",
            Self::Scalar => "scalar",
        }
    }
}

#[cfg(target_arch = "x86_64")]
fn avx2_fma_available() -> bool {
    is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma")
}

#[cfg(not(target_arch = "x86_64"))]
fn avx2_fma_available() -> bool {
    false
}

/// A vector of `N` lanes of `Elem`, the only operations the kernels need.
///
/// `mul_add(a, b)` is `self * a + b` and `mul_sub(a, b)` is `self * a - b`; backends with FMA fuse
/// them (one rounding), the others round twice. Loads and stores take slices of at least `N`
/// elements.
pub(crate) trait Lanes: Copy {
    /// Element type (f32 or f64).
    type Elem: Copy + Default + core::ops::Add<Output = Self::Elem>;
    /// Number of lanes.
    const N: usize;
    fn splat(x: Self::Elem) -> Self;
    fn load(src: &[Self::Elem]) -> Self;
    fn store(self, dst: &mut [Self::Elem]);
    fn add(self, other: Self) -> Self;
    fn mul(self, other: Self) -> Self;
    fn mul_add(self, a: Self, b: Self) -> Self;
    fn mul_sub(self, a: Self, b: Self) -> Self;
    fn reduce_add(self) -> Self::Elem;
}

macro_rules! wide_lanes {
    ($t:ty, $e:ty, $n:expr) => {
        impl Lanes for $t {
            type Elem = $e;
            const N: usize = $n;
            #[inline(always)]
            fn splat(x: $e) -> Self {
                <$t>::splat(x)
            }
            #[inline(always)]
            fn load(src: &[$e]) -> Self {
                let mut a = [<$e>::default(); $n];
                a.copy_from_slice(&src[..$n]);
                <$t>::new(a)
            }
            #[inline(always)]
            fn store(self, dst: &mut [$e]) {
                dst[..$n].copy_from_slice(&self.to_array());
            }
            #[inline(always)]
            fn add(self, other: Self) -> Self {
                self + other
            }
            #[inline(always)]
            fn mul(self, other: Self) -> Self {
                self * other
            }
            #[inline(always)]
            fn mul_add(self, a: Self, b: Self) -> Self {
                <$t>::mul_add(self, a, b)
            }
            #[inline(always)]
            fn mul_sub(self, a: Self, b: Self) -> Self {
                <$t>::mul_sub(self, a, b)
            }
            #[inline(always)]
            fn reduce_add(self) -> $e {
                <$t>::reduce_add(self)
            }
        }
    };
}

wide_lanes!(wide::f32x8, f32, 8);
wide_lanes!(wide::f64x4, f64, 4);

/// 8 x f32 in an AVX register. Only constructed inside `#[target_feature(enable = "avx2,fma")]`
/// functions, which are only called after [`SimdBackend::is_available`] for [`SimdBackend::Avx2Fma`].
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub(crate) struct F32x8Avx(__m256);

/// 4 x f64 in an AVX register; same contract as [`F32x8Avx`].
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub(crate) struct F64x4Avx(__m256d);

#[cfg(target_arch = "x86_64")]
impl Lanes for F32x8Avx {
    type Elem = f32;
    const N: usize = 8;
    #[inline(always)]
    fn splat(x: f32) -> Self {
        // SAFETY: this type is only used in code running after AVX2+FMA detection (see type docs).
        Self(unsafe { _mm256_set1_ps(x) })
    }
    #[inline(always)]
    fn load(src: &[f32]) -> Self {
        assert!(src.len() >= 8);
        // SAFETY: 8 readable f32 checked above; unaligned load; AVX detected (type contract).
        Self(unsafe { _mm256_loadu_ps(src.as_ptr()) })
    }
    #[inline(always)]
    fn store(self, dst: &mut [f32]) {
        assert!(dst.len() >= 8);
        // SAFETY: 8 writable f32 checked above; unaligned store; AVX detected (type contract).
        unsafe { _mm256_storeu_ps(dst.as_mut_ptr(), self.0) }
    }
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        // SAFETY: AVX detected (type contract).
        Self(unsafe { _mm256_add_ps(self.0, o.0) })
    }
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        // SAFETY: AVX detected (type contract).
        Self(unsafe { _mm256_mul_ps(self.0, o.0) })
    }
    #[inline(always)]
    fn mul_add(self, a: Self, b: Self) -> Self {
        // SAFETY: FMA detected (type contract).
        Self(unsafe { _mm256_fmadd_ps(self.0, a.0, b.0) })
    }
    #[inline(always)]
    fn mul_sub(self, a: Self, b: Self) -> Self {
        // SAFETY: FMA detected (type contract).
        Self(unsafe { _mm256_fmsub_ps(self.0, a.0, b.0) })
    }
    #[inline(always)]
    fn reduce_add(self) -> f32 {
        // SAFETY: AVX detected (type contract); pure register shuffles.
        unsafe {
            let lo = _mm256_castps256_ps128(self.0);
            let hi = _mm256_extractf128_ps(self.0, 1);
            let s = _mm_add_ps(lo, hi);
            let s = _mm_add_ps(s, _mm_movehl_ps(s, s));
            let s = _mm_add_ss(s, _mm_shuffle_ps(s, s, 0b01));
            _mm_cvtss_f32(s)
        }
    }
}

#[cfg(target_arch = "x86_64")]
impl Lanes for F64x4Avx {
    type Elem = f64;
    const N: usize = 4;
    #[inline(always)]
    fn splat(x: f64) -> Self {
        // SAFETY: AVX detected (type contract).
        Self(unsafe { _mm256_set1_pd(x) })
    }
    #[inline(always)]
    fn load(src: &[f64]) -> Self {
        assert!(src.len() >= 4);
        // SAFETY: 4 readable f64 checked above; unaligned load; AVX detected (type contract).
        Self(unsafe { _mm256_loadu_pd(src.as_ptr()) })
    }
    #[inline(always)]
    fn store(self, dst: &mut [f64]) {
        assert!(dst.len() >= 4);
        // SAFETY: 4 writable f64 checked above; unaligned store; AVX detected (type contract).
        unsafe { _mm256_storeu_pd(dst.as_mut_ptr(), self.0) }
    }
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        // SAFETY: AVX detected (type contract).
        Self(unsafe { _mm256_add_pd(self.0, o.0) })
    }
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        // SAFETY: AVX detected (type contract).
        Self(unsafe { _mm256_mul_pd(self.0, o.0) })
    }
    #[inline(always)]
    fn mul_add(self, a: Self, b: Self) -> Self {
        // SAFETY: FMA detected (type contract).
        Self(unsafe { _mm256_fmadd_pd(self.0, a.0, b.0) })
    }
    #[inline(always)]
    fn mul_sub(self, a: Self, b: Self) -> Self {
        // SAFETY: FMA detected (type contract).
        Self(unsafe { _mm256_fmsub_pd(self.0, a.0, b.0) })
    }
    #[inline(always)]
    fn reduce_add(self) -> f64 {
        // SAFETY: AVX detected (type contract); pure register shuffles.
        unsafe {
            let lo = _mm256_castpd256_pd128(self.0);
            let hi = _mm256_extractf128_pd(self.0, 1);
            let s = _mm_add_pd(lo, hi);
            _mm_cvtsd_f64(_mm_add_sd(s, _mm_unpackhi_pd(s, s)))
        }
    }
}

/// Lanes are padded to this many elements so that every backend's vectors tile the arrays.
pub(crate) const PAD: usize = 16;

/// `n` rounded up to a multiple of [`PAD`].
pub(crate) fn padded_len(n: usize) -> usize {
    n.div_ceil(PAD) * PAD
}

#[cfg(test)]
mod tests {
    use super::*;

    fn exercise<L: Lanes<Elem = f32>>() -> ([f32; 8], f32) {
        let a: Vec<f32> = (0..8).map(|i| i as f32 + 1.0).collect();
        let b = vec![0.5f32; 8];
        let va = L::load(&a);
        let vb = L::load(&b);
        // (a * 0.5 + a) * a - 0.5
        let r = va
            .mul_add(vb, va)
            .mul(va)
            .mul_sub(L::splat(1.0), vb)
            .add(L::splat(0.0));
        let mut out = [0f32; 8];
        r.store(&mut out);
        (out, r.reduce_add())
    }

    #[test]
    fn backends_agree_on_exact_arithmetic() {
        // All inputs and results are small integers and halves: exact in f32 on every path.
        let (p, ps) = exercise::<wide::f32x8>();
        for (i, v) in p.iter().enumerate() {
            let a = i as f32 + 1.0;
            assert_eq!(*v, 1.5 * a * a - 0.5);
        }
        assert_eq!(ps, p.iter().sum::<f32>());
        #[cfg(target_arch = "x86_64")]
        if SimdBackend::Avx2Fma.is_available() {
            #[target_feature(enable = "avx2,fma")]
            unsafe fn run() -> ([f32; 8], f32) {
                exercise::<F32x8Avx>()
            }
            // SAFETY: AVX2+FMA availability checked just above.
            let (q, qs) = unsafe { run() };
            assert_eq!(p, q);
            assert_eq!(ps, qs);
        }
    }
}
