//! Assembly: the node numbering of the occupied cells, and `K` and `M` summed from the full
//! elements' shared unit matrices and the cut elements' integrals.
//!
//! Where it sits: [`FemModel::assemble`] and [`FemModel::assemble_cached`] call
//! [`FemModel::assemble_with`]; the cut elements go through [`cut::symmetry::Orbits`] (one
//! integration per orbit of fills), the [`ElementCache`] (fills seen in an earlier edit) and
//! [`cut::CutElement::matrices_batch`] (the rest, in batches of [`cut::CUT_BATCH`]).

mod reuse;

use super::sparse::{self, ElementBlocks, ALL_ROWS};
use super::{cut, ElementCache, ElementKind, FemModel, UnitElement};
use crate::shape::fill::{FULL, SUBCELLS_PER_AXIS};
use crate::shape::{lattice_coords, lattice_index, FillLookup, ShapeError, VoxelFill, VoxelGrid};

impl FemModel {
    /// [`FemModel::assemble_cached`], with the cut elements' orbits shared or each cut
    /// element integrated on its own (`share_orbits`, for the tests' reference), and the rows
    /// away from an edit copied from `after`'s model where it is a model of the same grid
    /// before a local edit ([`reuse`]; else every row is summed), or not held at all beyond
    /// its radius ([`After::held_radius`]).
    pub(super) fn assemble_with(
        grid: &VoxelGrid,
        kind: ElementKind,
        poisson_ratio: f64,
        mut cache: Option<&mut ElementCache>,
        share_orbits: bool,
        after: Option<After<'_>>,
    ) -> Result<Self, ShapeError> {
        grid.check_solvable()?;
        let block = kind.voxels_per_element();
        let unit = UnitElement::shared(kind, poisson_ratio);
        let mut unit = ElementBlocks::from_dense(kind.nodes(), &unit.stiffness, &unit.mass);
        // Voxel reference units (the cut elements come in them).
        if block > 1 {
            let (k_scale, m_scale) = kind.voxel_scales();
            unit.scale(k_scale, m_scale);
        }
        let p = kind.order();
        let n1 = p + 1;
        let nloc = kind.nodes();
        let fine_dims = grid.dims();
        let dims = fine_dims.map(|d| d.div_ceil(block));
        let lattice = [p * dims[0] + 1, p * dims[1] + 1, p * dims[2] + 1];
        let lidx = |x: usize, y: usize, z: usize| lattice_index([x, y, z], lattice);
        let voxels = element_cells(grid, kind);
        // Number the nodes in lattice order (keeps neighbours close in memory).
        let mut lattice_node = vec![u32::MAX; lattice.iter().product()];
        for v in &voxels {
            for az in 0..n1 {
                for ay in 0..n1 {
                    for ax in 0..n1 {
                        lattice_node[lidx(p * v[0] + ax, p * v[1] + ay, p * v[2] + az)] = 0;
                    }
                }
            }
        }
        let mut node_lattice = Vec::new();
        for (i, slot) in lattice_node.iter_mut().enumerate() {
            if *slot == 0 {
                *slot = node_lattice.len() as u32;
                node_lattice.push(i);
            }
        }
        let mut elements = Vec::with_capacity(voxels.len() * nloc);
        for v in &voxels {
            for az in 0..n1 {
                for ay in 0..n1 {
                    for ax in 0..n1 {
                        elements
                            .push(lattice_node[lidx(p * v[0] + ax, p * v[1] + ay, p * v[2] + az)]);
                    }
                }
            }
        }
        let nodes = node_lattice.len();
        // Each node's neighbour offsets give the pattern and every element's block positions.
        let rows = sparse::LatticeRows::new(p, nodes, &elements);
        let pattern = rows.pattern(&node_lattice, &lattice_node, lattice);
        // Partial voxels (and blocks that are not solid throughout): cut elements, evaluated
        // in batches.
        let per_voxel = cut::subcells_per_axis(kind);
        let cut = (!grid.is_binary() || block > 1)
            .then(|| cut::CutElement::shared(kind, poisson_ratio, per_voxel * block));
        let mut scratch = cut.as_ref().map(|c| c.scratch());
        let subcells = cut.as_ref().map_or(0, |c| c.per_axis().pow(3));
        // The cut elements waiting to be integrated together.
        let mut batch = CutBatch {
            elements: Vec::with_capacity(cut::CUT_BATCH),
            rows: Vec::with_capacity(cut::CUT_BATCH),
            fills: vec![0.0; subcells * cut::CUT_BATCH],
            keys: Vec::new(),
            orbits: Vec::with_capacity(cut::CUT_BATCH),
        };
        let mut voxel_fill = vec![0.0; per_voxel.pow(3)];
        let mut slots = vec![0usize; nloc * nloc];
        // A refined fill reads a one-voxel halo, which is then part of an element's input.
        let halo = per_voxel == crate::shape::refine::REFINED_PER_AXIS;
        // Only refined fills (each reads its 26 neighbours) and hex27x2 blocks (8 voxels each)
        // look fills up by voxel; the others read the element's own fill.
        let voxel_fills = if halo || block > 1 {
            FillLookup::new(grid)
        } else {
            FillLookup::unindexed(grid)
        };
        // The rows an edit leaves as they were, where an earlier model has them.
        let reuse = after.and_then(
            |After {
                 previous,
                 held_radius,
             }| {
                let states = (voxels.iter())
                    .map(|&v| block_state(&voxel_fills, v, block))
                    .collect();
                let mesh = reuse::Mesh {
                    kind,
                    poisson_ratio,
                    voxel_dims: fine_dims,
                    lattice,
                    voxels: &voxels,
                    node_lattice: &node_lattice,
                    lattice_node: &lattice_node,
                    pattern: &pattern,
                };
                reuse::Reuse::plan(previous, &mesh, states, held_radius)
            },
        );
        // `K` and `M` in kept buffers where the pool has them: after an edit the untouched
        // rows are copied over and only the summed ones cleared, else every entry is.
        let blocks = pattern.col.len();
        let (mut k, mut m) = match &reuse {
            Some(reuse) => {
                let mut k = crate::buffer::take_unfilled(blocks)
                    .unwrap_or_else(|_| crate::buffer::zeroed(blocks));
                let mut m = crate::buffer::take_unfilled(blocks)
                    .unwrap_or_else(|_| crate::buffer::zeroed(blocks));
                reuse.prefill(&pattern, &mut k, &mut m);
                (k, m)
            }
            None => (
                crate::buffer::take_zeroed(blocks),
                crate::buffer::take_zeroed(blocks),
            ),
        };
        if let Some(cache) = cache.as_deref_mut() {
            if reuse.is_some() {
                cache.begin_partial(kind, poisson_ratio);
            } else {
                cache.begin(kind, poisson_ratio);
            }
        }
        let mut key = Vec::new();
        // Cut elements whose fills are images of each other under a symmetry of the cube share
        // one integration ([`cut::symmetry`]): the batch's orbits, and the mapped matrices.
        // The linear elements' orbits are those of their sub-cell weights. A hex27x2 block's
        // refined fill comes from floating-point plane fits that are symmetric only to
        // rounding (175 orbits for 176 cut blocks of the 16-voxel bowl), so its orbit is that
        // of its input instead, the sub-cell bytes of its voxels and their ring (the images'
        // matrices then differ from their own integration by rounding), oriented by its
        // moments: ordering 4096 weights 48 ways would cost more than it saves.
        let by_input = share_orbits && p == 2 && block > 1;
        let input_side = (block + 2 * usize::from(halo)) * SUBCELLS_PER_AXIS;
        let mut input = vec![0u8; if by_input { input_side.pow(3) } else { 0 }];
        let mut orbits = cut
            .as_ref()
            .filter(|_| share_orbits && (p == 1 || by_input))
            .map(|c| {
                let cells = if by_input { input_side } else { c.per_axis() };
                cut::symmetry::Orbits::new(p + 1, cells)
            });
        let mut mapped = ElementBlocks::zeros(nloc);
        let mut flush = |batch: &mut CutBatch,
                         k: &mut [[f64; 9]],
                         m: &mut [f64],
                         mut cache: Option<&mut ElementCache>,
                         mut orbits: Option<&mut cut::symmetry::Orbits>| {
            if let (Some(cut), Some(scratch)) = (&cut, &mut scratch) {
                let count = batch.elements.len();
                let fills: Vec<&[f64]> = batch.fills.chunks_exact(subcells).take(count).collect();
                cut.matrices_batch(&fills, scratch, |j, blocks| {
                    let e = batch.elements[j];
                    let nodes = &elements[e * nloc..(e + 1) * nloc];
                    rows.slots(&pattern, nodes, &mut slots);
                    sparse::add_element_rows(&slots, &blocks.k, &blocks.m, k, m, batch.rows[j]);
                    if let Some(cache) = cache.as_deref_mut() {
                        cache.store(&batch.keys[j], blocks);
                    }
                    if let Some(orbits) = orbits.as_deref_mut() {
                        if let Some((orbit, g)) = batch.orbits[j] {
                            orbits.keep(orbit, g, blocks);
                        }
                    }
                });
            }
            batch.elements.clear();
            batch.rows.clear();
            batch.orbits.clear();
        };
        let mut unit_slots = vec![0usize; nloc * nloc];
        let mut cell_fills = Vec::with_capacity(voxels.len());
        // One element per voxel: the voxels come in storage order, and so do the grid's
        // partial voxels, so one walk along both finds each voxel's fill without a search.
        let mut partial_voxels = grid.partial_voxels().peekable();
        for (e, v) in voxels.iter().enumerate() {
            let nodes = &elements[e * nloc..(e + 1) * nloc];
            let partial = if block == 1 && cut.is_some() {
                let i = grid.index(v[0], v[1], v[2]);
                while partial_voxels.next_if(|&(j, _)| j < i).is_some() {}
                partial_voxels.next_if(|&(j, _)| j == i).map(|(_, f)| f)
            } else {
                None
            };
            let (full, fingerprint) = if let Some(reuse) = &reuse {
                reuse.state(e)
            } else if block == 1 {
                // (`partial` is the voxel's fill: a binary grid has none.)
                let fill = partial.map_or(VoxelFill::Full, |f| VoxelFill::Partial(*f));
                (partial.is_none(), fill_fingerprint([fill]))
            } else {
                block_state(&voxel_fills, *v, block)
            };
            cell_fills.push(fingerprint);
            // The element's rows summed here: all, or those an edit touched.
            let wanted = reuse.as_ref().map_or(ALL_ROWS, |r| r.rows_of(nodes));
            if wanted == 0 {
                continue;
            }
            if full {
                rows.slots(&pattern, nodes, &mut unit_slots);
                sparse::add_element_rows(&unit_slots, &unit.k, &unit.m, &mut k, &mut m, wanted);
                continue;
            }
            if let Some(cache) = cache.as_deref_mut() {
                ElementCache::key_into(grid, *v, block, halo, &mut key);
                rows.slots(&pattern, nodes, &mut unit_slots);
                if cache.add_stored(&key, &unit_slots, &mut k, &mut m, wanted) {
                    continue;
                }
                let at = batch.elements.len();
                if batch.keys.len() <= at {
                    batch.keys.push(Vec::new());
                }
                batch.keys[at].clone_from(&key);
            }
            let at = batch.elements.len() * subcells;
            let fills = at..at + subcells;
            let gather = |out: &mut [f64], voxel_fill: &mut [f64]| match partial {
                Some(fill) => voxel_subcells(&voxel_fills, *v, fill, out),
                None => gather_block_fill(&voxel_fills, *v, block, per_voxel, voxel_fill, out),
            };
            // The fill is gathered before its orbit is found from it, or after one found from
            // the block's input says it is needed.
            let found = match orbits.as_mut() {
                Some(orbits) if by_input => {
                    block_input(&voxel_fills, *v, block, halo, &mut input);
                    Some(orbits.find_input(&input))
                }
                Some(orbits) => {
                    let out = &mut batch.fills[fills.clone()];
                    gather(out, &mut voxel_fill);
                    out.iter_mut().for_each(|w| *w = cut::subcell_weight(*w));
                    Some(orbits.find(out))
                }
                None => {
                    gather(&mut batch.fills[fills.clone()], &mut voxel_fill);
                    None
                }
            };
            if by_input && !matches!(found, Some(cut::symmetry::Found::Seen { .. })) {
                gather(&mut batch.fills[fills], &mut voxel_fill);
            }
            if let (Some(orbits), Some(found)) = (orbits.as_mut(), found) {
                match found {
                    cut::symmetry::Found::New { orbit, g } => batch.orbits.push(Some((orbit, g))),
                    cut::symmetry::Found::Unkept => batch.orbits.push(None),
                    cut::symmetry::Found::Seen { orbit, g } => {
                        if !orbits.matrices(orbit, g, &mut mapped) {
                            // The orbit's first element waits in this batch.
                            flush(
                                &mut batch,
                                &mut k,
                                &mut m,
                                cache.as_deref_mut(),
                                Some(orbits),
                            );
                            let kept = orbits.matrices(orbit, g, &mut mapped);
                            debug_assert!(kept, "a flush integrates every orbit in its batch");
                        }
                        rows.slots(&pattern, nodes, &mut unit_slots);
                        sparse::add_element_rows(
                            &unit_slots,
                            &mapped.k,
                            &mapped.m,
                            &mut k,
                            &mut m,
                            wanted,
                        );
                        if let Some(cache) = cache.as_deref_mut() {
                            cache.store(&key, &mapped);
                        }
                        continue;
                    }
                }
            }
            batch.elements.push(e);
            batch.rows.push(wanted);
            if batch.elements.len() == cut::CUT_BATCH {
                flush(
                    &mut batch,
                    &mut k,
                    &mut m,
                    cache.as_deref_mut(),
                    orbits.as_mut(),
                );
            }
        }
        flush(
            &mut batch,
            &mut k,
            &mut m,
            cache.as_deref_mut(),
            orbits.as_mut(),
        );
        if let (None, Some(cache)) = (&reuse, cache) {
            cache.finish();
        }
        let traces = std::sync::OnceLock::new();
        let near_edit = reuse.as_ref().and_then(|reuse| {
            let held = reuse.held()?.to_vec();
            let _ = traces.set(reuse.traces(&pattern, &k, &m));
            Some(super::NearEdit { held })
        });
        Ok(FemModel {
            kind,
            poisson_ratio,
            voxel_dims: fine_dims,
            lattice,
            node_lattice,
            lattice_node,
            elements,
            voxels,
            cell_fills,
            pattern,
            k,
            m,
            near_edit,
            traces,
        })
    }
}

/// The model an assembly after an edit starts from ([`FemModel::assemble_with`]).
pub(super) struct After<'a> {
    /// The model before the edit (of the same grid size, element and Poisson's ratio, or it
    /// is not used).
    pub previous: &'a FemModel,
    /// `None`: every row of the new model is held (copied or summed). `Some(r)`: only the rows
    /// of the nodes within `r` cells of a changed cell ([`FemModel::assemble_near_edit`]).
    pub held_radius: Option<usize>,
}

/// Cut elements waiting to be integrated together ([`cut::CutElement::matrices_batch`]).
struct CutBatch {
    /// Their element numbers.
    elements: Vec<usize>,
    /// The rows each adds ([`sparse::add_element_rows`]).
    rows: Vec<u32>,
    /// Their sub-cell fills side by side.
    fills: Vec<f64>,
    /// Their element cache keys (where a cache is in use; kept allocated between batches).
    keys: Vec<Vec<u8>>,
    /// Their orbits and the symmetries to their canonical fills ([`cut::symmetry`]; `None`
    /// past the orbits' memory budget).
    orbits: Vec<Option<(usize, usize)>>,
}

/// The sub-cell fractions (x fastest) of the partial voxel `v` (its fill `fill`; `fills` looks
/// up its neighbours) into `out`, whose length picks the count per axis: the stored ones
/// averaged down to 1, 2 or 4 per axis, or refined to 8 by the fill's plane in each cut
/// sub-cell ([`crate::shape::refine`]).
fn voxel_subcells(
    fills: &FillLookup,
    v: [usize; 3],
    fill: &crate::shape::SubFill,
    out: &mut [f64],
) {
    if out.len() == crate::shape::refine::REFINED_PER_AXIS.pow(3) {
        crate::shape::refine::refined_fill(fills, v, fill, out);
    } else {
        fill.coarsened_into(out);
    }
}

/// The cells of `grid` that `kind` puts an element on, in storage order: the solid voxels, or
/// for [`ElementKind::Hex27Blocks`] the `2^3` blocks holding any solid voxel (in block
/// coordinates).
pub fn element_cells(grid: &VoxelGrid, kind: ElementKind) -> Vec<[usize; 3]> {
    let block = kind.voxels_per_element();
    if block == 1 {
        return grid.solid_voxels();
    }
    let dims = grid.dims().map(|d| d.div_ceil(block));
    let mut occupied = vec![false; dims.iter().product()];
    for v in grid.solid_voxels() {
        occupied[lattice_index(v.map(|c| c / block), dims)] = true;
    }
    occupied
        .iter()
        .enumerate()
        .filter(|(_, &o)| o)
        .map(|(i, _)| lattice_coords(i, dims))
        .collect()
}

/// Whether every voxel of the `block^3` voxels from `cell * block` is full (the unit element
/// applies), and their fills' [`fill_fingerprint`].
fn block_state(voxel_fills: &FillLookup, cell: [usize; 3], block: usize) -> (bool, u64) {
    let fills = (0..block.pow(3)).map(|o| {
        let d = [o % block, (o / block) % block, o / (block * block)];
        let v = [0, 1, 2].map(|a| (cell[a] * block + d[a]) as isize);
        voxel_fills.fill_at(v[0], v[1], v[2])
    });
    let mut full = true;
    let fingerprint = fill_fingerprint(fills.inspect(|f| full &= *f == VoxelFill::Full));
    (full, fingerprint)
}

/// A fingerprint of voxel fills (FNV-1a over their states and sub-cell bytes).
fn fill_fingerprint(fills: impl IntoIterator<Item = VoxelFill>) -> u64 {
    let mut fingerprint: u64 = 0xcbf2_9ce4_8422_2325;
    let mut mix = |byte: u8| {
        fingerprint = (fingerprint ^ byte as u64).wrapping_mul(0x0100_0000_01b3);
    };
    for fill in fills {
        match fill {
            VoxelFill::Empty => mix(0),
            VoxelFill::Full => mix(1),
            VoxelFill::Partial(f) => {
                mix(2);
                f.0.iter().for_each(|&b| mix(b));
            }
        }
    }
    fingerprint
}

/// The input of block `cell`'s cut element: the sub-cell bytes of its `block^3` voxels from
/// `cell * block` and, with `halo`, of their one-voxel ring (0 for an empty or out-of-grid
/// voxel, [`FULL`] for a full one, a partial one's [`crate::shape::SubFill`]), x fastest, into
/// `out`. Its refined fill is a function of this alone, and its orbit is found from it
/// ([`cut::symmetry::Orbits::find_input`]).
fn block_input(fills: &FillLookup, cell: [usize; 3], block: usize, halo: bool, out: &mut [u8]) {
    let n = SUBCELLS_PER_AXIS;
    let h = isize::from(halo);
    let voxels = block + 2 * usize::from(halo);
    let side = voxels * n;
    for vz in 0..voxels {
        for vy in 0..voxels {
            for vx in 0..voxels {
                let at = |o: usize, c: usize| (c * block) as isize - h + o as isize;
                let fill = fills.fill_at(at(vx, cell[0]), at(vy, cell[1]), at(vz, cell[2]));
                for sz in 0..n {
                    for sy in 0..n {
                        let row = vx * n + side * (vy * n + sy + side * (vz * n + sz));
                        let out = &mut out[row..row + n];
                        match &fill {
                            VoxelFill::Empty => out.fill(0),
                            VoxelFill::Full => out.fill(FULL),
                            VoxelFill::Partial(f) => {
                                let from = n * (sy + n * sz);
                                out.copy_from_slice(&f.0[from..from + n]);
                            }
                        }
                    }
                }
            }
        }
    }
}

/// The sub-cell fills (x fastest, `block * per_voxel` per axis) of the element over the
/// `block^3` voxels from `cell * block` into `out`: a full voxel's sub-cells are 1, an empty or
/// out-of-grid one's 0, a partial one's its [`crate::shape::SubFill`] averaged to `per_voxel`
/// per axis (or refined, [`voxel_subcells`]).
fn gather_block_fill(
    fills: &FillLookup,
    cell: [usize; 3],
    block: usize,
    per_voxel: usize,
    voxel_fill: &mut [f64],
    out: &mut [f64],
) {
    let side = block * per_voxel;
    for oz in 0..block {
        for oy in 0..block {
            for ox in 0..block {
                let v = [
                    cell[0] * block + ox,
                    cell[1] * block + oy,
                    cell[2] * block + oz,
                ];
                match fills.fill_at(v[0] as isize, v[1] as isize, v[2] as isize) {
                    VoxelFill::Empty => voxel_fill.fill(0.0),
                    VoxelFill::Full => voxel_fill.fill(1.0),
                    VoxelFill::Partial(f) => voxel_subcells(fills, v, &f, voxel_fill),
                }
                for sz in 0..per_voxel {
                    for sy in 0..per_voxel {
                        let from = per_voxel * (sy + per_voxel * sz);
                        let to = ox * per_voxel
                            + side * (oy * per_voxel + sy + side * (oz * per_voxel + sz));
                        out[to..to + per_voxel]
                            .copy_from_slice(&voxel_fill[from..from + per_voxel]);
                    }
                }
            }
        }
    }
}
