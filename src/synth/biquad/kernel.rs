//! The biquad bank's inner loop: transposed direct form II in f64, one filter per SIMD lane.
//!
//! ```text
//! y  = b0 x + s1
//! s1 = b1 x - a1 y + s2
//! s2 = b2 x - a2 y
//! ```
//!
//! f64 because a driven filter cannot be re-anchored like the oscillator bank (its state depends on
//! the whole input), so its coefficients must be exact enough on their own: in f32, `a1 = -2 r cos w`
//! of a 20 Hz mode at 96 kHz differs from -2 by 1.7e-6 and the f32 spacing there (2.4e-7) detunes
//! it by several percent; in f64 the error is ~1e-10. When every numerator is `b1 z^-1` alone (modal
//! resonators), a specialised loop drops the `b0` and `b2` terms: 4 operations per lane-sample.
//!
//! Branches (parallel filters, Diaz et al. 2023, eq. 3) are lanes; the stages of one branch run one
//! after another on a per-group scratch signal, and the last stage of every branch is summed.

use crate::synth::simd::{Lanes, SimdBackend};

/// Vectors stepped together (hides the 8-cycle y -> s1 -> y dependency chain).
pub(crate) const GROUP_VECTORS: usize = 3;

/// Coefficient and state arrays, `[stage * padded + branch]`, padded branches all zero.
pub(crate) struct BankArrays<'a> {
    pub stages: usize,
    pub padded: usize,
    /// True when every b0 and b2 is zero.
    pub modal: bool,
    pub b0: &'a [f64],
    pub b1: &'a [f64],
    pub b2: &'a [f64],
    /// Negated denominators, -a1 and -a2.
    pub na1: &'a [f64],
    pub na2: &'a [f64],
    pub s1: &'a mut [f64],
    pub s2: &'a mut [f64],
}

/// Filters `x` through every branch and writes the sum of the branches' outputs to `out`.
/// `scratch` holds at least `(GROUP_VECTORS + 1) * 4 * x.len()` f64 (`GROUP_VECTORS` cascade signals and the sum).
pub(crate) fn process(
    backend: SimdBackend,
    a: BankArrays<'_>,
    x: &[f64],
    scratch: &mut [f64],
    out: &mut [f32],
) {
    match (backend, a.modal) {
        #[cfg(target_arch = "x86_64")]
        (SimdBackend::Avx2Fma, modal) => {
            assert!(SimdBackend::Avx2Fma.is_available());
            // SAFETY: AVX2 and FMA are present (asserted above).
            unsafe {
                if modal {
                    process_avx2::<false>(a, x, scratch, out)
                } else {
                    process_avx2::<true>(a, x, scratch, out)
                }
            }
        }
        (SimdBackend::Scalar, _) => process_scalar(a, x, out),
        (_, true) => process_lanes::<wide::f64x4, false>(a, x, scratch, out),
        (_, false) => process_lanes::<wide::f64x4, true>(a, x, scratch, out),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn process_avx2<const GENERAL: bool>(
    a: BankArrays<'_>,
    x: &[f64],
    scratch: &mut [f64],
    out: &mut [f32],
) {
    process_lanes::<crate::synth::simd::F64x4Avx, GENERAL>(a, x, scratch, out)
}

#[inline(always)]
fn process_lanes<L: Lanes<Elem = f64>, const GENERAL: bool>(
    mut a: BankArrays<'_>,
    x: &[f64],
    scratch: &mut [f64],
    out: &mut [f32],
) {
    let n = x.len();
    let w = L::N;
    let (sum, signals) = scratch.split_at_mut(n * w);
    sum.fill(0.0);
    let groups = a.padded / w;
    let mut g = 0;
    while g + GROUP_VECTORS <= groups {
        branch_groups::<L, GROUP_VECTORS, GENERAL>(
            g * w,
            &mut a,
            x,
            &mut signals[..GROUP_VECTORS * n * w],
            sum,
        );
        g += GROUP_VECTORS;
    }
    while g < groups {
        branch_groups::<L, 1, GENERAL>(g * w, &mut a, x, &mut signals[..n * w], sum);
        g += 1;
    }
    for (o, s) in out.iter_mut().zip(sum.chunks_exact(w)) {
        *o = L::load(s).reduce_add() as f32;
    }
}

#[inline(always)]
fn branch_groups<L: Lanes<Elem = f64>, const G: usize, const GENERAL: bool>(
    base: usize,
    a: &mut BankArrays<'_>,
    x: &[f64],
    signals: &mut [f64],
    sum: &mut [f64],
) {
    let (w, n) = (L::N, x.len());
    let zero = L::splat(0.0);
    for stage in 0..a.stages {
        let first = stage == 0;
        let last = stage + 1 == a.stages;
        let (mut b0, mut b1, mut b2, mut na1, mut na2) =
            ([zero; G], [zero; G], [zero; G], [zero; G], [zero; G]);
        let (mut s1, mut s2) = ([zero; G], [zero; G]);
        for j in 0..G {
            let o = stage * a.padded + base + j * w;
            b0[j] = L::load(&a.b0[o..]);
            b1[j] = L::load(&a.b1[o..]);
            b2[j] = L::load(&a.b2[o..]);
            na1[j] = L::load(&a.na1[o..]);
            na2[j] = L::load(&a.na2[o..]);
            s1[j] = L::load(&a.s1[o..]);
            s2[j] = L::load(&a.s2[o..]);
        }
        for s in 0..n {
            let xs = L::splat(x[s]);
            let mut acc = if last { L::load(&sum[s * w..]) } else { zero };
            for j in 0..G {
                let sig = &mut signals[(j * n + s) * w..(j * n + s + 1) * w];
                let xi = if first { xs } else { L::load(sig) };
                let (y, t) = if GENERAL {
                    (b0[j].mul_add(xi, s1[j]), b1[j].mul_add(xi, s2[j]))
                } else {
                    (s1[j], b1[j].mul_add(xi, s2[j]))
                };
                s1[j] = na1[j].mul_add(y, t);
                s2[j] = if GENERAL {
                    na2[j].mul_add(y, b2[j].mul(xi))
                } else {
                    na2[j].mul(y)
                };
                if last {
                    acc = acc.add(y);
                } else {
                    y.store(sig);
                }
            }
            if last {
                acc.store(&mut sum[s * w..]);
            }
        }
        for j in 0..G {
            let o = stage * a.padded + base + j * w;
            s1[j].store(&mut a.s1[o..]);
            s2[j].store(&mut a.s2[o..]);
        }
    }
}

/// One filter at a time, plain f64: the baseline and the tests' second path.
fn process_scalar(a: BankArrays<'_>, x: &[f64], out: &mut [f32]) {
    let n = x.len();
    let mut sum = [0f64; 64];
    let mut sig = [0f64; 64];
    assert!(n <= 64);
    for branch in 0..a.padded {
        sig[..n].copy_from_slice(x);
        for stage in 0..a.stages {
            let o = stage * a.padded + branch;
            let (b0, b1, b2, na1, na2) = (a.b0[o], a.b1[o], a.b2[o], a.na1[o], a.na2[o]);
            let (mut s1, mut s2) = (a.s1[o], a.s2[o]);
            for v in sig[..n].iter_mut() {
                let xi = *v;
                let y = b0 * xi + s1;
                s1 = b1 * xi + s2 + na1 * y;
                s2 = b2 * xi + na2 * y;
                *v = y;
            }
            a.s1[o] = s1;
            a.s2[o] = s2;
        }
        for (s, v) in sum[..n].iter_mut().zip(&sig[..n]) {
            *s += v;
        }
    }
    for (o, s) in out.iter_mut().zip(&sum[..n]) {
        *o = *s as f32;
    }
}
