//! The oscillator bank's exact state: each mode's complex amplitude at the last anchor, in f64.
//!
//! Every [`ANCHOR_SAMPLES`](super::ANCHOR_SAMPLES) samples, `z <- z * e^(lambda * 64 / fs)` (exact
//! to f64 rounding, so 10 minutes of ringing drift by ~1e-12) and the f32 kernel state restarts from
//! it: `y = Im z`, `dy = Im(z * back)`. Arrays are structure-of-arrays by kernel slot, so the
//! update is a straight loop the compiler vectorises (AVX2 inside the `target_feature` wrapper).

use crate::synth::simd::SimdBackend;
use num_complex::Complex64;

/// Complex amplitudes below this magnitude become exactly zero at an anchor, so a decayed mode
/// never reaches f32 denormals (1.2e-38) and stays silent at no cost.
pub(crate) const SILENCE_FLOOR: f64 = 1e-30;

/// Exact per-slot state and constants (padded slots are all zero and stay zero).
pub(crate) struct Anchors {
    pub z_re: Vec<f64>,
    pub z_im: Vec<f64>,
    pub step_re: Vec<f64>,
    pub step_im: Vec<f64>,
    pub back_re: Vec<f64>,
    pub back_im: Vec<f64>,
}

impl Anchors {
    /// Zeroed state for `slots` slots.
    pub fn new(slots: usize) -> Self {
        let zero = || vec![0.0; slots];
        Self {
            z_re: zero(),
            z_im: zero(),
            step_re: zero(),
            step_im: zero(),
            back_re: zero(),
            back_im: zero(),
        }
    }

    /// The kernel's second state variable for slot `k` holding amplitude `c`: `Im(c * back)`.
    pub fn second_state(&self, k: usize, c: Complex64) -> f64 {
        c.re * self.back_im[k] + c.im * self.back_re[k]
    }

    /// Advances the first `y.len()` slots one anchor interval and writes the f32 kernel state.
    pub fn advance(&mut self, backend: SimdBackend, y: &mut [f32], dy: &mut [f32]) {
        #[cfg(target_arch = "x86_64")]
        if backend == SimdBackend::Avx2Fma && SimdBackend::Avx2Fma.is_available() {
            // SAFETY: AVX2 and FMA are present (checked just above).
            return unsafe { advance_avx2(self, y, dy) };
        }
        let _ = backend;
        advance_plain(self, y, dy)
    }

    /// Moves slot `from`'s state and constants to slot `to`.
    pub fn move_slot(&mut self, from: usize, to: usize) {
        for v in self.all() {
            v[to] = v[from];
        }
    }

    /// Silences slots `range` and zeroes their constants.
    pub fn clear(&mut self, range: std::ops::Range<usize>) {
        for v in self.all() {
            v[range.clone()].fill(0.0);
        }
    }

    fn all(&mut self) -> [&mut Vec<f64>; 6] {
        [
            &mut self.z_re,
            &mut self.z_im,
            &mut self.step_re,
            &mut self.step_im,
            &mut self.back_re,
            &mut self.back_im,
        ]
    }

    /// Silences every slot.
    pub fn reset(&mut self) {
        self.z_re.fill(0.0);
        self.z_im.fill(0.0);
    }

    /// Silences the first `slots` slots and zeroes their constants (before a new layout is
    /// written).
    pub fn clear_first(&mut self, slots: usize) {
        self.clear(0..slots);
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn advance_avx2(a: &mut Anchors, y: &mut [f32], dy: &mut [f32]) {
    advance_plain(a, y, dy)
}

#[inline(always)]
fn advance_plain(a: &mut Anchors, y: &mut [f32], dy: &mut [f32]) {
    // The slots in use: `y` is cut to them.
    let n = y.len();
    let (zr, zi) = (&mut a.z_re[..n], &mut a.z_im[..n]);
    let (sr, si, br, bi) = (
        &a.step_re[..n],
        &a.step_im[..n],
        &a.back_re[..n],
        &a.back_im[..n],
    );
    let (y, dy) = (&mut y[..n], &mut dy[..n]);
    let floor2 = SILENCE_FLOOR * SILENCE_FLOOR;
    for k in 0..n {
        let re = zr[k] * sr[k] - zi[k] * si[k];
        let im = zr[k] * si[k] + zi[k] * sr[k];
        let loud = re * re + im * im >= floor2;
        let (re, im) = if loud { (re, im) } else { (0.0, 0.0) };
        zr[k] = re;
        zi[k] = im;
        y[k] = im as f32;
        dy[k] = (re * bi[k] + im * br[k]) as f32;
    }
}
