//! Finite-element discretisation of a voxel object: linear elasticity, free-free, consistent mass.
//!
//! Where it sits: between the shape ([`crate::shape`]) and the eigensolvers ([`crate::eigen`]).
//! [`FemModel::assemble`] numbers the nodes of the occupied voxels, and sums the single unit-cube
//! element matrix ([`element`]) over all full voxels, and a cut element ([`cut`], the finite
//! cell method) over the partial ones, into node-blocked sparse `K` and `M` ([`sparse`]). The
//! model is assembled in *reference units* (`E = 1`, `rho = 1`, voxel edge `h = 1`): physical
//! matrices are `E h K` and `rho h^3 M`, so the eigenvalues of a physical object are
//! `E / (rho h^2)` times the reference ones and its mass-normalised modes are `(rho h^3)^(-1/2)`
//! times the reference ones (the exact form of Deep-Modal's scaling laws, Jin et al. 2020, eq.
//! 10-12; [`crate::basis`] applies them).

mod assembly;
pub mod cache;
pub mod cut;
pub mod element;
pub mod memo;
pub mod ordering;
pub mod sparse;

use crate::shape::lattice_coords;
pub use assembly::element_cells;
pub use cache::ElementCache;
pub use element::{ElementKind, UnitElement};
use sparse::{BlockPattern, Blocks};

use crate::shape::{ShapeError, VoxelGrid};

/// An assembled free-free FEM model in reference units.
#[derive(Clone, Debug)]
pub struct FemModel {
    /// Element kind.
    pub kind: ElementKind,
    /// Poisson's ratio.
    pub poisson_ratio: f64,
    /// Voxels along x, y, z of the grid the model was assembled from.
    pub voxel_dims: [usize; 3],
    /// Lattice dimensions (`p n + 1` per axis, `n` elements along it).
    pub lattice: [usize; 3],
    /// Lattice index of each model node.
    pub node_lattice: Vec<usize>,
    /// Lattice index -> node number (`u32::MAX` where unused).
    pub lattice_node: Vec<u32>,
    /// Local-to-global node numbers, `kind.nodes()` per element (one element per solid voxel,
    /// or per block of them, in the grid's storage order).
    pub elements: Vec<u32>,
    /// The elements' cells: the solid voxels, or for [`ElementKind::Hex27Blocks`] the blocks
    /// (in block coordinates, [`FemModel::cell_dims`]), in element order.
    pub voxels: Vec<[usize; 3]>,
    /// A fingerprint of each element's voxel fills: what a stroke that refills a partial voxel,
    /// or (for [`ElementKind::Hex27Blocks`]) changes a voxel inside a block, changes without
    /// changing the cells ([`crate::eigen::warm`] finds the edit by it).
    pub cell_fills: Vec<u64>,
    /// Block sparsity shared by `K` and `M`.
    pub pattern: BlockPattern,
    /// Stiffness blocks ([`FemModel::k`]).
    k: Blocks,
    /// Mass, one scalar per block (every block is `m_ab I3`, [`sparse::MassBlocks`];
    /// [`FemModel::m`]).
    m: sparse::MassBlocks,
    /// `None` for a whole model; for the model of a stroke's carried answer
    /// ([`FemModel::assemble_near_edit`]), which rows of `k` and `m` it holds.
    near_edit: Option<NearEdit>,
    /// `trace K` and `trace M` ([`FemModel::traces`]): summed on the first call for a whole
    /// model, set by the assembly for a model near an edit.
    traces: std::sync::OnceLock<[f64; 2]>,
}

/// What a model assembled only near an edit holds ([`FemModel::assemble_near_edit`]): the
/// rows of its nodes within a few cells of the edit.
#[derive(Clone, Debug)]
pub(crate) struct NearEdit {
    /// Per node: whether its rows of `K` and `M` are held (the others are unspecified).
    pub held: Vec<bool>,
}

/// `K` and `M` go back to the process's kept buffers ([`crate::buffer`]): a sculpting session
/// assembles a model per stroke, and the next one's matrices then reuse mapped pages instead
/// of faulting in fresh ones (the kernel zeroing those was 13 % of the ceramic cup's carried
/// answer, stop 70).
impl Drop for FemModel {
    fn drop(&mut self) {
        crate::buffer::recycle(std::mem::take(&mut self.k));
        crate::buffer::recycle(std::mem::take(&mut self.m));
    }
}

impl FemModel {
    /// Assembles `K` and `M` for every solid voxel of `grid`: one element per voxel, or for
    /// [`ElementKind::Hex27Blocks`] one per block of `2^3` voxels (a block holding any solid
    /// voxel is an element), integrated over the voxels' fills sub-cell by sub-cell (a block
    /// with an empty or partial voxel is a cut element of `2 * subcells_per_axis(kind)`
    /// sub-cells per axis). The matrices are in voxel reference units either way: a block's
    /// are its own unit-edge matrices times `b` (stiffness) and `b^3` (mass), `b` voxels a side.
    pub fn assemble(
        grid: &VoxelGrid,
        kind: ElementKind,
        poisson_ratio: f64,
    ) -> Result<Self, ShapeError> {
        Self::assemble_cached(grid, kind, poisson_ratio, None)
    }

    /// [`FemModel::assemble`], taking the matrices of cut elements whose fills it has seen
    /// from `cache` and storing the ones it integrates there ([`cache`]): the same model, to
    /// rounding, in a fraction of the time when `grid` is an edit of a recently assembled one.
    pub fn assemble_cached(
        grid: &VoxelGrid,
        kind: ElementKind,
        poisson_ratio: f64,
        cache: Option<&mut ElementCache>,
    ) -> Result<Self, ShapeError> {
        Self::assemble_with(grid, kind, poisson_ratio, cache, true, None)
    }

    /// [`FemModel::assemble_cached`] for `grid` after an edit of the grid `previous` was
    /// assembled from (same element kind, Poisson's ratio and grid size): rows of `K` and `M`
    /// that no changed element reaches are copied from `previous`, the others summed as
    /// [`FemModel::assemble_cached`] sums them (each entry is the same sum in the same
    /// order, so with the same cache the model is the same to the bit where `previous` was
    /// assembled with every element cached). Elements within one cell of a changed one count
    /// as changed (a refined fill reads its neighbours'). Anything else (another size or
    /// integrand, or more than a few cells changed) is assembled in full. What a brush
    /// stroke's carried answer assembles ([`crate::basis::ModeBasis::carried_ritz`]).
    pub fn assemble_after_edit(
        grid: &VoxelGrid,
        kind: ElementKind,
        poisson_ratio: f64,
        previous: &FemModel,
        cache: Option<&mut ElementCache>,
    ) -> Result<Self, ShapeError> {
        let after = assembly::After {
            previous,
            held_radius: None,
        };
        Self::assemble_with(grid, kind, poisson_ratio, cache, true, Some(after))
    }

    /// [`FemModel::assemble_after_edit`] holding only the rows of `K` and `M` of the nodes
    /// within `radius_cells` element cells of the edit (and the whole matrices' traces):
    /// what a stroke's carried answer reads ([`crate::eigen::warm::ritz_factored`], which
    /// checks that it holds every row it reads). The untouched rows beyond are not copied (6-10
    /// ms of the ceramic cup's carried answer: `K` is 35 MB). [`FemModel::k`] and
    /// [`FemModel::m`] panic on such a model ([`FemModel::is_whole`]); nothing but the
    /// carried answer and its strikes reads it. Where the edit is not local (see
    /// [`FemModel::assemble_after_edit`]) the model is whole.
    pub fn assemble_near_edit(
        grid: &VoxelGrid,
        kind: ElementKind,
        poisson_ratio: f64,
        previous: &FemModel,
        cache: Option<&mut ElementCache>,
        radius_cells: usize,
    ) -> Result<Self, ShapeError> {
        let after = assembly::After {
            previous,
            held_radius: Some(radius_cells),
        };
        Self::assemble_with(grid, kind, poisson_ratio, cache, true, Some(after))
    }

    /// The same model with `K` multiplied by `stiffness` and `M` by `mass` (for example
    /// `E h` and `rho h^3` to obtain the physical matrices).
    pub fn scaled(&self, stiffness: f64, mass: f64) -> Self {
        self.assert_whole();
        let mut out = self.clone();
        out.traces = std::sync::OnceLock::new();
        out.k.iter_mut().flatten().for_each(|v| *v *= stiffness);
        out.m.iter_mut().for_each(|v| *v *= mass);
        out
    }

    /// The stiffness blocks on [`FemModel::pattern`]. Panics for a model assembled only near
    /// an edit ([`FemModel::assemble_near_edit`]; [`FemModel::is_whole`] says which): its
    /// other rows are not there to read.
    pub fn k(&self) -> &Blocks {
        self.assert_whole();
        &self.k
    }

    /// The mass blocks on [`FemModel::pattern`]; panics as [`FemModel::k`] does.
    pub fn m(&self) -> &sparse::MassBlocks {
        self.assert_whole();
        &self.m
    }

    /// Whether the model holds every row of `K` and `M` (every model but a stroke's carried
    /// answer's, [`FemModel::assemble_near_edit`]).
    pub fn is_whole(&self) -> bool {
        self.near_edit.is_none()
    }

    /// `K` and `M` as held: every row, or for a model near an edit only the rows of the nodes
    /// [`FemModel::holds_rows`] says, the others unspecified (the reader near an edit checks,
    /// [`crate::eigen::warm`]).
    pub(crate) fn rows_held(&self) -> (&Blocks, &sparse::MassBlocks) {
        (&self.k, &self.m)
    }

    /// `trace K` and `trace M`, whose ratio is the scale of the spectrum
    /// ([`crate::eigen::Operators`]): one pass over the diagonal blocks on the first call
    /// (1-2 ms on a 30k-DOF model, kept for the strokes carried from it), or, for a model
    /// near an edit, its assembly's update of the previous model's.
    pub fn traces(&self) -> [f64; 2] {
        *self.traces.get_or_init(|| {
            self.assert_whole();
            [
                sparse::trace(&self.pattern, &self.k),
                sparse::mass_trace(&self.pattern, &self.m),
            ]
        })
    }

    /// Whether the rows of every node of `nodes` are held.
    pub(crate) fn holds_rows(&self, nodes: &[usize]) -> bool {
        self.near_edit
            .as_ref()
            .is_none_or(|n| nodes.iter().all(|&a| n.held[a]))
    }

    /// The stiffness blocks to change (the tests' perturbed models).
    #[cfg(test)]
    pub(crate) fn k_mut(&mut self) -> &mut Blocks {
        self.assert_whole();
        self.traces = std::sync::OnceLock::new();
        &mut self.k
    }

    fn assert_whole(&self) {
        assert!(
            self.is_whole(),
            "this model holds K and M only near an edit (a stroke's carried answer); \
             assemble the whole model to read them"
        );
    }

    /// Number of nodes.
    pub fn nodes(&self) -> usize {
        self.node_lattice.len()
    }

    /// Degrees of freedom (3 per node).
    pub fn dofs(&self) -> usize {
        3 * self.nodes()
    }

    /// Lattice coordinates of a node (`order()` lattice steps per voxel).
    pub fn node_lattice_coords(&self, node: usize) -> [i64; 3] {
        lattice_coords(self.node_lattice[node], self.lattice).map(|c| c as i64)
    }

    /// Position of a node in voxel units.
    pub fn node_position(&self, node: usize) -> [f64; 3] {
        let p = self.kind.order() as f64 / self.kind.voxels_per_element() as f64;
        self.node_lattice_coords(node).map(|c| c as f64 / p)
    }

    /// Voxels along x, y, z of the grid the model was assembled from.
    pub fn grid_dims(&self) -> [usize; 3] {
        self.voxel_dims
    }

    /// Element cells along x, y, z: the voxels, or the blocks of
    /// [`ElementKind::Hex27Blocks`] (the coordinates of [`FemModel::voxels`]).
    pub fn cell_dims(&self) -> [usize; 3] {
        let p = self.kind.order();
        self.lattice.map(|l| (l - 1) / p)
    }
}

/// Voxels along the longest side that resolve `fmax_hz` (see ARCHITECTURE.md, resolution).
pub fn auto_resolution(
    material: &crate::material::Material,
    element: ElementKind,
    size_m: f64,
    thinnest_fraction: f64,
    fmax_hz: f64,
) -> usize {
    // Shortest wavelength at fmax: shear waves, or bending waves in the thinnest wall.
    let omega = std::f64::consts::TAU * fmax_hz;
    let shear = material.shear_wave_speed_m_s() / fmax_hz;
    let t = (thinnest_fraction * size_m).max(1e-6);
    let nu = material.poisson_ratio;
    let d_over_rho_t =
        material.youngs_modulus_pa * t * t / (12.0 * (1.0 - nu * nu) * material.density_kg_m3);
    let bending = std::f64::consts::TAU * d_over_rho_t.powf(0.25) / omega.sqrt();
    // Voxels per wavelength: 3 quadratic elements, or 6 linear ones (hex27x2's quadratic
    // elements are 2 voxels long).
    let per_wavelength = match element {
        ElementKind::Hex27 => 3.0,
        _ => 6.0,
    };
    let h = shear.min(bending) / per_wavelength;
    // At least two voxels across the thinnest feature.
    let by_wave = (size_m / h).ceil();
    let by_wall = (2.0 / thinnest_fraction).ceil();
    by_wave.max(by_wall).clamp(8.0, 96.0) as usize
}

/// A built-in shape's spec (`"bar:l=16,w=4,h=3"`) rasterised plainly at voxel edge 1: the
/// unit tests' small objects.
#[cfg(test)]
pub(crate) fn test_grid(spec: &str) -> VoxelGrid {
    let crate::shape::spec::ShapeSpec::Primitive { shape, .. } = spec.parse().expect("spec") else {
        panic!("{spec}: not a primitive")
    };
    shape.rasterize(1.0, 1.0).expect("grid")
}

/// [`test_grid`]'s object assembled with `kind` and Poisson's ratio `poisson`.
#[cfg(test)]
pub(crate) fn test_model(spec: &str, kind: ElementKind, poisson: f64) -> FemModel {
    FemModel::assemble(&test_grid(spec), kind, poisson).expect("model")
}

#[cfg(test)]
mod tests {
    use super::{ElementKind, FemModel};

    /// The hex27x2 cut blocks of a curved object share their orbit's integration (the 16-voxel
    /// bowl's mirrors and quarter turn make orbits of up to 8); the independent truth is
    /// every cut block integrated on its own. A mapped block is its orbit's first block's
    /// matrices rotated, and a block's refined fill is symmetric to its image's only to the
    /// rounding of the plane fits: equal to 1e-12 of the largest entry. An orbit that took
    /// in a block whose input is not an image would be off by that block's matrices, tens
    /// of percent of an entry.
    #[test]
    fn hex27x2_blocks_that_share_an_orbit_assemble_as_integrated_alone() {
        for spec in ["bowl:d=16,wall=2", "sphere:d=16"] {
            let grid = super::test_grid(spec);
            let kind = ElementKind::Hex27Blocks;
            let shared =
                FemModel::assemble_with(&grid, kind, 0.3, None, true, None).expect("model");
            let alone =
                FemModel::assemble_with(&grid, kind, 0.3, None, false, None).expect("model");
            assert_eq!(shared.pattern.col, alone.pattern.col);
            let scale = alone.k.iter().flatten().fold(0.0f64, |s, v| s.max(v.abs()));
            let dk = (shared.k.iter().flatten())
                .zip(alone.k.iter().flatten())
                .fold(0.0f64, |d, (a, b)| d.max((a - b).abs()));
            assert!(dk <= 1e-12 * scale, "{spec}: K off by {dk:e} of {scale:e}");
            let scale = alone.m.iter().fold(0.0f64, |s, v| s.max(v.abs()));
            let dm = (shared.m.iter())
                .zip(&alone.m)
                .fold(0.0f64, |d, (a, b)| d.max((a - b).abs()));
            assert!(dm <= 1e-12 * scale, "{spec}: M off by {dm:e} of {scale:e}");
        }
    }
}
