//! Voxel objects: what the user sculpts and what the FEM meshes.
//!
//! Where it sits: the first stage of the modal pipeline. A [`VoxelGrid`] comes from a primitive
//! ([`primitives`], parsed from a spec string by [`spec`]), from a MagicaVoxel file ([`vox`]) or
//! from a closed OBJ/STL mesh ([`mesh`]); boolean operations, hollowing and face-connected
//! components live in [`ops`]. [`crate::fem`] turns each occupied voxel into one hexahedral
//! element, so every element is the same cube of edge [`VoxelGrid::voxel_size_m`] (the hexahedral
//! voxel FEM of NeuralSound, Jin et al. 2022, sec. 3.1, and Deep-Modal, Jin et al. 2020, sec. 4.1).
//! Voxels cut by a smooth surface keep how full they are ([`fill`]), and their elements integrate
//! over the filled part only.

pub mod fill;
pub mod mesh;
pub mod ops;
pub mod primitives;
pub mod refine;
pub mod spec;
pub mod vox;

use std::collections::BTreeMap;
use std::hash::{Hash, Hasher};

pub use fill::{SubFill, VoxelFill};

/// Linear index of point `c` of a lattice of `dims` points, x fastest: `x + dims[0] (y +
/// dims[1] z)`. Voxel grids, FEM node lattices and multigrid cell meshes all number this way.
#[inline]
pub fn lattice_index(c: [usize; 3], dims: [usize; 3]) -> usize {
    c[0] + dims[0] * (c[1] + dims[1] * c[2])
}

/// An axis permutation: new axis `a` is old axis `perm[a]`.
pub type Perm = [usize; 3];

/// The six axis permutations (the predictor's augmentations; with the eight reflections, the
/// cube's 48 symmetries that cut elements share integrations under, `fem::cut::symmetry`).
pub const PERMS: [Perm; 6] = [
    [0, 1, 2],
    [0, 2, 1],
    [1, 0, 2],
    [1, 2, 0],
    [2, 0, 1],
    [2, 1, 0],
];

/// Coordinates of the point with linear index `i` (the inverse of [`lattice_index`]).
#[inline]
pub fn lattice_coords(i: usize, dims: [usize; 3]) -> [usize; 3] {
    [
        i % dims[0],
        (i / dims[0]) % dims[1],
        i / (dims[0] * dims[1]),
    ]
}

/// Largest number of voxels along any axis a grid may have. A 256^3 solid is ~50 million degrees
/// of freedom, far past what a modal solve on one machine can factor.
pub const MAX_GRID_DIM: usize = 256;

/// Largest number of occupied voxels the FEM accepts (a 64^3 solid is 262,144).
pub const MAX_OCCUPIED_VOXELS: usize = 300_000;

/// A box of cubic voxels, each empty, solid, or partly filled (a [`SubFill`]).
///
/// Voxel `(x, y, z)` occupies `[x, x+1] x [y, y+1] x [z, z+1]` times `voxel_size_m`. Storage is
/// x-fastest: index `x + nx (y + ny z)`. A partial voxel is occupied (it is an element) and
/// its fill is kept beside the occupancy, so a binary grid pays nothing for fractions.
#[derive(Clone, Debug, PartialEq)]
pub struct VoxelGrid {
    dims: [usize; 3],
    voxel_size_m: f64,
    occupied: Vec<bool>,
    /// Fill of the partial voxels, by linear index; every key is occupied.
    partial: BTreeMap<usize, SubFill>,
}

/// Bytes per partial voxel in [`VoxelGrid::partial_records`]: its linear index (`u32`, little
/// endian) and its [`fill::SUBCELLS`] sub-cell fills ([`SubFill`]).
pub const PARTIAL_RECORD_BYTES: usize = 4 + fill::SUBCELLS;

/// Why stored partial-voxel records ([`VoxelGrid::set_partial_records`]) do not fit a grid.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PartialRecordError {
    /// The bytes are not whole records.
    #[error("partial-voxel fill has {0} bytes, not a multiple of {PARTIAL_RECORD_BYTES}")]
    Length(usize),
    /// A record names a voxel that is not occupied.
    #[error("partial voxel {index} is not an occupied voxel of {dims:?}")]
    NotOccupied {
        /// The record's linear index.
        index: usize,
        /// The grid's dimensions.
        dims: [usize; 3],
    },
}

/// What is wrong with a voxel grid.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ShapeError {
    /// A dimension is zero.
    #[error("grid dimensions {0:?} include a zero: every axis needs at least one voxel")]
    ZeroDimension([usize; 3]),
    /// A dimension is too large.
    #[error(
        "grid dimensions {dims:?} exceed the limit of {MAX_GRID_DIM} voxels per axis: \
         use a coarser resolution or a larger voxel size"
    )]
    TooLarge {
        /// The offending dimensions.
        dims: [usize; 3],
    },
    /// The voxel edge is not a positive finite length.
    #[error("voxel size {0} m is not a positive finite length")]
    BadVoxelSize(f64),
    /// The occupancy vector does not match the dimensions.
    #[error("occupancy has {got} entries but dimensions {dims:?} need {want}")]
    OccupancyLength {
        /// Dimensions.
        dims: [usize; 3],
        /// Entries given.
        got: usize,
        /// Entries needed.
        want: usize,
    },
    /// No voxel is occupied.
    #[error("the shape is empty (no occupied voxel): check its parameters or the input file")]
    Empty,
    /// Too many occupied voxels for the solver.
    #[error(
        "the shape has {0} occupied voxels, over the limit of {MAX_OCCUPIED_VOXELS}: \
         use a coarser resolution (larger --voxel-size, lower --fmax)"
    )]
    TooManyVoxels(usize),
}

impl VoxelGrid {
    /// An empty grid.
    pub fn new(dims: [usize; 3], voxel_size_m: f64) -> Result<Self, ShapeError> {
        // Checked before the occupancy is allocated: a corrupt file's dimensions asked for
        // 2e17 bytes here (found by `tests/fuzz.rs`).
        Self::check_dims(dims)?;
        Self::from_occupancy(dims, voxel_size_m, vec![false; dims.iter().product()])
    }

    /// Every side positive and at most [`MAX_GRID_DIM`].
    fn check_dims(dims: [usize; 3]) -> Result<(), ShapeError> {
        if dims.contains(&0) {
            return Err(ShapeError::ZeroDimension(dims));
        }
        if dims.iter().any(|&d| d > MAX_GRID_DIM) {
            return Err(ShapeError::TooLarge { dims });
        }
        Ok(())
    }

    /// A grid from an x-fastest occupancy vector.
    pub fn from_occupancy(
        dims: [usize; 3],
        voxel_size_m: f64,
        occupied: Vec<bool>,
    ) -> Result<Self, ShapeError> {
        Self::check_dims(dims)?;
        if !(voxel_size_m.is_finite() && voxel_size_m > 0.0) {
            return Err(ShapeError::BadVoxelSize(voxel_size_m));
        }
        let want = dims.iter().product();
        if occupied.len() != want {
            return Err(ShapeError::OccupancyLength {
                dims,
                got: occupied.len(),
                want,
            });
        }
        Ok(Self {
            dims,
            voxel_size_m,
            occupied,
            partial: BTreeMap::new(),
        })
    }

    /// A grid of `dims` rasterised from a signed distance in voxel units (negative inside, see
    /// [`fill::voxel_fill`]): voxels the surface cuts keep their sub-cell fill.
    pub fn from_sdf(
        dims: [usize; 3],
        voxel_size_m: f64,
        sdf: impl Fn(f64, f64, f64) -> f64,
    ) -> Result<Self, ShapeError> {
        let mut grid = Self::new(dims, voxel_size_m)?;
        for z in 0..dims[2] {
            for y in 0..dims[1] {
                for x in 0..dims[0] {
                    grid.set_fill(x, y, z, fill::voxel_fill(&sdf, [x, y, z]));
                }
            }
        }
        Ok(grid)
    }

    /// A grid of `dims` filled where `inside(x, y, z)` holds for the voxel's centre, given in
    /// voxel units (the centre of voxel `(0,0,0)` is `(0.5, 0.5, 0.5)`).
    pub fn from_fn(
        dims: [usize; 3],
        voxel_size_m: f64,
        inside: impl Fn(f64, f64, f64) -> bool,
    ) -> Result<Self, ShapeError> {
        let mut grid = Self::new(dims, voxel_size_m)?;
        for z in 0..dims[2] {
            for y in 0..dims[1] {
                for x in 0..dims[0] {
                    let i = grid.index(x, y, z);
                    grid.occupied[i] = inside(x as f64 + 0.5, y as f64 + 0.5, z as f64 + 0.5);
                }
            }
        }
        Ok(grid)
    }

    /// Voxels along x, y, z.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// Edge length of one voxel in metres.
    pub fn voxel_size_m(&self) -> f64 {
        self.voxel_size_m
    }

    /// The same occupancy with another voxel edge length.
    pub fn with_voxel_size(mut self, voxel_size_m: f64) -> Result<Self, ShapeError> {
        if !(voxel_size_m.is_finite() && voxel_size_m > 0.0) {
            return Err(ShapeError::BadVoxelSize(voxel_size_m));
        }
        self.voxel_size_m = voxel_size_m;
        Ok(self)
    }

    /// Linear index of voxel `(x, y, z)`.
    #[inline]
    pub fn index(&self, x: usize, y: usize, z: usize) -> usize {
        lattice_index([x, y, z], self.dims)
    }

    /// Whether voxel `(x, y, z)` is solid; out-of-range coordinates are empty.
    #[inline]
    pub fn get(&self, x: isize, y: isize, z: isize) -> bool {
        let [nx, ny, nz] = self.dims;
        if x < 0 || y < 0 || z < 0 || x as usize >= nx || y as usize >= ny || z as usize >= nz {
            return false;
        }
        self.occupied[self.index(x as usize, y as usize, z as usize)]
    }

    /// Sets voxel `(x, y, z)` solid (full) or empty.
    pub fn set(&mut self, x: usize, y: usize, z: usize, solid: bool) {
        let i = self.index(x, y, z);
        self.occupied[i] = solid;
        self.partial.remove(&i);
    }

    /// Sets voxel `(x, y, z)` empty, full or partly filled.
    pub fn set_fill(&mut self, x: usize, y: usize, z: usize, fill: VoxelFill) {
        match fill {
            VoxelFill::Empty => self.set(x, y, z, false),
            VoxelFill::Full => self.set(x, y, z, true),
            VoxelFill::Partial(f) if f.is_full() => self.set(x, y, z, true),
            VoxelFill::Partial(f) if f.0.iter().all(|&v| v == 0) => self.set(x, y, z, false),
            VoxelFill::Partial(f) => {
                let i = self.index(x, y, z);
                self.occupied[i] = true;
                self.partial.insert(i, f);
            }
        }
    }

    /// What voxel `(x, y, z)` holds; out-of-range coordinates are empty.
    pub fn fill_at(&self, x: isize, y: isize, z: isize) -> VoxelFill {
        if !self.get(x, y, z) {
            return VoxelFill::Empty;
        }
        match self
            .partial
            .get(&self.index(x as usize, y as usize, z as usize))
        {
            Some(f) => VoxelFill::Partial(*f),
            None => VoxelFill::Full,
        }
    }

    /// Filled volume fraction of voxel `(x, y, z)` in `[0, 1]`; out-of-range coordinates are 0.
    pub fn fraction(&self, x: isize, y: isize, z: isize) -> f64 {
        match self.fill_at(x, y, z) {
            VoxelFill::Empty => 0.0,
            VoxelFill::Full => 1.0,
            VoxelFill::Partial(f) => f.mean(),
        }
    }

    /// The sub-cell fill of the voxel at linear index `i`, if it is partial.
    pub fn subcell_fill(&self, i: usize) -> Option<&SubFill> {
        self.partial.get(&i)
    }

    /// The partial voxels by linear index (empty for a binary grid).
    pub fn partial_voxels(&self) -> impl Iterator<Item = (usize, &SubFill)> {
        self.partial.iter().map(|(&i, f)| (i, f))
    }

    /// The partial voxels as bytes, [`PARTIAL_RECORD_BYTES`] per voxel in index order (empty
    /// for a binary grid): how the plugin state and the predictor's records store them.
    pub fn partial_records(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.partial.len() * PARTIAL_RECORD_BYTES);
        for (&i, f) in &self.partial {
            out.extend_from_slice(&(i as u32).to_le_bytes());
            out.extend_from_slice(&f.0);
        }
        out
    }

    /// Makes the voxels named by [`VoxelGrid::partial_records`] bytes partial, with their fill;
    /// refuses (changing nothing) bytes that are not whole records or name an empty voxel.
    pub fn set_partial_records(&mut self, bytes: &[u8]) -> Result<(), PartialRecordError> {
        if !bytes.len().is_multiple_of(PARTIAL_RECORD_BYTES) {
            return Err(PartialRecordError::Length(bytes.len()));
        }
        let records = bytes.chunks_exact(PARTIAL_RECORD_BYTES).map(|r| {
            let index = u32::from_le_bytes(r[..4].try_into().expect("4 bytes")) as usize;
            (index, SubFill(r[4..].try_into().expect("SUBCELLS bytes")))
        });
        if let Some((index, _)) = records
            .clone()
            .find(|&(i, _)| !self.occupied.get(i).copied().unwrap_or(false))
        {
            return Err(PartialRecordError::NotOccupied {
                index,
                dims: self.dims,
            });
        }
        for (i, sub) in records {
            let [x, y, z] = lattice_coords(i, self.dims);
            self.set_fill(x, y, z, VoxelFill::Partial(sub));
        }
        Ok(())
    }

    /// Whether every occupied voxel is full.
    pub fn is_binary(&self) -> bool {
        self.partial.is_empty()
    }

    /// The same grid with every partial voxel made full if at least `threshold` of it is
    /// filled and empty otherwise (a `.vox` export uses 1/2).
    pub fn thresholded(&self, threshold: f64) -> VoxelGrid {
        let mut out = self.clone();
        for (&i, f) in &self.partial {
            out.occupied[i] = f.mean() >= threshold;
        }
        out.partial.clear();
        out
    }

    /// The filled volume in voxels (partial voxels count their fraction).
    pub fn volume_voxels(&self) -> f64 {
        let partial: f64 = self.partial.values().map(|f| 1.0 - f.mean()).sum();
        self.count() as f64 - partial
    }

    /// The x-fastest occupancy (partial voxels are occupied).
    pub fn occupancy(&self) -> &[bool] {
        &self.occupied
    }

    /// Number of solid voxels.
    pub fn count(&self) -> usize {
        self.occupied.iter().filter(|&&o| o).count()
    }

    /// Coordinates of every solid voxel, in storage order.
    pub fn solid_voxels(&self) -> Vec<[usize; 3]> {
        self.occupied
            .iter()
            .enumerate()
            .filter(|(_, &o)| o)
            .map(|(i, _)| lattice_coords(i, self.dims))
            .collect()
    }

    /// Checks that the grid can be meshed: not empty, not over the voxel limit.
    pub fn check_solvable(&self) -> Result<(), ShapeError> {
        match self.count() {
            0 => Err(ShapeError::Empty),
            n if n > MAX_OCCUPIED_VOXELS => Err(ShapeError::TooManyVoxels(n)),
            _ => Ok(()),
        }
    }

    /// Every voxel split into `factor^3` voxels of edge `voxel_size_m / factor`: the same
    /// staircased object on a finer mesh (what a converged reference solves).
    pub fn split(&self, factor: usize) -> Result<VoxelGrid, ShapeError> {
        let dims = self.dims.map(|d| d * factor.max(1));
        if factor == 0 || dims.iter().any(|&d| d > MAX_GRID_DIM) {
            return Err(ShapeError::TooLarge { dims });
        }
        let f = factor as f64;
        let mut out = VoxelGrid::from_fn(dims, self.voxel_size_m / f, |x, y, z| {
            self.get((x / f) as isize, (y / f) as isize, (z / f) as isize)
        })?;
        // A fine voxel inside a partial one takes the fill of the sub-cell holding its centre.
        let n = fill::SUBCELLS_PER_AXIS;
        for (&i, sub) in &self.partial {
            let c = [
                i % self.dims[0],
                (i / self.dims[0]) % self.dims[1],
                i / (self.dims[0] * self.dims[1]),
            ];
            for fz in 0..factor {
                for fy in 0..factor {
                    for fx in 0..factor {
                        let o = [fx, fy, fz];
                        let s = o.map(|o| ((o as f64 + 0.5) / f * n as f64) as usize);
                        let frac = sub.fractions()[s[0] + n * (s[1] + n * s[2])];
                        let p = [0, 1, 2].map(|a| c[a] * factor + o[a]);
                        out.set_fill(p[0], p[1], p[2], fill::uniform(frac));
                    }
                }
            }
        }
        Ok(out)
    }

    /// The grid cropped to the bounding box of its solid voxels (unchanged if empty).
    pub fn cropped(&self) -> VoxelGrid {
        let solid = self.solid_voxels();
        if solid.is_empty() {
            return self.clone();
        }
        let mut lo = [usize::MAX; 3];
        let mut hi = [0; 3];
        for v in &solid {
            for a in 0..3 {
                lo[a] = lo[a].min(v[a]);
                hi[a] = hi[a].max(v[a]);
            }
        }
        self.copy_box(&solid, lo, [0, 1, 2].map(|a| hi[a] - lo[a] + 1))
    }

    /// The box of `dims` voxels starting at voxel `lo`, fills kept (a crop; what lies outside
    /// this grid is empty).
    pub fn window(&self, lo: [usize; 3], dims: [usize; 3]) -> VoxelGrid {
        self.copy_box(&self.solid_voxels(), lo, dims)
    }

    /// [`VoxelGrid::window`] given this grid's solid voxels (so a caller that has them does
    /// not scan the grid again).
    fn copy_box(&self, solid: &[[usize; 3]], lo: [usize; 3], dims: [usize; 3]) -> VoxelGrid {
        let mut out = VoxelGrid {
            dims,
            voxel_size_m: self.voxel_size_m,
            occupied: vec![false; dims.iter().product()],
            partial: BTreeMap::new(),
        };
        for &v in solid {
            if (0..3).all(|a| v[a] >= lo[a] && v[a] - lo[a] < dims[a]) {
                let f = self.fill_at(v[0] as isize, v[1] as isize, v[2] as isize);
                out.set_fill(v[0] - lo[0], v[1] - lo[1], v[2] - lo[2], f);
            }
        }
        out
    }

    /// A hash of the occupancy pattern and dimensions (not the voxel size): the cache key of a
    /// shape's mode basis, which is size independent (see [`crate::basis`]).
    pub fn shape_hash(&self) -> u64 {
        let mut h = std::collections::hash_map::DefaultHasher::new();
        self.dims.hash(&mut h);
        // Pack occupancy into words so the hash is fast for big grids.
        for chunk in self.occupied.chunks(64) {
            let word = chunk
                .iter()
                .enumerate()
                .fold(0u64, |w, (i, &o)| w | ((o as u64) << i));
            word.hash(&mut h);
        }
        self.partial.hash(&mut h);
        h.finish()
    }

    /// Largest extent of the grid box in metres.
    pub fn extent_m(&self) -> f64 {
        *self.dims.iter().max().unwrap() as f64 * self.voxel_size_m
    }
}

/// A grid's fills by voxel index, for the many lookups of a whole assembly (each refined
/// partial voxel reads its 26 neighbours' fills, [`refine`]; each hex27x2 block its 8
/// voxels'): the grid keeps its partial voxels in an ordered map, a search per lookup (about
/// a fifth of the refinement's time before this index).
pub struct FillLookup<'a> {
    grid: &'a VoxelGrid,
    /// Per voxel (storage order): its place in `fills`, or `u32::MAX` where it is not partial;
    /// `None` for grids over [`MAX_INDEXED_VOXELS`] (the map's search then).
    slot: Option<Vec<u32>>,
    fills: Vec<&'a SubFill>,
}

/// Largest grid (voxels, occupied or not) given a dense index: 16 MB of it.
pub const MAX_INDEXED_VOXELS: usize = 1 << 22;

impl<'a> FillLookup<'a> {
    /// The index of `grid`'s partial voxels (one `u32` per voxel of the grid).
    pub fn new(grid: &'a VoxelGrid) -> Self {
        let [nx, ny, nz] = grid.dims();
        let voxels = nx * ny * nz;
        let mut fills = Vec::new();
        let slot = (voxels <= MAX_INDEXED_VOXELS).then(|| {
            let mut slot = vec![u32::MAX; voxels];
            for (i, fill) in grid.partial_voxels() {
                slot[i] = fills.len() as u32;
                fills.push(fill);
            }
            slot
        });
        FillLookup { grid, slot, fills }
    }

    /// A lookup that searches the grid's map each time: for an assembly that reads few or
    /// no neighbours' fills (binary grids, unrefined single-voxel elements), where building
    /// the index would cost more than it saves.
    pub fn unindexed(grid: &'a VoxelGrid) -> Self {
        FillLookup {
            grid,
            slot: None,
            fills: Vec::new(),
        }
    }

    /// [`VoxelGrid::fill_at`], without the search.
    pub fn fill_at(&self, x: isize, y: isize, z: isize) -> VoxelFill {
        let Some(slot) = &self.slot else {
            return self.grid.fill_at(x, y, z);
        };
        if !self.grid.get(x, y, z) {
            return VoxelFill::Empty;
        }
        match slot[self.grid.index(x as usize, y as usize, z as usize)] {
            u32::MAX => VoxelFill::Full,
            at => VoxelFill::Partial(*self.fills[at as usize]),
        }
    }
}
