//! The built-in demo object: a free-free steel bar, struck near one end, from beam theory.
//!
//! Where it sits: a mode source for `modalforge render` without `--modes`, until voxel shapes and
//! the FEM solver exist. Euler-Bernoulli theory for a free-free beam (e.g. Blevins, *Formulas for
//! Natural Frequency and Mode Shape*, table 8-1): `f_n = (beta_n L)^2 / (2 pi L^2) sqrt(E I / (rho A))`,
//! mode shape `phi_n(x) = cosh(bx) + cos(bx) - s_n (sinh(bx) + sin(bx))` with
//! `s_n = (cosh(bL) - cos(bL)) / (sinh(bL) - sin(bL))`, normalised so `integral phi^2 dx = L`.
//!
//! A unit impulse at `x_hit` gives mode `n` the displacement amplitude `phi_n(x_hit) / (m w_n)`
//! with modal mass `m = rho A L`; the radiated pressure follows surface acceleration, `w_n^2` times
//! that, so the gain is `phi_n(x_hit) w_n / m`, normalised to a loudest mode of 1. Damping is
//! Rayleigh, `decay = (alpha + beta w^2) / 2` (Deep-Modal eq. 4), with illustrative steel-like
//! coefficients; measured materials arrive with the FEM issue.

use crate::modes::ModeSet;
use std::f64::consts::{PI, TAU};

/// Bar length in metres.
pub const BAR_LENGTH_M: f64 = 0.32;
/// Side of the square cross-section in metres.
pub const BAR_SIDE_M: f64 = 0.02;
/// Young's modulus of steel in Pa.
pub const STEEL_E_PA: f64 = 200e9;
/// Density of steel in kg/m^3.
pub const STEEL_RHO_KG_M3: f64 = 7850.0;
/// Rayleigh mass-proportional damping in 1/s.
pub const RAYLEIGH_ALPHA_PER_S: f64 = 1.0;
/// Rayleigh stiffness-proportional damping in s.
pub const RAYLEIGH_BETA_S: f64 = 2e-8;
/// Where the demo bar is struck, as a fraction of its length.
pub const HIT_FRACTION: f64 = 0.11;

/// Roots of `cos(x) cosh(x) = 1`, the free-free beam's `beta_n L` (n = 1..).
pub fn free_free_roots(count: usize) -> Vec<f64> {
    (1..=count)
        .map(|n| {
            // Start from the asymptote (2n + 1) pi / 2 and polish with Newton on
            // g(x) = cos x - 1/cosh x (same roots, well scaled).
            let mut x = (2 * n + 1) as f64 * PI / 2.0;
            for _ in 0..50 {
                let g = x.cos() - 1.0 / x.cosh();
                let dg = -x.sin() + x.tanh() / x.cosh();
                let step = g / dg;
                x -= step;
                if step.abs() < 1e-15 * x {
                    break;
                }
            }
            x
        })
        .collect()
}

/// Bending modes (one plane) of a free-free bar of square section below `max_freq_hz`, struck at
/// `hit_fraction` of its length.
pub fn free_free_bar(
    length_m: f64,
    side_m: f64,
    e_pa: f64,
    rho_kg_m3: f64,
    hit_fraction: f64,
    max_freq_hz: f64,
) -> ModeSet {
    let area = side_m * side_m;
    let inertia = side_m.powi(4) / 12.0;
    let c = (e_pa * inertia / (rho_kg_m3 * area)).sqrt();
    let mass = rho_kg_m3 * area * length_m;
    let (mut f, mut d, mut g) = (vec![], vec![], vec![]);
    for bl in free_free_roots(40) {
        let freq = bl * bl / (TAU * length_m * length_m) * c;
        if freq > max_freq_hz {
            break;
        }
        let b = bl / length_m;
        let x = hit_fraction * length_m;
        // For large bL, cosh and sinh overflow together; use the scaled form e^(-bx) terms.
        let s = (bl.cosh() - bl.cos()) / (bl.sinh() - bl.sin());
        let phi = (b * x).cosh() + (b * x).cos() - s * ((b * x).sinh() + (b * x).sin());
        let w = TAU * freq;
        f.push(freq);
        d.push(0.5 * (RAYLEIGH_ALPHA_PER_S + RAYLEIGH_BETA_S * w * w));
        g.push(phi * w / mass);
    }
    let loudest = g.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let g = g.into_iter().map(|x| x / loudest).collect();
    ModeSet::new(f, d, g).expect("beam theory gives finite, non-negative modes")
}

/// The demo: the steel bar of [`BAR_LENGTH_M`] x [`BAR_SIDE_M`]^2, modes below 20 kHz.
pub fn steel_bar() -> ModeSet {
    free_free_bar(
        BAR_LENGTH_M,
        BAR_SIDE_M,
        STEEL_E_PA,
        STEEL_RHO_KG_M3,
        HIT_FRACTION,
        20_000.0,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roots_match_the_published_values() {
        // Blevins table 8-1: 4.73004074, 7.85320462, 10.9956078, 14.1371655, 17.2787597.
        let r = free_free_roots(5);
        for (got, want) in r
            .iter()
            .zip([4.73004074, 7.85320462, 10.9956078, 14.1371655, 17.2787597])
        {
            assert!((got - want).abs() < 1e-7, "{got} vs {want}");
        }
    }

    #[test]
    fn steel_bar_fundamental() {
        // f1 = 4.73004^2 / (2 pi 0.32^2) * sqrt(200e9 * (0.02^2/12) / 7850) = 1012.6 Hz.
        let m = steel_bar();
        let want = 4.730_040_74f64.powi(2) / (TAU * 0.1024)
            * (200e9 * 0.02f64.powi(2) / 12.0 / 7850.0).sqrt();
        assert!((m.freq_hz()[0] - want).abs() < 1e-8 * want); // the root is quoted to 9 digits
        assert!((1000.0..1025.0).contains(&m.freq_hz()[0]));
        assert!(m.len() >= 5 && m.freq_hz().iter().all(|&f| f < 20_000.0));
        assert!(m.gain().iter().all(|g| g.is_finite() && g.abs() <= 1.0));
    }
}
