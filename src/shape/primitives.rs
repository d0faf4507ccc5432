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
