//! The two eigensolvers against each other and against the identities every eigen-solution
//! must satisfy: LOBPCG with multigrid (an iterative method on products with K and M) must
//! reproduce shift-invert Lanczos on a direct factorisation (a different algorithm on a
//! different operator), and both must return M-orthonormal vectors whose recomputed residuals
//! (Jin et al. 2022, eq. 6) meet the tolerance.

use modalforge::eigen::symmetric::{self, Mirrors};
use modalforge::eigen::{self, EigenOptions, ModeCount, SolverKind, Stop};
use modalforge::fem::{ElementKind, FemModel};
use modalforge::shape::primitives::Primitive;
use modalforge::shape::VoxelGrid;

mod common;
use common::eigen::{identities, options, TOL};
use common::two_cubes;

const NU: f64 = 0.3;

fn bowl(d: f64) -> VoxelGrid {
    Primitive::Bowl {
        diameter: d,
        wall: 2.0,
    }
    .rasterize(1.0, 1.0)
    .unwrap()
}

#[test]
fn lobpcg_agrees_with_lanczos_and_both_satisfy_the_identities() {
    let bracket = VoxelGrid::from_fn([16, 12, 4], 1.0, |x, y, _| x < 4.0 || y < 4.0).unwrap();
    let cases = [
        (
            "bar 32x4x4 hex8i",
            VoxelGrid::from_fn([32, 4, 4], 1.0, |_, _, _| true).unwrap(),
            ElementKind::Hex8Incompatible,
        ),
        ("L bracket hex8", bracket, ElementKind::Hex8),
        ("bowl d=12 hex27", bowl(12.0), ElementKind::Hex27),
        ("bowl d=16 hex27x2", bowl(16.0), ElementKind::Hex27Blocks),
        (
            "plate 24x24x1 hex8i",
            VoxelGrid::from_fn([24, 24, 1], 1.0, |_, _, _| true).unwrap(),
            ElementKind::Hex8Incompatible,
        ),
    ];
    for (name, grid, kind) in cases {
        let model = FemModel::assemble(&grid, kind, NU).unwrap();
        let opts = options(ModeCount::First(12));
        let lanczos = eigen::solve(&model, SolverKind::Lanczos, &opts).unwrap();
        let lobpcg = eigen::solve(&model, SolverKind::Lobpcg, &opts).unwrap();
        assert_eq!(lobpcg.rigid_modes, 6, "{name}");
        assert_eq!(lobpcg.eigenvalues.len(), 12, "{name}");
        // Both converged to residual 1e-9 of ||K||: the eigenvalue error is of the order of the
        // squared residual over the gap, so 1e-7 relative leaves a wide margin while any
        // missed or spurious mode (a gap of percents) fails.
        for (a, b) in lanczos.eigenvalues.iter().zip(&lobpcg.eigenvalues) {
            assert!((a - b).abs() <= 1e-7 * a, "{name}: {a} vs {b}");
        }
        for (solver, sol) in [("lanczos", &lanczos), ("lobpcg", &lobpcg)] {
            let (res, orth) = identities(&model, sol);
            // The residual is recomputed independently of the solver, so it may differ from the
            // solver's own by rounding: 2x the tolerance.
            assert!(res <= 2.0 * TOL, "{name} {solver}: residual {res:e}");
            assert!(sol.residuals.iter().all(|&r| r <= TOL), "{name} {solver}");
            // M-orthonormality: Ritz vectors of a Rayleigh-Ritz step are M-orthonormal to
            // rounding, eps sqrt(n) ~ 1e-13; converged pairs to the residual over the gap.
            assert!(orth <= 1e-8, "{name} {solver}: orthonormality {orth:e}");
        }
    }
}

#[test]
fn both_solvers_find_rigid_modes_numerically() {
    // Sharing a face: one body (6). Along an edge: a hinge (7). At a corner: a ball joint (9).
    // Apart: two bodies (12). Counted from eigenvalues, never from parts. LOBPCG's coarse
    // level merges the two cubes, so its fine solve must discover the extra zero modes itself
    // and grow its block.
    for solver in [SolverKind::Lanczos, SolverKind::Lobpcg] {
        for (offset, want) in [
            ([2, 0, 0], 6),
            ([2, 2, 0], 7),
            ([2, 2, 2], 9),
            ([3, 3, 3], 12),
        ] {
            let model =
                FemModel::assemble(&two_cubes(offset), ElementKind::Hex8Incompatible, NU).unwrap();
            let sol = eigen::solve(&model, solver, &options(ModeCount::First(4))).unwrap();
            assert_eq!(sol.rigid_modes, want, "{solver:?} offset {offset:?}");
            assert_eq!(sol.eigenvalues.len(), 4);
            assert!(sol.eigenvalues[0] > 1e-6, "{:?}", sol.eigenvalues);
        }
    }
}

#[test]
fn lobpcg_finds_every_mode_below_a_bound() {
    let grid = VoxelGrid::from_fn([40, 5, 3], 1.0, |_, _, _| true).unwrap();
    let model = FemModel::assemble(&grid, ElementKind::Hex8Incompatible, NU).unwrap();
    let first = eigen::solve(&model, SolverKind::Lanczos, &options(ModeCount::First(30))).unwrap();
    // A bound between the 17th and 18th modes (not on a repeated pair).
    let bound = 0.5 * (first.eigenvalues[16] + first.eigenvalues[17]);
    for solver in [SolverKind::Lobpcg, SolverKind::Lanczos] {
        let below = eigen::solve(&model, solver, &options(ModeCount::Below(bound))).unwrap();
        assert_eq!(below.eigenvalues.len(), 17, "{solver:?}");
        for (a, b) in below.eigenvalues.iter().zip(&first.eigenvalues) {
            assert!((a - b).abs() <= 1e-7 * b, "{solver:?}: {a} vs {b}");
        }
    }
}

/// A thin shell whose 10th mode the coarse multigrid level barely represents (its cells stiffen
/// the wall's bending): started from coarse modes alone, LOBPCG converged every column and
/// still skipped the 8127 Hz mode (it returned 8729 Hz as the 10th). The random guard columns
/// of the start must let it find the same lowest modes as the direct solver.
#[test]
fn lobpcg_misses_no_mode_of_a_thin_shell() {
    let grid = Primitive::Bowl {
        diameter: 48.0,
        wall: 3.0,
    }
    .rasterize(1.0, 1.0)
    .unwrap();
    let model = FemModel::assemble(&grid, ElementKind::Hex8Incompatible, NU).unwrap();
    let count = ModeCount::First(10);
    let direct = eigen::solve(&model, SolverKind::Lanczos, &options(count)).unwrap();
    // At the CLI's default residual, 1e-6 (at 1e-9 the extra iterations found the mode anyway).
    let loose = EigenOptions {
        tolerance: 1e-6,
        ..options(count)
    };
    let iterative = eigen::solve(&model, SolverKind::Lobpcg, &loose).unwrap();
    for (a, b) in iterative.eigenvalues.iter().zip(&direct.eigenvalues) {
        // Residual 1e-6 is relative to ||K||, ~1000x these low eigenvalues: measured 2e-6
        // relative eigenvalue error. 1e-4 leaves room; a skipped mode is 30 % off.
        assert!((a - b).abs() <= 1e-4 * b, "LOBPCG {a} vs Lanczos {b}");
    }
}

/// A box with cut faces that a dataset generator once drew (17 x 27 x 25 voxels, ~40k DOFs),
/// on which LOBPCG's multigrid stalls at a residual of ~1e-3: `Auto` picks LOBPCG there and
/// must still answer (by Lanczos), with the same modes below the bound as Lanczos asked
/// directly, and the identities met. A corner voxel is taken off: the whole box is
/// mirror-symmetric, which `Auto` solves by classes without trying LOBPCG.
#[test]
fn auto_answers_where_lobpcg_stalls() {
    use modalforge::predictor::{bands, dataset};
    let mut grid = Primitive::Box {
        x: 16.89422057103969,
        y: 27.495418427017842,
        z: 24.692692642611288,
    }
    .rasterize(1.0, 1.0)
    .unwrap()
    .cropped();
    assert_eq!(grid.dims(), [17, 27, 25]);
    grid.set(0, 0, 0, false);
    let model = FemModel::assemble(
        &grid,
        ElementKind::Hex8Incompatible,
        dataset::REFERENCE_POISSON,
    )
    .expect("assemble");
    let opts = EigenOptions {
        count: ModeCount::Below(bands::reference_eigenvalue(bands::HIGH_HZ)),
        ..Default::default()
    };
    assert_eq!(
        SolverKind::Auto.resolve(model.dofs(), &opts),
        SolverKind::Lobpcg
    );
    assert!(Mirrors::detect(&model).is_none(), "no mirrors left");
    assert!(
        eigen::solve(&model, SolverKind::Lobpcg, &opts).is_err(),
        "LOBPCG converged here: pick another object for this regression test"
    );
    let auto = eigen::solve(&model, SolverKind::Auto, &opts).expect("auto answers");
    let lanczos = eigen::solve(&model, SolverKind::Lanczos, &opts).expect("lanczos");
    assert_eq!(auto.eigenvalues, lanczos.eigenvalues);
    let (res, orth) = identities(&model, &auto);
    // Recomputed independently of the solver: 2x the tolerance for rounding, as above.
    assert!(res <= 2.0 * opts.tolerance, "residual {res:e}");
    assert!(orth < 1e-8, "orthonormality {orth:e}");
}

/// Where `Auto` would pick LOBPCG (a model over 30k DOFs, 20 modes), a mirror-symmetric one
/// is answered by Lanczos class by class (2-8x faster on solid spheres: `eigen::AUTO_CLASSES_MAX_DOFS`),
/// with the class solve's own modes and the identities met on the whole model.
#[test]
fn auto_solves_a_large_symmetric_model_by_classes() {
    let grid = Primitive::Sphere { diameter: 26.0 }
        .rasterize(1.0, 1.0)
        .unwrap();
    let model = FemModel::assemble(&grid, ElementKind::Hex8Incompatible, 0.3).unwrap();
    // The default residual, 1e-6 (LOBPCG's range: Auto never picks it below 1e-7).
    let opts = EigenOptions {
        count: ModeCount::First(20),
        ..Default::default()
    };
    assert_eq!(
        SolverKind::Auto.resolve(model.dofs(), &opts),
        SolverKind::Lobpcg,
        "{} DOFs: over Auto's LOBPCG limit",
        model.dofs()
    );
    assert!(model.dofs() <= eigen::AUTO_CLASSES_MAX_DOFS);
    let auto = eigen::solve(&model, SolverKind::Auto, &opts).expect("auto answers");
    assert_eq!(auto.solver, SolverKind::Lanczos, "by classes, not LOBPCG");
    let classes = symmetric::solve_until(&model, &opts, Stop::NEVER)
        .expect("mirror-symmetric")
        .unwrap();
    assert_eq!(auto.eigenvalues, classes.eigenvalues);
    assert_eq!(auto.rigid_modes, 6);
    let (res, orth) = identities(&model, &auto);
    // Recomputed independently of the solver: 2x the tolerance for rounding, as above.
    assert!(res <= 2.0 * opts.tolerance, "residual {res:e}");
    assert!(orth < 1e-8, "orthonormality {orth:e}");
}
