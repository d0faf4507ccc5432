//! What every eigen-solution must satisfy, recomputed from the returned vectors alone with
//! the plain sparse kernels (not the solvers' operators): shared by the eigensolver tests.

use modalforge::eigen::{EigenOptions, EigenSolution, ModeCount};
use modalforge::fem::sparse::{self, RowBlock};
use modalforge::fem::FemModel;

/// The residual tolerance the eigensolver tests ask for.
pub const TOL: f64 = 1e-9;

/// Options for `count` modes at [`TOL`].
pub fn options(count: ModeCount) -> EigenOptions {
    EigenOptions {
        count,
        tolerance: TOL,
        ..Default::default()
    }
}

/// Recomputes `max_j ||K v - lambda M v|| / ((||K|| + lambda ||M||) ||v||)` and
/// `max |V^T M V - I|` from the returned vectors alone.
pub fn identities(model: &FemModel, sol: &EigenSolution) -> (f64, f64) {
    let n = model.dofs();
    let k_norm = sparse::norm_inf(&model.pattern, model.k());
    let m_norm = sparse::mass_norm_inf(&model.pattern, model.m());
    let cols = sol.vectors.ncols();
    let mut mv = Vec::with_capacity(cols);
    let mut worst_res = 0.0f64;
    for j in 0..cols {
        let v: Vec<f64> = (0..n).map(|i| sol.vectors[(i, j)]).collect();
        let (mut kv, mut m) = (vec![0.0; n], vec![0.0; n]);
        sparse::spmm(&model.pattern, model.k(), &v, &mut kv, RowBlock::dense(1));
        sparse::spmm_mass(&model.pattern, model.m(), &v, &mut m, RowBlock::dense(1));
        let l = sol.eigenvalues[j];
        let r = kv
            .iter()
            .zip(&m)
            .map(|(a, b)| (a - l * b).powi(2))
            .sum::<f64>()
            .sqrt();
        let vn = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        worst_res = worst_res.max(r / ((k_norm + l * m_norm) * vn));
        mv.push(m);
    }
    let mut worst_orth = 0.0f64;
    for a in 0..cols {
        for (b, mb) in mv.iter().enumerate() {
            let dot: f64 = (0..n).map(|i| sol.vectors[(i, a)] * mb[i]).sum();
            let want = if a == b { 1.0 } else { 0.0 };
            worst_orth = worst_orth.max((dot - want).abs());
        }
    }
    (worst_res, worst_orth)
}
