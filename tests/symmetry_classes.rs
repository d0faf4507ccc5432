//! Mirror-symmetric objects solved class by class (`eigen::symmetric`) against the same
//! objects solved whole: the class-by-class answer must be the whole model's lowest modes
//! (none missed, none doubled: a bowl's paired modes fall in two classes, a sphere's triplets
//! in three), with residuals (Jin et al. 2022, eq. 6) and M-orthonormality recomputed on the
//! whole `K` and `M` from the lifted vectors alone (`common::eigen::identities`).

use modalforge::eigen::symmetric::{self, Mirrors};
use modalforge::eigen::{self, lanczos, ModeCount, SolverKind, Stop};
use modalforge::fem::{ElementKind, FemModel};
use modalforge::shape::primitives::Primitive;
use modalforge::shape::spec::primitive_voxels;
use modalforge::shape::VoxelGrid;

mod common;
use common::eigen::{identities, options, TOL};

const NU: f64 = 0.24;
fn bowl() -> VoxelGrid {
    Primitive::Bowl {
        diameter: 16.0,
        wall: 2.0,
    }
    .rasterize(1.0, 1.0)
    .unwrap()
}

/// The default bowl (two mirrors; partial voxels, so its fills are symmetric only to the
/// rounding of their refinement for hex27x2), a solid sphere and a small bar (three mirrors),
/// each by classes and whole.
#[test]
fn classes_give_the_whole_model_s_lowest_modes() {
    let sphere = Primitive::Sphere { diameter: 12.0 }
        .rasterize(1.0, 1.0)
        .unwrap();
    // Large enough that its classes are split by the swaps that map them onto themselves
    // (`symmetric::MIN_SPLIT_CLASS_DOFS`): three swaps, and classes split by different ones
    // (the class even in all three mirrors by the x-y swap, the one odd in x only by y-z).
    let large_sphere = Primitive::Sphere { diameter: 18.0 }
        .rasterize(1.0, 1.0)
        .unwrap();
    let small_bar = Primitive::Bar {
        length: 30.0,
        width: 3.0,
        height: 3.0,
    }
    .rasterize(1.0, 1.0)
    .unwrap();
    // The steel bar preset as the plugin rasterises it for hex27x2 (`primitive_voxels`: its
    // 3-voxel sides padded to the 2-voxel blocks and the bar centred): three mirrors and the
    // swap of its square section, where the plain rasterisation, one full block and one half
    // full across each short side, has only the mirror along its length.
    let steel_bar = primitive_voxels(
        &Primitive::Bar {
            length: 30.0,
            width: 3.0,
            height: 3.0,
        },
        None,
        1.0,
        ElementKind::Hex27Blocks.voxels_per_element(),
    )
    .unwrap();
    // The aluminium plate preset rasterised plainly: hex27x2 elements span 2x2x2 voxels, so
    // its one-voxel thickness has no mirror (4 classes). Its first class holds more of the lowest 60 modes
    // than the others, which were asked below too low a bound and are asked again: their
    // Lanczos iterations go on from where the first request stopped.
    let plate = Primitive::Plate {
        length: 32.0,
        width: 24.0,
        thickness: 1.0,
    }
    .rasterize(1.0, 1.0)
    .unwrap();
    // (name, grid, element, modes, mirrors, swaps of mirrored axes): the bowl's x-y swap makes
    // its class odd in y the image of the one odd in x; the sphere's swaps leave four of its
    // eight classes to solve.
    let all_swaps = vec![(0, 1), (1, 2), (0, 2)];
    let bowl_swap = vec![(0, 1)];
    let hex8i = ElementKind::Hex8Incompatible;
    let cases = [
        ("bowl hex8i", bowl(), hex8i, 60, 0b011, bowl_swap.clone()),
        (
            "bowl hex27x2",
            bowl(),
            ElementKind::Hex27Blocks,
            40,
            0b011,
            bowl_swap,
        ),
        ("sphere hex8i", sphere, hex8i, 30, 0b111, all_swaps.clone()),
        (
            "sphere d=18 hex8i",
            large_sphere,
            hex8i,
            40,
            0b111,
            all_swaps,
        ),
        // 1.5k DOFs, just over `MIN_DOFS`: eight classes of ~190 DOFs for 60 modes, and for
        // 20 (the SciPy comparison's smallest case), whose classes expect so few pairs that
        // they iterate in blocks of two (`symmetric::TINY_BLOCK_SIZE`).
        (
            "bar hex8i",
            small_bar.clone(),
            hex8i,
            60,
            0b111,
            vec![(1, 2)],
        ),
        (
            "bar hex8i, 20 modes",
            small_bar,
            hex8i,
            20,
            0b111,
            vec![(1, 2)],
        ),
        (
            "steel bar hex27x2 on blocks",
            steel_bar,
            ElementKind::Hex27Blocks,
            60,
            0b111,
            vec![(1, 2)],
        ),
        (
            "plate hex27x2",
            plate,
            ElementKind::Hex27Blocks,
            60,
            0b011,
            vec![],
        ),
    ];
    for (name, grid, kind, modes, axes, swaps) in cases {
        let model = FemModel::assemble(&grid, kind, NU).unwrap();
        assert!(
            model.dofs() >= symmetric::MIN_DOFS,
            "{name}: solved by classes"
        );
        let mirrors = Mirrors::detect(&model).expect("mirrors");
        assert_eq!(mirrors.axes(), axes, "{name}: mirrors");
        assert_eq!(mirrors.swaps(), swaps, "{name}: swaps");
        if name == "bowl hex27x2" || name == "sphere d=18 hex8i" {
            let classes = mirrors.classes();
            assert!(
                model.dofs() / classes.len() >= symmetric::MIN_SPLIT_CLASS_DOFS
                    && classes.iter().any(|&c| mirrors.splitting_swap(c).is_some()),
                "{name}: classes split by a swap"
            );
        }
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
    // Midway across the first clear gap from the 20th mode on (not inside a degenerate pair,
    // whose two copies may land on either side of a bound between them).
    let e = &whole.eigenvalues;
    let count = (20..29)
        .find(|&i| e[i] - e[i - 1] > 1e-3 * e[i])
        .expect("a gap");
    let bound = 0.5 * (e[count - 1] + e[count]);
    let opts = options(ModeCount::Below(bound));
    let classes = symmetric::solve_until(&model, &opts, Stop::NEVER)
        .expect("solved by classes")
        .unwrap();
    assert_eq!(classes.eigenvalues.len(), count);
    for (a, b) in classes.eigenvalues.iter().zip(&whole.eigenvalues) {
        assert!((a - b).abs() <= 1e-7 * b, "{a} against {b}");
    }
}

/// A stroke off the mirror planes leaves the mirror it crosses no longer a symmetry, and a
/// model without any mirror (or too small) is left to the whole solve.
#[test]
fn an_asymmetric_stroke_removes_its_mirrors() {
    let mut grid = bowl();
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
    let mirrors = Mirrors::detect(&one).expect("mirror");
    assert_eq!(mirrors.axes(), 0b001);
    assert!(mirrors.swaps().is_empty(), "no swap without both mirrors");
    let opts = options(ModeCount::First(20));
    let classes = symmetric::solve_until(&one, &opts, Stop::NEVER)
        .expect("solved by classes")
        .unwrap();
    let whole = lanczos::solve(&one, &opts).unwrap();
    for (a, b) in classes.eigenvalues.iter().zip(&whole.eigenvalues) {
        assert!((a - b).abs() <= 1e-7 * b, "{a} against {b}");
    }
}

/// The voicing does not depend on the solver: the default bowl's modal forces at its default
/// hit, by classes (Lanczos) and whole (LOBPCG), are the same and all positive (every mode
/// turned so it starts in phase there, `ModeBasis`), where the signs the solvers return are
/// arbitrary.
#[test]
fn the_strike_does_not_depend_on_the_solver_s_signs() {
    use modalforge::basis::ModeBasis;
    use modalforge::material::Material;
    let grid = bowl();
    let opts = options(ModeCount::First(20));
    let forces = |solver| {
        let basis = ModeBasis::solve(&grid, ElementKind::Hex8Incompatible, NU, solver, &opts)
            .expect("modes");
        let glass = Material::preset("glass").expect("glass");
        basis
            .modal_forces(&glass, 0.01, &basis.default_hit(0.01))
            .expect("forces")
    };
    let (classes, whole) = (forces(SolverKind::Lanczos), forces(SolverKind::Lobpcg));
    let largest = classes.iter().fold(0.0f64, |m, f| m.max(f.abs()));
    for (j, (a, b)) in classes.iter().zip(&whole).enumerate() {
        // Eigenvectors to residual 1e-9: a mode's force agrees to ~1e-9 / gap; 1e-6 of the
        // largest leaves room for the closest pair (0.06 % apart) and fails on any sign flip.
        assert!((a - b).abs() <= 1e-6 * largest, "mode {j}: {a} against {b}");
        assert!(*a >= -1e-9 * largest, "mode {j}: {a} is negative");
    }
}
