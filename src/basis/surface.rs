//! Where a strike lands: a shape's exposed voxel faces, the point of the surface nearest to
//! where a strike aims, and the direction it pushes (the voxel face's normal, or on a curved
//! surface of partial voxels the fill field's, Youngs' volume-of-fluid normal).
//!
//! Where it sits: [`super::ModeBasis`] finds its shape's faces once ([`exposed_faces`]) and
//! snaps every strike to them ([`nearest_face`], [`point_on_face`]) before interpolating the
//! modes there; the editor draws its hit marker at [`struck_point`].

use crate::shape::VoxelGrid;

/// An exposed voxel face: the voxel, the axis of the face's normal and its side (-1 or +1),
/// and the inward normal a strike on it pushes along.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Face {
    pub voxel: [usize; 3],
    pub axis: usize,
    pub side: isize,
    /// Unit inward normal: the voxel face's own, or on a curved surface of partial voxels the
    /// fill field's ([`surface_normal`]).
    pub normal: [f64; 3],
}

/// The inward unit normal of the smooth surface at voxel `v` of a grid with partial voxels:
/// the gradient of the fill fraction (1 inside, 0 outside) by a 3x3x3 Sobel-weighted central
/// difference (weights 1, 2, 4 by how close a neighbour row is), the standard normal of a
/// volume-fraction interface (Youngs' method in volume-of-fluid codes). `None` where the
/// neighbourhood holds no partial voxel (a binary staircase keeps its face normals) or the
/// gradient vanishes.
fn surface_normal(fractions: &Fractions, v: [usize; 3]) -> Option<[f64; 3]> {
    let c = v.map(|c| c as isize);
    let mut any_partial = false;
    let mut g = [0.0; 3];
    for dz in -1..=1isize {
        for dy in -1..=1isize {
            for dx in -1..=1isize {
                let d = [dx, dy, dz];
                let f = fractions.get(c[0] + dx, c[1] + dy, c[2] + dz);
                any_partial |= f > 0.0 && f < 1.0;
                for a in 0..3 {
                    // Sobel: the centre row weighs 4, edge rows 2, corner rows 1.
                    let off = (0..3).filter(|&b| b != a && d[b] != 0).count();
                    let w = [4.0, 2.0, 1.0][off];
                    g[a] += w * d[a] as f64 * f;
                }
            }
        }
    }
    let norm = g.iter().map(|x| x * x).sum::<f64>().sqrt();
    (any_partial && norm > 1e-9).then(|| g.map(|x| x / norm))
}

/// Every voxel's filled volume fraction ([`VoxelGrid::fraction`]), by voxel index.
struct Fractions {
    dims: [usize; 3],
    values: Vec<f64>,
}

impl Fractions {
    fn of(grid: &VoxelGrid) -> Self {
        let mut values: Vec<f64> = grid
            .occupancy()
            .iter()
            .map(|&o| if o { 1.0 } else { 0.0 })
            .collect();
        for (i, fill) in grid.partial_voxels() {
            if grid.occupancy()[i] {
                values[i] = fill.mean();
            }
        }
        Fractions {
            dims: grid.dims(),
            values,
        }
    }

    /// The fraction of voxel `(x, y, z)`; 0 out of range.
    fn get(&self, x: isize, y: isize, z: isize) -> f64 {
        let [nx, ny, nz] = self.dims.map(|d| d as isize);
        if x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz {
            return 0.0;
        }
        self.values[(x + nx * (y + ny * z)) as usize]
    }
}

/// Every voxel face with no solid neighbour across it.
pub(super) fn exposed_faces(grid: &VoxelGrid) -> Vec<Face> {
    let mut out = Vec::new();
    // The normals read 27 fills a surface voxel: each voxel's fraction is worked out once
    // (the mean of its 64 sub-cells), not 27 times.
    let fractions = Fractions::of(grid);
    for v in grid.solid_voxels() {
        // The fill's normal, once per voxel, for whichever of its faces are exposed.
        let mut smooth: Option<Option<[f64; 3]>> = None;
        for axis in 0..3 {
            for side in [-1isize, 1] {
                let mut nb = v.map(|c| c as isize);
                nb[axis] += side;
                if !grid.get(nb[0], nb[1], nb[2]) {
                    let mut normal = [0.0; 3];
                    normal[axis] = -(side as f64);
                    // The fill's normal, unless it points out of this face (a thin feature).
                    let fill_normal = *smooth.get_or_insert_with(|| surface_normal(&fractions, v));
                    if let Some(n) = fill_normal.filter(|n| n[axis] * normal[axis] > 0.0) {
                        normal = n;
                    }
                    out.push(Face {
                        voxel: v,
                        axis,
                        side,
                        normal,
                    });
                }
            }
        }
    }
    out
}

/// The point of the unit face square `face` nearest to `p` (voxel units).
pub(super) fn point_on_face(face: &Face, p: [f64; 3]) -> [f64; 3] {
    let v = face.voxel;
    std::array::from_fn(|a| {
        if a == face.axis {
            v[a] as f64 + if face.side > 0 { 1.0 } else { 0.0 }
        } else {
            p[a].clamp(v[a] as f64, v[a] as f64 + 1.0)
        }
    })
}

/// The face of `surface` nearest to `p` (voxel units): where a hit lands. The first of equals.
pub(super) fn nearest_face(surface: &[Face], p: [f64; 3]) -> Option<Face> {
    let mut best: Option<(f64, Face)> = None;
    for &face in surface {
        let q = point_on_face(&face, p);
        let d2: f64 = (0..3).map(|a| (p[a] - q[a]).powi(2)).sum();
        if best.is_none_or(|b| d2 < b.0) {
            best = Some((d2, face));
        }
    }
    best.map(|(_, f)| f)
}

/// Where a strike aimed at `point` lands, as a solve snaps it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StruckPoint {
    /// The nearest point of the nearest exposed face, voxel units from the grid's corner.
    pub point_voxels: [f64; 3],
    /// The face's unit inward normal (the smooth fill's on a curved surface of partial voxels):
    /// the direction a strike without a force direction pushes.
    pub inward_normal: [f64; 3],
}

/// Where a strike aimed at `point_voxels` (voxel units from the grid's corner) lands on `grid`
/// (what [`super::ModeBasis`] strikes: the editor draws its hit marker here). `None` for a grid with
/// no surface or a point that is not finite.
pub fn struck_point(grid: &VoxelGrid, point_voxels: [f64; 3]) -> Option<StruckPoint> {
    if point_voxels.iter().any(|c| !c.is_finite()) {
        return None;
    }
    let face = nearest_face(&exposed_faces(grid), point_voxels)?;
    Some(StruckPoint {
        point_voxels: point_on_face(&face, point_voxels),
        inward_normal: face.normal,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Face counts from Euler-style counting: a box of a x b x c voxels exposes
    /// 2 (ab + bc + ca) faces, whatever its position in the grid; a hollow cavity adds its
    /// inner walls.
    #[test]
    fn exposed_faces_are_the_surface() {
        let boxed = |a: usize, b: usize, c: usize| {
            VoxelGrid::from_fn([a + 2, b + 2, c + 2], 1.0, |x, y, z| {
                (1.0..=a as f64 + 1.0).contains(&x)
                    && (1.0..=b as f64 + 1.0).contains(&y)
                    && (1.0..=c as f64 + 1.0).contains(&z)
            })
            .unwrap()
        };
        assert_eq!(exposed_faces(&boxed(1, 1, 1)).len(), 6);
        assert_eq!(exposed_faces(&boxed(4, 2, 3)).len(), 2 * (8 + 6 + 12));
        // A 3^3 cube touching the grid's faces, with its centre voxel removed: 54 + 6.
        let mut g = VoxelGrid::from_fn([3, 3, 3], 1.0, |_, _, _| true).unwrap();
        g.set(1, 1, 1, false);
        assert_eq!(exposed_faces(&g).len(), 60);
    }

    /// Truth: the geometry of a box and of a tube, by hand. A point above a box lands straight
    /// below on its top, pushing down; a point in a tube's empty inside lands on the nearest
    /// inner wall (half a voxel away), pushing into the wall, never in the air.
    #[test]
    fn a_strike_lands_on_the_nearest_face_of_the_surface() {
        let block = VoxelGrid::from_fn([4, 2, 3], 1.0, |_, _, _| true).unwrap();
        let s = struck_point(&block, [1.3, 0.7, 5.0]).unwrap();
        assert_eq!(s.point_voxels, [1.3, 0.7, 3.0]);
        assert_eq!(s.inward_normal, [0.0, 0.0, -1.0]);
        let mut tube = VoxelGrid::from_fn([3, 3, 4], 1.0, |_, _, _| true).unwrap();
        for z in 0..4 {
            tube.set(1, 1, z, false);
        }
        let aim = [1.5, 1.5, 2.5];
        let s = struck_point(&tube, aim).unwrap();
        let d: Vec<f64> = (0..3).map(|a| s.point_voxels[a] - aim[a]).collect();
        assert!(((d.iter().map(|x| x * x).sum::<f64>()).sqrt() - 0.5).abs() < 1e-12);
        assert!((0..3).map(|a| d[a] * s.inward_normal[a]).sum::<f64>() > 0.49);
        assert!(struck_point(&tube, [f64::NAN, 0.0, 0.0]).is_none());
    }

    #[test]
    fn a_sphere_is_struck_along_its_true_normal() {
        // Truth: the inward normal of a sphere at a point is towards its centre. The voxel
        // faces of the staircase are off by up to 45 degrees (54.7 at a corner); the fill
        // field's normal is within 6 degrees everywhere on a 16-voxel sphere (the 3x3x3
        // stencil sees the curvature of a 8-voxel radius).
        let sphere = crate::shape::primitives::Primitive::Sphere { diameter: 16.0 };
        let grid = sphere.rasterize(1.0, 1.0).unwrap();
        let mut worst = 0.0f64;
        for f in exposed_faces(&grid) {
            let c = f.voxel.map(|c| c as f64 + 0.5);
            let to_centre = [8.0 - c[0], 8.0 - c[1], 8.0 - c[2]];
            let len = to_centre.iter().map(|x| x * x).sum::<f64>().sqrt();
            let cos: f64 = (0..3).map(|a| f.normal[a] * to_centre[a] / len).sum();
            worst = worst.max(cos.clamp(-1.0, 1.0).acos().to_degrees());
        }
        assert!(worst < 6.0, "worst normal error {worst:.2} degrees");
        // The staircase keeps its voxel-face normals.
        let stair = sphere.rasterize_staircase(1.0, 1.0).unwrap();
        for f in exposed_faces(&stair) {
            assert_eq!(f.normal.iter().map(|x| x.abs()).sum::<f64>(), 1.0);
        }
    }
}
