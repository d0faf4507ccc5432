//! The oscillator bank's per-mode constants, computed from each mode's `lambda = -d + i w`
//! (rad/s), four modes at a time.
//!
//! Where it sits: [`super::OscillatorBank::retune`] lays the modes out in kernel slots and
//! [`super::OscillatorBank::retune_in_place`] keeps the layout; both then call [`fn@write`] for the
//! constants the render needs, and `retune_in_place` calls [`carry`] first to bring every mode's
//! exact amplitude to the retune instant. With per-note expression a voice is re-tuned every
//! block, so this is the audio thread's second-largest cost after rendering (issue 15).
//!
//! Per mode, with `a = d / fs` and `b = w / fs` (rad per sample), `r = e^-a`:
//!
//! - `kappa = (1 - r)^2 + 4 r sin^2(w'/2)` and `c2 = r^2` for the f32 recurrence
//!   ([`super::kernel`]), with `w' = b`, or `pi - b` for a mirrored mode (`b > pi/2`);
//! - `step = e^(64 lambda / fs)`, the exact anchor advance ([`super::anchor`]);
//! - `back = -expm1(-lambda / fs)` (mirrored: `1 + e^(-lambda / fs)`), which maps an exact
//!   amplitude to the recurrence's second state.
//!
//! Everything comes from `expm1(-a)` and `sincos(b/2)` (Taylor series, inlined so that they run
//! on AVX2, evaluated by Estrin's scheme), arranged so that nothing cancels:
//! `cos b - 1 = -2 sin^2(b/2)`, `1 + cos b = 2 cos^2(b/2)`, `expm1(a) = -expm1(-a) / r`; the
//! anchor step by six squarings of `r` and seven doublings of the angle. [`SimdBackend::Scalar`]
//! computes the same constants with the platform's libm, one mode at a time, from the textbook
//! forms; the tests hold the two to a few ulps.

use super::anchor::Anchors;
use super::ANCHOR_SAMPLES;
use crate::synth::simd::SimdBackend;
use num_complex::Complex64;
use wide::f64x4;

/// The constants' destinations, by kernel slot, and the layout that maps modes to slots.
pub(super) struct Slots<'a> {
    /// Kernel slot of each mode.
    pub slot: &'a [usize],
    /// First mirrored slot.
    pub split: usize,
    pub kappa: &'a mut [f32],
    pub c2: &'a mut [f32],
    pub anchors: &'a mut Anchors,
}

/// Writes every mode's constants (`lambda` in mode order) into its slot.
pub(super) fn write(backend: SimdBackend, fs: f64, lambda: &[Complex64], s: Slots<'_>) {
    match backend {
        #[cfg(target_arch = "x86_64")]
        SimdBackend::Avx2Fma if SimdBackend::Avx2Fma.is_available() => {
            // SAFETY: AVX2 and FMA are present (checked in the guard).
            unsafe { write_avx2(fs, lambda, s) }
        }
        SimdBackend::Scalar => write_scalar(fs, lambda, s),
        _ => write_lanes(fs, lambda, s),
    }
}

/// Moves every mode's exact amplitude `dt_s` seconds on: `z <- z e^(lambda dt)`.
pub(super) fn carry(
    backend: SimdBackend,
    dt_s: f64,
    lambda: &[Complex64],
    slot: &[usize],
    anchors: &mut Anchors,
) {
    match backend {
        #[cfg(target_arch = "x86_64")]
        SimdBackend::Avx2Fma if SimdBackend::Avx2Fma.is_available() => {
            // SAFETY: AVX2 and FMA are present (checked in the guard).
            unsafe { carry_avx2(dt_s, lambda, slot, anchors) }
        }
        SimdBackend::Scalar => {
            for (l, &k) in lambda.iter().zip(slot) {
                let z = Complex64::new(anchors.z_re[k], anchors.z_im[k]) * (l * dt_s).exp();
                (anchors.z_re[k], anchors.z_im[k]) = (z.re, z.im);
            }
        }
        _ => carry_lanes(dt_s, lambda, slot, anchors),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn write_avx2(fs: f64, lambda: &[Complex64], s: Slots<'_>) {
    write_lanes(fs, lambda, s)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn carry_avx2(dt_s: f64, lambda: &[Complex64], slot: &[usize], anchors: &mut Anchors) {
    carry_lanes(dt_s, lambda, slot, anchors)
}

/// Four modes' `lambda` as `(-d, w)` lanes; lanes past the end get a harmless mode
/// (`w = 1`, `d = 0`) whose results are never stored.
#[inline(always)]
fn load(lambda: &[Complex64]) -> (f64x4, f64x4) {
    let mut d = [0.0; 4];
    let mut w = [1.0; 4];
    for (j, l) in lambda.iter().enumerate() {
        d[j] = -l.re;
        w[j] = l.im;
    }
    (f64x4::from(d), f64x4::from(w))
}

#[inline(always)]
fn write_lanes(fs: f64, lambda: &[Complex64], s: Slots<'_>) {
    let inv_fs = f64x4::splat(1.0 / fs);
    let (one, two, half) = (f64x4::ONE, f64x4::splat(2.0), f64x4::HALF);
    for (c, chunk) in lambda.chunks(4).enumerate() {
        let (d, w) = load(chunk);
        let (a, b) = (d * inv_fs, w * inv_fs);
        // The layout decides which modes run mirrored (those above fs/4).
        let mut m = [0.0; 4];
        for (j, m) in m.iter_mut().enumerate().take(chunk.len()) {
            *m = f64::from(u8::from(s.slot[4 * c + j] >= s.split));
        }
        let mirrored = f64x4::from(m).simd_gt(f64x4::HALF);
        let rm1 = expm1_neg(a);
        let r = one + rm1;
        let (sh, ch) = sin_cos_quadrant(half * b);
        let (sh2, ch2) = (sh * sh, ch * ch);
        // sin^2(w'/2): sin^2(b/2), or cos^2(b/2) for the mirrored pi - b.
        let sw2 = mirrored.select(ch2, sh2);
        let kappa = rm1.mul_add(rm1, f64x4::splat(4.0) * r * sw2);
        let c2 = r * r;
        // e^(-64 a) = r^64 by six squarings, and (cos, sin)(64 b) by seven angle doublings
        // from b/2: each doubles the relative error, 128 eps ~ 1.4e-14 in all, which moves a
        // ringing mode's phase by ~6e-9 rad over ten minutes of anchors.
        let mut decay64 = r;
        for _ in 0..6 {
            decay64 = decay64 * decay64;
        }
        let (mut s64, mut c64) = (sh, ch);
        for _ in 0..7 {
            (s64, c64) = (two * s64 * c64, (c64 - s64) * (c64 + s64));
        }
        let (step_re, step_im) = (decay64 * c64, decay64 * s64);
        // e^a = 1/r, expm1(a) = -expm1(-a)/r; cos b = 1 - 2 sin^2(b/2), sin b = 2 sin cos.
        let ea = one / r;
        let em1a = -rm1 * ea;
        let cos_b = two.mul_neg_add(sh2, one);
        let ea_sin_b = ea * two * sh * ch;
        let back_low_re = two.mul_sub(sh2, em1a * cos_b);
        let back_mirror_re = em1a.mul_add(cos_b, two * ch2);
        let back_re = mirrored.select(back_mirror_re, back_low_re);
        let back_im = mirrored.select(-ea_sin_b, ea_sin_b);
        let (kappa, c2) = (kappa.to_array(), c2.to_array());
        let (step_re, step_im) = (step_re.to_array(), step_im.to_array());
        let (back_re, back_im) = (back_re.to_array(), back_im.to_array());
        for j in 0..chunk.len() {
            let k = s.slot[4 * c + j];
            s.kappa[k] = kappa[j] as f32;
            s.c2[k] = c2[j] as f32;
            let a = &mut *s.anchors;
            (a.step_re[k], a.step_im[k]) = (step_re[j], step_im[j]);
            (a.back_re[k], a.back_im[k]) = (back_re[j], back_im[j]);
        }
    }
}

#[inline(always)]
fn carry_lanes(dt_s: f64, lambda: &[Complex64], slot: &[usize], anchors: &mut Anchors) {
    let dt = f64x4::splat(dt_s);
    for (c, chunk) in lambda.chunks(4).enumerate() {
        let (d, w) = load(chunk);
        let decay = (-(d * dt)).exp();
        let (s, co) = (w * dt).sin_cos();
        let (f_re, f_im) = ((decay * co).to_array(), (decay * s).to_array());
        for j in 0..chunk.len() {
            let k = slot[4 * c + j];
            let z =
                Complex64::new(anchors.z_re[k], anchors.z_im[k]) * Complex64::new(f_re[j], f_im[j]);
            (anchors.z_re[k], anchors.z_im[k]) = (z.re, z.im);
        }
    }
}

// `write_lanes` reaches `e^(64 lambda / fs)` by six squarings and seven doublings.
const _: () = assert!(ANCHOR_SAMPLES == 64);

/// `1/n!` for `n` in `0..24`.
const INV_FACTORIAL: [f64; 24] = {
    let mut c = [1.0; 24];
    let mut n = 1;
    while n < 24 {
        c[n] = c[n - 1] / n as f64;
        n += 1;
    }
    c
};

/// `e^-a - 1` for `a >= 0`: its Taylor series to the 13th power where every lane has
/// `a <= 1/4` (the first omitted term is below 1e-18 of the result there; a mode that loses
/// more than a quarter of its amplitude per sample is rare), else `wide`'s range-reduced
/// `exp_m1`. Inlined, unlike `wide`'s, so it runs on AVX2 inside [`write_avx2`].
#[inline(always)]
fn expm1_neg(a: f64x4) -> f64x4 {
    if a.simd_gt(f64x4::splat(0.25)).any() {
        return (-a).exp_m1();
    }
    let x = -a;
    // e^x - 1 = x (1 + x/2! + x^2/3! + ... + x^12/13!).
    let c: [f64; 13] = std::array::from_fn(|n| INV_FACTORIAL[n + 1]);
    x * estrin(x, c)
}

/// `(sin x, cos x)` for `x` in `[0, pi/2]`: the Taylor series to the 21st and 22nd powers,
/// whose first omitted terms are below 2e-18 there (no range reduction needed: the callers'
/// angles are half of at most pi). Inlined, for AVX2 inside [`write_avx2`].
#[inline(always)]
fn sin_cos_quadrant(x: f64x4) -> (f64x4, f64x4) {
    let x2 = x * x;
    let sign = |k: usize| if k.is_multiple_of(2) { 1.0 } else { -1.0 };
    let s: [f64; 11] = std::array::from_fn(|k| sign(k) * INV_FACTORIAL[2 * k + 1]);
    let c: [f64; 12] = std::array::from_fn(|k| sign(k) * INV_FACTORIAL[2 * k]);
    (x * estrin(x2, s), estrin(x2, c))
}

/// `c[0] + c[1] y + ... + c[N-1] y^(N-1)` by Estrin's scheme: pairs, then pairs of pairs with
/// `y^2`, `y^4`, ...: a dependency chain of `log2 N` fused multiply-adds instead of Horner's
/// `N`, so the lanes' latency does not bound the loop.
#[inline(always)]
fn estrin<const N: usize>(y: f64x4, c: [f64; N]) -> f64x4 {
    let mut t: [f64x4; N] = std::array::from_fn(|i| f64x4::splat(c[i]));
    let (mut len, mut p) = (N, y);
    while len > 1 {
        let half = len.div_ceil(2);
        for i in 0..half {
            t[i] = if 2 * i + 1 < len {
                t[2 * i + 1].mul_add(p, t[2 * i])
            } else {
                t[2 * i]
            };
        }
        len = half;
        p = p * p;
    }
    t[0]
}

/// The reference: libm, one mode at a time, in the textbook forms.
fn write_scalar(fs: f64, lambda: &[Complex64], s: Slots<'_>) {
    for (&l, &k) in lambda.iter().zip(s.slot) {
        let (d, w) = (-l.re, l.im);
        let mirrored = k >= s.split;
        let r_minus_1 = (-d / fs).exp_m1();
        let r = 1.0 + r_minus_1;
        let kernel_w = if mirrored {
            std::f64::consts::PI - w / fs
        } else {
            w / fs
        };
        s.kappa[k] = (r_minus_1 * r_minus_1 + 4.0 * r * (0.5 * kernel_w).sin().powi(2)) as f32;
        s.c2[k] = (r * r) as f32;
        let step = (l * (ANCHOR_SAMPLES as f64 / fs)).exp();
        (s.anchors.step_re[k], s.anchors.step_im[k]) = (step.re, step.im);
        let back = if mirrored {
            -exp_m1_complex(-l / fs + Complex64::new(0.0, std::f64::consts::PI))
        } else {
            -exp_m1_complex(-l / fs)
        };
        (s.anchors.back_re[k], s.anchors.back_im[k]) = (back.re, back.im);
    }
}

/// `e^x - 1` for complex `x`, accurate for small `|x|`:
/// `(e^a - 1) cos b + (cos b - 1) + i e^a sin b`, with `cos b - 1 = -2 sin^2(b/2)`.
fn exp_m1_complex(x: Complex64) -> Complex64 {
    let (a, b) = (x.re, x.im);
    let em1 = a.exp_m1();
    let cm1 = -2.0 * (0.5 * b).sin().powi(2);
    Complex64::new(em1 * b.cos() + cm1, (em1 + 1.0) * b.sin())
}
