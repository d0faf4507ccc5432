//! Cut element matrices kept between assemblies: a brush stroke re-integrates only the cut
//! elements it touched.
//!
//! Where it sits: [`super::FemModel::assemble_cached`] looks every cut element (a partial voxel,
//! or a hex27x2 block that is not solid throughout) up here before integrating it over its
//! sub-cells ([`super::cut`]), and stores what it integrates. The worker's solver chain
//! ([`crate::engine::interactive_solvers`]) shares one cache, so a stroke's carried answer, its
//! exact solve and the next stroke's all assemble the same object with most cut elements
//! already integrated. Full elements never come here: they share the one unit element.
//!
//! **The key is the element's whole input**, byte for byte: the fill state of every voxel the
//! element's sub-cell fractions are computed from, and the sub-cell bytes of the partial
//! ones. That is the element's own voxels, plus a one-voxel ring around them where the
//! quadratic elements refine their fills by the surface's plane ([`crate::shape::refine`]
//! reads a halo). So a hit is the same matrices (the same arithmetic on the same numbers), and
//! no collision can hand an element another's matrices. Position is not in the key: a stroke at
//! the boundary that moves the cropped grid's origin still finds every unchanged element.
//!
//! **Memory** stays bounded: an entry not used by one of the last [`KEEP_ASSEMBLIES`]
//! assemblies is dropped, and nothing is stored past [`MAX_BYTES`]. An entry holds the
//! upper triangle of the stiffness as 3x3 node blocks and the mass as one scalar per node pair
//! (a consistent mass is `M_ab delta_cd`): about 30 kB for a hex27x2 block.

use super::sparse::ElementBlocks;
use super::ElementKind;
use crate::shape::{VoxelFill, VoxelGrid};
use std::collections::HashMap;

/// Assemblies an entry survives without being used. The worker's chain assembles up to three
/// grids per edit (the coarse answer's, then the edited object's twice), so an edit's coarse
/// grid does not push out the fine object's elements.
pub const KEEP_ASSEMBLIES: u64 = 4;

/// Most bytes of element matrices kept (beyond it, new elements are integrated but not kept):
/// a 32^3 object's cut hex27x2 blocks take about 40 MB.
pub const MAX_BYTES: usize = 64 << 20;

/// One cut element's matrices, compactly (an [`ElementBlocks`]'s).
#[derive(Clone, Debug)]
struct Entry {
    /// Stiffness 3x3 blocks (row-major) of the node pairs `a <= b`, row by row.
    k: Box<[[f64; 9]]>,
    /// Scalar mass of the same node pairs.
    m: Box<[f64]>,
    /// The assembly that last used it.
    used: u64,
}

impl Entry {
    fn bytes(&self, key: usize) -> usize {
        key + self.k.len() * 72 + self.m.len() * 8 + 64
    }
}

/// Cut element matrices of one element kind and Poisson's ratio, by their fills.
#[derive(Clone, Debug, Default)]
pub struct ElementCache {
    /// What the entries were integrated for (a change clears them).
    integrand: Option<(ElementKind, u64)>,
    entries: HashMap<Box<[u8]>, Entry>,
    bytes: usize,
    assembly: u64,
    hits: usize,
    misses: usize,
}

/// What the last assembly found in the cache.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CacheStats {
    /// Cut elements whose matrices were reused.
    pub hits: usize,
    /// Cut elements integrated.
    pub misses: usize,
    /// Elements held now.
    pub entries: usize,
    /// Bytes held now (approximately).
    pub bytes: usize,
}

impl ElementCache {
    /// An empty cache.
    pub fn new() -> Self {
        Self::default()
    }

    /// What the last assembly found, and what is held.
    pub fn stats(&self) -> CacheStats {
        CacheStats {
            hits: self.hits,
            misses: self.misses,
            entries: self.entries.len(),
            bytes: self.bytes,
        }
    }

    /// Starts an assembly of `kind` at Poisson's ratio `nu` (another integrand clears the
    /// cache).
    pub(super) fn begin(&mut self, kind: ElementKind, nu: f64) {
        let integrand = Some((kind, nu.to_bits()));
        if self.integrand != integrand {
            self.entries.clear();
            self.bytes = 0;
            self.integrand = integrand;
        }
        self.assembly += 1;
        self.hits = 0;
        self.misses = 0;
    }

    /// Starts an assembly that reads only the elements near an edit and copies the rest from
    /// an earlier model ([`super::FemModel::assemble_after_edit`]): it does not count as one
    /// of the last [`KEEP_ASSEMBLIES`] (the elements it skips are still in use) and is not
    /// [`ElementCache::finish`]ed.
    pub(super) fn begin_partial(&mut self, kind: ElementKind, nu: f64) {
        self.begin(kind, nu);
        self.assembly -= 1;
    }

    /// Ends an assembly: drops what the last [`KEEP_ASSEMBLIES`] did not use.
    pub(super) fn finish(&mut self) {
        let oldest = self.assembly.saturating_sub(KEEP_ASSEMBLIES - 1);
        let mut bytes = 0;
        self.entries.retain(|key, e| {
            let keep = e.used >= oldest;
            if keep {
                bytes += e.bytes(key.len());
            }
            keep
        });
        self.bytes = bytes;
    }

    /// The key of the element on the `block^3` voxels from `cell * block` of `grid` into
    /// `out`: every voxel its fills are computed from (with a one-voxel ring when `halo`), one
    /// byte each for empty and full, a marker and the sub-cell bytes for a partial one.
    pub(super) fn key_into(
        grid: &VoxelGrid,
        cell: [usize; 3],
        block: usize,
        halo: bool,
        out: &mut Vec<u8>,
    ) {
        out.clear();
        let h = halo as isize;
        let lo = cell.map(|c| (c * block) as isize - h);
        let side = block as isize + 2 * h;
        for z in lo[2]..lo[2] + side {
            for y in lo[1]..lo[1] + side {
                for x in lo[0]..lo[0] + side {
                    match grid.fill_at(x, y, z) {
                        VoxelFill::Empty => out.push(0),
                        VoxelFill::Full => out.push(1),
                        VoxelFill::Partial(f) => {
                            out.push(2);
                            out.extend_from_slice(&f.0);
                        }
                    }
                }
            }
        }
    }

    /// Adds the matrices stored under `key` into the rows `rows` of `k` and `m`
    /// ([`ALL_ROWS`](super::sparse::ALL_ROWS) for all) at the element's block positions
    /// `slots` ([`super::sparse::add_element_rows`]), or returns `false` where there are none.
    pub(super) fn add_stored(
        &mut self,
        key: &[u8],
        slots: &[usize],
        k: &mut [[f64; 9]],
        m: &mut [f64],
        rows: u32,
    ) -> bool {
        let Some(entry) = self.entries.get_mut(key) else {
            self.misses += 1;
            return false;
        };
        entry.used = self.assembly;
        self.hits += 1;
        super::sparse::add_element_rows(slots, &entry.k, &entry.m, k, m, rows);
        true
    }

    /// Stores an element's matrices under `key`, unless the cache is full.
    pub(super) fn store(&mut self, key: &[u8], blocks: &ElementBlocks) {
        let entry = Entry {
            k: blocks.k.as_slice().into(),
            m: blocks.m.as_slice().into(),
            used: self.assembly,
        };
        let bytes = entry.bytes(key.len());
        if self.bytes + bytes > MAX_BYTES {
            return;
        }
        if self.entries.insert(key.into(), entry).is_none() {
            self.bytes += bytes;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::FemModel;
    use crate::shape::primitives::Primitive;

    fn bowl() -> VoxelGrid {
        Primitive::Bowl {
            diameter: 12.0,
            wall: 2.0,
        }
        .rasterize(1.0, 1.0)
        .unwrap()
    }

    /// Largest entry difference of two models' `K` and `M`, over the largest entry.
    fn difference(a: &FemModel, b: &FemModel) -> f64 {
        assert_eq!(a.pattern.col, b.pattern.col);
        let mut worst = 0.0f64;
        let mut compare = |x: &[f64], y: &[f64]| {
            let scale = x.iter().fold(0.0f64, |s, v| s.max(v.abs()));
            for (p, q) in x.iter().zip(y) {
                worst = worst.max((p - q).abs() / scale);
            }
        };
        compare(a.k.as_flattened(), b.k.as_flattened());
        compare(&a.m, &b.m);
        worst
    }

    #[test]
    fn a_stroke_reuses_every_untouched_cut_element_and_assembles_the_same_model() {
        // The truth is the uncached assembly of the same grid. Reused matrices are the same
        // numbers added in the same order (both scatter `ElementBlocks`), but a batch
        // integrates its elements together and the batch boundaries move with the cache's
        // hits, so the models agree to rounding: 1e-13 of the largest entry (f64 eps is
        // 2.2e-16; an element sums a few hundred sub-cell terms). A one-voxel stroke touches the
        // elements whose key holds that voxel: at most 27 of them (the element and the
        // halo's), so nearly every other cut element must come from the cache.
        for kind in [
            ElementKind::Hex8Incompatible,
            ElementKind::Hex27Blocks,
            ElementKind::Hex27,
        ] {
            let grid = bowl();
            let mut cache = ElementCache::new();
            let first = FemModel::assemble_cached(&grid, kind, 0.24, Some(&mut cache)).unwrap();
            // Cut elements with the same fills (a symmetric object has some) are reused even
            // in a cold assembly, except within one batch (integrated together).
            let cold = cache.stats();
            assert!(cold.misses > 50, "{kind}: {cold:?}");
            assert!(cold.entries <= cold.misses, "{kind}: {cold:?}");
            assert!(cold.entries * 10 >= cold.misses * 9, "{kind}: {cold:?}");
            assert!(difference(&first, &FemModel::assemble(&grid, kind, 0.24).unwrap()) < 1e-13);
            // The stroke: the first partial voxel becomes full.
            let (i, _) = grid.partial_voxels().next().unwrap();
            let v = crate::shape::lattice_coords(i, grid.dims());
            let mut edited = grid.clone();
            edited.set(v[0], v[1], v[2], true);
            let again = FemModel::assemble_cached(&edited, kind, 0.24, Some(&mut cache)).unwrap();
            let warm = cache.stats();
            let fresh = FemModel::assemble(&edited, kind, 0.24).unwrap();
            let worst = difference(&again, &fresh);
            assert!(worst < 1e-13, "{kind}: {worst:e}");
            assert!(warm.misses <= 27, "{kind}: {warm:?}");
            let cut = cold.hits + cold.misses;
            assert!(
                warm.hits + warm.misses + 27 >= cut,
                "{kind}: {warm:?} of {cut}"
            );
            eprintln!("{kind}: cold {cold:?}, after the stroke {warm:?}");
        }
    }

    #[test]
    fn entries_unused_for_several_assemblies_are_dropped_and_another_ratio_clears() {
        // Memory is bounded by what recent assemblies used: after KEEP_ASSEMBLIES assemblies
        // of another object, only that object's elements are left.
        let kind = ElementKind::Hex27Blocks;
        let mut cache = ElementCache::new();
        FemModel::assemble_cached(&bowl(), kind, 0.24, Some(&mut cache)).unwrap();
        let bowl_entries = cache.stats().entries;
        let sphere = Primitive::Sphere { diameter: 9.0 }
            .rasterize(1.0, 1.0)
            .unwrap();
        for _ in 0..KEEP_ASSEMBLIES {
            FemModel::assemble_cached(&sphere, kind, 0.24, Some(&mut cache)).unwrap();
        }
        let left = cache.stats();
        let mut alone = ElementCache::new();
        FemModel::assemble_cached(&sphere, kind, 0.24, Some(&mut alone)).unwrap();
        assert!(bowl_entries > 0);
        assert_eq!(
            left.entries,
            alone.stats().entries,
            "only the sphere's are left"
        );
        assert_eq!(left.bytes, alone.stats().bytes);
        FemModel::assemble_cached(&sphere, kind, 0.24, Some(&mut cache)).unwrap();
        assert_eq!(cache.stats().misses, 0);
        assert_eq!(cache.stats().entries, left.entries, "a steady state");
        // Another Poisson's ratio is another integrand: nothing is reused.
        FemModel::assemble_cached(&sphere, kind, 0.3, Some(&mut cache)).unwrap();
        assert_eq!(cache.stats().hits, 0);
    }
}
