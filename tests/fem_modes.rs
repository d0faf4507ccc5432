//! FEM modal analysis against independent truths: beam, rod and Saint-Venant theory for a
//! free-free bar; rigid-body mode counts for touching and separate parts; the scaling laws
//! against a direct physical re-solve; convergence under refinement.

use modalforge::basis::{Hit, ModeBasis};
use modalforge::eigen::{self, EigenOptions, ModeCount, SolverKind};
use modalforge::fem::{ElementKind, FemModel};
use modalforge::material::Material;
use modalforge::shape::primitives::Primitive;
use modalforge::shape::VoxelGrid;
use std::f64::consts::PI;

mod common;
use common::timoshenko;

const NU: f64 = 0.29;

fn options(k: usize) -> EigenOptions {
    EigenOptions {
        count: ModeCount::First(k),
        tolerance: 1e-10,
        ..Default::default()
    }
}

/// Classifies a bar mode (axis x) as longitudinal, torsional or bending by where its motion is.
#[derive(Debug, PartialEq)]
enum BarMode {
    Longitudinal,
    Torsion,
    Bending,
}

fn classify(model: &FemModel, u: &[f64], centre: [f64; 2]) -> BarMode {
    let (mut axial, mut twist, mut total) = (0.0, 0.0, 0.0);
    for node in 0..model.nodes() {
        let p = model.node_position(node);
        let (ux, uy, uz) = (u[3 * node], u[3 * node + 1], u[3 * node + 2]);
        let (ry, rz) = (p[1] - centre[0], p[2] - centre[1]);
        let r = (ry * ry + rz * rz).sqrt();
        if r > 0.0 {
            twist += ((-rz * uy + ry * uz) / r).powi(2);
        }
        axial += ux * ux;
        total += ux * ux + uy * uy + uz * uz;
    }
    if axial > 0.8 * total {
        BarMode::Longitudinal
    } else if twist > 0.8 * total {
        BarMode::Torsion
    } else {
        BarMode::Bending
    }
}

/// Relative errors of the bar 64x4x4 (reference units) against theory: the first three distinct
/// bending frequencies, the first longitudinal and the first torsional.
fn bar_errors(kind: ElementKind) -> ([f64; 3], f64, f64) {
    let grid = Primitive::Bar {
        length: 64.0,
        width: 4.0,
        height: 4.0,
    }
    .rasterize(1.0, 1.0)
    .unwrap();
    let model = FemModel::assemble(&grid, kind, NU).unwrap();
    let sol = eigen::solve(&model, SolverKind::Lanczos, &options(12)).unwrap();
    assert_eq!(sol.rigid_modes, 6);
    let (mut bending, mut long, mut torsion) = (Vec::new(), None, None);
    for (i, &lambda) in sol.eigenvalues.iter().enumerate() {
        let w = lambda.sqrt();
        match classify(&model, sol.vectors.col_as_slice(i), [2.0, 2.0]) {
            BarMode::Bending => {
                if bending
                    .last()
                    .is_none_or(|&b: &f64| (w - b).abs() > 1e-6 * w)
                {
                    bending.push(w);
                }
            }
            BarMode::Longitudinal => long = long.or(Some(w)),
            BarMode::Torsion => torsion = torsion.or(Some(w)),
        }
    }
    let timo = timoshenko(1.0, 1.0, NU, 64.0, 4.0, 4.0, 3);
    let rod = PI / 64.0;
    // Saint-Venant: J = beta a^4 with beta = 0.140577 for a square (Timoshenko & Goodier).
    let g = 1.0 / (2.0 * (1.0 + NU));
    let saint_venant = PI / 64.0 * (g * 0.140577 * 256.0 / (256.0 / 6.0)).sqrt();
    let rel = |a: f64, b: f64| (a - b).abs() / b;
    (
        [
            rel(bending[0], timo[0]),
            rel(bending[1], timo[1]),
            rel(bending[2], timo[2]),
        ],
        rel(long.expect("a longitudinal mode"), rod),
        rel(torsion.expect("a torsional mode"), saint_venant),
    )
}

#[test]
fn steel_bar_matches_beam_rod_and_torsion_theory_default_element() {
    // Tolerances from the issue: 1% bending (Timoshenko), 0.5% rod, 3% Saint-Venant (which
    // ignores warping restraint and the voxel corners, so it is the loosest).
    let (bending, long, torsion) = bar_errors(ElementKind::Hex8Incompatible);
    println!("hex8i: bending {bending:?}, longitudinal {long:.2e}, torsion {torsion:.2e}");
    for e in bending {
        assert!(e < 0.01, "bending {e}");
    }
    assert!(long < 0.005, "longitudinal {long}");
    assert!(torsion < 0.03, "torsion {torsion}");
}

#[test]
fn steel_bar_quadratic_elements_within_0_2_percent() {
    let (bending, long, torsion) = bar_errors(ElementKind::Hex27);
    println!("hex27: bending {bending:?}, longitudinal {long:.2e}, torsion {torsion:.2e}");
    for e in bending.into_iter().chain([long, torsion]) {
        assert!(e < 0.002, "{e}");
    }
}

#[test]
fn refining_the_grid_lowers_the_error() {
    // Plain hex8 on the same 16:1 bar at 2, 4 and 6 voxels across: first bending mode error
    // against Timoshenko must fall monotonically (shear locking fades as elements shrink).
    let timo = timoshenko(1.0, 1.0, NU, 16.0, 1.0, 1.0, 1)[0];
    let mut errors = Vec::new();
    for n in [2usize, 4, 6] {
        let grid = VoxelGrid::from_fn([16 * n, n, n], 1.0, |_, _, _| true).unwrap();
        let model = FemModel::assemble(&grid, ElementKind::Hex8, NU).unwrap();
        let sol = eigen::solve(&model, SolverKind::Lanczos, &options(1)).unwrap();
        // Reference units with voxel edge 1: the bar is 16 n long, so omega scales by n.
        errors.push((sol.eigenvalues[0].sqrt() * n as f64 - timo) / timo);
    }
    println!("hex8 first bending error at 2, 4, 6 voxels across: {errors:?}");
    assert!(
        errors[0] > errors[1] && errors[1] > errors[2] && errors[2] > 0.0,
        "{errors:?}"
    );
}

#[test]
fn scaling_laws_equal_a_direct_physical_solve() {
    // An asymmetric blob (no repeated eigenvalues), solved once in reference units and rescaled
    // to brass at 7 mm voxels, against a solve of the physical matrices E h K, rho h^3 M.
    let grid = VoxelGrid::from_fn([7, 5, 4], 1.0, |x, y, z| x + 0.7 * y + 1.3 * z < 11.0).unwrap();
    let brass = Material::preset("brass").unwrap();
    let h = 0.007;
    let basis = ModeBasis::solve(
        &grid,
        ElementKind::Hex8Incompatible,
        brass.poisson_ratio,
        SolverKind::Lanczos,
        &options(10),
    )
    .unwrap();
    let scaled = basis.eigenvalues(&brass, h);
    let physical = basis
        .model
        .scaled(brass.youngs_modulus_pa * h, brass.density_kg_m3 * h.powi(3));
    let direct = eigen::solve(&physical, SolverKind::Lanczos, &options(10)).unwrap();
    for (a, b) in scaled.iter().zip(&direct.eigenvalues) {
        assert!((a - b).abs() < 1e-9 * b, "{a} vs {b}");
    }
    // Gains: the rescaled modes at a hit equal the direct modes (up to sign).
    let hit = Hit {
        point_m: [0.0, 2.5 * h, 2.0 * h],
        direction: Some([1.0, 0.2, 0.0]),
    };
    let forces = basis.modal_forces(&brass, h, &hit).unwrap();
    let mut direct_basis = basis.clone();
    direct_basis.solution = direct;
    // The direct vectors are already physical: undo the rescaling the basis would apply.
    let unit = Material::new("unit", 1.0, 1.0, brass.poisson_ratio, brass.damping.clone()).unwrap();
    let direct_forces = direct_basis
        .modal_forces(
            &unit,
            1.0,
            &Hit {
                point_m: [0.0, 2.5, 2.0],
                ..hit
            },
        )
        .unwrap();
    // The two solves' eigenvectors differ by about residual / relative gap (Davis-Kahan):
    // residuals up to 2e-11 of ||K||, gaps down to 1.4 %, so up to ~1e-9 of a mode's own
    // scale. That error is absolute on the field, so the tolerance is 1e-9 of the largest
    // value, not of each value (mode 9's hit sits near a nodal line: 0.026 of the largest,
    // and the two agree to 3e-11).
    let scale = forces.iter().fold(0.0f64, |m, f| m.max(f.abs()));
    for (a, b) in forces.iter().zip(&direct_forces) {
        assert!((a.abs() - b.abs()).abs() < 1e-9 * scale, "{a} vs {b}");
    }
}

#[test]
fn degenerate_inputs_give_errors_or_correct_modes() {
    // One voxel: 24 DOFs, 6 rigid, 18 elastic; 20 modes is a clear error, 5 works.
    let one = VoxelGrid::from_fn([1, 1, 1], 0.01, |_, _, _| true).unwrap();
    let model = FemModel::assemble(&one, ElementKind::Hex8Incompatible, NU).unwrap();
    let e = eigen::solve(&model, SolverKind::Lanczos, &options(20)).unwrap_err();
    assert!(e.to_string().contains("degrees of freedom"), "{e}");
    let sol = eigen::solve(
        &model,
        SolverKind::Lanczos,
        &EigenOptions {
            block_size: 2,
            ..options(5)
        },
    )
    .unwrap();
    assert_eq!(sol.rigid_modes, 6);
    // A 1-voxel-thin sheet, a 64:1 needle and nu = 0.49: finite, positive, converged.
    for (grid, nu) in [
        (
            VoxelGrid::from_fn([12, 12, 1], 0.01, |_, _, _| true).unwrap(),
            NU,
        ),
        (
            VoxelGrid::from_fn([64, 1, 1], 0.01, |_, _, _| true).unwrap(),
            NU,
        ),
        (
            VoxelGrid::from_fn([6, 6, 6], 0.01, |_, _, _| true).unwrap(),
            0.49,
        ),
    ] {
        let model = FemModel::assemble(&grid, ElementKind::Hex8Incompatible, nu).unwrap();
        let sol = eigen::solve(&model, SolverKind::Lanczos, &options(6)).unwrap();
        assert_eq!(sol.rigid_modes, 6, "{:?}", grid.dims());
        assert!(sol.eigenvalues.iter().all(|l| l.is_finite() && *l > 0.0));
        assert!(sol.residuals.iter().all(|r| *r < 1e-10));
    }
    // Empty grid: a clear error before any solve.
    let empty = VoxelGrid::new([4, 4, 4], 0.01).unwrap();
    let e = FemModel::assemble(&empty, ElementKind::Hex8, NU).unwrap_err();
    assert!(e.to_string().contains("empty"), "{e}");
}
