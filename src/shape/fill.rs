//! Partial voxels: how much of a voxel a curved surface fills, down to sub-cells.
//!
//! Where it sits: a [`super::VoxelGrid`] is binary except on the surface of a smooth shape,
//! where each cut voxel keeps a [`SubFill`]: the fraction of each of its
//! [`SUBCELLS_PER_AXIS`]`^3` sub-cells inside the shape. The FEM integrates stiffness and mass
//! over exactly those fractions ([`crate::fem::cut`], the finite cell method), which is what
//! keeps a voxelised bowl's degenerate mode pairs together and its pitch right. Primitives
//! rasterise through [`voxel_fill`], closed meshes through [`super::mesh::voxelize`];
//! MagicaVoxel files and sculpting stay binary.
//!
//! The sub-cell count was chosen by measurement: the split of the lowest mode pair of the
//! 16- and 32-voxel bowls, and their frequencies against a smooth-geometry reference, with 1, 2
//! and 4 sub-cells per axis (ARCHITECTURE.md, "Partial voxels").

/// Sub-cells per voxel axis.
pub const SUBCELLS_PER_AXIS: usize = 4;

/// Sub-cells per voxel.
pub const SUBCELLS: usize = SUBCELLS_PER_AXIS * SUBCELLS_PER_AXIS * SUBCELLS_PER_AXIS;

/// Fill of a sub-cell, in 1/255: 255 is full.
pub const FULL: u8 = 255;

/// Sample points per axis of a sub-cell the surface cuts: `4^3`, so a voxel is sampled on a
/// 16^3 lattice where it is cut (a plane's position to 1/16 of a voxel; over a curved surface
/// the sampling errors average out: volumes within 0.1 %, `tests/partial_voxels.rs`).
const SAMPLES_PER_SUBCELL_AXIS: usize = 4;

/// A voxel's mean fill below which rasterisation leaves it empty: a sliver under 1 % of a voxel
/// adds DOFs and nothing audible.
pub const MIN_VOXEL_FILL: f64 = 0.01;

/// Fill of each sub-cell of one partial voxel, x fastest, in 1/255.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct SubFill(pub [u8; SUBCELLS]);

impl SubFill {
    /// Fractions in `[0, 1]` quantised to 1/255.
    pub fn from_fractions(fractions: [f64; SUBCELLS]) -> Self {
        Self(fractions.map(|f| (f.clamp(0.0, 1.0) * FULL as f64).round() as u8))
    }

    /// The fractions averaged onto `per_axis^3` coarser sub-cells (x fastest); `per_axis` divides
    /// [`SUBCELLS_PER_AXIS`].
    pub fn coarsened(&self, per_axis: usize) -> Vec<f64> {
        let mut out = vec![0.0; per_axis.clamp(1, SUBCELLS_PER_AXIS).pow(3)];
        self.coarsened_into(&mut out);
        out
    }

    /// [`SubFill::coarsened`] into `out`, whose length (`per_axis^3`) picks the sub-cell count.
    pub fn coarsened_into(&self, out: &mut [f64]) {
        let n = SUBCELLS_PER_AXIS;
        let per_axis = (1..=n)
            .find(|p| p * p * p >= out.len())
            .expect("at most SUBCELLS sub-cells");
        assert_eq!(per_axis.pow(3), out.len(), "a cube number of sub-cells");
        let r = n / per_axis;
        // Integer sums (exact), then one scaling per coarse sub-cell.
        let coarse: [usize; SUBCELLS_PER_AXIS] = std::array::from_fn(|i| i / r);
        let mut sums = [0u32; SUBCELLS];
        let mut fine = self.0.iter();
        for &z in &coarse {
            for &y in &coarse {
                let row = per_axis * (y + per_axis * z);
                for (&x, &f) in coarse.iter().zip(fine.by_ref()) {
                    sums[row + x] += f as u32;
                }
            }
        }
        let norm = (FULL as usize * r * r * r) as f64;
        for (o, &s) in out.iter_mut().zip(&sums) {
            *o = s as f64 / norm;
        }
    }

    /// Every sub-cell's fraction in `[0, 1]`.
    pub fn fractions(&self) -> [f64; SUBCELLS] {
        self.0.map(|f| f as f64 / FULL as f64)
    }

    /// The voxel's filled volume fraction.
    pub fn mean(&self) -> f64 {
        self.0.iter().map(|&f| f as f64).sum::<f64>() / (FULL as f64 * SUBCELLS as f64)
    }

    /// Whether every sub-cell is full (the voxel is an ordinary solid one).
    pub fn is_full(&self) -> bool {
        self.0.iter().all(|&f| f == FULL)
    }

    /// The fill's centroid offset from the voxel centre, in voxel units (each axis in
    /// `[-1/4, 1/4]`): where in the voxel the material sits, for surface normals.
    pub fn centroid_offset(&self) -> [f64; 3] {
        let total: f64 = self.0.iter().map(|&f| f as f64).sum();
        let mut c = [0.0; 3];
        if total == 0.0 {
            return c;
        }
        let n = SUBCELLS_PER_AXIS;
        for (i, &f) in self.0.iter().enumerate() {
            let idx = [i % n, (i / n) % n, i / (n * n)];
            for a in 0..3 {
                c[a] += f as f64 * ((idx[a] as f64 + 0.5) / n as f64 - 0.5);
            }
        }
        c.map(|v| v / total)
    }
}

/// What a voxel of a rasterised shape is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum VoxelFill {
    /// Outside the shape.
    Empty,
    /// Inside the shape.
    Full,
    /// Cut by the surface.
    Partial(SubFill),
}

/// A voxel filled to `fraction` throughout (empty or full at the ends).
pub fn uniform(fraction: f64) -> VoxelFill {
    fill_of([fraction; SUBCELLS])
}

/// Rasterises a shape given by a signed distance `sdf(x, y, z)` in voxel units (negative
/// inside, at most 1 per voxel of change: an exact distance or a lower bound scaled to be
/// 1-Lipschitz): voxels, and then sub-cells, farther than half their diagonal from the surface
/// are full or empty from their centre; the sub-cells the surface cuts are sampled on a
/// `4^3` lattice.
pub fn voxel_fill(sdf: &impl Fn(f64, f64, f64) -> f64, voxel: [usize; 3]) -> VoxelFill {
    let c = voxel.map(|v| v as f64 + 0.5);
    let d = sdf(c[0], c[1], c[2]);
    // Half the voxel's diagonal plus rounding room.
    let band = 0.5 * 3f64.sqrt() + 1e-9;
    if d > band {
        return VoxelFill::Empty;
    }
    if d < -band {
        return VoxelFill::Full;
    }
    let n = SUBCELLS_PER_AXIS;
    let m = SAMPLES_PER_SUBCELL_AXIS;
    let step = 1.0 / (n * m) as f64;
    let mut fractions = [0.0; SUBCELLS];
    // A sub-cell farther from the surface than half its diagonal is empty or full.
    let sub_band = 0.5 * 3f64.sqrt() / n as f64 + 1e-9;
    for (i, frac) in fractions.iter_mut().enumerate() {
        let sub = [i % n, (i / n) % n, i / (n * n)];
        let centre = [0, 1, 2].map(|a| voxel[a] as f64 + (sub[a] as f64 + 0.5) / n as f64);
        let d = sdf(centre[0], centre[1], centre[2]);
        if d.abs() > sub_band {
            *frac = if d < 0.0 { 1.0 } else { 0.0 };
            continue;
        }
        let mut inside = 0usize;
        for sz in 0..m {
            let z = voxel[2] as f64 + (sub[2] * m + sz) as f64 * step + 0.5 * step;
            for sy in 0..m {
                let y = voxel[1] as f64 + (sub[1] * m + sy) as f64 * step + 0.5 * step;
                for sx in 0..m {
                    let x = voxel[0] as f64 + (sub[0] * m + sx) as f64 * step + 0.5 * step;
                    inside += (sdf(x, y, z) <= 0.0) as usize;
                }
            }
        }
        *frac = inside as f64 / (m * m * m) as f64;
    }
    fill_of(fractions)
}

/// What a voxel with these sub-cell fractions is: full when every sub-cell rounds to full,
/// empty under [`MIN_VOXEL_FILL`], else partial.
pub fn fill_of(fractions: [f64; SUBCELLS]) -> VoxelFill {
    let fill = SubFill::from_fractions(fractions);
    if fill.is_full() {
        VoxelFill::Full
    } else if fill.mean() < MIN_VOXEL_FILL {
        VoxelFill::Empty
    } else {
        VoxelFill::Partial(fill)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_plane_through_a_voxel_fills_it_by_volume() {
        // x <= 0.3 within voxel 0: fill 0.3 (4^3 samples per sub-cell resolve 1/16 of a voxel
        // along x; 0.3 lies between the sample planes 0.28125 and 0.34375, so 5/16 = 0.3125).
        let sdf = |x: f64, _: f64, _: f64| x - 0.3;
        let VoxelFill::Partial(f) = voxel_fill(&sdf, [0, 0, 0]) else {
            panic!("a cut voxel is partial")
        };
        assert!((f.mean() - 0.3125).abs() < 1.0 / 255.0, "{}", f.mean());
        // The material sits on the low-x side.
        assert!(f.centroid_offset()[0] < -0.1);
        assert_eq!(voxel_fill(&sdf, [3, 0, 0]), VoxelFill::Empty);
        assert_eq!(voxel_fill(&|x, _, _| x - 9.0, [3, 0, 0]), VoxelFill::Full);
    }
}
