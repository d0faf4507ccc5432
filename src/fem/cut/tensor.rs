//! Sum-factorised cut-element integrals for the triquadratic element (hex27).
//!
//! Where it sits: [`super::CutElement`] evaluates a partial voxel's matrices as a fill-weighted
//! sum of sub-cell matrices. For hex27 the table of sub-cell matrices is `2 x 81^2` entries by
//! 64 sub-cells, so that sum costs 0.84 M multiply-adds per element, which made the assembly of
//! a curved object 4-5x slower than its staircase's. Every integrand here is a product of 1D
//! factors, one per axis, and the fill is constant on each sub-cell, so the same integrals
//! factor axis by axis (sum factorisation, Orszag 1980; used for the finite cell method's
//! sub-cells since Düster, Parvizian, Yang and Rank 2008):
//!
//! `int chi d_i N_a d_j N_b = sum_{c1 c2 c3} chi[c] A_x[c1](a1, b1) A_y[c2](a2, b2) A_z[c3](a3, b3)`
//!
//! where `A_k[c](f, g)` is the 1D integral over sub-cell `c` of the two 1D factors along axis
//! `k`, differentiated where `k` is `i` (the first) or `j` (the second). Contracting one axis
//! at a time costs `s^3 9 + s^2 81 + s 729` multiply-adds (4.8 k for `s = 4`) per integral,
//! seven integrals per element (six derivative pairs and the mass): 25x fewer than the table
//! (12 us per element on one core of this machine, against 46 us with the table). The x
//! contraction, the largest term, depends only on the x table, of which the seven integrals
//! use three, and a row of sub-cells filled alike (a full or empty voxel's) contracts to one
//! weight times the table's row sum: what keeps hex27x2's 16 sub-cells per axis (2 voxels of
//! refined 8^3, `crate::shape::refine`) affordable.
//! The stiffness follows from the derivative integrals `I^{ij}(a, b)` with Lamé's constants:
//! `K(3a+c, 3b+d) = lambda I^{cd}(a, b) + mu I^{dc}(a, b) + mu delta_cd sum_l I^{ll}(a, b)`,
//! which is `int B^T D B` for isotropic `D` written out.

use super::EMPTY_SUBCELL_FLOOR;
use crate::fem::element::{basis_1d, gauss};

/// Lagrange factors per axis (hex27: nodes at `xi = -1, 0, 1`).
const M: usize = 3;
/// Pairs of factors per axis, `f * M + g`.
const P: usize = M * M;
/// Nodes of the element and DOFs.
const NODES: usize = M * M * M;
const NDOF: usize = 3 * NODES;

/// Where the integral of nodes `a` and `b` sits in a flattened `[pair_z][pair_y][pair_x]`
/// tensor (node `a = ax + 3 (ay + 3 az)`).
fn pair_index(a: usize, b: usize) -> usize {
    let (ax, ay, az) = (a % M, (a / M) % M, a / (M * M));
    let (bx, by, bz) = (b % M, (b / M) % M, b / (M * M));
    ((az * M + bz) * P + ay * M + by) * P + ax * M + bx
}

/// hex27's cut-element integrals for one sub-cell count and Poisson's ratio.
#[derive(Clone, Debug)]
pub struct Hex27Subcells {
    per_axis: usize,
    /// The 1D integrals of one axis, per sub-cell: `table[p][q][c][f * M + g] = int_c f^(p)
    /// g^(q) dx` over sub-cell `c` of the unit interval (`x = (xi + 1) / 2`, so
    /// `d/dx = 2 d/dxi`); the same on every axis.
    table: [[Vec<[f64; P]>; 2]; 2],
    /// Each table summed over the sub-cells (a whole axis of constant fill).
    row_sums: [[[f64; P]; 2]; 2],
    /// `(pair_index(a, b), pair_index(b, a))` for every node pair, `a` major.
    pairs: Vec<(u16, u16)>,
    lambda: f64,
    mu: f64,
}

/// Reusable buffers of [`Hex27Subcells::matrices`].
#[derive(Clone, Debug, Default)]
pub struct TensorScratch {
    /// The weights `chi`, x fastest.
    weights: Vec<f64>,
    /// After contracting x, for each of the three x tables: `[c3][c2][pair_x]`.
    t1: [Vec<[f64; P]>; 3],
    /// After contracting y: `[c3][pair_y][pair_x]`.
    t2: Vec<[[f64; P]; P]>,
    /// The seven integrals, `[pair_z][pair_y][pair_x]` each: I^xx, I^yy, I^zz, I^xy, I^yz,
    /// I^xz, mass.
    integrals: Vec<[[[f64; P]; P]; P]>,
}

impl Hex27Subcells {
    /// The 1D tables for `per_axis` sub-cells per axis and Poisson's ratio `nu` (`E = 1`).
    pub fn new(per_axis: usize, nu: f64) -> Self {
        // Three Gauss points per sub-cell integrate the degree-4 products exactly.
        let (pts, wts) = gauss(3);
        let mut table: [[Vec<[f64; P]>; 2]; 2] = Default::default();
        let step = 2.0 / per_axis as f64;
        for (p, row) in table.iter_mut().enumerate() {
            for (q, cells) in row.iter_mut().enumerate() {
                for c in 0..per_axis {
                    let (lo, hi) = (-1.0 + step * c as f64, -1.0 + step * (c + 1) as f64);
                    let mut out = [0.0; P];
                    for (t, w) in pts.iter().zip(wts) {
                        let xi = 0.5 * (lo + hi) + 0.5 * (hi - lo) * t;
                        // dx = dxi / 2 over a sub-interval of half-width (hi - lo) / 2.
                        let weight = w * 0.5 * (hi - lo) * 0.5;
                        let (v, d) = basis_1d(2, xi);
                        let pick =
                            |k: usize, deriv: usize| if deriv == 1 { 2.0 * d[k] } else { v[k] };
                        for f in 0..M {
                            for g in 0..M {
                                out[f * M + g] += weight * pick(f, p) * pick(g, q);
                            }
                        }
                    }
                    cells.push(out);
                }
            }
        }
        let pairs = (0..NODES * NODES)
            .map(|ab| {
                let (a, b) = (ab / NODES, ab % NODES);
                (pair_index(a, b) as u16, pair_index(b, a) as u16)
            })
            .collect();
        let row_sums = table.each_ref().map(|row| {
            row.each_ref().map(|cells| {
                let mut sum = [0.0; P];
                for c in cells {
                    sum.iter_mut().zip(c).for_each(|(s, v)| *s += v);
                }
                sum
            })
        });
        Self {
            per_axis,
            table,
            row_sums,
            pairs,
            lambda: nu / ((1.0 + nu) * (1.0 - 2.0 * nu)),
            mu: 1.0 / (2.0 * (1.0 + nu)),
        }
    }

    /// Buffers for [`Hex27Subcells::matrices`].
    pub fn scratch(&self) -> TensorScratch {
        let s = self.per_axis;
        TensorScratch {
            weights: vec![0.0; s * s * s],
            t1: std::array::from_fn(|_| vec![[0.0; P]; s * s]),
            t2: vec![[[0.0; P]; P]; s],
            integrals: vec![[[[0.0; P]; P]; P]; 7],
        }
    }

    /// Stiffness `k` and mass `m` (`81 x 81`, row-major, DOF `3 a + c`) of a hex27 element whose
    /// sub-cells (x fastest) are filled to `fill`, each clamped to `[EMPTY_SUBCELL_FLOOR, 1]`.
    pub fn matrices(
        &self,
        fill: &[f64],
        k: &mut [f64],
        m: &mut [f64],
        scratch: &mut TensorScratch,
    ) {
        let s = self.per_axis;
        assert_eq!(fill.len(), s * s * s, "one fraction per sub-cell");
        assert!(
            k.len() == NDOF * NDOF && m.len() == NDOF * NDOF,
            "81 x 81 outputs"
        );
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: the CPU supports AVX2 and FMA (checked just above), the only requirement
            // of the `target_feature` function; it is the same safe code compiled for them.
            unsafe { self.matrices_avx2(fill, k, m, scratch) };
            return;
        }
        self.matrices_body(fill, k, m, scratch);
    }

    /// [`Hex27Subcells::matrices`] compiled for AVX2 (4 lanes instead of SSE2's 2).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn matrices_avx2(
        &self,
        fill: &[f64],
        k: &mut [f64],
        m: &mut [f64],
        scratch: &mut TensorScratch,
    ) {
        self.matrices_body(fill, k, m, scratch);
    }

    #[inline(always)]
    fn matrices_body(
        &self,
        fill: &[f64],
        k: &mut [f64],
        m: &mut [f64],
        scratch: &mut TensorScratch,
    ) {
        let s = self.per_axis;
        for (w, f) in scratch.weights.iter_mut().zip(fill) {
            *w = f.clamp(0.0, 1.0).max(EMPTY_SUBCELL_FLOOR);
        }
        // (derivative axis of the first factor, of the second), 3 = none.
        const PATTERNS: [(usize, usize); 7] =
            [(0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2), (3, 3)];
        // The x contraction depends only on the x table, `table[p][q]` with `(p, q)` one of
        // (0, 0), (1, 0), (1, 1) (i <= j in every pattern): three contractions serve the
        // seven integrals. A row of sub-cells filled alike (a full or empty voxel's, or a
        // block's) contracts to its weight times the table's row sum.
        const X_TABLES: [(usize, usize); 3] = [(0, 0), (1, 0), (1, 1)];
        for (t1, &(p, q)) in scratch.t1.iter_mut().zip(&X_TABLES) {
            let ax = &self.table[p][q];
            let sum = &self.row_sums[p][q];
            for (row, t) in scratch.weights.chunks_exact(s).zip(t1.iter_mut()) {
                if row.iter().all(|&w| w == row[0]) {
                    let w = row[0];
                    t.iter_mut().zip(sum).for_each(|(t, a)| *t = w * a);
                    continue;
                }
                *t = [0.0; P];
                for (w, a) in row.iter().zip(ax) {
                    t.iter_mut().zip(a).for_each(|(t, a)| *t += w * a);
                }
            }
        }
        for (slot, &(i, j)) in PATTERNS.iter().enumerate() {
            let axis = |k: usize| &self.table[(k == i) as usize][(k == j) as usize];
            let (ay, az) = (axis(1), axis(2));
            let x_key = ((0 == i) as usize, (0 == j) as usize);
            let t1 = &scratch.t1[X_TABLES.iter().position(|&k| k == x_key).expect("x table")];
            // Contract y: t2[c3][py][px] = sum_c2 ay[c2][py] t1[c3 s + c2][px].
            for (t1, t2) in t1.chunks_exact(s).zip(scratch.t2.iter_mut()) {
                let t2 = t2.as_flattened_mut();
                t2.fill(0.0);
                for (t, a) in t1.iter().zip(ay) {
                    for (out, &a) in t2.chunks_exact_mut(P).zip(a) {
                        out.iter_mut().zip(t).for_each(|(o, t)| *o += a * t);
                    }
                }
            }
            // Contract z: I[pz][py][px] = sum_c3 az[c3][pz] t2[c3][py][px].
            let out = scratch.integrals[slot]
                .as_flattened_mut()
                .as_flattened_mut();
            out.fill(0.0);
            for (t2, a) in scratch.t2.iter().zip(az) {
                let t2 = t2.as_flattened();
                for (plane, &a) in out.chunks_exact_mut(P * P).zip(a) {
                    plane.iter_mut().zip(t2).for_each(|(o, t)| *o += a * t);
                }
            }
        }
        // Flat views: entry (a, b) of integral `slot` sits at `pair_index(a, b)`.
        let ints: [&[f64; P * P * P]; 7] = std::array::from_fn(|slot| {
            let flat = scratch.integrals[slot].as_flattened().as_flattened();
            flat.try_into().expect("729 entries")
        });
        let (lambda, mu) = (self.lambda, self.mu);
        for a in 0..NODES {
            for b in 0..NODES {
                let (ab, ba) = self.pairs[a * NODES + b];
                let (ab, ba) = (ab as usize, ba as usize);
                let diag = [ints[0][ab], ints[1][ab], ints[2][ab]];
                let trace = diag[0] + diag[1] + diag[2];
                let mass = ints[6][ab];
                // I^{cd}(a, b) for c < d is stored; I^{dc}(a, b) = I^{cd}(b, a).
                let upper = [ints[3][ab], ints[4][ab], ints[5][ab]]; // xy, yz, xz
                let lower = [ints[3][ba], ints[4][ba], ints[5][ba]]; // yx, zy, zx
                let i = |c: usize, d: usize| -> f64 {
                    match (c, d) {
                        (0, 1) => upper[0],
                        (1, 2) => upper[1],
                        (0, 2) => upper[2],
                        (1, 0) => lower[0],
                        (2, 1) => lower[1],
                        (2, 0) => lower[2],
                        _ => diag[c],
                    }
                };
                for c in 0..3 {
                    let row = (3 * a + c) * NDOF + 3 * b;
                    for d in 0..3 {
                        let mut v = lambda * i(c, d) + mu * i(d, c);
                        if c == d {
                            v += mu * trace;
                        }
                        k[row + d] = v;
                        m[row + d] = if c == d { mass } else { 0.0 };
                    }
                }
            }
        }
    }
}
