//! Partially filled voxels: element matrices integrated over the filled part of the cube (the
//! finite cell method of Parvizian, Düster and Rank 2007, in its voxel form).
//!
//! Where it sits: [`super::FemModel::assemble`] uses the unit element ([`super::UnitElement`])
//! for every full voxel, and this for every partial one ([`crate::shape::SubFill`]). The unit
//! cube is split into `s^3` sub-cells; the uncondensed stiffness and the mass of each sub-cell
//! are integrated once ([`super::element::integrate_box`]), and a partial element's matrices are
//! the fill-weighted sums `K_e = sum_c max(f_c, alpha) K_c`, `M_e = sum_c max(f_c, alpha) M_c`
//! — exact for a fill that is constant on each sub-cell — followed by the static condensation of
//! the incompatible modes for hex8i. `alpha` ([`EMPTY_SUBCELL_FLOOR`]) keeps the bubble block
//! positive definite when sub-cells are empty, as the finite cell method's `alpha` does.

use super::element::{condense, elasticity, integrate_box, BoxIntegrals, ElementKind};

/// Stiffness and mass kept in an empty sub-cell of a partial voxel, relative to a full one. It
/// changes a bowl's frequencies by far less than the solver tolerance but keeps every element
/// matrix positive definite on its non-rigid motions.
pub const EMPTY_SUBCELL_FLOOR: f64 = 1e-3;

/// Sub-cells per axis the FEM integrates a partial voxel of `kind` over, chosen by measurement
/// (the lowest mode pair of `bowl:d=16,wall=2` and `bowl:d=32,wall=2`, glass; ARCHITECTURE.md,
/// "Partial voxels"): hex27's split falls from 1.2 % (2) to 0.14 % (4) to 0.00 % (8), and its
/// frequency error against the smooth reference from 2.4 % to 0.9 % to 0.2 %; 4 is the stored
/// resolution. Hex8 with incompatible modes is best at 2 (split 0.74 % / 0.37 %; 1.6 % / 1.0 %
/// at 4, 1.9 % / 1.2 % at 8: its bubbles follow the lattice, so the finer the cut geometry,
/// the more its lattice anisotropy shows), and so is plain hex8.
pub fn subcells_per_axis(kind: ElementKind) -> usize {
    match kind {
        ElementKind::Hex27 => 4,
        ElementKind::Hex8 | ElementKind::Hex8Incompatible => 2,
    }
}

/// The sub-cell matrices of one element kind and Poisson's ratio.
#[derive(Clone, Debug)]
pub struct CutElement {
    kind: ElementKind,
    per_axis: usize,
    /// Uncondensed stiffness of each sub-cell (x fastest), `(3 (n + bubbles))^2` entries each.
    stiffness: Vec<Vec<f64>>,
    /// Mass of each sub-cell, `(3 n)^2` entries each.
    mass: Vec<Vec<f64>>,
    /// `int B dV` of each bubble DOF over each sub-cell (hex8i only): the Taylor correction.
    bubble_strain: Vec<Vec<[f64; 6]>>,
    /// `int B dV` of each nodal DOF over each sub-cell (hex8i only).
    nodal_strain: Vec<Vec<[f64; 6]>>,
    /// Volume of one sub-cell (unit cube = 1).
    subcell_volume: f64,
    /// Elasticity matrix (E = 1).
    elasticity: [[f64; 6]; 6],
}

/// Reusable buffers for [`CutElement::matrices`].
#[derive(Clone, Debug, Default)]
pub struct CutScratch {
    kfull: Vec<f64>,
    condense: Vec<f64>,
}

impl CutElement {
    /// Integrates the `per_axis^3` sub-cells of `kind` for Poisson's ratio `nu`.
    pub fn new(kind: ElementKind, nu: f64, per_axis: usize) -> Self {
        let per_axis = per_axis.max(1);
        let step = 2.0 / per_axis as f64;
        let mut stiffness = Vec::new();
        let mut mass = Vec::new();
        let mut bubble_strain = Vec::new();
        let mut nodal_strain = Vec::new();
        let ndof = 3 * kind.nodes();
        for cz in 0..per_axis {
            for cy in 0..per_axis {
                for cx in 0..per_axis {
                    let c = [cx, cy, cz];
                    let lo = c.map(|i| -1.0 + step * i as f64);
                    let hi = c.map(|i| -1.0 + step * (i + 1) as f64);
                    let BoxIntegrals {
                        kfull,
                        mass: m,
                        mut strain,
                        ..
                    } = integrate_box(kind, nu, lo, hi);
                    stiffness.push(kfull);
                    mass.push(m);
                    if kind == ElementKind::Hex8Incompatible {
                        bubble_strain.push(strain.split_off(ndof));
                        nodal_strain.push(strain);
                    }
                }
            }
        }
        Self {
            kind,
            per_axis,
            stiffness,
            mass,
            bubble_strain,
            nodal_strain,
            subcell_volume: (1.0 / per_axis as f64).powi(3),
            elasticity: elasticity(nu),
        }
    }

    /// Sub-cells per axis.
    pub fn per_axis(&self) -> usize {
        self.per_axis
    }

    /// The element matrices (`3 n` square, row-major, like [`super::UnitElement`]) of a voxel
    /// whose sub-cells (x fastest) are filled to the fractions `fill` (each in `[0, 1]`).
    pub fn matrices(&self, fill: &[f64], k: &mut [f64], m: &mut [f64], scratch: &mut CutScratch) {
        assert_eq!(
            fill.len(),
            self.stiffness.len(),
            "one fraction per sub-cell"
        );
        scratch.kfull.clear();
        scratch.kfull.resize(self.stiffness[0].len(), 0.0);
        m.fill(0.0);
        for ((f, kc), mc) in fill.iter().zip(&self.stiffness).zip(&self.mass) {
            let w = f.clamp(0.0, 1.0).max(EMPTY_SUBCELL_FLOOR);
            scratch
                .kfull
                .iter_mut()
                .zip(kc)
                .for_each(|(a, b)| *a += w * b);
            m.iter_mut().zip(mc).for_each(|(a, b)| *a += w * b);
        }
        if self.kind == ElementKind::Hex8Incompatible {
            self.taylor_correction(fill, &mut scratch.kfull);
        }
        condense(self.kind, &scratch.kfull, k, &mut scratch.condense);
    }

    /// Makes the incompatible modes' strains average to zero over the filled part of the cell
    /// (Taylor, Beresford and Wilson 1976): `B_b -> B_b - G`, `G = int_f B_b dV / V_f`. On a
    /// full cube the bubbles' strains already average to zero (`G = 0`); on a cut cell they do
    /// not, and the uncorrected element fails the constant-strain patch test and locks.
    ///
    /// With `S_u = int_f B_u dV` and `int_f B_b dV = V_f G`:
    /// `K_ub -= S_u^T D G`, `K_bu -= G^T D S_u`, `K_bb -= V_f G^T D G`.
    fn taylor_correction(&self, fill: &[f64], kfull: &mut [f64]) {
        let nb = self.bubble_strain[0].len();
        let nu_ = self.nodal_strain[0].len();
        let full = nu_ + nb;
        let mut volume = 0.0;
        let mut g = [[0.0; 6]; 9];
        let mut su = vec![[0.0; 6]; nu_];
        for (c, f) in fill.iter().enumerate() {
            let w = f.clamp(0.0, 1.0).max(EMPTY_SUBCELL_FLOOR);
            volume += w * self.subcell_volume;
            for (gi, b) in g.iter_mut().zip(&self.bubble_strain[c]) {
                gi.iter_mut().zip(b).for_each(|(x, y)| *x += w * y);
            }
            for (si, b) in su.iter_mut().zip(&self.nodal_strain[c]) {
                si.iter_mut().zip(b).for_each(|(x, y)| *x += w * y);
            }
        }
        g.iter_mut().flatten().for_each(|x| *x /= volume);
        let d = &self.elasticity;
        let dot_d = |a: &[f64; 6], b: &[f64; 6]| -> f64 {
            (0..6)
                .map(|r| a[r] * (0..6).map(|s| d[r][s] * b[s]).sum::<f64>())
                .sum()
        };
        for (j, gj) in g.iter().enumerate() {
            for (i, si) in su.iter().enumerate() {
                let corr = dot_d(si, gj);
                kfull[i * full + nu_ + j] -= corr;
                kfull[(nu_ + j) * full + i] -= corr;
            }
            for (i, gi) in g.iter().enumerate() {
                kfull[(nu_ + i) * full + nu_ + j] -= volume * dot_d(gi, gj);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::UnitElement;

    fn max_abs(v: &[f64]) -> f64 {
        v.iter().fold(0.0f64, |m, x| m.max(x.abs()))
    }

    #[test]
    fn full_sub_cells_sum_to_the_unit_element() {
        // Sum of per_axis^3 exact sub-integrals = the whole integral, up to rounding in the
        // sum of a few dozen terms per entry: 1e-13 of the largest entry.
        for kind in ElementKind::ALL {
            let unit = UnitElement::new(kind, 0.3);
            let n = unit.dofs();
            for per_axis in [1, 2, 3, 4] {
                let cut = CutElement::new(kind, 0.3, per_axis);
                let fill = vec![1.0; per_axis.pow(3)];
                let (mut k, mut m) = (vec![0.0; n * n], vec![0.0; n * n]);
                cut.matrices(&fill, &mut k, &mut m, &mut CutScratch::default());
                let dk: Vec<f64> = k.iter().zip(&unit.stiffness).map(|(a, b)| a - b).collect();
                let dm: Vec<f64> = m.iter().zip(&unit.mass).map(|(a, b)| a - b).collect();
                assert!(max_abs(&dk) < 1e-13 * max_abs(&unit.stiffness), "{kind:?}");
                assert!(max_abs(&dm) < 1e-13 * max_abs(&unit.mass), "{kind:?}");
            }
        }
    }

    #[test]
    fn half_filled_cube_has_half_the_mass_at_the_right_place() {
        // The lower half (z < 1/2) filled: mass = 1/2 and its centroid at z = 1/4, exactly
        // (the consistent mass integrates the linear field z exactly).
        for kind in ElementKind::ALL {
            let unit = UnitElement::new(kind, 0.3);
            let n = unit.dofs();
            let cut = CutElement::new(kind, 0.3, 2);
            let fill: Vec<f64> = (0..8).map(|c| if c < 4 { 1.0 } else { 0.0 }).collect();
            let (mut k, mut m) = (vec![0.0; n * n], vec![0.0; n * n]);
            cut.matrices(&fill, &mut k, &mut m, &mut CutScratch::default());
            let ones: Vec<f64> = (0..n).map(|i| (i % 3 == 0) as u8 as f64).collect();
            let zs: Vec<f64> = (0..n)
                .map(|i| {
                    if i % 3 == 0 {
                        unit.node_position(i / 3)[2]
                    } else {
                        0.0
                    }
                })
                .collect();
            let form = |a: &[f64], b: &[f64]| -> f64 {
                (0..n)
                    .map(|i| (0..n).map(|j| a[i] * m[i * n + j] * b[j]).sum::<f64>())
                    .sum()
            };
            let floor = EMPTY_SUBCELL_FLOOR;
            let mass = 0.5 + 0.5 * floor;
            assert!((form(&ones, &ones) - mass).abs() < 1e-14, "{kind:?}");
            let moment = 0.5 * 0.25 + 0.5 * floor * 0.75;
            assert!((form(&ones, &zs) - moment).abs() < 1e-14, "{kind:?}");
            // Rigid motions still cost nothing.
            let ku: Vec<f64> = (0..n)
                .map(|i| (0..n).map(|j| k[i * n + j] * ones[j]).sum())
                .collect();
            assert!(max_abs(&ku) < 1e-13 * max_abs(&k), "{kind:?}");
        }
    }
}
