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

pub mod cut;
pub mod element;
pub mod ordering;
pub mod sparse;

use crate::shape::{lattice_coords, lattice_index};
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
    /// Lattice dimensions (`p n + 1` per axis).
    pub lattice: [usize; 3],
    /// Lattice index of each model node.
    pub node_lattice: Vec<usize>,
    /// Lattice index -> node number (`u32::MAX` where unused).
    pub lattice_node: Vec<u32>,
    /// Local-to-global node numbers, `kind.nodes()` per element (one element per solid voxel, in
    /// the grid's storage order).
    pub elements: Vec<u32>,
    /// The solid voxels, in element order.
    pub voxels: Vec<[usize; 3]>,
    /// Block sparsity shared by `K` and `M`.
    pub pattern: BlockPattern,
    /// Stiffness blocks.
    pub k: Blocks,
    /// Mass blocks.
    pub m: Blocks,
}

impl FemModel {
    /// Assembles `K` and `M` for every solid voxel of `grid`.
    pub fn assemble(
        grid: &VoxelGrid,
        kind: ElementKind,
        poisson_ratio: f64,
    ) -> Result<Self, ShapeError> {
        grid.check_solvable()?;
        let unit = UnitElement::new(kind, poisson_ratio);
        let p = kind.order();
        let n1 = p + 1;
        let nloc = kind.nodes();
        let dims = grid.dims();
        let lattice = [p * dims[0] + 1, p * dims[1] + 1, p * dims[2] + 1];
        let lidx = |x: usize, y: usize, z: usize| lattice_index([x, y, z], lattice);
        let voxels = grid.solid_voxels();
        // Number the nodes in lattice order (keeps neighbours close in memory).
        let mut lattice_node = vec![u32::MAX; lattice.iter().product()];
        for v in &voxels {
            for az in 0..n1 {
                for ay in 0..n1 {
                    for ax in 0..n1 {
                        lattice_node[lidx(p * v[0] + ax, p * v[1] + ay, p * v[2] + az)] = 0;
                    }
                }
            }
        }
        let mut node_lattice = Vec::new();
        for (i, slot) in lattice_node.iter_mut().enumerate() {
            if *slot == 0 {
                *slot = node_lattice.len() as u32;
                node_lattice.push(i);
            }
        }
        let mut elements = Vec::with_capacity(voxels.len() * nloc);
        for v in &voxels {
            for az in 0..n1 {
                for ay in 0..n1 {
                    for ax in 0..n1 {
                        elements
                            .push(lattice_node[lidx(p * v[0] + ax, p * v[1] + ay, p * v[2] + az)]);
                    }
                }
            }
        }
        let nodes = node_lattice.len();
        let pattern = BlockPattern::from_elements(nodes, &elements, nloc);
        let mut k = crate::buffer::zeroed(pattern.col.len());
        let mut m = crate::buffer::zeroed(pattern.col.len());
        // Partial voxels: cut elements, evaluated in batches.
        let cut = (!grid.is_binary())
            .then(|| cut::CutElement::new(kind, poisson_ratio, cut::subcells_per_axis(kind)));
        let mut scratch = cut.as_ref().map(|c| c.scratch());
        let subcells = cut.as_ref().map_or(0, |c| c.per_axis().pow(3));
        // The batch: element numbers, and their sub-cell fills side by side.
        let mut pending: Vec<usize> = Vec::with_capacity(cut::CUT_BATCH);
        let mut fills = vec![0.0; subcells * cut::CUT_BATCH];
        let mut slots = vec![0usize; nloc * nloc];
        let mut flush =
            |pending: &mut Vec<usize>, fills: &[f64], k: &mut [[f64; 9]], m: &mut [[f64; 9]]| {
                if let (Some(cut), Some(scratch)) = (&cut, &mut scratch) {
                    let batch: Vec<&[f64]> =
                        fills.chunks_exact(subcells).take(pending.len()).collect();
                    cut.matrices_batch(&batch, scratch, |j, ke, me| {
                        let e = pending[j];
                        let nodes = &elements[e * nloc..(e + 1) * nloc];
                        sparse::add_element(&pattern, nodes, ke, me, k, m, &mut slots);
                    });
                }
                pending.clear();
            };
        let mut unit_slots = vec![0usize; nloc * nloc];
        for (e, v) in voxels.iter().enumerate() {
            match (grid.subcell_fill(grid.index(v[0], v[1], v[2])), &cut) {
                (Some(fill), Some(_)) => {
                    let at = pending.len() * subcells;
                    fill.coarsened_into(&mut fills[at..at + subcells]);
                    pending.push(e);
                    if pending.len() == cut::CUT_BATCH {
                        flush(&mut pending, &fills, &mut k, &mut m);
                    }
                }
                _ => {
                    let nodes = &elements[e * nloc..(e + 1) * nloc];
                    let (ke, me) = (&unit.stiffness[..], &unit.mass[..]);
                    sparse::add_element(&pattern, nodes, ke, me, &mut k, &mut m, &mut unit_slots);
                }
            }
        }
        flush(&mut pending, &fills, &mut k, &mut m);
        Ok(FemModel {
            kind,
            poisson_ratio,
            lattice,
            node_lattice,
            lattice_node,
            elements,
            voxels,
            pattern,
            k,
            m,
        })
    }

    /// The same model with `K` multiplied by `stiffness` and `M` by `mass` (for example
    /// `E h` and `rho h^3` to obtain the physical matrices).
    pub fn scaled(&self, stiffness: f64, mass: f64) -> Self {
        let mut out = self.clone();
        out.k.iter_mut().flatten().for_each(|v| *v *= stiffness);
        out.m.iter_mut().flatten().for_each(|v| *v *= mass);
        out
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
        let p = self.kind.order() as f64;
        self.node_lattice_coords(node).map(|c| c as f64 / p)
    }

    /// Voxels along x, y, z of the grid the model was assembled from.
    pub fn grid_dims(&self) -> [usize; 3] {
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
