//! The stiffness images `K X` of the instant answer's block, mostly without a product with `K`.
//!
//! Where it sits: inside [`super::ritz`], between [`super::transfer`] (the carried block `X`
//! on the edited mesh) and the Rayleigh-Ritz step, which needs `K X` and `M X`. Both were
//! block products over the whole matrix (on the default bowl, 80 columns of 6k DOFs: a third
//! of the instant answer's time each). A carried mode `x` was an eigenvector of the previous
//! shape, `K_old x = lambda M_old x` to its residual (Jin et al. 2022, eq. 6), and a row of
//! the new `K X` whose elements the edit left alone (the same cells with the same fills, so
//! the same element matrices; every node of them persisting, so the same carried values) is
//! the old row. There, `K x = lambda M x` with the new `M x`, which the step computes anyway.
//! Only the rows of the nodes near an edited cell are multiplied out. The rigid fields'
//! images are zero (`K r = 0` for every rigid motion). The columns that are not converged
//! eigenvectors are multiplied in full: the carried guards (Ritz vectors), the extra rigid
//! modes of an object whose parts touch along edges, and every mode of a previous answer that
//! was itself approximate (a residual above [`RELATION_MAX_RESIDUAL`]).
//!
//! The error this leaves in `K x` is the previous solve's residual, `||K x - lambda M x|| <=
//! 1e-6 (||K|| + lambda ||M||) ||x||`: a relative error of that order in the Gram matrices,
//! three orders below what the carried answer is accurate to (1e-5 to 3e-3).

use super::super::{EigenSolution, Operators, Which};
use super::{add_block_product, extra_rigid, nodes_near};
use crate::fem::FemModel;

use std::collections::HashSet;

/// A carried mode whose residual was at most this (the default solver tolerance) is taken as
/// an eigenpair of the previous shape; above it (an approximate answer) it is multiplied out.
pub(super) const RELATION_MAX_RESIDUAL: f64 = 1e-6;

/// `K X` on `next` for the instant answer's block `X` (`n x w`, given by rows: `x_rows[i * w +
/// j]`; `fields` rigid fields, then the carried columns of [`super::previous_rows`]), given
/// `M X` (`mx_rows`, by rows) and the cells
/// the edit changed ([`super::edited_cells`]), by rows. See the module docs; the whole product
/// where the edit is too large to tell apart (`edited` is `None`).
pub(super) fn stiffness_images(
    ops: &Operators,
    next: &FemModel,
    edited: Option<&HashSet<[i64; 3]>>,
    previous_solution: &EigenSolution,
    x_rows: &[f64],
    mx_rows: &[f64],
    fields: usize,
) -> Vec<f64> {
    let (n, w) = (ops.dofs(), x_rows.len() / ops.dofs().max(1));
    let extra = extra_rigid(previous_solution).ncols();
    let modes = previous_solution.vectors.ncols();
    // Per column: the eigenvalue whose relation gives its image, or `None` (multiplied out).
    let lambda: Vec<Option<f64>> = (0..w)
        .map(|j| {
            let m = j.checked_sub(fields + extra).filter(|&m| m < modes)?;
            (previous_solution.residuals[m] <= RELATION_MAX_RESIDUAL)
                .then(|| previous_solution.eigenvalues[m])
        })
        .collect();
    let related: Vec<usize> = (0..w).filter(|&j| lambda[j].is_some()).collect();
    let Some(rows) = edited
        .filter(|_| !related.is_empty())
        .and_then(|e| touched_nodes(next, e))
    else {
        return ops.rows_product(Which::K, x_rows, w);
    };
    // By rows, as `X` and `M X` are: every pass below streams through them.
    let mut kx = vec![0.0; n * w];
    for (out, m) in kx.chunks_exact_mut(w).zip(mx_rows.chunks_exact(w)) {
        for &j in &related {
            out[j] = lambda[j].expect("related") * m[j];
        }
    }
    // The columns multiplied out: guards, extra rigid modes, approximate modes.
    let exact: Vec<usize> = (fields..w).filter(|&j| lambda[j].is_none()).collect();
    if !exact.is_empty() {
        let ne = exact.len();
        let xe: Vec<f64> = (0..n * ne)
            .map(|k| x_rows[k / ne * w + exact[k % ne]])
            .collect();
        let ke = ops.rows_product(Which::K, &xe, ne);
        for (out, row) in kx.chunks_exact_mut(w).zip(ke.chunks_exact(ne)) {
            for (&j, &v) in exact.iter().zip(row) {
                out[j] = v;
            }
        }
    }
    // The rows near the edit, multiplied out (every column, read by rows: a DOF's values side
    // by side; the related columns' are kept).
    let mut acc = vec![0.0; 3 * w];
    for node in rows {
        acc.fill(0.0);
        for b in ops.pattern.row_ptr[node]..ops.pattern.row_ptr[node + 1] {
            let col = 3 * ops.pattern.col[b] as usize;
            add_block_product(&ops.k[b], &x_rows[col * w..(col + 3) * w], &mut acc);
        }
        for (r, a) in acc.chunks_exact(w).enumerate() {
            let out = &mut kx[(3 * node + r) * w..(3 * node + r + 1) * w];
            for &j in &related {
                out[j] = a[j];
            }
        }
    }
    kx
}

/// The nodes of `next` whose rows of `K` may differ from the previous shape's: those of every
/// element within one cell of an `edited` cell (one cell more because a quadratic cut
/// element's refined fill reads its neighbours' fills, `shape::refine`). `None` where the edit
/// is too large to be worth it (more than a quarter of the nodes).
fn touched_nodes(next: &FemModel, edited: &HashSet<[i64; 3]>) -> Option<Vec<usize>> {
    let nodes = nodes_near(next, edited, 1);
    (4 * nodes.len() <= next.nodes()).then_some(nodes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eigen::lobpcg::rigid_fields;
    use crate::eigen::{self, EigenOptions, ModeCount, SolverKind};
    use crate::fem::ElementKind;
    use crate::shape::{ops as shape_ops, primitives::Primitive, SubFill, VoxelFill, VoxelGrid};
    use faer::{Mat, MatRef};

    /// `K X` by the relation against the whole product, for a stroke on a hollow sphere: a
    /// carried mode's difference is bounded by its residual in the previous solve (scaled by
    /// `||K|| max |x|`, with a factor 10 for the norms' slack: the residual is a 2-norm
    /// ratio); the guards and rigid fields must match to rounding. Leaving out the rows of
    /// the cells next to an edited one (the refined fill's halo) is caught on hex27x2: off
    /// by 1.6e-6 where the residual was 2e-14. The residual is the previous mode's own,
    /// recomputed: the sphere is solved by symmetry classes, and a mode imaged across a swap
    /// reports its source's residual while its own also holds the mesh's asymmetry (accepted
    /// to `SYMMETRY_TOLERANCE`): measured 1e-11 where 2e-16 was reported.
    fn check(kind: ElementKind, edit: impl Fn(&mut VoxelGrid)) {
        let before = shape_ops::hollow(
            &Primitive::Sphere { diameter: 10.0 }
                .rasterize(1.0, 1.0)
                .unwrap(),
            2,
        );
        let previous = FemModel::assemble(&before, kind, 0.24).unwrap();
        let options = EigenOptions {
            count: ModeCount::First(20),
            ..Default::default()
        };
        let solution = eigen::solve(&previous, SolverKind::Lanczos, &options).unwrap();
        let own_residuals = Operators::new(&previous)
            .block_residuals(&solution.eigenvalues, solution.vectors.as_ref());
        let mut after = before.clone();
        edit(&mut after);
        let next = FemModel::assemble(&after, kind, 0.24).unwrap();
        let (offset, _) = super::super::align(&previous, &next);
        let (old, w_old) = super::super::previous_rows(&solution, 8);
        let carried = super::super::transfer_rows(&previous, &old, w_old, &next, offset, 0);
        let ops = Operators::new(&next);
        let n = next.dofs();
        let rigid = rigid_fields(&next);
        let w = 6 + carried.columns;
        let x = Mat::from_fn(n, w, |i, j| {
            if j < 6 {
                rigid[i * 6 + j]
            } else {
                carried.block[i * carried.columns + j - 6]
            }
        });
        let mx = ops.apply_block(Which::M, x.as_ref());
        let want = ops.apply_block(Which::K, x.as_ref());
        let edited = super::super::edited_cells(&previous, &next, offset);
        assert!(edited
            .as_ref()
            .and_then(|e| touched_nodes(&next, e))
            .is_some_and(|r| !r.is_empty()));
        let x_rows = crate::eigen::to_rows(x.as_ref());
        let got = stiffness_images(
            &ops,
            &next,
            edited.as_ref(),
            &solution,
            &x_rows,
            &crate::eigen::to_rows(mx.as_ref()),
            6,
        );
        let got = MatRef::from_row_major_slice(&got, n, w);
        for j in 0..w {
            let (mut diff, mut norm) = (0.0f64, 0.0f64);
            for i in 0..n {
                diff = diff.max((got[(i, j)] - want[(i, j)]).abs());
                norm = norm.max(x[(i, j)].abs());
            }
            // A related column's images are off by its mode's residual (measured 2-4x it in
            // this norm), plus rounding; a product's match to rounding.
            let bound = match j.checked_sub(6).filter(|&m| m < solution.vectors.ncols()) {
                Some(m) => 10.0 * own_residuals[m] + 1e-11,
                None => 1e-11,
            };
            assert!(
                diff <= bound * ops.k_norm * norm,
                "{kind:?} column {j}: {diff:e} against {:e}",
                ops.k_norm * norm
            );
        }
    }

    #[test]
    fn images_by_the_eigen_relation_match_the_product() {
        // A voxel added on the outside (hex8i, hex27x2) and a partial voxel's fill changed
        // without changing which voxels are solid (the cell's fingerprint must catch it).
        let add = |g: &mut VoxelGrid| {
            let d = g.dims();
            let (x, y) = (d[0] / 2, d[1] / 2);
            let z = (0..d[2])
                .rev()
                .find(|&z| g.get(x as isize, y as isize, z as isize))
                .unwrap();
            g.set(x - 1, y, z, true);
            g.set(x, y + 1, z, true);
        };
        let refill = |g: &mut VoxelGrid| {
            let (i, _) = g.partial_voxels().nth(3).map(|(i, f)| (i, *f)).unwrap();
            let v = crate::shape::lattice_coords(i, g.dims());
            g.set_fill(v[0], v[1], v[2], VoxelFill::Partial(SubFill([200; 64])));
        };
        for kind in [ElementKind::Hex8Incompatible, ElementKind::Hex27Blocks] {
            check(kind, add);
            check(kind, refill);
        }
    }
}
