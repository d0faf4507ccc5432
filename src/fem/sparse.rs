//! Node-blocked sparse symmetric matrices (3x3 blocks, one per node pair), as the FEM assembles
//! them, with the products the eigensolvers need and the conversion to `faer` for factoring.
//!
//! Both triangles are stored, so a product is one pass over the blocks; `K` and `M` share one
//! [`BlockPattern`]. `K` keeps a 3x3 block per node pair ([`Blocks`]), `M` one number
//! ([`MassBlocks`]): every finite-element mass block is `m_ab I3`.

use faer::sparse::{SparseColMat, SymbolicSparseColMat};
use faer::Side;

mod lattice;
mod mass;
mod scatter;
mod spmm;
pub use lattice::LatticeRows;
pub use mass::{
    mass_as_blocks, mass_norm_inf, mass_trace, spmm_mass, spmm_mass_diagonal, ComponentScale,
    MassBlocks,
};
pub use scatter::{
    add_element, add_element_blocks, add_element_rows, add_elements, find_slots, node_pairs,
    ElementBlocks, ALL_ROWS,
};
pub use spmm::{spmm, Scalar};

/// Sparsity of a node-blocked matrix: CSR over nodes, columns sorted.
#[derive(Clone, Debug)]
pub struct BlockPattern {
    /// Row starts, `nodes + 1` entries.
    pub row_ptr: Vec<usize>,
    /// Column node of each block.
    pub col: Vec<u32>,
}

impl BlockPattern {
    /// Number of block rows (nodes).
    pub fn nodes(&self) -> usize {
        self.row_ptr.len() - 1
    }

    /// Position of block `(row, col)`, if present.
    #[inline]
    pub fn find(&self, row: usize, col: u32) -> Option<usize> {
        let s = self.row_ptr[row];
        let cols = &self.col[s..self.row_ptr[row + 1]];
        cols.binary_search(&col).ok().map(|i| s + i)
    }
}

impl BlockPattern {
    /// The pattern of an element mesh: node `a` couples to every node that shares an element
    /// with it. `elements` holds `nodes_per_element` node numbers per element.
    ///
    /// Row by row, from each node's elements (a first pass lists them): a mark per node keeps
    /// each neighbour once, so a row sorts its distinct columns only (27 for a hex8 node inside
    /// a solid, where its 8 elements name 64), and no row is a vector of its own.
    pub fn from_elements(nodes: usize, elements: &[u32], nodes_per_element: usize) -> Self {
        // The elements of each node, CSR: node `a`'s are `of_node[first[a]..first[a + 1]]`.
        let mut first = vec![0usize; nodes + 1];
        for &a in elements {
            first[a as usize + 1] += 1;
        }
        for a in 0..nodes {
            first[a + 1] += first[a];
        }
        let mut of_node = vec![0u32; elements.len()];
        let mut next = first.clone();
        for (e, element) in elements.chunks_exact(nodes_per_element).enumerate() {
            for &a in element {
                of_node[next[a as usize]] = e as u32;
                next[a as usize] += 1;
            }
        }
        let mut mark = vec![u32::MAX; nodes];
        let mut row_ptr = Vec::with_capacity(nodes + 1);
        let mut col = Vec::with_capacity(elements.len() * nodes_per_element / 4);
        row_ptr.push(0);
        for a in 0..nodes {
            let start = col.len();
            for &e in &of_node[first[a]..first[a + 1]] {
                let e = e as usize;
                for &b in &elements[e * nodes_per_element..(e + 1) * nodes_per_element] {
                    if mark[b as usize] != a as u32 {
                        mark[b as usize] = a as u32;
                        col.push(b);
                    }
                }
            }
            col[start..].sort_unstable();
            row_ptr.push(col.len());
        }
        BlockPattern { row_ptr, col }
    }
}

/// Values of a symmetric node-blocked matrix on a shared pattern: block `b` is row-major 3x3.
pub type Blocks = Vec<[f64; 9]>;

/// `y = A x` for a node-blocked matrix.
pub fn spmv(pattern: &BlockPattern, a: &[[f64; 9]], x: &[f64], y: &mut [f64]) {
    for r in 0..pattern.nodes() {
        let mut acc = [0.0; 3];
        let span = pattern.row_ptr[r]..pattern.row_ptr[r + 1];
        for (&col, v) in pattern.col[span.clone()].iter().zip(&a[span]) {
            let c = col as usize * 3;
            let (x0, x1, x2) = (x[c], x[c + 1], x[c + 2]);
            acc[0] += v[0] * x0 + v[1] * x1 + v[2] * x2;
            acc[1] += v[3] * x0 + v[4] * x1 + v[5] * x2;
            acc[2] += v[6] * x0 + v[7] * x1 + v[8] * x2;
        }
        y[3 * r..3 * r + 3].copy_from_slice(&acc);
    }
}

/// A block of `width` vectors stored row-major with row stride `stride`: the values of DOF `i`
/// are `data[i * stride..i * stride + width]`. Block methods (LOBPCG, multigrid on a block) keep
/// their vectors this way so one pass over a matrix serves every vector.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RowBlock {
    /// Vectors in the block.
    pub width: usize,
    /// Distance between consecutive DOFs' rows (`>= width`).
    pub stride: usize,
}

impl RowBlock {
    /// A dense block (`stride == width`).
    pub fn dense(width: usize) -> Self {
        RowBlock {
            width,
            stride: width,
        }
    }
}

/// Sum of the diagonal.
pub fn trace(pattern: &BlockPattern, a: &[[f64; 9]]) -> f64 {
    (0..pattern.nodes())
        .map(|r| {
            let b = pattern.find(r, r as u32).expect("diagonal block");
            a[b][0] + a[b][4] + a[b][8]
        })
        .sum()
}

/// Largest absolute row sum (the 1- and infinity-norm, an upper bound on the 2-norm).
pub fn norm_inf(pattern: &BlockPattern, a: &[[f64; 9]]) -> f64 {
    let mut worst = 0.0f64;
    for r in 0..pattern.nodes() {
        let mut s = [0.0; 3];
        for blk in &a[pattern.row_ptr[r]..pattern.row_ptr[r + 1]] {
            for (i, si) in s.iter_mut().enumerate() {
                *si += blk[3 * i].abs() + blk[3 * i + 1].abs() + blk[3 * i + 2].abs();
            }
        }
        worst = worst.max(s[0]).max(s[1]).max(s[2]);
    }
    worst
}

/// One triangle of `P (K - shift M) P^T` as a DOF-level `faer` CSC matrix, `P` the node
/// permutation that puts node `nodes[j]` `j`-th (its DOFs at `3 j + c`): the matrix a sparse
/// Cholesky factors in that order, given already permuted so that `faer` does not permute it
/// again. The lower triangle is what its supernodal numeric factorisation reads (a column's
/// rows unsorted, as its own permutation leaves them), the upper what its symbolic analysis
/// reads. Entry `(3 i + d, 3 j + c)` is `K(b, a)[d][c] = K(a, b)[c][d]` for `a = nodes[j]`,
/// `b = nodes[i]`, read from row `a`'s blocks.
pub fn permuted_shifted_csc(
    pattern: &BlockPattern,
    k: &[[f64; 9]],
    mass: BlockMass<'_>,
    shift: f64,
    nodes: &[usize],
    side: Side,
) -> SparseColMat<usize, f64> {
    let n = pattern.nodes();
    assert_eq!(nodes.len(), n, "one position per node");
    let mut position = vec![0u32; n];
    for (j, &a) in nodes.iter().enumerate() {
        position[a] = j as u32;
    }
    // 9 entries a block off the diagonal and 6 a diagonal block in either triangle (the
    // pattern is symmetric); from the process's kept buffers (`crate::buffer`), to go back
    // there once the factorisation has read them.
    // (Halved over the whole pattern, not row by row: a row may hold an odd number of
    // off-diagonal blocks.)
    let (off_diagonal, diagonal) = (0..n)
        .map(|a| {
            let row = &pattern.col[pattern.row_ptr[a]..pattern.row_ptr[a + 1]];
            let diagonal = usize::from(row.binary_search(&(a as u32)).is_ok());
            (row.len() - diagonal, diagonal)
        })
        .fold((0, 0), |(o, d), (ro, rd)| (o + ro, d + rd));
    let entries = 9 * off_diagonal / 2 + 6 * diagonal;
    let mut col_ptr = Vec::with_capacity(3 * n + 1);
    let mut row_idx = crate::buffer::take(entries);
    let mut val = crate::buffer::take(entries);
    // Empty (as `take` hands them back), so their spare capacity starts at element 0.
    row_idx.clear();
    val.clear();
    row_idx.reserve_exact(entries);
    val.reserve_exact(entries);
    col_ptr.push(0);
    let lower = side == Side::Lower;
    // Written in place, not pushed: a push's length and capacity live in memory between
    // entries, which made this loop 6 ns an entry.
    let (rows_out, vals_out) = (
        &mut row_idx.spare_capacity_mut()[..entries],
        &mut val.spare_capacity_mut()[..entries],
    );
    let mut at = 0;
    // A node's blocks in the triangle, as (first permuted row, block), found once for its
    // three columns.
    let mut blocks: Vec<(usize, usize)> = Vec::new();
    for (j, &a) in nodes.iter().enumerate() {
        blocks.clear();
        let mut own = None;
        for blk in pattern.row_ptr[a]..pattern.row_ptr[a + 1] {
            let i = position[pattern.col[blk] as usize] as usize;
            if i == j {
                own = Some(blk);
            } else if (i > j) == lower {
                blocks.push((3 * i, blk));
            }
        }
        for c in 0..3 {
            if let Some(blk) = own {
                let m = mass.diagonal(blk);
                let within = if lower { c..3 } else { 0..c + 1 };
                for d in within {
                    let shifted = if c == d { shift * m[c] } else { 0.0 };
                    rows_out[at].write(3 * j + d);
                    vals_out[at].write(k[blk][3 * c + d] - shifted);
                    at += 1;
                }
            }
            for &(row, blk) in &blocks {
                let kc = &k[blk][3 * c..3 * c + 3];
                let mc = shift * mass.diagonal(blk)[c];
                for (d, &kcd) in kc.iter().enumerate() {
                    let shifted = if c == d { mc } else { 0.0 };
                    rows_out[at].write(row + d);
                    vals_out[at].write(kcd - shifted);
                    at += 1;
                }
            }
            col_ptr.push(at);
        }
    }
    assert_eq!(at, entries, "every entry of the triangle written");
    // SAFETY: both vectors are empty with room for `entries` elements (cleared and reserved
    // above), and the loop wrote elements `0..at` of both spare capacities, one per entry,
    // with `at == entries` asserted.
    unsafe {
        row_idx.set_len(entries);
        val.set_len(entries);
    }
    let symbolic = SymbolicSparseColMat::new_unsorted_checked(3 * n, 3 * n, col_ptr, None, row_idx);
    SparseColMat::new(symbolic, val)
}

/// The mass a shifted matrix subtracts, by blocks of `K`'s pattern.
#[derive(Clone, Copy)]
pub enum BlockMass<'a> {
    /// `m I3` a block: every assembled model's ([`crate::fem::FemModel::m`]).
    Scalar(&'a [f64]),
    /// A diagonal a block, one number per component: a symmetry class's (its reduction
    /// flips components' signs), whose few entries off the blocks' diagonals are added apart.
    Diagonal(&'a [[f64; 3]]),
}

impl BlockMass<'_> {
    /// Block `blk`'s diagonal.
    #[inline]
    fn diagonal(self, blk: usize) -> [f64; 3] {
        match self {
            BlockMass::Scalar(m) => [m[blk]; 3],
            BlockMass::Diagonal(m) => m[blk],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Both triangles of the permuted matrix, entry by entry, against `P (K - shift M) P^T`
    /// formed densely from the blocks: every structural entry of the triangle once, at its
    /// permuted place, with the same value (the same arithmetic, so equal to the bit).
    #[test]
    fn the_permuted_triangles_are_those_of_the_permuted_matrix() {
        use crate::fem::ElementKind;
        let model = crate::fem::test_model("box:x=3,y=2,z=2", ElementKind::Hex8Incompatible, 0.3);
        let (nodes, shift) = (model.nodes(), -0.25);
        let n = 3 * nodes;
        // Row `a` of the block matrix at (3a + c, 3b + d); `None` off the pattern.
        let mut dense = vec![None; n * n];
        for a in 0..nodes {
            for blk in model.pattern.row_ptr[a]..model.pattern.row_ptr[a + 1] {
                let b = model.pattern.col[blk] as usize;
                for (c, d) in (0..3).flat_map(|c| (0..3).map(move |d| (c, d))) {
                    let mass = if c == d { model.m[blk] } else { 0.0 };
                    dense[(3 * a + c) * n + 3 * b + d] =
                        Some(model.k[blk][3 * c + d] - shift * mass);
                }
            }
        }
        // A scrambled elimination order: `order[j]` is eliminated j-th.
        let order: Vec<usize> = (0..nodes).map(|j| (j * 7 + 3) % nodes).collect();
        assert_eq!(
            order
                .iter()
                .collect::<std::collections::BTreeSet<_>>()
                .len(),
            nodes
        );
        let dof = |j: usize| 3 * order[j / 3] + j % 3;
        for side in [Side::Lower, Side::Upper] {
            let a = permuted_shifted_csc(
                &model.pattern,
                &model.k,
                BlockMass::Scalar(&model.m),
                shift,
                &order,
                side,
            );
            for col in 0..n {
                let range = a.symbolic().col_range(col);
                let mut rows: Vec<usize> = a.symbolic().row_idx()[range.clone()].to_vec();
                for (&row, &value) in rows.iter().zip(&a.val()[range]) {
                    assert_eq!(
                        dense[dof(row) * n + dof(col)],
                        Some(value),
                        "{side:?} ({row}, {col})"
                    );
                }
                rows.sort_unstable();
                let want: Vec<usize> = (0..n)
                    .filter(|&row| {
                        if side == Side::Lower {
                            row >= col
                        } else {
                            row <= col
                        }
                    })
                    .filter(|&row| dense[dof(row) * n + dof(col)].is_some())
                    .collect();
                assert_eq!(rows, want, "{side:?} column {col}");
            }
        }
    }

    #[test]
    fn the_pattern_holds_exactly_the_pairs_that_share_an_element() {
        // Against the pairs listed one by one: hex8-like elements on a 3x2x2 lattice whose
        // node numbers are scrambled (so elements' nodes are not ascending), one node shared
        // by every element and one by none.
        let scramble = |n: u32| (n * 7 + 3) % 25; // a permutation of 0..25
        let mut elements = Vec::new();
        for (x, y) in [(0, 0), (1, 0), (2, 0), (0, 1), (1, 1)] {
            let corner = |dx: u32, dy: u32, dz: u32| scramble((x + dx) + 4 * ((y + dy) + 3 * dz));
            elements.extend((0..8).map(|i| corner(i & 1, (i >> 1) & 1, i >> 2)));
            elements.push(scramble(24)); // a ninth node shared by all (off the lattice)
        }
        let nodes = 26; // node 25 is in no element
        let pattern = BlockPattern::from_elements(nodes, &elements, 9);
        let mut want = vec![std::collections::BTreeSet::new(); nodes];
        for e in elements.chunks_exact(9) {
            for &a in e {
                want[a as usize].extend(e.iter().copied());
            }
        }
        for (a, row) in want.iter().enumerate() {
            let got = &pattern.col[pattern.row_ptr[a]..pattern.row_ptr[a + 1]];
            assert_eq!(
                got,
                row.iter().copied().collect::<Vec<_>>().as_slice(),
                "row {a}"
            );
        }
        let used: std::collections::BTreeSet<u32> = elements.iter().copied().collect();
        assert!(want[25].is_empty() && want[scramble(24) as usize] == used);
    }
}
