//! The progressive first answer ([`coarse_grid`], [`CoarseFemSolver`]). Truths: volumes counted
//! by hand, the mirror images of the fine grid's fills, and cold solves of the fine grid.

use super::*;
use crate::eigen::Stop;
use crate::shape::fill::SUBCELLS_PER_AXIS;
use crate::shape::primitives::Primitive;
use crate::shape::VoxelFill;

/// A hollow cube `side` voxels a side with walls `wall` thick.
fn hollow_box(side: usize, wall: usize) -> VoxelGrid {
    let solid = VoxelGrid::from_fn([side; 3], 0.01, |_, _, _| true).unwrap();
    crate::shape::ops::hollow(&solid, wall)
}

/// A built-in primitive (`spec`, as the CLI parses it) voxelised on hex27x2's 2-voxel blocks.
fn on_blocks(spec: &str) -> VoxelGrid {
    let crate::shape::spec::ShapeSpec::Primitive { shape, hollow } = spec.parse().unwrap() else {
        panic!("{spec}")
    };
    crate::shape::spec::primitive_voxels(&shape, hollow, 1.0, 2).unwrap()
}

#[test]
fn the_coarse_grid_halves_the_resolution_and_keeps_the_volume() {
    // Walls two voxels thick on even planes: every coarse voxel is full or empty, and the
    // volume is the fine one exactly.
    let thick = hollow_box(16, 2);
    let coarse = coarse_grid(&thick).expect("a coarse grid");
    assert_eq!(coarse.dims(), [8, 8, 8]);
    assert_eq!(coarse.voxel_size_m(), 0.02);
    assert!(coarse.is_binary());
    assert_eq!(8.0 * coarse.volume_voxels(), thick.volume_voxels());
    // Walls one voxel thick stay one voxel thick: half-filled coarse voxels (a threshold on
    // whole voxels made them two thick or nothing). The volume is kept to the fills'
    // quantisation: a half-filled sub-cell stores 128/255, 0.4 % over a half.
    let thin = hollow_box(16, 1);
    let coarse = coarse_grid(&thin).expect("a coarse grid");
    let ratio = 8.0 * coarse.volume_voxels() / thin.volume_voxels();
    assert!((ratio - 1.0).abs() < 0.004, "{ratio}");
    // Its coarse voxels hold the fine fill: half on the faces (6 x 6^2), three quarters
    // along the edges (12 x 6), seven eighths at the corners (8), 0.5 % at most off by
    // the bytes' quantisation.
    let count = |fill: f64| {
        (coarse.partial_voxels())
            .filter(|(_, f)| (f.mean() - fill).abs() < 0.005)
            .count()
    };
    assert_eq!((count(0.5), count(0.75), count(0.875)), (216, 72, 8));
    assert_eq!(coarse.count(), 296);
    // The cost model orders objects by size.
    let (count, el) = (ModeCount::First(60), ElementKind::Hex8Incompatible);
    assert!(
        predicted_cold_ms(&hollow_box(24, 2), el, count) > predicted_cold_ms(&thick, el, count)
    );
}

#[test]
fn the_coarse_grid_keeps_mirrors_and_refuses_to_join_parts() {
    // A bowl's fills are mirror images across its centre planes bit for bit; the coarse
    // grid's must be too (sums in integers), or its model loses the mirrors and is solved
    // whole, several times slower.
    let grid = Primitive::Bowl {
        diameter: 16.0,
        wall: 1.0,
    }
    .rasterize(1.0, 1.0)
    .unwrap();
    let coarse = coarse_grid(&grid).expect("a coarse grid");
    let d = coarse.dims();
    let n = SUBCELLS_PER_AXIS;
    let mut partial = 0;
    for z in 0..d[2] {
        for y in 0..d[1] {
            for x in 0..d[0] {
                let at = |x: usize| coarse.fill_at(x as isize, y as isize, z as isize);
                match (at(x), at(d[0] - 1 - x)) {
                    (VoxelFill::Partial(a), VoxelFill::Partial(b)) => {
                        partial += 1;
                        for i in 0..n * n * n {
                            let mirrored = (n - 1 - i % n) + n * (i / n);
                            assert_eq!(a.0[i], b.0[mirrored], "voxel {x},{y},{z}");
                        }
                    }
                    (a, b) => assert_eq!(a, b, "voxel {x},{y},{z}"),
                }
            }
        }
    }
    assert!(partial > 20, "{partial}");
    // Two bars one voxel apart, the gap inside a coarse voxel: joined on the coarse grid,
    // which would have six rigid-body modes fewer; refused.
    let mut apart = VoxelGrid::new([9, 2, 2], 0.01).unwrap();
    for x in (0..9).filter(|&x| x != 3) {
        for (y, z) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
            apart.set(x, y, z, true);
        }
    }
    assert_eq!(crate::shape::ops::components(&apart).1, 2);
    assert!(coarse_grid(&apart).is_none());
}

#[test]
fn the_coarse_answer_is_within_its_expected_error() {
    // The lowest 10 modes of the coarse answer against a cold solve of the fine grid, mean
    // relative frequency error (hex27x2, the plugin's element): within the figure the status
    // line shows for each class of object, and for the thin walls closer than the half-
    // resolution model before its stiffening is divided out (`coarse_stiffening`; fitted on
    // random primitives, none of these). Measured (corrected, uncorrected): the plate
    // 1.5 % (8.3 %), the bowl with a one-voxel wall 5.9 % (9.1 %) (thin, 7 % stated); the
    // bowl with a two-voxel wall 2.9 % (3.4 %) and the sphere 0.5 % (0.2 %) (thick, 4 % stated).
    let cases = [
        ("plate:l=32,w=24,t=1", 0.33, COARSE_THIN_EXPECTED_ERROR),
        ("bowl:d=16,wall=1", 0.24, COARSE_THIN_EXPECTED_ERROR),
        ("bowl:d=12,wall=2", 0.3, COARSE_EXPECTED_ERROR),
        ("sphere:d=12", 0.3, COARSE_EXPECTED_ERROR),
    ];
    let options = EigenOptions {
        count: ModeCount::First(10),
        ..EigenOptions::default()
    };
    for (spec, nu, stated) in cases {
        let grid = on_blocks(spec);
        assert_eq!(coarse_expected_error(&grid), stated, "{spec}");
        let hex27x2 = ElementKind::Hex27Blocks;
        let fine = ModeBasis::solve(&grid, hex27x2, nu, SolverKind::Auto, &options).unwrap();
        let coarse = solve_coarse(
            &grid,
            hex27x2,
            nu,
            SolverKind::Auto,
            &options,
            None,
            Stop::NEVER,
        )
        .unwrap();
        // Reference units scale frequency by 1/h: the coarse voxel is twice the edge.
        let mean_error = |ratio: f64| {
            let errors: Vec<f64> = (coarse.solution.eigenvalues.iter())
                .zip(&fine.solution.eigenvalues)
                .map(|(c, f)| (ratio * c.sqrt() / 2.0 - f.sqrt()).abs() / f.sqrt())
                .collect();
            assert_eq!(errors.len(), 10);
            errors.iter().sum::<f64>() / 10.0
        };
        let stiffening = coarse_stiffening(&grid);
        let (corrected, uncorrected) = (mean_error(1.0), mean_error(stiffening));
        println!(
            "{spec}: stiffening {stiffening:.3}, {corrected:.4} ({uncorrected:.4} uncorrected)"
        );
        assert!(
            corrected < stated,
            "{spec}: {corrected:.3} against {stated}"
        );
        if stated == COARSE_THIN_EXPECTED_ERROR {
            assert!(
                corrected < uncorrected,
                "{spec}: {corrected:.3}, {uncorrected:.3}"
            );
        }
    }
}

#[test]
fn the_stiffening_law_is_one_for_solids_and_grows_as_walls_thin() {
    // `coarse_stiffening`'s form: 1 where the wall fills a coarse element (a 24^3 sphere's
    // mean wall, 2V/A, is 5.3 voxels), above 1 and larger for thinner walls otherwise.
    assert_eq!(coarse_stiffening(&on_blocks("sphere:d=24")), 1.0);
    let (one, two) = (
        coarse_stiffening(&on_blocks("plate:l=16,w=16,t=1")),
        coarse_stiffening(&on_blocks("plate:l=16,w=16,t=2")),
    );
    // Walls of one and two voxels: the law's 1/t^2 makes the first stiffen over 3x more.
    assert!(one > two && two > 1.0, "{one} {two}");
    assert!((one - 1.0) > 3.0 * (two - 1.0), "{one} {two}");
}

#[test]
fn the_time_estimate_counts_the_mirrors_the_voxels_have() {
    // Truths by hand: a bowl has two mirror planes, a sphere three; one voxel removed off
    // every plane leaves none; a 3x4x5 box has three for hex8i, but only along its even side
    // for hex27x2, whose 2-voxel blocks from the origin map onto blocks only where the first
    // and last voxel indices add up to an odd number.
    let hex27x2 = ElementKind::Hex27Blocks;
    assert_eq!(grid_mirrors(&on_blocks("bowl:d=16,wall=1"), hex27x2), 2);
    let mut sphere = on_blocks("sphere:d=12");
    assert_eq!(grid_mirrors(&sphere, hex27x2), 3);
    let v = sphere.solid_voxels()[0];
    sphere.set(v[0], v[1], v[2], false);
    assert_eq!(grid_mirrors(&sphere, hex27x2), 0);
    let block = VoxelGrid::from_fn([3, 4, 5], 0.01, |_, _, _| true).unwrap();
    assert_eq!(grid_mirrors(&block, ElementKind::Hex8Incompatible), 3);
    assert_eq!(grid_mirrors(&block, hex27x2), 1);
    // Fewer mirrors, a longer estimate for the same object.
    let count = ModeCount::First(60);
    assert!(
        predicted_cold_ms(&block, hex27x2, count)
            > predicted_cold_ms(&block, ElementKind::Hex8Incompatible, count)
    );
}
