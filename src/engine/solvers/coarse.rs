//! The progressive first answer's numerics: when to give one, the object at half the
//! resolution, and what to expect of it.
//!
//! Where it sits: [`super::CoarseFemSolver`] (the chain's first answer to a slow new object,
//! issue 13) asks [`predicted_cold_ms`] whether the exact solve would take longer than
//! [`PROGRESSIVE_BUDGET_MS`], solves [`coarse_grid`] through [`solve_coarse`] (which divides out
//! the half-resolution model's known stiffening, [`coarse_stiffening`]) and shows
//! [`coarse_expected_error`] on the status line. The bench (`cargo bench --bench
//! interactive`, the coarse column) and `engine/tests/coarse.rs` call the same functions.

use crate::basis::{BasisError, ModeBasis};
use crate::eigen::{EigenOptions, ModeCount, SolverKind, Stop};
use crate::fem::{ElementCache, ElementKind};
use crate::shape::fill::{fill_of, FULL, SUBCELLS, SUBCELLS_PER_AXIS};
use crate::shape::{lattice_coords, lattice_index, ops, VoxelFill, VoxelGrid};

/// An exact solve predicted to take longer than this (ms) gets a coarse answer first.
pub const PROGRESSIVE_BUDGET_MS: f64 = 100.0;

/// Predicted one-core time of a cold exact solve of an object without mirrors, ms per DOF
/// per wanted pair (modes plus six rigid): the default bowl solved whole (hex27x2, 60 modes,
/// as a stroke off its planes leaves it) takes 0.72e-3 ([`predicted_cold_ms`] divides by
/// [`MIRROR_SPEEDUP`] for mirrored ones); an estimate for scheduling, not a promise.
const COLD_MS_PER_DOF_PAIR: f64 = 0.7e-3;

/// How much faster a cold solve is with 0, 1, 2 or 3 mirror planes (solved by symmetry
/// classes, `eigen/symmetric.rs`). Measured side by side with whole solves (hex27x2, 60
/// modes): two mirrors (and the bowls' axis swap) 2.8-3.4x (the bell, the default bowl),
/// three 6.5x (a 16-voxel sphere); but 4 fits the cold times of the three-mirror presets and
/// the 24^3 sphere (`cargo bench --bench interactive`, stop 59: within 0.8-1.3x of the
/// estimate), whose classes are smaller and pay more overhead each. One mirror between.
const MIRROR_SPEEDUP: [f64; 4] = [1.0, 1.7, 3.0, 4.0];

/// Predicted cold solve time of `grid` (ms, one core) for `count` modes with `element`:
/// DOFs estimated from the voxel count, the mirrors from the fills ([`grid_mirrors`]).
/// Against `cargo bench --bench interactive` on the presets (stop 59): the tin can, the
/// glass bowl and vase, the ceramic cup and the bell (0.11-0.36 s cold) are predicted over
/// 100 ms (115-345 ms); the ones solved under 100 ms at 29-75 ms.
pub fn predicted_cold_ms(grid: &VoxelGrid, element: ElementKind, count: ModeCount) -> f64 {
    // Nodes of a voxel object: about the voxel count plus its surface layer.
    let voxels = grid.count() as f64;
    let dofs = 3.0 * (voxels + 2.0 * voxels.powf(2.0 / 3.0) + voxels / 2.0);
    let pairs = match count {
        ModeCount::First(k) => k as f64 + 6.0,
        ModeCount::Below(_) => 66.0,
    };
    COLD_MS_PER_DOF_PAIR * dofs * pairs / MIRROR_SPEEDUP[grid_mirrors(grid, element)]
}

/// How many of the three axes `grid` is mirror-symmetric along, fill for fill (a partial
/// voxel's sub-cells mirrored too), about the centre of its solid voxels' bounding box, with
/// `element`'s blocks mapped onto blocks (hex27x2's start at the grid's origin, so the box's
/// first and last voxel indices must add up to an odd number). The eigensolver finds its
/// mirrors on the assembled matrices (`eigen/symmetric.rs`); this is the cheap look at the
/// voxels that the time estimate needs before any assembly.
pub fn grid_mirrors(grid: &VoxelGrid, element: ElementKind) -> usize {
    let solid = grid.solid_voxels();
    if solid.is_empty() {
        return 0;
    }
    let lo: [usize; 3] = std::array::from_fn(|a| solid.iter().map(|v| v[a]).min().unwrap_or(0));
    let hi: [usize; 3] = std::array::from_fn(|a| solid.iter().map(|v| v[a]).max().unwrap_or(0));
    let block = element.voxels_per_element();
    let sub = [SUBCELLS_PER_AXIS; 3];
    (0..3)
        .filter(|&a| {
            if block > 1 && (lo[a] + hi[a]) % block != block - 1 {
                return false;
            }
            solid.iter().all(|v| {
                let mut m = *v;
                m[a] = lo[a] + hi[a] - v[a];
                let at = |c: [usize; 3]| grid.fill_at(c[0] as isize, c[1] as isize, c[2] as isize);
                match (at(*v), at(m)) {
                    (VoxelFill::Partial(f), VoxelFill::Partial(g)) => (0..SUBCELLS).all(|i| {
                        let mut s = lattice_coords(i, sub);
                        s[a] = sub[a] - 1 - s[a];
                        f.0[i] == g.0[lattice_index(s, sub)]
                    }),
                    (f, g) => f == g,
                }
            })
        })
        .count()
}

/// The coarse answer's expected error on objects whose walls are thicker than
/// [`THIN_WALL_VOXELS`], for the status line ([`coarse_expected_error`]): the 90th percentile
/// over objects of the mean relative error of the lowest 10 frequencies (after
/// [`coarse_stiffening`] is divided out). Measured on the 31 of 60 random primitives (that the
/// stiffening law was not fitted on; a temporary harness, hex27x2) whose mean wall is over
/// [`THIN_WALL_VOXELS`]: 4.0 %, mean 2.7 %, the worst a small hollow box with two-voxel walls
/// 11 % (8.0 %, 3.9 % and 13 % before the correction); a 24^3 sphere 0.0 %.
pub const COARSE_EXPECTED_ERROR: f64 = 0.04;

/// [`COARSE_EXPECTED_ERROR`] for walls at most [`THIN_WALL_VOXELS`] thick. The same
/// measurement, the other 29 (one-voxel walls and a few of 1.5 voxels): 6.9 %, mean 3.5 %, the
/// worst an 8-voxel tube 11 % (16.3 %, 11.1 % and 21 % before the correction, when the status
/// line said 15 %).
pub const COARSE_THIN_EXPECTED_ERROR: f64 = 0.07;

/// Mean wall thickness ([`mean_wall_voxels`]) at or under which [`coarse_expected_error`]
/// says [`COARSE_THIN_EXPECTED_ERROR`]: the one-voxel walls of the presets measure 0.78-1.0,
/// the two-voxel curved ones 1.2-1.3.
pub const THIN_WALL_VOXELS: f64 = 1.1;

/// The coarse answer's expected error for `grid` (see [`COARSE_EXPECTED_ERROR`]).
pub fn coarse_expected_error(grid: &VoxelGrid) -> f64 {
    expected_error_of_wall(mean_wall_voxels(grid))
}

fn expected_error_of_wall(wall_voxels: f64) -> f64 {
    if wall_voxels <= THIN_WALL_VOXELS {
        COARSE_THIN_EXPECTED_ERROR
    } else {
        COARSE_EXPECTED_ERROR
    }
}

/// The constant `c` of [`coarse_stiffening`]'s law, fitted (least mean absolute error of the
/// lowest 10 frequencies) on 60 random primitives (bowls, cups, tubes, bells, plates, discs
/// and hollow boxes, 8-32 voxels, walls of 1, 1.5, 2 and 3 voxels, Poisson's ratios 0.2-0.4; a
/// temporary harness solving each at both resolutions, hex27x2): with it their mean error went
/// from 8.0 % to 3.1 %, and on 60 others drawn the same way from 7.4 % to 3.1 % (median 7.0 %
/// to 2.4 %). A free exponent instead of the square fitted 1.9, no better on the others.
const COARSE_STIFFENING_CONSTANT: f64 = 0.09;

/// Width of a coarse element in fine voxels (hex27x2 on the half-resolution grid): a wall this
/// thick fills the element and does not stiffen.
const COARSE_ELEMENT_VOXELS: f64 = 4.0;

/// How much higher the half-resolution model ([`coarse_grid`]) rings than the object itself:
/// `1 + c (1 / t^2 - 1 / h^2)` for a mean wall `t` voxels thick ([`mean_wall_voxels`], at least
/// half a voxel) in coarse elements `h` = [`COARSE_ELEMENT_VOXELS`] wide, and 1 for walls
/// thicker than `h` (solids); `c` = [`COARSE_STIFFENING_CONSTANT`].
///
/// A coarse element spans four one-voxel walls' thickness, and its quadratic field bends a
/// thin wall stiffly: the spurious stiffness of a thin wall in displacement elements `h` wide
/// grows as `(h / t)^2` against its bending stiffness (shear locking: a Timoshenko beam
/// element's shear stiffness over its bending stiffness goes as `(h / t)^2`), hence the law's
/// form. Measured (120 random primitives), the lowest 10 coarse frequencies of one-voxel
/// walls came out 8-24 % high on average (flat plates and discs 8-10 %, curved shells 10-21 %,
/// hollow boxes 12-24 %), two-voxel walls 1-5 % (hollow boxes 5-13 %), a 24^3 solid sphere
/// within 0.1 %: systematic, so
/// [`solve_coarse`] divides it out. What is left is the spread between shapes and between
/// modes (a shell's stretching modes stiffen less than its bending ones), which
/// [`coarse_expected_error`] states.
pub fn coarse_stiffening(grid: &VoxelGrid) -> f64 {
    stiffening_of_wall(mean_wall_voxels(grid))
}

fn stiffening_of_wall(wall_voxels: f64) -> f64 {
    let wall_voxels = wall_voxels.max(0.5);
    let locking =
        1.0 / (wall_voxels * wall_voxels) - 1.0 / (COARSE_ELEMENT_VOXELS * COARSE_ELEMENT_VOXELS);
    1.0 + COARSE_STIFFENING_CONSTANT * locking.max(0.0)
}

/// The progressive first answer for `grid`: [`coarse_grid`] solved, its frequencies divided by
/// [`coarse_stiffening`] (its eigenvalues by the square; the mode shapes and residuals are the
/// coarse model's). `elements` caches the coarse model's cut elements like an exact solve's;
/// `stop` interrupts it between steps ([`ModeBasis::solve_cached`]).
///
/// # Errors
/// [`BasisError::NoCoarseGrid`] where [`coarse_grid`] gives none; the solve's own errors.
pub fn solve_coarse(
    grid: &VoxelGrid,
    element: ElementKind,
    poisson_ratio: f64,
    solver: SolverKind,
    options: &EigenOptions,
    elements: Option<&mut ElementCache>,
    stop: Stop,
) -> Result<ModeBasis, BasisError> {
    let coarse = coarse_grid(grid).ok_or(BasisError::NoCoarseGrid)?;
    solve_coarse_grid(
        &coarse,
        coarse_stiffening(grid),
        element,
        poisson_ratio,
        solver,
        options,
        elements,
        stop,
    )
}

/// What the coarse answer needs of an object, found once ([`super::CoarseFemSolver`] keeps it
/// from `applies` to `solve`): the object, its [`coarse_grid`], its [`coarse_stiffening`] and
/// its [`coarse_expected_error`] (the last two from one wall-thickness scan).
pub(super) struct CoarsePlan {
    /// The object (to tell whether a request is the one planned for).
    pub fine: VoxelGrid,
    /// The object at half the resolution.
    pub coarse: VoxelGrid,
    /// [`coarse_stiffening`] of `fine`.
    pub stiffening: f64,
    /// [`coarse_expected_error`] of `fine`.
    pub expected_error: f64,
}

impl CoarsePlan {
    /// `None` where [`coarse_grid`] gives none.
    pub fn new(grid: &VoxelGrid) -> Option<Self> {
        let coarse = coarse_grid(grid)?;
        let wall_voxels = mean_wall_voxels(grid);
        Some(Self {
            fine: grid.clone(),
            coarse,
            stiffening: stiffening_of_wall(wall_voxels),
            expected_error: expected_error_of_wall(wall_voxels),
        })
    }
}

/// [`solve_coarse`] of a grid already halved (`coarse`), its frequencies divided by
/// `stiffening` (the fine grid's [`coarse_stiffening`]).
#[allow(clippy::too_many_arguments)]
pub(super) fn solve_coarse_grid(
    coarse: &VoxelGrid,
    stiffening: f64,
    element: ElementKind,
    poisson_ratio: f64,
    solver: SolverKind,
    options: &EigenOptions,
    elements: Option<&mut ElementCache>,
    stop: Stop,
) -> Result<ModeBasis, BasisError> {
    let mut basis = ModeBasis::solve_cached(
        coarse,
        element,
        poisson_ratio,
        solver,
        options,
        elements,
        stop,
    )?;
    let eigenvalue_ratio = stiffening * stiffening;
    for lambda in &mut basis.solution.eigenvalues {
        *lambda /= eigenvalue_ratio;
    }
    Ok(basis)
}

pub use crate::shape::ops::mean_wall_voxels;

/// `grid` resampled to half the resolution (the voxel edge doubles, the extent stays), its
/// fills kept: each coarse voxel's sub-cells ([`SUBCELLS_PER_AXIS`] a side) hold the mean of
/// the `2^3` fine sub-cells they cover, summed in integers so that mirror-image voxels get
/// the same bytes (and the coarse model keeps the object's mirrors). The geometry is the
/// fine grid's at half the sub-cell resolution, so a wall one voxel thick stays one voxel
/// thick (half of a coarse voxel), where thresholding whole voxels would make it two or
/// nothing. `None` where the coarse grid would join parts the fine one keeps apart (its
/// face-connected components, counted on the voxels, differ: the answer would have the wrong
/// rigid-body modes) or is empty.
pub fn coarse_grid(grid: &VoxelGrid) -> Option<VoxelGrid> {
    let d = grid.dims();
    let cd = d.map(|v| v.div_ceil(2));
    let sub = [SUBCELLS_PER_AXIS; 3];
    let mut coarse = VoxelGrid::new(cd, 2.0 * grid.voxel_size_m()).ok()?;
    for c in (0..cd.iter().product()).map(|i| lattice_coords(i, cd)) {
        // Sums of the covered fine sub-cells' bytes (a full voxel's are FULL).
        let mut sums = [0u32; SUBCELLS];
        for o in 0..8 {
            let off = lattice_coords(o, [2; 3]);
            let [x, y, z] = std::array::from_fn(|a| (2 * c[a] + off[a]) as isize);
            let bytes = match grid.fill_at(x, y, z) {
                VoxelFill::Empty => continue,
                VoxelFill::Full => [FULL; SUBCELLS],
                VoxelFill::Partial(f) => f.0,
            };
            for (i, &b) in bytes.iter().enumerate() {
                let s = lattice_coords(i, sub);
                let coarse_cell = std::array::from_fn(|a| (off[a] * sub[a] + s[a]) / 2);
                sums[lattice_index(coarse_cell, sub)] += u32::from(b);
            }
        }
        let fill = fill_of(sums.map(|v| f64::from(v) / (8.0 * f64::from(FULL))));
        coarse.set_fill(c[0], c[1], c[2], fill);
    }
    (coarse.count() > 0 && ops::components(&coarse).1 == ops::components(grid).1).then_some(coarse)
}
