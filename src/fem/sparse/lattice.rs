//! The sparsity pattern and the element scatter's block positions of a lattice mesh, from
//! each node's neighbour offsets instead of searches.
//!
//! Where it sits: [`crate::fem::FemModel::assemble`] builds its elements on a node lattice
//! (nodes numbered in lattice order, each element's nodes in local lattice order, x fastest).
//! A node then couples only to nodes within `order` lattice steps on each axis, so its row of
//! the pattern is a subset of `(2 order + 1)^3` offsets: one bit each ([`LatticeRows`]). The
//! row's columns are the set bits in order (lattice order is node order, and the offsets'
//! lexicographic order `(dz, dy, dx)` is their lattice order), and the block of node pair
//! `(a, b)` is the row start plus the number of bits below `b`'s offset: a population count
//! where [`super::find_slots`] scans the row. [`BlockPattern::from_elements`] and
//! [`super::find_slots`] remain for meshes without a lattice (the multigrid's coarse levels).

use super::BlockPattern;
use crate::shape::lattice_coords;

/// Each node's neighbour offsets on a lattice mesh of order 1 or 2 (hex8, hex27).
#[derive(Clone, Debug)]
pub struct LatticeRows {
    /// Per node: bit `o` set where the node shares an element with the node at offset `o`
    /// (`o = (dx + p) + w ((dy + p) + w (dz + p))`, `w = 2 p + 1`, `p` the order).
    masks: Vec<u128>,
    /// Per local node pair `(i, j)` of an element (`i` major): the offset of node `j` seen from
    /// node `i`.
    pair_offset: Vec<u8>,
    /// Lattice steps per element edge.
    order: usize,
}

/// Offsets per axis and their count for lattice order `p`.
fn offsets(order: usize) -> (usize, usize) {
    let w = 2 * order + 1;
    (w, w * w * w)
}

impl LatticeRows {
    /// The rows of a mesh of `nodes` nodes whose elements (`(order + 1)^3` nodes each, in
    /// local lattice order, x fastest) are `elements`.
    ///
    /// # Panics
    /// If `order` is not 1 or 2.
    pub fn new(order: usize, nodes: usize, elements: &[u32]) -> Self {
        assert!(matches!(order, 1 | 2), "lattice order 1 or 2");
        let n1 = order + 1;
        let nloc = n1 * n1 * n1;
        let (w, _) = offsets(order);
        let local = |i: usize| lattice_coords(i, [n1; 3]);
        let offset = |i: usize, j: usize| {
            let (a, b) = (local(i), local(j));
            let d = [0, 1, 2].map(|k| b[k] + order - a[k]);
            d[0] + w * (d[1] + w * d[2])
        };
        let pair_offset: Vec<u8> = (0..nloc * nloc)
            .map(|ij| offset(ij / nloc, ij % nloc) as u8)
            .collect();
        // The offsets local node `i` sees within one element.
        let local_masks: Vec<u128> = (0..nloc)
            .map(|i| {
                pair_offset[i * nloc..(i + 1) * nloc]
                    .iter()
                    .fold(0u128, |m, &o| m | (1u128 << o))
            })
            .collect();
        let mut masks = vec![0u128; nodes];
        for element in elements.chunks_exact(nloc) {
            for (&a, &mask) in element.iter().zip(&local_masks) {
                masks[a as usize] |= mask;
            }
        }
        LatticeRows {
            masks,
            pair_offset,
            order,
        }
    }

    /// The pattern: node `a`'s columns are the nodes at its offsets. `node_lattice[a]` is node
    /// `a`'s lattice index, `lattice_node` its inverse (`u32::MAX` where there is no node), on
    /// a lattice of `lattice` points per axis. The same pattern as
    /// [`BlockPattern::from_elements`] on the same elements.
    pub fn pattern(
        &self,
        node_lattice: &[usize],
        lattice_node: &[u32],
        lattice: [usize; 3],
    ) -> BlockPattern {
        let p = self.order as isize;
        let (w, count) = offsets(self.order);
        let (lx, ly) = (lattice[0] as isize, lattice[1] as isize);
        let delta: Vec<isize> = (0..count)
            .map(|o| {
                let d = lattice_coords(o, [w; 3]).map(|c| c as isize - p);
                d[0] + lx * (d[1] + ly * d[2])
            })
            .collect();
        let entries: usize = self.masks.iter().map(|m| m.count_ones() as usize).sum();
        let mut row_ptr = Vec::with_capacity(self.masks.len() + 1);
        let mut col = Vec::with_capacity(entries);
        row_ptr.push(0);
        for (&mask, &at) in self.masks.iter().zip(node_lattice) {
            let mut bits = mask;
            while bits != 0 {
                let o = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let neighbour = (at as isize + delta[o]) as usize;
                col.push(lattice_node[neighbour]);
            }
            row_ptr.push(col.len());
        }
        debug_assert!(col.iter().all(|&c| c != u32::MAX), "every offset is a node");
        BlockPattern { row_ptr, col }
    }

    /// The block of every node pair of an element on `pattern` (from [`LatticeRows::pattern`])
    /// into `slots`, as [`super::find_slots`] gives them: `slots[i n + j]` for the pair
    /// `(nodes[i], nodes[j])`, `nodes` in local lattice order.
    #[inline]
    pub fn slots(&self, pattern: &BlockPattern, nodes: &[u32], slots: &mut [usize]) {
        let n = nodes.len();
        debug_assert_eq!(n * n, self.pair_offset.len());
        for (i, &a) in nodes.iter().enumerate() {
            let start = pattern.row_ptr[a as usize];
            let mask = self.masks[a as usize];
            let offsets = &self.pair_offset[i * n..(i + 1) * n];
            for (slot, &o) in slots[i * n..(i + 1) * n].iter_mut().zip(offsets) {
                let below = (1u128 << o) - 1;
                *slot = start + (mask & below).count_ones() as usize;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::sparse::find_slots;
    use crate::shape::lattice_index;

    /// A lattice mesh of order `p` on a scattered set of cells of an `nx x ny x nz` grid
    /// (holes, isolated cells, thin bridges): `(elements, node_lattice, lattice_node,
    /// lattice)`, numbered as the assembly numbers them.
    fn mesh(p: usize, dims: [usize; 3]) -> (Vec<u32>, Vec<usize>, Vec<u32>, [usize; 3]) {
        let lattice = dims.map(|d| p * d + 1);
        let idx = |c: [usize; 3]| lattice_index(c, lattice);
        let cells: Vec<[usize; 3]> = (0..dims.iter().product::<usize>())
            .filter(|i| (i * 7919) % 13 < 8)
            .map(|i| lattice_coords(i, dims))
            .collect();
        let n1 = p + 1;
        let local = |c: [usize; 3], l: usize| {
            let d = lattice_coords(l, [n1; 3]);
            idx([0, 1, 2].map(|a| p * c[a] + d[a]))
        };
        let mut lattice_node = vec![u32::MAX; lattice.iter().product()];
        for &c in &cells {
            for l in 0..n1 * n1 * n1 {
                lattice_node[local(c, l)] = 0;
            }
        }
        let mut node_lattice = Vec::new();
        for (i, slot) in lattice_node.iter_mut().enumerate() {
            if *slot == 0 {
                *slot = node_lattice.len() as u32;
                node_lattice.push(i);
            }
        }
        let elements = cells
            .iter()
            .flat_map(|&c| (0..n1 * n1 * n1).map(move |l| (c, l)))
            .map(|(c, l)| lattice_node[local(c, l)])
            .collect();
        (elements, node_lattice, lattice_node, lattice)
    }

    #[test]
    fn rows_and_slots_match_the_searched_ones() {
        // The independent truth: the pattern from each node's elements (marks and sorts) and
        // the slots from a search of each row. Exactly equal, for hex8's and hex27's lattices,
        // including a grid one cell thick on x (the offsets' order must not depend on it).
        for (p, dims) in [
            (1, [5, 4, 6]),
            (2, [4, 5, 3]),
            (1, [1, 4, 3]),
            (2, [1, 3, 4]),
        ] {
            let (elements, node_lattice, lattice_node, lattice) = mesh(p, dims);
            let nloc = (p + 1).pow(3);
            let rows = LatticeRows::new(p, node_lattice.len(), &elements);
            let pattern = rows.pattern(&node_lattice, &lattice_node, lattice);
            let want = BlockPattern::from_elements(node_lattice.len(), &elements, nloc);
            assert_eq!(pattern.row_ptr, want.row_ptr, "order {p}, {dims:?}");
            assert_eq!(pattern.col, want.col, "order {p}, {dims:?}");
            let (mut got, mut searched) = (vec![0; nloc * nloc], vec![0; nloc * nloc]);
            for element in elements.chunks_exact(nloc) {
                rows.slots(&pattern, element, &mut got);
                find_slots(&want, element, &mut searched);
                assert_eq!(got, searched, "order {p}, {dims:?}");
            }
            assert!(
                elements.len() > 4 * nloc,
                "{} elements",
                elements.len() / nloc
            );
        }
    }
}
