//! The multigrid hierarchy, built once per solve: hex27 to hex8 on the same voxels, then 2x2x2
//! coarsening of the cells, trilinear prolongation, and Galerkin coarse operators `P^T A P`
//! formed cell by cell from a memoised table of distinct child matrices (the module docs of
//! [`super`] say why).
//!
//! Where it sits: called by [`super::Multigrid::new`]; the V-cycle ([`super`]) applies the
//! levels and prolongations made here.

use super::{CellMesh, Level, Prolongation};
use crate::buffer::zeroed;
use crate::fem::sparse::{self, BlockPattern, Blocks, MassBlocks};
use crate::shape::{lattice_coords, lattice_index};
use std::collections::HashMap;

/// Trilinear weights of a parent cell's 8 corners (x fastest) at a point `t` in `[0, 1]^3`.
pub(super) fn trilinear(t: [f64; 3]) -> [f64; 8] {
    let mut w = [0.0; 8];
    for (c, wc) in w.iter_mut().enumerate() {
        let corner = [c & 1, (c >> 1) & 1, c >> 2];
        *wc = (0..3)
            .map(|a| 1.0 - (t[a] - corner[a] as f64).abs())
            .product();
    }
    w
}

/// `p[i * 8 + I]`: weight of parent corner `I` at the child (octant `o`) node `i`.
pub(super) fn octant_interpolation(o: [usize; 3]) -> Vec<f64> {
    let mut p = Vec::with_capacity(64);
    for i in 0..8 {
        let local = [i & 1, (i >> 1) & 1, i >> 2];
        let t = [0, 1, 2].map(|a| (o[a] + local[a]) as f64 / 2.0);
        p.extend_from_slice(&trilinear(t));
    }
    p
}

/// `p[i * 8 + I]` for the 27 hex27 nodes (x fastest) of a cell from its 8 corners.
pub(super) fn hex27_to_hex8() -> Vec<f64> {
    let mut p = Vec::with_capacity(27 * 8);
    for i in 0..27 {
        let t = [i % 3, (i / 3) % 3, i / 9].map(|v| v as f64 / 2.0);
        p.extend_from_slice(&trilinear(t));
    }
    p
}

/// `P^T A P` with `P = p (x) I_3`: `a` is `3 nf` square (node-major DOFs), `p` is `nf x 8`.
pub(super) fn galerkin(a: &[f64], p: &[f64], nf: usize) -> Vec<f64> {
    let nd = 3 * nf;
    // ap = A P: nd x 24.
    let mut ap = vec![0.0; nd * 24];
    for r in 0..nd {
        for i in 0..nf {
            for d in 0..3 {
                let v = a[r * nd + 3 * i + d];
                if v == 0.0 {
                    continue;
                }
                for big in 0..8 {
                    ap[r * 24 + 3 * big + d] += v * p[i * 8 + big];
                }
            }
        }
    }
    let mut out = vec![0.0; 24 * 24];
    for i in 0..nf {
        for big in 0..8 {
            let w = p[i * 8 + big];
            if w == 0.0 {
                continue;
            }
            for c in 0..3 {
                let row = &ap[(3 * i + c) * 24..(3 * i + c + 1) * 24];
                for (o, v) in out[(3 * big + c) * 24..(3 * big + c + 1) * 24]
                    .iter_mut()
                    .zip(row)
                {
                    *o += w * v;
                }
            }
        }
    }
    out
}

/// The 2x2x2-coarser mesh with Galerkin cell matrices.
pub(super) fn coarsen(fine: &CellMesh) -> CellMesh {
    let dims = fine.dims.map(|d| d.div_ceil(2));
    let index = |c: [usize; 3]| lattice_index(c, dims);
    let mut children = vec![[u32::MAX; 8]; dims.iter().product()];
    for (cell, &id) in fine.cells.iter().zip(&fine.matrix) {
        let parent = cell.map(|v| v / 2);
        let octant = (cell[0] & 1) | ((cell[1] & 1) << 1) | ((cell[2] & 1) << 2);
        children[index(parent)][octant] = id;
    }
    let interp: Vec<Vec<f64>> = (0..8)
        .map(|o| octant_interpolation([o & 1, (o >> 1) & 1, o >> 2]))
        .collect();
    let mut memo: HashMap<[u32; 8], u32> = HashMap::new();
    let mut out = CellMesh {
        dims,
        cells: Vec::new(),
        matrix: Vec::new(),
        k_table: Vec::new(),
        m_table: Vec::new(),
    };
    for (i, kids) in children.iter().enumerate() {
        if kids.iter().all(|&k| k == u32::MAX) {
            continue;
        }
        let id = *memo.entry(*kids).or_insert_with(|| {
            let mut k = vec![0.0; 576];
            let mut m = vec![0.0; 576];
            for (o, &kid) in kids.iter().enumerate() {
                if kid == u32::MAX {
                    continue;
                }
                let kid = kid as usize;
                let gk = galerkin(&fine.k_table[kid], &interp[o], 8);
                let gm = galerkin(&fine.m_table[kid], &interp[o], 8);
                k.iter_mut().zip(gk).for_each(|(a, b)| *a += b);
                m.iter_mut().zip(gm).for_each(|(a, b)| *a += b);
            }
            out.k_table.push(k);
            out.m_table.push(m);
            (out.k_table.len() - 1) as u32
        });
        out.cells.push(lattice_coords(i, dims));
        out.matrix.push(id);
    }
    out
}

/// Assembles a cell mesh: the level (with `a` empty) and its `K`, `M`.
pub(super) fn assemble(mesh: &CellMesh) -> (Level, Blocks, MassBlocks) {
    let lattice = mesh.dims.map(|d| d + 1);
    let lidx = |x: usize, y: usize, z: usize| lattice_index([x, y, z], lattice);
    let mut lattice_node = vec![u32::MAX; lattice.iter().product()];
    let corners = |c: [usize; 3]| {
        (0..8).map(move |i| lidx(c[0] + (i & 1), c[1] + ((i >> 1) & 1), c[2] + (i >> 2)))
    };
    for c in &mesh.cells {
        for l in corners(*c) {
            lattice_node[l] = 0;
        }
    }
    let mut coords = Vec::new();
    for (l, slot) in lattice_node.iter_mut().enumerate() {
        if *slot == 0 {
            *slot = coords.len() as u32;
            coords.push(lattice_coords(l, lattice).map(|c| c as i64));
        }
    }
    let elements: Vec<u32> = mesh
        .cells
        .iter()
        .flat_map(|c| corners(*c).map(|l| lattice_node[l]).collect::<Vec<_>>())
        .collect();
    let pattern = BlockPattern::from_elements(coords.len(), &elements, 8);
    let mut k = zeroed(pattern.col.len());
    let mut m = zeroed(pattern.col.len());
    sparse::add_elements(
        &pattern,
        &elements,
        8,
        |e| {
            let id = mesh.matrix[e] as usize;
            (&mesh.k_table[id][..], &mesh.m_table[id][..])
        },
        &mut k,
        &mut m,
    );
    (
        Level::new(pattern, Vec::new(), lattice, lattice_node, coords),
        k,
        m,
    )
}

/// Trilinear interpolation from `coarse` (lattice spacing 2 in fine lattice steps) to the fine
/// nodes at `fine_coords`.
pub(super) fn prolongation(fine_coords: &[[i64; 3]], coarse: &Level) -> Prolongation {
    let mut out = Prolongation {
        row_ptr: vec![0],
        coarse: Vec::new(),
        weight: Vec::new(),
    };
    for c in fine_coords {
        let axis = |v: i64| -> ([usize; 2], [f64; 2], usize) {
            if v % 2 == 0 {
                ([(v / 2) as usize, 0], [1.0, 0.0], 1)
            } else {
                ([(v / 2) as usize, (v / 2 + 1) as usize], [0.5, 0.5], 2)
            }
        };
        let (ix, wx, nx) = axis(c[0]);
        let (iy, wy, ny) = axis(c[1]);
        let (iz, wz, nz) = axis(c[2]);
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    let node =
                        coarse.lattice_node[lattice_index([ix[x], iy[y], iz[z]], coarse.lattice)];
                    debug_assert!(node != u32::MAX, "a fine node outside every coarse cell");
                    if node != u32::MAX {
                        out.coarse.push(node);
                        out.weight.push(wx[x] * wy[y] * wz[z]);
                    }
                }
            }
        }
        out.row_ptr.push(out.coarse.len());
    }
    out
}
