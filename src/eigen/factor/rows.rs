//! Triangular solves with a supernodal Cholesky factor on row-major blocks of right-hand sides.
//!
//! Where it sits: [`super::ShiftedCholesky`] factors `K - sigma M` with faer; every Lanczos
//! block, every exact LOBPCG preconditioner application and the multigrid's coarse level then
//! solve `L L^T X = B` for a block of a few vectors. faer's supernodal solve works on
//! column-major blocks and calls its general dense kernels (triangular solve, matrix product)
//! once per supernode; the factors of voxel objects have thousands of supernodes of 3 to a few
//! dozen columns, where the fixed cost of those calls, not arithmetic, set the time (~3.5 ms
//! for a block of 8 on the 4.6k-DOF default bowl, about the same for 2k or 5k DOFs).
//!
//! Here a block is stored by rows, each row a short array `[f64; W]` (`W` = 8, 4, 2 or 1: a
//! wider block is solved in chunks), so one factor entry is one `W`-wide multiply-add on
//! contiguous memory and a solve is one forward and one backward pass over the factor's values,
//! four columns of a supernode at a time (one load and store of a right-hand-side row serves
//! four factor entries). Kernels are compiled for AVX2 + FMA and picked at run time, with a
//! portable build of the same code as the fallback.

use crate::fma::mul_add;

/// The supernodal structure of a factor, copied from faer's symbolic factorisation and checked
/// once, so the kernels can index without bounds checks.
pub(super) struct SupernodalRows {
    /// Supernode `s` holds the factor's columns `begin[s]..begin[s + 1]`.
    begin: Vec<u32>,
    /// Its rows below the diagonal block: `rows[row_ptr[s]..row_ptr[s + 1]]`, all past its
    /// last column.
    row_ptr: Vec<u32>,
    rows: Vec<u32>,
    /// Its values: `values[val_ptr[s]..val_ptr[s + 1]]`, column-major, `(columns + rows) x
    /// columns` (the diagonal block, then the rows below), faer's layout.
    val_ptr: Vec<usize>,
    /// `1 / L[j, j]` for every column.
    inv_diag: Vec<f64>,
}

/// The factor's layout did not have the shape faer documents (never expected; checked so the
/// kernels' unchecked indexing is sound whatever faer returns).
#[derive(Debug)]
pub(super) struct LayoutError(pub String);

impl SupernodalRows {
    /// Copies and checks the layout of a supernodal factor whose numeric values are `values`.
    pub(super) fn new(
        symbolic: &faer::sparse::linalg::cholesky::supernodal::SymbolicSupernodalCholesky<usize>,
        values: &[f64],
    ) -> Result<Self, LayoutError> {
        let n = symbolic.nrows();
        let count = symbolic.n_supernodes();
        let bad = |what: &str| Err(LayoutError(format!("supernodal factor: {what}")));
        if n >= u32::MAX as usize || values.len() != symbolic.len_val() {
            return bad("size");
        }
        let (mut begin, mut row_ptr, mut rows) = (vec![0u32], vec![0u32], Vec::new());
        let mut val_ptr = vec![0usize];
        let mut inv_diag = vec![0.0; n];
        let starts = symbolic.supernode_begin();
        let ends = symbolic.supernode_end();
        let vptr = symbolic.col_ptr_for_val();
        for s in 0..count {
            let (c0, c1) = (starts[s], ends[s]);
            if c0 != *begin.last().expect("nonempty") as usize || c1 <= c0 || c1 > n {
                return bad("supernode columns");
            }
            let pattern = symbolic.supernode(s).pattern();
            for &r in pattern {
                if r < c1 || r >= n {
                    return bad("row pattern");
                }
                rows.push(r as u32);
            }
            let (nc, ld) = (c1 - c0, c1 - c0 + pattern.len());
            let (v0, v1) = (vptr[s], vptr[s + 1]);
            if v0 != *val_ptr.last().expect("nonempty") || v1 - v0 != ld * nc {
                return bad("value layout");
            }
            for c in 0..nc {
                let d = values[v0 + c * ld + c];
                if !(d > 0.0 && d.is_finite()) {
                    return bad("diagonal");
                }
                inv_diag[c0 + c] = 1.0 / d;
            }
            begin.push(c1 as u32);
            row_ptr.push(rows.len() as u32);
            val_ptr.push(v1);
        }
        if *begin.last().expect("nonempty") as usize != n || val_ptr[count] != values.len() {
            return bad("coverage");
        }
        Ok(SupernodalRows {
            begin,
            row_ptr,
            rows,
            val_ptr,
            inv_diag,
        })
    }

    /// Order of the factor.
    pub(super) fn dofs(&self) -> usize {
        self.inv_diag.len()
    }

    /// Overwrites `x` (row `k` = the right-hand sides' entries of the `k`-th eliminated DOF)
    /// with `(L L^T)^-1 x`; `values` are the factor's (checked in [`Self::new`]).
    pub(super) fn solve<const W: usize>(&self, values: &[f64], x: &mut [[f64; W]]) {
        assert_eq!(x.len(), self.dofs(), "one row per DOF");
        assert_eq!(values.len(), *self.val_ptr.last().expect("nonempty"));
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: the CPU supports AVX2 and FMA (checked just above), the only requirement
            // of the `target_feature` function; lengths were asserted above.
            unsafe { solve_avx2::<W>(self, values, x) };
            return;
        }
        forward::<W, false>(self, values, x);
        backward::<W, false>(self, values, x);
    }

    /// Supernode `s`: first column, column count, rows below, values.
    #[inline(always)]
    fn supernode<'a>(
        &'a self,
        values: &'a [f64],
        s: usize,
    ) -> (usize, usize, &'a [u32], &'a [f64]) {
        let c0 = self.begin[s] as usize;
        let nc = self.begin[s + 1] as usize - c0;
        let rows = &self.rows[self.row_ptr[s] as usize..self.row_ptr[s + 1] as usize];
        (c0, nc, rows, &values[self.val_ptr[s]..self.val_ptr[s + 1]])
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
/// [`SupernodalRows::solve`] compiled for AVX2 + FMA.
unsafe fn solve_avx2<const W: usize>(f: &SupernodalRows, values: &[f64], x: &mut [[f64; W]]) {
    forward::<W, true>(f, values, x);
    backward::<W, true>(f, values, x);
}

/// The below-diagonal parts (`nc..ld`) of supernode columns `c..c + 4`, from a supernode's
/// column-major values `l` (`ld` rows, `nc` of them in the diagonal block).
#[inline(always)]
fn below_four(l: &[f64], c: usize, nc: usize, ld: usize) -> [&[f64]; 4] {
    std::array::from_fn(|k| &l[(c + k) * ld + nc..(c + k + 1) * ld])
}

/// `y -= a x` on one row.
#[inline(always)]
fn sub_scaled<const W: usize, const FMA: bool>(y: &mut [f64; W], a: f64, x: &[f64; W]) {
    for j in 0..W {
        y[j] = mul_add::<FMA, _>(-a, x[j], y[j]);
    }
}

/// `L y = b`, in place, supernode by supernode.
#[inline(always)]
fn forward<const W: usize, const FMA: bool>(
    f: &SupernodalRows,
    values: &[f64],
    x: &mut [[f64; W]],
) {
    for s in 0..f.begin.len() - 1 {
        let (c0, nc, rows, l) = f.supernode(values, s);
        let ld = nc + rows.len();
        let (head, tail) = x.split_at_mut(c0 + nc);
        let top = &mut head[c0..];
        // The diagonal block, column by column.
        for c in 0..nc {
            let d = f.inv_diag[c0 + c];
            let xc = top[c].map(|v| v * d);
            top[c] = xc;
            let col = &l[c * ld..c * ld + nc];
            for r in c + 1..nc {
                sub_scaled::<W, FMA>(&mut top[r], col[r], &xc);
            }
        }
        // The rows below, four columns at a time.
        let first = c0 + nc;
        let mut c = 0;
        while c + 4 <= nc {
            let (t0, t1, t2, t3) = (top[c], top[c + 1], top[c + 2], top[c + 3]);
            let cols = below_four(l, c, nc, ld);
            for (p, &row) in rows.iter().enumerate() {
                // SAFETY: `SupernodalRows::new` checked every pattern row is past this
                // supernode's last column (`first - 1`) and below the order, which
                // `solve` asserted is `x.len()`; so `row - first < tail.len()`.
                let y = unsafe { tail.get_unchecked_mut(row as usize - first) };
                // SAFETY: every column slice has `rows.len()` entries (the value layout was
                // checked in `new`), and `p < rows.len()`.
                let a = unsafe {
                    [
                        *cols[0].get_unchecked(p),
                        *cols[1].get_unchecked(p),
                        *cols[2].get_unchecked(p),
                        *cols[3].get_unchecked(p),
                    ]
                };
                for j in 0..W {
                    let mut v = y[j];
                    v = mul_add::<FMA, _>(-a[0], t0[j], v);
                    v = mul_add::<FMA, _>(-a[1], t1[j], v);
                    v = mul_add::<FMA, _>(-a[2], t2[j], v);
                    v = mul_add::<FMA, _>(-a[3], t3[j], v);
                    y[j] = v;
                }
            }
            c += 4;
        }
        while c < nc {
            let t = top[c];
            let col = &l[c * ld + nc..(c + 1) * ld];
            for (&row, &a) in rows.iter().zip(col) {
                // SAFETY: as above, `row - first < tail.len()`.
                let y = unsafe { tail.get_unchecked_mut(row as usize - first) };
                sub_scaled::<W, FMA>(y, a, &t);
            }
            c += 1;
        }
    }
}

/// `L^T x = y`, in place, supernodes in reverse order.
#[inline(always)]
fn backward<const W: usize, const FMA: bool>(
    f: &SupernodalRows,
    values: &[f64],
    x: &mut [[f64; W]],
) {
    for s in (0..f.begin.len() - 1).rev() {
        let (c0, nc, rows, l) = f.supernode(values, s);
        let ld = nc + rows.len();
        let (head, tail) = x.split_at_mut(c0 + nc);
        let top = &mut head[c0..];
        let first = c0 + nc;
        // The rows below are final: subtract their part from every column, four at a time.
        let mut c = 0;
        while c + 4 <= nc {
            let mut acc = [top[c], top[c + 1], top[c + 2], top[c + 3]];
            let cols = below_four(l, c, nc, ld);
            for (p, &row) in rows.iter().enumerate() {
                // SAFETY: as in `forward`, `row - first < tail.len()`.
                let y = unsafe { tail.get_unchecked(row as usize - first) };
                for (k, col) in cols.iter().enumerate() {
                    // SAFETY: every column slice has `rows.len()` entries, `p < rows.len()`.
                    let a = unsafe { *col.get_unchecked(p) };
                    for j in 0..W {
                        acc[k][j] = mul_add::<FMA, _>(-a, y[j], acc[k][j]);
                    }
                }
            }
            top[c..c + 4].copy_from_slice(&acc);
            c += 4;
        }
        while c < nc {
            let mut acc = top[c];
            let col = &l[c * ld + nc..(c + 1) * ld];
            for (&row, &a) in rows.iter().zip(col) {
                // SAFETY: as above.
                let y = unsafe { tail.get_unchecked(row as usize - first) };
                for j in 0..W {
                    acc[j] = mul_add::<FMA, _>(-a, y[j], acc[j]);
                }
            }
            top[c] = acc;
            c += 1;
        }
        // The diagonal block, last column first.
        for c in (0..nc).rev() {
            let col = &l[c * ld..c * ld + nc];
            let mut acc = top[c];
            for r in c + 1..nc {
                let y = top[r];
                for j in 0..W {
                    acc[j] = mul_add::<FMA, _>(-col[r], y[j], acc[j]);
                }
            }
            let d = f.inv_diag[c0 + c];
            top[c] = acc.map(|v| v * d);
        }
    }
}
