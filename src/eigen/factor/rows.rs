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
//! contiguous memory and a solve is one forward and one backward pass over the factor's values.
//! The supernodes of the hex27 factors are large (the default bowl's whole factor: 112
//! supernodes of 53 columns on average), so the passes are dense products, and they run at the
//! speed the factor streams from cache. The values are therefore copied once, after the
//! numeric factorisation, from faer's column-major supernodes into panels of [`R`] rows stored
//! column by column (`[k][i]`, [`SupernodalRows::new`]): both passes then read the factor in
//! order, four rows of a column at a time, with the products of a panel against the block in
//! registers (eight independent 4-wide accumulators for a block of eight). Reading faer's
//! layout directly, one pass strided across columns and the other re-read right-hand-side rows
//! four columns at a time: a block of eight on the default bowl's whole factor (5,967 DOFs,
//! 1.75M entries) took 5.4-5.5 ms, against 2.5-3.3 ms in panels (stop 47, `cargo bench
//! --bench eigen -- solve_bowl16`, the two builds interleaved), and a whole solve of 60 modes
//! 282-334 ms against 239-279 ms.
//! Kernels are compiled for AVX2 + FMA and picked at run time, with a portable build of the
//! same code as the fallback.

use crate::buffer;
use crate::fma::mul_add;

/// Rows of a panel: four rows against a block of eight right-hand sides keep eight independent
/// 4-wide accumulators, what two FMA pipes with a four-cycle latency need to stay busy.
const R: usize = 4;

/// The supernodal structure of a factor, copied from faer's symbolic factorisation and checked
/// once, so the kernels can index without bounds checks.
pub(super) struct SupernodalRows {
    /// Supernode `s` holds the factor's columns `begin[s]..begin[s + 1]`.
    begin: Vec<u32>,
    /// Its rows below the diagonal block: `rows[row_ptr[s]..row_ptr[s + 1]]`, all past its
    /// last column.
    row_ptr: Vec<u32>,
    rows: Vec<u32>,
    /// Its packed values: `values[val_ptr[s]..val_ptr[s + 1]]` (the layout
    /// [`SupernodalRows::new`] makes).
    val_ptr: Vec<usize>,
    /// `1 / L[j, j]` for every column.
    inv_diag: Vec<f64>,
}

/// The factor's layout did not have the shape faer documents (never expected; checked so the
/// kernels' unchecked indexing is sound whatever faer returns).
#[derive(Debug)]
pub(super) struct LayoutError(pub String);

/// Values a supernode of `nc` columns and `below` rows below takes in panels: its diagonal
/// block's panels hold the columns up to their last row (panel `q`, rows `4q..4q + n`, holds
/// `4q + n` columns), the panels of the rows below hold every column.
fn packed_len(nc: usize, below: usize) -> usize {
    let full = nc / R;
    let diagonal = R * R * full * (full + 1) / 2 + if nc.is_multiple_of(R) { 0 } else { R * nc };
    diagonal + R * nc * below.div_ceil(R)
}

/// Values the packed copy of a factor with this symbolic structure takes.
pub(super) fn packed_total(
    symbolic: &faer::sparse::linalg::cholesky::supernodal::SymbolicSupernodalCholesky<usize>,
) -> usize {
    let (starts, ends) = (symbolic.supernode_begin(), symbolic.supernode_end());
    (0..symbolic.n_supernodes())
        .map(|s| packed_len(ends[s] - starts[s], symbolic.supernode(s).pattern().len()))
        .sum()
}

impl SupernodalRows {
    /// Copies and checks the layout of a supernodal factor whose numeric values are `values`
    /// (faer's column-major supernodes), and packs those values into panels of [`R`] rows, each
    /// stored column by column (`panel[k * R + i] = L[row + i, k]`, zero past the supernode's
    /// last row and above the diagonal). Within a supernode: the diagonal block's panels, then
    /// those of the rows below. The packed values come from the process's kept buffers.
    pub(super) fn new(
        symbolic: &faer::sparse::linalg::cholesky::supernodal::SymbolicSupernodalCholesky<usize>,
        values: &[f64],
    ) -> Result<(Self, Vec<f64>), LayoutError> {
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
        let mut v_end = 0;
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
            if v0 != v_end || v1 - v0 != ld * nc {
                return bad("value layout");
            }
            v_end = v1;
            for c in 0..nc {
                let d = values[v0 + c * ld + c];
                if !(d > 0.0 && d.is_finite()) {
                    return bad("diagonal");
                }
                inv_diag[c0 + c] = 1.0 / d;
            }
            begin.push(c1 as u32);
            row_ptr.push(rows.len() as u32);
            val_ptr.push(val_ptr[s] + packed_len(nc, pattern.len()));
        }
        if *begin.last().expect("nonempty") as usize != n || v_end != values.len() {
            return bad("coverage");
        }
        let layout = SupernodalRows {
            begin,
            row_ptr,
            rows,
            val_ptr,
            inv_diag,
        };
        let total = *layout.val_ptr.last().expect("nonempty");
        // Every entry is written below (a short panel's missing rows as zeros), so the
        // buffer is not cleared first.
        let mut packed = buffer::take_unfilled::<f64>(total)
            .map_err(|_| LayoutError("out of memory for the packed factor".into()))?;
        for s in 0..count {
            let (_, nc, below) = layout.shape(s);
            let ld = nc + below.len();
            let from = &values[vptr[s]..vptr[s + 1]];
            let to = &mut packed[layout.val_ptr[s]..layout.val_ptr[s + 1]];
            let mut at = 0;
            for (row, kc, span) in layout.panels(nc, ld) {
                if span == R && row >= nc {
                    // A full panel below the diagonal block (most of the entries): four of
                    // the factor's values per column, as they are. (Copied without the
                    // per-entry test below, the packing's own time in a perf profile of the
                    // 32^3 sphere's class solve went from 5.7 to 4.0 % of the whole.)
                    for k in 0..kc {
                        let column = &from[k * ld + row..k * ld + row + R];
                        to[at + k * R..at + (k + 1) * R].copy_from_slice(column);
                    }
                    at += kc * R;
                    continue;
                }
                for k in 0..kc {
                    let column = &from[k * ld..(k + 1) * ld];
                    let out = &mut to[at + k * R..at + (k + 1) * R];
                    for (i, v) in out.iter_mut().enumerate() {
                        // Zero above the diagonal and below a short panel's last row.
                        *v = if i < span && row + i >= k {
                            column[row + i]
                        } else {
                            0.0
                        };
                    }
                }
                at += kc * R;
            }
        }
        Ok((layout, packed))
    }

    /// Order of the factor.
    pub(super) fn dofs(&self) -> usize {
        self.inv_diag.len()
    }

    /// Supernode `s`: its first column, column count and rows below.
    #[inline(always)]
    fn shape(&self, s: usize) -> (usize, usize, &[u32]) {
        let c0 = self.begin[s] as usize;
        let nc = self.begin[s + 1] as usize - c0;
        let rows = &self.rows[self.row_ptr[s] as usize..self.row_ptr[s + 1] as usize];
        (c0, nc, rows)
    }

    /// The panels of a supernode of `nc` columns and `ld` rows, in packed order: each panel's
    /// first row, its column count and its row count (`R`, or fewer in a block's last panel).
    #[inline(always)]
    fn panels(&self, nc: usize, ld: usize) -> impl Iterator<Item = (usize, usize, usize)> {
        let diagonal = (0..nc)
            .step_by(R)
            .map(move |g| (g, g + R.min(nc - g), R.min(nc - g)));
        let below = (nc..ld).step_by(R).map(move |p| (p, nc, R.min(ld - p)));
        diagonal.chain(below)
    }

    /// Overwrites `x` (row `k` = the right-hand sides' entries of the `k`-th eliminated DOF)
    /// with `(L L^T)^-1 x`; `values` are the packed factor [`Self::new`] returned.
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

    /// The portable build of [`Self::solve`] (the two builds are compared in the tests).
    #[cfg(test)]
    pub(super) fn solve_portable<const W: usize>(&self, values: &[f64], x: &mut [[f64; W]]) {
        assert_eq!(x.len(), self.dofs(), "one row per DOF");
        assert_eq!(values.len(), *self.val_ptr.last().expect("nonempty"));
        forward::<W, false>(self, values, x);
        backward::<W, false>(self, values, x);
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
/// [`SupernodalRows::solve`] compiled for AVX2 + FMA.
unsafe fn solve_avx2<const W: usize>(f: &SupernodalRows, values: &[f64], x: &mut [[f64; W]]) {
    forward::<W, true>(f, values, x);
    backward::<W, true>(f, values, x);
}

/// `acc[i] = sum_{k < kc} panel[k R + i] t[k]`: a panel's rows times the block's rows `t`, read
/// in order with every accumulator in a register.
#[inline(always)]
fn panel_times<const W: usize, const FMA: bool>(
    panel: &[f64],
    t: &[[f64; W]],
    kc: usize,
) -> [[f64; W]; R] {
    let mut acc = [[0.0; W]; R];
    let (panel, t) = (&panel[..kc * R], &t[..kc]);
    for (a, tk) in panel.chunks_exact(R).zip(t) {
        for i in 0..R {
            for j in 0..W {
                acc[i][j] = mul_add::<FMA, _>(a[i], tk[j], acc[i][j]);
            }
        }
    }
    acc
}

/// `t[k] -= sum_i panel[k R + i] y[i]` for `k < kc`: the transposed product, a panel's final
/// rows `y` (in registers) taken from every column's row.
#[inline(always)]
fn subtract_transposed<const W: usize, const FMA: bool>(
    panel: &[f64],
    y: &[[f64; W]; R],
    t: &mut [[f64; W]],
    kc: usize,
) {
    let (panel, t) = (&panel[..kc * R], &mut t[..kc]);
    #[cfg(target_arch = "x86_64")]
    if FMA && W == 8 {
        // SAFETY: `FMA` is set only inside `solve_avx2`, which runs where the CPU has AVX2 and
        // FMA; with `W == 8` the casts are between identical types, and `panel` holds `kc * R`
        // entries for the `kc` rows of `t` (both sliced just above).
        unsafe {
            let y = &*(y as *const [[f64; W]; R]).cast::<[[f64; 8]; R]>();
            let t = std::slice::from_raw_parts_mut(t.as_mut_ptr().cast::<[f64; 8]>(), kc);
            subtract_transposed_avx2(panel, y, t);
        }
        return;
    }
    let minus_y = y.map(|row| row.map(|v| -v));
    for (a, tk) in panel.chunks_exact(R).zip(t) {
        let mut v = *tk;
        for i in 0..R {
            for j in 0..W {
                v[j] = mul_add::<FMA, _>(a[i], minus_y[i][j], v[j]);
            }
        }
        *tk = v;
    }
}

/// [`subtract_transposed`] for blocks of eight with AVX2 + FMA, in intrinsics: the compiler's
/// own vectorisation of the generic loop transposed four columns at a time through the stack.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline]
unsafe fn subtract_transposed_avx2(panel: &[f64], y: &[[f64; 8]; R], t: &mut [[f64; 8]]) {
    use std::arch::x86_64::*;
    assert_eq!(
        panel.len(),
        t.len() * R,
        "a panel entry per row of t and panel row"
    );
    // SAFETY: each `y[i]` is 8 contiguous floats; the loads are unaligned ones.
    let ys: [[__m256d; 2]; R] = std::array::from_fn(|i| unsafe {
        let p = y[i].as_ptr();
        [_mm256_loadu_pd(p), _mm256_loadu_pd(p.add(4))]
    });
    let a = panel.as_ptr();
    for (k, tk) in t.iter_mut().enumerate() {
        let p = tk.as_mut_ptr();
        // SAFETY: row `k` of `t` is 8 contiguous floats at `p` (unaligned loads and stores);
        // its panel entries are `panel[k R..k R + R]`, in bounds as `k < t.len()` and
        // `panel.len() = t.len() R` (asserted above).
        unsafe {
            let (mut lo, mut hi) = (_mm256_loadu_pd(p), _mm256_loadu_pd(p.add(4)));
            for (i, [y_lo, y_hi]) in ys.iter().enumerate() {
                let ai = _mm256_broadcast_sd(&*a.add(k * R + i));
                lo = _mm256_fnmadd_pd(ai, *y_lo, lo);
                hi = _mm256_fnmadd_pd(ai, *y_hi, hi);
            }
            _mm256_storeu_pd(p, lo);
            _mm256_storeu_pd(p.add(4), hi);
        }
    }
}

/// `L y = b`, in place, supernode by supernode, panel by panel: a panel's rows take the
/// products with every column solved before them (the diagonal block's earlier columns, or all
/// of them for the rows below), then a diagonal panel solves its own small triangle.
#[inline(always)]
fn forward<const W: usize, const FMA: bool>(
    f: &SupernodalRows,
    values: &[f64],
    x: &mut [[f64; W]],
) {
    for s in 0..f.begin.len() - 1 {
        let (c0, nc, rows) = f.shape(s);
        let ld = nc + rows.len();
        let v = &values[f.val_ptr[s]..f.val_ptr[s + 1]];
        let (head, tail) = x.split_at_mut(c0 + nc);
        let top = &mut head[c0..];
        let first = c0 + nc;
        let mut at = 0;
        for (row, kc, n) in f.panels(nc, ld) {
            let panel = &v[at..at + kc * R];
            at += kc * R;
            if row < nc {
                // A diagonal panel: its columns before `row`, then its triangle.
                let acc = panel_times::<W, FMA>(panel, top, row);
                for (i, a) in acc.iter().enumerate().take(n) {
                    for j in 0..W {
                        top[row + i][j] -= a[j];
                    }
                }
                for c in row..row + n {
                    let xc = top[c].map(|v| v * f.inv_diag[c0 + c]);
                    top[c] = xc;
                    for r in c + 1..row + n {
                        let a = panel[c * R + r - row];
                        for j in 0..W {
                            top[r][j] = mul_add::<FMA, _>(-a, xc[j], top[r][j]);
                        }
                    }
                }
            } else {
                let acc = panel_times::<W, FMA>(panel, top, nc);
                for (i, a) in acc.iter().enumerate().take(n) {
                    // SAFETY: a panel's rows lie in the supernode's `ld`, so `row - nc + i <
                    // rows.len()` (`i < n`); `SupernodalRows::new` checked every pattern row is
                    // past this supernode's last column (`first - 1`) and below the order,
                    // which `solve` asserted is `x.len()`; so `row - first < tail.len()`.
                    let y = unsafe {
                        tail.get_unchecked_mut(*rows.get_unchecked(row - nc + i) as usize - first)
                    };
                    for j in 0..W {
                        y[j] -= a[j];
                    }
                }
            }
        }
    }
}

/// `L^T x = y`, in place, supernodes in reverse order: the rows below are final, so each panel
/// of them is taken from the supernode's rows; then the diagonal panels from the last: each
/// solves its triangle and is taken from the rows before it.
#[inline(always)]
fn backward<const W: usize, const FMA: bool>(
    f: &SupernodalRows,
    values: &[f64],
    x: &mut [[f64; W]],
) {
    for s in (0..f.begin.len() - 1).rev() {
        let (c0, nc, rows) = f.shape(s);
        let ld = nc + rows.len();
        let v = &values[f.val_ptr[s]..f.val_ptr[s + 1]];
        let (head, tail) = x.split_at_mut(c0 + nc);
        let top = &mut head[c0..];
        let first = c0 + nc;
        let diagonal_len = packed_len(nc, 0);
        let mut at = diagonal_len;
        for (row, kc, n) in f.panels(nc, ld).filter(|p| p.0 >= nc) {
            let panel = &v[at..at + kc * R];
            at += kc * R;
            let y: [[f64; W]; R] = std::array::from_fn(|i| {
                if i < n {
                    // SAFETY: as in `forward`, `row - nc + i < rows.len()` and
                    // `row - first < tail.len()`.
                    unsafe {
                        *tail.get_unchecked(*rows.get_unchecked(row - nc + i) as usize - first)
                    }
                } else {
                    [0.0; W]
                }
            });
            subtract_transposed::<W, FMA>(panel, &y, top, nc);
        }
        // The diagonal panels, last first (their packed ends are `at`, walking back).
        let mut end = diagonal_len;
        let mut row = (nc - 1) / R * R;
        loop {
            let n = R.min(nc - row);
            let kc = row + n;
            let panel = &v[end - kc * R..end];
            end -= kc * R;
            for c in (row..row + n).rev() {
                let mut acc = top[c];
                for r in c + 1..row + n {
                    let a = panel[c * R + r - row];
                    for j in 0..W {
                        acc[j] = mul_add::<FMA, _>(-a, top[r][j], acc[j]);
                    }
                }
                top[c] = acc.map(|v| v * f.inv_diag[c0 + c]);
            }
            let y: [[f64; W]; R] =
                std::array::from_fn(|i| if i < n { top[row + i] } else { [0.0; W] });
            subtract_transposed::<W, FMA>(panel, &y, top, row);
            if row == 0 {
                break;
            }
            row -= R;
        }
    }
}
