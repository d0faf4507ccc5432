//! The instant answer's Gram matrices `X^T K X` and `X^T M X`, mostly from the previous solve's.
//!
//! Where it sits: inside [`super::ritz`], between [`super::transfer_rows`] (the carried block
//! `X` on the edited mesh) and the relaxation near the edit (`warm/correction.rs`) and the
//! Rayleigh-Ritz step. Before stop 61 the step formed `M X` and most of `K X` over the whole
//! mesh (80 columns of 6k-30k DOFs) and both Gram matrices from them: on the ceramic cup
//! preset, 42 of the 104 ms of its instant answer.
//!
//! The Gram matrices of the previous shape's modes are known without a product: they are its
//! eigenvectors, `X'^T M' X' = I` and `X'^T K' X' = Lambda` to the previous solve's residual
//! (Jin et al. 2022, eq. 6). A Gram matrix is a sum over rows, `X^T A X = sum_i x_i^T (A X)_i`,
//! and a row whose elements the edit left alone (the same cells with the same fills, every node
//! of them persisting with its carried values) is the same in both shapes. So for the carried
//! modes
//!
//! `X^T A X = X'^T A' X' + sum_{i in T} x_i^T (A X)_i - sum_{o in T'} x'_o^T (A' X')_o`
//!
//! where `T` are the new nodes near the edit ([`touched_nodes`]: the nodes of every element
//! within one cell of an edited cell, one cell more because a quadratic cut element's refined
//! fill reads its neighbours' fills) and `T'` the previous nodes that no untouched new node
//! carries (those of the edited cells and around them, and the nodes a removal dropped). Both
//! sums are over a few hundred nodes. The columns that are no converged eigenvectors (the rigid
//! fields, whose images `K r = 0` are exact, the carried guards and extra rigid modes, the modes
//! of an approximate previous answer: a residual above [`RELATION_MAX_RESIDUAL`]) are multiplied
//! out over the whole mesh, and their Gram rows with every column formed from those products;
//! except where the previous answer's whole Gram columns of them are given ([`Moved`], the
//! engine's factored answer, `warm/exact_grams.rs`): those are then updated near the edit as
//! the carried modes' are, and `X` is read only there.
//!
//! The error this leaves is the previous solve's residual: a relative error of about 1e-6 in
//! the Gram matrices, three orders below what the carried answer is accurate to (1e-5 to 3e-3).

mod products;

pub(super) use products::BlockRows;
use products::{cross_rows, gram, local_gram, Blocks};

use super::super::{EigenSolution, Operators, Which};
use super::exact_grams::Moved;
use super::patch::nodes_near;
use crate::buffer;
use crate::eigen::lobpcg::rigid_row;
use crate::fem::FemModel;
use faer::{Mat, MatRef};
use std::collections::HashSet;

/// A carried mode whose residual was at most this (the default solver tolerance) is taken as
/// an eigenpair of the previous shape; above it (an approximate answer) it is multiplied out.
pub(super) const RELATION_MAX_RESIDUAL: f64 = 1e-6;

/// What the Rayleigh-Ritz step and the relaxation need of the block `X`.
pub(super) struct Grams {
    /// `X^T K X` (`w x w`, symmetric).
    pub k: Mat<f64>,
    /// `X^T M X`.
    pub m: Mat<f64>,
    /// `K X` on the rows of the requested nodes (three DOF rows per node, in the order given).
    pub k_rows: Mat<f64>,
    /// `M X` on the same rows.
    pub m_rows: Mat<f64>,
}

/// The previous shape's side of an instant answer.
pub(super) struct Previous<'a> {
    /// The previous model.
    pub model: &'a FemModel,
    /// Its carried columns ([`super::transfer::previous_columns`]).
    pub columns: &'a [&'a [f64]],
    /// For each carried column, the eigenvalue whose relation stands for its products, or
    /// `None` (multiplied out): see [`relations`].
    pub lambda: &'a [Option<f64>],
}

/// For each of the `cc` carried columns of [`super::transfer::previous_columns`] (`extra` extra rigid
/// modes, the modes, the guards), the previous eigenvalue of a mode or a guard that was solved
/// to [`RELATION_MAX_RESIDUAL`], or `None`.
pub(super) fn relations(previous: &EigenSolution, extra: usize, cc: usize) -> Vec<Option<f64>> {
    let modes = previous.eigenvalues.len();
    (0..cc)
        .map(|j| {
            let m = j.checked_sub(extra)?;
            let (lambda, residual) = match m.checked_sub(modes) {
                None => (previous.eigenvalues[m], previous.residuals[m]),
                Some(g) => (
                    *previous.guard_eigenvalues.get(g)?,
                    *previous.guard_residuals.get(g)?,
                ),
            };
            (residual <= RELATION_MAX_RESIDUAL).then_some(lambda)
        })
        .collect()
}

/// The nodes whose rows of `X` [`grams`] reads where the edit is local and the columns it
/// cannot relate come from [`Moved`] kept columns: the patch's (`rows_at`), the `touched`
/// ones, and their neighbours in `next`'s pattern. Ascending.
pub(super) fn rows_read(next: &FemModel, rows_at: &[usize], touched: &[usize]) -> Vec<usize> {
    let p = &next.pattern;
    let mut read = vec![false; next.nodes()];
    for &v in rows_at.iter().chain(touched) {
        for &c in &p.col[p.row_ptr[v]..p.row_ptr[v + 1]] {
            read[c as usize] = true;
        }
    }
    (0..next.nodes()).filter(|&v| read[v]).collect()
}

/// The Gram matrices of `X` ([`BlockRows`], its first `fields` columns the rigid fields) on
/// `next`, and its images on the rows of `rows_at` (the relaxation's patch). `touched` are
/// [`touched_nodes`] of the edit (`None`: not a local edit); `node_map` gives each new node's
/// previous node (`u32::MAX` for a new one); `fields_rows` is the rigid fields by rows (`n x
/// 6`, [`crate::eigen::lobpcg::rigid_fields`]) where `fields` is 6 and `X` is whole (else
/// empty). By the previous solve's Grams where the edit is local (see the module docs), else
/// by whole products. The columns that are not related (the rigid fields, unconverged
/// guards) come from `kept` (the previous answer's whole Gram columns, the fields about the
/// same centre) where those are given for the same columns and the edit is local; else by
/// whole products, which need `X` whole: `None` if it is not. The rows of `K X` and `M X`
/// on `rows_at` are multiplied out either way.
#[allow(clippy::too_many_arguments)]
pub(super) fn grams(
    ops: &Operators,
    next: &FemModel,
    touched: Option<&[usize]>,
    previous: &Previous,
    node_map: &[u32],
    x: BlockRows,
    fields: usize,
    fields_rows: &[f64],
    rows_at: &[usize],
    kept: Option<&Moved>,
) -> Option<Grams> {
    let (n, w) = (ops.dofs(), x.w);
    let new_blocks = Blocks::of(ops.pattern, ops.k, ops.m);
    let lambda: Vec<Option<f64>> = (0..w)
        .map(|j| j.checked_sub(fields).and_then(|c| previous.lambda[c]))
        .collect();
    let related: Vec<usize> = (0..w).filter(|&j| lambda[j].is_some()).collect();
    let touched = touched.filter(|_| !related.is_empty());
    // The rows multiplied out on the new mesh: the patch's, then the touched nodes off it (for
    // hex27x2 the two are the same nodes).
    let mut near: Vec<usize> = rows_at.to_vec();
    let mut place = vec![u32::MAX; next.nodes()];
    rows_at
        .iter()
        .enumerate()
        .for_each(|(i, &v)| place[v] = i as u32);
    for &v in touched.iter().copied().flatten() {
        if place[v] == u32::MAX {
            place[v] = near.len() as u32;
            near.push(v);
        }
    }
    let k_near = new_blocks.product(Which::K, &near, x);
    let m_near = new_blocks.product(Which::M, &near, x);
    let patch_rows = |a: &Mat<f64>| a.get(..3 * rows_at.len(), ..).to_owned();
    let (k_rows, m_rows) = (patch_rows(&k_near), patch_rows(&m_near));
    // The previous nodes that no untouched new node carries. Every untouched node persists (a
    // new node lies on an edited cell); were one new, the edit would not be local after all.
    let left = touched.as_ref().and_then(|t| {
        let mut is_touched = vec![false; next.nodes()];
        t.iter().for_each(|&v| is_touched[v] = true);
        let mut carried_previous = vec![false; previous.model.nodes()];
        for (v, &o) in node_map.iter().enumerate() {
            if !is_touched[v] {
                *carried_previous.get_mut(o as usize)? = true;
            }
        }
        Some(
            (0..previous.model.nodes())
                .filter(|&o| !carried_previous[o])
                .collect::<Vec<usize>>(),
        )
    });
    // `X` whole, for the whole products.
    let whole = || {
        x.slot
            .is_none()
            .then(|| MatRef::from_row_major_slice(x.rows, n, w))
    };
    let (Some(touched), Some(left)) = (touched, left) else {
        // Whole products: the edit is not local, or nothing was converged.
        let xw = whole()?;
        let mx = ops.rows_product(Which::M, x.rows, w);
        let kx = ops.rows_product(Which::K, x.rows, w);
        return Some(Grams {
            k: gram(xw, MatRef::from_row_major_slice(&kx, n, w)),
            m: gram(xw, MatRef::from_row_major_slice(&mx, n, w)),
            k_rows,
            m_rows,
        });
    };
    // The columns multiplied out, and their Gram columns against every column.
    let others: Vec<usize> = (0..w).filter(|&j| lambda[j].is_none()).collect();
    let no = others.len();
    // Their Gram columns from the previous answer's (`warm/exact_grams.rs`), where it kept
    // the same columns.
    let moved = kept.filter(|mv| fields == 6 && mv.others == others);
    // The rigid fields' images are zero (they lead `others`): only the rest are multiplied
    // (none, where every carried mode and guard converged), their Gram columns beside zeros.
    let rigid = others.iter().take_while(|&&j| j < fields).count();
    let whole_cross = if moved.is_some() {
        None
    } else {
        let x_rows = x.slot.is_none().then_some(x.rows)?;
        // Where only the rigid fields are (the previous modes and guards all converged), they
        // are `fields_rows` as they are: no pass over `X` (1.3 ms of the ceramic cup's
        // answer).
        let xo: std::borrow::Cow<[f64]> =
            if fields == 6 && others.len() == fields && fields_rows.len() == 6 * n {
                fields_rows.into()
            } else {
                (0..n * no)
                    .map(|k| x_rows[k / no * w + others[k % no]])
                    .collect::<Vec<f64>>()
                    .into()
            };
        let mo = ops.rows_product(Which::M, &xo, no);
        let mut k_cross = Mat::<f64>::zeros(w, no);
        if rigid < no {
            let nk = no - rigid;
            let xk: Vec<f64> = (0..n * nk)
                .map(|k| xo[k / nk * no + rigid + k % nk])
                .collect();
            let kk = ops.rows_product(Which::K, &xk, nk);
            k_cross
                .get_mut(.., rigid..)
                .copy_from(cross_rows(x_rows, w, &kk, nk));
        }
        Some((k_cross, cross_rows(x_rows, w, &mo, no)))
    };
    // The related block: the previous Grams, plus the new rows near the edit, less the previous
    // rows on `left`.
    let touched_at: Vec<usize> = touched.iter().map(|&v| place[v] as usize).collect();
    let new_side = |y: &Mat<f64>| local_gram(x, touched, y, &touched_at);
    let pm = previous.model;
    let old_blocks = Blocks::of(&pm.pattern, pm.k(), pm.m());
    let cc = w - fields;
    // The previous rows lead with the rigid fields where their kept columns are updated too
    // (about the same centre, in the previous mesh's positions).
    let lead = if moved.is_some() { fields } else { 0 };
    let ow = lead + cc;
    let old_at = |j: usize| j - fields + lead;
    // The previous columns by rows on `left` and its neighbours, the only rows the sums read:
    // a kept buffer, never cleared (a zeroed one was a pass over all 16 MB of the ceramic
    // cup's wherever the allocator handed back used memory).
    let len = 3 * pm.nodes() * ow;
    let mut old_rows = buffer::take_unfilled(len).unwrap_or_else(|_| vec![0.0; len]);
    let mut read = vec![false; pm.nodes()];
    for &o in &left {
        for b in pm.pattern.row_ptr[o]..pm.pattern.row_ptr[o + 1] {
            let v = pm.pattern.col[b] as usize;
            if !std::mem::replace(&mut read[v], true) {
                for d in 3 * v..3 * v + 3 {
                    let row = &mut old_rows[d * ow..(d + 1) * ow];
                    if let Some(mv) = moved {
                        let r = rigid_row(pm.node_position(v), mv.centre, d % 3);
                        row[..lead].copy_from_slice(&r[..lead]);
                    }
                    for (out, column) in row[lead..].iter_mut().zip(previous.columns) {
                        *out = column[d];
                    }
                }
            }
        }
    }
    let old_side = |which| {
        let old = BlockRows::whole(&old_rows, ow);
        let y = old_blocks.product(which, &left, old);
        local_gram(old, &left, &y, &(0..left.len()).collect::<Vec<_>>())
    };
    let (k_new, m_new, k_old, m_old) = (
        new_side(&k_near),
        new_side(&m_near),
        old_side(Which::K),
        old_side(Which::M),
    );
    buffer::recycle(old_rows);
    // Both sums are over rows, so each alone is not symmetric; their difference is (the whole
    // Grams' difference), to rounding: its mean is taken.
    let change = |new: &Mat<f64>, old: &Mat<f64>, i: usize, j: usize| {
        let local = |a: &Mat<f64>, p: usize, q: usize| a[(p, q)] + a[(q, p)];
        0.5 * (local(new, i, j) - local(old, old_at(i), old_at(j)))
    };
    let (k_cross, m_cross) = whole_cross.unwrap_or_else(|| {
        let mv = moved.expect("kept columns, where not multiplied out");
        let cross = |g: &Mat<f64>, new: &Mat<f64>, old: &Mat<f64>, from: usize| {
            Mat::from_fn(w, no, |i, c| {
                if c >= from {
                    g[(i, c)] + change(new, old, i, others[c])
                } else {
                    0.0
                }
            })
        };
        // The fields' `K` columns are zero, as multiplied out: their sums near the edit are
        // rounding only, and that rounding on the fields' own block moved the Ritz values
        // by 1e-8 (the fields' `M` block is large, positions squared).
        (
            cross(&mv.k, &k_new, &k_old, rigid),
            cross(&mv.m, &m_new, &m_old, 0),
        )
    });
    let assemble = |which: Which, new: &Mat<f64>, old: &Mat<f64>, cross: &Mat<f64>| {
        let mut g = Mat::<f64>::zeros(w, w);
        for (c, &j) in others.iter().enumerate() {
            for i in 0..w {
                g[(i, j)] = cross[(i, c)];
                g[(j, i)] = cross[(i, c)];
            }
        }
        for &i in &related {
            for &j in &related {
                let before = match (which, i == j) {
                    (_, false) => 0.0,
                    (Which::M, true) => 1.0,
                    (Which::K, true) => lambda[i].expect("related"),
                };
                g[(i, j)] = before + change(new, old, i, j);
            }
        }
        g
    };
    Some(Grams {
        k: assemble(Which::K, &k_new, &k_old, &k_cross),
        m: assemble(Which::M, &m_new, &m_old, &m_cross),
        k_rows,
        m_rows,
    })
}

/// The nodes of `next` whose rows of `K` and `M` may differ from the previous shape's: those
/// of every element within one cell of an `edited` cell. `None` where the edit is too large to
/// be worth it (more than a quarter of the nodes).
pub(super) fn touched_nodes(next: &FemModel, edited: &HashSet<[i64; 3]>) -> Option<Vec<usize>> {
    let nodes = nodes_near(next, edited, 1);
    (4 * nodes.len() <= next.nodes()).then_some(nodes)
}

#[cfg(test)]
mod tests {
    use super::super::exact_grams::ExactGrams;
    use super::super::transfer::previous_columns;
    use super::*;
    use crate::eigen::lobpcg::{rigid_centre, rigid_fields};
    use crate::eigen::{self, EigenOptions, ModeCount, SolverKind};
    use crate::fem::ElementKind;
    use crate::shape::{ops as shape_ops, primitives::Primitive, SubFill, VoxelFill, VoxelGrid};

    /// The Gram matrices from the previous solve's against those of the whole products, for a
    /// stroke on a hollow sphere. An entry between two carried modes is off by their previous
    /// residual (`x_i^T r_j`, bounded by `||x_i|| ||r_j||`, with a factor 10 for the norms'
    /// slack: eq. 6 is a ratio of 2-norms scaled by infinity norms) and the previous modes'
    /// M-orthonormality (rounding: 1e-11 of `||M|| ||x_i|| ||x_j||`); every other entry, and the
    /// patch rows, must match to rounding. Leaving out the rows of the cells next to an edited
    /// one (the refined fill's halo) is caught on hex27x2. The residuals are the previous
    /// modes' own, recomputed: the sphere is solved by symmetry classes, and a mode imaged
    /// across a swap reports its source's residual while its own also holds the mesh's
    /// asymmetry (accepted to `SYMMETRY_TOLERANCE`).
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
        let mut solution = eigen::solve(&previous, SolverKind::Lanczos, &options).unwrap();
        // Two guards taken as unconverged, as a whole solve's last Ritz vectors often are:
        // multiplied out (or kept, below) instead of related.
        solution.guard_residuals[1] = 1.0;
        solution.guard_residuals[5] = 1.0;
        let previous_ops = Operators::new(&previous);
        let mut own_residuals =
            previous_ops.block_residuals(&solution.eigenvalues, solution.vectors.as_ref());
        let guard_lambdas: Vec<f64> = (solution.guard_eigenvalues.iter())
            .map(|&l| if l.is_nan() { 0.0 } else { l })
            .collect();
        own_residuals
            .extend(previous_ops.block_residuals(&guard_lambdas, solution.guard_vectors.as_ref()));
        let mut after = before.clone();
        edit(&mut after);
        let next = FemModel::assemble(&after, kind, 0.24).unwrap();
        let (offset, _) = super::super::align(&previous, &next);
        let old = previous_columns(&solution, 8);
        let cc = old.len();
        let sources = super::super::NodeSources::new(&previous, &next, offset);
        let map = &sources.map;
        let carried = super::super::transfer_rows(&old, &next, &sources, 6);
        let ops = Operators::new(&next);
        let n = next.dofs();
        let w = carried.columns;
        let mut x_rows = carried.block;
        let rigid = rigid_fields(&next);
        for (i, row) in x_rows.chunks_exact_mut(w).enumerate() {
            row[..6].copy_from_slice(&rigid[i * 6..i * 6 + 6]);
        }
        let edited = super::super::patch::edited_cells(&previous, &next, offset);
        assert!(edited
            .as_ref()
            .and_then(|e| touched_nodes(&next, e))
            .is_some_and(|r| !r.is_empty()));
        let lambda = relations(&solution, 0, cc);
        // Every mode is related, and some of the guards (the classes' modes above the 20th).
        assert!(lambda[..20].iter().all(|l| l.is_some()));
        assert!(lambda[20..].iter().any(|l| l.is_some()));
        assert_eq!(lambda[21..26].iter().filter(|l| l.is_none()).count(), 2);
        let patch: Vec<usize> = (0..next.nodes()).step_by(7).collect();
        let previous_side = Previous {
            model: &previous,
            columns: &old,
            lambda: &lambda,
        };
        // Kept buffers full of NaNs for the previous rows (the Grams take one and write only
        // the rows they read): a row read but never written would show.
        crate::buffer::poison_kept(3 * previous.nodes() * cc);
        let touched = edited.as_ref().and_then(|e| touched_nodes(&next, e));
        let run = |touched: Option<&[usize]>, fields_rows: &[f64]| {
            let (g, x) = (&previous_side, BlockRows::whole(&x_rows, w));
            grams(
                &ops,
                &next,
                touched,
                g,
                map,
                x,
                6,
                fields_rows,
                &patch,
                None,
            )
            .unwrap()
        };
        let got = run(touched.as_deref(), &rigid);
        // The rigid fields read from `X` instead of given by rows: the same numbers.
        let extracted = run(touched.as_deref(), &[]);
        assert!(got.k == extracted.k && got.m == extracted.m);
        // Without the edit's cells (a stroke too large to tell apart), whole products.
        let whole = run(None, &rigid);
        let x = MatRef::from_row_major_slice(&x_rows, n, w);
        let (kx, mx) = (ops.apply_block(Which::K, x), ops.apply_block(Which::M, x));
        let (want_k, want_m) = (x.transpose() * &kx, x.transpose() * &mx);
        let norms: Vec<f64> = (0..w).map(|j| x.col(j).norm_l2()).collect();
        // The Grams and patch rows of `got` against the products, on the first `wl` columns.
        let compare = |got: &Grams, wl: usize, patch: &[usize]| {
            for i in 0..wl {
                for j in 0..wl {
                    let scale = norms[i] * norms[j];
                    // A related column's own residual; an unrelated one's products are exact.
                    let residual = |c: usize| match c.checked_sub(6) {
                        Some(m) if lambda[m].is_some() => own_residuals[m],
                        _ => 0.0,
                    };
                    let res = residual(i).max(residual(j));
                    let lam = guard_lambdas.iter().cloned().fold(0.0, f64::max);
                    let bound_k = (10.0 * res + 1e-11) * (ops.k_norm + lam * ops.m_norm) * scale;
                    let bound_m = 1e-11 * ops.m_norm * scale;
                    let (dk, dm) = (
                        (got.k[(i, j)] - want_k[(i, j)]).abs(),
                        (got.m[(i, j)] - want_m[(i, j)]).abs(),
                    );
                    assert!(
                        dk <= bound_k,
                        "{kind:?} K ({i}, {j}): {dk:e} against {bound_k:e}"
                    );
                    assert!(
                        dm <= bound_m,
                        "{kind:?} M ({i}, {j}): {dm:e} against {bound_m:e}"
                    );
                }
            }
            for (r, &node) in patch.iter().enumerate() {
                for c in 0..3 {
                    for j in 0..wl {
                        let d = 3 * node + c;
                        let scale = norms[j];
                        assert!(
                            (got.k_rows[(3 * r + c, j)] - kx[(d, j)]).abs()
                                <= 1e-11 * ops.k_norm * scale
                        );
                        assert!(
                            (got.m_rows[(3 * r + c, j)] - mx[(d, j)]).abs()
                                <= 1e-11 * ops.m_norm * scale
                        );
                    }
                }
            }
        };
        compare(&got, w, &patch);
        for i in 0..w {
            for j in 0..w {
                let rounding = 1e-11 * norms[i] * norms[j];
                assert!((whole.k[(i, j)] - want_k[(i, j)]).abs() <= rounding * ops.k_norm);
                assert!((whole.m[(i, j)] - want_m[(i, j)]).abs() <= rounding * ops.m_norm);
            }
        }
        // The factored answer's way (`warm/exact_grams.rs`): the columns it cannot relate
        // (the rigid fields and the unconverged guards) from the previous answer's whole Gram
        // columns, and the block given only on the rows read near the edit (the same values
        // as the whole block's, to the bit). The same bounds; without the kept columns such a
        // block gives no Grams.
        let touched = touched.expect("a local edit");
        let at = &touched[..touched.len() / 2];
        let read = rows_read(&next, at, &touched);
        // (A small sphere: the edit's neighbourhood is much of it, but not all.)
        assert!(
            read.len() < next.nodes(),
            "{} of {}",
            read.len(),
            next.nodes()
        );
        let mut slot = vec![u32::MAX; next.nodes()];
        (read.iter().enumerate()).for_each(|(i, &v)| slot[v] = i as u32);
        let centre = rigid_centre(&next);
        let rows = super::super::block_rows_on(&next, &old, &sources, 6, centre, &read);
        for (r, &v) in read.iter().enumerate() {
            for d in 0..3 {
                let whole_row = &x_rows[(3 * v + d) * w..][..w];
                assert_eq!(&rows[(3 * r + d) * w..][..w], whole_row);
            }
        }
        let vpe = next.kind.voxels_per_element() as i64;
        let moved = ExactGrams::new(&previous, &solution)
            .expect("one part")
            .about([0, 1, 2].map(|a| centre[a] + (offset[a] * vpe) as f64));
        let x = BlockRows {
            rows: &rows,
            w,
            slot: Some(&slot),
        };
        let local = |m: Option<&Moved>| {
            grams(
                &ops,
                &next,
                Some(&touched),
                &previous_side,
                map,
                x,
                6,
                &[],
                at,
                m,
            )
        };
        assert!(
            local(None).is_none(),
            "a partial block needs the kept columns"
        );
        compare(&local(Some(&moved)).expect("local Grams"), w, at);
    }

    #[test]
    fn grams_from_the_previous_solve_match_the_products() {
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
