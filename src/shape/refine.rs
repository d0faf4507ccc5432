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
//! child gets the share of that solid part that falls in it. Both are closed forms: the volume
//! a plane cuts from a cube and its inverse (Scardovelli and Zaleski 2000, "Analytical
//! relations connecting linear interfaces and volume fractions in rectangular grids", J.
//! Comput. Phys. 164; as Basilisk's `plane_volume` and `plane_alpha` write them). The
//! children's mean is the sub-cell's fraction, so volumes are unchanged; full and empty
//! sub-cells stay as they are.
//! On the bowls this recovers what a rasterisation at `8^3` sub-cells gives
//! (ARCHITECTURE.md, "Partial voxels").

use super::fill::{SubFill, FULL, SUBCELLS_PER_AXIS};
use super::{FillLookup, VoxelFill};

/// Children per axis of a refined sub-cell.
const SPLIT: usize = 2;

/// Sub-cells per voxel axis after refinement.
pub const REFINED_PER_AXIS: usize = SUBCELLS_PER_AXIS * SPLIT;

/// Sub-cells per axis of the halo field: a voxel's and one layer from each neighbour.
const HALO_SIDE: usize = SUBCELLS_PER_AXIS + 2;

/// A stored sub-cell byte as a fraction (`byte / FULL`, exactly as dividing gives it).
const FRACTION: [f64; 256] = {
    let mut t = [0.0; 256];
    let mut b = 0;
    while b < 256 {
        t[b] = b as f64 / FULL as f64;
        b += 1;
    }
    t
};

/// The `8^3` refined sub-cell fractions (x fastest) of the partial voxel `voxel` of the grid
/// `fills` indexes, into `out`.
pub fn refined_fill(fills: &FillLookup, voxel: [usize; 3], fill: &SubFill, out: &mut [f64]) {
    let n = SUBCELLS_PER_AXIS;
    let r = REFINED_PER_AXIS;
    assert_eq!(out.len(), r * r * r, "8^3 refined sub-cells");
    // The fractions of this voxel's sub-cells and a one-sub-cell halo from its neighbours,
    // (n + 2)^3, x fastest.
    let side = HALO_SIDE;
    let mut field = [0.0f64; HALO_SIDE.pow(3)];
    // Each of the voxel and its 26 neighbours (`[dz][dy][dx]`, each -1..=1) fills its part of
    // the halo: per axis, offset -1 gives the last sub-cell layer, 0 all of them, +1 the first.
    for k in 0..27 {
        let d = [k % 3, (k / 3) % 3, k / 9];
        let neighbour = if d == [1, 1, 1] {
            VoxelFill::Partial(*fill)
        } else {
            let v = [0, 1, 2].map(|a| voxel[a] as isize + d[a] as isize - 1);
            fills.fill_at(v[0], v[1], v[2])
        };
        // Per axis: the sub-cells taken from the neighbour and where they go in the halo.
        let range = d.map(|o| match o {
            0 => (n - 1..n, 0),
            1 => (0..n, 1),
            _ => (0..1, n + 1),
        });
        for sz in range[2].0.clone() {
            for sy in range[1].0.clone() {
                for sx in range[0].0.clone() {
                    let s = [sx, sy, sz];
                    let h = [0, 1, 2].map(|a| s[a] - range[a].0.start + range[a].1);
                    field[h[0] + side * (h[1] + side * h[2])] = match &neighbour {
                        VoxelFill::Empty => 0.0,
                        VoxelFill::Full => 1.0,
                        VoxelFill::Partial(f) => FRACTION[f.0[sx + n * (sy + n * sz)] as usize],
                    };
                }
            }
        }
    }
    for sz in 0..n {
        for sy in 0..n {
            for sx in 0..n {
                let c = [sx + 1, sy + 1, sz + 1];
                let f = field[c[0] + side * (c[1] + side * c[2])];
                let mut children = [f; SPLIT * SPLIT * SPLIT];
                if f > 0.0 && f < 1.0 {
                    if let Some(normal) = gradient(&field, c) {
                        children = split(f, normal);
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

/// The direction of increasing fill at sub-cell `c` of the halo `field` (`(n + 2)^3`, x
/// fastest; the inward normal of the surface): the Sobel-weighted central difference over its
/// 3^3 neighbourhood (weights 4, 2, 1 by how close a neighbour row is: the product of 2, 1 per
/// transverse offset). `None` where it vanishes.
fn gradient(field: &[f64], c: [usize; 3]) -> Option<[f64; 3]> {
    const W: [f64; 3] = [1.0, 2.0, 1.0];
    let at = |x: usize, y: usize, z: usize| field[x + HALO_SIDE * (y + HALO_SIDE * z)];
    let [x, y, z] = c;
    let mut g = [0.0; 3];
    for (j, wj) in W.iter().enumerate() {
        for (i, wi) in W.iter().enumerate() {
            let w = wi * wj;
            // Transverse offsets `i - 1` and `j - 1` (every index is at least 1 here).
            g[0] += w * (at(x + 1, y + i - 1, z + j - 1) - at(x - 1, y + i - 1, z + j - 1));
            g[1] += w * (at(x + i - 1, y + 1, z + j - 1) - at(x + i - 1, y - 1, z + j - 1));
            g[2] += w * (at(x + i - 1, y + j - 1, z + 1) - at(x + i - 1, y + j - 1, z - 1));
        }
    }
    let norm = g.iter().map(|x| x * x).sum::<f64>().sqrt();
    (norm > 1e-9).then(|| g.map(|x| x / norm))
}

/// The volume of `{y in [0,1]^3 : m . y <= alpha}` for `m` sorted ascending, non-negative and
/// summing to 1 (Scardovelli and Zaleski 2000, eq. 2.8 with its symmetry `V(1 - alpha) = 1 - V`).
fn plane_volume(m: [f64; 3], alpha: f64) -> f64 {
    if alpha <= 0.0 {
        return 0.0;
    }
    if alpha >= 1.0 {
        return 1.0;
    }
    let [m1, m2, m3] = m;
    let a = alpha.min(1.0 - alpha);
    let m12 = m1 + m2;
    let v = if a < m1 {
        a * a * a / (6.0 * m1 * m2 * m3)
    } else if a < m2 {
        a * (a - m1) / (2.0 * m2 * m3) + m1 * m1 / (6.0 * m2 * m3)
    } else if a < m12.min(m3) {
        (a * a * (3.0 * m12 - a) + m1 * m1 * (m1 - 3.0 * a) + m2 * m2 * (m2 - 3.0 * a))
            / (6.0 * m1 * m2 * m3)
    } else if m3 < m12 {
        (a * a * (3.0 - 2.0 * a)
            + m1 * m1 * (m1 - 3.0 * a)
            + m2 * m2 * (m2 - 3.0 * a)
            + m3 * m3 * (m3 - 3.0 * a))
            / (6.0 * m1 * m2 * m3)
    } else {
        (2.0 * a - m12) / (2.0 * m3)
    };
    if alpha <= 0.5 {
        v
    } else {
        1.0 - v
    }
}

/// The `alpha` with `plane_volume(m, alpha) = volume` (the inverse of [`plane_volume`], in
/// closed form: Scardovelli and Zaleski 2000, sec. 3, as Basilisk's `plane_alpha` writes it).
fn plane_alpha(m: [f64; 3], volume: f64) -> f64 {
    let [m1, m2, m3] = m;
    let m12 = m1 + m2;
    let pr = (6.0 * m1 * m2 * m3).max(1e-50);
    let v1 = m1 * m1 * m1 / pr;
    let v2 = v1 + (m2 - m1) / (2.0 * m3);
    let (mm, v3) = if m3 < m12 {
        (
            m3,
            (m3 * m3 * (3.0 * m12 - m3) + m1 * m1 * (m1 - 3.0 * m3) + m2 * m2 * (m2 - 3.0 * m3))
                / pr,
        )
    } else {
        (m12, m12 / (2.0 * m3))
    };
    let c = volume.min(1.0 - volume);
    let alpha = if c < v1 {
        (pr * c).cbrt()
    } else if c < v2 {
        (m1 + (m1 * m1 + 8.0 * m2 * m3 * (c - v1)).sqrt()) / 2.0
    } else if c < v3 {
        let p12 = (2.0 * m1 * m2).sqrt();
        let q = 3.0 * (m12 - 2.0 * m3 * c) / (4.0 * p12);
        let cs = (q.clamp(-1.0, 1.0).acos() / 3.0).cos();
        p12 * ((3.0 * (1.0 - cs * cs)).sqrt() - cs) + m12
    } else if m12 <= m3 {
        m3 * c + mm / 2.0
    } else {
        let p = m1 * (m2 + m3) + m2 * m3 - 0.25;
        let p12 = p.sqrt();
        let q = 3.0 * m1 * m2 * m3 * (0.5 - c) / (2.0 * p * p12);
        let cs = (q.clamp(-1.0, 1.0).acos() / 3.0).cos();
        p12 * ((3.0 * (1.0 - cs * cs)).sqrt() - cs) + 0.5
    };
    if volume > 0.5 {
        1.0 - alpha
    } else {
        alpha
    }
}

/// The children's fractions of a sub-cell filled to `f` whose solid side lies along `normal`
/// (unit): the solid part is `normal . x >= t` with `t` placed so that it holds `f` exactly
/// (PLIC), and each child gets the exact volume of that half-space inside it, rescaled so the
/// children's mean is exactly `f` where rounding moved it.
fn split(f: f64, normal: [f64; 3]) -> [f64; SPLIT * SPLIT * SPLIT] {
    // Mirror the axes with negative components so the normal is non-negative; scale it to sum
    // 1 (the unit cube's plane-volume formulas take it so), and sort it.
    let abs = normal.map(f64::abs);
    let sum = abs[0] + abs[1] + abs[2];
    let m = abs.map(|c| c / sum);
    let mut sorted = m;
    sorted.sort_by(f64::total_cmp);
    // The empty part is `m . y < alpha` in mirrored coordinates `y`.
    let alpha = plane_alpha(sorted, 1.0 - f);
    let mut children = [0.0; SPLIT * SPLIT * SPLIT];
    let mut total = 0.0;
    for (child, value) in children.iter_mut().enumerate() {
        // The child's lowest corner in mirrored coordinates (0 or 1/2 per axis).
        let corner: f64 = (0..3)
            .map(|a| {
                let upper = (child >> a & 1) == 1;
                let mirrored = upper != (normal[a] < 0.0);
                if mirrored {
                    0.5 * m[a]
                } else {
                    0.0
                }
            })
            .sum();
        *value = 1.0 - plane_volume(sorted, 2.0 * (alpha - corner));
        total += *value;
    }
    let mean = total / children.len() as f64;
    if mean > f {
        children.iter_mut().for_each(|c| *c *= f / mean);
    } else if mean < f {
        let scale = (1.0 - f) / (1.0 - mean);
        children
            .iter_mut()
            .for_each(|c| *c = 1.0 - (1.0 - *c) * scale);
    }
    children
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shape::VoxelGrid;

    /// The refined fill of the partial voxel `voxel` of a shape given by `sdf`.
    fn refine(sdf: impl Fn(f64, f64, f64) -> f64, dims: [usize; 3], voxel: [usize; 3]) -> Vec<f64> {
        let grid = VoxelGrid::from_sdf(dims, 1.0, sdf).unwrap();
        let VoxelFill::Partial(fill) =
            grid.fill_at(voxel[0] as isize, voxel[1] as isize, voxel[2] as isize)
        else {
            panic!("voxel {voxel:?} is not partial")
        };
        let mut out = vec![0.0; REFINED_PER_AXIS.pow(3)];
        refined_fill(&FillLookup::new(&grid), voxel, &fill, &mut out);
        out
    }

    #[test]
    fn the_plane_volume_and_its_inverse_match_closed_forms() {
        // Independent truths for the cube cut by `m . y <= alpha` (`m` summing to 1): an
        // axis plane cuts a slab of volume `alpha`; an edge-diagonal one a prism of volume
        // `2 alpha^2` (alpha <= 1/2); the body diagonal a corner tetrahedron `(3 alpha)^3 / 6`
        // (alpha <= 1/3). The formulas are exact, so the bound is rounding (1e-12).
        let third = 1.0 / 3.0;
        for a in [0.05f64, 0.2, 0.3, 0.45] {
            // (normal, alpha, the exact volume)
            let body = 2.0 * a / 3.0;
            let cases = [
                ([0.0, 0.0, 1.0], a, a),
                ([0.0, 0.5, 0.5], a, 2.0 * a * a),
                ([third, third, third], body, (3.0 * body).powi(3) / 6.0),
            ];
            for (m, alpha, want) in cases {
                let got = plane_volume(m, alpha);
                assert!((got - want).abs() < 1e-12, "{m:?} {alpha}: {got} vs {want}");
                // The mirror image: the rest of the cube.
                let rest = plane_volume(m, 1.0 - alpha);
                assert!((rest - (1.0 - want)).abs() < 1e-12, "{m:?}: {rest}");
            }
        }
        // The inverse round-trips for every kind of normal, degenerate ones included.
        let normals = [
            [0.0, 0.0, 1.0],
            [0.0, 0.3, 0.7],
            [1e-9, 0.4, 0.6 - 1e-9],
            [0.1, 0.2, 0.7],
            [0.2, 0.3, 0.5],
            [third, third, third],
        ];
        for m in normals {
            for k in 1..100 {
                let volume = k as f64 / 100.0;
                let alpha = plane_alpha(m, volume);
                let back = plane_volume(m, alpha);
                assert!((back - volume).abs() < 1e-9, "{m:?} {volume}: {back}");
            }
        }
    }

    #[test]
    fn a_split_puts_the_solid_where_the_plane_does() {
        // A sub-cell 30 % full on its +z side: the plane is z = 0.7, so the four upper
        // children hold 0.3 / 0.5 = 0.6 and the lower ones nothing. Along the diagonal
        // (1, 1, 0) / sqrt(2) half full: the plane x + y = 1 leaves the (+x, +y) children
        // full, the (-x, -y) ones empty and the other two half full.
        let got = split(0.3, [0.0, 0.0, 1.0]);
        for (child, v) in got.iter().enumerate() {
            let want = if child >= 4 { 0.6 } else { 0.0 };
            assert!((v - want).abs() < 1e-12, "child {child}: {v}");
        }
        let d = std::f64::consts::FRAC_1_SQRT_2;
        let got = split(0.5, [d, d, 0.0]);
        for (child, v) in got.iter().enumerate() {
            let want = [0.0, 0.5, 0.5, 1.0][child % 4];
            assert!((v - want).abs() < 1e-12, "child {child}: {v}");
        }
        // A mirrored normal mirrors the children.
        let up = split(0.2, [0.3, -0.5, 0.81]);
        let down = split(0.2, [0.3, 0.5, 0.81]);
        for child in 0..8 {
            assert!((up[child] - down[child ^ 2]).abs() < 1e-12);
        }
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
    fn the_lookup_gives_the_grids_fills() {
        // Every voxel of a partial sphere and a one-voxel margin outside the grid, against the
        // grid's own search.
        let sdf = |x: f64, y: f64, z: f64| {
            ((x - 4.0).powi(2) + (y - 4.5).powi(2) + (z - 3.5).powi(2)).sqrt() - 3.3
        };
        let grid = VoxelGrid::from_sdf([8, 9, 7], 1.0, sdf).unwrap();
        let lookup = FillLookup::new(&grid);
        let searched = FillLookup::unindexed(&grid);
        let (mut partial, mut full) = (0, 0);
        for z in -1..=7 {
            for y in -1..=9 {
                for x in -1..=8 {
                    let fill = grid.fill_at(x, y, z);
                    assert_eq!(lookup.fill_at(x, y, z), fill, "({x}, {y}, {z})");
                    assert_eq!(searched.fill_at(x, y, z), fill, "({x}, {y}, {z})");
                    partial += matches!(fill, VoxelFill::Partial(_)) as usize;
                    full += (fill == VoxelFill::Full) as usize;
                }
            }
        }
        assert!(partial > 50 && full > 20, "{partial} partial, {full} full");
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
            refined_fill(&FillLookup::new(&grid), v, fill, &mut out);
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
