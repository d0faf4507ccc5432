//! Eigenvalues of a small symmetric band matrix and the last rows of its eigenvectors, in
//! `O(n^2 kd)` operations.
//!
//! Where it sits: the Lanczos convergence checks ([`super::lanczos`]). Block Lanczos projects
//! the operator onto a block tridiagonal matrix `H` (half-bandwidth `kd` = the block size), and
//! the residual estimate of a Ritz pair needs only its eigenvalue and the last block's rows of
//! its eigenvector (the Lanczos relation). A dense eigen-decomposition of a 200 x 200 `H` costs
//! ~4 ms, more than the block's triangular solves on small objects, and a solve checks several
//! times; this costs ~1.5 ms (one core, `n = 200`, `kd = 8`).
//!
//! The method is the classical one (e.g. LAPACK's `dsbtrd` and `dsteqr`, EISPACK's `tql2`):
//! - Band to tridiagonal by Givens rotations with bulge chasing (Rutishauser 1963, Schwarz
//!   1968): zero the outermost diagonal element by element, chase each bulge down the band.
//! - Tridiagonal eigenvalues by the implicit QL algorithm with Wilkinson-like shifts (Bowdler,
//!   Martin, Reinsch and Wilkinson 1968).
//! - Every rotation of both stages is applied to the requested rows of the accumulated
//!   orthogonal matrix only (`rows x n`, not `n x n`), which is what makes it cheap.
//!
//! The QL recurrence is latency-bound (a square root and a division per rotation, in a chain),
//! so small checks cost more than their operation count says: 8 us at `n = 12`, 90 us at
//! `n = 38` (`kd = 2`). It is compiled for AVX2/FMA where the CPU has them (fused
//! multiply-adds shorten the chain, the accumulated rows rotate 4 wide): 0.87x the time of
//! the portable build on the projected matrices of a bar's class solves.
//!
//! Both stages apply orthogonal transformations, so the eigenvalues are backward stable (error
//! ~eps `||A||`) and the eigenvector rows as accurate as the gaps allow (~eps `||A||` / gap).

use super::EigenError;
use crate::fma::mul_add;
use faer::Mat;

/// Eigenvalues of a symmetric band matrix, ascending, with the matching eigenvector rows.
pub struct BandEigen {
    /// Eigenvalues, ascending.
    pub values: Vec<f64>,
    /// `rows x n`: column `k` holds the requested rows of the eigenvector of `values[k]`.
    pub rows: Mat<f64>,
}

/// `sqrt(x^2 + y^2)` without glibc's correctly rounded `hypot`, which took more than half of
/// the time; values whose squares would overflow or underflow fall back to it.
#[inline]
fn hypot(x: f64, y: f64) -> f64 {
    let h = (x * x + y * y).sqrt();
    if h.is_finite() && h > 1e-150 {
        h
    } else {
        x.hypot(y)
    }
}

/// Most implicit QL sweeps one eigenvalue may take (it takes 1-3 in practice).
const MAX_SWEEPS: usize = 60;

/// The eigenvalues of the symmetric matrix `a` (dense storage, `n x n`; only entries within
/// `kd` of the diagonal are read, the two triangles averaged) and rows `first_row..n` of its
/// eigenvectors.
pub fn band_eigen(a: &Mat<f64>, kd: usize, first_row: usize) -> Result<BandEigen, EigenError> {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU supports AVX2 and FMA (checked just above), the only requirement of
        // the `target_feature` function; it is the same safe code compiled for them.
        return unsafe { band_eigen_avx2(a, kd, first_row) };
    }
    band_eigen_in::<false>(a, kd, first_row)
}

/// [`band_eigen_in`] compiled for AVX2/FMA: the rotations of the accumulated rows are 4 wide
/// and the QL recurrence's multiply-adds fused (a shorter dependency chain).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn band_eigen_avx2(
    a: &Mat<f64>,
    kd: usize,
    first_row: usize,
) -> Result<BandEigen, EigenError> {
    band_eigen_in::<true>(a, kd, first_row)
}

/// [`band_eigen`], its multiply-adds fused where `FMA` ([`crate::fma`]).
#[inline(always)]
fn band_eigen_in<const FMA: bool>(
    a: &Mat<f64>,
    kd: usize,
    first_row: usize,
) -> Result<BandEigen, EigenError> {
    let n = a.nrows();
    assert!(
        a.ncols() == n && first_row <= n,
        "a square matrix and rows within it"
    );
    let kd = kd.min(n.saturating_sub(1));
    let mut band = LowerBand::new(n, kd + 1);
    for j in 0..n {
        for i in j..(j + kd + 1).min(n) {
            let v = 0.5 * (a[(i, j)] + a[(j, i)]);
            if !v.is_finite() {
                return Err(EigenError::NonFinite);
            }
            band.set(i, j, v);
        }
    }
    let rows = n - first_row;
    let mut z = Accumulated {
        rows,
        z: vec![0.0; rows * n],
    };
    for r in 0..rows {
        z.z[(first_row + r) * rows + r] = 1.0;
    }
    band.tridiagonalise::<FMA>(kd, &mut z);
    let mut d: Vec<f64> = (0..n).map(|i| band.get(i, i)).collect();
    let mut e: Vec<f64> = (0..n)
        .map(|i| if i + 1 < n { band.get(i + 1, i) } else { 0.0 })
        .collect();
    ql_implicit::<FMA>(&mut d, &mut e, &mut z)?;
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&x, &y| d[x].total_cmp(&d[y]));
    Ok(BandEigen {
        values: order.iter().map(|&k| d[k]).collect(),
        rows: Mat::from_fn(rows, n, |r, k| z.z[order[k] * rows + r]),
    })
}

/// The lower triangle of a symmetric matrix within `width` of the diagonal, by diagonals:
/// `W[i][j]` (`i >= j`) at `(i - j) n + j`.
struct LowerBand {
    n: usize,
    data: Vec<f64>,
}

impl LowerBand {
    fn new(n: usize, width: usize) -> Self {
        LowerBand {
            n,
            data: vec![0.0; (width + 1) * n],
        }
    }

    #[inline]
    fn at(&self, i: usize, j: usize) -> usize {
        (i - j) * self.n + j
    }

    #[inline]
    fn get(&self, i: usize, j: usize) -> f64 {
        self.data[self.at(i, j)]
    }

    #[inline]
    fn set(&mut self, i: usize, j: usize, v: f64) {
        let k = self.at(i, j);
        self.data[k] = v;
    }

    /// `W <- G W G^T` for the rotation `G` in the plane `(p, p + 1)` (`G[p][p] = G[q][q] = c`,
    /// `G[p][q] = s`, `G[q][p] = -s`), every nonzero of rows `p` and `p + 1` lying in columns
    /// `lo..hi`; and `Z <- Z G^T` for the accumulated rows.
    #[inline(always)]
    fn rotate<const FMA: bool>(
        &mut self,
        z: &mut Accumulated,
        p: usize,
        (c, s): (f64, f64),
        (lo, hi): (usize, usize),
    ) {
        let q = p + 1;
        for k in lo..p {
            let (ip, iq) = (self.at(p, k), self.at(q, k));
            let (x, y) = (self.data[ip], self.data[iq]);
            self.data[ip] = c * x + s * y;
            self.data[iq] = c * y - s * x;
        }
        let (ia, ib, id) = (self.at(p, p), self.at(q, p), self.at(q, q));
        let (a, b, d) = (self.data[ia], self.data[ib], self.data[id]);
        let (cc, ss, cs) = (c * c, s * s, c * s);
        self.data[ia] = cc * a + 2.0 * cs * b + ss * d;
        self.data[id] = ss * a - 2.0 * cs * b + cc * d;
        self.data[ib] = (cc - ss) * b + cs * (d - a);
        for k in q + 1..hi {
            let (ip, iq) = (self.at(k, p), self.at(k, q));
            let (x, y) = (self.data[ip], self.data[iq]);
            self.data[ip] = c * x + s * y;
            self.data[iq] = c * y - s * x;
        }
        z.rotate::<FMA>(p, q, c, s);
    }

    /// Reduces the band (half-bandwidth `kd`, stored with room for one more diagonal, the
    /// bulge) to tridiagonal form by Givens rotations, accumulating them into `z`.
    #[inline(always)]
    fn tridiagonalise<const FMA: bool>(&mut self, kd: usize, z: &mut Accumulated) {
        let n = self.n;
        // One diagonal at a time, from the outermost.
        for bw in (2..=kd).rev() {
            for j in 0..n - bw {
                // Zero W[j + bw][j] by rotating rows (j + bw - 1, j + bw). That makes a bulge
                // at (j + 2 bw, j + bw - 1), one beyond the band, which the same kind of
                // rotation chases down and off the end.
                let (mut row, mut col) = (j + bw, j);
                while row < n {
                    let (x, y) = (self.get(row - 1, col), self.get(row, col));
                    if y == 0.0 {
                        break;
                    }
                    let r = hypot(x, y);
                    self.rotate::<FMA>(z, row - 1, (x / r, y / r), (col, (row + bw + 1).min(n)));
                    self.set(row, col, 0.0);
                    col = row - 1;
                    row += bw;
                }
            }
        }
    }
}

/// Rows of the accumulated orthogonal matrix, by column (`z[i rows + r]` is row `r` of column
/// `i`): the columns a rotation mixes are contiguous.
struct Accumulated {
    rows: usize,
    z: Vec<f64>,
}

impl Accumulated {
    /// `Z <- Z G^T` for the rotation of [`LowerBand::rotate`] in the plane `(p, q)`, `p < q`.
    #[inline(always)]
    fn rotate<const FMA: bool>(&mut self, p: usize, q: usize, c: f64, s: f64) {
        let r = self.rows;
        let (head, tail) = self.z.split_at_mut(q * r);
        for (zp, zq) in head[p * r..(p + 1) * r].iter_mut().zip(&mut tail[..r]) {
            let (x, y) = (*zp, *zq);
            *zp = mul_add::<FMA, _>(c, x, s * y);
            *zq = mul_add::<FMA, _>(c, y, -(s * x));
        }
    }
}

/// Eigenvalues of the symmetric tridiagonal `(d, e)` in place (unsorted) by the implicit QL
/// algorithm (EISPACK `tql2`, as in Numerical Recipes' `tqli`), accumulating its rotations into
/// the columns of `z`.
#[inline(always)]
fn ql_implicit<const FMA: bool>(
    d: &mut [f64],
    e: &mut [f64],
    z: &mut Accumulated,
) -> Result<(), EigenError> {
    let n = d.len();
    for l in 0..n {
        let mut sweeps = 0;
        loop {
            let mut m = l;
            while m + 1 < n {
                let dd = d[m].abs() + d[m + 1].abs();
                if e[m].abs() <= f64::EPSILON * dd {
                    break;
                }
                m += 1;
            }
            if m == l {
                break;
            }
            sweeps += 1;
            if sweeps > MAX_SWEEPS {
                return Err(EigenError::NonFinite);
            }
            let mut g = (d[l + 1] - d[l]) / (2.0 * e[l]);
            let mut r = hypot(g, 1.0);
            g = d[m] - d[l] + e[l] / (g + r.copysign(g));
            let (mut s, mut c, mut p) = (1.0, 1.0, 0.0);
            let mut deflated = false;
            for i in (l..m).rev() {
                let f = s * e[i];
                let b = c * e[i];
                r = hypot(f, g);
                e[i + 1] = r;
                if r == 0.0 {
                    // Underflow: the matrix splits here; start the sweep again.
                    d[i + 1] -= p;
                    e[m] = 0.0;
                    deflated = true;
                    break;
                }
                s = f / r;
                c = g / r;
                g = d[i + 1] - p;
                r = mul_add::<FMA, _>(d[i] - g, s, 2.0 * c * b);
                p = s * r;
                d[i + 1] = g + p;
                g = mul_add::<FMA, _>(c, r, -b);
                // z[:, i + 1] = s z[:, i] + c z[:, i + 1]; z[:, i] = c z[:, i] - s z[:, i + 1]:
                // the rotation of [`Accumulated::rotate`] with (c, -s).
                z.rotate::<FMA>(i, i + 1, c, -s);
            }
            if deflated {
                continue;
            }
            d[l] -= p;
            e[l] = g;
            e[m] = 0.0;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eigen::sym_eigen;

    /// A random symmetric band matrix (entries uniform in [-1, 1)).
    fn random_band(n: usize, kd: usize, seed: u64) -> Mat<f64> {
        let mut rng = crate::rng::SplitMix64::new(seed);
        let mut next = || rng.range(-1.0, 1.0);
        let mut a = Mat::<f64>::zeros(n, n);
        for j in 0..n {
            for i in j..(j + kd + 1).min(n) {
                let v = next();
                a[(i, j)] = v;
                a[(j, i)] = v;
            }
        }
        a
    }

    /// Against the dense eigen-decomposition (faer): the eigenvalues to `eps n ||A||` (both are
    /// backward stable: ~1e-15 here, bound 1e-12), and the eigenvector rows up to sign to
    /// `1e-9`: their error is ~eps `||A||` / gap, and the smallest gap of these random matrices
    /// is above 1e-4 (asserted, so the bound means something).
    #[test]
    fn matches_the_dense_decomposition() {
        for (n, kd, seed) in [
            (1, 1, 3),
            (2, 1, 5),
            (9, 8, 7),
            (40, 1, 11),
            (60, 4, 13),
            (120, 8, 17),
        ] {
            let a = random_band(n, kd, seed);
            let (values, vectors) = sym_eigen(&a).expect("dense");
            let first = n.saturating_sub(kd);
            let band = band_eigen(&a, kd, first).expect("band");
            let gap = values
                .windows(2)
                .map(|w| w[1] - w[0])
                .fold(f64::INFINITY, f64::min);
            assert!(gap > 1e-4, "n {n}: gap {gap:e}");
            for k in 0..n {
                assert!(
                    (band.values[k] - values[k]).abs() <= 1e-12,
                    "n {n} kd {kd}: eigenvalue {k}: {} vs {}",
                    band.values[k],
                    values[k]
                );
                let dot: f64 = (first..n)
                    .map(|i| band.rows[(i - first, k)] * vectors[(i, k)])
                    .sum();
                let sign = if dot < 0.0 { -1.0 } else { 1.0 };
                for i in first..n {
                    let diff = band.rows[(i - first, k)] - sign * vectors[(i, k)];
                    assert!(
                        diff.abs() <= 1e-9,
                        "n {n} kd {kd}: vector {k} row {i}: {diff:e}"
                    );
                }
            }
        }
    }

    /// The portable build (multiplies and adds) and the FMA one that runs on AVX2 machines
    /// agree to rounding: eigenvalues to 1e-12 and eigenvector rows up to sign to 1e-9, the
    /// bounds of the dense comparison above (both are backward stable).
    #[test]
    fn the_portable_build_matches_the_fused_one() {
        for (n, kd, seed) in [(24, 2, 29), (40, 4, 31), (90, 8, 37)] {
            let a = random_band(n, kd, seed);
            let (fused, plain) = (
                band_eigen(&a, kd, 0).unwrap(),
                band_eigen_in::<false>(&a, kd, 0).unwrap(),
            );
            for k in 0..n {
                assert!(
                    (fused.values[k] - plain.values[k]).abs() <= 1e-12,
                    "n {n}: {k}"
                );
                let dot: f64 = (0..n)
                    .map(|i| fused.rows[(i, k)] * plain.rows[(i, k)])
                    .sum();
                for i in 0..n {
                    let diff = fused.rows[(i, k)] - dot.signum() * plain.rows[(i, k)];
                    assert!(diff.abs() <= 1e-9, "n {n}: vector {k} row {i}: {diff:e}");
                }
            }
        }
    }

    /// Entries beyond the band are not read: a matrix with junk outside it gives the band's
    /// answer.
    #[test]
    fn reads_only_the_band() {
        let a = random_band(30, 3, 23);
        let mut junk = a.clone();
        junk[(20, 2)] = 5.0;
        junk[(2, 25)] = -7.0;
        let (clean, noisy) = (
            band_eigen(&a, 3, 27).unwrap(),
            band_eigen(&junk, 3, 27).unwrap(),
        );
        assert_eq!(clean.values, noisy.values);
    }
}
