//! A symmetry class that an axis swap maps onto itself, split in two by that swap.
//!
//! Where it sits: [`super::solve_classes`] reduces a class ([`Mirrors::reduce`]) and, where
//! one of the model's axis swaps maps the class onto itself (a class even in both swapped
//! axes' mirrors, or odd in both), reduces it once more here into the swap's two characters
//! `tau = +1` and `tau = -1`, each about half the class. With the two mirrors and their swap
//! (the square's symmetry group `D4`: a bowl, a can, a bell, a gong) the classes even or odd
//! in both mirrors are `D4`'s four one-dimensional representations (A1, A2, B1, B2), the other
//! two classes its two-dimensional one (E), which the swap's image already halves (Bossavit
//! 1986, sec. 4; Zienkiewicz, Taylor and Zhu, sec. 9.16).
//!
//! On the class's DOFs the swap `s` is a signed permutation `P`: the class basis vector of
//! orbit `O`, component `c` goes to `eps * b(sO, to c)` (`to` swaps the two axes'
//! components; `eps = +-1`, read from the class's signs at the image of `O`'s
//! representative). `P` commutes with the class's `K` and `M` and `P^2 = I`, so the class
//! splits into `P u = tau u`. Its orthonormal basis: for a pair of distinct DOFs `i`,
//! `j = P i`, `(e_i + tau eps_i e_j) / sqrt 2`; a DOF the swap maps onto itself (`P e_i =
//! eps_i e_i`: the third axis's component on an orbit the swap fixes) belongs to the subclass
//! with `tau = eps_i` alone. On an orbit the swap fixes (nodes on or mirrored across the
//! diagonal plane) the two swapped components pair with each other: slot `a` holds their
//! combination and slot `b` is absent, a decoupled massless row like the mirror classes'.
//!
//! The subclass's `K_tau = B^T K B` has full 3x3 blocks like the class's; its mass
//! `B^T M B` is component-diagonal except where an orbit couples with the swap image of
//! another (next to the diagonal plane), whose few entries couple a swapped component with
//! the other ([`ClassProblem::mass_extra`]).

use super::mirrors::{ClassProblem, Lifting, Mirrors};
use super::reduced::ReducedPattern;
use crate::fem::sparse::BlockPattern;

/// One of the two halves of a class that an axis swap maps onto itself.
pub(super) struct Split {
    /// Each class DOF's subclass DOF and coefficient in that DOF's basis vector (`0.0`: the
    /// DOF is not in this half).
    member: Vec<(u32, f64)>,
    /// The class orbits that stand for the subclass's nodes (of each pair the swap exchanges,
    /// the one on the lower side of its diagonal plane).
    reps: Vec<u32>,
    /// Each class orbit's subclass node.
    node_of: Vec<u32>,
    /// Each class orbit's image under the swap.
    image: Vec<u32>,
}

impl Split {
    /// The half `tau` (`+1.0` or `-1.0`) of class `chi` under swap number `swap`, which must
    /// map the class onto itself ([`Mirrors::splitting_swap`]). `coords` are the lattice
    /// coordinates of the orbits' representatives: of each pair of orbits the swap exchanges,
    /// the one on the lower side of the swap's diagonal plane stands for both, so the half's
    /// nodes are one region of the object for its nested-dissection order (representatives
    /// taken from both sides, by orbit number, made the glass bowl's set-up 410 ms against
    /// 252 in a same-hour run).
    pub(super) fn new(
        mirrors: &Mirrors,
        chi: u8,
        swap: usize,
        tau: f64,
        coords: &[[i64; 3]],
    ) -> Self {
        let (a, b) = mirrors.swap_axes(swap);
        let third = 3 - a - b;
        let orbits = mirrors.reps.len();
        let image: Vec<u32> = (0..orbits)
            .map(|o| mirrors.orbit_of[mirrors.swap_image(swap, mirrors.reps[o])])
            .collect();
        // eps of DOF (o, c): the class's sign at the swap image of o's representative, for
        // the component c goes to.
        let to = |c: usize| match c {
            c if c == a => b,
            c if c == b => a,
            c => c,
        };
        let eps = |o: usize, c: usize| {
            mirrors.sign(mirrors.swap_image(swap, mirrors.reps[o]), to(c), chi)
        };
        let mut node_of = vec![u32::MAX; orbits];
        let mut reps = Vec::new();
        let mut member = vec![(0u32, 0.0f64); 3 * orbits];
        let half = std::f64::consts::FRAC_1_SQRT_2;
        for o in 0..orbits {
            if node_of[o] != u32::MAX {
                continue;
            }
            let r = reps.len() as u32;
            let side = |o: usize| coords[o][a] - coords[o][b];
            let (o, so) = match image[o] as usize {
                so if side(so) < side(o) => (so, o),
                so => (o, so),
            };
            debug_assert!(
                image[so] as usize == o,
                "the swap is an involution on orbits"
            );
            node_of[o] = r;
            node_of[so] = r;
            reps.push(o as u32);
            if so != o {
                for c in 0..3 {
                    if !mirrors.present(o, c, chi) {
                        continue;
                    }
                    debug_assert!(mirrors.present(so, to(c), chi));
                    debug_assert_eq!(eps(o, c) * eps(so, to(c)), 1.0, "P^2 = I");
                    member[3 * o + c] = (3 * r + c as u32, half);
                    member[3 * so + to(c)] = (3 * r + c as u32, tau * eps(o, c) * half);
                }
            } else {
                if mirrors.present(o, third, chi) && eps(o, third) == tau {
                    member[3 * o + third] = (3 * r + third as u32, 1.0);
                }
                debug_assert_eq!(mirrors.present(o, a, chi), mirrors.present(o, b, chi));
                if mirrors.present(o, a, chi) {
                    member[3 * o + a] = (3 * r + a as u32, half);
                    member[3 * o + b] = (3 * r + a as u32, tau * eps(o, a) * half);
                }
            }
        }
        Split {
            member,
            reps,
            node_of,
            image,
        }
    }

    /// The class orbits that stand for the subclass's nodes.
    pub(super) fn reps(&self) -> &[u32] {
        &self.reps
    }

    /// The pattern of this half, which it shares with the other half and with every class
    /// the same swap splits (their halves pair the same orbits), given the classes'.
    pub(super) fn pattern(&self, class: &BlockPattern) -> ReducedPattern {
        let reps: Vec<usize> = self.reps.iter().map(|&o| o as usize).collect();
        ReducedPattern::new(class, &reps, |o| self.node_of[o])
    }

    /// The subclass's `B^T K B` and `B^T M B` from its class's (see the module docs), on its
    /// pattern `plan` ([`Split::pattern`]).
    pub(super) fn reduce(&self, class: &ClassProblem, plan: &ReducedPattern) -> ClassProblem {
        let nodes = self.reps.len();
        let p = &class.pattern;
        let blocks = plan.pattern.col.len();
        let (mut k, mut m) = (vec![[0.0; 9]; blocks], vec![[0.0; 3]; blocks]);
        // The mass's entries off the blocks' diagonals, as they are summed: `(row DOF,
        // column DOF, value)`; the same entry's terms are added up below.
        let mut off_diagonal: Vec<(u32, u32, f64)> = Vec::new();
        let mut target = plan.target.iter();
        for (r, &rep) in self.reps.iter().enumerate() {
            let rep = rep as usize;
            // By the swap's invariance, the representative's row alone gives the half's
            // row: a pair's basis vector `(e_i + tau eps e_j) / sqrt 2` has `e_j^T A v =
            // tau eps e_i^T A v` for any `v` of the half, so `u^T A v = sqrt 2 e_i^T A v`
            // (as the classes are made from the orbit representatives' rows).
            // This row's components in the half, as (slot, weight): not in this half, or the
            // second member of an orbit's own pair (the swapped component of an orbit the
            // swap fixes), which the first stands for, are left out; a pair's first member
            // (1 / sqrt 2) weighs sqrt 2, a DOF alone 1.
            let rows: Vec<(usize, usize, f64)> = (0..3)
                .filter_map(|c| {
                    let (u, cu) = self.member[3 * rep + c];
                    let su = u as usize % 3;
                    let weight = if cu == 1.0 { 1.0 } else { 2.0 * cu };
                    (cu != 0.0 && su == c).then_some((c, su, weight))
                })
                .collect();
            for blk in p.row_ptr[rep]..p.row_ptr[rep + 1] {
                let q = p.col[blk] as usize;
                let at = *target.next().expect("a target per block") as usize;
                let columns = &self.member[3 * q..3 * q + 3];
                for &(c, su, weight) in &rows {
                    for (d, &(v, cv)) in columns.iter().enumerate() {
                        if cv == 0.0 {
                            continue;
                        }
                        let sv = v as usize % 3;
                        k[at][3 * su + sv] += weight * cv * class.k[blk][3 * c + d];
                        if c == d {
                            let term = weight * cv * class.m[blk][c];
                            if su == sv {
                                m[at][su] += term;
                            } else {
                                let s = plan.pattern.col[at];
                                off_diagonal.push(((3 * r + su) as u32, 3 * s + sv as u32, term));
                            }
                        }
                    }
                }
            }
            // A DOF outside this half: a decoupled massless row with the class's stiffness
            // there (an infinite eigenvalue, as for the classes' absent DOFs).
            let (diag, own) = plan.diagonal[r];
            for c in 0..3 {
                if !self.has(r, c) {
                    k[diag as usize][4 * c] = class.k[own as usize][4 * c];
                }
            }
        }
        // In the order of the pattern (row node, column node, then components), each entry's
        // terms summed in the order they came.
        off_diagonal.sort_by_key(|&(i, j, _)| (i / 3, j / 3, i % 3, j % 3));
        let mut mass_extra: Vec<(u32, u32, f64)> = Vec::with_capacity(off_diagonal.len());
        for (i, j, v) in off_diagonal {
            match mass_extra.last_mut() {
                Some(last) if (last.0, last.1) == (i, j) => last.2 += v,
                _ => mass_extra.push((i, j, v)),
            }
        }
        mass_extra.retain(|e| e.2 != 0.0);
        let absent = (0..3 * nodes)
            .filter(|&i| !self.has(i / 3, i % 3))
            .collect();
        ClassProblem {
            chi: class.chi,
            pattern: plan.pattern.clone(),
            k,
            m,
            mass_extra,
            absent,
        }
    }

    /// Whether subclass node `r` has component slot `c`.
    fn has(&self, r: usize, c: usize) -> bool {
        let rep = self.reps[r] as usize;
        let own = 3 * r as u32 + c as u32;
        [rep, self.image[rep] as usize]
            .iter()
            .flat_map(|&o| &self.member[3 * o..3 * o + 3])
            .any(|&(u, w)| w != 0.0 && u == own)
    }

    /// `lifting` (whole model from class) followed by this half's basis: the whole model from
    /// the subclass.
    pub(super) fn compose(&self, lifting: Lifting) -> Lifting {
        lifting.then(|i| {
            let (u, w) = self.member[i];
            (u as usize, w)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eigen::{Operators, Which};
    use crate::fem::{ElementKind, FemModel};
    use crate::shape::primitives::Primitive;

    /// The half's factor ([`ShiftedCholesky::for_class`]) solves `(K - shift M) x = b` with
    /// the mass's entries off the blocks' diagonals included: the residual against the half's
    /// own products is at rounding level. The shift, `-scale`, makes `K - shift M` well
    /// conditioned (its eigenvalues from `scale` up), so 1e-10 of `||b||` bounds rounding;
    /// leaving out the extra entries fails it (a residual of 0.14 of `||b||`).
    fn factor_solves_the_shifted_half(sub: &ClassProblem, ops: &Operators, scale: f64) {
        use crate::eigen::factor::ShiftedCholesky;
        use crate::fem::sparse::RowBlock;
        let n = ops.dofs();
        let shift = -scale;
        let nodes: Vec<usize> = (0..sub.pattern.nodes()).rev().collect();
        let (k, m, extra) = (&sub.k, &sub.m, &sub.mass_extra);
        let mut llt = ShiftedCholesky::for_class(
            &sub.pattern,
            k,
            m,
            extra,
            shift,
            &nodes,
            crate::eigen::Stop::NEVER,
        )
        .expect("the shifted half is positive definite");
        let b = ops.random_block(1, 11);
        let mut x = b.clone();
        llt.solve_in_place(x.as_mut());
        let x = x.col(0).try_as_col_major().unwrap().as_slice();
        let b = b.col(0).try_as_col_major().unwrap().as_slice();
        let (mut kx, mut mx) = (vec![0.0; n], vec![0.0; n]);
        ops.spmm(Which::K, x, &mut kx, RowBlock::dense(1));
        ops.spmm(Which::M, x, &mut mx, RowBlock::dense(1));
        let norm = |v: &mut dyn Iterator<Item = f64>| v.map(|e| e * e).sum::<f64>().sqrt();
        let residual = norm(&mut (0..n).map(|i| kx[i] - shift * mx[i] - b[i]));
        let b_norm = norm(&mut b.iter().copied());
        assert!(
            residual <= 1e-10 * b_norm,
            "chi {}: ||(K - shift M) x - b|| = {residual:e} of ||b|| = {b_norm:e}",
            sub.chi
        );
    }

    /// Each half's `K` and `M` are the class's in the half's basis (`B^T A B x = A_half x` for
    /// random `x`, the mass's off-diagonal entries included), the two halves together keep
    /// every DOF of the class, and a half's vectors are even or odd under the swap as `tau`
    /// says. A 10-voxel bowl (two mirrors and their swap; 1.6k DOFs): its classes even or
    /// odd in both mirrors split.
    #[test]
    fn halves_are_the_class_in_their_basis() {
        let grid = Primitive::Bowl {
            diameter: 10.0,
            wall: 2.0,
        }
        .rasterize(1.0, 1.0)
        .unwrap();
        let model = FemModel::assemble(&grid, ElementKind::Hex8Incompatible, 0.3).unwrap();
        let mirrors = Mirrors::detect(&model).unwrap();
        let whole = Operators::new(&model);
        let coords: Vec<[i64; 3]> = (mirrors.reps.iter())
            .map(|&n| model.node_lattice_coords(n))
            .collect();
        let mut split_classes = 0;
        for chi in mirrors.classes() {
            let Some(swap) = mirrors.splitting_swap(chi) else {
                continue;
            };
            split_classes += 1;
            let class = mirrors.reduce(&model, chi);
            let class_ops = class.operators(&whole);
            let n = class_ops.dofs();
            let mut kept = 0;
            let mut extra = 0;
            for tau in [1.0, -1.0] {
                let half = Split::new(&mirrors, chi, swap, tau, &coords);
                let sub = half.reduce(&class, &half.pattern(&class.pattern));
                let ops = sub.operators(&whole);
                kept += ops.dofs() - sub.absent.len();
                extra += sub.mass_extra.len();
                factor_solves_the_shifted_half(&sub, &ops, whole.scale);
                let x = ops.random_block(1, 7);
                let x = x.col(0).try_as_col_major().unwrap().as_slice();
                // The class vector of x: x_class[i] = c_i x[u_i].
                let lift = |x: &[f64]| -> Vec<f64> {
                    (0..n)
                        .map(|i| half.member[i].1 * x[half.member[i].0 as usize])
                        .collect()
                };
                let xc = lift(x);
                // Its image under the swap is tau times itself: the class vector of orbit
                // o's component c sits, times eps, at the image orbit's component to(c).
                let (a, b) = mirrors.swap_axes(swap);
                let to = |c: usize| {
                    if c == a {
                        b
                    } else if c == b {
                        a
                    } else {
                        c
                    }
                };
                for o in 0..mirrors.reps.len() {
                    let so = half.image[o] as usize;
                    let image = mirrors.swap_image(swap, mirrors.reps[o]);
                    for c in 0..3 {
                        let eps = mirrors.sign(image, to(c), chi);
                        let (p, q) = (xc[3 * so + to(c)], tau * eps * xc[3 * o + c]);
                        assert!((p - q).abs() <= 1e-14, "chi {chi} tau {tau}: P x = tau x");
                    }
                }
                for which in [Which::K, Which::M] {
                    let mut yc = vec![0.0; n];
                    class_ops.spmm(which, &xc, &mut yc, crate::fem::sparse::RowBlock::dense(1));
                    // B^T y.
                    let mut projected = vec![0.0; ops.dofs()];
                    for (i, &(u, c)) in half.member.iter().enumerate() {
                        projected[u as usize] += c * yc[i];
                    }
                    let mut y = vec![0.0; ops.dofs()];
                    ops.spmm(which, x, &mut y, crate::fem::sparse::RowBlock::dense(1));
                    let scale = projected.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                    for &i in &sub.absent {
                        // An absent DOF's row is its own (decoupled); x is zero there.
                        assert_eq!(x[i], 0.0);
                        projected[i] = y[i];
                    }
                    for (i, (p, q)) in projected.iter().zip(&y).enumerate() {
                        // Sums of a few dozen terms in another order: 1e-13 of the largest.
                        assert!(
                            (p - q).abs() <= 1e-13 * scale,
                            "chi {chi} tau {tau}: row {i}: {p} against {q}"
                        );
                    }
                }
            }
            assert_eq!(
                kept,
                n - class.absent.len(),
                "chi {chi}: the halves keep every DOF"
            );
            assert!(
                extra > 0,
                "the mass couples swapped components next to the diagonal"
            );
        }
        assert_eq!(split_classes, 2, "the classes even and odd in both mirrors");
    }
}
