//! The smooth-geometry references of the curved primitives (`tests/data/smooth_references.json`,
//! made by `scripts/smooth_reference.py`: gmsh + scikit-fem curved quadratic tetrahedra,
//! converged by refinement) and the measures the partial-voxel test and bench take against
//! them. Eigenvalues are in reference units (E = rho = 1, lengths in voxels), nu = 0.2.
#![allow(dead_code)]

use serde_json::Value;

/// Poisson's ratio the references were solved for (glass).
pub const NU: f64 = 0.2;

/// The stored references, by shape spec.
pub fn all() -> Value {
    serde_json::from_str(include_str!("../data/smooth_references.json")).expect("parse")
}

/// The shapes that have a reference.
pub fn specs() -> Vec<String> {
    all().as_object().expect("object").keys().cloned().collect()
}

/// The finest level of the reference of `spec`: non-rigid eigenvalues, ascending.
pub fn reference(spec: &str) -> Vec<f64> {
    let all = all();
    let levels = all[spec]["levels"].as_array().expect("levels");
    levels.last().expect("a level")["eigenvalues"]
        .as_array()
        .expect("eigenvalues")
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect()
}

/// Relative frequency errors (percent) of the lowest `k` eigenvalues, matched in order.
pub fn frequency_errors(got: &[f64], want: &[f64], k: usize) -> Vec<f64> {
    got.iter()
        .zip(want)
        .take(k)
        .map(|(g, w)| 100.0 * ((g / w).sqrt() - 1.0))
        .collect()
}

/// Largest absolute value.
pub fn worst(errors: &[f64]) -> f64 {
    errors.iter().fold(0.0, |m: f64, v| m.max(v.abs()))
}

/// The degenerate groups of the smooth reference among its lowest `k` modes (consecutive
/// eigenvalues within 0.1 %: exact multiplicities of the axisymmetric solid, split only by its
/// tetrahedral mesh), and the largest frequency split (percent) of the same positions in
/// `got`: `(split, groups)`.
pub fn worst_split(got: &[f64], want: &[f64], k: usize) -> (f64, usize) {
    let k = k.min(want.len()).min(got.len());
    let mut worst = 0.0f64;
    let mut groups = 0;
    let mut start = 0;
    for i in 1..=k {
        if i == k || want[i] > want[start] * 1.001 {
            if i - start > 1 {
                groups += 1;
                let lo = got[start..i].iter().copied().fold(f64::INFINITY, f64::min);
                let hi = got[start..i].iter().copied().fold(0.0, f64::max);
                worst = worst.max(100.0 * ((hi / lo).sqrt() - 1.0));
            }
            start = i;
        }
    }
    (worst, groups)
}
