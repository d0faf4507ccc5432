//! Partial voxels (issue 19): curved primitives keep their volume, their symmetry and their
//! pitch, against independent truths:
//! - exact volumes of the smooth solids;
//! - the smooth geometry solved with curved quadratic tetrahedra (`scripts/smooth_reference.py`:
//!   gmsh + scikit-fem, converged by refinement; eigenvalues in reference units, E = rho = 1,
//!   lengths in voxels, nu = 0.2), committed as `tests/data/smooth_references.json`;
//! - for binary grids, today's assembly (the unit element on every voxel) bit for bit.

mod common;

use common::smooth::{frequency_errors, reference, worst, worst_split, NU};
use modalforge::basis::ModeBasis;
use modalforge::eigen::{EigenOptions, ModeCount, SolverKind};
use modalforge::fem::{sparse, ElementKind, FemModel, UnitElement};
use modalforge::shape::primitives::Primitive;
use modalforge::shape::spec::ShapeSpec;
use modalforge::shape::VoxelGrid;

fn primitive(spec: &str) -> Primitive {
    match spec.parse::<ShapeSpec>().expect("spec") {
        ShapeSpec::Primitive { shape, .. } => shape,
        _ => panic!("{spec} is not a primitive"),
    }
}

fn eigenvalues(grid: &VoxelGrid, kind: ElementKind, modes: usize) -> Vec<f64> {
    let options = EigenOptions {
        count: ModeCount::First(modes),
        tolerance: 1e-8,
        ..EigenOptions::default()
    };
    let basis = ModeBasis::solve(grid, kind, NU, SolverKind::Auto, &options).expect("solve");
    basis.solution.eigenvalues.clone()
}

#[test]
fn binary_grids_assemble_exactly_todays_matrices() {
    // Today's assembly: the unit element on every voxel, through the same scatter.
    let grid = primitive("bowl:d=12,wall=2")
        .rasterize_staircase(1.0, 1.0)
        .unwrap();
    assert!(grid.is_binary());
    for kind in ElementKind::ALL {
        let model = FemModel::assemble(&grid, kind, NU).unwrap();
        let unit = UnitElement::new(kind, NU);
        let mut k = vec![[0.0; 9]; model.pattern.col.len()];
        let mut m = k.clone();
        let unit_matrices = (&unit.stiffness[..], &unit.mass[..]);
        sparse::add_elements(
            &model.pattern,
            &model.elements,
            kind.nodes(),
            |_| unit_matrices,
            &mut k,
            &mut m,
        );
        assert!(model.k[..] == k[..] && model.m[..] == m[..], "{kind:?}");
    }
}

#[test]
fn partial_voxels_hold_the_true_volume() {
    // Exact volumes in voxels^3. The fill is sampled on 16^3 points per voxel and stored in
    // 1/255 per sub-cell; the errors of the ~1000 surface voxels average out: 0.2 % bounds
    // them. The staircase misses by percents (reported).
    let cases = [
        (
            "sphere:d=16",
            4.0 / 3.0 * std::f64::consts::PI * 8f64.powi(3),
        ),
        (
            "bowl:d=16,wall=2",
            2.0 / 3.0 * std::f64::consts::PI * (8f64.powi(3) - 6f64.powi(3)),
        ),
        (
            "tube:d=16,h=32,wall=2",
            std::f64::consts::PI * (64.0 - 36.0) * 32.0,
        ),
    ];
    for (spec, exact) in cases {
        let shape = primitive(spec);
        let smooth = shape.rasterize(1.0, 1.0).unwrap().volume_voxels();
        let stair = shape.rasterize_staircase(1.0, 1.0).unwrap().volume_voxels();
        let err = 100.0 * (smooth / exact - 1.0);
        eprintln!(
            "{spec}: volume {err:+.3} % (staircase {:+.2} %)",
            100.0 * (stair / exact - 1.0)
        );
        assert!(err.abs() < 0.2, "{spec}: {err:.3} %");
    }
}

#[test]
fn the_default_bowl_rings_true_with_quadratic_elements() {
    // The bounds on the 16-voxel bowl: lowest 10 frequencies within 2 % of the
    // smooth reference, the lowest pair split under 0.5 %. Measured: hex27 +0.9 % worst, split
    // 0.13 %. The default element (hex8i) is reported beside it and held to its measured
    // state: +7.6 % (its bubbles follow the lattice; the staircase was -7.4 %), split 0.74 %
    // (staircase 3.6 %).
    let spec = "bowl:d=16,wall=2";
    let want = reference(spec);
    let shape = primitive(spec);
    let grid = shape.rasterize(1.0, 1.0).unwrap();
    let hex27 = eigenvalues(&grid, ElementKind::Hex27, 16);
    let e27 = frequency_errors(&hex27, &want, 10);
    let (split27, groups) = worst_split(&hex27, &want, 12);
    let hex8i = eigenvalues(&grid, ElementKind::Hex8Incompatible, 16);
    let e8 = frequency_errors(&hex8i, &want, 10);
    let (split8, _) = worst_split(&hex8i, &want, 12);
    let stair = shape.rasterize_staircase(1.0, 1.0).unwrap();
    let old = eigenvalues(&stair, ElementKind::Hex8Incompatible, 16);
    let (split_old, _) = worst_split(&old, &want, 12);
    eprintln!(
        "{spec}: hex27 worst {:.2} %, split {split27:.3} %; hex8i worst {:.2} %, split \
         {split8:.2} %; staircase hex8i worst {:.2} %, split {split_old:.2} % ({groups} pairs)",
        worst(&e27),
        worst(&e8),
        worst(&frequency_errors(&old, &want, 10)),
    );
    assert!(groups >= 3, "the reference has its degenerate pairs");
    assert!(worst(&e27) < 2.0, "hex27 {e27:?}");
    assert!(split27 < 0.5, "hex27 split {split27}");
    assert!(
        worst(&e8) < 9.0 && split8 < 1.0,
        "hex8i {e8:?}, split {split8}"
    );
    assert!(
        split8 < split_old / 3.0,
        "partial voxels must close the split"
    );
}
