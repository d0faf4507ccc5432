//! Gliding: every mode of a bank re-tuned by one shared frequency ratio, in f32, a few
//! operations a mode (issue 15's per-note expression, which re-tunes a voice every block).
//!
//! Where it sits: [`super::OscillatorBank::set_glide_reference`] records, at an exact tuning
//! (the *key*), each mode's undamped `omega_n^2`, its damping-law decay and that decay's slope
//! in the log of the frequency ratio; [`super::OscillatorBank::glide`] then moves every mode to
//! ratio `r` of the key: `omega_n -> r omega_n`, the law's decay `d -> d e^(p ln r)` (a local
//! power law, the cubic Taylor series of the exponential), plus an extra decay shared by all
//! modes (pressure, mute), and the damped frequency `sqrt(r^2 omega_n^2 - d^2)`: what
//! `engine::voicing::tune` gives at that size, to within the power law's curvature (for a
//! Rayleigh law `ln d` bends by at most `(ln r)^2 / 2`, 0.4 % of the decay at the widest
//! glide, 1.5 semitones, [`GLIDE_MAX_LN_RATIO`]; the frequency is exact but for that decay's
//! share in `sqrt(omega_n^2 - d^2)`).
//!
//! The exact path ([`super::constants`]) keeps an f64 anchor per mode and restarts the f32
//! recurrence from it every 64 samples; re-tuning it costs two f64 series, the anchor step
//! and a restart per mode. A glide instead carries the f32 kernel state itself across the
//! change of constants, keeping each mode's complex amplitude: with `back = 1 - e^(-lambda/fs)`
//! the kernel state is `y = Im z`, `dy = Im(z back)`, so `Re z = (dy - y Re back) / Im back`
//! and the new state is `dy' = Re z Im back' + y Re back'` (parity free: the mirrored slots'
//! sign flips cancel). While a bank glides its anchors are stale and not advanced (the f32
//! recurrence alone drifts ~1e-7 of the peak per block, 1e-3 /s of decay at most); the next
//! exact re-tune recovers every anchor from the f32 state.
//!
//! Per slot, with `a = d / fs` and the kernel angle `w` (`pi - w` mirrored), everything from
//! `e^(+-a) - 1` (one even and one odd Taylor series, shared) and `sin`, `cos` of `w / 2`
//! (Taylor, `w / 2 <= 0.3 pi`): `kappa = (e^-a - 1)^2 + 4 e^-a sin^2(w/2)`,
//! `c2 = 1 + (e^-a - 1)(2 + e^-a - 1)`, `back = 2 sin^2(w/2) e^a - (e^a - 1) + i 2 e^a
//! sin(w/2) cos(w/2)`, as [`super::constants`] writes them in f64.
//!
//! Lifecycle: [`Glide::new`] allocates; [`Glide::key`] and [`Glide::retune`] never do.

use super::anchor::Anchors;
use crate::fma::mul_add;
use crate::synth::simd::SimdBackend;
use std::f64::consts::{PI, TAU};

/// Widest glide from the key, as a natural log of the frequency ratio (1.5 semitones): a
/// wider one re-keys on the exact path.
pub const GLIDE_MAX_LN_RATIO: f64 = 1.5 * std::f64::consts::LN_2 / 12.0;

/// How far (in units of fs) a glide may carry a mode past fs/4 on its kernel half: the
/// halves split at fs/4 so that neither runs near its ill-conditioned end (the direct
/// recurrence near Nyquist, the mirrored one near 0 Hz); at 0.3 fs the direct kernel's
/// angle is 0.6 pi, as well conditioned as at 0.2 fs. The next exact re-tune lays the mode
/// out on its own half again.
pub const QUARTER_SLACK: f64 = 0.05;

/// Steepest decay slope `|d ln d / d ln r|` a key accepts (a Rayleigh or power law with
/// exponent up to 2 on `omega^2`); steeper laws glide on the exact path.
pub const MAX_DECAY_SLOPE: f64 = 4.0;

/// Largest decay per sample a glide computes with its series (`e^-a` to 7 terms: error below
/// 4e-10 at 1/4); keys whose modes could decay faster are refused.
const MAX_DECAY_PER_SAMPLE: f64 = 0.25;

/// Why a glide or a key was refused (the bank is left unchanged).
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum GlideError {
    /// No key describes the bank's current tuning (never set, or an exact re-tune since).
    #[error("the bank has no glide key for its current tuning")]
    NotKeyed,
    /// The ratio or extra decay leaves the range the key allows (a mode would cross fs/4 or
    /// Nyquist, stop oscillating, or the glide would be wider than [`GLIDE_MAX_LN_RATIO`]).
    #[error(
        "glide ratio {ratio} with extra decay {extra_decay_per_s} /s is outside the key's range"
    )]
    OutOfRange {
        /// Frequency ratio asked for.
        ratio: f64,
        /// Extra decay asked for.
        extra_decay_per_s: f64,
    },
    /// A key with other than one value of each per mode, or a value that is not finite, not
    /// positive where it must be, or a slope steeper than [`MAX_DECAY_SLOPE`].
    #[error("glide key rejected: mode {index} has no valid reference")]
    BadKey {
        /// Index of the first offending mode (or the bank's length for a length mismatch).
        index: usize,
    },
}

/// Glide reference and state of one bank.
pub(super) struct Glide {
    // By kernel slot, per-sample units, for the kernel: omega_n^2 / fs^2, the law's decay / fs,
    // its slope in ln r, and the kernel-level back constant the state was last written with.
    wn2: Vec<f32>,
    decay: Vec<f32>,
    slope: Vec<f32>,
    back_re: Vec<f32>,
    inv_back_im: Vec<f32>,
    // By mode, per second, for reporting the tuning exactly as the kernel was given it.
    mode_wn2: Vec<f64>,
    mode_decay: Vec<f64>,
    mode_slope: Vec<f64>,
    /// A key for the bank's modes and layout: a glide's ratio is relative to it.
    pub keyed: bool,
    /// The kernel state is a glide's: the anchors are stale.
    pub active: bool,
    ratio_lo: f64,
    ratio_hi: f64,
    extra_max_per_s: f64,
    /// The last glide's ratio (and its log) and extra decay.
    pub ratio: f64,
    ln_ratio: f64,
    pub extra_decay_per_s: f64,
}

/// The decay factor of a glide: `e^x` to its cubic term (`x = slope ln r`, `|x| <= 0.35`),
/// the same in f64 (reporting) and f32 (the kernel).
#[inline(always)]
fn law_factor(x: f64) -> f64 {
    1.0 + x * (1.0 + x * (0.5 + x * (1.0 / 6.0)))
}

/// A bound on the law's decay `d` (slope `p`) anywhere in a glide's range: 1 % above the
/// cubic's largest value there.
fn top_decay(d: f64, p: f64) -> f64 {
    1.01 * d * law_factor(p.abs() * GLIDE_MAX_LN_RATIO)
}

impl Glide {
    /// Room for `slots` kernel slots and `capacity` modes. Allocates.
    pub fn new(slots: usize, capacity: usize) -> Self {
        Self {
            wn2: vec![0.0; slots],
            decay: vec![0.0; slots],
            slope: vec![0.0; slots],
            back_re: vec![0.0; slots],
            inv_back_im: vec![0.0; slots],
            mode_wn2: vec![0.0; capacity],
            mode_decay: vec![0.0; capacity],
            mode_slope: vec![0.0; capacity],
            keyed: false,
            active: false,
            ratio_lo: 1.0,
            ratio_hi: 1.0,
            extra_max_per_s: 0.0,
            ratio: 1.0,
            ln_ratio: 0.0,
            extra_decay_per_s: 0.0,
        }
    }

    /// Records the key (per mode: `omega_n^2` in rad^2/s^2, the law's decay in 1/s, its slope
    /// in `ln r`) for the layout `slot`/`split`/`used`, and the ratio and extra-decay range
    /// within which no mode changes kernel half, reaches Nyquist or stops oscillating.
    #[allow(clippy::too_many_arguments)]
    pub fn key(
        &mut self,
        fs: f64,
        slot: &[usize],
        split: usize,
        used: usize,
        wn2_rad2_s2: &[f64],
        decay_per_s: &[f64],
        slope: &[f64],
    ) -> Result<(), GlideError> {
        let n = slot.len();
        if wn2_rad2_s2.len() != n || decay_per_s.len() != n || slope.len() != n {
            return Err(GlideError::BadKey { index: n });
        }
        // A glide carries no mode to the other kernel half: direct slots stay below
        // (1/4 + QUARTER_SLACK) fs, mirrored ones above (1/4 - QUARTER_SLACK) fs.
        let direct_top = TAU * (0.25 + QUARTER_SLACK) * fs;
        let mirrored_bottom = TAU * (0.25 - QUARTER_SLACK) * fs;
        let nyquist = PI * fs;
        let (mut lo, mut hi) = ((-GLIDE_MAX_LN_RATIO).exp(), GLIDE_MAX_LN_RATIO.exp());
        let mut dmax = 0.0f64;
        for i in 0..n {
            let (w2, d, p) = (wn2_rad2_s2[i], decay_per_s[i], slope[i]);
            let valid = w2.is_finite()
                && w2 > 0.0
                && d.is_finite()
                && d >= 0.0
                && p.is_finite()
                && p.abs() <= MAX_DECAY_SLOPE;
            if !valid {
                return Err(GlideError::BadKey { index: i });
            }
            let wn = w2.sqrt();
            let top = top_decay(d, p);
            dmax = dmax.max(top);
            if slot[i] < split {
                // The damped frequency is below r omega_n.
                hi = hi.min(direct_top / wn * (1.0 - 1e-9));
            } else {
                let bottom = (mirrored_bottom * mirrored_bottom + top * top).sqrt();
                lo = lo.max(bottom / wn * (1.0 + 1e-9));
                hi = hi.min(nyquist / wn * (1.0 - 1e-9));
            }
        }
        // Every mode keeps oscillating, and within the series' range, at the lowest ratio.
        let mut extra_max = MAX_DECAY_PER_SAMPLE * fs - dmax;
        for i in 0..n {
            let top = top_decay(decay_per_s[i], slope[i]);
            let wd_min = (wn2_rad2_s2[i] * lo * lo - top * top).max(0.0).sqrt();
            extra_max = extra_max.min(0.999 * wd_min - top);
        }
        if !(lo < 1.0 && hi > 1.0 && extra_max > 0.0) {
            self.keyed = false;
            return Err(GlideError::BadKey { index: n });
        }
        // Padded slots get a harmless mode (their state is zero and stays zero).
        let inv_fs = 1.0 / fs;
        self.pad(0..split.min(used), false);
        self.pad(split.min(used)..used, true);
        for i in 0..n {
            let k = slot[i];
            self.wn2[k] = (wn2_rad2_s2[i] * inv_fs * inv_fs) as f32;
            self.decay[k] = (decay_per_s[i] * inv_fs) as f32;
            self.slope[k] = slope[i] as f32;
            self.mode_wn2[i] = wn2_rad2_s2[i];
            self.mode_decay[i] = decay_per_s[i];
            self.mode_slope[i] = slope[i];
        }
        (self.ratio_lo, self.ratio_hi, self.extra_max_per_s) = (lo, hi, extra_max);
        self.keyed = true;
        (self.ratio, self.ln_ratio) = (1.0, 0.0);
        Ok(())
    }

    /// Moves slot `from`'s key and back constants to slot `to` (a drop;
    /// [`super::OscillatorBank::retain`]).
    pub fn move_slot(&mut self, from: usize, to: usize) {
        for v in [
            &mut self.wn2,
            &mut self.decay,
            &mut self.slope,
            &mut self.back_re,
            &mut self.inv_back_im,
        ] {
            v[to] = v[from];
        }
    }

    /// Moves mode `from`'s key to mode `to` (a drop).
    pub fn move_mode(&mut self, from: usize, to: usize) {
        for v in [
            &mut self.mode_wn2,
            &mut self.mode_decay,
            &mut self.mode_slope,
        ] {
            v[to] = v[from];
        }
    }

    /// Gives slots `range` the harmless padding mode (a zero state stays zero).
    pub fn pad(&mut self, range: std::ops::Range<usize>, mirrored: bool) {
        let w = if mirrored { 0.75 * PI } else { 0.25 * PI };
        self.wn2[range.clone()].fill((w * w) as f32);
        for v in [
            &mut self.decay,
            &mut self.slope,
            &mut self.back_re,
            &mut self.inv_back_im,
        ] {
            v[range.clone()].fill(0.0);
        }
    }

    /// Checks a glide against the key's range.
    pub fn check(&self, ratio: f64, extra_decay_per_s: f64) -> Result<(), GlideError> {
        if !self.keyed {
            return Err(GlideError::NotKeyed);
        }
        let inside = ratio > self.ratio_lo
            && ratio < self.ratio_hi
            && extra_decay_per_s >= 0.0
            && extra_decay_per_s < self.extra_max_per_s;
        if inside {
            Ok(())
        } else {
            Err(GlideError::OutOfRange {
                ratio,
                extra_decay_per_s,
            })
        }
    }

    /// Mode `i`'s frequency (Hz) and decay (1/s) at the last glide, in f64.
    pub fn tuning(&self, i: usize) -> (f64, f64) {
        let r = self.ratio;
        let d = self.mode_decay[i] * law_factor(self.mode_slope[i] * self.ln_ratio);
        let wd = (self.mode_wn2[i] * r * r - d * d).sqrt();
        (wd / TAU, d + self.extra_decay_per_s)
    }

    /// Takes over from the exact path: the kernel-level back constants the f32 state was
    /// written with, from the anchors' f64 ones (mirrored slots store `conj`: `1 + e^-lambda`).
    pub fn enter(&mut self, anchors: &Anchors, split: usize, used: usize) {
        for k in 0..used {
            let (re, im) = (anchors.back_re[k], anchors.back_im[k]);
            self.back_re[k] = re as f32;
            // Padded slots (all zero) get 0: their zero state stays zero.
            let inv = if im == 0.0 { 0.0 } else { 1.0 / im };
            self.inv_back_im[k] = (if k < split { inv } else { -inv }) as f32;
        }
        self.active = true;
    }

    /// Slot `k`'s exact complex amplitude (re, im) from its f32 state, for the anchors: the
    /// state's own sign `sign` (-1 for a mirrored slot at an odd sample).
    pub fn amplitude(&self, k: usize, split: usize, y: f32, dy: f32, sign: f64) -> (f64, f64) {
        let (y, dy) = (sign * y as f64, sign * dy as f64);
        let inv = self.inv_back_im[k] as f64;
        let inv = if k < split { inv } else { -inv };
        ((dy - y * self.back_re[k] as f64) * inv, y)
    }

    /// Slot `k`'s amplitude `|z|` from its f32 state.
    pub fn magnitude(&self, k: usize, y: f32, dy: f32) -> f64 {
        let (y, dy) = (y as f64, dy as f64);
        let re = (dy - y * self.back_re[k] as f64) * self.inv_back_im[k] as f64;
        (re * re + y * y).sqrt()
    }

    /// Moves every slot below `used` to `ratio` of the key with `extra_decay_per_s`, keeping
    /// each mode's complex amplitude (after [`Self::check`] and [`Self::enter`]). Never
    /// allocates.
    #[allow(clippy::too_many_arguments)]
    pub fn retune(
        &mut self,
        backend: SimdBackend,
        fs: f64,
        split: usize,
        ratio: f64,
        extra_decay_per_s: f64,
        k: KernelState<'_>,
    ) {
        let used = k.y.len();
        let ln_ratio = ratio.ln();
        let v = Shared {
            ratio_sq: (ratio * ratio) as f32,
            ln_ratio: ln_ratio as f32,
            extra: (extra_decay_per_s / fs) as f32,
        };
        let mut g = GlideSlots {
            wn2: &self.wn2[..used],
            decay: &self.decay[..used],
            slope: &self.slope[..used],
            back_re: &mut self.back_re[..used],
            inv_back_im: &mut self.inv_back_im[..used],
        };
        match backend {
            #[cfg(target_arch = "x86_64")]
            SimdBackend::Avx2Fma if SimdBackend::Avx2Fma.is_available() => {
                // SAFETY: AVX2 and FMA are present (checked in the guard).
                unsafe { retune_avx2(&mut g, k, split, v) }
            }
            _ => retune_slots::<false>(&mut g, k, split, v),
        }
        (self.ratio, self.ln_ratio) = (ratio, ln_ratio);
        self.extra_decay_per_s = extra_decay_per_s;
    }
}

/// The f32 kernel arrays a glide rewrites, cut to the slots in use.
pub(super) struct KernelState<'a> {
    pub y: &'a [f32],
    pub dy: &'a mut [f32],
    pub kappa: &'a mut [f32],
    pub c2: &'a mut [f32],
}

struct GlideSlots<'a> {
    wn2: &'a [f32],
    decay: &'a [f32],
    slope: &'a [f32],
    back_re: &'a mut [f32],
    inv_back_im: &'a mut [f32],
}

/// The glide's values shared by every mode (the extra decay per sample).
#[derive(Clone, Copy)]
struct Shared {
    ratio_sq: f32,
    ln_ratio: f32,
    extra: f32,
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn retune_avx2(g: &mut GlideSlots<'_>, k: KernelState<'_>, split: usize, v: Shared) {
    retune_slots::<true>(g, k, split, v)
}

/// The two halves (direct, mirrored): the kernel angle is `w` or `pi - w`.
#[inline(always)]
fn retune_slots<const FMA: bool>(
    g: &mut GlideSlots<'_>,
    k: KernelState<'_>,
    split: usize,
    v: Shared,
) {
    let used = k.y.len();
    let split = split.min(used);
    let KernelState { y, dy, kappa, c2 } = k;
    let (y_lo, y_hi) = y.split_at(split);
    let (dy_lo, dy_hi) = dy.split_at_mut(split);
    let (kappa_lo, kappa_hi) = kappa.split_at_mut(split);
    let (c2_lo, c2_hi) = c2.split_at_mut(split);
    let (br_lo, br_hi) = g.back_re.split_at_mut(split);
    let (ib_lo, ib_hi) = g.inv_back_im.split_at_mut(split);
    let refs = |from: usize, to: usize| {
        let r = from..to;
        (&g.wn2[r.clone()], &g.decay[r.clone()], &g.slope[r])
    };
    let (wn2, decay, slope) = refs(0, split);
    let lo = Half {
        wn2,
        decay,
        slope,
        y: y_lo,
        dy: dy_lo,
        kappa: kappa_lo,
        c2: c2_lo,
        back_re: br_lo,
        inv_back_im: ib_lo,
    };
    retune_half::<FMA>(lo, 0.0, 0.5, v);
    let (wn2, decay, slope) = refs(split, used);
    let hi = Half {
        wn2,
        decay,
        slope,
        y: y_hi,
        dy: dy_hi,
        kappa: kappa_hi,
        c2: c2_hi,
        back_re: br_hi,
        inv_back_im: ib_hi,
    };
    retune_half::<FMA>(hi, std::f32::consts::FRAC_PI_2, -0.5, v);
}

/// One kernel half's arrays, all of one length.
struct Half<'a> {
    wn2: &'a [f32],
    decay: &'a [f32],
    slope: &'a [f32],
    y: &'a [f32],
    dy: &'a mut [f32],
    kappa: &'a mut [f32],
    c2: &'a mut [f32],
    back_re: &'a mut [f32],
    inv_back_im: &'a mut [f32],
}

/// Every slot of one half: kernel half-angle `base + sign w` (`w / 2`, or `pi/2 - w / 2`
/// mirrored). A straight loop the compiler vectorises (the lengths are checked once, up
/// front).
#[inline(always)]
fn retune_half<const FMA: bool>(h: Half<'_>, base: f32, sign: f32, v: Shared) {
    let n = h.y.len();
    assert!(
        h.wn2.len() == n
            && h.decay.len() == n
            && h.slope.len() == n
            && h.dy.len() == n
            && h.kappa.len() == n
            && h.c2.len() == n
            && h.back_re.len() == n
            && h.inv_back_im.len() == n
    );
    for j in 0..n {
        // The law's decay at this ratio, the damped angle, the kernel's half angle.
        let x = h.slope[j] * v.ln_ratio;
        let factor = mul_add::<FMA, _>(
            x,
            mul_add::<FMA, _>(x, mul_add::<FMA, _>(x, 1.0 / 6.0, 0.5), 1.0),
            1.0,
        );
        let d = h.decay[j] * factor;
        let wd = mul_add::<FMA, _>(h.wn2[j], v.ratio_sq, -(d * d)).sqrt();
        let half = mul_add::<FMA, _>(sign, wd, base);
        let a = d + v.extra;
        // e^(+-a) - 1 = even +- odd, to a^7.
        let a2 = a * a;
        let even = a2 * mul_add::<FMA, _>(a2, mul_add::<FMA, _>(a2, 1.0 / 720.0, 1.0 / 24.0), 0.5);
        let odd_series = mul_add::<FMA, _>(
            a2,
            mul_add::<FMA, _>(a2, 1.0 / 5040.0, 1.0 / 120.0),
            1.0 / 6.0,
        );
        let odd = a * mul_add::<FMA, _>(a2, odd_series, 1.0);
        let (em, ep) = (even - odd, even + odd);
        // sin, cos of the half angle (<= 0.3 pi), to its 9th and 10th powers (the first
        // terms left out are below 1.4e-8 and 1e-9).
        let h2 = half * half;
        let sin_series = mul_add::<FMA, _>(h2, 1.0 / 362_880.0, -1.0 / 5040.0);
        let sin_series = mul_add::<FMA, _>(
            h2,
            mul_add::<FMA, _>(h2, sin_series, 1.0 / 120.0),
            -1.0 / 6.0,
        );
        let s = half * mul_add::<FMA, _>(h2, sin_series, 1.0);
        let cos_series = mul_add::<FMA, _>(h2, -1.0 / 3_628_800.0, 1.0 / 40_320.0);
        let cos_series = mul_add::<FMA, _>(
            h2,
            mul_add::<FMA, _>(h2, cos_series, -1.0 / 720.0),
            1.0 / 24.0,
        );
        let c = mul_add::<FMA, _>(h2, mul_add::<FMA, _>(h2, cos_series, -0.5), 1.0);
        let s2 = s * s;
        let r = 1.0 + em;
        h.kappa[j] = mul_add::<FMA, _>(em, em, 4.0 * r * s2);
        h.c2[j] = mul_add::<FMA, _>(em, 2.0 + em, 1.0);
        let e = 1.0 + ep;
        let back_re = mul_add::<FMA, _>(2.0 * s2, e, -ep);
        let back_im = 2.0 * e * s * c;
        // The amplitude's real part under the old constants; the state under the new.
        let y = h.y[j];
        let re = (h.dy[j] - y * h.back_re[j]) * h.inv_back_im[j];
        h.dy[j] = mul_add::<FMA, _>(re, back_im, y * back_re);
        h.back_re[j] = back_re;
        h.inv_back_im[j] = 1.0 / back_im;
    }
}

#[cfg(test)]
mod tests;
