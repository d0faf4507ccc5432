//! Partially filled voxels: element matrices integrated over the filled part of the cube (the
//! finite cell method of Parvizian, Düster and Rank 2007, in its voxel form).
//!
//! Where it sits: [`super::FemModel::assemble`] uses the unit element ([`super::UnitElement`])
//! for every full voxel, and this for every partial one ([`crate::shape::SubFill`]). The unit
//! cube is split into `s^3` sub-cells; the uncondensed stiffness and the mass of each sub-cell
//! are integrated once (`element::integrate_box`), and a partial element's matrices are
//! the fill-weighted sums `K_e = sum_c max(f_c, alpha) K_c`, `M_e = sum_c max(f_c, alpha) M_c`
//! (exact for a fill that is constant on each sub-cell), followed by the static condensation
//! of the incompatible modes for hex8i. `alpha` ([`EMPTY_SUBCELL_FLOOR`]) keeps the bubble block
//! positive definite when sub-cells are empty, as the finite cell method's `alpha` does.

use super::element::{condense, elasticity, integrate_box, BoxIntegrals, ElementKind};
use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, Par};

/// Partial voxels evaluated together: their fill-weighted sums are one matrix product per
/// batch (`[entries x sub-cells] x [sub-cells x batch]`), which runs at matrix-product speed
/// instead of one axpy per sub-cell per element.
pub const CUT_BATCH: usize = 64;

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
    /// Uncondensed stiffness of each sub-cell (x fastest) as the columns of one matrix,
    /// `(3 (n + bubbles))^2` rows, one column per sub-cell.
    stiffness: Mat<f64>,
    /// Mass of each sub-cell, `(3 n)^2` rows, one column per sub-cell.
    mass: Mat<f64>,
    /// Rows of `stiffness` that are the uncondensed stiffness; for hex8i the rest are, per
    /// sub-cell, `int B dV` of the 9 bubble DOFs and the 24 nodal DOFs (Voigt, 6 each) and the
    /// sub-cell's volume: the Taylor correction's sums.
    kfull_len: usize,
    /// Elasticity matrix (E = 1).
    elasticity: [[f64; 6]; 6],
}

/// Reusable buffers for [`CutElement::matrices_batch`].
#[derive(Clone, Debug)]
pub struct CutScratch {
    /// Sub-cell weights of the batch, one column per element.
    weights: Mat<f64>,
    /// Uncondensed stiffness of the batch, one column per element.
    kfull: Mat<f64>,
    /// Mass of the batch, one column per element.
    mass: Mat<f64>,
    /// One element's uncondensed stiffness (Taylor-corrected in place).
    column: Vec<f64>,
    /// One element's condensed stiffness.
    k: Vec<f64>,
    condense: Vec<f64>,
}

impl CutElement {
    /// Integrates the `per_axis^3` sub-cells of `kind` for Poisson's ratio `nu`.
    pub fn new(kind: ElementKind, nu: f64, per_axis: usize) -> Self {
        let per_axis = per_axis.max(1);
        let step = 2.0 / per_axis as f64;
        let mut stiffness: Vec<Vec<f64>> = Vec::new();
        let mut mass: Vec<Vec<f64>> = Vec::new();
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
        // hex8i: the integrated strains and the volume ride along as extra rows of the
        // stiffness table, so one product also gives the Taylor correction's sums.
        let subcell_volume = (1.0 / per_axis as f64).powi(3);
        for (c, k) in stiffness.iter_mut().enumerate() {
            if kind == ElementKind::Hex8Incompatible {
                k.extend(bubble_strain[c].iter().flatten());
                k.extend(nodal_strain[c].iter().flatten());
                k.push(subcell_volume);
            }
        }
        let table = |cols: &[Vec<f64>]| Mat::from_fn(cols[0].len(), cols.len(), |i, j| cols[j][i]);
        let kfull_len = {
            let nall = if kind == ElementKind::Hex8Incompatible {
                kind.nodes() + 3
            } else {
                kind.nodes()
            };
            9 * nall * nall
        };
        Self {
            kind,
            per_axis,
            stiffness: table(&stiffness),
            mass: table(&mass),
            kfull_len,
            elasticity: elasticity(nu),
        }
    }

    /// Sub-cells per axis.
    pub fn per_axis(&self) -> usize {
        self.per_axis
    }

    /// Buffers for [`CutElement::matrices_batch`].
    pub fn scratch(&self) -> CutScratch {
        let ndof = 3 * self.kind.nodes();
        CutScratch {
            weights: Mat::zeros(self.stiffness.ncols(), CUT_BATCH),
            kfull: Mat::zeros(self.stiffness.nrows(), CUT_BATCH),
            mass: Mat::zeros(self.mass.nrows(), CUT_BATCH),
            column: vec![0.0; self.kfull_len],
            k: vec![0.0; ndof * ndof],
            condense: Vec::new(),
        }
    }

    /// The element matrices of up to [`CUT_BATCH`] partial voxels whose sub-cells (x fastest)
    /// are filled to the fractions `fills[j]` (each in `[0, 1]`): calls `each(j, k, m)` with
    /// `3 n` square row-major matrices, like [`super::UnitElement`]'s.
    pub fn matrices_batch(
        &self,
        fills: &[&[f64]],
        scratch: &mut CutScratch,
        mut each: impl FnMut(usize, &[f64], &[f64]),
    ) {
        let count = fills.len();
        assert!(count <= CUT_BATCH, "at most CUT_BATCH elements per batch");
        let subcells = self.stiffness.ncols();
        for (j, fill) in fills.iter().enumerate() {
            assert_eq!(fill.len(), subcells, "one fraction per sub-cell");
            for (c, f) in fill.iter().enumerate() {
                scratch.weights[(c, j)] = f.clamp(0.0, 1.0).max(EMPTY_SUBCELL_FLOOR);
            }
        }
        let weights = scratch.weights.as_ref().subcols(0, count);
        for (table, out) in [
            (&self.stiffness, &mut scratch.kfull),
            (&self.mass, &mut scratch.mass),
        ] {
            matmul(
                out.as_mut().subcols_mut(0, count),
                Accum::Replace,
                table.as_ref(),
                weights,
                1.0,
                Par::Seq,
            );
        }
        for j in 0..count {
            let (kfull, sums) = scratch.kfull.col_as_slice(j).split_at(self.kfull_len);
            scratch.column.copy_from_slice(kfull);
            if self.kind == ElementKind::Hex8Incompatible {
                taylor_correction(&self.elasticity, sums, &mut scratch.column);
            }
            condense(
                self.kind,
                &scratch.column,
                &mut scratch.k,
                &mut scratch.condense,
            );
            each(j, &scratch.k, scratch.mass.col_as_slice(j));
        }
    }

    /// The element matrices of one partial voxel (see [`CutElement::matrices_batch`]).
    pub fn matrices(&self, fill: &[f64], k: &mut [f64], m: &mut [f64], scratch: &mut CutScratch) {
        self.matrices_batch(&[fill], scratch, |_, ke, me| {
            k.copy_from_slice(ke);
            m.copy_from_slice(me);
        });
    }
}

/// Makes the incompatible modes' strains average to zero over the filled part of the cell
/// (Taylor, Beresford and Wilson 1976): `B_b -> B_b - G`, `G = int_f B_b dV / V_f`. On a full
/// cube the bubbles' strains already average to zero (`G = 0`); on a cut cell they do not, and
/// the uncorrected element fails the constant-strain patch test and locks.
///
/// `sums` holds the fill-weighted `int_f B_b dV` (9 x 6), `S_u = int_f B_u dV` (24 x 6) and
/// `V_f`; with `int_f B_b dV = V_f G`:
/// `K_ub -= S_u^T D G`, `K_bu -= G^T D S_u`, `K_bb -= V_f G^T D G`.
fn taylor_correction(d: &[[f64; 6]; 6], sums: &[f64], kfull: &mut [f64]) {
    const NB: usize = 9;
    const NU: usize = 24;
    let full = NU + NB;
    let volume = sums[6 * (NB + NU)];
    let g: [[f64; 6]; NB] =
        std::array::from_fn(|j| std::array::from_fn(|r| sums[6 * j + r] / volume));
    let su = |i: usize| &sums[6 * (NB + i)..6 * (NB + i + 1)];
    // D G_j once per bubble DOF; then every correction is a 6-term dot product.
    let dg: [[f64; 6]; NB] =
        g.map(|gj| std::array::from_fn(|r| (0..6).map(|s| d[r][s] * gj[s]).sum()));
    let dot = |a: &[f64], b: &[f64; 6]| -> f64 { (0..6).map(|r| a[r] * b[r]).sum() };
    for (j, dgj) in dg.iter().enumerate() {
        for i in 0..NU {
            let corr = dot(su(i), dgj);
            kfull[i * full + NU + j] -= corr;
            kfull[(NU + j) * full + i] -= corr;
        }
        for (i, gi) in g.iter().enumerate() {
            kfull[(NU + i) * full + NU + j] -= volume * dot(gi, dgj);
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
                cut.matrices(&fill, &mut k, &mut m, &mut cut.scratch());
                let dk: Vec<f64> = k.iter().zip(&unit.stiffness).map(|(a, b)| a - b).collect();
                let dm: Vec<f64> = m.iter().zip(&unit.mass).map(|(a, b)| a - b).collect();
                assert!(max_abs(&dk) < 1e-13 * max_abs(&unit.stiffness), "{kind:?}");
                assert!(max_abs(&dm) < 1e-13 * max_abs(&unit.mass), "{kind:?}");
            }
        }
    }

    #[test]
    fn cut_elements_pass_the_patch_test() {
        // A uniform strain in any partly filled cube stores exactly V_f/2 eps^T D eps (V_f the
        // weighted volume): the constant-strain patch test. Without the Taylor correction the
        // hex8i bubbles would absorb part of it on a cut cell (energy too low) and, worse,
        // couple to it (the element would not converge).
        let nu = 0.3;
        let d = elasticity(nu);
        let eps = [1e-3, -2e-3, 0.5e-3, 2e-3, -1e-3, 1.5e-3];
        let want_density: f64 = (0..6)
            .map(|i| (0..6).map(|j| eps[i] * d[i][j] * eps[j]).sum::<f64>())
            .sum();
        for kind in ElementKind::ALL {
            let unit = UnitElement::new(kind, nu);
            let n = unit.dofs();
            let cut = CutElement::new(kind, nu, subcells_per_axis(kind));
            let cells = subcells_per_axis(kind).pow(3);
            // A corner-heavy fill: sub-cell c filled to (c * 37 % 11) / 10, some empty.
            let fill: Vec<f64> = (0..cells).map(|c| ((c * 37) % 11) as f64 / 10.0).collect();
            let (mut k, mut m) = (vec![0.0; n * n], vec![0.0; n * n]);
            cut.matrices(&fill, &mut k, &mut m, &mut cut.scratch());
            // u = (eps_xx x + eps_xy y, eps_yy y + eps_yz z, eps_zz z + eps_zx x): engineering
            // shears are the sums of the cross derivatives.
            let u: Vec<f64> = (0..unit.kind.nodes())
                .flat_map(|a| {
                    let p = unit.node_position(a);
                    [
                        eps[0] * p[0] + eps[3] * p[1],
                        eps[1] * p[1] + eps[4] * p[2],
                        eps[2] * p[2] + eps[5] * p[0],
                    ]
                })
                .collect();
            let energy: f64 = (0..n)
                .map(|i| (0..n).map(|j| u[i] * k[i * n + j] * u[j]).sum::<f64>())
                .sum();
            let volume: f64 = fill
                .iter()
                .map(|f| f.max(EMPTY_SUBCELL_FLOOR) / cells as f64)
                .sum();
            let want = volume * want_density;
            assert!(
                (energy - want).abs() < 1e-10 * want,
                "{kind:?}: {energy} vs {want}"
            );
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
            cut.matrices(&fill, &mut k, &mut m, &mut cut.scratch());
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
