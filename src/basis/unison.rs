//! Degenerate modes voiced as one: a symmetric object's exactly degenerate pairs and
//! multiplets (a square bar's two bending directions, a sphere's multiplets) have no preferred
//! basis, so the gains of a strike are given in the basis aligned with it.
//!
//! Where it sits: inside [`super::ModeBasis::reference_forces_into`], after each mode's
//! projection `phi_i(p) . f` (Jin et al. 2020, eq. 7) and before any gain is formed, on the
//! audio thread as everywhere else (allocation-free). ARCHITECTURE.md, "Degenerate pairs".

/// Relative eigenvalue difference under which modes sound in unison and are voiced as one
/// ([`strike_align_unisons`]): `2e-6` in `omega^2` is `1e-6` in frequency, two partials that
/// beat once in `10^6` periods (once in 17 minutes at 1 kHz), one partial to any ear. Exactly
/// degenerate modes of a symmetric object come out of the solvers equal to ~1e-13; the
/// nearest physical splits the product models (a partial-voxel bowl's pairs, issue 19) are
/// 1e-4 and wider.
pub const UNISON_REL: f64 = 2e-6;

/// Aligns each unison (a run of modes whose eigenvalues lie within [`UNISON_REL`] of the
/// run's first) with the strike: `forces` holds each mode's `phi_i(p) . f` in whatever
/// orthonormal basis of the unison's eigenspace the solver returned; the strike excites only
/// the projection `P f` of the force on that space, a single mode of amplitude `|P f|`, so the
/// first mode of the run takes `sqrt(sum_i forces_i^2)` (the norm is basis-independent) and
/// the rest `0`. Without this the summed amplitude of the unison, which rings at one frequency
/// and in phase, is `sum_i forces_i`, and depends on the basis (ARCHITECTURE.md, "Degenerate
/// pairs"). `eigenvalues` ascending, as the solvers return them. Never allocates.
pub fn strike_align_unisons(eigenvalues: &[f64], forces: &mut [f64]) {
    let n = forces.len().min(eigenvalues.len());
    let mut start = 0;
    while start < n {
        let limit = eigenvalues[start].abs() * (1.0 + UNISON_REL);
        let end = start
            + 1
            + eigenvalues[start + 1..n]
                .iter()
                .take_while(|&&l| l <= limit)
                .count();
        if end - start > 1 {
            let norm = forces[start..end].iter().map(|f| f * f).sum::<f64>().sqrt();
            forces[start] = norm;
            forces[start + 1..end].iter_mut().for_each(|f| *f = 0.0);
        }
        start = end;
    }
}

#[cfg(test)]
mod tests {
    use super::super::{Hit, ModeBasis};
    use super::*;
    use crate::eigen::{self, EigenOptions, SolverKind};
    use crate::fem::ElementKind;
    use crate::shape::VoxelGrid;

    #[test]
    fn a_unison_sounds_the_same_in_any_basis_of_its_eigenspace() {
        // A square bar's bending pairs are exactly degenerate: any rotation of a pair's two
        // eigenvectors is an equally valid answer of the solver. The struck amplitudes must
        // not change with it: with the unison aligned to the strike they are an identity of
        // the rotation (rounding only: 1e-12 of the largest), and the pair's amplitude is
        // `|P f|`, the norm of the two projections, which rotation keeps.
        let grid = VoxelGrid::from_fn([12, 2, 2], 1.0, |_, _, _| true).unwrap();
        let options = EigenOptions {
            count: eigen::ModeCount::First(8),
            ..Default::default()
        };
        let basis = ModeBasis::solve(
            &grid,
            ElementKind::Hex8Incompatible,
            0.3,
            SolverKind::Lanczos,
            &options,
        )
        .unwrap();
        let l = &basis.solution.eigenvalues;
        let pairs: Vec<usize> = (0..l.len() - 1)
            .filter(|&i| (l[i + 1] - l[i]) <= UNISON_REL * l[i])
            .collect();
        assert!(pairs.len() >= 2, "the bar's bending pairs: {l:?}");
        let hit = Hit {
            point_m: [4.3, 0.7, 2.0],
            direction: Some([0.2, -0.5, -1.0]),
        };
        let n = l.len();
        let (mut raw, mut merged) = (vec![0.0; n], vec![0.0; n]);
        basis
            .projected_forces_into(&hit, 1.0, &mut raw, false)
            .unwrap();
        basis.reference_forces_into(&hit, 1.0, &mut merged).unwrap();
        let scale = raw.iter().fold(0.0f64, |m, f| m.max(f.abs()));
        for &i in &pairs {
            assert!(raw[i].abs() > 1e-3 * scale && raw[i + 1].abs() > 1e-3 * scale);
            let norm = raw[i].hypot(raw[i + 1]);
            assert!((merged[i] - norm).abs() < 1e-12 * scale && merged[i + 1] == 0.0);
        }
        let mut rotated = basis.clone();
        for (k, &i) in pairs.iter().enumerate() {
            let angle = 0.4 + k as f64;
            let (c, s) = (angle.cos(), angle.sin());
            let v = &mut rotated.solution.vectors;
            for r in 0..v.nrows() {
                let (a, b) = (v[(r, i)], v[(r, i + 1)]);
                v[(r, i)] = c * a - s * b;
                v[(r, i + 1)] = s * a + c * b;
            }
        }
        let (mut raw2, mut merged2) = (vec![0.0; n], vec![0.0; n]);
        rotated
            .projected_forces_into(&hit, 1.0, &mut raw2, false)
            .unwrap();
        rotated
            .reference_forces_into(&hit, 1.0, &mut merged2)
            .unwrap();
        let moved = pairs
            .iter()
            .map(|&i| (raw2[i] - raw[i]).abs())
            .fold(0.0, f64::max);
        assert!(
            moved > 1e-2 * scale,
            "the rotation changes the raw projections"
        );
        for (a, b) in merged.iter().zip(&merged2) {
            assert!((a - b).abs() < 1e-12 * scale, "{merged:?} vs {merged2:?}");
        }
    }

    #[test]
    fn modes_apart_are_not_merged() {
        // A split of 1e-5 (a partial-voxel bowl's pair is 1e-3 and wider) stays two partials;
        // 1e-7 (rounding of a degenerate pair, inaudible) is one.
        let mut forces = [3.0, 4.0, 1.0, -2.0, 5.0];
        strike_align_unisons(
            &[1.0, 1.0 + 1e-7, 2.0, 2.0 * (1.0 + 1e-5), 3.0],
            &mut forces,
        );
        assert_eq!(forces, [5.0, 0.0, 1.0, -2.0, 5.0]);
    }
}
