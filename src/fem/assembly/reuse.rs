//! An assembly after a local edit: rows of `K` and `M` that no changed element reaches are
//! copied from the model before the edit, and only the rest are summed.
//!
//! Where it sits: [`crate::fem::FemModel::assemble_after_edit`] (a brush stroke's carried
//! answer, [`crate::basis::ModeBasis::carried_ritz`]) plans a [`Reuse`] once the new mesh's
//! nodes and pattern are known; the element loop of the assembly then skips the elements with
//! no touched node and adds only the touched rows of the others
//! ([`crate::fem::sparse::add_element_rows`]) into the rows [`Reuse::prefill`] cleared, the
//! rest copied by it.
//! A stroke changes a few cells of a mesh of thousands, so a cached assembly then spends its
//! time on the copy instead of on keying, looking up and scattering every element (the
//! ceramic cup's: ~60 % of its time was the scatter and the cache keys).
//!
//! **Which rows.** Row `a` is the sum over the elements holding node `a` of their blocks,
//! in element order. It is unchanged where every such element is unchanged: present in both
//! meshes with the same matrices. An element's matrices are a function of its voxels' fills
//! and, for refined fills, of a one-voxel ring around them ([`crate::fem::cache`]'s key), so
//! the changed elements are the cells whose fill fingerprints differ ([`FemModel::cell_fills`];
//! 64-bit FNV-1a, as [`crate::eigen::warm`] finds an edit), the cells added or removed, and
//! every cell within one cell of those. Their lattice points are the touched rows. An
//! untouched row's columns are the same lattice points in both meshes, and both number their
//! nodes in lattice order, so the row is the previous row's blocks in the same order: one
//! copy. The plan checks each untouched row's length against the previous one and gives up
//! (a full assembly) on any mismatch.
//!
//! **Rows not held.** The engine's carried answer reads `K` and `M` only within a few cells
//! of the stroke ([`crate::eigen::warm::rows_read_radius_cells`]), and nothing reads its
//! model's matrices after it. [`FemModel::assemble_near_edit`] copies only the untouched rows
//! within that radius and leaves the rest of the buffers as they were (the copy was 6-10 ms of
//! the ceramic cup's answer, a 35 MB `K`). Such a model records which rows it holds and the
//! whole matrices' traces (the previous model's updated near the edit, [`Reuse::traces`]),
//! and refuses [`FemModel::k`] and [`FemModel::m`]; a later edit assembles in full from it.

use crate::fem::sparse::{BlockPattern, Blocks, MassBlocks};
use crate::fem::{ElementKind, FemModel};
use crate::shape::lattice_index;

/// Most changed cells (added, removed or refilled) a reuse is planned for, as a share of
/// the new mesh's cells: a larger edit is not a brush stroke, and its touched rows would be
/// most of the model.
const MAX_CHANGED_SHARE: f64 = 1.0 / 16.0;

/// The new mesh as the assembly has numbered it, before any element is added.
pub(super) struct Mesh<'a> {
    pub kind: ElementKind,
    pub poisson_ratio: f64,
    pub voxel_dims: [usize; 3],
    pub lattice: [usize; 3],
    /// The element cells, in element order.
    pub voxels: &'a [[usize; 3]],
    pub node_lattice: &'a [usize],
    pub lattice_node: &'a [u32],
    pub pattern: &'a BlockPattern,
}

/// What an assembly after an edit sums and what it copies.
pub(super) struct Reuse<'a> {
    previous: &'a FemModel,
    /// Per element: whether it is full (the unit element) and its fills' fingerprint.
    states: Vec<(bool, u64)>,
    /// Per node of the new mesh: whether its rows are summed (else copied).
    touched: Vec<bool>,
    /// The new mesh's node numbers by lattice index (to find an element's touched nodes).
    node_lattice: &'a [usize],
    /// The new mesh's lattice index -> node number (`u32::MAX` where unused).
    lattice_node: &'a [u32],
    /// The cells added, removed or refilled.
    changed: Vec<[usize; 3]>,
    /// Per node of the new mesh: whether its rows are held at all (`None`: every row is).
    /// A model assembled near an edit ([`FemModel::assemble_near_edit`]) copies only the
    /// untouched rows within its radius.
    held: Option<Vec<bool>>,
}

impl<'a> Reuse<'a> {
    /// The plan for `mesh` after `previous`, the element `states` ([`Reuse::state`]) computed
    /// by the caller, every row held or (`held_radius`) only those of the nodes within that
    /// many cells of a changed one; `None` where the whole model must be summed (a previous
    /// model that is not whole among the reasons: its rows are not all there to copy).
    pub fn plan(
        previous: &'a FemModel,
        mesh: &Mesh<'a>,
        states: Vec<(bool, u64)>,
        held_radius: Option<usize>,
    ) -> Option<Self> {
        let same_integrand = previous.kind == mesh.kind
            && previous.poisson_ratio.to_bits() == mesh.poisson_ratio.to_bits();
        if !same_integrand
            || !previous.is_whole()
            || previous.voxel_dims != mesh.voxel_dims
            || previous.lattice != mesh.lattice
            || previous.cell_fills.len() != previous.voxels.len()
        {
            return None;
        }
        let cells = previous.cell_dims();
        let cell_index = |c: [usize; 3]| lattice_index(c, cells);
        // The previous element on each cell, and which cells the new mesh has.
        let mut previous_at = vec![u32::MAX; cells.iter().product()];
        for (e, &c) in previous.voxels.iter().enumerate() {
            previous_at[cell_index(c)] = e as u32;
        }
        let mut present = vec![false; previous_at.len()];
        let mut changed = Vec::new();
        for (&c, &(_, fingerprint)) in mesh.voxels.iter().zip(&states) {
            let at = cell_index(c);
            present[at] = true;
            let same = previous_at[at] != u32::MAX
                && previous.cell_fills[previous_at[at] as usize] == fingerprint;
            if !same {
                changed.push(c);
            }
        }
        changed.extend(previous.voxels.iter().filter(|&&c| !present[cell_index(c)]));
        if changed.len() as f64 > MAX_CHANGED_SHARE * mesh.voxels.len() as f64 {
            return None;
        }
        let touched = nodes_within(mesh, cells, &changed, 1);
        let held = held_radius.map(|r| nodes_within(mesh, cells, &changed, r.max(1)));
        // Every untouched row lines up with the previous model's.
        for (a, _) in touched.iter().enumerate().filter(|(_, &t)| !t) {
            let o = previous.lattice_node[mesh.node_lattice[a]];
            if o == u32::MAX || row_len(mesh.pattern, a) != row_len(&previous.pattern, o as usize) {
                return None;
            }
            debug_assert!(
                row(mesh.pattern, a)
                    .zip(row(&previous.pattern, o as usize))
                    .all(|(n, p)| mesh.node_lattice[n] == previous.node_lattice[p]),
                "an untouched row has the previous row's columns"
            );
        }
        Some(Reuse {
            previous,
            states,
            touched,
            node_lattice: mesh.node_lattice,
            lattice_node: mesh.lattice_node,
            changed,
            held,
        })
    }

    /// Per node whether its rows are held (`None`: every row), for the model.
    pub fn held(&self) -> Option<&[bool]> {
        self.held.as_deref()
    }

    /// Element `e`'s `(full, fingerprint)`: [`super::block_state`] of its cell.
    pub fn state(&self, e: usize) -> (bool, u64) {
        self.states[e]
    }

    /// The bit mask of an element's nodes whose rows are summed here
    /// ([`crate::fem::sparse::add_element_rows`]); 0 where the element can be skipped.
    pub fn rows_of(&self, nodes: &[u32]) -> u32 {
        debug_assert!(nodes.len() <= 32);
        (nodes.iter().enumerate())
            .filter(|(_, &a)| self.touched[a as usize])
            .fold(0, |mask, (i, _)| mask | 1 << i)
    }

    /// Fills `k` and `m` (on `pattern`, buffers of unspecified values) before the element
    /// loop: every untouched row that is held copied from the previous model, every touched
    /// row zeroed for the loop to sum into. The rows not held are left as they were.
    pub fn prefill(&self, pattern: &BlockPattern, k: &mut Blocks, m: &mut MassBlocks) {
        let previous = self.previous;
        for (a, &touched) in self.touched.iter().enumerate() {
            let to = pattern.row_ptr[a]..pattern.row_ptr[a + 1];
            if self.held.as_ref().is_some_and(|h| !h[a]) {
                continue;
            }
            if touched {
                k[to.clone()].fill([0.0; 9]);
                m[to].fill(0.0);
            } else {
                let o = previous.lattice_node[self.node_lattice[a]] as usize;
                let from = previous.pattern.row_ptr[o]..previous.pattern.row_ptr[o + 1];
                k[to.clone()].copy_from_slice(&previous.k[from.clone()]);
                m[to].copy_from_slice(&previous.m[from]);
            }
        }
    }

    /// `trace K` and `trace M` of the new model once the element loop has summed `k` and `m`:
    /// the previous model's ([`FemModel::traces`]), less the diagonal blocks of its rows that
    /// were summed here again or whose nodes the edit removed, plus those summed here. An
    /// untouched row is the previous one, so this is the whole sum, in another order (to
    /// rounding): a pass over the rows near the edit instead of over every node's diagonal
    /// block, scattered over the matrices (2 ms of the ceramic cup's carried answer).
    pub fn traces(&self, pattern: &BlockPattern, k: &Blocks, m: &MassBlocks) -> [f64; 2] {
        let previous = self.previous;
        let [mut trace_k, mut trace_m] = previous.traces();
        let diagonal = |pattern: &BlockPattern, k: &Blocks, m: &MassBlocks, a: usize| {
            let b = pattern.find(a, a as u32).expect("diagonal block");
            (k[b][0] + k[b][4] + k[b][8], 3.0 * m[b])
        };
        let (pk, pm) = (&previous.k, &previous.m);
        for (a, _) in self.touched.iter().enumerate().filter(|(_, &t)| t) {
            let (dk, dm) = diagonal(pattern, k, m, a);
            (trace_k, trace_m) = (trace_k + dk, trace_m + dm);
            let o = previous.lattice_node[self.node_lattice[a]];
            if o != u32::MAX {
                let (dk, dm) = diagonal(&previous.pattern, pk, pm, o as usize);
                (trace_k, trace_m) = (trace_k - dk, trace_m - dm);
            }
        }
        // A node the edit removed is a lattice point of a removed cell, which is changed.
        let p = previous.kind.order();
        let mut removed: Vec<usize> = Vec::new();
        for c in &self.changed {
            for z in p * c[2]..=p * (c[2] + 1) {
                for y in p * c[1]..=p * (c[1] + 1) {
                    for x in p * c[0]..=p * (c[0] + 1) {
                        let l = lattice_index([x, y, z], previous.lattice);
                        if self.lattice_node[l] == u32::MAX && previous.lattice_node[l] != u32::MAX
                        {
                            removed.push(previous.lattice_node[l] as usize);
                        }
                    }
                }
            }
        }
        removed.sort_unstable();
        removed.dedup();
        for o in removed {
            let (dk, dm) = diagonal(&previous.pattern, pk, pm, o);
            (trace_k, trace_m) = (trace_k - dk, trace_m - dm);
        }
        [trace_k, trace_m]
    }
}

/// Per node of `mesh`: whether it lies on a cell within `radius` cells (Chebyshev) of a
/// `changed` one (cells of a grid of `cells` per axis).
fn nodes_within(
    mesh: &Mesh<'_>,
    cells: [usize; 3],
    changed: &[[usize; 3]],
    radius: usize,
) -> Vec<bool> {
    let p = mesh.kind.order();
    let mut touched = vec![false; mesh.node_lattice.len()];
    for c in changed {
        // The lattice points of the cells from c - radius to c + radius (clipped to the grid).
        let lo = c.map(|x| p * x.saturating_sub(radius));
        let hi = [0, 1, 2].map(|a| p * (c[a] + 1 + radius).min(cells[a]));
        for z in lo[2]..=hi[2] {
            for y in lo[1]..=hi[1] {
                for x in lo[0]..=hi[0] {
                    let node = mesh.lattice_node[lattice_index([x, y, z], mesh.lattice)];
                    if node != u32::MAX {
                        touched[node as usize] = true;
                    }
                }
            }
        }
    }
    touched
}

fn row_len(pattern: &BlockPattern, a: usize) -> usize {
    pattern.row_ptr[a + 1] - pattern.row_ptr[a]
}

fn row(pattern: &BlockPattern, a: usize) -> impl Iterator<Item = usize> + '_ {
    pattern.col[pattern.row_ptr[a]..pattern.row_ptr[a + 1]]
        .iter()
        .map(|&c| c as usize)
}

#[cfg(test)]
mod tests {
    use crate::fem::{ElementCache, ElementKind, FemModel};
    use crate::shape::primitives::Primitive;
    use crate::shape::{lattice_coords, VoxelGrid};

    /// Large enough that hex27x2's 2-voxel cells within two of a stroke are a part of it.
    fn bowl() -> VoxelGrid {
        Primitive::Bowl {
            diameter: 20.0,
            wall: 2.0,
        }
        .rasterize(1.0, 1.0)
        .unwrap()
    }

    /// The bits of each value (NaN-safe equality).
    fn bits(x: &[f64]) -> Vec<u64> {
        x.iter().map(|v| v.to_bits()).collect()
    }

    /// Whether two models are the same to the bit (numbering, pattern, `K`, `M`, fills).
    fn identical(a: &FemModel, b: &FemModel) -> bool {
        a.node_lattice == b.node_lattice
            && a.elements == b.elements
            && a.cell_fills == b.cell_fills
            && a.pattern.row_ptr == b.pattern.row_ptr
            && a.pattern.col == b.pattern.col
            && bits(a.k.as_flattened()) == bits(b.k.as_flattened())
            && bits(&a.m) == bits(&b.m)
    }

    /// The edits: a partial voxel made full, a surface voxel removed, an empty voxel beside
    /// the surface filled, and a third of the voxels removed (not a stroke: summed in full).
    fn edits(grid: &VoxelGrid) -> Vec<(&'static str, VoxelGrid)> {
        let d = grid.dims();
        let at = |i: usize| lattice_coords(i, d);
        let solid = |v: [usize; 3]| grid.get(v[0] as isize, v[1] as isize, v[2] as isize);
        let beside = |v: [usize; 3]| {
            let v = v.map(|c| c as isize);
            [
                (1, 0, 0),
                (-1, 0, 0),
                (0, 1, 0),
                (0, -1, 0),
                (0, 0, 1),
                (0, 0, -1),
            ]
            .iter()
            .filter(|(x, y, z)| grid.get(v[0] + x, v[1] + y, v[2] + z))
            .count()
        };
        let voxels: Vec<[usize; 3]> = (0..d.iter().product()).map(at).collect();
        let mut out = Vec::new();
        let (i, _) = grid.partial_voxels().next().unwrap();
        let mut filled = grid.clone();
        filled.set(at(i)[0], at(i)[1], at(i)[2], true);
        out.push(("a partial voxel filled", filled));
        let surface = *voxels.iter().find(|&&v| solid(v) && beside(v) < 6).unwrap();
        let mut removed = grid.clone();
        removed.set(surface[0], surface[1], surface[2], false);
        out.push(("a surface voxel removed", removed));
        let outside = *voxels
            .iter()
            .find(|&&v| !solid(v) && beside(v) > 0)
            .unwrap();
        let mut added = grid.clone();
        added.set(outside[0], outside[1], outside[2], true);
        out.push(("a voxel added", added));
        let mut cut = grid.clone();
        for v in voxels.iter().filter(|v| v[2] < d[2] / 3) {
            cut.set(v[0], v[1], v[2], false);
        }
        out.push(("a third removed", cut));
        out
    }

    #[test]
    fn an_assembly_after_an_edit_is_the_full_cached_one_to_the_bit() {
        // The truth is the full cached assembly of the edited grid with the same cache. Where
        // the model before the edit was assembled with every element from the cache (its rows
        // summed in element order), every row must be the same sum in the same order, so the
        // models must agree bit for bit: the copied rows are the earlier sums of unchanged
        // elements, the summed ones the same elements' blocks added in the same order. A
        // stroke must be assembled from the elements near it: at most the 5^3 cells within
        // two of it (those sharing a node with a changed element's neighbour), against the
        // whole object's cut elements in full.
        for kind in [
            ElementKind::Hex8Incompatible,
            ElementKind::Hex27Blocks,
            ElementKind::Hex27,
        ] {
            let grid = bowl();
            let mut cache = ElementCache::new();
            FemModel::assemble_cached(&grid, kind, 0.24, Some(&mut cache)).unwrap();
            let previous = FemModel::assemble_cached(&grid, kind, 0.24, Some(&mut cache)).unwrap();
            assert_eq!(cache.stats().misses, 0, "{kind}: every element cached");
            for (edit, edited) in edits(&grid) {
                let (mut partial, mut whole) = (cache.clone(), cache.clone());
                // Kept buffers full of NaNs: a row neither copied nor cleared would show.
                crate::buffer::poison_kept(2 * previous.k.len());
                let after = FemModel::assemble_after_edit(
                    &edited,
                    kind,
                    0.24,
                    &previous,
                    Some(&mut partial),
                )
                .unwrap();
                let full =
                    FemModel::assemble_cached(&edited, kind, 0.24, Some(&mut whole)).unwrap();
                assert!(
                    identical(&after, &full),
                    "{kind}, {edit}: not the same bits"
                );
                // Near the edit only: the same rows where held, the whole model's traces, and
                // (a stroke) rows far from it not held. NaNs kept again: a held row neither
                // copied nor cleared would show.
                crate::buffer::poison_kept(2 * previous.k.len());
                let mut near_cache = cache.clone();
                let near = FemModel::assemble_near_edit(
                    &edited,
                    kind,
                    0.24,
                    &previous,
                    Some(&mut near_cache),
                    2,
                )
                .unwrap();
                let held = near.near_edit.as_ref().map(|n| &n.held);
                assert_eq!(held.is_none(), edit == "a third removed", "{kind}, {edit}");
                if let Some(held) = held {
                    assert!(held.iter().any(|&h| !h), "{kind}, {edit}: every row held");
                    let p = &full.pattern;
                    assert_eq!(near.pattern.col, p.col);
                    for a in (0..full.nodes()).filter(|&a| held[a]) {
                        let r = p.row_ptr[a]..p.row_ptr[a + 1];
                        assert!(
                            bits(near.k[r.clone()].as_flattened())
                                == bits(full.k[r.clone()].as_flattened())
                                && bits(&near.m[r.clone()]) == bits(&full.m[r]),
                            "{kind}, {edit}: row {a}"
                        );
                    }
                    // The traces, updated near the edit: the whole sums to rounding (the
                    // sum of ~10^3 positive terms in another order: 1e-13 of them).
                    let traces = near.traces();
                    let whole_traces = [
                        crate::fem::sparse::trace(p, &full.k),
                        crate::fem::sparse::mass_trace(p, &full.m),
                    ];
                    for (t, w) in traces.iter().zip(whole_traces) {
                        assert!(
                            (t - w).abs() <= 1e-13 * w,
                            "{kind}, {edit}: {t} against {w}"
                        );
                    }
                }
                let (read, all) = (partial.stats(), whole.stats());
                let looked_up = |s: crate::fem::cache::CacheStats| s.hits + s.misses;
                if edit == "a third removed" {
                    assert_eq!(read, all, "{kind}: summed in full");
                } else {
                    assert!(looked_up(read) <= 125, "{kind}, {edit}: {read:?}");
                    assert!(
                        looked_up(all) > 3 * looked_up(read),
                        "{kind}, {edit}: {all:?}"
                    );
                    assert_eq!(read.misses, all.misses, "{kind}, {edit}");
                }
            }
        }
    }

    #[test]
    fn a_model_held_near_an_edit_refuses_to_be_read_whole() {
        // `K` of a model that holds only the rows near an edit is not there to read: reading
        // it whole panics with what to do instead, and a later edit assembles in full from it
        // (no rows to copy).
        let kind = ElementKind::Hex27Blocks;
        let grid = bowl();
        let previous = FemModel::assemble(&grid, kind, 0.24).unwrap();
        let (_, edited) = edits(&grid).swap_remove(2);
        let near = FemModel::assemble_near_edit(&edited, kind, 0.24, &previous, None, 2).unwrap();
        assert!(!near.is_whole());
        let read = std::panic::catch_unwind(|| near.k().len());
        let message = read.expect_err("a panic");
        let text = message.downcast_ref::<&str>().copied().unwrap_or_default();
        assert!(text.contains("only near an edit"), "{text}");
        let again = FemModel::assemble_after_edit(&grid, kind, 0.24, &near, None).unwrap();
        assert!(again.is_whole() && identical(&again, &previous));
    }

    #[test]
    fn a_model_of_another_size_or_ratio_is_not_reused() {
        // Reuse needs the same grid size and integrand; otherwise the model is summed in full
        // (the same as an uncached assembly: no cache is involved here).
        let kind = ElementKind::Hex27Blocks;
        let grid = bowl();
        let other_ratio = FemModel::assemble(&grid, kind, 0.3).unwrap();
        let other_size = FemModel::assemble(
            &Primitive::Bowl {
                diameter: 10.0,
                wall: 2.0,
            }
            .rasterize(1.0, 1.0)
            .unwrap(),
            kind,
            0.24,
        )
        .unwrap();
        let full = FemModel::assemble(&grid, kind, 0.24).unwrap();
        for previous in [&other_ratio, &other_size] {
            let after = FemModel::assemble_after_edit(&grid, kind, 0.24, previous, None).unwrap();
            assert!(identical(&after, &full));
        }
    }
}
