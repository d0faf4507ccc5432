//! What a strike with the current voicing excites: one line per playable mode (frequency,
//! decay, level), for the editor's spectrum view.
//!
//! Where it sits: read by views (the plugin editor) off the audio thread, from the newest
//! solved object ([`super::EngineControl::latest_object`]) and the voicing the knobs describe.
//! It applies the same scaling laws and strike gains as [`super::AudioEngine`] (Jin et al. 2020,
//! eq. 7 and 12: `omega^2 = lambda E / (rho h^2)`, gain `phi(x) . d / (sqrt(rho h^3) omega_d)`
//! times the mallet's modal factor), so the lines are what the next velocity-1 strike at the
//! object's own size plays.

use super::object::ObjectModes;
use super::voicing::{tune, Voicing};
use crate::basis::HitError;
use crate::synth::excitation::Excitation;
use num_complex::Complex64;
use std::f64::consts::TAU;

/// One playable mode as struck.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpectrumLine {
    /// Index of the mode in the basis.
    pub index: usize,
    /// Damped frequency, Hz.
    pub freq_hz: f64,
    /// Amplitude decay rate, 1/s.
    pub decay_per_s: f64,
    /// Initial amplitude of the mode for a velocity-1 strike (output units before the engine's
    /// level normalisation).
    pub amplitude: f64,
}

impl SpectrumLine {
    /// Time for the mode to fall by 60 dB, s.
    pub fn t60_s(&self) -> f64 {
        3.0 * std::f64::consts::LN_10 / self.decay_per_s
    }
}

/// The playable modes of `basis` under `voicing` at the object's own size, struck at the
/// voicing's hit point with its mallet, in basis order.
pub fn spectrum(
    basis: &ObjectModes,
    voicing: &Voicing,
    sample_rate_hz: f64,
) -> Result<Vec<SpectrumLine>, HitError> {
    let dims = basis.grid_dims();
    let extent = dims.into_iter().max().unwrap_or(1);
    let hit = voicing.hit.reference_hit(dims);
    let mut forces = vec![0.0; basis.mode_count()];
    basis.reference_forces_into(&hit, 1.0, &mut forces)?;
    let excitation = if voicing.hardness_s > 0.0 {
        Excitation::mallet(voicing.hardness_s).unwrap_or(Excitation::Impulse)
    } else {
        Excitation::Impulse
    };
    let h = voicing.voxel_size_m(extent, 1.0);
    Ok(basis
        .eigenvalues()
        .iter()
        .zip(&forces)
        .enumerate()
        .filter_map(|(index, (&lambda, &force))| {
            let (freq_hz, decay_per_s) = tune(
                voicing,
                lambda,
                h,
                basis.decay_ratio(index),
                0.0,
                sample_rate_hz,
            )?;
            let gain = voicing.modal_gain(force, h, freq_hz);
            let factor = excitation.modal_factor(Complex64::new(-decay_per_s, TAU * freq_hz));
            let amplitude = (gain * factor.norm()).abs();
            amplitude.is_finite().then_some(SpectrumLine {
                index,
                freq_hz,
                decay_per_s,
                amplitude,
            })
        })
        .collect())
}
