//! Operations on voxel grids: booleans, hollowing, face-connected components.

use super::{FillLookup, VoxelFill, VoxelGrid};
use std::collections::VecDeque;

/// The six face neighbours.
pub const FACE_NEIGHBOURS: [[isize; 3]; 6] = [
    [1, 0, 0],
    [-1, 0, 0],
    [0, 1, 0],
    [0, -1, 0],
    [0, 0, 1],
    [0, 0, -1],
];

/// Why two grids cannot be combined.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CombineError {
    /// The placed grid does not fit.
    #[error("the second shape ({dims:?} voxels at offset {offset:?}) does not fit in the first ({into:?})")]
    DoesNotFit {
        /// Dimensions of the placed grid.
        dims: [usize; 3],
        /// Offset.
        offset: [usize; 3],
        /// Dimensions of the target.
        into: [usize; 3],
    },
}

fn combine(
    a: &VoxelGrid,
    b: &VoxelGrid,
    offset: [usize; 3],
    op: impl Fn(bool, bool) -> bool,
) -> Result<VoxelGrid, CombineError> {
    let (da, db) = (a.dims(), b.dims());
    if (0..3).any(|i| offset[i] + db[i] > da[i]) {
        return Err(CombineError::DoesNotFit {
            dims: db,
            offset,
            into: da,
        });
    }
    let mut out = a.clone();
    for z in 0..db[2] {
        for y in 0..db[1] {
            for x in 0..db[0] {
                let (px, py, pz) = (x + offset[0], y + offset[1], z + offset[2]);
                let v = op(
                    a.get(px as isize, py as isize, pz as isize),
                    b.occupancy()[b.index(x, y, z)],
                );
                // Voxels the operation leaves as they were keep their partial fill; a voxel
                // the second grid fills takes its fill.
                let was = a.get(px as isize, py as isize, pz as isize);
                if v && !was {
                    out.set_fill(px, py, pz, b.fill_at(x as isize, y as isize, z as isize));
                } else if v != was {
                    out.set(px, py, pz, v);
                }
            }
        }
    }
    Ok(out)
}

/// `a` with `b` (placed at `offset` inside `a`'s grid) added.
pub fn union(a: &VoxelGrid, b: &VoxelGrid, offset: [usize; 3]) -> Result<VoxelGrid, CombineError> {
    combine(a, b, offset, |p, q| p || q)
}

/// `a` with `b` (placed at `offset`) carved away.
pub fn difference(
    a: &VoxelGrid,
    b: &VoxelGrid,
    offset: [usize; 3],
) -> Result<VoxelGrid, CombineError> {
    combine(a, b, offset, |p, q| p && !q)
}

/// Keeps only solid voxels within `wall_voxels` face steps of the outside (an empty voxel or
/// the grid boundary): a closed shell of that wall thickness. `wall_voxels = 0` keeps nothing.
/// Partial voxels count as whole steps and keep their fill.
pub fn hollow(grid: &VoxelGrid, wall_voxels: usize) -> VoxelGrid {
    let [nx, ny, nz] = grid.dims();
    let mut dist = vec![usize::MAX; grid.occupancy().len()];
    let mut queue = VecDeque::new();
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                let i = grid.index(x, y, z);
                let on_boundary =
                    x == 0 || y == 0 || z == 0 || x == nx - 1 || y == ny - 1 || z == nz - 1;
                if !grid.occupancy()[i] {
                    dist[i] = 0;
                    queue.push_back([x, y, z]);
                } else if on_boundary {
                    dist[i] = 1;
                    queue.push_back([x, y, z]);
                }
            }
        }
    }
    while let Some([x, y, z]) = queue.pop_front() {
        let d = dist[grid.index(x, y, z)];
        for n in FACE_NEIGHBOURS {
            let (px, py, pz) = (x as isize + n[0], y as isize + n[1], z as isize + n[2]);
            if grid.get(px, py, pz) {
                let j = grid.index(px as usize, py as usize, pz as usize);
                if dist[j] > d + 1 {
                    dist[j] = d + 1;
                    queue.push_back([px as usize, py as usize, pz as usize]);
                }
            }
        }
    }
    // The voxels that stay keep their fill (a smooth outer surface stays smooth).
    let mut out = grid.clone();
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                let i = grid.index(x, y, z);
                if grid.occupancy()[i] && dist[i] > wall_voxels {
                    out.set(x, y, z, false);
                }
            }
        }
    }
    out
}

/// Labels face-connected components of the solid voxels: `(labels, count)`, with label
/// `usize::MAX` for empty voxels and `0..count` for solid ones.
pub fn components(grid: &VoxelGrid) -> (Vec<usize>, usize) {
    let mut label = vec![usize::MAX; grid.occupancy().len()];
    let mut count = 0;
    let mut stack = Vec::new();
    for start in grid.solid_voxels() {
        let s = grid.index(start[0], start[1], start[2]);
        if label[s] != usize::MAX {
            continue;
        }
        label[s] = count;
        stack.push(start);
        while let Some([x, y, z]) = stack.pop() {
            for n in FACE_NEIGHBOURS {
                let (px, py, pz) = (x as isize + n[0], y as isize + n[1], z as isize + n[2]);
                if grid.get(px, py, pz) {
                    let j = grid.index(px as usize, py as usize, pz as usize);
                    if label[j] == usize::MAX {
                        label[j] = count;
                        stack.push([px as usize, py as usize, pz as usize]);
                    }
                }
            }
        }
        count += 1;
    }
    (label, count)
}

/// `grid` resampled so that its longest side is `side` voxels (at least 1), keeping its
/// proportions: each new voxel takes the fill of the old voxel its centre falls in (nearest
/// voxel centre; a partial voxel's sub-cell fills go with it). The voxel edge scales so the
/// object keeps its size in metres. `None` when the object vanishes at that size (empty, or
/// thinner than one new voxel everywhere).
pub fn resampled(grid: &VoxelGrid, side: usize) -> Option<VoxelGrid> {
    let dims = grid.dims();
    let longest = dims.into_iter().max().unwrap_or(1).max(1);
    let side = side.max(1);
    let s = side as f64 / longest as f64;
    let new_dims = dims.map(|d| ((d as f64 * s).round() as usize).clamp(1, side));
    let mut out = VoxelGrid::new(new_dims, grid.voxel_size_m() / s).ok()?;
    // The source coordinate of each new row, column and layer, once (a source outside the
    // grid is empty); the partial fills are read through an index and written in index order,
    // so the whole is one pass (it was a map lookup and insert per voxel: ~1 ms at 32^3).
    let source = |a: usize| -> Vec<Option<usize>> {
        (0..new_dims[a])
            .map(|v| {
                let c = ((v as f64 + 0.5) / s).floor();
                (c >= 0.0 && (c as usize) < dims[a]).then_some(c as usize)
            })
            .collect()
    };
    let [sx, sy, sz] = [source(0), source(1), source(2)];
    let partial_of = FillLookup::new(grid);
    let mut partial = Vec::new();
    let mut i = 0;
    for z in &sz {
        for y in &sy {
            for x in &sx {
                if let (Some(x), Some(y), Some(z)) = (x, y, z) {
                    match partial_of.fill_at(*x as isize, *y as isize, *z as isize) {
                        // As `set_fill` stores them: a full partial is full, an empty one empty.
                        VoxelFill::Partial(f) if f.0.iter().all(|&v| v == 0) => {}
                        VoxelFill::Empty => {}
                        VoxelFill::Full => out.occupied[i] = true,
                        VoxelFill::Partial(f) if f.is_full() => out.occupied[i] = true,
                        VoxelFill::Partial(f) => {
                            out.occupied[i] = true;
                            partial.push((i, f));
                        }
                    }
                }
                i += 1;
            }
        }
    }
    // In index order already: the map is built in bulk.
    out.partial = partial.into_iter().collect();
    (out.count() > 0).then_some(out)
}

/// Each voxel's filled fraction in `[0, 1]`, dense, x fastest ([`super::lattice_index`]): one
/// pass over the occupancy and the partial voxels, not a lookup per voxel.
pub fn fill_fractions(grid: &VoxelGrid) -> Vec<f64> {
    let mut values: Vec<f64> = grid
        .occupancy()
        .iter()
        .map(|&o| f64::from(u8::from(o)))
        .collect();
    for (i, f) in grid.partial_voxels() {
        values[i] = f.mean();
    }
    values
}

/// An object's mean wall thickness in voxels, `2 V / A`: twice its filled volume over its
/// surface area, both counted on the voxel fills (the area as the fill's jumps between
/// neighbouring voxels along each axis, the grid's outside empty). A plate or a shell of
/// thickness `t` gives about `t`.
pub fn mean_wall_voxels(grid: &VoxelGrid) -> f64 {
    mean_wall_of(grid.dims(), &fill_fractions(grid))
}

/// [`mean_wall_voxels`] of the fills [`fill_fractions`] gave for a grid of `dims`.
pub fn mean_wall_of(dims: [usize; 3], fills: &[f64]) -> f64 {
    let [nx, ny, nz] = dims;
    // A fill, 0 outside the grid.
    let f = |x: usize, y: usize, z: usize| {
        if x < nx && y < ny && z < nz {
            fills[x + nx * (y + ny * z)]
        } else {
            0.0
        }
    };
    let (mut volume, mut area) = (0.0, 0.0);
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                let here = f(x, y, z);
                volume += here;
                area += (f(x + 1, y, z) - here).abs()
                    + (f(x, y + 1, z) - here).abs()
                    + (f(x, y, z + 1) - here).abs();
                // The faces on the grid's low sides.
                area += here * [x, y, z].iter().filter(|&&c| c == 0).count() as f64;
            }
        }
    }
    2.0 * volume / area.max(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube(n: usize) -> VoxelGrid {
        VoxelGrid::from_fn([n; 3], 0.01, |_, _, _| true).unwrap()
    }

    #[test]
    fn the_mean_wall_of_a_plate_is_counted_by_hand() {
        // A 20 x 10 x 2 plate: 400 voxels, 2 (200 + 40 + 20) = 520 exposed faces, so
        // 2 V / A = 800 / 520; half-filled voxels count half (the same plate at fill 0.5 has
        // 200 of volume over the same 520 faces at jumps of 0.5: 400 / 260).
        let plate = VoxelGrid::from_fn([20, 10, 2], 0.01, |_, _, _| true).unwrap();
        assert!((mean_wall_voxels(&plate) - 800.0 / 520.0).abs() < 1e-12);
        let mut half = plate.clone();
        for z in 0..2 {
            for y in 0..10 {
                for x in 0..20 {
                    half.set_fill(x, y, z, crate::shape::fill::uniform(0.5));
                }
            }
        }
        let fills = fill_fractions(&half);
        assert!(
            fills.iter().all(|&f| (f - 0.5).abs() < 0.01),
            "{:?}",
            &fills[..4]
        );
        let want = 2.0 * fills.iter().sum::<f64>() / (520.0 * fills[0]);
        assert!((mean_wall_voxels(&half) - want).abs() < 1e-12);
    }

    #[test]
    fn hollow_cube_keeps_a_shell() {
        // A 6^3 cube hollowed to 1 voxel keeps 6^3 - 4^3 voxels; to 3 it stays solid.
        assert_eq!(hollow(&cube(6), 1).count(), 216 - 64);
        assert_eq!(hollow(&cube(6), 3).count(), 216);
    }

    #[test]
    fn hollowing_a_smooth_sphere_keeps_its_surface_fill() {
        // Every partial voxel lies on the outside, so all of them stay, with their fill.
        let sphere = crate::shape::primitives::Primitive::Sphere { diameter: 12.0 }
            .rasterize(1.0, 1.0)
            .unwrap();
        let shell = hollow(&sphere, 2);
        assert!(shell.count() < sphere.count());
        assert!(sphere
            .partial_voxels()
            .all(|(i, f)| shell.subcell_fill(i) == Some(f)));
    }

    #[test]
    fn resampling_takes_each_new_voxel_from_the_old_one_its_centre_falls_in() {
        // The definition, voxel by voxel through the grid's own accessors, against the one
        // pass: a smooth sphere (partial voxels) up to 32 and down to 5, a bar whose sides
        // round differently, equal (`VoxelGrid`'s own equality: occupancy, fills, edge).
        let by_definition = |grid: &VoxelGrid, side: usize| {
            let longest = grid.dims().into_iter().max().unwrap();
            let s = side as f64 / longest as f64;
            let dims = grid
                .dims()
                .map(|d| ((d as f64 * s).round() as usize).clamp(1, side));
            let mut out = VoxelGrid::new(dims, grid.voxel_size_m() / s).unwrap();
            for z in 0..dims[2] {
                for y in 0..dims[1] {
                    for x in 0..dims[0] {
                        let src = [x, y, z].map(|v| ((v as f64 + 0.5) / s).floor() as isize);
                        out.set_fill(x, y, z, grid.fill_at(src[0], src[1], src[2]));
                    }
                }
            }
            out
        };
        let sphere = crate::shape::primitives::Primitive::Sphere { diameter: 12.0 }
            .rasterize(1.0, 0.01)
            .unwrap();
        assert!(!sphere.is_binary());
        let bar = VoxelGrid::from_fn([7, 3, 2], 0.01, |x, y, _| {
            !((x + y) as usize).is_multiple_of(3)
        })
        .unwrap();
        for (grid, side) in [(&sphere, 32), (&sphere, 5), (&bar, 16), (&bar, 4)] {
            let fast = resampled(grid, side).unwrap();
            assert_eq!(fast, by_definition(grid, side), "side {side}");
            assert!(!fast.is_binary() || grid.is_binary());
        }
    }

    #[test]
    fn components_count_face_connection_only() {
        // Two cubes touching along an edge are two face-connected components.
        let mut g = VoxelGrid::new([4, 4, 2], 0.01).unwrap();
        g.set(0, 0, 0, true);
        g.set(1, 1, 0, true);
        g.set(3, 3, 1, true);
        g.set(3, 2, 1, true);
        assert_eq!(components(&g).1, 3);
    }

    #[test]
    fn union_and_difference() {
        let a = cube(4);
        let b = cube(2);
        assert_eq!(difference(&a, &b, [1, 1, 1]).unwrap().count(), 64 - 8);
        let empty = VoxelGrid::new([4; 3], 0.01).unwrap();
        assert_eq!(union(&empty, &b, [2, 2, 2]).unwrap().count(), 8);
        assert!(union(&empty, &b, [3, 3, 3]).is_err());
    }
}
