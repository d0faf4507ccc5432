//! LOBPCG's starting block: the six rigid-body fields, the coarsest multigrid level's modes
//! interpolated to the fine grid, and a few random columns (the module docs of [`super`]).
//!
//! Where it sits: [`super::solve_until`] builds its block here once the multigrid hierarchy
//! is set up; the rigid fields also start the warm starts and the carried answer
//! ([`crate::eigen::warm`]).

use super::{guard, COARSE_TOLERANCE};
use crate::buffer::zeroed;
use crate::eigen::multigrid::Multigrid;
use crate::eigen::{
    lanczos, random_block, to_rows, EigenError, EigenOptions, ModeCount, Operators,
};
use crate::fem::FemModel;

/// The six rigid-body fields (translations, rotations about the centroid), row-major `n x 6`.
pub(crate) fn rigid_fields(model: &FemModel) -> Vec<f64> {
    let nodes = model.nodes();
    let centre = rigid_centre(model);
    let mut out = vec![0.0; 3 * nodes * 6];
    for i in 0..nodes {
        let p = model.node_position(i);
        for c in 0..3 {
            let row = (3 * i + c) * 6;
            out[row..row + 6].copy_from_slice(&rigid_row(p, centre, c));
        }
    }
    out
}

/// The centroid of `model`'s nodes, about which [`rigid_fields`] rotates.
pub(crate) fn rigid_centre(model: &FemModel) -> [f64; 3] {
    let nodes = model.nodes();
    let mut centre = [0.0; 3];
    for i in 0..nodes {
        let p = model.node_position(i);
        (0..3).for_each(|a| centre[a] += p[a] / nodes as f64);
    }
    centre
}

/// The six rigid fields' component `c` at a node at `p` ([`rigid_fields`]' row for that DOF).
pub(crate) fn rigid_row(p: [f64; 3], centre: [f64; 3], c: usize) -> [f64; 6] {
    let r = [0, 1, 2].map(|a| p[a] - centre[a]);
    let mut row = [0.0; 6];
    row[c] = 1.0;
    // Rotation about axis q: (e_q x r)_c.
    for q in 0..3 {
        let e = [0, 1, 2].map(|a| if a == q { 1.0 } else { 0.0 });
        let cross = [
            e[1] * r[2] - e[2] * r[1],
            e[2] * r[0] - e[0] * r[2],
            e[0] * r[1] - e[1] * r[0],
        ];
        row[3 + q] = cross[c];
    }
    row
}

/// The starting block: how many columns must converge and the block itself (`n x m`).
pub(super) struct Start {
    pub(super) need: usize,
    pub(super) m: usize,
    pub(super) block: Vec<f64>,
}

/// Builds the nested start from the coarsest level (see the module docs).
pub(super) fn nested_start(
    model: &FemModel,
    mg: &mut Multigrid,
    options: &EigenOptions,
) -> Result<Start, EigenError> {
    let n = model.dofs();
    let tau = mg.tau();
    let coarse_count = match options.count {
        ModeCount::First(k) => ModeCount::First(k + guard(k + 6)),
        ModeCount::Below(limit) => ModeCount::Below(1.25 * limit),
    };
    let coarse_options = EigenOptions {
        count: coarse_count,
        tolerance: COARSE_TOLERANCE.max(options.tolerance),
        ..*options
    };
    let coarse = {
        let cp = mg.coarse_problem();
        let (pattern, k, m) = (cp.pattern.clone(), cp.k.clone(), cp.m.clone());
        let ops = Operators::from_parts(&pattern, &k, &m);
        lanczos::run(&ops, mg.coarse_factor(), -tau, &coarse_options)
    };
    let (rigid, vectors, below) = match coarse {
        Ok(sol) => {
            let below = match options.count {
                ModeCount::Below(limit) => sol.eigenvalues.iter().filter(|&&l| l <= limit).count(),
                ModeCount::First(k) => k,
            };
            let w = sol.vectors.ncols();
            let fine = mg.prolong_from_coarsest(&to_rows(sol.vectors.as_ref()), w);
            (sol.rigid_modes, Some((fine, w)), below)
        }
        // Too small or too hard a coarse problem: start from rigid fields and random vectors.
        Err(_) => (
            6,
            None,
            match options.count {
                ModeCount::First(k) => k,
                ModeCount::Below(_) => 20,
            },
        ),
    };
    let need = rigid + below.max(1);
    let m = need + guard(need);
    let mut block = zeroed(n * m);
    let rig = rigid_fields(model);
    let mut col = 0;
    let mut put = |src: &[f64], w: usize, take: usize, col: &mut usize| {
        for i in 0..n {
            block[i * m + *col..i * m + *col + take].copy_from_slice(&src[i * w..i * w + take]);
        }
        *col += take;
    };
    put(&rig, 6, 6.min(m), &mut col);
    // The last guard columns start random: a fine mode the coarse level represents badly (a
    // thin shell's bending, stiffened by the coarse cells) may be missing from the coarse
    // modes, and random columns give every mode a component for Rayleigh-Ritz to grow.
    let random = (guard(need) / 2).max(2);
    if let Some((fine, w)) = &vectors {
        let take = (*w)
            .min(m.saturating_sub(col + random))
            .min(m.saturating_sub(rigid));
        put(fine, *w, take, &mut col);
    }
    if col < m {
        let fill = to_rows(random_block(n, m - col, 7).as_ref());
        put(&fill, m - col, m - col, &mut col);
    }
    Ok(Start { need, m, block })
}
