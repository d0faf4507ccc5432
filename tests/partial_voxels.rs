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
    // Kinds with one element per voxel (hex27x2's blocks: the next test).
    for kind in ElementKind::ALL
        .into_iter()
        .filter(|k| k.voxels_per_element() == 1)
    {
        let model = FemModel::assemble(&grid, kind, NU).unwrap();
        let unit = UnitElement::new(kind, NU);
        let mut k = vec![[0.0; 9]; model.pattern.col.len()];
        let mut m = vec![0.0; model.pattern.col.len()];
        let unit_matrices = (&unit.stiffness[..], &unit.mass[..]);
        sparse::add_elements(
            &model.pattern,
            &model.elements,
            kind.nodes(),
            |_| unit_matrices,
            &mut k,
            &mut m,
        );
        assert!(model.k()[..] == k[..] && model.m()[..] == m[..], "{kind:?}");
    }
}

#[test]
fn partial_grids_assemble_each_cut_element_as_integrated_alone() {
    // The assembly of a curved bowl shares one integration among the cut elements whose
    // fills are images of each other under a cube symmetry (`fem::cut::symmetry`), finds
    // each element's blocks from its nodes' lattice offsets (`sparse::LatticeRows`) and
    // batches the integrations. The independent truth: every element integrated on its own
    // (`CutElement::matrices` on its sub-cell fill, the unit element on a full voxel) and
    // scattered by the searched pattern. Equal to rounding, 1e-13 of the largest entry (a
    // mapped element is the integration of its orbit's first, rotated: sums in another order).
    let grid = primitive("bowl:d=12,wall=2").rasterize(1.0, 1.0).unwrap();
    assert!(!grid.is_binary());
    for kind in [ElementKind::Hex8Incompatible, ElementKind::Hex8] {
        let model = FemModel::assemble(&grid, kind, NU).unwrap();
        let nloc = kind.nodes();
        let pattern = sparse::BlockPattern::from_elements(model.nodes(), &model.elements, nloc);
        assert_eq!(model.pattern.row_ptr, pattern.row_ptr, "{kind:?}");
        assert_eq!(model.pattern.col, pattern.col, "{kind:?}");
        let per_axis = modalforge::fem::cut::subcells_per_axis(kind);
        let cut = modalforge::fem::cut::CutElement::new(kind, NU, per_axis);
        let unit = UnitElement::new(kind, NU);
        let n = 3 * nloc;
        let (mut ke, mut me) = (vec![0.0; n * n], vec![0.0; n * n]);
        let mut fill = vec![0.0; per_axis.pow(3)];
        let mut scratch = cut.scratch();
        let mut k = vec![[0.0; 9]; pattern.col.len()];
        let mut m = vec![0.0; pattern.col.len()];
        let mut slots = vec![0; nloc * nloc];
        let mut cut_elements = 0;
        for (e, v) in model.voxels.iter().enumerate() {
            let nodes = &model.elements[e * nloc..(e + 1) * nloc];
            match grid.subcell_fill(grid.index(v[0], v[1], v[2])) {
                Some(sub) => {
                    sub.coarsened_into(&mut fill);
                    cut.matrices(&fill, &mut ke, &mut me, &mut scratch);
                    sparse::add_element(&pattern, nodes, &ke, &me, &mut k, &mut m, &mut slots);
                    cut_elements += 1;
                }
                None => sparse::add_element(
                    &pattern,
                    nodes,
                    &unit.stiffness,
                    &unit.mass,
                    &mut k,
                    &mut m,
                    &mut slots,
                ),
            }
        }
        assert!(cut_elements > 100, "{cut_elements} cut elements");
        let scale = k.iter().flatten().fold(0.0f64, |s, v| s.max(v.abs()));
        let dk = model
            .k()
            .iter()
            .flatten()
            .zip(k.iter().flatten())
            .fold(0.0f64, |d, (a, b)| d.max((a - b).abs()));
        assert!(dk < 1e-13 * scale, "{kind:?}: K off by {dk} of {scale}");
        let scale = m.iter().fold(0.0f64, |s, v| s.max(v.abs()));
        let dm = model
            .m()
            .iter()
            .zip(&m)
            .fold(0.0f64, |d, (a, b)| d.max((a - b).abs()));
        assert!(dm < 1e-13 * scale, "{kind:?}: M off by {dm} of {scale}");
    }
}

#[test]
fn hex27x2_is_hex27_on_the_grid_of_blocks() {
    // A block of 2^3 full voxels is one hex27 element of edge 2: in voxel reference units its
    // stiffness is twice and its mass eight times the unit element's (K = E h K_ref, M = rho
    // h^3 M_ref), exactly (powers of two). So a binary grid of full blocks assembles to hex27 on
    // the grid of blocks, times 2 and 8, bit for bit.
    let fine =
        VoxelGrid::from_fn([6, 4, 8], 1.0, |x, y, z| x >= 2.0 || (y >= 2.0 && z < 4.0)).unwrap();
    let coarse =
        VoxelGrid::from_fn([3, 2, 4], 2.0, |x, y, z| x >= 1.0 || (y >= 1.0 && z < 2.0)).unwrap();
    let blocks = FemModel::assemble(&fine, ElementKind::Hex27Blocks, NU).unwrap();
    let hex27 = FemModel::assemble(&coarse, ElementKind::Hex27, NU).unwrap();
    assert_eq!(blocks.dofs(), hex27.dofs());
    assert_eq!(blocks.voxels, hex27.voxels);
    assert_eq!(
        (blocks.grid_dims(), blocks.cell_dims()),
        ([6, 4, 8], [3, 2, 4])
    );
    let twice: Vec<_> = hex27.k().iter().map(|b| b.map(|v| 2.0 * v)).collect();
    let eight: Vec<_> = hex27.m().iter().map(|v| 8.0 * v).collect();
    assert!(blocks.k()[..] == twice[..] && blocks.m()[..] == eight[..]);
    // Node positions in voxels: the block's far corner is 2 voxels out.
    let far = (0..blocks.nodes())
        .map(|n| blocks.node_position(n))
        .fold([0.0f64; 3], |m, p| [0, 1, 2].map(|a| m[a].max(p[a])));
    assert_eq!(far, [6.0, 4.0, 8.0]);

    // A block whose lower voxel layer is full and upper one empty is hex27 over a coarse voxel
    // whose lower half of sub-cells is full: the same integral, summed over 8 sub-cells per
    // axis instead of 4 (rounding only: 1e-12 of the largest entry).
    let fine = VoxelGrid::from_fn([4, 4, 2], 1.0, |_, _, z| z < 1.0).unwrap();
    let mut coarse = VoxelGrid::new([2, 2, 1], 2.0).unwrap();
    let n = modalforge::shape::fill::SUBCELLS_PER_AXIS;
    let half = std::array::from_fn(|i| if i / (n * n) < n / 2 { 1.0 } else { 0.0 });
    for (x, y) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
        let fill = modalforge::shape::SubFill::from_fractions(half);
        coarse.set_fill(x, y, 0, modalforge::shape::VoxelFill::Partial(fill));
    }
    let blocks = FemModel::assemble(&fine, ElementKind::Hex27Blocks, NU).unwrap();
    let hex27 = FemModel::assemble(&coarse, ElementKind::Hex27, NU).unwrap();
    let scale = hex27
        .k()
        .iter()
        .flatten()
        .fold(0.0f64, |m, v| m.max(v.abs()));
    for (a, b) in blocks.k().iter().flatten().zip(hex27.k().iter().flatten()) {
        assert!((a - 2.0 * b).abs() < 1e-12 * 2.0 * scale, "{a} vs 2 x {b}");
    }
    let scale = hex27.m().iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for (a, b) in blocks.m().iter().zip(hex27.m()) {
        assert!((a - 8.0 * b).abs() < 1e-12 * 8.0 * scale, "{a} vs 8 x {b}");
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
    // smooth reference, the lowest pair split under 0.5 %. Measured: hex27 +0.33 % worst, split
    // 0.014 % (8^3 refined sub-cells; 4^3 gave +1.15 % and 0.13 %). The default element (hex8i) is reported beside it and held to its measured
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

#[test]
fn hex27x2_rings_every_curved_primitive_true() {
    // Quadratic elements on 2x2x2-voxel blocks, integrated over the voxels' fills refined to
    // 8^3 sub-cells (shape::refine), against the smooth solids. The bounds: every
    // degenerate group among the lowest 12 modes within 0.5 % on the 16-voxel bowl and 0.2 %
    // on every other shape (measured 0.15 % and 0.011-0.14 %); the bowl's lowest 10
    // frequencies within 2 % at 16 voxels and 1 % at 32 (measured +1.71 % and +0.98 %: the
    // margin on the 32-voxel bowl is thin, and the computation deterministic). The other thin
    // walls within 2.5 % (cup +1.99 %, tube +1.31 %, bell +0.58 %; the tube's and cup's
    // references are converged to about 1 % only, scripts/smooth_reference.py), solids within
    // 0.2 % (measured 0.05-0.08 %). hex8i is 8-11 % sharp on the thin walls.
    for spec in common::smooth::specs() {
        let want = reference(&spec);
        let grid = primitive(&spec).rasterize(1.0, 1.0).unwrap();
        let got = eigenvalues(&grid, ElementKind::Hex27Blocks, 16);
        let errors = frequency_errors(&got, &want, 10);
        let (split, groups) = worst_split(&got, &want, 12);
        eprintln!(
            "{spec}: hex27x2 worst {:.2} %, split {split:.3} % ({groups} groups)",
            worst(&errors)
        );
        assert!(groups >= 1, "{spec}: the reference has degenerate groups");
        let split_bound = if spec == "bowl:d=16,wall=2" { 0.5 } else { 0.2 };
        assert!(split < split_bound, "{spec}: split {split:.3} %");
        let bound = match spec.as_str() {
            "bowl:d=16,wall=2" => 2.0,
            "bowl:d=32,wall=2" => 1.0,
            s if s.starts_with("sphere") || s.starts_with("cylinder") => 0.2,
            _ => 2.5,
        };
        assert!(worst(&errors) < bound, "{spec}: {errors:?}");
    }
}

/// A square bar rasterised for hex27x2 the plugin's way (`primitive_voxels`: its 3-voxel
/// sides padded to the 2-voxel blocks, half-filled face voxels, the bar centred) against an
/// independent truth, Saint-Venant's free-free torsion: `omega_1 = (pi / L) sqrt(G J / (rho
/// I_p))`, `J = 0.140577 a^4` for a square section, `I_p = a^4 / 6`. Its fifth elastic mode
/// (after two pairs of bending modes) is within 0.73 % of it; the plain rasterisation (one
/// full block and one half-full across each side, not mirror-symmetric) was 1.31 % stiff,
/// so the 1 % bound tells the two apart. The bending pairs are exact pairs on the centred
/// mesh (the swap of its section's axes and both mirrors hold; 1e-9 is the solver's
/// tolerance), where the plain one split them by 0.07-0.1 %.
#[test]
fn a_bar_centred_on_the_blocks_twists_at_saint_venant_s_frequency() {
    let (length, side) = (30.0, 3.0);
    let bar = Primitive::Bar {
        length,
        width: side,
        height: side,
    };
    let kind = ElementKind::Hex27Blocks;
    let grid =
        modalforge::shape::spec::primitive_voxels(&bar, None, 1.0, kind.voxels_per_element())
            .expect("grid");
    assert_eq!(grid.dims(), [30, 4, 4]);
    let values = eigenvalues(&grid, kind, 6);
    let omega: Vec<f64> = values.iter().map(|l| l.sqrt()).collect();
    for pair in [0, 2] {
        let (a, b) = (omega[pair], omega[pair + 1]);
        assert!((a - b).abs() <= 1e-9 * a, "bending pair {pair}: {a} {b}");
    }
    let shear_modulus = 1.0 / (2.0 * (1.0 + NU));
    let torsion = std::f64::consts::PI / length * (shear_modulus * 0.140577 * 6.0).sqrt();
    let error = omega[4] / torsion - 1.0;
    assert!(
        error.abs() <= 0.01,
        "torsion {} against {torsion}: {error:+e}",
        omega[4]
    );
}
