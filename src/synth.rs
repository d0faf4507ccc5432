//! Real-time modal synthesis: the banks that turn modes into sound, and their excitations.
//!
//! Where it sits: after [`crate::modes`] (which culls a [`ModeSet`](crate::modes::ModeSet) into
//! [`PlayableModes`](crate::modes::PlayableModes)); before the audio output: the WAV writer of
//! the CLI, and the real-time engine ([`crate::engine`]) that the plugin and the app run.
//!
//! - [`OscillatorBank`]: modes as free damped sines, struck; the fast path (f32, SIMD, exact
//!   re-anchoring every 64 samples so it never drifts).
//! - [`BiquadBank`]: modes as resonant filters (parallel x cascade), driven by any force signal:
//!   strikes, scraping, rolling.
//! - [`excitation`]: impulse, mallet contact pulse, noise.
//! - [`render`]: offline rendering of one strike through either bank, in blocks.
//! - [`simd`]: the lane abstraction and run-time CPU dispatch shared by both banks.
//!
//! Every bank follows one lifecycle: construction allocates; `strike`, `render`/`process` and
//! `reset` never allocate, lock, block or log, so they may run on an audio thread.

pub mod biquad;
pub mod excitation;
pub mod oscillator;
pub mod render;
pub mod simd;

pub use biquad::{BiquadBank, BiquadCoeffs, BiquadError};
pub use excitation::{Excitation, ExcitationError, ForcePulse, NoiseForce};
pub use oscillator::{
    GlideError, OscillatorBank, RetuneError, StrikeError, Tuning, GLIDE_MAX_LN_RATIO,
};
pub use simd::SimdBackend;

/// Helpers shared by the banks' unit tests.
#[cfg(test)]
pub(crate) mod test_support {
    use crate::modes::{CullSettings, ModeSet, PlayableModes};

    /// Playable modes from parallel arrays, with no gain culling.
    pub fn modes(f: &[f64], d: &[f64], g: &[f64], fs: f64) -> PlayableModes {
        let set = ModeSet::new(f.to_vec(), d.to_vec(), g.to_vec()).unwrap();
        set.playable(
            fs,
            &CullSettings {
                min_relative_gain: 0.0,
            },
        )
        .unwrap()
        .0
    }
}
