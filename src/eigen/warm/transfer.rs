//! Carrying the previous shape's vectors to an edited mesh: the first step of both warm
//! answers ([`super::solve`], [`super::ritz`]).
//!
//! Where it sits: after the edited shape's assembly, before either answer's products. The two
//! voxel sets are aligned first ([`align`]: a brush stroke at the edge of the object moves the
//! cropped grid's origin); a node that persists keeps its values, a new node takes the mean of
//! its persisting lattice neighbours.

use super::extra_rigid;
use crate::eigen::EigenSolution;
use crate::fem::FemModel;
use faer::MatRef;

/// Largest voxel offset between the previous and the new grid that [`align`] tries on each
/// axis (a stroke at the boundary moves the cropped origin by the brush radius at most).
const MAX_OFFSET: i64 = 4;

/// The previous mesh's eigenvectors on the new mesh.
#[derive(Clone, Debug)]
pub struct Transferred {
    /// Row-major `dofs x columns` block.
    pub block: Vec<f64>,
    /// Columns (modes carried).
    pub columns: usize,
    /// New nodes that existed before (kept their values).
    pub kept_nodes: usize,
    /// New nodes that did not (interpolated from neighbours, or zero).
    pub new_nodes: usize,
}

/// The voxel offset `d` that maps the most voxels of `next` onto voxels of `previous`
/// (element cells: blocks of voxels for [`crate::fem::ElementKind::Hex27Blocks`])
/// (`next` voxel `v` is `previous` voxel `v + d`), and that overlap's size. Offset zero wins
/// ties.
pub fn align(previous: &FemModel, next: &FemModel) -> ([i64; 3], usize) {
    align_voxels(&previous.voxels, previous.cell_dims(), &next.voxels)
}

/// [`align`] on voxel lists: `previous` lies in a grid of `previous_dims`.
pub fn align_voxels(
    previous: &[[usize; 3]],
    previous_dims: [usize; 3],
    next: &[[usize; 3]],
) -> ([i64; 3], usize) {
    let pd = previous_dims;
    let mut occupied = vec![false; pd.iter().product()];
    for v in previous {
        occupied[v[0] + pd[0] * (v[1] + pd[1] * v[2])] = true;
    }
    let overlap = |d: [i64; 3]| {
        next.iter()
            .filter(|v| {
                let q = [0, 1, 2].map(|a| v[a] as i64 + d[a]);
                (0..3).all(|a| q[a] >= 0 && q[a] < pd[a] as i64)
                    && occupied[q[0] as usize + pd[0] * (q[1] as usize + pd[1] * q[2] as usize)]
            })
            .count()
    };
    let mut best = ([0; 3], overlap([0; 3]));
    if best.1 == next.len().min(previous.len()) {
        return best;
    }
    for dz in -MAX_OFFSET..=MAX_OFFSET {
        for dy in -MAX_OFFSET..=MAX_OFFSET {
            for dx in -MAX_OFFSET..=MAX_OFFSET {
                let o = overlap([dx, dy, dz]);
                if o > best.1 {
                    best = ([dx, dy, dz], o);
                }
            }
        }
    }
    best
}

/// Carries `vectors` (columns over `previous`'s DOFs) to `next` (same element kind), with
/// the voxel offset `offset` from [`align`].
pub fn transfer(
    previous: &FemModel,
    vectors: MatRef<'_, f64>,
    next: &FemModel,
    offset: [i64; 3],
) -> Transferred {
    let sources = NodeSources::new(previous, next, offset);
    // A view whose columns are not contiguous (a transposed or strided one) is copied first.
    let owned;
    let vectors = if vectors.row_stride() == 1 {
        vectors
    } else {
        owned = vectors.to_owned();
        owned.as_ref()
    };
    let columns: Vec<&[f64]> = (0..vectors.ncols())
        .map(|j| column_slice(vectors, j))
        .collect();
    transfer_rows(&columns, next, &sources, 0)
}

/// Column `j` of a matrix with unit row stride (an owned matrix's, or a column range of one:
/// every matrix of an [`EigenSolution`]), as a slice.
fn column_slice(m: MatRef<'_, f64>, j: usize) -> &[f64] {
    m.col(j)
        .try_as_col_major()
        .expect("solution matrices are column-major")
        .as_slice()
}

/// Where each node of an edited mesh takes its carried values from.
#[derive(Clone, Debug)]
pub(super) struct NodeSources {
    /// Each node of `next` that existed in `previous` (the voxel offset from [`align`]
    /// applied): its previous node number, `u32::MAX` for a new node.
    pub map: Vec<u32>,
    /// Each new node, ascending, with the previous nodes at its persisting lattice neighbours
    /// (of the 26 around it, in a fixed order), whose mean it carries.
    pub fresh: Vec<(usize, Vec<usize>)>,
}

impl NodeSources {
    /// The sources of `next`'s nodes in `previous`, `offset` from [`align`].
    pub(super) fn new(previous: &FemModel, next: &FemModel, offset: [i64; 3]) -> Self {
        let lattice = PreviousLattice::new(previous, next, offset);
        let map: Vec<u32> = (0..next.nodes())
            .map(|node| {
                let q = lattice.place(next, node);
                lattice.node(q).map_or(u32::MAX, |o| o as u32)
            })
            .collect();
        let fresh = (map.iter().enumerate())
            .filter(|(_, &o)| o == u32::MAX)
            .map(|(node, _)| {
                let q = lattice.place(next, node);
                let around = (0..27i64).filter_map(|d| {
                    let step = [d % 3 - 1, (d / 3) % 3 - 1, d / 9 - 1];
                    lattice.node([0, 1, 2].map(|a| q[a] + step[a]))
                });
                (node, around.collect())
            })
            .collect();
        NodeSources { map, fresh }
    }
}

/// Where one node of an edited mesh takes its carried values from ([`NodeSources::source`]).
pub(super) enum Source<'a> {
    /// A node that persists: its previous node.
    Kept(usize),
    /// A new node: the previous nodes at its persisting neighbours, whose mean it carries
    /// (zero where there are none).
    Fresh(&'a [usize]),
}

impl NodeSources {
    /// Where node `node` of the new mesh takes its carried values from.
    pub(super) fn source(&self, node: usize) -> Source<'_> {
        match self.map[node] {
            u32::MAX => {
                let at = self.fresh.binary_search_by_key(&node, |(n, _)| *n);
                Source::Fresh(at.map_or(&[][..], |i| &self.fresh[i].1[..]))
            }
            o => Source::Kept(o as usize),
        }
    }
}

/// The previous model's lattice as the new one sees it.
struct PreviousLattice<'a> {
    previous: &'a FemModel,
    /// Lattice points per element along an axis, as `i64`.
    order: i64,
    offset: [i64; 3],
}

impl<'a> PreviousLattice<'a> {
    fn new(previous: &'a FemModel, next: &FemModel, offset: [i64; 3]) -> Self {
        PreviousLattice {
            previous,
            order: next.kind.order() as i64,
            offset,
        }
    }

    /// Where a node of `next` lies in the previous lattice.
    fn place(&self, next: &FemModel, node: usize) -> [i64; 3] {
        let here = next.node_lattice_coords(node);
        [0, 1, 2].map(|a| here[a] + self.order * self.offset[a])
    }

    /// The previous node at lattice point `q`, if any.
    fn node(&self, q: [i64; 3]) -> Option<usize> {
        let [plx, ply, plz] = self.previous.lattice.map(|v| v as i64);
        if (0..3).any(|a| q[a] < 0) || q[0] >= plx || q[1] >= ply || q[2] >= plz {
            return None;
        }
        let node = self.previous.lattice_node[(q[0] + plx * (q[1] + ply * q[2])) as usize];
        (node != u32::MAX).then_some(node as usize)
    }
}

/// [`transfer`] of the previous vectors `columns` (each over the previous model's DOFs) into
/// a block by rows of `lead + columns.len()` columns whose first `lead` are left zero for the
/// caller (the instant answer's rigid fields): one pass, read in place, each node from its
/// [`NodeSources`]. The kept nodes go in tiles of [`TILE_NODES`], column by column: each
/// column is read in order and the tile's rows stay in cache (reading a node's values across
/// all columns at once, or copying the columns by rows first, took longer).
pub(super) fn transfer_rows(
    columns: &[&[f64]],
    next: &FemModel,
    sources: &NodeSources,
    lead: usize,
) -> Transferred {
    let map = &sources.map;
    let n = next.dofs();
    let width = lead + columns.len();
    let mut block = vec![0.0; n * width];
    for start in (0..map.len()).step_by(TILE_NODES) {
        let tile = &map[start..(start + TILE_NODES).min(map.len())];
        for (j, column) in columns.iter().enumerate() {
            for (t, &old) in tile.iter().enumerate() {
                if old == u32::MAX {
                    continue;
                }
                let (src, dst) = (3 * old as usize, 3 * (start + t) * width + lead + j);
                block[dst] = column[src];
                block[dst + width] = column[src + 1];
                block[dst + 2 * width] = column[src + 2];
            }
        }
    }
    // A new node: the mean of its persisting lattice neighbours.
    for (node, sources) in &sources.fresh {
        let rows = &mut block[3 * node * width..3 * (node + 1) * width];
        for &o in sources {
            for (c, row) in rows.chunks_exact_mut(width).enumerate() {
                for (r, column) in row[lead..].iter_mut().zip(columns) {
                    *r += column[3 * o + c];
                }
            }
        }
        if !sources.is_empty() {
            let count = sources.len() as f64;
            for row in rows.chunks_exact_mut(width) {
                row[lead..].iter_mut().for_each(|v| *v /= count);
            }
        }
    }
    let fresh = sources.fresh.len();
    Transferred {
        block,
        columns: width,
        kept_nodes: map.len() - fresh,
        new_nodes: fresh,
    }
}

/// Nodes per tile of [`transfer_rows`].
const TILE_NODES: usize = 32;

/// The matrices whose columns a warm start carries: the extra rigid modes (if any,
/// [`extra_rigid`]), the modes, and at most `guards` guard vectors.
pub(super) fn previous_parts(previous: &EigenSolution, guards: usize) -> [MatRef<'_, f64>; 3] {
    let guards = previous.guard_vectors.ncols().min(guards);
    [
        extra_rigid(previous),
        previous.vectors.as_ref(),
        previous.guard_vectors.get(.., ..guards),
    ]
}

/// The columns of [`previous_parts`], in place.
pub(super) fn previous_columns(previous: &EigenSolution, guards: usize) -> Vec<&[f64]> {
    previous_parts(previous, guards)
        .into_iter()
        .flat_map(|part| (0..part.ncols()).map(move |j| column_slice(part, j)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::ElementKind;
    use crate::shape::primitives::Primitive;
    use faer::Mat;

    #[test]
    fn a_strided_view_transfers_as_its_copy() {
        // A view with non-contiguous columns (a transpose) is copied first, not refused.
        let grid = Primitive::Sphere { diameter: 5.0 }
            .rasterize(1.0, 1.0)
            .unwrap();
        let model = FemModel::assemble(&grid, ElementKind::Hex8Incompatible, 0.3).unwrap();
        let n = model.dofs();
        let rows = Mat::<f64>::from_fn(3, n, |j, i| (i * 7 + j * 3) as f64);
        let strided = rows.transpose();
        assert_ne!(strided.row_stride(), 1);
        let a = transfer(&model, strided, &model, [0; 3]);
        let b = transfer(&model, strided.to_owned().as_ref(), &model, [0; 3]);
        assert_eq!(a.block, b.block);
        assert_eq!((a.kept_nodes, a.new_nodes), (model.nodes(), 0));
        // The identity: row `i` holds the columns' values at DOF `i`.
        assert!((0..n).all(|i| (0..3).all(|j| a.block[i * 3 + j] == strided[(i, j)])));
    }
}
