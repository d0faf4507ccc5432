//! The editor's sculpting model: a working box of 32^3 voxels (the editor's resolution limit)
//! with brush edits, mirror symmetry, primitives, hollowing, resampling and undo/redo. No GUI
//! here, so tests drive it.
//!
//! Where it sits: the editor's view ([`super::view3d`]) turns clicks into cells; this model
//! edits the box; [`Sculptor::sculpt`] crops it into the [`Sculpt`] the plugin persists and the
//! worker solves (the crop's longest side is what the Size parameter spans).

use crate::error::PluginError;
use crate::sculpt::{Sculpt, BLOCK_VOXELS, MAX_SIDE};
use modalforge::shape::spec::{self, ShapeSpec};
use modalforge::shape::{VoxelFill, VoxelGrid};

/// Undo steps kept (each is one working box: 32 KiB plus its partial voxels).
const UNDO_DEPTH: usize = 100;

/// Smallest object side a primitive or a resample may ask for.
pub const MIN_SIDE: usize = 2;

/// Side of the working box: objects sit in it centred, with room to grow.
pub const BOX_SIDE: usize = MAX_SIDE;

/// Voxel editing with history.
#[derive(Clone, Debug)]
pub struct Sculptor {
    /// The working box, [`BOX_SIDE`]^3 voxels of edge 1; partial voxels keep their fill.
    cells: VoxelGrid,
    undo: Vec<VoxelGrid>,
    redo: Vec<VoxelGrid>,
    /// Brush radius in voxels (0 = one voxel).
    pub brush_radius: usize,
    /// Mirror edits across the object's centre plane normal to x, y, z (the middle of its
    /// bounding box, as the stroke finds it).
    pub mirror: [bool; 3],
}

impl Sculptor {
    /// Opens an object, centred in the working box.
    pub fn new(sculpt: &Sculpt) -> Result<Self, PluginError> {
        let grid = sculpt.to_grid()?;
        let mut s = Self {
            cells: empty_box(),
            undo: Vec::new(),
            redo: Vec::new(),
            brush_radius: 0,
            mirror: [false; 3],
        };
        s.place(&grid, None);
        Ok(s)
    }

    /// Side of the working box, voxels.
    pub fn side(&self) -> usize {
        BOX_SIDE
    }

    /// Whether cell `c` is solid (outside the box is empty).
    pub fn get(&self, c: [i64; 3]) -> bool {
        self.cells.get(c[0] as isize, c[1] as isize, c[2] as isize)
    }

    /// What cell `c` holds: empty, full, or a partial voxel's fill.
    pub fn fill(&self, c: [i64; 3]) -> VoxelFill {
        self.cells
            .fill_at(c[0] as isize, c[1] as isize, c[2] as isize)
    }

    /// A hash of the object (occupancy and partial fills): a cache key for what is derived
    /// from it.
    pub fn shape_hash(&self) -> u64 {
        self.cells.shape_hash()
    }

    /// Where a strike aimed at `aim` (box voxel units) lands: the nearest point of the
    /// object's surface and that face's inward normal, as the solver snaps it.
    pub fn struck_point(&self, aim: [f64; 3]) -> Option<modalforge::basis::StruckPoint> {
        modalforge::basis::struck_point(&self.cells, aim)
    }

    /// Solid (full or partial) voxels.
    pub fn count(&self) -> usize {
        self.cells.count()
    }

    fn inside(c: [i64; 3]) -> bool {
        c.iter().all(|&v| (0..BOX_SIDE as i64).contains(&v))
    }

    /// The object as persisted and solved: the box cropped to the solid voxels (partial ones
    /// keep their fill), or an error if nothing is solid.
    pub fn sculpt(&self) -> Result<Sculpt, PluginError> {
        if self.cells.count() == 0 {
            return Err(PluginError::Empty("add voxels"));
        }
        Ok(Sculpt::from_grid(&self.cells.cropped()))
    }

    /// Lowest solid corner and the solid voxels' bounding dimensions (the solved grid's),
    /// `None` when empty.
    pub fn bounds(&self) -> Option<([i64; 3], [usize; 3])> {
        let n = BOX_SIDE as i64;
        let (mut lo, mut hi) = ([n; 3], [-1i64; 3]);
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    if self.get([x, y, z]) {
                        for (a, v) in [x, y, z].into_iter().enumerate() {
                            lo[a] = lo[a].min(v);
                            hi[a] = hi[a].max(v);
                        }
                    }
                }
            }
        }
        (hi[0] >= 0).then(|| (lo, [0, 1, 2].map(|a| (hi[a] - lo[a] + 1) as usize)))
    }

    /// Adds (or with `solid = false` removes) a ball of `brush_radius` voxels at `cell`, and its
    /// mirror images; one undo step. Painted voxels become full (or empty), partial ones too.
    /// Cells outside the box are skipped. Removing the last voxel is refused (an empty object
    /// cannot be solved). Returns whether anything changed.
    ///
    /// Mirror images are taken across the object's own centre planes, not the box's: an object
    /// whose extent and the box's differ in parity sits half a voxel off the box's centre, and
    /// strokes mirrored across the box's planes would break the object's symmetry, which makes
    /// its exact modes several times slower to solve (`eigen::symmetric`).
    pub fn paint(&mut self, cell: [i64; 3], solid: bool) -> bool {
        let before = self.cells.clone();
        let r = self.brush_radius as i64;
        // lo + hi: twice the centre, so an image is `lo + hi - c` (an object always has a voxel).
        let (lo, dims) = self.bounds().unwrap_or(([0; 3], [BOX_SIDE; 3]));
        let twice_centre: [i64; 3] = std::array::from_fn(|a| 2 * lo[a] + dims[a] as i64 - 1);
        let mut centres = vec![cell];
        for a in 0..3 {
            if self.mirror[a] {
                let mirrored: Vec<[i64; 3]> = centres
                    .iter()
                    .map(|c| {
                        let mut m = *c;
                        m[a] = twice_centre[a] - c[a];
                        m
                    })
                    .collect();
                centres.extend(mirrored);
            }
        }
        for c in centres {
            for dz in -r..=r {
                for dy in -r..=r {
                    for dx in -r..=r {
                        if dx * dx + dy * dy + dz * dz > r * r {
                            continue;
                        }
                        let p = [c[0] + dx, c[1] + dy, c[2] + dz];
                        if Self::inside(p) {
                            self.cells
                                .set(p[0] as usize, p[1] as usize, p[2] as usize, solid);
                        }
                    }
                }
            }
        }
        if self.cells.count() == 0 {
            self.cells = before;
            return false;
        }
        self.commit(before)
    }

    /// Replaces the object with a built-in primitive (the CLI's `--shape` names, e.g. `bowl`,
    /// `bell:d=24,h=24,wall=2`) scaled so its longest side is `side` voxels; one undo step.
    pub fn load_primitive(&mut self, spec: &str, side: usize) -> Result<(), PluginError> {
        let side = side.clamp(MIN_SIDE, MAX_SIDE);
        let ShapeSpec::Primitive { shape, hollow } = spec.parse::<ShapeSpec>()? else {
            return Err(PluginError::FileSpec(spec.into()));
        };
        let longest = shape.extent().into_iter().fold(0.0, f64::max);
        let grid = spec::primitive_voxels(&shape, hollow, side as f64 / longest, BLOCK_VOXELS)?;
        if grid.count() == 0 {
            return Err(PluginError::EmptyAt {
                spec: spec.into(),
                side,
            });
        }
        self.replace(&grid)
    }

    /// Replaces the object with `grid` (a loaded `.vox`, a preset); one undo step.
    pub fn replace(&mut self, grid: &VoxelGrid) -> Result<(), PluginError> {
        let grid = grid.cropped();
        if grid.count() == 0 {
            return Err(PluginError::Empty("nothing to load"));
        }
        if let Some(d) = grid.dims().into_iter().find(|&d| d > MAX_SIDE) {
            return Err(PluginError::TooLong(d));
        }
        let before = self.cells.clone();
        self.place(&grid, None);
        self.push_undo(before);
        Ok(())
    }

    /// Keeps only a shell `wall` voxels thick (the inside becomes empty); one undo step.
    pub fn hollow(&mut self, wall: usize) -> Result<(), PluginError> {
        let sculpt = self.sculpt()?;
        let grid = sculpt.to_grid()?;
        let shell = modalforge::shape::ops::hollow(&grid, wall.max(1));
        if shell.count() == grid.count() {
            return Err(PluginError::AlreadyThin(wall));
        }
        let (lo, _) = self.bounds().expect("not empty");
        let before = self.cells.clone();
        self.place(&shell, Some(lo));
        self.push_undo(before);
        Ok(())
    }

    /// Resamples the object so its longest side is `side` voxels (nearest voxel centre; a
    /// partial voxel's fill goes with it); one undo step.
    pub fn resample(&mut self, side: usize) -> Result<(), PluginError> {
        let side = side.clamp(MIN_SIDE, MAX_SIDE);
        let (lo, dims) = self.bounds().ok_or(PluginError::Empty("add voxels"))?;
        let longest = dims.into_iter().max().unwrap_or(1);
        if longest == side {
            return Ok(());
        }
        let s = side as f64 / longest as f64;
        let new_dims = dims.map(|d| ((d as f64 * s).round() as usize).max(1));
        // Each voxel takes the voxel its centre falls in.
        let mut grid = VoxelGrid::new(new_dims, 1.0)?;
        for z in 0..new_dims[2] {
            for y in 0..new_dims[1] {
                for x in 0..new_dims[0] {
                    let src = [x, y, z].map(|v| ((v as f64 + 0.5) / s).floor() as i64);
                    grid.set_fill(x, y, z, self.fill([0, 1, 2].map(|a| lo[a] + src[a])));
                }
            }
        }
        if grid.count() == 0 {
            return Err(PluginError::Vanishes(side));
        }
        let before = self.cells.clone();
        self.place(&grid, None);
        self.push_undo(before);
        Ok(())
    }

    /// Steps back; false when there is nothing to undo.
    pub fn undo(&mut self) -> bool {
        let Some(prev) = self.undo.pop() else {
            return false;
        };
        let now = std::mem::replace(&mut self.cells, prev);
        self.redo.push(now);
        true
    }

    /// Takes the last step back without leaving it to redo (a previewed import the user
    /// cancelled); false when there is nothing to take back.
    pub fn retract(&mut self) -> bool {
        let Some(prev) = self.undo.pop() else {
            return false;
        };
        self.cells = prev;
        true
    }

    /// Steps forward again; false when there is nothing to redo.
    pub fn redo(&mut self) -> bool {
        let Some(next) = self.redo.pop() else {
            return false;
        };
        let now = std::mem::replace(&mut self.cells, next);
        self.undo.push(now);
        true
    }

    /// Undo steps available.
    pub fn undo_depth(&self) -> usize {
        self.undo.len()
    }

    /// Redo steps available.
    pub fn redo_depth(&self) -> usize {
        self.redo.len()
    }

    /// Puts `grid` (at most [`BOX_SIDE`] per side) in a fresh box: centred, or with its low
    /// corner at `at`.
    fn place(&mut self, grid: &VoxelGrid, at: Option<[i64; 3]>) {
        let dims = grid.dims();
        let side = BOX_SIDE;
        let lo = at.unwrap_or_else(|| [0, 1, 2].map(|a| (side.saturating_sub(dims[a]) / 2) as i64));
        self.cells = empty_box();
        for z in 0..dims[2] {
            for y in 0..dims[1] {
                for x in 0..dims[0] {
                    let fill = grid.fill_at(x as isize, y as isize, z as isize);
                    let c = [lo[0] + x as i64, lo[1] + y as i64, lo[2] + z as i64];
                    if fill != VoxelFill::Empty && Self::inside(c) {
                        self.cells
                            .set_fill(c[0] as usize, c[1] as usize, c[2] as usize, fill);
                    }
                }
            }
        }
    }

    fn commit(&mut self, before: VoxelGrid) -> bool {
        if before == self.cells {
            return false;
        }
        self.push_undo(before);
        true
    }

    fn push_undo(&mut self, before: VoxelGrid) {
        self.undo.push(before);
        if self.undo.len() > UNDO_DEPTH {
            self.undo.remove(0);
        }
        self.redo.clear();
    }
}

/// An empty working box.
fn empty_box() -> VoxelGrid {
    VoxelGrid::new([BOX_SIDE; 3], 1.0).expect("the working box is a valid grid")
}
