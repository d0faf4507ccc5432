//! Proportional damping models (Sterling and Lin 2016, sec. 3).
//!
//! Every model here is *generalized proportional damping*: the damping matrix is diagonalised by
//! the undamped modes, so each mode's viscous coefficient is a function of its own eigenvalue
//! `lambda = omega_n^2` (Sterling and Lin 2016, eq. 14, `c_i = beta(omega_n^2)`). The mode then
//! rings as `a e^(-d t) cos(omega_d t)` with `d = c / 2` (eq. 10) and `omega_d = sqrt(omega_n^2 -
//! d^2)` (eq. 11); a mode with `d >= omega_n` does not oscillate (overdamped) and is never played.

use std::sync::Arc;

/// The named damping laws a material preset or a fit to a recording can hold. Their names
/// (`rayleigh`, `caughey`, `power_law`) in presets, on the command line and in JSON all come
/// from the variant names by one rule (snake case); `Display` prints the same.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, clap::ValueEnum, serde::Serialize)]
#[value(rename_all = "snake_case")]
#[serde(rename_all = "snake_case")]
pub enum DampingLaw {
    /// `c = alpha1 + alpha2 omega^2`.
    Rayleigh,
    /// `c = sum_j eta_j omega^(2j)`.
    Caughey,
    /// `c = mu1 omega^(2 mu2)`.
    PowerLaw,
}

impl std::fmt::Display for DampingLaw {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        crate::cli_name(self, f)
    }
}

/// A damping model: the map from a mode's eigenvalue to its viscous coefficient `c`.
#[derive(Clone)]
pub enum Damping {
    /// Rayleigh damping `C = alpha1 M + alpha2 K`: `c = alpha1 + alpha2 omega^2` (Sterling and Lin
    /// 2016, eq. 6, 12).
    Rayleigh {
        /// Mass-proportional term, 1/s.
        alpha1: f64,
        /// Stiffness-proportional term, s.
        alpha2: f64,
    },
    /// Caughey series `c = sum_j eta_j omega^(2j)`, `j = 0..n` (Sterling and Lin 2016, eq. 7, 13),
    /// any order.
    Caughey {
        /// `eta_0, eta_1, ...`; `eta_j` has units s^(2j-1).
        eta: Vec<f64>,
    },
    /// Power law `c = mu1 omega^(2 mu2)` (Sterling and Lin 2016, eq. 16).
    PowerLaw {
        /// Coefficient.
        mu1: f64,
        /// Exponent on `omega^2`.
        mu2: f64,
    },
    /// Any function of the eigenvalue `omega^2` (rad^2/s^2), returning `c` in 1/s (eq. 14).
    Custom(Arc<dyn Fn(f64) -> f64 + Send + Sync>),
}

impl std::fmt::Debug for Damping {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Damping::Rayleigh { alpha1, alpha2 } => write!(f, "Rayleigh({alpha1}, {alpha2})"),
            Damping::Caughey { eta } => write!(f, "Caughey({eta:?})"),
            Damping::PowerLaw { mu1, mu2 } => write!(f, "PowerLaw({mu1}, {mu2})"),
            Damping::Custom(_) => write!(f, "Custom(fn)"),
        }
    }
}

/// One mode after damping: what the synthesis banks need.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DampedMode {
    /// An oscillating mode.
    Oscillating {
        /// Damped frequency `omega_d / 2 pi`, Hz.
        freq_hz: f64,
        /// Amplitude decay rate `d = c / 2`, 1/s.
        decay_per_s: f64,
    },
    /// `d >= omega_n`: the mode creeps back without ringing; it makes no tone.
    Overdamped {
        /// Decay rate `d`, 1/s.
        decay_per_s: f64,
    },
}

impl Damping {
    /// Which named law this is (`None` for [`Damping::Custom`]).
    pub fn law(&self) -> Option<DampingLaw> {
        match self {
            Damping::Rayleigh { .. } => Some(DampingLaw::Rayleigh),
            Damping::Caughey { .. } => Some(DampingLaw::Caughey),
            Damping::PowerLaw { .. } => Some(DampingLaw::PowerLaw),
            Damping::Custom(_) => None,
        }
    }

    /// Viscous coefficient `c` (1/s) for a mode of eigenvalue `omega_n^2` (rad^2/s^2).
    pub fn coefficient(&self, omega_n_sq: f64) -> f64 {
        let w2 = omega_n_sq.max(0.0);
        match self {
            Damping::Rayleigh { alpha1, alpha2 } => alpha1 + alpha2 * w2,
            Damping::Caughey { eta } => eta.iter().rev().fold(0.0, |acc, &e| acc * w2 + e),
            Damping::PowerLaw { mu1, mu2 } => mu1 * w2.powf(*mu2),
            Damping::Custom(f) => f(w2),
        }
    }

    /// The damped mode of eigenvalue `omega_n^2` (Sterling and Lin 2016, eq. 10-11). A negative or
    /// non-finite coefficient (a Caughey series can go negative far outside its fitted band) is
    /// clamped to zero: a mode is never amplified.
    pub fn damp(&self, omega_n_sq: f64) -> DampedMode {
        let c = self.coefficient(omega_n_sq);
        let d = if c.is_finite() {
            (c / 2.0).max(0.0)
        } else {
            f64::INFINITY
        };
        let w2 = omega_n_sq.max(0.0);
        if d * d >= w2 {
            DampedMode::Overdamped { decay_per_s: d }
        } else {
            DampedMode::Oscillating {
                freq_hz: (w2 - d * d).sqrt() / std::f64::consts::TAU,
                decay_per_s: d,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    #[test]
    fn models_agree_where_they_coincide() {
        // Rayleigh = Caughey of order 2 = custom c(w2); power law with mu2 = 1 is the stiffness term.
        let w2 = (TAU * 1000.0f64).powi(2);
        let r = Damping::Rayleigh {
            alpha1: 3.0,
            alpha2: 2e-7,
        };
        let c = Damping::Caughey {
            eta: vec![3.0, 2e-7],
        };
        let g = Damping::Custom(Arc::new(|w2| 3.0 + 2e-7 * w2));
        let p = Damping::PowerLaw {
            mu1: 2e-7,
            mu2: 1.0,
        };
        let want = 3.0 + 2e-7 * w2;
        for m in [&r, &c, &g] {
            assert!((m.coefficient(w2) - want).abs() < 1e-12 * want);
        }
        assert!((p.coefficient(w2) - 2e-7 * w2).abs() < 1e-12 * want);
    }

    #[test]
    fn damped_frequency_and_overdamping() {
        // omega_n = 100 rad/s, c = 120 -> d = 60, omega_d = 80 (a 3-4-5 triangle).
        let m = Damping::Rayleigh {
            alpha1: 120.0,
            alpha2: 0.0,
        };
        match m.damp(1e4) {
            DampedMode::Oscillating {
                freq_hz,
                decay_per_s,
            } => {
                assert!((freq_hz - 80.0 / TAU).abs() < 1e-12);
                assert_eq!(decay_per_s, 60.0);
            }
            o => panic!("{o:?}"),
        }
        // c = 200 -> d = 100 = omega_n: critically damped, not played.
        let m = Damping::Rayleigh {
            alpha1: 200.0,
            alpha2: 0.0,
        };
        assert!(matches!(m.damp(1e4), DampedMode::Overdamped { .. }));
        // A negative Caughey tail is clamped, never amplifies.
        let m = Damping::Caughey {
            eta: vec![0.0, 0.0, -1.0],
        };
        assert!(
            matches!(m.damp(1e4), DampedMode::Oscillating { decay_per_s, .. } if decay_per_s == 0.0)
        );
    }
}
