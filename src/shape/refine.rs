//! Sub-cell fills refined by one level: where in a cut sub-cell its material lies.
//!
//! Where it sits: between the stored fills ([`super::fill`], `4^3` sub-cells per voxel) and the
//! quadratic cut elements ([`crate::fem::cut`]), which integrate over `8^3` sub-cells per
//! voxel. A fill fraction says how much of a sub-cell is solid, not where: integrating it as
//! spread evenly over the sub-cell moves material of a thin wall's surface layer outwards from
//! the wall's middle, which stiffens bending (the 16- and 32-voxel bowls rang 1.8-2.6 % sharp
//! with hex27x2 on `4^3` sub-cells). Here each cut sub-cell is split into `2^3` children with
//! the piecewise-linear interface calculation of volume-of-fluid codes (PLIC; Youngs 1982,
//! with the normal of Youngs' method, the Sobel-weighted gradient of the fractions, as
//! [`crate::basis`] uses for strike normals): the surface inside the sub-cell is the plane
//! across the fill's gradient that leaves exactly its fraction on the solid side, and each
//! child gets the share of that solid part that falls in it. The children's mean is the
//! sub-cell's fraction, so volumes are unchanged; full and empty sub-cells stay as they are.
//! On the bowls this recovers what a rasterisation at `8^3` sub-cells gives
//! (ARCHITECTURE.md, "Partial voxels").

use super::fill::{SubFill, FULL, SUBCELLS_PER_AXIS};
use super::{VoxelFill, VoxelGrid};

/// Children per axis of a refined sub-cell.
const SPLIT: usize = 2;

/// Sub-cells per voxel axis after refinement.
pub const REFINED_PER_AXIS: usize = SUBCELLS_PER_AXIS * SPLIT;

/// Sample points per child axis that place the plane (so `4^3` per sub-cell).
const SAMPLES: usize = 2;

/// The `8^3` refined sub-cell fractions (x fastest) of the partial voxel `voxel` of `grid`,
/// into `out`.
pub fn refined_fill(grid: &VoxelGrid, voxel: [usize; 3], fill: &SubFill, out: &mut [f64]) {
    let n = SUBCELLS_PER_AXIS;
    let r = REFINED_PER_AXIS;
    assert_eq!(out.len(), r * r * r, "8^3 refined sub-cells");
    // The fractions of this voxel's sub-cells and a one-sub-cell halo from its neighbours,
    // (n + 2)^3, x fastest.
    let side = n + 2;
    let mut field = [0.0f64; (SUBCELLS_PER_AXIS + 2).pow(3)];
    // The voxel and its 26 neighbours (`[dz][dy][dx]`, each -1..=1), looked up once.
    let neighbours: [VoxelFill; 27] = std::array::from_fn(|k| {
        let d = [k % 3, (k / 3) % 3, k / 9];
        if d == [1, 1, 1] {
            return VoxelFill::Partial(*fill);
        }
        let v = [0, 1, 2].map(|a| voxel[a] as isize + d[a] as isize - 1);
        grid.fill_at(v[0], v[1], v[2])
    });
    // Halo coordinate `l` (0..n + 2) -> (neighbour offset 0..=2, sub-cell within it).
    let split_coord = |l: usize| match l {
        0 => (0, n - 1),
        l if l <= n => (1, l - 1),
        _ => (2, 0),
    };
    for (i, value) in field.iter_mut().enumerate() {
        let [(vx, sx), (vy, sy), (vz, sz)] =
            [i % side, (i / side) % side, i / (side * side)].map(split_coord);
        *value = match &neighbours[vx + 3 * (vy + 3 * vz)] {
            VoxelFill::Empty => 0.0,
            VoxelFill::Full => 1.0,
            VoxelFill::Partial(f) => f.0[sx + n * (sy + n * sz)] as f64 / FULL as f64,
        };
    }
    let at = |c: [usize; 3]| field[c[0] + side * (c[1] + side * c[2])];
    // The sample points of one sub-cell, in its unit cube, and the child each belongs to.
    const M: usize = SPLIT * SAMPLES;
    let points: [([f64; 3], usize); M * M * M] = std::array::from_fn(|k| {
        let q = [k % M, (k / M) % M, k / (M * M)];
        let x = q.map(|c| (c as f64 + 0.5) / M as f64);
        let child = q.map(|c| c / SAMPLES);
        (x, child[0] + SPLIT * (child[1] + SPLIT * child[2]))
    });
    let mut heights = [(0.0, 0usize); M * M * M];
    for sz in 0..n {
        for sy in 0..n {
            for sx in 0..n {
                let c = [sx + 1, sy + 1, sz + 1];
                let f = at(c);
                let mut children = [f; SPLIT * SPLIT * SPLIT];
                if f > 0.0 && f < 1.0 {
                    if let Some(normal) = gradient(&at, c) {
                        children = split(f, normal, &points, &mut heights);
                    }
                }
                for (child, &value) in children.iter().enumerate() {
                    let o = [
                        child % SPLIT,
                        (child / SPLIT) % SPLIT,
                        child / (SPLIT * SPLIT),
                    ];
                    let q = [sx * SPLIT + o[0], sy * SPLIT + o[1], sz * SPLIT + o[2]];
                    out[q[0] + r * (q[1] + r * q[2])] = value;
                }
            }
        }
    }
}

/// The direction of increasing fill at sub-cell `c` of the halo field (the inward normal of
/// the surface): the Sobel-weighted central difference over its 3^3 neighbourhood (weights 4,
/// 2, 1 by how close a neighbour row is). `None` where it vanishes.
fn gradient(at: &impl Fn([usize; 3]) -> f64, c: [usize; 3]) -> Option<[f64; 3]> {
    /// Per neighbour (`[dz][dy][dx]`, each 0..3 for -1..=1) and axis: the Sobel weight (4, 2
    /// or 1 by how many of the other two offsets are non-zero) times the offset along the axis.
    const WEIGHTS: [[f64; 3]; 27] = {
        let mut w = [[0.0; 3]; 27];
        let mut k = 0;
        while k < 27 {
            let d = [
                (k % 3) as i32 - 1,
                ((k / 3) % 3) as i32 - 1,
                (k / 9) as i32 - 1,
            ];
            let mut a = 0;
            while a < 3 {
                let off = (d[(a + 1) % 3] != 0) as usize + (d[(a + 2) % 3] != 0) as usize;
                w[k][a] = [4.0, 2.0, 1.0][off] * d[a] as f64;
                a += 1;
            }
            k += 1;
        }
        w
    };
    let mut g = [0.0; 3];
    for (k, w) in WEIGHTS.iter().enumerate() {
        let f = at([c[0] + k % 3 - 1, c[1] + (k / 3) % 3 - 1, c[2] + k / 9 - 1]);
        for a in 0..3 {
            g[a] += w[a] * f;
        }
    }
    let norm = g.iter().map(|x| x * x).sum::<f64>().sqrt();
    (norm > 1e-9).then(|| g.map(|x| x / norm))
}

/// The children's fractions of a sub-cell filled to `f` whose solid side lies along `normal`:
/// the solid part is the `f` share of the sample points highest along `normal` (the plane
/// `normal . x = t` that keeps the fraction), counted per child, with the boundary sample
/// taking the remainder so the children's mean is exactly `f`.
fn split(
    f: f64,
    normal: [f64; 3],
    points: &[([f64; 3], usize)],
    heights: &mut [(f64, usize)],
) -> [f64; SPLIT * SPLIT * SPLIT] {
    for (h, (x, child)) in heights.iter_mut().zip(points) {
        *h = (
            normal[0] * x[0] + normal[1] * x[1] + normal[2] * x[2],
            *child,
        );
    }
    let per_child = (heights.len() / (SPLIT * SPLIT * SPLIT)) as f64;
    let total = f * heights.len() as f64;
    // The `whole` highest samples are solid; the next one holds the remainder.
    let whole = (total.floor() as usize).min(heights.len() - 1);
    // Highest first (deterministic for the same input).
    heights.select_nth_unstable_by(whole, |a, b| b.0.total_cmp(&a.0));
    let mut children = [0.0; SPLIT * SPLIT * SPLIT];
    for &(_, child) in &heights[..whole] {
        children[child] += 1.0 / per_child;
    }
    children[heights[whole].1] += (total - whole as f64) / per_child;
    children
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The refined fill of the partial voxel `voxel` of a shape given by `sdf`.
    fn refine(sdf: impl Fn(f64, f64, f64) -> f64, dims: [usize; 3], voxel: [usize; 3]) -> Vec<f64> {
        let grid = VoxelGrid::from_sdf(dims, 1.0, sdf).unwrap();
        let VoxelFill::Partial(fill) =
            grid.fill_at(voxel[0] as isize, voxel[1] as isize, voxel[2] as isize)
        else {
            panic!("voxel {voxel:?} is not partial")
        };
        let mut out = vec![0.0; REFINED_PER_AXIS.pow(3)];
        refined_fill(&grid, voxel, &fill, &mut out);
        out
    }

    #[test]
    fn a_tilted_plane_is_refined_to_its_true_sub_cell_volumes() {
        // The half-space below a tilted plane through the middle of voxel (1, 1, 1): the exact
        // fraction of each of the 8^3 refined sub-cells is the rasterisation at 8^3 sub-cells
        // (16^3 samples per voxel here, so 2^3 per refined sub-cell: sampling error 1/8 at
        // worst where the plane cuts one). Spreading each 4^3 sub-cell's fill evenly over its
        // children instead is off by up to 1/2 in a child the plane cuts near its edge; the
        // reconstruction must be within 0.2 in every child and twice as close on average.
        let n: [f64; 3] = [0.3, 0.5, 0.81];
        let norm = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        let sdf = |x: f64, y: f64, z: f64| {
            (n[0] * (x - 1.5) + n[1] * (y - 1.5) + n[2] * (z - 1.47)) / norm
        };
        let got = refine(sdf, [3, 3, 3], [1, 1, 1]);
        let r = REFINED_PER_AXIS;
        let samples = 8usize;
        let (mut worst, mut total, mut spread_total) = (0.0f64, 0.0, 0.0);
        let grid = VoxelGrid::from_sdf([3, 3, 3], 1.0, sdf).unwrap();
        let VoxelFill::Partial(stored) = grid.fill_at(1, 1, 1) else {
            panic!("partial")
        };
        for (i, g) in got.iter().enumerate() {
            let q = [i % r, (i / r) % r, i / (r * r)];
            let mut inside = 0;
            for k in 0..samples.pow(3) {
                let s = [
                    k % samples,
                    (k / samples) % samples,
                    k / (samples * samples),
                ];
                let p = [0, 1, 2]
                    .map(|a| 1.0 + (q[a] as f64 + (s[a] as f64 + 0.5) / samples as f64) / r as f64);
                inside += (sdf(p[0], p[1], p[2]) <= 0.0) as usize;
            }
            let exact = inside as f64 / samples.pow(3) as f64;
            let parent = q.map(|c| c / SPLIT);
            let spread = stored.0
                [parent[0] + SUBCELLS_PER_AXIS * (parent[1] + SUBCELLS_PER_AXIS * parent[2])]
                as f64
                / FULL as f64;
            worst = worst.max((g - exact).abs());
            total += (g - exact).abs();
            spread_total += (spread - exact).abs();
        }
        assert!(worst < 0.2, "worst child {worst}");
        assert!(
            total < 0.5 * spread_total,
            "{total} vs spread {spread_total}"
        );
    }

    #[test]
    fn refinement_keeps_each_sub_cells_volume() {
        // A sphere's surface voxel: every refined sub-cell in [0, 1], and each stored
        // sub-cell's children average to its fraction (to rounding).
        let sdf = |x: f64, y: f64, z: f64| {
            ((x - 4.0).powi(2) + (y - 4.0).powi(2) + (z - 4.0).powi(2)).sqrt() - 3.3
        };
        let grid = VoxelGrid::from_sdf([8, 8, 8], 1.0, sdf).unwrap();
        let mut checked = 0;
        for (i, fill) in grid.partial_voxels() {
            let v = crate::shape::lattice_coords(i, grid.dims());
            let mut out = vec![0.0; REFINED_PER_AXIS.pow(3)];
            refined_fill(&grid, v, fill, &mut out);
            assert!(out.iter().all(|f| (0.0..=1.0 + 1e-12).contains(f)));
            let mut coarse = vec![0.0; SUBCELLS_PER_AXIS.pow(3)];
            fill.coarsened_into(&mut coarse);
            let r = REFINED_PER_AXIS;
            for (c, want) in coarse.iter().enumerate() {
                let n = SUBCELLS_PER_AXIS;
                let p = [c % n, (c / n) % n, c / (n * n)];
                let mut sum = 0.0;
                for o in 0..8 {
                    let q = [0, 1, 2].map(|a| p[a] * SPLIT + (o >> a & 1));
                    sum += out[q[0] + r * (q[1] + r * q[2])];
                }
                assert!((sum / 8.0 - want).abs() < 1e-12, "{sum} vs {want}");
            }
            checked += 1;
        }
        assert!(checked > 50);
    }
}
