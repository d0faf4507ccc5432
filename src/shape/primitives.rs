//! Built-in parametric shapes, rasterised onto a voxel grid.
//!
//! Every length is in voxels at resolution scale 1; [`Primitive::rasterize`] multiplies them all
//! (walls included) by a scale, so the same object can be meshed finer or coarser with its
//! proportions and physical wall thickness kept. Each shape is a signed distance in voxel units:
//! [`Primitive::rasterize`] keeps how full the voxels its surface cuts are (partial voxels,
//! [`super::fill`]); [`Primitive::rasterize_staircase`] makes a voxel solid when its centre is
//! inside (the binary staircase, kept to compare against).

use super::{ShapeError, VoxelGrid};

/// A built-in shape with its size parameters (voxels at scale 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Primitive {
    /// Rectangular bar, `length` along x.
    Bar {
        /// Along x.
        length: f64,
        /// Along y.
        width: f64,
        /// Along z.
        height: f64,
    },
    /// Flat plate in the x-y plane.
    Plate {
        /// Along x.
        length: f64,
        /// Along y.
        width: f64,
        /// Along z.
        thickness: f64,
    },
    /// Solid box (same as a bar; kept for readable specs).
    Box {
        /// Along x.
        x: f64,
        /// Along y.
        y: f64,
        /// Along z.
        z: f64,
    },
    /// Solid sphere.
    Sphere {
        /// Diameter.
        diameter: f64,
    },
    /// Solid cylinder along z.
    Cylinder {
        /// Diameter.
        diameter: f64,
        /// Height along z.
        height: f64,
    },
    /// Open tube along z.
    Tube {
        /// Outer diameter.
        diameter: f64,
        /// Height along z.
        height: f64,
        /// Wall thickness.
        wall: f64,
    },
    /// Hemispherical shell, opening upwards (+z).
    Bowl {
        /// Outer diameter.
        diameter: f64,
        /// Wall thickness.
        wall: f64,
    },
    /// Cylindrical cup: tube wall plus a closed bottom of the same thickness.
    Cup {
        /// Outer diameter.
        diameter: f64,
        /// Height along z.
        height: f64,
        /// Wall and bottom thickness.
        wall: f64,
    },
    /// Church-bell-like shell: a flared body (mouth at the bottom, z = 0) closed by a crown.
    Bell {
        /// Mouth outer diameter.
        diameter: f64,
        /// Height along z.
        height: f64,
        /// Wall thickness.
        wall: f64,
    },
}

impl Primitive {
    /// Bounding box in voxels at scale 1.
    pub fn extent(&self) -> [f64; 3] {
        match *self {
            Primitive::Bar {
                length,
                width,
                height,
            } => [length, width, height],
            Primitive::Plate {
                length,
                width,
                thickness,
            } => [length, width, thickness],
            Primitive::Box { x, y, z } => [x, y, z],
            Primitive::Sphere { diameter } => [diameter; 3],
            Primitive::Cylinder { diameter, height }
            | Primitive::Tube {
                diameter, height, ..
            }
            | Primitive::Cup {
                diameter, height, ..
            }
            | Primitive::Bell {
                diameter, height, ..
            } => [diameter, diameter, height],
            Primitive::Bowl { diameter, .. } => [diameter, diameter, diameter / 2.0],
        }
    }

    /// Thinnest feature (wall or smallest box side) in voxels at scale 1: the resolution
    /// heuristic keeps at least two elements across it.
    pub fn thinnest(&self) -> f64 {
        match *self {
            Primitive::Tube { wall, .. }
            | Primitive::Bowl { wall, .. }
            | Primitive::Cup { wall, .. }
            | Primitive::Bell { wall, .. } => wall,
            _ => self.extent().into_iter().fold(f64::INFINITY, f64::min),
        }
    }

    /// Rasterises the shape with every length multiplied by `scale`; voxels the surface cuts
    /// keep their sub-cell fill.
    pub fn rasterize(&self, scale: f64, voxel_size_m: f64) -> Result<VoxelGrid, ShapeError> {
        let dims = self.grid_dims(scale)?;
        let sdf = self.signed_distance(scale, dims);
        VoxelGrid::from_sdf(dims, voxel_size_m, sdf)
    }

    /// [`Primitive::rasterize`] for elements that span `block_voxels` voxels along each axis
    /// (2 for hex27x2, [`crate::fem::ElementKind::voxels_per_element`]): each side shorter
    /// than the longest gets as many more voxels as make it a whole number of blocks, and the
    /// shape sits in the middle of them, with partly filled voxels at both faces.
    ///
    /// Why: the elements' node planes are those of the blocks, which start at the grid's
    /// origin. A 3-voxel side spans two blocks, one full and one half full, so the mesh is
    /// not mirror-symmetric across it even though the shape is; padded to 4 voxels, filled
    /// `1/2, 1, 1, 1/2`, the same two blocks are mirror images (the same nodes and DOFs).
    /// The steel bar preset (`bar:l=30,w=3,h=3`) keeps its three mirrors instead of one: its
    /// class-by-class solve (`crate::eigen::symmetric`) took 0.37x the time, the wooden
    /// slat's 0.59x (five interleaved rounds), and the bar's paired bending modes are exactly
    /// paired. Two sides are left as they are: the longest, which the object's physical size
    /// is spread over, and a plate's thickness (the thinnest side, under half the next),
    /// whose mirror only parts the few in-plane modes from the bending ones: padded, the
    /// brass gong's solve took 1.16x the time and the aluminium plate's 1.04x.
    pub fn rasterize_on_blocks(
        &self,
        scale: f64,
        voxel_size_m: f64,
        block_voxels: usize,
    ) -> Result<VoxelGrid, ShapeError> {
        let dims = self.grid_dims(scale)?;
        let mut sides = dims;
        sides.sort_unstable();
        let [thinnest, middle, longest] = sides;
        // A plate's thickness: the thinnest side, under half the next.
        let thickness = (2 * thinnest < middle).then_some(thinnest);
        let block = block_voxels.max(1);
        let padded = dims.map(|d| {
            if d == longest || Some(d) == thickness {
                d
            } else {
                d.next_multiple_of(block)
            }
        });
        if padded == dims {
            return self.rasterize(scale, voxel_size_m);
        }
        if padded.iter().any(|&d| d > super::MAX_GRID_DIM) {
            return Err(ShapeError::TooLarge { dims: padded });
        }
        let sdf = self.signed_distance(scale, dims);
        // The shape moves by half the padding; the slabs of its own extent bound it along the
        // padded axes (a bar's distance is -1 everywhere).
        let shift = [0, 1, 2].map(|a| (padded[a] - dims[a]) as f64 / 2.0);
        let half = dims.map(|d| d as f64 / 2.0);
        let centre = padded.map(|d| d as f64 / 2.0);
        let padded_axes: Vec<usize> = (0..3).filter(|&a| padded[a] != dims[a]).collect();
        VoxelGrid::from_sdf(padded, voxel_size_m, move |x, y, z| {
            let p = [x, y, z];
            let inner = sdf(x - shift[0], y - shift[1], z - shift[2]);
            padded_axes
                .iter()
                .map(|&a| (p[a] - centre[a]).abs() - half[a])
                .fold(inner, f64::max)
        })
    }

    /// Rasterises the shape with every length multiplied by `scale`, a voxel solid when its
    /// centre is inside: the binary staircase.
    pub fn rasterize_staircase(
        &self,
        scale: f64,
        voxel_size_m: f64,
    ) -> Result<VoxelGrid, ShapeError> {
        let dims = self.grid_dims(scale)?;
        let sdf = self.signed_distance(scale, dims);
        VoxelGrid::from_fn(dims, voxel_size_m, |x, y, z| sdf(x, y, z) <= 0.0)
    }

    /// The grid's dimensions at `scale`, refused before anything is allocated when too large.
    fn grid_dims(&self, scale: f64) -> Result<[usize; 3], ShapeError> {
        let ext = self.extent();
        let dim = |e: f64| ((e * scale).round().max(1.0)) as usize;
        let dims = [dim(ext[0]), dim(ext[1]), dim(ext[2])];
        if dims.iter().any(|&d| d > super::MAX_GRID_DIM) {
            return Err(ShapeError::TooLarge { dims });
        }
        Ok(dims)
    }

    /// The shape as a signed distance in voxel units on a grid of `dims` (negative inside,
    /// 1-Lipschitz: exact for spheres and cylinders, max/min combinations of them for walls,
    /// and a scaled lower bound for the bell's flared profile).
    fn signed_distance(&self, scale: f64, dims: [usize; 3]) -> Box<dyn Fn(f64, f64, f64) -> f64> {
        let s = scale;
        let (cx, cy) = (dims[0] as f64 / 2.0, dims[1] as f64 / 2.0);
        let radial = move |x: f64, y: f64| ((x - cx).powi(2) + (y - cy).powi(2)).sqrt();
        match *self {
            Primitive::Bar { .. } | Primitive::Plate { .. } | Primitive::Box { .. } => {
                Box::new(|_, _, _| -1.0)
            }
            Primitive::Sphere { diameter } => {
                let r = diameter * s / 2.0;
                let c = dims[2] as f64 / 2.0;
                Box::new(move |x, y, z| (radial(x, y).powi(2) + (z - c).powi(2)).sqrt() - r)
            }
            Primitive::Cylinder { diameter, .. } => {
                let r = diameter * s / 2.0;
                Box::new(move |x, y, _| radial(x, y) - r)
            }
            Primitive::Tube { diameter, wall, .. } => {
                let (r, w) = (diameter * s / 2.0, wall * s);
                Box::new(move |x, y, _| {
                    let d = radial(x, y);
                    (d - r).max(r - w - d)
                })
            }
            Primitive::Cup { diameter, wall, .. } => {
                let (r, w) = (diameter * s / 2.0, wall * s);
                Box::new(move |x, y, z| {
                    let d = radial(x, y);
                    (d - r).max((r - w - d).min(z - w))
                })
            }
            Primitive::Bowl { diameter, wall } => {
                // Centre of the sphere at the top face: the lower hemisphere is the bowl.
                let (r, w) = (diameter * s / 2.0, wall * s);
                let top = dims[2] as f64;
                Box::new(move |x, y, z| {
                    let d = (radial(x, y).powi(2) + (z - top).powi(2)).sqrt();
                    (d - r).max(r - w - d)
                })
            }
            Primitive::Bell {
                diameter, height, ..
            } => {
                let (r_mouth, h, w) = (diameter * s / 2.0, height * s, self.thinnest() * s);
                // Outer radius flares from 0.55 R at the crown to R at the mouth (a quadratic
                // profile, roughly a church bell's); the crown is a closed cap `w` thick.
                let outer = move |z: f64| r_mouth * (0.55 + 0.45 * (1.0 - z / h).powi(2));
                // |d outer / dz| <= 0.9 R / h: dividing the radial gaps by sqrt(1 + slope^2)
                // makes them 1-Lipschitz lower bounds of the distance.
                let lipschitz = (1.0 + (0.9 * r_mouth / h).powi(2)).sqrt();
                Box::new(move |x, y, z| {
                    let d = radial(x, y);
                    let ro = outer(z);
                    let outside = (d - ro) / lipschitz;
                    let inner = (ro - w - d) / lipschitz;
                    outside.max(inner.min(h - w - z))
                })
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Primitive;

    /// A 30x3x3 bar on hex27x2's 2-voxel blocks: its two short sides get a fourth voxel and
    /// the bar sits in the middle, half of each face voxel filled. The volume is the bar's
    /// (270 voxels: the fills of axis-aligned planes through voxel middles are exact), the
    /// fills are mirror images across both padded axes bit for bit (the mesh's mirrors need
    /// them to rounding), and the longest side is not padded.
    #[test]
    fn an_odd_bar_sits_centred_on_the_blocks() {
        let bar = Primitive::Bar {
            length: 31.0,
            width: 3.0,
            height: 3.0,
        };
        let grid = bar.rasterize_on_blocks(1.0, 1.0, 2).expect("grid");
        assert_eq!(grid.dims(), [31, 4, 4]);
        assert!(
            (grid.volume_voxels() - 31.0 * 9.0).abs() <= 1e-9,
            "volume {}",
            grid.volume_voxels()
        );
        for z in 0..4isize {
            for y in 0..4isize {
                for x in 0..31isize {
                    let f = grid.fraction(x, y, z);
                    assert_eq!(f, grid.fraction(x, 3 - y, z), "y mirror at {x} {y} {z}");
                    assert_eq!(f, grid.fraction(x, y, 3 - z), "z mirror at {x} {y} {z}");
                    let faces = [y, z].iter().filter(|&&c| c == 0 || c == 3).count();
                    let expected = [1.0, 0.5, 0.25][faces];
                    assert!((f - expected).abs() <= 1e-12, "fill {f} at {x} {y} {z}");
                }
            }
        }
    }

    /// Sides that are whole blocks already, and elements of one voxel, leave the plain
    /// rasterisation as it is.
    #[test]
    fn whole_blocks_are_rasterised_as_before() {
        let bowl = Primitive::Bowl {
            diameter: 16.0,
            wall: 2.0,
        };
        let plain = bowl.rasterize(1.0, 1.0).expect("grid");
        assert_eq!(bowl.rasterize_on_blocks(1.0, 1.0, 2).expect("grid"), plain);
        let bar = Primitive::Bar {
            length: 30.0,
            width: 3.0,
            height: 5.0,
        };
        let plain = bar.rasterize(1.0, 1.0).expect("grid");
        assert_eq!(bar.rasterize_on_blocks(1.0, 1.0, 1).expect("grid"), plain);
        assert_eq!(plain.volume_voxels(), 450.0);
    }
}
