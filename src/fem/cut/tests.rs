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
        let mut unit = UnitElement::new(kind, 0.3);
        let n = unit.dofs();
        // In voxel units (hex27x2's element is two voxels wide: K x 2, M x 8).
        let (k_scale, m_scale) = kind.voxel_scales();
        unit.stiffness.iter_mut().for_each(|v| *v *= k_scale);
        unit.mass.iter_mut().for_each(|v| *v *= m_scale);
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
fn sum_factorisation_matches_the_sub_cell_table() {
    // hex27's cut elements come from the fill's Legendre moments contracted axis by axis
    // (`cut::tensor`); the sub-cell table (the fill-weighted sum of matrices integrated
    // on each sub-box in 3D) is an independent evaluation of the same sums. They agree to
    // rounding: 1e-13 of the largest entry (sums of up to 512 terms of mixed sign).
    let nu = 0.3;
    let kind = ElementKind::Hex27;
    let n = 3 * kind.nodes();
    // Every sub-cell different, and (per_axis 4, 8) rows along x filled alike, which the
    // sum factorisation folds.
    let varied: fn(usize, usize) -> f64 = |c, _| ((c * 37) % 11) as f64 / 10.0;
    let rows: fn(usize, usize) -> f64 = |c, s| ((c / s * 37) % 11) as f64 / 10.0;
    for (per_axis, fill_of) in [(1, varied), (2, varied), (4, varied), (4, rows), (8, rows)] {
        let cells = per_axis * per_axis * per_axis;
        let fill: Vec<f64> = (0..cells).map(|c| fill_of(c, per_axis)).collect();
        let cut = CutElement::new(kind, nu, per_axis);
        let (mut k, mut m) = (vec![0.0; n * n], vec![0.0; n * n]);
        cut.matrices(&fill, &mut k, &mut m, &mut cut.scratch());
        let table = CutElement {
            kind,
            per_axis,
            integrals: Integrals::Table(Box::new(SubcellTable::new(kind, nu, per_axis))),
        };
        let (mut kt, mut mt) = (vec![0.0; n * n], vec![0.0; n * n]);
        table.matrices(&fill, &mut kt, &mut mt, &mut table.scratch());
        let dk: Vec<f64> = k.iter().zip(&kt).map(|(a, b)| a - b).collect();
        let dm: Vec<f64> = m.iter().zip(&mt).map(|(a, b)| a - b).collect();
        assert!(
            max_abs(&dk) < 1e-13 * max_abs(&kt),
            "{per_axis}: {}",
            max_abs(&dk)
        );
        assert!(
            max_abs(&dm) < 1e-13 * max_abs(&mt),
            "{per_axis}: {}",
            max_abs(&dm)
        );
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
        // An element `h` voxels wide ([`ElementKind::voxel_scales`]) holds `h^3` times the
        // volume at `1 / h` the strain (`u` is given on the unit cube's nodes).
        let want = kind.voxel_scales().0 * volume * want_density;
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
        // In voxel units: hex27x2's element holds 8 voxels.
        let scale = kind.voxel_scales().1;
        let mass = scale * (0.5 + 0.5 * floor);
        assert!(
            (form(&ones, &ones) - mass).abs() < 1e-14 * scale,
            "{kind:?}"
        );
        let moment = scale * (0.5 * 0.25 + 0.5 * floor * 0.75);
        assert!(
            (form(&ones, &zs) - moment).abs() < 1e-14 * scale,
            "{kind:?}"
        );
        // Rigid motions still cost nothing.
        let ku: Vec<f64> = (0..n)
            .map(|i| (0..n).map(|j| k[i * n + j] * ones[j]).sum())
            .collect();
        assert!(max_abs(&ku) < 1e-13 * max_abs(&k), "{kind:?}");
    }
}
