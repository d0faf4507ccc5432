//! `a b + c`, fused only where the caller's kernel is compiled for FMA.
//!
//! Where it sits: under the kernels that are compiled twice, once inside a
//! `#[target_feature(enable = "avx2,fma")]` function and once portable, and pick one at run time
//! (the factor's triangular solves, `eigen/factor/rows.rs`; the cut elements' condensation,
//! `fem/cut.rs`; the oscillators' glides, `synth/oscillator/glide.rs`). In the FMA build
//! `mul_add` is one instruction; in the portable build it would be a call into libm's software
//! `fma`, many times slower, so that build multiplies and adds.

use std::ops::{Add, Mul};

/// Floats with a fused multiply-add.
pub(crate) trait MulAdd: Copy + Mul<Output = Self> + Add<Output = Self> {
    /// `self b + c` rounded once.
    fn fused(self, b: Self, c: Self) -> Self;
}

impl MulAdd for f64 {
    #[inline(always)]
    fn fused(self, b: Self, c: Self) -> Self {
        self.mul_add(b, c)
    }
}

impl MulAdd for f32 {
    #[inline(always)]
    fn fused(self, b: Self, c: Self) -> Self {
        self.mul_add(b, c)
    }
}

/// `a b + c`: fused where `FMA` (the caller runs inside an FMA-enabled kernel), else a multiply
/// and an add.
#[inline(always)]
pub(crate) fn mul_add<const FMA: bool, T: MulAdd>(a: T, b: T, c: T) -> T {
    if FMA {
        a.fused(b, c)
    } else {
        a * b + c
    }
}
