//! The assembly's scatter: element matrices added into the node-blocked `K` and `M`.
//!
//! Where it sits: [`crate::fem::FemModel::assemble`] adds every element's matrices here, as
//! [`ElementBlocks`] (the unit element, cut elements from [`crate::fem::cut`], cached ones from
//! [`crate::fem::cache`]); the multigrid's coarse levels add dense Galerkin element matrices
//! ([`add_elements`]). Both find an element's blocks on the pattern with [`find_slots`].

use super::BlockPattern;

/// Adds element matrices into `k` and `m` (both on `pattern`). Element `e` has the nodes
/// `elements[e * nloc..(e + 1) * nloc]` and the dense matrices `matrices(e)`: `3 nloc` square,
/// row-major, DOFs node-major (`3 a + c`).
pub fn add_elements<'a>(
    pattern: &BlockPattern,
    elements: &[u32],
    nloc: usize,
    matrices: impl Fn(usize) -> (&'a [f64], &'a [f64]),
    k: &mut [[f64; 9]],
    m: &mut [f64],
) {
    let mut slots = vec![0usize; nloc * nloc];
    for (index, e) in elements.chunks_exact(nloc).enumerate() {
        let (ke, me) = matrices(index);
        add_element(pattern, e, ke, me, k, m, &mut slots);
    }
}

/// Adds one element's matrices `ke`, `me` (`3 nodes.len()` square, row-major, DOFs node-major)
/// into `k` and `m`; `slots` is scratch of `nodes.len()^2` entries.
///
/// # Panics
/// If `me` is not of the form `m_ab delta_cd`, exactly ([`super::MassBlocks`] holds no more).
pub fn add_element(
    pattern: &BlockPattern,
    nodes: &[u32],
    ke: &[f64],
    me: &[f64],
    k: &mut [[f64; 9]],
    m: &mut [f64],
    slots: &mut [usize],
) {
    let nloc = nodes.len();
    let ndof = 3 * nloc;
    find_slots(pattern, nodes, slots);
    for i in 0..nloc {
        for j in 0..nloc {
            let s = slots[i * nloc + j];
            let mass = me[3 * i * ndof + 3 * j];
            for c in 0..3 {
                for d in 0..3 {
                    let off = (3 * i + c) * ndof + 3 * j + d;
                    k[s][3 * c + d] += ke[off];
                    let want = if c == d { mass } else { 0.0 };
                    assert!(me[off] == want, "element mass is m_ab delta_cd");
                }
            }
            m[s] += mass;
        }
    }
}

/// The block of every node pair of an element on `pattern`, into `slots` (`slots[i n + j]` for
/// the pair `(nodes[i], nodes[j])`). An element's nodes in ascending order (every element the
/// voxel assembly builds: local order is lattice order) are found by one forward scan per row
/// after the first binary search; others by a binary search each.
pub fn find_slots(pattern: &BlockPattern, nodes: &[u32], slots: &mut [usize]) {
    const MISSING: &str = "pattern holds every element pair";
    let n = nodes.len();
    for (i, &a) in nodes.iter().enumerate() {
        let start = pattern.row_ptr[a as usize];
        let cols = &pattern.col[start..pattern.row_ptr[a as usize + 1]];
        let mut at = 0;
        for (j, &b) in nodes.iter().enumerate() {
            at = if at < cols.len() && cols[at] <= b {
                at + cols[at..].iter().position(|&c| c >= b).expect(MISSING)
            } else {
                cols.binary_search(&b).expect(MISSING)
            };
            assert!(cols[at] == b, "{MISSING}");
            slots[i * n + j] = start + at;
        }
    }
}

/// Node pairs `(a, b)` with `b >= a` of an element with `nodes` nodes: the entries of an
/// [`ElementBlocks`].
pub const fn node_pairs(nodes: usize) -> usize {
    nodes * (nodes + 1) / 2
}

/// One element's matrices as the assembly scatters them: for every node pair `(a, b)` with
/// `b >= a`, row by row (`(0, 0), (0, 1), .., (1, 1), ..`), the 3x3 stiffness block
/// `K(3a + c, 3b + d)` (row-major; symmetric where `a = b`) and the scalar mass `m_ab`: the mass of every element kind
/// is `M(3a + c, 3b + d) = m_ab delta_cd` (the same shape functions for the three components).
/// Half the dense matrices, and three numbers of every mass block instead of nine.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ElementBlocks {
    /// Stiffness blocks, one per node pair.
    pub k: Vec<[f64; 9]>,
    /// Scalar mass, one per node pair.
    pub m: Vec<f64>,
}

impl ElementBlocks {
    /// Zero matrices of an element with `nodes` nodes.
    pub fn zeros(nodes: usize) -> Self {
        let pairs = node_pairs(nodes);
        ElementBlocks {
            k: vec![[0.0; 9]; pairs],
            m: vec![0.0; pairs],
        }
    }

    /// The blocks of dense element matrices `ke`, `me` (`3 nodes` square, row-major, DOFs
    /// node-major); `ke` must be symmetric and `me` of the form `m_ab delta_cd` (the upper
    /// blocks and the first component's mass are read).
    pub fn from_dense(nodes: usize, ke: &[f64], me: &[f64]) -> Self {
        let ndof = 3 * nodes;
        assert!(
            ke.len() == ndof * ndof && me.len() == ndof * ndof,
            "3 n square matrices"
        );
        let mut out = Self::zeros(nodes);
        let mut pair = 0;
        for a in 0..nodes {
            for b in a..nodes {
                out.k[pair] = std::array::from_fn(|i| ke[(3 * a + i / 3) * ndof + 3 * b + i % 3]);
                out.m[pair] = me[3 * a * ndof + 3 * b];
                pair += 1;
            }
        }
        out
    }

    /// The dense matrices (`3 nodes` square, row-major) into `ke` and `me`.
    pub fn to_dense(&self, nodes: usize, ke: &mut [f64], me: &mut [f64]) {
        let ndof = 3 * nodes;
        assert!(
            ke.len() == ndof * ndof && me.len() == ndof * ndof,
            "3 n square matrices"
        );
        me.fill(0.0);
        let mut pair = 0;
        for a in 0..nodes {
            for b in a..nodes {
                let (blk, s) = (&self.k[pair], self.m[pair]);
                for c in 0..3 {
                    // A diagonal block's upper triangle (the blocks are symmetric there).
                    for d in if a == b { c..3 } else { 0..3 } {
                        ke[(3 * a + c) * ndof + 3 * b + d] = blk[3 * c + d];
                        ke[(3 * b + d) * ndof + 3 * a + c] = blk[3 * c + d];
                    }
                    me[(3 * a + c) * ndof + 3 * b + c] = s;
                    me[(3 * b + c) * ndof + 3 * a + c] = s;
                }
                pair += 1;
            }
        }
    }

    /// Multiplies the stiffness by `stiffness` and the mass by `mass`.
    pub fn scale(&mut self, stiffness: f64, mass: f64) {
        self.k.iter_mut().flatten().for_each(|v| *v *= stiffness);
        self.m.iter_mut().for_each(|v| *v *= mass);
    }
}

/// Adds one element's matrices `kb`, `mb` (an [`ElementBlocks`]'s) into `k` and `m`: each
/// pair's block into `(a, b)` and its transpose into `(b, a)`. `slots` holds the element's
/// block positions on the pattern of `k` and `m` ([`find_slots`], or
/// [`super::LatticeRows::slots`] on a lattice mesh). For a symmetric element with
/// `m_ab delta_cd` mass it adds the same numbers as [`add_element`] with the dense matrices.
#[inline]
pub fn add_element_blocks(
    slots: &[usize],
    kb: &[[f64; 9]],
    mb: &[f64],
    k: &mut [[f64; 9]],
    m: &mut [f64],
) {
    let n = slots.len().isqrt();
    debug_assert!(n * n == slots.len());
    debug_assert!(kb.len() == node_pairs(n) && mb.len() == node_pairs(n));
    let mut pair = 0;
    for i in 0..n {
        for j in i..n {
            let (b, s) = (&kb[pair], mb[pair]);
            let upper = slots[i * n + j];
            k[upper].iter_mut().zip(b).for_each(|(u, v)| *u += v);
            m[upper] += s;
            if j != i {
                add_transposed(&mut k[slots[j * n + i]], b);
                m[slots[j * n + i]] += s;
            }
            pair += 1;
        }
    }
}

/// Adds the transpose of a node pair's 3x3 block (row-major) into `lower`: the `(b, a)` block
/// of a symmetric matrix from its `(a, b)` one.
#[inline(always)]
fn add_transposed(lower: &mut [f64; 9], block: &[f64; 9]) {
    for c in 0..3 {
        for d in 0..3 {
            lower[3 * c + d] += block[3 * d + c];
        }
    }
}

/// Every row of an element: the mask [`add_element_rows`] takes to add all of it.
pub const ALL_ROWS: u32 = u32::MAX;

/// [`add_element_blocks`] restricted to the rows of the element's local nodes `i` whose bit
/// `rows & (1 << i)` is set (up to 32 nodes): a pair's block goes into `(a, b)` where `a`'s
/// row is wanted and its transpose into `(b, a)` where `b`'s is. Each entry of a wanted row
/// receives the same number as from [`add_element_blocks`], so summing elements in the same
/// order gives those rows bit for bit (an assembly that copies its other rows from an
/// earlier model: [`crate::fem::FemModel::assemble_after_edit`]).
#[inline]
pub fn add_element_rows(
    slots: &[usize],
    kb: &[[f64; 9]],
    mb: &[f64],
    k: &mut [[f64; 9]],
    m: &mut [f64],
    rows: u32,
) {
    let n = slots.len().isqrt();
    if rows == ALL_ROWS || (n < 32 && rows == (1 << n) - 1) {
        return add_element_blocks(slots, kb, mb, k, m);
    }
    debug_assert!(n * n == slots.len() && n <= 32);
    debug_assert!(kb.len() == node_pairs(n) && mb.len() == node_pairs(n));
    let wanted = |i: usize| rows & (1 << i) != 0;
    let mut pair = 0;
    for i in 0..n {
        for j in i..n {
            let (b, s) = (&kb[pair], mb[pair]);
            pair += 1;
            if wanted(i) {
                let upper = slots[i * n + j];
                k[upper].iter_mut().zip(b).for_each(|(u, v)| *u += v);
                m[upper] += s;
            }
            if j != i && wanted(j) {
                add_transposed(&mut k[slots[j * n + i]], b);
                m[slots[j * n + i]] += s;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A symmetric 3n x 3n stiffness and an `m_ab delta_cd` mass with distinct entries.
    fn element(nodes: usize) -> (Vec<f64>, Vec<f64>) {
        let n = 3 * nodes;
        let entry = |i: usize, j: usize| ((i.min(j) * 31 + i.max(j) * 17) % 23) as f64 - 11.0;
        let ke = (0..n * n).map(|x| entry(x / n, x % n)).collect();
        let me = (0..n * n)
            .map(|x| {
                let (i, j) = (x / n, x % n);
                if i % 3 == j % 3 {
                    entry(i / 3, j / 3) + 20.0
                } else {
                    0.0
                }
            })
            .collect();
        (ke, me)
    }

    /// Two hex8 elements sharing a face, node numbers not all ascending in the second.
    const TWO_HEX8: [u32; 16] = [0, 1, 2, 3, 4, 5, 6, 7, 1, 8, 3, 9, 5, 10, 11, 7];

    #[test]
    fn blocks_hold_the_dense_matrices_exactly() {
        let nodes = 8;
        let (ke, me) = element(nodes);
        let blocks = ElementBlocks::from_dense(nodes, &ke, &me);
        assert_eq!(blocks.k.len(), node_pairs(nodes));
        let (mut k2, mut m2) = (vec![1.0; ke.len()], vec![1.0; me.len()]);
        blocks.to_dense(nodes, &mut k2, &mut m2);
        assert!(k2 == ke && m2 == me);
    }

    #[test]
    fn the_block_scatter_adds_what_the_dense_scatter_adds() {
        // Two hex8 elements sharing a face (node numbers not all ascending in the second, so
        // `find_slots` takes its binary-search path too): the same numbers, bit for bit.
        let elements = TWO_HEX8;
        let pattern = BlockPattern::from_elements(12, &elements, 8);
        let (ke, me) = element(8);
        let blocks = ElementBlocks::from_dense(8, &ke, &me);
        let zeros = vec![[0.0; 9]; pattern.col.len()];
        let (mut kd, mut kb) = (zeros.clone(), zeros);
        let (mut md, mut mb) = (vec![0.0; pattern.col.len()], vec![0.0; pattern.col.len()]);
        let mut slots = vec![0; 64];
        for e in elements.chunks_exact(8) {
            add_element(&pattern, e, &ke, &me, &mut kd, &mut md, &mut slots);
            find_slots(&pattern, e, &mut slots);
            add_element_blocks(&slots, &blocks.k, &blocks.m, &mut kb, &mut mb);
        }
        assert!(kd == kb && md == mb);
        assert!(kd.iter().flatten().any(|&v| v != 0.0));
    }

    #[test]
    fn a_masked_scatter_adds_exactly_the_wanted_rows() {
        // Two hex8 elements sharing a face, the rows of a set of nodes wanted (each element's
        // mask picks its local nodes in the set): those rows hold what the whole scatter adds,
        // bit for bit, and the others nothing.
        let elements = TWO_HEX8;
        let pattern = BlockPattern::from_elements(12, &elements, 8);
        let (ke, me) = element(8);
        let blocks = ElementBlocks::from_dense(8, &ke, &me);
        let mut slots = vec![0; 64];
        let zeros = (
            vec![[0.0; 9]; pattern.col.len()],
            vec![0.0; pattern.col.len()],
        );
        let (mut kw, mut mw) = zeros.clone();
        for e in elements.chunks_exact(8) {
            find_slots(&pattern, e, &mut slots);
            add_element_blocks(&slots, &blocks.k, &blocks.m, &mut kw, &mut mw);
        }
        for set in [0u32, 1, 0b10, 0b1010_0101_0011, 0xfff] {
            let (mut km, mut mm) = zeros.clone();
            for e in elements.chunks_exact(8) {
                let mask = (e.iter().enumerate())
                    .filter(|(_, &a)| set & (1 << a) != 0)
                    .fold(0, |mask, (i, _)| mask | 1 << i);
                find_slots(&pattern, e, &mut slots);
                add_element_rows(&slots, &blocks.k, &blocks.m, &mut km, &mut mm, mask);
            }
            for a in 0..12 {
                for s in pattern.row_ptr[a]..pattern.row_ptr[a + 1] {
                    if set & (1 << a) != 0 {
                        assert!(km[s] == kw[s] && mm[s] == mw[s], "set {set:#x} row {a}");
                    } else {
                        assert!(km[s] == [0.0; 9] && mm[s] == 0.0, "set {set:#x} row {a}");
                    }
                }
            }
            assert!(set == 0 || km.iter().flatten().any(|&v| v != 0.0));
        }
    }

    #[test]
    #[should_panic(expected = "m_ab delta_cd")]
    fn a_mass_that_couples_components_is_refused() {
        let elements: Vec<u32> = (0..8).collect();
        let pattern = BlockPattern::from_elements(8, &elements, 8);
        let (ke, mut me) = element(8);
        me[1] = 1e-300;
        let (mut k, mut m) = (
            vec![[0.0; 9]; pattern.col.len()],
            vec![0.0; pattern.col.len()],
        );
        add_element(&pattern, &elements, &ke, &me, &mut k, &mut m, &mut [0; 64]);
    }

    #[test]
    fn slots_are_found_in_any_node_order() {
        let elements = TWO_HEX8;
        let pattern = BlockPattern::from_elements(12, &elements, 8);
        let mut slots = vec![0; 64];
        for e in elements.chunks_exact(8) {
            for order in [e.to_vec(), e.iter().rev().copied().collect()] {
                find_slots(&pattern, &order, &mut slots);
                for (i, &a) in order.iter().enumerate() {
                    for (j, &b) in order.iter().enumerate() {
                        assert_eq!(Some(slots[i * 8 + j]), pattern.find(a as usize, b));
                    }
                }
            }
        }
    }
}
