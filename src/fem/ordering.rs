//! Fill-reducing orderings for the sparse Cholesky factorisations: geometric nested dissection
//! on the node lattice, and minimum degree on the node graph; [`fill_reducing`] takes whichever
//! fills less.
//!
//! Where it sits: the Lanczos factors ([`crate::eigen::factor`]) of whole models and of their
//! symmetry classes ([`crate::eigen::symmetric`]) eliminate nodes in the order
//! [`fill_reducing`] gives; the instant answer's patch and the multigrid's coarsest level use
//! the dissection alone.
//!
//! On a voxel grid a lattice plane at an element boundary separates the nodes on either side
//! exactly (no element straddles it), so nested dissection needs no graph partitioner: split the
//! node set at the median element boundary of its longest axis, order the two halves recursively,
//! then the separator (George 1973). For solids this gives less fill than minimum degree (a
//! 32^3 sphere's symmetry classes: 177k node-factor entries against 203k). Thin shells are
//! another matter: the planes cut a bowl's or a can's wall obliquely, and a sector of one (a
//! symmetry class) is split along planes that do not follow it; approximate minimum degree
//! (Amestoy, Davis and Duff 1996, faer's implementation) left 26-47 % fewer factor entries on
//! every curved preset's classes (the glass bowl's quarter 2.15M against 1.14M) and 14-22 % on
//! whole shells. Which one an object is needs no rule: the symbolic factorisations of its node
//! graph (a ninth of the DOFs' entries, 0.5-5 ms) are compared.

use super::sparse::BlockPattern;
use super::FemModel;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::linalg::{amd, SupernodalThreshold};
use faer::sparse::FaerError;
use faer::sparse::{SymbolicSparseColMat, SymbolicSparseColMatRef};
use faer::Side;

/// Parts smaller than this are ordered as they come (lattice order).
const LEAF_NODES: usize = 48;

/// A node permutation: `order[k]` is the node eliminated `k`-th.
pub fn nested_dissection(model: &FemModel) -> Vec<usize> {
    nested_dissection_of(&lattice_coords(model), model.kind.order() as i64)
}

/// Every node's lattice coordinates, what [`nested_dissection_of`] splits.
fn lattice_coords(model: &FemModel) -> Vec<[i64; 3]> {
    (0..model.nodes())
        .map(|n| model.node_lattice_coords(n))
        .collect()
}

/// [`fill_reducing`] for the whole of `model`: the order its Lanczos factor eliminates nodes in.
pub fn fill_reducing_for(model: &FemModel) -> Vec<usize> {
    let p = model.kind.order() as i64;
    fill_reducing(&model.pattern, &lattice_coords(model), p)
}

/// Nested dissection of any node set on a lattice whose element boundaries lie every `p`
/// lattice steps (`p = 1` for hex8, 2 for hex27); `coords` are lattice coordinates.
pub fn nested_dissection_of(coords: &[[i64; 3]], p: i64) -> Vec<usize> {
    let mut order = Vec::with_capacity(coords.len());
    let nodes: Vec<usize> = (0..coords.len()).collect();
    dissect(nodes, coords, p, &mut order);
    order
}

fn dissect(nodes: Vec<usize>, coords: &[[i64; 3]], p: i64, order: &mut Vec<usize>) {
    if nodes.len() <= LEAF_NODES {
        order.extend(nodes);
        return;
    }
    let mut lo = [i64::MAX; 3];
    let mut hi = [i64::MIN; 3];
    for &n in &nodes {
        for a in 0..3 {
            lo[a] = lo[a].min(coords[n][a]);
            hi[a] = hi[a].max(coords[n][a]);
        }
    }
    let axis = (0..3).max_by_key(|&a| hi[a] - lo[a]).unwrap();
    if hi[axis] - lo[axis] < 2 * p {
        order.extend(nodes);
        return;
    }
    // Median coordinate, snapped to an element boundary strictly inside the extent.
    let mut c: Vec<i64> = nodes.iter().map(|&n| coords[n][axis]).collect();
    let mid = c.len() / 2;
    let median = *c.select_nth_unstable(mid).1;
    let plane = ((median / p) * p).clamp(lo[axis] + p, hi[axis] - p);
    let (mut left, mut right, mut sep) = (Vec::new(), Vec::new(), Vec::new());
    for n in nodes {
        let x = coords[n][axis];
        if x < plane {
            left.push(n);
        } else if x > plane {
            right.push(n);
        } else {
            sep.push(n);
        }
    }
    dissect(left, coords, p, order);
    dissect(right, coords, p, order);
    order.extend(sep);
}

/// Approximate minimum degree (Amestoy, Davis and Duff 1996; faer's AMD) on the node graph of
/// `pattern` (a symmetric block pattern, each row's columns ascending): a node permutation,
/// `order[k]` the node eliminated `k`-th, for a factor whose DOFs go by node as with
/// [`nested_dissection`]. Where the lattice planes cut a thin shell obliquely (the symmetry
/// classes' sectors of a bowl or a can), it leaves far less fill than the geometric
/// dissection; `None` if faer refuses the graph (an index overflow).
pub fn minimum_degree(pattern: &BlockPattern) -> Option<Vec<usize>> {
    let n = pattern.nodes();
    let col_ptr: Vec<u32> = (pattern.row_ptr.iter())
        .map(|&p| u32::try_from(p).ok())
        .collect::<Option<_>>()?;
    let graph = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &pattern.col);
    let mut perm = vec![0u32; n];
    let mut perm_inv = vec![0u32; n];
    let mut scratch = MemBuffer::try_new(amd::order_scratch::<u32>(n, pattern.col.len())).ok()?;
    amd::order(
        &mut perm,
        &mut perm_inv,
        graph,
        amd::Control::default(),
        MemStack::new(&mut scratch),
    )
    .ok()?;
    Some(perm.into_iter().map(|v| v as usize).collect())
}

/// The node ordering of the two (the lattice's [`nested_dissection_of`] for the nodes at
/// `coords`, or [`minimum_degree`] on `pattern`) whose Cholesky factor of the node graph holds
/// fewer entries: minimum degree for shells, whose sectors the lattice planes cut obliquely
/// (the symmetry classes of the glass bowl: 0.53x the factor entries), dissection for solids
/// (a 32^3 sphere's classes 1.16x slower ordered by minimum degree). The node graph's
/// symbolic factorisations, a ninth of the DOFs' entries, decide.
pub fn fill_reducing(pattern: &BlockPattern, coords: &[[i64; 3]], p: i64) -> Vec<usize> {
    let dissection = nested_dissection_of(coords, p);
    let Some(degree) = minimum_degree(pattern) else {
        return dissection;
    };
    match (
        node_factor_len(pattern, &dissection),
        node_factor_len(pattern, &degree),
    ) {
        (Some(d), Some(m)) if m < d => degree,
        _ => dissection,
    }
}

/// Entries of the supernodal Cholesky factor of `pattern`'s node graph eliminated in `order`.
fn node_factor_len(pattern: &BlockPattern, order: &[usize]) -> Option<usize> {
    let n = pattern.nodes();
    // The upper triangle, by columns: column `r` holds the row's columns up to `r`.
    let mut col_ptr = Vec::with_capacity(n + 1);
    let mut row_idx = Vec::with_capacity(pattern.col.len() / 2 + n);
    col_ptr.push(0usize);
    for r in 0..n {
        let row = &pattern.col[pattern.row_ptr[r]..pattern.row_ptr[r + 1]];
        row_idx.extend(row.iter().map(|&c| c as usize).filter(|&c| c <= r));
        col_ptr.push(row_idx.len());
    }
    let upper = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
    let mut inv = vec![0usize; n];
    for (k, &v) in order.iter().enumerate() {
        inv[v] = k;
    }
    let perm = PermRef::new_checked(order, &inv, n);
    let symbolic = supernodal_symbolic(upper.as_ref(), SymmetricOrdering::Custom(perm)).ok()?;
    Some(symbolic.len_val())
}

/// faer's symbolic Cholesky factorisation of the upper triangle `upper`, always supernodal
/// (faer would pick its simplicial factor for the sparsest objects; the Lanczos solves in
/// `eigen/factor/rows.rs` read the supernodal layout, and the fill compared in
/// [`fill_reducing`] is that layout's).
pub fn supernodal_symbolic<I: faer::Index>(
    upper: SymbolicSparseColMatRef<'_, I>,
    ordering: SymmetricOrdering<'_, I>,
) -> Result<SymbolicCholesky<I>, FaerError> {
    let params = CholeskySymbolicParams {
        supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL,
        ..Default::default()
    };
    factorize_symbolic_cholesky(upper, Side::Upper, ordering, params)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::ElementKind;
    use crate::shape::primitives::Primitive;

    fn model(shape: Primitive) -> FemModel {
        let grid = shape.rasterize(1.0, 1.0).expect("grid");
        FemModel::assemble(&grid, ElementKind::Hex27Blocks, 0.3).expect("model")
    }

    fn is_permutation(order: &[usize], n: usize) -> bool {
        let mut seen = vec![false; n];
        order.len() == n
            && order
                .iter()
                .all(|&v| v < n && !std::mem::replace(&mut seen[v], true))
    }

    /// Both orderings are permutations of the nodes, and [`fill_reducing`] returns the one whose
    /// node factor is smaller, measured independently here for both: on a thin bowl minimum
    /// degree wins (by more than 10 %: the reason it exists), on a solid cube the dissection
    /// does. Fails if the comparison were reversed or either order dropped a node.
    #[test]
    fn the_order_that_fills_less_is_taken() {
        for (shape, degree_wins) in [
            (
                Primitive::Bowl {
                    diameter: 16.0,
                    wall: 1.0,
                },
                true,
            ),
            (
                Primitive::Box {
                    x: 16.0,
                    y: 16.0,
                    z: 16.0,
                },
                false,
            ),
        ] {
            let m = model(shape);
            let coords = lattice_coords(&m);
            let p = m.kind.order() as i64;
            let dissection = nested_dissection_of(&coords, p);
            let degree = minimum_degree(&m.pattern).expect("amd");
            assert!(is_permutation(&dissection, m.nodes()) && is_permutation(&degree, m.nodes()));
            let (d, g) = (
                node_factor_len(&m.pattern, &dissection).unwrap(),
                node_factor_len(&m.pattern, &degree).unwrap(),
            );
            assert_eq!(
                g < d,
                degree_wins,
                "{shape:?}: dissection {d}, minimum degree {g}"
            );
            if degree_wins {
                assert!(
                    10 * g < 9 * d,
                    "{shape:?}: dissection {d}, minimum degree {g}"
                );
            }
            let chosen = fill_reducing(&m.pattern, &coords, p);
            assert_eq!(chosen, if degree_wins { degree } else { dissection });
        }
    }
}
