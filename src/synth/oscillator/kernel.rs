//! The oscillator bank's inner loop: `n` samples of every mode, summed into one output.
//!
//! Each mode is the second-order recurrence `y[n+1] = 2 r cos(w) y[n] - r^2 y[n-1]` of a damped
//! sine (`r = e^(-d/fs)`, `w = 2 pi f / fs`), run in the difference form
//!
//! ```text
//! dy[n+1] = c2 * dy[n] - kappa * y[n]      (dy[n] = y[n] - y[n-1])
//! y[n+1]  = y[n] + dy[n+1]
//! ```
//!
//! with `c2 = r^2` and `kappa = 1 - 2 r cos(w) + r^2 = (1 - r)^2 + 4 r sin^2(w/2)`. In the usual
//! direct form, `2 r cos w` sits next to 2 and a 20 Hz mode's pitch lives in its last few f32 bits;
//! here the pitch lives in `kappa ~ w^2`, which f32 holds to full relative precision (pitch error
//! ~3e-8 relative), and an f32 rounding of `c2` moves only the decay, by < 1e-3 /s at 48 kHz.
//! Four operations per mode-sample (out += y, mul, fused mul-sub, add).
//!
//! Modes above a quarter of the sample rate run mirrored: `z[n] = (-1)^n y[n]` is a mode at
//! `pi - w`, low and well conditioned again (near Nyquist `kappa ~ 4` and its f32 rounding, and
//! that of `c2`, would detune `y` by up to 4e-7 rad per sample). Their slots come after
//! `split`, accumulate separately, and enter the output with the sign `(-1)^n`.
//!
//! Layout: modes are lanes. A vector holds `L::N` modes; `G` vectors are stepped together so the
//! 12-cycle dependency chain of one mode overlaps with the others; per sample the `G` vectors are
//! summed into a per-sample accumulator vector, reduced horizontally once at the end.

use crate::synth::simd::{Lanes, SimdBackend};

/// Vectors stepped together in the inner loop: latency hiding (one mode's chain is 12 cycles per
/// sample) against register pressure. Measured with AVX2 on the 2-core Xeon (2.0 GHz) CI machine,
/// 10k modes: 4 -> 4.1, 6 -> 3.6, 8 -> 2.2 G mode-samples/s (8 spills).
const GROUP: usize = 4;

/// Kernel state and coefficients, one entry per mode, padded to a multiple of 16 with zeros.
pub(crate) struct KernelArrays<'a> {
    pub y: &'a mut [f32],
    pub dy: &'a mut [f32],
    pub kappa: &'a [f32],
    pub c2: &'a [f32],
}

/// Where the mirrored slots start and the parity of the first output sample.
#[derive(Clone, Copy)]
pub(crate) struct Mirror {
    /// First mirrored slot (a multiple of 16).
    pub split: usize,
    /// True when the first sample of `out` has an odd index on the bank's clock.
    pub odd_start: bool,
}

/// Advances every mode `out.len()` samples and writes the sum of all modes to `out`.
/// `acc` is caller-owned scratch of at least `2 * 16 * out.len()` floats.
pub(crate) fn render(
    backend: SimdBackend,
    k: KernelArrays<'_>,
    mirror: Mirror,
    acc: &mut [f32],
    out: &mut [f32],
) {
    match backend {
        #[cfg(target_arch = "x86_64")]
        SimdBackend::Avx2Fma => {
            assert!(SimdBackend::Avx2Fma.is_available());
            // SAFETY: AVX2 and FMA are present (asserted above).
            unsafe { render_avx2(k, mirror, acc, out) }
        }
        #[cfg(not(target_arch = "x86_64"))]
        SimdBackend::Avx2Fma => render_lanes::<wide::f32x8>(k, mirror, acc, out),
        SimdBackend::Portable => render_lanes::<wide::f32x8>(k, mirror, acc, out),
        SimdBackend::Scalar => render_scalar(k, mirror, out),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn render_avx2(k: KernelArrays<'_>, mirror: Mirror, acc: &mut [f32], out: &mut [f32]) {
    render_lanes::<crate::synth::simd::F32x8Avx>(k, mirror, acc, out)
}

#[inline(always)]
fn render_lanes<L: Lanes<Elem = f32>>(
    mut k: KernelArrays<'_>,
    mirror: Mirror,
    acc: &mut [f32],
    out: &mut [f32],
) {
    let n = out.len();
    let w = L::N;
    let (low, high) = acc[..2 * n * w].split_at_mut(n * w);
    for (acc, from, to) in [(low, 0, mirror.split), (high, mirror.split, k.y.len())] {
        let mut g = from / w;
        let groups = to / w;
        // The first call stores into `acc` and the rest add to it: no clearing but of a half
        // with no modes (clearing both halves was 4 kB of memset a voice and block).
        let first = g;
        if g == groups {
            acc.fill(0.0);
        }
        while g + GROUP <= groups {
            if g == first {
                step_groups::<L, GROUP, true>(g * w, &mut k, acc);
            } else {
                step_groups::<L, GROUP, false>(g * w, &mut k, acc);
            }
            g += GROUP;
        }
        while g < groups {
            if g == first {
                step_groups::<L, 1, true>(g * w, &mut k, acc);
            } else {
                step_groups::<L, 1, false>(g * w, &mut k, acc);
            }
            g += 1;
        }
    }
    let (low, high) = acc[..2 * n * w].split_at(n * w);
    let mut sign = if mirror.odd_start { -1.0 } else { 1.0 };
    for ((o, a), b) in out
        .iter_mut()
        .zip(low.chunks_exact(w))
        .zip(high.chunks_exact(w))
    {
        *o = L::load(a).reduce_add() + sign * L::load(b).reduce_add();
        sign = -sign;
    }
}

#[inline(always)]
fn step_groups<L: Lanes<Elem = f32>, const G: usize, const FIRST: bool>(
    base: usize,
    k: &mut KernelArrays<'_>,
    acc: &mut [f32],
) {
    let w = L::N;
    let zero = L::splat(0.0);
    let (mut y, mut dy, mut kappa, mut c2) = ([zero; G], [zero; G], [zero; G], [zero; G]);
    for j in 0..G {
        let o = base + j * w;
        y[j] = L::load(&k.y[o..]);
        dy[j] = L::load(&k.dy[o..]);
        kappa[j] = L::load(&k.kappa[o..]);
        c2[j] = L::load(&k.c2[o..]);
    }
    for a in acc.chunks_exact_mut(w) {
        let mut sum = if FIRST { zero } else { L::load(a) };
        for j in 0..G {
            sum = sum.add(y[j]);
            let m = kappa[j].mul(y[j]);
            dy[j] = c2[j].mul_sub(dy[j], m);
            y[j] = y[j].add(dy[j]);
        }
        sum.store(a);
    }
    for j in 0..G {
        let o = base + j * w;
        y[j].store(&mut k.y[o..]);
        dy[j].store(&mut k.dy[o..]);
    }
}

/// One mode at a time, plain f32: the benchmark baseline and the tests' second path.
fn render_scalar(k: KernelArrays<'_>, mirror: Mirror, out: &mut [f32]) {
    out.fill(0.0);
    for i in 0..k.y.len() {
        let (mut y, mut dy, kappa, c2) = (k.y[i], k.dy[i], k.kappa[i], k.c2[i]);
        let mut sign = if i >= mirror.split && mirror.odd_start {
            -1.0
        } else {
            1.0
        };
        let flip = if i >= mirror.split { -1.0 } else { 1.0 };
        for o in out.iter_mut() {
            *o += sign * y;
            sign *= flip;
            let m = kappa * y;
            dy = c2 * dy - m;
            y += dy;
        }
        k.y[i] = y;
        k.dy[i] = dy;
    }
}
