//! Damping laws fitted to a recording's modes (Sterling and Lin 2016, sec. 3-4).
//!
//! Where it sits: after [`super::extract`]. Each mode gives a point in eigenvalue-damping
//! space: its undamped eigenvalue `lambda = omega_d^2 + d^2` (eq. 11) and its viscous
//! coefficient `c = 2 d` (eq. 10). Three laws are fitted to those points, each by least squares
//! on the *relative* error (decay rates span orders of magnitude, and a law that is 10 % off
//! sounds equally wrong at 100 Hz and 10 kHz):
//! - Rayleigh, `c = alpha1 + alpha2 lambda` (eq. 12);
//! - the Caughey series of order 3, `c = eta0 + eta1 lambda + eta2 lambda^2` (eq. 13; its
//!   order 2 is Rayleigh);
//! - the power law, `c = mu1 lambda^mu2` (eq. 16), linear in logarithms.
//!
//! Each law's error is the RMS of `ln(c_law / c)` over the modes; the law chosen is the one with
//! the lowest Bayesian information criterion, `n ln(RSS / n) + k ln n` (`k` parameters), which
//! takes the Caughey series' third parameter only where it pays.

use crate::material::damping::{Damping, DampingLaw};
use faer::linalg::solvers::SolveLstsqCore;
use faer::{Conj, Mat};
use std::f64::consts::TAU;

/// Decay rates from a recording are not known better than this (relative): below it a law's
/// smaller residual is rounding, and the criterion must not reward a parameter for it.
const PRECISION: f64 = 1e-3;

/// One law's fit.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct LawFit {
    /// Which law.
    pub law: DampingLaw,
    /// Its parameters: `[alpha1, alpha2]`, `[eta0, eta1, eta2]` or `[mu1, mu2]` (SI units:
    /// `c` in 1/s, `lambda` in rad^2/s^2).
    pub parameters: Vec<f64>,
    /// RMS relative error of the decay rates it gives, `exp(rms |ln(c_law / c)|) - 1`.
    pub rms_relative_error: f64,
    /// Bayesian information criterion (lower is better).
    pub bic: f64,
}

impl LawFit {
    /// The fitted law as the engine's [`Damping`].
    pub fn damping(&self) -> Damping {
        let p = &self.parameters;
        match self.law {
            DampingLaw::Rayleigh => Damping::Rayleigh {
                alpha1: p[0],
                alpha2: p[1],
            },
            DampingLaw::Caughey => Damping::Caughey { eta: p.clone() },
            DampingLaw::PowerLaw => Damping::PowerLaw {
                mu1: p[0],
                mu2: p[1],
            },
        }
    }
}

/// Every law that could be fitted, and the one the criterion picks.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct DampingFits {
    /// The fits, Rayleigh, Caughey, power law (a law needs two more modes than parameters).
    pub laws: Vec<LawFit>,
    /// The chosen law, or `None` with fewer than four modes.
    pub best: Option<DampingLaw>,
}

/// Fits the three laws to modes given as `(damped frequency Hz, decay rate 1/s)`; modes with a
/// non-positive decay rate are left out.
pub fn fit(modes: &[(f64, f64)]) -> DampingFits {
    let points: Vec<(f64, f64)> = modes
        .iter()
        .filter(|(f, d)| *d > 0.0 && *f > 0.0 && d.is_finite() && f.is_finite())
        .map(|&(f, d)| ((TAU * f).powi(2) + d * d, 2.0 * d))
        .collect();
    let mut laws = Vec::new();
    // Polynomial laws in lambda / scale (conditioning), weighted by 1 / c (relative error).
    let scale = {
        let mut l: Vec<f64> = points.iter().map(|p| p.0).collect();
        l.sort_by(f64::total_cmp);
        l.get(l.len() / 2).copied().unwrap_or(1.0)
    };
    for (law, terms) in [(DampingLaw::Rayleigh, 2usize), (DampingLaw::Caughey, 3)] {
        if points.len() < terms + 2 {
            continue;
        }
        let a = Mat::<f64>::from_fn(points.len(), terms, |i, j| {
            (points[i].0 / scale).powi(j as i32) / points[i].1
        });
        let mut b = Mat::<f64>::from_fn(points.len(), 1, |_, _| 1.0);
        a.qr().solve_lstsq_in_place_with_conj(Conj::No, b.as_mut());
        let parameters: Vec<f64> = (0..terms)
            .map(|j| b[(j, 0)] / scale.powi(j as i32))
            .collect();
        let c = |l: f64| parameters.iter().rev().fold(0.0, |acc, &e| acc * l + e);
        laws.push(summarise(law, parameters.clone(), &points, c));
    }
    if points.len() >= 4 {
        let a = Mat::<f64>::from_fn(points.len(), 2, |i, j| {
            if j == 0 {
                1.0
            } else {
                (points[i].0 / scale).ln()
            }
        });
        let mut b = Mat::<f64>::from_fn(points.len(), 1, |i, _| points[i].1.ln());
        a.qr().solve_lstsq_in_place_with_conj(Conj::No, b.as_mut());
        let mu2 = b[(1, 0)];
        let mu1 = (b[(0, 0)] - mu2 * scale.ln()).exp();
        laws.push(summarise(
            DampingLaw::PowerLaw,
            vec![mu1, mu2],
            &points,
            |l| mu1 * l.powf(mu2),
        ));
    }
    let best = laws
        .iter()
        .filter(|l| l.bic.is_finite())
        .min_by(|a, b| a.bic.total_cmp(&b.bic))
        .map(|l| l.law);
    DampingFits { laws, best }
}

/// A law's error and criterion over the points `(lambda, c)`.
fn summarise(
    law: DampingLaw,
    parameters: Vec<f64>,
    points: &[(f64, f64)],
    c: impl Fn(f64) -> f64,
) -> LawFit {
    let n = points.len() as f64;
    // A law that gives a non-positive coefficient at a mode is infinitely wrong there in log
    // terms; count it as a factor of 10 off (it would play that mode undamped or overdamped).
    let rss: f64 = points
        .iter()
        .map(|&(l, ci)| {
            let model = c(l);
            if model > 0.0 && model.is_finite() {
                (model / ci).ln().powi(2)
            } else {
                10f64.ln().powi(2)
            }
        })
        .sum();
    let k = parameters.len() as f64;
    LawFit {
        law,
        parameters,
        rms_relative_error: (rss / n).sqrt().exp() - 1.0,
        bic: n * (rss / n).max(PRECISION * PRECISION).ln() + k * n.ln(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Modes damped by a known law with 3 % multiplicative noise on the decay rates, 30 modes
    /// from 100 Hz to 15 kHz: the criterion picks that law, and its parameters come back to
    /// the noise over sqrt(n) (bound 5 %; the exponent of the power law to 0.01).
    #[test]
    fn recovers_the_law_that_made_the_modes() {
        let laws = [
            (
                DampingLaw::Rayleigh,
                Damping::Rayleigh {
                    alpha1: 4.0,
                    alpha2: 2e-8,
                },
            ),
            (
                DampingLaw::PowerLaw,
                Damping::PowerLaw {
                    mu1: 0.05,
                    mu2: 0.4,
                },
            ),
            (
                DampingLaw::Caughey,
                Damping::Caughey {
                    eta: vec![30.0, -1e-7, 2e-16],
                },
            ),
        ];
        for (name, law) in laws {
            let mut rng = crate::rng::SplitMix64::new(7);
            let modes: Vec<(f64, f64)> = (0..30)
                .map(|i| {
                    let noise = 1.0 + 0.03 * rng.range(-1.0, 1.0);
                    let f = 100.0 * 150f64.powf(i as f64 / 29.0);
                    let lambda = (TAU * f).powi(2);
                    (f, 0.5 * law.coefficient(lambda) * noise)
                })
                .collect();
            let fits = fit(&modes);
            assert_eq!(fits.best, Some(name), "{fits:?}");
            let got = fits.laws.iter().find(|l| l.law == name).unwrap();
            assert!(got.rms_relative_error < 0.03, "{got:?}");
            let want: Vec<f64> = match law {
                Damping::Rayleigh { alpha1, alpha2 } => vec![alpha1, alpha2],
                Damping::PowerLaw { mu1, mu2 } => vec![mu1, mu2],
                Damping::Caughey { ref eta } => eta.clone(),
                Damping::Custom(_) => unreachable!(),
            };
            // Each law's coefficient at the modes, not its raw parameters (the Caughey terms
            // trade off against each other), within 5 %.
            for &(f, _) in &modes {
                let l = (TAU * f).powi(2);
                let (a, b) = (got.damping().coefficient(l), law.coefficient(l));
                assert!(
                    (a / b - 1.0).abs() < 0.05,
                    "{name} at {f} Hz: {a} vs {b} ({want:?})"
                );
            }
        }
    }

    #[test]
    fn too_few_modes_fit_nothing() {
        let fits = fit(&[(100.0, 1.0), (200.0, 2.0), (300.0, 0.0)]);
        assert!(fits.laws.is_empty() && fits.best.is_none());
    }
}
