//! The sparse Cholesky factorisation of the shifted stiffness `K - sigma M` (faer, supernodal),
//! ordered by geometric nested dissection ([`crate::fem::ordering`]), with its solve scratch
//! allocated once and reused (solves in the Lanczos loop allocate nothing of size `nnz(L)`).

use super::EigenError;
use crate::fem::sparse::BlockPattern;
use crate::fem::sparse::RowBlock;
use crate::fem::{ordering, sparse, FemModel};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, LltRef, SymbolicCholesky, SymmetricOrdering,
};
use faer::{Conj, Mat, MatMut, Par, Side};

/// Largest Cholesky factor accepted, in bytes: beyond it the solve would exhaust memory or take
/// minutes; the error suggests LOBPCG or a coarser grid.
pub const MAX_FACTOR_BYTES: usize = 6 << 30;

/// `K - sigma M = L L^T`, ready to solve.
pub struct ShiftedCholesky {
    symbolic: SymbolicCholesky<usize>,
    values: Vec<f64>,
    scratch: MemBuffer,
    max_rhs: usize,
    par: Par,
    dofs: usize,
}

impl ShiftedCholesky {
    /// Factors `K - shift M` of `model`; `max_rhs` bounds the columns of later solves.
    pub fn new(model: &FemModel, shift: f64, max_rhs: usize, par: Par) -> Result<Self, EigenError> {
        let nodes = ordering::nested_dissection(model);
        Self::from_blocks(
            &model.pattern,
            &model.k,
            &model.m,
            shift,
            &nodes,
            max_rhs,
            par,
        )
    }

    /// Factors `K - shift M` given as node blocks, eliminating nodes in the order `nodes`
    /// (`nodes[k]` is the node eliminated `k`-th).
    pub fn from_blocks(
        pattern: &BlockPattern,
        k: &[[f64; 9]],
        m: &[[f64; 9]],
        shift: f64,
        nodes: &[usize],
        max_rhs: usize,
        par: Par,
    ) -> Result<Self, EigenError> {
        let fail = |e: &dyn std::fmt::Debug| EigenError::Factorization(format!("{e:?}"));
        let a = sparse::shifted_upper_csc(pattern, k, m, shift);
        let n = a.nrows();
        // fwd[k] = the DOF eliminated k-th; inv is its inverse.
        let fwd: Vec<usize> = nodes
            .iter()
            .flat_map(|&v| [3 * v, 3 * v + 1, 3 * v + 2])
            .collect();
        let mut inv = vec![0usize; n];
        for (k, &d) in fwd.iter().enumerate() {
            inv[d] = k;
        }
        let perm = PermRef::new_checked(&fwd, &inv, n);
        let symbolic = factorize_symbolic_cholesky(
            a.symbolic(),
            Side::Upper,
            SymmetricOrdering::Custom(perm),
            Default::default(),
        )
        .map_err(|e| fail(&e))?;
        let bytes = symbolic
            .len_val()
            .saturating_mul(std::mem::size_of::<f64>());
        if bytes > MAX_FACTOR_BYTES {
            return Err(EigenError::Factorization(format!(
                "the factor would need {:.1} GB, over the {} GB limit; use --solver lobpcg or a coarser --resolution",
                bytes as f64 / 1e9,
                MAX_FACTOR_BYTES >> 30
            )));
        }
        let mut values = Vec::new();
        values.try_reserve_exact(symbolic.len_val()).map_err(|_| {
            EigenError::Factorization("out of memory for the Cholesky factor".into())
        })?;
        values.resize(symbolic.len_val(), 0.0);
        let mut fac_scratch =
            MemBuffer::new(symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default()));
        symbolic
            .factorize_numeric_llt(
                &mut values,
                a.as_ref(),
                Side::Upper,
                Default::default(),
                par,
                MemStack::new(&mut fac_scratch),
                Default::default(),
            )
            .map_err(|e| fail(&e))?;
        let scratch = MemBuffer::new(symbolic.solve_in_place_scratch::<f64>(max_rhs, par));
        Ok(ShiftedCholesky {
            dofs: n,
            symbolic,
            values,
            scratch,
            max_rhs,
            par,
        })
    }

    /// Nonzeros in the factor.
    pub fn factor_nnz(&self) -> usize {
        self.values.len()
    }

    /// Overwrites `rhs` (at most `max_rhs` columns) with `(K - sigma M)^-1 rhs`.
    pub fn solve_in_place(&mut self, rhs: MatMut<'_, f64>) {
        assert!(
            rhs.ncols() <= self.max_rhs,
            "solve wider than the scratch was sized for"
        );
        LltRef::new(&self.symbolic, &self.values).solve_in_place_with_conj(
            Conj::No,
            rhs,
            self.par,
            MemStack::new(&mut self.scratch),
        );
    }
}

impl super::lobpcg::Preconditioner for ShiftedCholesky {
    /// The exact inverse `(K - sigma M)^-1`, in chunks of `max_rhs` columns (allocates one
    /// column-major copy of a chunk).
    fn apply(&mut self, r: &[f64], r_layout: RowBlock, z: &mut [f64], z_layout: RowBlock) {
        assert_eq!(r_layout.width, z_layout.width);
        let n = self.dofs;
        let mut c0 = 0;
        while c0 < r_layout.width {
            let b = self.max_rhs.min(r_layout.width - c0);
            let mut block = Mat::from_fn(n, b, |i, j| r[i * r_layout.stride + c0 + j]);
            self.solve_in_place(block.as_mut());
            for j in 0..b {
                for (i, v) in block.col(j).iter().enumerate() {
                    z[i * z_layout.stride + c0 + j] = *v;
                }
            }
            c0 += b;
        }
    }
}
