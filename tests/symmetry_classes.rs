//! Mirror-symmetric objects solved class by class (`eigen::symmetric`) against the same
//! objects solved whole: the class-by-class answer must be the whole model's lowest modes
//! (none missed, none doubled: a bowl's paired modes fall in two classes, a sphere's triplets
//! in three), with residuals (Jin et al. 2022, eq. 6) and M-orthonormality recomputed on the
//! whole `K` and `M` from the lifted vectors alone.

use modalforge::eigen::symmetric::{self, Mirrors};
use modalforge::eigen::{
    self, lanczos, EigenOptions, ModeCount, Operators, SolverKind, Stop, Which,
};
use modalforge::fem::{ElementKind, FemModel};
use modalforge::shape::primitives::Primitive;
use modalforge::shape::VoxelGrid;

const NU: f64 = 0.24;
const TOL: f64 = 1e-9;

fn options(count: ModeCount) -> EigenOptions {
    EigenOptions {
        count,
        tolerance: TOL,
        ..Default::default()
    }
}

fn bowl() -> VoxelGrid {
    Primitive::Bowl {
        diameter: 16.0,
        wall: 2.0,
    }
    .rasterize(1.0, 1.0)
    .unwrap()
}

/// `(max residual, max |V^T M V - I|)` recomputed on the whole model.
fn identities(model: &FemModel, sol: &eigen::EigenSolution) -> (f64, f64) {
    let ops = Operators::new(model);
    let residual = ops
        .block_residuals(&sol.eigenvalues, sol.vectors.as_ref())
        .into_iter()
        .fold(0.0, f64::max);
    let mv = ops.apply_block(Which::M, sol.vectors.as_ref());
    let gram = sol.vectors.transpose() * &mv;
    let mut orth = 0.0f64;
    for i in 0..gram.nrows() {
        for j in 0..gram.ncols() {
            let want = if i == j { 1.0 } else { 0.0 };
            orth = orth.max((gram[(i, j)] - want).abs());
        }
    }
    (residual, orth)
}

/// The default bowl (two mirrors; partial voxels, so its fills are symmetric only to the
/// rounding of their refinement for hex27x2) and a solid sphere (three mirrors), each by
/// classes and whole.
#[test]
fn classes_give_the_whole_model_s_lowest_modes() {
    let sphere = Primitive::Sphere { diameter: 12.0 }
        .rasterize(1.0, 1.0)
        .unwrap();
    let cases = [
        (
            "bowl hex8i",
            bowl(),
            ElementKind::Hex8Incompatible,
            60,
            0b011,
        ),
        ("bowl hex27x2", bowl(), ElementKind::Hex27Blocks, 40, 0b011),
        (
            "sphere hex8i",
            sphere,
            ElementKind::Hex8Incompatible,
            30,
            0b111,
        ),
    ];
    for (name, grid, kind, modes, axes) in cases {
        let model = FemModel::assemble(&grid, kind, NU).unwrap();
        assert!(
            model.dofs() >= symmetric::MIN_DOFS,
            "{name}: solved by classes"
        );
        let mirrors = Mirrors::detect(&model).expect("mirrors");
        assert_eq!(mirrors.axes(), axes, "{name}: mirrors");
        let opts = options(ModeCount::First(modes));
        let classes = symmetric::solve_until(&model, &opts, Stop::NEVER)
            .expect("solved by classes")
            .unwrap();
        let whole = lanczos::solve(&model, &opts).unwrap();
        assert_eq!(classes.eigenvalues.len(), modes, "{name}");
        assert_eq!(classes.rigid_modes, 6, "{name}");
        assert_eq!(classes.rigid_vectors.ncols(), 6, "{name}");
        // Both converged to residual 1e-9 of ||K||; an eigenvalue's error is of the order of
        // the squared residual over the gap, so 1e-7 relative leaves a wide margin, while a
        // missed or doubled mode shifts every one after it by a gap (percents).
        for (j, (a, b)) in classes
            .eigenvalues
            .iter()
            .zip(&whole.eigenvalues)
            .enumerate()
        {
            assert!(
                (a - b).abs() <= 1e-7 * b,
                "{name}: mode {j}: {a} against {b}"
            );
        }
        let (residual, orth) = identities(&model, &classes);
        assert!(residual <= TOL, "{name}: recomputed residual {residual:e}");
        // M-orthonormality: the classes are orthogonal by construction, each class's vectors
        // to its Lanczos basis's rounding, ~1e-13 measured; 1e-10 is eps x sqrt(n) x 1e3.
        assert!(orth <= 1e-10, "{name}: M-orthonormality {orth:e}");
        for (r, reported) in classes.residuals.iter().enumerate() {
            assert!(
                *reported <= TOL,
                "{name}: reported residual {r}: {reported:e}"
            );
        }
        // The public solve takes this path for Lanczos.
        let public = eigen::solve(&model, SolverKind::Lanczos, &opts).unwrap();
        assert_eq!(public.eigenvalues, classes.eigenvalues, "{name}");
    }
}

/// "Every mode below a bound" by classes is the whole model's list.
#[test]
fn classes_find_every_mode_below_a_bound() {
    let model = FemModel::assemble(&bowl(), ElementKind::Hex8Incompatible, NU).unwrap();
    let whole = lanczos::solve(&model, &options(ModeCount::First(30))).unwrap();
    // Midway between the 25th and 26th modes.
    let bound = 0.5 * (whole.eigenvalues[24] + whole.eigenvalues[25]);
    let opts = options(ModeCount::Below(bound));
    let classes = symmetric::solve_until(&model, &opts, Stop::NEVER)
        .expect("solved by classes")
        .unwrap();
    assert_eq!(classes.eigenvalues.len(), 25);
    for (a, b) in classes.eigenvalues.iter().zip(&whole.eigenvalues) {
        assert!((a - b).abs() <= 1e-7 * b, "{a} against {b}");
    }
}

/// A stroke off the mirror planes leaves the mirror it crosses no longer a symmetry, and a
/// model without any mirror (or too small) is left to the whole solve.
#[test]
fn an_asymmetric_stroke_removes_its_mirrors() {
    let mut grid = bowl();
    let before = FemModel::assemble(&grid, ElementKind::Hex8Incompatible, NU).unwrap();
    assert_eq!(Mirrors::detect(&before).expect("mirrors").axes(), 0b011);
    // A wall voxel at x = 2 on the y mirror plane's side y < 8: breaks both mirrors.
    let voxel = grid
        .solid_voxels()
        .into_iter()
        .find(|v| v[0] == 2 && v[1] == 5)
        .expect("a wall voxel");
    grid.set(voxel[0], voxel[1], voxel[2], false);
    let after = FemModel::assemble(&grid, ElementKind::Hex8Incompatible, NU).unwrap();
    assert!(Mirrors::detect(&after).is_none(), "no mirror left");
    assert!(symmetric::solve_until(&after, &options(ModeCount::First(10)), Stop::NEVER).is_none());
    // One mirror kept: a voxel and its image in x removed together.
    let mut grid = bowl();
    let d = grid.dims();
    for x in [voxel[0], d[0] - 1 - voxel[0]] {
        grid.set(x, voxel[1], voxel[2], false);
    }
    let one = FemModel::assemble(&grid, ElementKind::Hex8Incompatible, NU).unwrap();
    assert_eq!(Mirrors::detect(&one).expect("mirror").axes(), 0b001);
    let opts = options(ModeCount::First(20));
    let classes = symmetric::solve_until(&one, &opts, Stop::NEVER)
        .expect("solved by classes")
        .unwrap();
    let whole = lanczos::solve(&one, &opts).unwrap();
    for (a, b) in classes.eigenvalues.iter().zip(&whole.eigenvalues) {
        assert!((a - b).abs() <= 1e-7 * b, "{a} against {b}");
    }
}
