//! Offline rendering: one performance (a strike, or a scrape) through either bank, in blocks.
//!
//! Where it sits: used by the CLI (`modalforge render`) and by tests; the real-time engine drives
//! the banks itself. Output streams to a caller's sink block by block, so any length renders in
//! constant memory.

use super::{BiquadBank, Excitation, ForcePulse, NoiseForce, OscillatorBank, StrikeError};
use crate::modes::PlayableModes;

/// Samples per block handed to the sink.
pub const RENDER_BLOCK: usize = 1024;

/// Which bank plays the modes (command-line names from the `clap::ValueEnum` derive;
/// `Display` prints the same name).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum BankKind {
    /// Damped oscillators (strikes only; exact and fastest).
    Oscillator,
    /// Biquad resonators driven by a force signal (strikes, scrapes).
    Biquad,
}

impl std::fmt::Display for BankKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        crate::cli_name(self, f)
    }
}

/// What happens to the object.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Performance {
    /// One strike at t = 0.
    Strike {
        /// Force shape.
        excitation: Excitation,
        /// Force multiplier (1 = the modes' own gains).
        velocity: f64,
    },
    /// Scraping: low-passed noise force for `seconds`, then the object rings out.
    Scrape {
        /// How long the scrape lasts.
        seconds: f64,
        /// Noise force level (RMS).
        level: f64,
        /// Low-pass corner of the noise in Hz (rougher surface = higher).
        cutoff_hz: f64,
    },
}

/// What stops a render.
#[derive(Debug, thiserror::Error)]
pub enum RenderError<E: std::error::Error + 'static> {
    /// The strike parameters are invalid.
    #[error(transparent)]
    Strike(#[from] StrikeError),
    /// The oscillator bank cannot be driven by a continuous force.
    #[error(
        "scraping needs the biquad bank (--bank biquad): the oscillator bank only plays strikes"
    )]
    ScrapeNeedsBiquad,
    /// The sink failed (e.g. writing the file).
    #[error(transparent)]
    Sink(E),
}

/// Renders `n_samples` of `performance` on `modes` through `bank`, fading out linearly over the
/// last `fade_out_samples`, and hands the audio to `sink` in blocks of [`RENDER_BLOCK`].
pub fn render<E: std::error::Error + 'static>(
    modes: &PlayableModes,
    bank: BankKind,
    performance: Performance,
    n_samples: usize,
    fade_out_samples: usize,
    mut sink: impl FnMut(&[f32]) -> Result<(), E>,
) -> Result<(), RenderError<E>> {
    let fs = modes.sample_rate_hz();
    let mut block = vec![0f32; RENDER_BLOCK];
    let mut force = vec![0f32; RENDER_BLOCK];
    let fade_start = n_samples.saturating_sub(fade_out_samples);
    let fade = |block: &mut [f32], start: usize| {
        for (k, y) in block.iter_mut().enumerate() {
            let n = start + k;
            if n >= fade_start {
                *y *= (n_samples - n) as f32 / (fade_out_samples as f32 + 1.0);
            }
        }
    };
    match (bank, performance) {
        (BankKind::Oscillator, Performance::Scrape { .. }) => {
            return Err(RenderError::ScrapeNeedsBiquad)
        }
        (
            BankKind::Oscillator,
            Performance::Strike {
                excitation,
                velocity,
            },
        ) => {
            let mut osc = OscillatorBank::new(modes);
            osc.strike(excitation, velocity)?;
            for start in (0..n_samples).step_by(RENDER_BLOCK) {
                let b = &mut block[..RENDER_BLOCK.min(n_samples - start)];
                osc.render(b);
                fade(b, start);
                sink(b).map_err(RenderError::Sink)?;
            }
        }
        (BankKind::Biquad, performance) => {
            let mut bank = BiquadBank::from_modes(modes);
            let mut pulse = None;
            let mut noise = None;
            let mut noise_samples = 0usize;
            match performance {
                Performance::Strike {
                    excitation,
                    velocity,
                } => {
                    super::oscillator::check_velocity(velocity).map_err(StrikeError::from)?;
                    pulse = Some(ForcePulse::new(excitation, velocity, fs));
                }
                Performance::Scrape {
                    seconds,
                    level,
                    cutoff_hz,
                } => {
                    noise = Some(NoiseForce::new(level as f32, cutoff_hz, fs, 0x5EED));
                    noise_samples = (seconds * fs) as usize;
                }
            }
            for start in (0..n_samples).step_by(RENDER_BLOCK) {
                let len = RENDER_BLOCK.min(n_samples - start);
                let f = &mut force[..len];
                f.fill(0.0);
                if let Some(p) = pulse.as_mut() {
                    p.add_to(f);
                }
                if let Some(nz) = noise.as_mut() {
                    let active = noise_samples.saturating_sub(start).min(len);
                    nz.add_to(&mut f[..active]);
                }
                let b = &mut block[..len];
                bank.process(f, b);
                fade(b, start);
                sink(b).map_err(RenderError::Sink)?;
            }
        }
    }
    Ok(())
}
