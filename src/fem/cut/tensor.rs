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
//! `k`, differentiated where `k` is `i` (the first) or `j` (the second). A product of two 1D
//! factors is a polynomial of degree 4 at most, so it is a combination of the Legendre
//! polynomials `L_0..L_4` of the element's axis, and every `A_k[c](f, g)` is that
//! combination of the sub-cell's Legendre moments `mu_l(c) = int_c L_l dx`. So the fill enters
//! only through its `5^3` moments `M[l3][l2][l1] = sum_c chi[c] mu_l1(c1) mu_l2(c2) mu_l3(c3)`
//! (moment fitting with exact moments: Müller, Kummer and Oberlack 2013, here for
//! piecewise-constant fills), contracted axis by axis (`s^3 5 + s^2 25 + s 125` multiply-adds
//! for `s` sub-cells per axis), and each of the seven integrals (six derivative pairs and the
//! mass) is then the moments contracted with the 9 x 5 coefficient matrices of its three axes
//! (`25 9 5 + 5 81 5 + 729 5` multiply-adds; the x step is shared by the integrals with the
//! same x factors). For hex27x2's 16 sub-cells per axis (2 voxels of refined 8^3,
//! `crate::shape::refine`) this is about 75 k multiply-adds per element where contracting the
//! 1D sub-cell tables themselves (27 numbers per sub-cell instead of 5) took about 340 k, and
//! the sub-cell table of matrices (`2 x 81^2` per sub-cell) would take 54 M. A row of
//! sub-cells filled alike (a full or empty voxel's) has the moments of its weight times the
//! whole interval's: `(w, 0, 0, 0, 0)`.
//! The stiffness follows from the derivative integrals `I^{ij}(a, b)` with Lamé's constants:
//! `K(3a+c, 3b+d) = lambda I^{cd}(a, b) + mu I^{dc}(a, b) + mu delta_cd sum_l I^{ll}(a, b)`,
//! which is `int B^T D B` for isotropic `D` written out.

use crate::fem::element::{basis_1d, gauss};
use crate::fem::sparse::{node_pairs, ElementBlocks};

/// Lagrange factors per axis (hex27: nodes at `xi = -1, 0, 1`).
const M: usize = 3;
/// Pairs of factors per axis, `f * M + g`.
const P: usize = M * M;
/// Legendre polynomials per axis: a product of two 1D factors has degree 4 at most.
const L: usize = 5;
/// Nodes of the element.
const NODES: usize = M * M * M;

/// Where the integral of nodes `a` and `b` sits in a flattened `[pair_z][pair_y][pair_x]`
/// tensor (node `a = ax + 3 (ay + 3 az)`).
fn pair_index(a: usize, b: usize) -> usize {
    let (ax, ay, az) = (a % M, (a / M) % M, a / (M * M));
    let (bx, by, bz) = (b % M, (b / M) % M, b / (M * M));
    ((az * M + bz) * P + ay * M + by) * P + ax * M + bx
}

/// Five-point Gauss-Legendre rule on [-1, 1].
const GAUSS5_POINTS: [f64; 5] = [
    -0.906_179_845_938_664,
    -0.538_469_310_105_683_1,
    0.0,
    0.538_469_310_105_683_1,
    0.906_179_845_938_664,
];
const GAUSS5_WEIGHTS: [f64; 5] = [
    0.236_926_885_056_189_1,
    0.478_628_670_499_366_5,
    0.568_888_888_888_888_9,
    0.478_628_670_499_366_5,
    0.236_926_885_056_189_1,
];

/// Legendre polynomials `L_0..L_4` at `xi` (Bonnet's recursion).
fn legendre(xi: f64) -> [f64; L] {
    let mut l = [0.0; L];
    l[0] = 1.0;
    l[1] = xi;
    for n in 1..L - 1 {
        l[n + 1] = ((2 * n + 1) as f64 * xi * l[n] - n as f64 * l[n - 1]) / (n + 1) as f64;
    }
    l
}

/// hex27's cut-element integrals for one sub-cell count and Poisson's ratio.
#[derive(Clone, Debug)]
pub struct Hex27Subcells {
    per_axis: usize,
    /// The Legendre moments of each sub-cell of one axis: `moments[c][l] = int_c L_l(xi) dx`
    /// over sub-cell `c` of the unit interval (`x = (xi + 1) / 2`); the same on every axis.
    moments: Vec<[f64; L]>,
    /// `coef[p][q][f * M + g][l]`: the Legendre coefficients of `f^(p) g^(q)`, the product
    /// of two 1D factors, differentiated (`d/dx = 2 d/dxi`) where `p` or `q` is 1.
    coef: [[[[f64; L]; P]; 2]; 2],
    /// `(pair_index(a, b), pair_index(b, a))` for every node pair, `a` major.
    pairs: Vec<(u16, u16)>,
    /// Lamé's constants times the stiffness scale.
    lambda: f64,
    mu: f64,
    /// The mass scale.
    mass_scale: f64,
}

/// Reusable buffers of [`Hex27Subcells::matrices`].
#[derive(Clone, Debug, Default)]
pub struct TensorScratch {
    /// The weights `chi`, x fastest.
    weights: Vec<f64>,
    /// The fill's x moments per row of sub-cells: `[c3][c2][l1]`.
    m1: Vec<[f64; L]>,
    /// ... and its x and y moments: `[c3][l2][l1]`.
    m2: Vec<[[f64; L]; L]>,
    /// The seven integrals, `[pair_z][pair_y][pair_x]` each: I^xx, I^yy, I^zz, I^xy, I^yz,
    /// I^xz, mass.
    integrals: Vec<[[[f64; P]; P]; P]>,
}

impl Hex27Subcells {
    /// The 1D moments and coefficients for `per_axis` sub-cells per axis and Poisson's ratio
    /// `nu` (`E = 1`); the matrices come multiplied by `scales`, `(stiffness, mass)` (the
    /// unit cube's element: `(1, 1)`).
    pub fn new(per_axis: usize, nu: f64, scales: (f64, f64)) -> Self {
        let (stiffness_scale, mass_scale) = scales;
        // Three Gauss points per sub-cell integrate the Legendre polynomials (degree 4 at
        // most) exactly.
        let (pts, wts) = gauss(3);
        let step = 2.0 / per_axis as f64;
        let moments = (0..per_axis)
            .map(|c| {
                let (lo, hi) = (-1.0 + step * c as f64, -1.0 + step * (c + 1) as f64);
                let mut out = [0.0; L];
                for (t, w) in pts.iter().zip(wts) {
                    let xi = 0.5 * (lo + hi) + 0.5 * (hi - lo) * t;
                    // dx = dxi / 2 over a sub-interval of half-width (hi - lo) / 2.
                    let weight = w * 0.5 * (hi - lo) * 0.5;
                    out.iter_mut()
                        .zip(legendre(xi))
                        .for_each(|(o, l)| *o += weight * l);
                }
                out
            })
            .collect();
        // Five Gauss points integrate a degree-4 product times L_4 exactly; L_l has norm
        // 2 / (2 l + 1) on [-1, 1].
        let mut coef = [[[[0.0; L]; P]; 2]; 2];
        for (p, row) in coef.iter_mut().enumerate() {
            for (q, pairs) in row.iter_mut().enumerate() {
                for (t, w) in GAUSS5_POINTS.iter().zip(GAUSS5_WEIGHTS) {
                    let (v, d) = basis_1d(2, *t);
                    let pick = |k: usize, deriv: usize| if deriv == 1 { 2.0 * d[k] } else { v[k] };
                    let l = legendre(*t);
                    for f in 0..M {
                        for g in 0..M {
                            let product = pick(f, p) * pick(g, q);
                            for (n, c) in pairs[f * M + g].iter_mut().enumerate() {
                                *c += w * product * l[n] * (2 * n + 1) as f64 / 2.0;
                            }
                        }
                    }
                }
            }
        }
        let pairs = (0..NODES * NODES)
            .map(|ab| {
                let (a, b) = (ab / NODES, ab % NODES);
                (pair_index(a, b) as u16, pair_index(b, a) as u16)
            })
            .collect();
        Self {
            per_axis,
            moments,
            coef,
            pairs,
            lambda: stiffness_scale * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)),
            mu: stiffness_scale / (2.0 * (1.0 + nu)),
            mass_scale,
        }
    }

    /// Buffers for [`Hex27Subcells::matrices`].
    pub fn scratch(&self) -> TensorScratch {
        let s = self.per_axis;
        TensorScratch {
            weights: vec![0.0; s * s * s],
            m1: vec![[0.0; L]; s * s],
            m2: vec![[[0.0; L]; L]; s],
            integrals: vec![[[[0.0; P]; P]; P]; 7],
        }
    }

    /// Stiffness and mass ([`ElementBlocks`] of 27 nodes) of a hex27 element whose sub-cells
    /// (x fastest) are filled to `fill`, each clamped to `[super::EMPTY_SUBCELL_FLOOR, 1]` ([`super::subcell_weight`]).
    pub fn matrices(&self, fill: &[f64], out: &mut ElementBlocks, scratch: &mut TensorScratch) {
        let s = self.per_axis;
        assert_eq!(fill.len(), s * s * s, "one fraction per sub-cell");
        assert!(
            out.k.len() == node_pairs(NODES) && out.m.len() == node_pairs(NODES),
            "27-node blocks"
        );
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: the CPU supports AVX2 and FMA (checked just above), the only requirement
            // of the `target_feature` function; it is the same safe code compiled for them.
            unsafe { self.matrices_avx2(fill, out, scratch) };
            return;
        }
        self.matrices_body(fill, out, scratch);
    }

    /// [`Hex27Subcells::matrices`] compiled for AVX2 (4 lanes instead of SSE2's 2).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn matrices_avx2(
        &self,
        fill: &[f64],
        out: &mut ElementBlocks,
        scratch: &mut TensorScratch,
    ) {
        self.matrices_body(fill, out, scratch);
    }

    #[inline(always)]
    fn matrices_body(&self, fill: &[f64], out: &mut ElementBlocks, scratch: &mut TensorScratch) {
        let s = self.per_axis;
        for (w, f) in scratch.weights.iter_mut().zip(fill) {
            *w = super::subcell_weight(*f);
        }
        // The fill's Legendre moments, one axis at a time. x: a row of sub-cells filled alike
        // (a full or empty voxel's) has its weight times the whole interval's, (w, 0, ...).
        let mu = &self.moments;
        for (row, m1) in scratch.weights.chunks_exact(s).zip(scratch.m1.iter_mut()) {
            *m1 = [0.0; L];
            if row.iter().all(|&w| w == row[0]) {
                m1[0] = row[0];
                continue;
            }
            for (w, mu) in row.iter().zip(mu) {
                m1.iter_mut().zip(mu).for_each(|(m, mu)| *m += w * mu);
            }
        }
        // y: m2[c3][l2][l1] = sum_c2 mu_l2(c2) m1[c3][c2][l1].
        for (m1, m2) in scratch.m1.chunks_exact(s).zip(scratch.m2.iter_mut()) {
            *m2 = [[0.0; L]; L];
            for (m1, mu) in m1.iter().zip(mu) {
                for (out, &mu) in m2.iter_mut().zip(mu) {
                    out.iter_mut().zip(m1).for_each(|(o, m)| *o += mu * m);
                }
            }
        }
        // z: moments[l3][l2][l1] = sum_c3 mu_l3(c3) m2[c3][l2][l1].
        let mut moments = [[[0.0; L]; L]; L];
        for (m2, mu) in scratch.m2.iter().zip(mu) {
            for (plane, &mu) in moments.iter_mut().zip(mu) {
                plane
                    .as_flattened_mut()
                    .iter_mut()
                    .zip(m2.as_flattened())
                    .for_each(|(o, m)| *o += mu * m);
            }
        }
        // The integrals: the moments contracted with each axis's coefficients. The x step
        // depends only on the x factors, `coef[p][q]` with `(p, q)` one of (0, 0), (1, 0),
        // (1, 1) (i <= j in every pattern): three serve the seven integrals.
        const X_FACTORS: [(usize, usize); 3] = [(0, 0), (1, 0), (1, 1)];
        let mut a1 = [[[[0.0; P]; L]; L]; 3];
        for (a1, &(p, q)) in a1.iter_mut().zip(&X_FACTORS) {
            let cx = &self.coef[p][q];
            for (a1, moments) in a1.as_flattened_mut().iter_mut().zip(moments.as_flattened()) {
                for (o, c) in a1.iter_mut().zip(cx) {
                    *o = c.iter().zip(moments).map(|(c, m)| c * m).sum();
                }
            }
        }
        // (derivative axis of the first factor, of the second), 3 = none.
        const PATTERNS: [(usize, usize); 7] =
            [(0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2), (3, 3)];
        for (slot, &(i, j)) in PATTERNS.iter().enumerate() {
            let axis = |k: usize| &self.coef[(k == i) as usize][(k == j) as usize];
            let (cy, cz) = (axis(1), axis(2));
            let x_key = ((0 == i) as usize, (0 == j) as usize);
            let a1 = &a1[X_FACTORS
                .iter()
                .position(|&k| k == x_key)
                .expect("x factors")];
            // y: a2[l3][py][px] = sum_l2 cy[py][l2] a1[l3][l2][px].
            let mut a2 = [[[0.0; P]; P]; L];
            for (a2, a1) in a2.iter_mut().zip(a1) {
                for (out, c) in a2.iter_mut().zip(cy) {
                    for (&c, a1) in c.iter().zip(a1) {
                        out.iter_mut().zip(a1).for_each(|(o, a)| *o += c * a);
                    }
                }
            }
            // z: I[pz][py][px] = sum_l3 cz[pz][l3] a2[l3][py][px].
            let out = scratch.integrals[slot]
                .as_flattened_mut()
                .as_flattened_mut();
            for (plane, c) in out.chunks_exact_mut(P * P).zip(cz) {
                plane.fill(0.0);
                for (&c, a2) in c.iter().zip(&a2) {
                    plane
                        .iter_mut()
                        .zip(a2.as_flattened())
                        .for_each(|(o, a)| *o += c * a);
                }
            }
        }
        // Flat views: entry (a, b) of integral `slot` sits at `pair_index(a, b)`.
        let ints: [&[f64; P * P * P]; 7] = std::array::from_fn(|slot| {
            let flat = scratch.integrals[slot].as_flattened().as_flattened();
            flat.try_into().expect("729 entries")
        });
        let (lambda, mu) = (self.lambda, self.mu);
        let mut pair = 0;
        for a in 0..NODES {
            for b in a..NODES {
                let (ab, ba) = self.pairs[a * NODES + b];
                let (ab, ba) = (ab as usize, ba as usize);
                let diag = [ints[0][ab], ints[1][ab], ints[2][ab]];
                let trace = diag[0] + diag[1] + diag[2];
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
                let block = &mut out.k[pair];
                for c in 0..3 {
                    for d in 0..3 {
                        let mut v = lambda * i(c, d) + mu * i(d, c);
                        if c == d {
                            v += mu * trace;
                        }
                        block[3 * c + d] = v;
                    }
                }
                out.m[pair] = self.mass_scale * ints[6][ab];
                pair += 1;
            }
        }
    }
}
