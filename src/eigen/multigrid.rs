//! Geometric multigrid on the voxel grid: the preconditioner of [`super::lobpcg`].
//!
//! Where it sits: built once per solve from the assembled [`FemModel`]; LOBPCG applies one
//! V-cycle to each block of residuals. The operator is `A = K + tau M` with a small `tau > 0`
//! (the Lanczos shift, relative to the spectrum's scale), so every level is positive definite
//! even though a free object's `K` is singular.
//!
//! Levels. A hex27 model first drops to hex8 on the same voxels (p-multigrid); hex8 levels then
//! coarsen 2x2x2 (h-multigrid): a coarse cell exists where any of its eight children does, and
//! coarse nodes sit on every second lattice plane. The prolongation `P` is trilinear
//! interpolation, which reproduces linear fields, so rigid-body modes live on every level.
//! Coarse operators are Galerkin products `P^T A P`, formed cell by cell: a coarse cell's
//! element matrix is the sum over its children of `P_o^T A_child P_o`, where `P_o` depends only
//! on the child's octant. Every voxel has the same element matrix, so on each level the cells
//! share a small table of distinct matrices (memoised by their children), and a staircased thin
//! wall is coarsened exactly instead of being re-discretised too stiff.
//!
//! Smoothing is Chebyshev (degree [`SMOOTHING_DEGREE`]) on the 3x3 node-block Jacobi
//! preconditioned operator, targeting the top `1/SMOOTHING_RANGE` of its spectrum; its largest
//! eigenvalue comes from a short power iteration. The coarsest level (at most
//! [`COARSE_NODES`] nodes) is solved exactly with the sparse Cholesky factor of
//! [`super::factor`]. Pre- and post-smoothing use the same polynomial, so the V-cycle is a
//! symmetric positive definite operator, as LOBPCG requires.

mod hierarchy;

use super::factor::ShiftedCholesky;
use super::{EigenError, Operators};
use crate::buffer::zeroed;
use crate::fem::ordering::nested_dissection_of;
use crate::fem::sparse::{self, BlockPattern, Blocks, MassBlocks, RowBlock, Scalar};
use crate::fem::{ElementKind, FemModel, UnitElement};
use hierarchy::{assemble, coarsen, galerkin, hex27_to_hex8, prolongation};

/// Coarsening stops once a level has at most this many nodes; that level is factored.
pub const COARSE_NODES: usize = 3000;

/// Chebyshev polynomial degree of each pre- and post-smoothing step.
pub const SMOOTHING_DEGREE: usize = 2;

/// The smoother damps the eigenvalues of `D^-1 A` in `[lambda_max / SMOOTHING_RANGE,
/// lambda_max]`; the coarse grid handles the rest.
pub const SMOOTHING_RANGE: f64 = 20.0;

/// Power iterations for the largest eigenvalue of `D^-1 A` (then padded by 10 %).
const POWER_STEPS: usize = 12;

/// The V-cycle's working precision below the coarsest level. Single precision halves the memory
/// traffic of the smoother and the transfers and doubles the SIMD width; a preconditioner only
/// has to approximate `A^-1` (LOBPCG's own products and Rayleigh-Ritz stay in f64). Levels are
/// built in f64 and rounded once.
type Real = f32;

/// Cells of one level, each with an element matrix (hex8 nodes, 24x24) from a shared table.
struct CellMesh {
    dims: [usize; 3],
    cells: Vec<[usize; 3]>,
    matrix: Vec<u32>,
    k_table: Vec<Vec<f64>>,
    m_table: Vec<Vec<f64>>,
}

/// Fine-node weights of the coarse nodes: a CSR over fine nodes.
struct Prolongation {
    row_ptr: Vec<usize>,
    coarse: Vec<u32>,
    weight: Vec<f64>,
}

/// One level: `A = K + tau M` and what smoothing needs.
struct Level {
    pattern: BlockPattern,
    /// `A` in f64 while the hierarchy is built; emptied by [`Level::prepare`].
    a: Blocks,
    /// `A` in the V-cycle's precision.
    a_real: Vec<[Real; 9]>,
    inv_diag: Vec<[Real; 9]>,
    lambda_max: f64,
    lattice: [usize; 3],
    lattice_node: Vec<u32>,
    coords: Vec<[i64; 3]>,
    /// From the next coarser level to this one (`None` on the coarsest).
    prolong: Option<Prolongation>,
    rhs: Vec<Real>,
    x: Vec<Real>,
    r: Vec<Real>,
    d: Vec<Real>,
}

/// The coarsest level's matrices, for the nested start of LOBPCG.
pub struct CoarseProblem {
    /// Pattern.
    pub pattern: BlockPattern,
    /// Galerkin stiffness.
    pub k: Blocks,
    /// Galerkin mass.
    pub m: MassBlocks,
}

/// A multigrid hierarchy for one model (see the module docs).
pub struct Multigrid {
    levels: Vec<Level>,
    coarse: CoarseProblem,
    factor: ShiftedCholesky,
    /// The coarsest level's block in f64, for the factor's solve, and its solution.
    coarse_x: Vec<f64>,
    coarse_solved: Vec<f64>,
    tau: f64,
    max_width: usize,
}

impl Multigrid {
    /// Builds the hierarchy of `model` for blocks of up to `max_width` vectors.
    pub fn new(model: &FemModel, max_width: usize) -> Result<Self, EigenError> {
        let mut unit = UnitElement::clone(&UnitElement::shared(model.kind, model.poisson_ratio));
        // The model's element matrices in voxel units (hex27x2's blocks are 2 voxels a side).
        let b = model.kind.voxels_per_element() as f64;
        unit.stiffness.iter_mut().for_each(|v| *v *= b);
        unit.mass.iter_mut().for_each(|v| *v *= b * b * b);
        let fine_dims = model.cell_dims();
        let voxel_mesh = |k: Vec<f64>, m: Vec<f64>| CellMesh {
            dims: fine_dims,
            cells: model.voxels.clone(),
            matrix: vec![0; model.voxels.len()],
            k_table: vec![k],
            m_table: vec![m],
        };
        // The first coarse mesh: hex8 on the same voxels (hex27), or 2x2x2 coarser cells.
        let mut next = match model.kind {
            ElementKind::Hex27 | ElementKind::Hex27Blocks => {
                let p = hex27_to_hex8();
                voxel_mesh(
                    galerkin(&unit.stiffness, &p, 27),
                    galerkin(&unit.mass, &p, 27),
                )
            }
            _ => coarsen(&voxel_mesh(unit.stiffness.clone(), unit.mass.clone())),
        };
        let fine_coords: Vec<[i64; 3]> = (0..model.nodes())
            .map(|n| model.node_lattice_coords(n))
            .collect();
        // Level matrices are K and M until tau is known (from the coarsest level).
        let mut fine_a = zeroed(model.k().len());
        fine_a.copy_from_slice(model.k());
        let mut levels = vec![Level::new(
            model.pattern.clone(),
            fine_a,
            model.lattice,
            model.lattice_node.clone(),
            fine_coords,
        )];
        // Coarse levels' mass matrices (the fine one is the model's own).
        let mut masses: Vec<MassBlocks> = Vec::new();
        let (coarse_k, coarse_m) = loop {
            let (level, k, m) = assemble(&next);
            let nodes = level.coords.len();
            let prev_nodes = levels.last().map(|l| l.coords.len()).unwrap_or(usize::MAX);
            let fine = levels.last_mut().expect("level 0");
            fine.prolong = Some(prolongation(&fine.coords, &level));
            levels.push(Level { a: k, ..level });
            masses.push(m.clone());
            let done = nodes <= COARSE_NODES
                || next.dims.iter().all(|&d| d <= 1)
                || nodes * 3 > prev_nodes * 2;
            if done {
                break (levels.last().expect("coarsest").a.clone(), m);
            }
            next = coarsen(&next);
        };
        let coarsest = levels.last().expect("coarsest");
        let ops = Operators::from_parts(&coarsest.pattern, &coarse_k, &coarse_m);
        let tau = super::lanczos::SHIFT_RELATIVE * ops.scale;
        let order = nested_dissection_of(&coarsest.coords, 1);
        let factor =
            ShiftedCholesky::from_blocks(&coarsest.pattern, &coarse_k, &coarse_m, -tau, &order)?;
        let coarse = CoarseProblem {
            pattern: coarsest.pattern.clone(),
            k: coarse_k,
            m: coarse_m,
        };
        for (i, level) in levels.iter_mut().enumerate() {
            let m = if i == 0 { model.m() } else { &masses[i - 1] };
            for (a, &mb) in level.a.iter_mut().zip(m) {
                for c in 0..3 {
                    a[4 * c] += tau * mb;
                }
            }
            level.prepare(max_width);
        }
        let coarse_x = vec![0.0; 3 * coarse.pattern.nodes() * max_width.max(1)];
        Ok(Multigrid {
            levels,
            coarse,
            factor,
            coarse_solved: coarse_x.clone(),
            coarse_x,
            tau,
            max_width,
        })
    }

    /// Number of levels, the fine one included.
    pub fn depth(&self) -> usize {
        self.levels.len()
    }

    /// Nodes on each level, finest first.
    pub fn level_nodes(&self) -> Vec<usize> {
        self.levels.iter().map(|l| l.coords.len()).collect()
    }

    /// The regularisation `tau` of `A = K + tau M`.
    pub fn tau(&self) -> f64 {
        self.tau
    }

    /// The coarsest level's Galerkin `K` and `M`.
    pub fn coarse_problem(&self) -> &CoarseProblem {
        &self.coarse
    }

    /// The factor of the coarsest `K + tau M` (a Lanczos run on the coarse problem reuses it
    /// with shift `-tau`).
    pub fn coarse_factor(&mut self) -> &mut ShiftedCholesky {
        &mut self.factor
    }

    /// Interpolates a dense block of `width` coarsest-level vectors to the fine level; returns a
    /// dense fine block of the same width.
    pub fn prolong_from_coarsest(&self, coarse: &[f64], width: usize) -> Vec<f64> {
        let mut current = coarse.to_vec();
        for level in self.levels.iter().rev().skip(1) {
            let p = level
                .prolong
                .as_ref()
                .expect("every level but the coarsest");
            let mut fine = vec![0.0; 3 * level.coords.len() * width];
            prolong_add(p, &current, &mut fine, width);
            current = fine;
        }
        current
    }

    /// `z ~= A^-1 r` by one V-cycle per column; `r` and `z` are fine-level blocks with their
    /// own layouts and the same width (any width: the columns go through in chunks of at most
    /// the `max_width` the hierarchy was built for). Allocates nothing: the scratch of every
    /// level was sized when the hierarchy was built.
    pub fn apply(&mut self, r: &[f64], r_layout: RowBlock, z: &mut [f64], z_layout: RowBlock) {
        assert_eq!(r_layout.width, z_layout.width);
        let n = 3 * self.levels[0].coords.len();
        let mut c0 = 0;
        while c0 < r_layout.width {
            let b = self.max_width.min(r_layout.width - c0);
            let fine = &mut self.levels[0];
            for i in 0..n {
                let at = i * r_layout.stride + c0;
                for (d, &v) in fine.rhs[i * b..(i + 1) * b].iter_mut().zip(&r[at..at + b]) {
                    *d = v as Real;
                }
            }
            self.vcycle(0, b);
            let fine = &self.levels[0];
            for i in 0..n {
                let at = i * z_layout.stride + c0;
                for (d, &v) in z[at..at + b].iter_mut().zip(&fine.x[i * b..(i + 1) * b]) {
                    *d = v as f64;
                }
            }
            c0 += b;
        }
    }

    fn vcycle(&mut self, l: usize, b: usize) {
        let last = self.levels.len() - 1;
        if l == last {
            let level = &mut self.levels[l];
            let n = 3 * level.coords.len();
            let x = &mut self.coarse_x[..n * b];
            for (d, &v) in x.iter_mut().zip(&level.rhs[..n * b]) {
                *d = v as f64;
            }
            let block = RowBlock::dense(b);
            let solved = &mut self.coarse_solved[..n * b];
            self.factor.solve_rows(x, block, solved, block);
            for (d, &v) in level.x[..n * b].iter_mut().zip(solved.iter()) {
                *d = v as Real;
            }
            return;
        }
        let (head, tail) = self.levels.split_at_mut(l + 1);
        let (level, coarse) = (&mut head[l], &mut tail[0]);
        let n = 3 * level.coords.len();
        let nc = 3 * coarse.coords.len();
        level.chebyshev(b, true);
        // Residual, restricted to the coarse right-hand side.
        level.residual(b);
        coarse.rhs[..nc * b].fill(0.0);
        restrict_add(
            level.prolong.as_ref().expect("not the coarsest"),
            &level.r[..n * b],
            &mut coarse.rhs[..nc * b],
            b,
        );
        self.vcycle(l + 1, b);
        let (head, tail) = self.levels.split_at_mut(l + 1);
        let (level, coarse) = (&mut head[l], &tail[0]);
        prolong_add(
            level.prolong.as_ref().expect("not the coarsest"),
            &coarse.x[..nc * b],
            &mut level.x[..n * b],
            b,
        );
        level.chebyshev(b, false);
    }
}

impl Level {
    fn new(
        pattern: BlockPattern,
        a: Blocks,
        lattice: [usize; 3],
        lattice_node: Vec<u32>,
        coords: Vec<[i64; 3]>,
    ) -> Self {
        Level {
            pattern,
            a,
            a_real: Vec::new(),
            inv_diag: Vec::new(),
            lambda_max: 0.0,
            lattice,
            lattice_node,
            coords,
            prolong: None,
            rhs: Vec::new(),
            x: Vec::new(),
            r: Vec::new(),
            d: Vec::new(),
        }
    }

    /// Block-diagonal inverse, spectrum bound and scratch, once `a` is final.
    fn prepare(&mut self, max_width: usize) {
        let nodes = self.coords.len();
        self.inv_diag = (0..nodes)
            .map(|r| {
                let b = self.pattern.find(r, r as u32).expect("diagonal block");
                invert3(&self.a[b]).map(|v| v as Real)
            })
            .collect();
        self.a_real = zeroed(self.a.len());
        for (r, a) in self.a_real.iter_mut().zip(&self.a) {
            *r = a.map(|v| v as Real);
        }
        self.a = Vec::new();
        let n = 3 * nodes;
        let size = n * max_width;
        self.rhs = zeroed(size);
        self.x = zeroed(size);
        self.r = zeroed(size);
        self.d = zeroed(size);
        // Power iteration on D^-1 A (as the V-cycle applies it) with a fixed pseudo-random start.
        let mut v: Vec<Real> = (0..n)
            .map(|i| ((i * 7919 % 1013) as Real / 1013.0) - 0.45)
            .collect();
        let mut av = vec![0.0; n];
        let mut lambda = 0.0;
        for _ in 0..POWER_STEPS {
            let norm = v.iter().map(|&x| x as f64 * x as f64).sum::<f64>().sqrt();
            if norm == 0.0 || !norm.is_finite() {
                break;
            }
            v.iter_mut().for_each(|x| *x = (*x as f64 / norm) as Real);
            sparse::spmm(&self.pattern, &self.a_real, &v, &mut av, RowBlock::dense(1));
            self.apply_inv_diag(&av, &mut v, 1);
            lambda = v.iter().map(|&x| x as f64 * x as f64).sum::<f64>().sqrt();
        }
        self.lambda_max = 1.1 * lambda;
    }

    /// `out = D^-1 v` for a dense block of width `b`.
    fn apply_inv_diag(&self, v: &[Real], out: &mut [Real], b: usize) {
        for (node, inv) in self.inv_diag.iter().enumerate() {
            let base = 3 * node * b;
            for j in 0..b {
                let (v0, v1, v2) = (v[base + j], v[base + b + j], v[base + 2 * b + j]);
                out[base + j] = inv[0] * v0 + inv[1] * v1 + inv[2] * v2;
                out[base + b + j] = inv[3] * v0 + inv[4] * v1 + inv[5] * v2;
                out[base + 2 * b + j] = inv[6] * v0 + inv[7] * v1 + inv[8] * v2;
            }
        }
    }

    /// `r = rhs - A x`.
    fn residual(&mut self, b: usize) {
        let n = 3 * self.coords.len() * b;
        sparse::spmm(
            &self.pattern,
            &self.a_real,
            &self.x[..n],
            &mut self.r[..n],
            RowBlock::dense(b),
        );
        for (r, f) in self.r[..n].iter_mut().zip(&self.rhs[..n]) {
            *r = f - *r;
        }
    }

    /// Chebyshev smoothing of `A x = rhs` (Saad, Iterative Methods, alg. 12.1, on `D^-1 A`);
    /// starts from `x = 0` when `zero_start`.
    fn chebyshev(&mut self, b: usize, zero_start: bool) {
        let n = 3 * self.coords.len() * b;
        let hi = self.lambda_max;
        let lo = hi / SMOOTHING_RANGE;
        let (theta, delta) = (0.5 * (hi + lo), 0.5 * (hi - lo));
        let sigma = theta / delta;
        let mut rho = 1.0 / sigma;
        let inv_theta = (1.0 / theta) as Real;
        if zero_start {
            self.x[..n].fill(0.0);
            self.r[..n].copy_from_slice(&self.rhs[..n]);
        } else {
            self.residual(b);
        }
        let mut d = std::mem::take(&mut self.d);
        self.apply_inv_diag(&self.r[..n], &mut d[..n], b);
        d[..n].iter_mut().for_each(|v| *v *= inv_theta);
        for _ in 1..SMOOTHING_DEGREE {
            for (x, dv) in self.x[..n].iter_mut().zip(&d[..n]) {
                *x += dv;
            }
            self.residual(b);
            let rho_new = 1.0 / (2.0 * sigma - rho);
            let (c1, c2) = ((rho_new * rho) as Real, (2.0 * rho_new / delta) as Real);
            // d = c1 d + c2 D^-1 r, fused in one pass.
            for (node, inv) in self.inv_diag.iter().enumerate() {
                let base = 3 * node * b;
                for j in 0..b {
                    let r = &self.r;
                    let (r0, r1, r2) = (r[base + j], r[base + b + j], r[base + 2 * b + j]);
                    d[base + j] = c1 * d[base + j] + c2 * (inv[0] * r0 + inv[1] * r1 + inv[2] * r2);
                    d[base + b + j] =
                        c1 * d[base + b + j] + c2 * (inv[3] * r0 + inv[4] * r1 + inv[5] * r2);
                    d[base + 2 * b + j] =
                        c1 * d[base + 2 * b + j] + c2 * (inv[6] * r0 + inv[7] * r1 + inv[8] * r2);
                }
            }
            rho = rho_new;
        }
        for (x, dv) in self.x[..n].iter_mut().zip(&d[..n]) {
            *x += dv;
        }
        self.d = d;
    }
}

/// Inverse of a row-major 3x3 matrix (a diagonal block of a positive definite matrix).
fn invert3(a: &[f64; 9]) -> [f64; 9] {
    let c = [
        a[4] * a[8] - a[5] * a[7],
        a[2] * a[7] - a[1] * a[8],
        a[1] * a[5] - a[2] * a[4],
        a[5] * a[6] - a[3] * a[8],
        a[0] * a[8] - a[2] * a[6],
        a[2] * a[3] - a[0] * a[5],
        a[3] * a[7] - a[4] * a[6],
        a[1] * a[6] - a[0] * a[7],
        a[0] * a[4] - a[1] * a[3],
    ];
    let det = a[0] * c[0] + a[1] * c[3] + a[2] * c[6];
    c.map(|v| v / det)
}

/// `fine += P coarse` for dense blocks of width `b`.
fn prolong_add<T: Scalar>(p: &Prolongation, coarse: &[T], fine: &mut [T], b: usize) {
    for node in 0..p.row_ptr.len() - 1 {
        let out = &mut fine[3 * node * b..3 * (node + 1) * b];
        for k in p.row_ptr[node]..p.row_ptr[node + 1] {
            let w = T::from_f64(p.weight[k]);
            let src = &coarse[3 * p.coarse[k] as usize * b..3 * (p.coarse[k] as usize + 1) * b];
            for (o, &s) in out.iter_mut().zip(src) {
                *o += w * s;
            }
        }
    }
}

/// `coarse += P^T fine` for dense blocks of width `b`.
fn restrict_add<T: Scalar>(p: &Prolongation, fine: &[T], coarse: &mut [T], b: usize) {
    for node in 0..p.row_ptr.len() - 1 {
        let src = &fine[3 * node * b..3 * (node + 1) * b];
        for k in p.row_ptr[node]..p.row_ptr[node + 1] {
            let w = T::from_f64(p.weight[k]);
            let c = p.coarse[k] as usize;
            for (o, &s) in coarse[3 * c * b..3 * (c + 1) * b].iter_mut().zip(src) {
                *o += w * s;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shape::VoxelGrid;

    /// Galerkin coarsening of one full 2x2x2 block of unit hex8 cells equals P^T K P of the
    /// assembled fine matrix, and reproduces rigid-body energy zero.
    #[test]
    fn coarse_operator_is_galerkin_and_keeps_rigid_modes() {
        let grid = VoxelGrid::from_fn([4, 4, 2], 1.0, |x, y, z| x + y + z < 6.0).unwrap();
        let model = FemModel::assemble(&grid, ElementKind::Hex8, 0.3).unwrap();
        let mg = Multigrid::new(&model, 4).unwrap();
        assert_eq!(mg.depth(), 2);
        // Rigid rotation about z prolonged from the coarse level has zero fine energy.
        let coarse = &mg.coarse;
        let nc = coarse.pattern.nodes();
        let level = &mg.levels[1];
        let mut rot = vec![0.0; 3 * nc];
        for (i, c) in level.coords.iter().enumerate() {
            rot[3 * i] = -(c[1] as f64) * 2.0;
            rot[3 * i + 1] = c[0] as f64 * 2.0;
        }
        let fine = mg.prolong_from_coarsest(&rot, 1);
        let mut kf = vec![0.0; fine.len()];
        sparse::spmm(
            &model.pattern,
            model.k(),
            &fine,
            &mut kf,
            RowBlock::dense(1),
        );
        let scale = sparse::norm_inf(&model.pattern, model.k())
            * fine.iter().map(|v| v.abs()).fold(0.0, f64::max);
        assert!(kf.iter().all(|v| v.abs() < 1e-12 * scale));
        // Galerkin identity on a random coarse vector: x^T Kc y = (P x)^T K (P y).
        let x: Vec<f64> = (0..3 * nc).map(|i| ((i * 37 % 11) as f64) - 5.0).collect();
        let y: Vec<f64> = (0..3 * nc).map(|i| ((i * 53 % 7) as f64) - 3.0).collect();
        let mut kcy = vec![0.0; 3 * nc];
        sparse::spmm(&coarse.pattern, &coarse.k, &y, &mut kcy, RowBlock::dense(1));
        let lhs: f64 = x.iter().zip(&kcy).map(|(a, b)| a * b).sum();
        let (px, py) = (
            mg.prolong_from_coarsest(&x, 1),
            mg.prolong_from_coarsest(&y, 1),
        );
        sparse::spmm(&model.pattern, model.k(), &py, &mut kf, RowBlock::dense(1));
        let rhs: f64 = px.iter().zip(&kf).map(|(a, b)| a * b).sum();
        assert!(
            (lhs - rhs).abs() < 1e-10 * rhs.abs().max(1.0),
            "{lhs} vs {rhs}"
        );
    }
}
