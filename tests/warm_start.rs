//! Sculpting edits: the warm-started exact solve and the instant carried answer against cold
//! solves of the same edited shape (an independent computation from a random start).
//!
//! Tolerances: both exact solves stop at the residual 1e-6 (Jin et al. 2022, eq. 6); an
//! eigenvalue's error is bounded by the residual squared over the gap (Parlett, Thm. 11.7.1), so
//! two exact answers agree to well under 1e-6 in frequency (measured 1.2e-9 here). The carried
//! answer is not exact: its frequencies must be within 1e-3 (measured ~1e-4 here; the bench sees
//! 1e-5 to 3e-3 on the presets), the ten-times margin a stated expectation allows.

use modalforge::basis::ModeBasis;
use modalforge::eigen::warm;
use modalforge::eigen::{EigenOptions, ModeCount, Operators, SolverKind};
use modalforge::fem::{ElementKind, FemModel};
use modalforge::shape::primitives::Primitive;
use modalforge::shape::{ops, VoxelGrid};

const NU: f64 = 0.24;
const MODES: usize = 30;

fn bowl() -> VoxelGrid {
    let grid = Primitive::Sphere { diameter: 12.0 }
        .rasterize(1.0, 1.0)
        .expect("sphere");
    ops::hollow(&grid, 2)
}

fn options() -> EigenOptions {
    EigenOptions {
        count: ModeCount::First(MODES),
        ..Default::default()
    }
}

fn cold(grid: &VoxelGrid) -> ModeBasis {
    cold_with(grid, ElementKind::Hex8Incompatible)
}

fn cold_with(grid: &VoxelGrid, kind: ElementKind) -> ModeBasis {
    ModeBasis::solve(grid, kind, NU, SolverKind::Lanczos, &options()).expect("cold solve")
}

fn frequencies(b: &ModeBasis) -> Vec<f64> {
    b.solution.eigenvalues.iter().map(|l| l.sqrt()).collect()
}

fn worst_relative(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| ((x - y) / y).abs())
        .fold(0.0, f64::max)
}

/// A solid voxel on the outer surface (largest z among the voxels at the centre column).
fn top_voxel(grid: &VoxelGrid) -> [usize; 3] {
    let d = grid.dims();
    let (x, y) = (d[0] / 2, d[1] / 2);
    let z = (0..d[2])
        .rev()
        .find(|&z| grid.get(x as isize, y as isize, z as isize));
    [x, y, z.expect("a voxel in the centre column")]
}

#[test]
fn transfer_to_the_same_mesh_is_the_identity() {
    let grid = bowl();
    let b = cold(&grid);
    let model = FemModel::assemble(&grid, ElementKind::Hex8Incompatible, NU).unwrap();
    let (offset, overlap) = warm::align(&b.model, &model);
    assert_eq!((offset, overlap), ([0; 3], grid.count()));
    let t = warm::transfer(&b.model, b.solution.vectors.as_ref(), &model, offset);
    assert_eq!((t.kept_nodes, t.new_nodes), (model.nodes(), 0));
    for j in 0..t.columns {
        for i in 0..model.dofs() {
            assert_eq!(t.block[i * t.columns + j], b.solution.vectors[(i, j)]);
        }
    }
}

#[test]
fn carried_answer_of_an_unchanged_shape_is_exact() {
    let grid = bowl();
    let b = cold(&grid);
    let r = ModeBasis::carried_ritz(&grid, ElementKind::Hex8Incompatible, NU, MODES, &b, None)
        .expect("comparable")
        .expect("carried");
    // Rayleigh-Ritz on the exact eigenvectors returns their eigenvalues (to roundoff).
    assert!(worst_relative(&frequencies(&r), &frequencies(&b)) < 1e-9);
}

/// `grid` with every voxel `by` voxels further from the corner on x and z, fills kept.
fn moved_from_corner(grid: &VoxelGrid, by: usize) -> VoxelGrid {
    let d = grid.dims();
    let mut moved =
        VoxelGrid::new([d[0] + by, d[1], d[2] + by], grid.voxel_size_m()).expect("grid");
    for [x, y, z] in grid.solid_voxels() {
        let fill = grid.fill_at(x as isize, y as isize, z as isize);
        moved.set_fill(x + by, y, z + by, fill);
    }
    moved
}

#[test]
fn alignment_follows_a_moved_origin() {
    let grid = bowl();
    let b = cold(&grid);
    // The same object one voxel further from the corner on x and z.
    let moved = moved_from_corner(&grid, 1);
    let model = FemModel::assemble(&moved, ElementKind::Hex8Incompatible, NU).unwrap();
    assert_eq!(warm::align(&b.model, &model), ([-1, 0, -1], grid.count()));
    let r = ModeBasis::carried_ritz(&moved, ElementKind::Hex8Incompatible, NU, MODES, &b, None)
        .expect("comparable")
        .expect("carried");
    assert!(worst_relative(&frequencies(&r), &frequencies(&b)) < 1e-9);
}

#[test]
fn warm_solves_of_brush_strokes_match_cold_solves() {
    // hex27x2 too: its elements are 2x2x2-voxel blocks, so a one-voxel stroke changes a cut
    // element's fill (or adds a block) instead of adding an element of its own.
    for kind in [ElementKind::Hex8Incompatible, ElementKind::Hex27Blocks] {
        let mut grid = bowl();
        let mut previous = cold_with(&grid, kind);
        let [x, y, z] = top_voxel(&grid);
        // Add a voxel on top, then remove another one beside it.
        for (at, solid) in [([x, y, z + 1], true), ([x + 1, y, z], false)] {
            let d = grid.dims();
            if at[2] >= d[2] {
                let mut bigger = VoxelGrid::new([d[0], d[1], d[2] + 1], 1.0).unwrap();
                for [a, b, c] in grid.solid_voxels() {
                    bigger.set_fill(a, b, c, grid.fill_at(a as isize, b as isize, c as isize));
                }
                grid = bigger;
            }
            grid.set(at[0], at[1], at[2], solid);
            let warm =
                ModeBasis::solve_warm(&grid, kind, NU, SolverKind::Auto, &options(), &previous)
                    .expect("warm solve");
            assert!(
                warm.solution.warm_start,
                "{kind}: a one-voxel edit is warm-started"
            );
            let reference = cold_with(&grid, kind);
            let err = worst_relative(&frequencies(&warm), &frequencies(&reference));
            eprintln!("{kind}: warm vs cold: {err:.1e}");
            assert!(err < 1e-6, "{kind}: warm vs cold: {err:.1e}");
            assert!(warm.solution.residuals.iter().all(|&r| r <= 1e-6));
            // The instant answer: close, not exact.
            let carried = ModeBasis::carried_ritz(&grid, kind, NU, MODES, &previous, None)
                .expect("comparable")
                .expect("carried");
            let err = worst_relative(&frequencies(&carried), &frequencies(&reference));
            eprintln!("{kind}: carried vs cold: {err:.1e}");
            assert!(err < 1e-3, "{kind}: carried vs cold: {err:.1e}");
            // Its residuals are not computed (NaN, as for a predicted answer: two more block
            // products for a figure nothing reads). Recomputed here from K and M, they are far
            // above the solver's tolerance (the answer is approximate) and small: the carried
            // vectors are close to the modes (measured 4.9e-5 to 1.6e-4 on these strokes).
            let sol = &carried.solution;
            assert!(sol.residuals.iter().all(|r| r.is_nan()), "{kind}");
            let explicit = Operators::new(&carried.model)
                .block_residuals(&sol.eigenvalues, sol.vectors.as_ref());
            let worst = explicit.iter().fold(0.0f64, |a, &r| a.max(r));
            eprintln!("{kind}: carried residuals at most {worst:.1e}");
            assert!(worst < 1e-3, "{kind}: carried residual {worst:e}");
            previous = warm;
        }
    }
}

#[test]
fn parts_touching_along_an_edge_keep_their_seven_rigid_modes() {
    // Two 4-voxel cubes sharing one edge: 7 rigid-body modes (6 + a hinge). The carried
    // answer and the warm solve carry the previous rigid modes instead of the six rigid fields
    // of a whole.
    let mut grid = VoxelGrid::new([8, 8, 4], 1.0).unwrap();
    for z in 0..4 {
        for y in 0..4 {
            for x in 0..4 {
                grid.set(x, y, z, true);
                grid.set(x + 4, y + 4, z, true);
            }
        }
    }
    let options = EigenOptions {
        count: ModeCount::First(20),
        ..Default::default()
    };
    let solve = |g: &VoxelGrid| {
        ModeBasis::solve(
            g,
            ElementKind::Hex8Incompatible,
            NU,
            SolverKind::Lanczos,
            &options,
        )
        .expect("cold")
    };
    let before = solve(&grid);
    assert_eq!(before.solution.rigid_modes, 7);
    assert_eq!(before.solution.rigid_vectors.ncols(), 7);
    grid.set(0, 0, 3, false);
    let reference = solve(&grid);
    let carried =
        ModeBasis::carried_ritz(&grid, ElementKind::Hex8Incompatible, NU, 20, &before, None)
            .expect("comparable")
            .expect("a carried answer");
    assert_eq!(carried.solution.rigid_modes, 7);
    let err = worst_relative(&frequencies(&carried), &frequencies(&reference));
    assert!(err < 3e-3, "carried vs cold: {err:.1e}");
    let warm = ModeBasis::solve_warm(
        &grid,
        ElementKind::Hex8Incompatible,
        NU,
        SolverKind::Auto,
        &options,
        &before,
    )
    .expect("warm");
    assert!(warm.solution.warm_start);
    let err = worst_relative(&frequencies(&warm), &frequencies(&reference));
    assert!(err < 1e-6, "warm vs cold: {err:.1e}");
}

/// A voxel on a new layer over the grid, above its top-front quarter: the interactive
/// bench's stroke on a shape that fills its box (a bar, a slat; a thin pipe, whose inside is
/// all partial voxels), every voxel below keeping its fill.
fn layer_stroke(grid: &VoxelGrid) -> VoxelGrid {
    let d = grid.dims();
    let mut out = VoxelGrid::new([d[0], d[1], d[2] + 1], grid.voxel_size_m()).expect("grid");
    for [x, y, z] in grid.solid_voxels() {
        out.set_fill(x, y, z, grid.fill_at(x as isize, y as isize, z as isize));
    }
    out.set(d[0] * 3 / 10, d[1] * 7 / 10, d[2], true);
    out
}

/// Adds the empty voxel touching the solid that lies nearest the point above the grid's
/// top-front quarter (the drag bench's stroke): repeated, a bump grows at one spot.
fn bump_stroke(grid: &VoxelGrid) -> VoxelGrid {
    let d = grid.dims();
    let target = [d[0] as f64 * 0.3, d[1] as f64 * 0.7, d[2] as f64];
    let faces = [
        (1, 0, 0),
        (-1, 0, 0),
        (0, 1, 0),
        (0, -1, 0),
        (0, 0, 1),
        (0, 0, -1),
    ];
    let mut best: Option<([usize; 3], f64)> = None;
    for x in 0..d[0] {
        for y in 0..d[1] {
            for z in 0..d[2] {
                let (xi, yi, zi) = (x as isize, y as isize, z as isize);
                let touching = faces
                    .iter()
                    .any(|(a, b, c)| grid.get(xi + a, yi + b, zi + c));
                if grid.get(xi, yi, zi) || !touching {
                    continue;
                }
                let dist = (x as f64 - target[0]).powi(2)
                    + (y as f64 - target[1]).powi(2)
                    + (z as f64 - target[2]).powi(2);
                if best.is_none_or(|b| dist < b.1) {
                    best = Some(([x, y, z], dist));
                }
            }
        }
    }
    let ([x, y, z], _) = best.expect("an empty voxel touching the object");
    let mut out = grid.clone();
    out.set(x, y, z, true);
    out
}

/// A built-in shape as the plugin's presets place it, centred on hex27x2's blocks.
fn on_blocks(p: Primitive) -> VoxelGrid {
    let per = ElementKind::Hex27Blocks.voxels_per_element();
    modalforge::shape::spec::primitive_voxels(&p, None, 1.0, per).expect("a built-in shape")
}

#[test]
fn the_patch_modes_keep_a_carried_answer_in_tune_over_several_strokes() {
    // Four strokes at one spot of the plugin's default object (hex27x2), carried from the
    // exact answer before them, against a cold solve of the result. The patch's own modes in
    // the Rayleigh-Ritz basis (`eigen::warm::correction`) hold the median frequency error to
    // 3.8e-5 (measured); without them it was 1.9e-4, so the bound 1e-4 tells the two apart.
    // The worst mode (the one the bump moves most: 7.8e-3 measured, 1.0e-2 without them) is
    // bounded at twice the status line's typical 1e-2.
    let kind = ElementKind::Hex27Blocks;
    let grid = on_blocks(Primitive::Bowl {
        diameter: 16.0,
        wall: 2.0,
    });
    let count = ModeCount::First(60);
    let solve = |g: &VoxelGrid| {
        ModeBasis::solve(
            g,
            kind,
            0.2,
            SolverKind::Auto,
            &EigenOptions {
                count,
                ..Default::default()
            },
        )
        .expect("cold solve")
    };
    let before = solve(&grid);
    let mut edited = grid.clone();
    for _ in 0..4 {
        edited = bump_stroke(&edited);
    }
    let carried = ModeBasis::carried_ritz(&edited, kind, 0.2, 60, &before, None)
        .expect("an edit of the same object")
        .expect("carried answer");
    let (c, e) = (frequencies(&carried), frequencies(&solve(&edited)));
    let mut errors: Vec<f64> = c.iter().zip(&e).map(|(x, y)| ((x - y) / y).abs()).collect();
    errors.sort_by(f64::total_cmp);
    let (median, worst) = (errors[errors.len() / 2], errors[errors.len() - 1]);
    assert!(median < 1e-4, "median {median:.1e}, worst {worst:.1e}");
    assert!(worst < 2e-2, "median {median:.1e}, worst {worst:.1e}");
}

#[test]
fn a_wide_patch_and_its_extra_modes_tune_the_carried_answer_on_small_objects() {
    // One stroke each on three presets' shapes (hex27x2, 60 modes), carried from the exact
    // answer before it, against a cold solve of the result. Where the relaxed patch two
    // blocks wide stays within 1,000 DOFs it is used (`eigen::warm`, `WIDE_PATCH_RADIUS`):
    // - the brass gong's disc, a voxel added at its rim: worst mode 1.7e-3 measured, 5.9e-3
    //   with the one-block patch; bounded at 3e-3;
    // - the wooden slat (30 x 5 x 1) with a voxel on top: its wide patch holds more of its
    //   own modes below the carried ones than the first block of 8, and the second block
    //   keeps them (`correction::patch_modes`): 9.9e-5 measured (1.3e-4 with stop 68's
    //   grown block), 6.4e-4 with 8 patch modes and 7.0e-4 with the narrow patch; bounded at
    //   3e-4;
    // - the iron pipe (Poisson's ratio 0.28), a voxel added: 9.8e-5 measured, bounded at
    //   3e-4. Its carried basis has nearly dependent columns (13 of 163 under 1e-10 of their
    //   norm outside the span of the ones before them), and a Ritz step that dropped them
    //   inside its Cholesky factorisation played modes 11 % low, spurious (`lobpcg::dense`).
    let kind = ElementKind::Hex27Blocks;
    let shape = on_blocks;
    let gong = shape(Primitive::Cylinder {
        diameter: 32.0,
        height: 1.0,
    });
    let slat = shape(Primitive::Bar {
        length: 30.0,
        width: 5.0,
        height: 1.0,
    });
    let pipe = modalforge::shape::spec::primitive_voxels(
        &Primitive::Tube {
            diameter: 4.0,
            height: 32.0,
            wall: 1.0,
        },
        None,
        1.0,
        kind.voxels_per_element(),
    )
    .expect("the iron pipe's shape");
    let options = EigenOptions {
        count: ModeCount::First(60),
        ..Default::default()
    };
    let solve = |g: &VoxelGrid, nu: f64| {
        ModeBasis::solve(g, kind, nu, SolverKind::Auto, &options).expect("cold solve")
    };
    for (name, grid, stroked, nu, bound) in [
        ("gong", &gong, bump_stroke(&gong), 0.3, 3e-3),
        ("slat", &slat, layer_stroke(&slat), 0.3, 3e-4),
        ("pipe", &pipe, layer_stroke(&pipe), 0.28, 3e-4),
    ] {
        let before = solve(grid, nu);
        let carried = ModeBasis::carried_ritz(&stroked, kind, nu, 60, &before, None)
            .expect("an edit of the same object")
            .expect("carried answer");
        let worst = worst_relative(&frequencies(&carried), &frequencies(&solve(&stroked, nu)));
        eprintln!("{name}: worst {worst:.1e}");
        assert!(worst < bound, "{name}: worst {worst:.1e}");
    }
}

#[test]
fn a_factored_carried_answer_strikes_as_the_formed_one() {
    // The engine's carried answer keeps its Ritz vectors as factors over the exact answer it
    // was carried from (`ModeBasis::carried_ritz_factored`) and forms a strike's rows on
    // demand, and reads the mesh only near the edit (the Gram columns it cannot relate from
    // the exact answer's whole ones, `warm/exact_grams.rs`); `carried_ritz` forms the vectors
    // by one dense product, and those Gram columns by whole products. Two strokes on a
    // hex27x2 cup (new nodes, the relaxed patch and its modes all in play), one on the cup
    // moved a block from the grid's corner (the fields' centre in the previous mesh's
    // positions), and one carried from the exact answer of a stroke (no mirrors: its last
    // guards unconverged, so kept too): the same eigenvalues to 1e-10 (the Grams' kept
    // columns differ by the rounding of sums in another order, 1e-11 of them measured; the
    // carried answer itself is 1e-5 to 3e-3 off), and the same forces, after the same
    // orientation, at the default hit, beside the strokes and at points all round, to 1e-8
    // of the largest (the same rounding over the closest pair's gap, 2 %).
    let kind = ElementKind::Hex27Blocks;
    let grid = on_blocks(Primitive::Cup {
        diameter: 12.0,
        height: 12.0,
        wall: 1.0,
    });
    let options = EigenOptions {
        count: ModeCount::First(30),
        ..Default::default()
    };
    let before = std::sync::Arc::new(
        ModeBasis::solve(&grid, kind, NU, SolverKind::Auto, &options).expect("cold solve"),
    );
    let moved = moved_from_corner(&grid, kind.voxels_per_element());
    for (grid, edited) in [
        (grid.clone(), bump_stroke(&bump_stroke(&grid))),
        (moved.clone(), bump_stroke(&moved)),
    ] {
        strikes_alike(&before, &grid, &edited);
    }
    let bumped = bump_stroke(&grid);
    let exact = std::sync::Arc::new(
        ModeBasis::solve(&bumped, kind, NU, SolverKind::Auto, &options).expect("exact solve"),
    );
    let guards = &exact.solution.guard_residuals;
    // (Not computed, NaN, or above the solver tolerance.)
    assert!(
        guards.iter().any(|&r| r.is_nan() || r > 1e-6),
        "unconverged guards: {guards:?}"
    );
    strikes_alike(&exact, &bumped, &bump_stroke(&bumped));
}

/// The check of [`a_factored_carried_answer_strikes_as_the_formed_one`] for one edit, `grid`
/// the shape before it in `edited`'s frame.
fn strikes_alike(before: &std::sync::Arc<ModeBasis>, grid: &VoxelGrid, edited: &VoxelGrid) {
    let kind = ElementKind::Hex27Blocks;
    let formed = ModeBasis::carried_ritz(edited, kind, NU, 30, before, None)
        .expect("an edit of the same object")
        .expect("carried answer");
    let factored = ModeBasis::carried_ritz_factored(edited, kind, NU, 30, before, None)
        .expect("an edit of the same object")
        .expect("carried answer");
    assert!(factored.is_factored() && !formed.is_factored());
    assert_eq!(factored.solution.vectors.ncols(), 0);
    assert!(
        worst_relative(&factored.solution.eigenvalues, &formed.solution.eigenvalues) <= 1e-10,
        "{:?} against {:?}",
        factored.solution.eigenvalues,
        formed.solution.eigenvalues
    );
    let d = edited.dims().map(|v| v as f64);
    let mut hits = vec![formed.default_hit(1.0)];
    // On the voxels the strokes added (each face's centre: their new nodes), and round about.
    let [dx, dy, dz] = edited.dims();
    for (x, y, z) in
        (0..dx).flat_map(|x| (0..dy).flat_map(move |y| (0..dz).map(move |z| (x, y, z))))
    {
        let (xi, yi, zi) = (x as isize, y as isize, z as isize);
        if edited.get(xi, yi, zi) && !grid.get(xi, yi, zi) {
            let centre = [x as f64 + 0.5, y as f64 + 0.5, z as f64 + 0.5];
            for axis in 0..3 {
                for side in [-0.5, 0.5] {
                    let mut point_m = centre;
                    point_m[axis] += side;
                    hits.push(modalforge::basis::Hit {
                        point_m,
                        direction: Some([0.3, -0.2, -1.0]),
                    });
                }
            }
        }
    }
    assert!(hits.len() > 1, "the strokes added voxels");
    for k in 0..12 {
        let t = k as f64 / 12.0;
        let angle = std::f64::consts::TAU * t;
        hits.push(modalforge::basis::Hit {
            point_m: [
                0.5 * d[0] * (1.0 + angle.cos()),
                0.5 * d[1] * (1.0 + angle.sin()),
                d[2] * t,
            ],
            direction: (k % 2 == 0).then_some([angle.sin(), 0.5, -angle.cos()]),
        });
    }
    let n = formed.mode_count();
    for hit in &hits {
        let (mut a, mut b) = (vec![0.0; n], vec![0.0; n]);
        formed.reference_forces_into(hit, 1.0, &mut a).unwrap();
        factored.reference_forces_into(hit, 1.0, &mut b).unwrap();
        let scale = a.iter().fold(0.0f64, |m, f| m.max(f.abs()));
        assert!(scale > 0.0);
        for (x, y) in a.iter().zip(&b) {
            assert!((x - y).abs() <= 1e-8 * scale, "{hit:?}: {a:?} vs {b:?}");
        }
    }
}

#[test]
fn the_wide_reach_keeps_a_drag_on_a_thin_wall_in_tune() {
    // Four strokes at one spot of the glass vase preset's shape (a one-voxel wall, hex27x2,
    // 60 modes), carried from the exact answer before them as a drag carries every stroke,
    // against a cold solve of the result. The instant answer keeps to the narrow patch for
    // its size and says a wider one exists (`ModeBasis::carried_widens`); the second answer
    // relaxes the wide patch with its patch modes grown (`eigen::warm::Reach::Wide`).
    // Measured: the instant answer's worst mode 2.0e-2, the wide one's 2.2e-3 (as in stop 73's
    // harness, ARCHITECTURE.md). The wide answer's bound, 6e-3, lies between them, so the
    // test tells the reaches apart; the instant one is held to twice its measured error.
    let kind = ElementKind::Hex27Blocks;
    let grid = on_blocks(Primitive::Cup {
        diameter: 16.0,
        height: 24.0,
        wall: 1.0,
    });
    let nu = 0.22;
    let options = EigenOptions {
        count: ModeCount::First(60),
        ..Default::default()
    };
    let solve = |g: &VoxelGrid| {
        ModeBasis::solve(g, kind, nu, SolverKind::Auto, &options).expect("cold solve")
    };
    let before = std::sync::Arc::new(solve(&grid));
    let mut edited = grid.clone();
    for _ in 0..4 {
        edited = bump_stroke(&edited);
    }
    let instant = ModeBasis::carried_ritz_factored(&edited, kind, nu, 60, &before, None)
        .expect("an edit of the same object")
        .expect("instant answer");
    assert!(
        instant.carried_widens(),
        "a wider patch than the instant answer's"
    );
    let wide = ModeBasis::carried_ritz_wide(
        &edited,
        kind,
        nu,
        60,
        &before,
        None,
        modalforge::eigen::Stop::NEVER,
    )
    .expect("an edit of the same object")
    .expect("wide answer");
    assert!(!wide.carried_widens());
    let exact = frequencies(&solve(&edited));
    let (narrow_err, wide_err) = (
        worst_relative(&frequencies(&instant), &exact),
        worst_relative(&frequencies(&wide), &exact),
    );
    eprintln!("instant {narrow_err:.1e}, wide {wide_err:.1e}");
    assert!(
        wide_err < 6e-3,
        "instant {narrow_err:.1e}, wide {wide_err:.1e}"
    );
    assert!(narrow_err < 4e-2, "instant {narrow_err:.1e}");
}
