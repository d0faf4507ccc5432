//! The operators both eigensolvers work on: borrowed `K` and `M` with their norms, their block
//! products and the residual criterion (Jin et al. 2022, eq. 6), and the row-major block layout
//! the kernels read.
//!
//! Where it sits: built once per solve by [`super::solve_until`] (a whole model) or
//! [`super::symmetric`] (a symmetry class's reduced matrices); the Lanczos, LOBPCG and warm
//! solvers read `K` and `M` only through it.

use super::{random_block, RIGID_RELATIVE};
use crate::fem::sparse::{self, BlockPattern};
use crate::fem::FemModel;
use faer::{Mat, MatRef};

/// Which of the two matrices a product uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Which {
    /// The stiffness `K`.
    K,
    /// The mass `M`.
    M,
}

/// Borrowed `K`, `M` and their norms: what both solvers work on.
#[derive(Clone, Copy)]
pub struct Operators<'a> {
    /// Pattern.
    pub pattern: &'a BlockPattern,
    /// Stiffness blocks.
    pub k: &'a [[f64; 9]],
    /// Mass, one scalar per block ([`sparse::MassBlocks`]); empty where `mass_diagonal` is set.
    pub m: &'a [f64],
    /// The mass as diagonal blocks instead, where it is not `m_ab I3`: a symmetry class's
    /// reduced mass ([`symmetric`]) differs by component.
    pub mass_diagonal: Option<&'a [[f64; 3]]>,
    /// With `mass_diagonal`, the mass's entries off its blocks' diagonals as `(row DOF,
    /// column DOF, value)`: a few, in a symmetry class split by an axis swap
    /// ([`symmetric`]); empty elsewhere.
    pub mass_extra: &'a [(u32, u32, f64)],
    /// DOFs that do not exist in this problem (a symmetry class's DOFs that its symmetry
    /// forces to zero; empty for a whole model): decoupled in `K`, massless, and kept at zero in
    /// every start vector.
    pub absent: &'a [usize],
    /// Infinity norm of K.
    pub k_norm: f64,
    /// Infinity norm of M.
    pub m_norm: f64,
    /// `trace K / trace M`: the scale of the spectrum.
    pub scale: f64,
}

impl<'a> Operators<'a> {
    /// Views a model's matrices.
    pub fn new(model: &'a FemModel) -> Self {
        Self::from_parts(&model.pattern, model.k(), model.m())
    }

    /// Views a model's matrices for products and the rigid-mode test only: the infinity norms
    /// (a pass over every block of `K`, 6 ms on a 30k-DOF model) are left `NaN`, for a caller
    /// that reports no residuals (the instant carried answer, [`super::warm::ritz`]). The
    /// scale is the model's kept traces' ([`FemModel::traces`]).
    pub fn without_norms(model: &'a FemModel) -> Self {
        let [trace_k, trace_m] = model.traces();
        Operators {
            scale: trace_k / trace_m,
            ..Self::unscaled(&model.pattern, model.k(), model.m())
        }
    }

    /// [`Self::without_norms`] for a model that may hold `K` and `M` only near an edit
    /// ([`FemModel::assemble_near_edit`]): a reader of its rows checks
    /// [`FemModel::holds_rows`] first ([`super::warm`]).
    pub(crate) fn held_without_norms(model: &'a FemModel) -> Self {
        let (k, m) = model.rows_held();
        let [trace_k, trace_m] = model.traces();
        Operators {
            scale: trace_k / trace_m,
            ..Self::unscaled(&model.pattern, k, m)
        }
    }

    /// Views `K` and `M` given as node blocks on one pattern.
    pub fn from_parts(p: &'a BlockPattern, k: &'a [[f64; 9]], m: &'a [f64]) -> Self {
        Operators {
            k_norm: sparse::norm_inf(p, k),
            m_norm: sparse::mass_norm_inf(p, m),
            ..Self::parts_without_norms(p, k, m)
        }
    }

    /// [`Self::from_parts`] with the norms left `NaN`.
    fn parts_without_norms(p: &'a BlockPattern, k: &'a [[f64; 9]], m: &'a [f64]) -> Self {
        Operators {
            scale: sparse::trace(p, k) / sparse::mass_trace(p, m),
            ..Self::unscaled(p, k, m)
        }
    }

    /// [`Self::parts_without_norms`] with the scale left `NaN` too.
    fn unscaled(p: &'a BlockPattern, k: &'a [[f64; 9]], m: &'a [f64]) -> Self {
        Operators {
            pattern: p,
            k,
            m,
            mass_diagonal: None,
            mass_extra: &[],
            absent: &[],
            k_norm: f64::NAN,
            m_norm: f64::NAN,
            scale: f64::NAN,
        }
    }

    /// A deterministic random block of `b` columns ([`random_block`]) with the absent DOFs'
    /// rows zeroed: where every Lanczos basis starts, and what refills it after a breakdown.
    pub(crate) fn random_block(&self, b: usize, seed: u64) -> Mat<f64> {
        let mut x = random_block(self.dofs(), b, seed);
        for &i in self.absent {
            for j in 0..b {
                x[(i, j)] = 0.0;
            }
        }
        x
    }

    /// Degrees of freedom.
    pub fn dofs(&self) -> usize {
        3 * self.pattern.nodes()
    }

    /// `y = K x`.
    pub fn apply_k(&self, x: &[f64], y: &mut [f64]) {
        sparse::spmv(self.pattern, self.k, x, y)
    }

    /// `y = M x`.
    pub fn apply_m(&self, x: &[f64], y: &mut [f64]) {
        self.spmm(Which::M, x, y, sparse::RowBlock::dense(1))
    }

    /// Residual of Jin et al. 2022, eq. 6 for one pair; `scratch` holds two vectors of `dofs()`.
    pub fn residual(&self, lambda: f64, x: &[f64], scratch: &mut [f64]) -> f64 {
        let n = self.dofs();
        let (kx, mx) = scratch.split_at_mut(n);
        self.apply_k(x, kx);
        self.apply_m(x, &mut mx[..n]);
        let r: f64 = kx
            .iter()
            .zip(&mx[..n])
            .map(|(a, b)| (a - lambda * b).powi(2))
            .sum::<f64>()
            .sqrt();
        let xn = x.iter().map(|v| v * v).sum::<f64>().sqrt();
        r / ((self.k_norm + lambda.abs() * self.m_norm) * xn)
    }

    /// `K X` (`Which::K`) or `M X` for a column-major block, through one block SpMM (one pass
    /// over the matrix serves every column).
    pub fn apply_block(&self, which: Which, x: MatRef<'_, f64>) -> Mat<f64> {
        let (n, w) = (x.nrows(), x.ncols());
        if w == 0 {
            return Mat::zeros(n, 0);
        }
        self.apply_rows(which, &to_rows(x), w)
    }

    /// [`Operators::apply_block`] for a block given by rows (`x[i * w + j]`: DOF `i` of column
    /// `j`), as its callers often build it; the product comes back column-major.
    pub fn apply_rows(&self, which: Which, x: &[f64], w: usize) -> Mat<f64> {
        from_rows(&self.rows_product(which, x, w), w)
    }

    /// `K X` or `M X` for a block given by rows, by rows (a [`MatRef::from_row_major_slice`]
    /// view of it reads as the matrix, without the copy [`Operators::apply_rows`] makes).
    pub fn rows_product(&self, which: Which, x: &[f64], w: usize) -> Vec<f64> {
        let mut out = vec![0.0; self.dofs() * w];
        self.spmm(which, x, &mut out, sparse::RowBlock::dense(w));
        out
    }

    /// `Y = K X` or `M X` for a row-major block of vectors ([`sparse::spmm`], and for the
    /// mass [`sparse::spmm_mass`]).
    pub fn spmm(&self, which: Which, x: &[f64], y: &mut [f64], layout: sparse::RowBlock) {
        match which {
            Which::K => sparse::spmm(self.pattern, self.k, x, y, layout),
            Which::M => match self.mass_diagonal {
                Some(m) => {
                    sparse::spmm_mass_diagonal(self.pattern, m, x, y, layout);
                    for &(i, j, v) in self.mass_extra {
                        let (i, j) = (i as usize * layout.stride, j as usize * layout.stride);
                        for c in 0..layout.width {
                            y[i + c] += v * x[j + c];
                        }
                    }
                }
                None => sparse::spmm_mass(self.pattern, self.m, x, y, layout),
            },
        }
    }

    /// Residuals (Jin et al. 2022, eq. 6) of the pairs `(lambdas[j], x[:, j])`, by block products.
    pub fn block_residuals(&self, lambdas: &[f64], x: MatRef<'_, f64>) -> Vec<f64> {
        let kx = self.apply_block(Which::K, x);
        let mx = self.apply_block(Which::M, x);
        (0..x.ncols())
            .map(|j| {
                let (mut r2, mut x2) = (0.0, 0.0);
                for i in 0..x.nrows() {
                    let r = kx[(i, j)] - lambdas[j] * mx[(i, j)];
                    r2 += r * r;
                    x2 += x[(i, j)] * x[(i, j)];
                }
                r2.sqrt() / ((self.k_norm + lambdas[j].abs() * self.m_norm) * x2.sqrt())
            })
            .collect()
    }

    /// Whether an eigenvalue is a rigid-body (zero-frequency) mode.
    pub fn is_rigid(&self, lambda: f64) -> bool {
        lambda < RIGID_RELATIVE * self.scale
    }
}

/// Dense `n x w` row-major copy of a column-major matrix (`out[i * w + j] = mat[(i, j)]`): the
/// layout the block kernels read, a DOF's values side by side.
pub(crate) fn to_rows(mat: MatRef<'_, f64>) -> Vec<f64> {
    let (n, w) = (mat.nrows(), mat.ncols());
    let mut out = vec![0.0; n * w];
    for j in 0..w {
        for (i, &v) in mat.col(j).iter().enumerate() {
            out[i * w + j] = v;
        }
    }
    out
}

/// The column-major matrix of a row-major block of width `w` ([`to_rows`]' inverse).
pub(crate) fn from_rows(rows: &[f64], w: usize) -> Mat<f64> {
    let n = rows.len().checked_div(w).unwrap_or(0);
    let mut out = Mat::<f64>::zeros(n, w);
    for j in 0..w {
        for (i, v) in out.col_mut(j).iter_mut().enumerate() {
            *v = rows[i * w + j];
        }
    }
    out
}
