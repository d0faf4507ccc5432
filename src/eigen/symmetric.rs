//! Mirror-symmetric objects solved one symmetry class at a time.
//!
//! Where it sits: [`super::solve_until`] offers every Lanczos solve here first. Most objects a
//! sound designer starts from are mirror-symmetric (the default bowl about two planes, a bar, a
//! plate or a sphere about three); their `K` and `M` commute with the mirrors, so the DOF space
//! splits into `2^m` classes (one per character `chi` of the mirror group `Z2^m`) that neither
//! matrix couples, and each class is an eigenproblem of about `1/2^m` the size. Its factor is
//! far smaller than the whole one (the default bowl's quarter: 0.40M nonzeros against 2.1M,
//! ~10 ms to factor against ~60), its Krylov vectors a quarter as long and its modes a quarter
//! as many. This is the symmetry-adapted basis of group representation theory (Bossavit 1986,
//! "Symmetry, groups and boundary value problems"; Zienkiewicz, Taylor and Zhu, sec. 9.16).
//!
//! The mirrors are those of the model's node bounding box, checked numerically on every block
//! of `K` and `M` (to [`SYMMETRY_TOLERANCE`] of the largest entry, since refined fills are
//! symmetric only to rounding). For a mirror `g` along axis `a`, `(g u)(p) = R_g u(g p)` with
//! `R_g` flipping component `a`. A node orbit `O` with representative `o` gives class `chi` one
//! basis vector per component `c`, `b = |O|^-1/2 sum_{q in O} sigma_q(c) e_{q,c}` with
//! `sigma_q(c) = chi(g_q) [R_{g_q}]_cc` (`g_q` maps `o` to `q`); it vanishes where a mirror
//! fixing `o` would have to flip it (a node on the plane `x = 0` has no `u_x` in the classes
//! even in `x`): such a DOF is *absent*, kept as a decoupled massless row. By the invariance
//! of `K`, `b_O^T K b_P = sqrt(|O|/|P|) sum_{q in P} sigma_q(d) K(o, c; q, d)`: one pass over
//! the representatives' rows. The basis is orthonormal and `M`-orthogonal across classes, so a
//! class's `M`-orthonormal eigenvectors lift to the whole model's.
//!
//! Which classes hold the lowest `k` modes is not known in advance (a bowl's paired modes fill
//! the two classes odd in one mirror). Each class first asks for `2k/2^m + 2` modes; the
//! `k`-th lowest of all of them bounds the answer, and a class whose every mode lies below that
//! bound is solved again for every mode below it. The residuals are the whole model's (the
//! classes' operators carry its norms, and `||B r|| = ||r||`).

use super::factor::ShiftedCholesky;
use super::lanczos::{self, FirstRoom, SHIFT_RELATIVE};
use super::{
    warm_guard, EigenError, EigenOptions, EigenSolution, ModeCount, Operators, SolveTimings,
    SolverKind, Stop,
};
use crate::fem::sparse::BlockPattern;
use crate::fem::{ordering, FemModel};
use faer::Mat;
use std::time::Instant;

/// Models below this many DOFs are solved whole: their solve is a few tens of ms, and their
/// classes would be too small for a block Krylov method.
pub const MIN_DOFS: usize = 1500;

/// Models above this many DOFs are solved whole (or refused there, with the way out): the
/// classes' factors are kept together for the rounds that ask a class again, and at this size
/// the eight classes of a solid's factors already take gigabytes.
pub const MAX_DOFS: usize = 200_000;

/// A mirror is accepted when every mapped block of `K` and `M` matches to this fraction of the
/// matrix's largest entry: rounding in the refined fills of cut elements, not a real
/// asymmetry (whose effect on the frequencies would be of the same relative size).
pub const SYMMETRY_TOLERANCE: f64 = 1e-11;

/// The mirror symmetries of a model and its node orbits under them.
pub struct Mirrors {
    /// Mirrored axes as a bit mask (bit `a`: the plane normal to axis `a`).
    axes: u8,
    /// Swaps of two mirrored axes that are symmetries too.
    swaps: Vec<Swap>,
    /// Orbit of each node.
    orbit_of: Vec<u32>,
    /// The group element (a mask of mirrored axes) mapping its orbit's representative to
    /// each node.
    from_rep: Vec<u8>,
    /// Representative node of each orbit.
    reps: Vec<usize>,
    /// Nodes in each orbit.
    size: Vec<u8>,
    /// Each orbit representative's stabiliser: the mirrors whose plane holds it.
    fixed: Vec<u8>,
}

impl Mirrors {
    /// The mirrors of `model` (planes through the centre of its nodes' bounding box that map
    /// its `K` and `M` onto themselves), or `None` when it has none.
    pub fn detect(model: &FemModel) -> Option<Self> {
        let nodes = model.nodes();
        if nodes == 0 {
            return None;
        }
        let coords: Vec<[i64; 3]> = (0..nodes).map(|n| model.node_lattice_coords(n)).collect();
        let (mut lo, mut hi) = ([i64::MAX; 3], [i64::MIN; 3]);
        for c in &coords {
            for a in 0..3 {
                lo[a] = lo[a].min(c[a]);
                hi[a] = hi[a].max(c[a]);
            }
        }
        let k_max = model.k.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
        let m_max = model.m.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let mut axes = 0u8;
        let mut image = vec![Vec::new(); 3];
        let mut at = vec![u32::MAX; nodes];
        let scale = (k_max, m_max);
        for a in 0..3 {
            let mirror = |mut c: [i64; 3]| {
                c[a] = lo[a] + hi[a] - c[a];
                c
            };
            let Some(map) = node_map(model, &coords, mirror) else {
                continue;
            };
            if maps_matrices(model, &map, Components::mirror(a), scale, &mut at) {
                axes |= 1 << a;
                image[a] = map;
            }
        }
        if axes == 0 {
            return None;
        }
        // Swaps of two mirrored axes of equal extent: they map the classes odd in one of the
        // two onto those odd in the other, whose modes are then images of theirs.
        let mut swaps = Vec::new();
        for (a, b) in [(0, 1), (1, 2), (0, 2)] {
            let both = axes & (1 << a) != 0 && axes & (1 << b) != 0;
            if !both || hi[a] - lo[a] != hi[b] - lo[b] {
                continue;
            }
            let swap = |c: [i64; 3]| {
                let mut m = c;
                m[a] = c[b] - lo[b] + lo[a];
                m[b] = c[a] - lo[a] + lo[b];
                m
            };
            let Some(map) = node_map(model, &coords, swap) else {
                continue;
            };
            if maps_matrices(model, &map, Components::swap(a, b), scale, &mut at) {
                swaps.push(Swap { axes: (a, b), map });
            }
        }
        // Orbits: the representative is the image with the smallest node number.
        let mut orbit_of = vec![u32::MAX; nodes];
        let mut from_rep = vec![0u8; nodes];
        let (mut reps, mut size, mut fixed) = (Vec::new(), Vec::new(), Vec::new());
        let images = |n: usize, g: u8| -> usize {
            (0..3)
                .filter(|a| g & (1 << a) != 0)
                .fold(n, |n, a| image[a][n] as usize)
        };
        for n in 0..nodes {
            if orbit_of[n] != u32::MAX {
                continue;
            }
            let id = reps.len() as u32;
            let (mut count, mut stab) = (0u8, 0u8);
            for g in subsets(axes) {
                let q = images(n, g);
                if q == n {
                    stab |= g;
                }
                if orbit_of[q] == u32::MAX {
                    orbit_of[q] = id;
                    from_rep[q] = g;
                    count += 1;
                }
            }
            reps.push(n);
            size.push(count);
            fixed.push(stab);
        }
        Some(Mirrors {
            axes,
            swaps,
            orbit_of,
            from_rep,
            reps,
            size,
            fixed,
        })
    }

    /// Mirrored axes as a bit mask (bit 0: the plane normal to x).
    pub fn axes(&self) -> u8 {
        self.axes
    }

    /// The swaps of two mirrored axes that are symmetries too (`(0, 1)`: x and y).
    pub fn swaps(&self) -> Vec<(usize, usize)> {
        self.swaps.iter().map(|s| s.axes).collect()
    }

    /// The symmetry classes: one character per subset of the mirrors (bit `a` set: odd in
    /// the mirror along axis `a`).
    pub fn classes(&self) -> Vec<u8> {
        subsets(self.axes).collect()
    }

    /// The classes in groups that the axis swaps map onto one another: each group's first
    /// class is solved, the others are images of it (each with the swaps, in order, that map
    /// the first onto it).
    fn groups(&self) -> Vec<Vec<(u8, Vec<usize>)>> {
        let mut seen = 0u8;
        let mut groups = Vec::new();
        for chi in self.classes() {
            if seen & (1 << chi) != 0 {
                continue;
            }
            seen |= 1 << chi;
            let mut group = vec![(chi, Vec::new())];
            let mut at = 0;
            while at < group.len() {
                let (from, path) = group[at].clone();
                for (i, swap) in self.swaps.iter().enumerate() {
                    let to = swap.class(from);
                    if seen & (1 << to) == 0 {
                        seen |= 1 << to;
                        let mut longer = path.clone();
                        longer.push(i);
                        group.push((to, longer));
                    }
                }
                at += 1;
            }
            groups.push(group);
        }
        groups
    }

    /// Whole-model vectors of class `group[0]` mapped onto class `member` by its swaps.
    fn image_of(&self, x: Mat<f64>, path: &[usize]) -> Mat<f64> {
        path.iter().fold(x, |x, &i| self.swaps[i].apply(&x))
    }

    /// Whether the DOF `c` of orbit `o` exists in class `chi`: every mirror that fixes the
    /// representative must map its basis vector to itself times `chi`.
    fn present(&self, o: usize, c: usize, chi: u8) -> bool {
        (0..3)
            .filter(|a| self.fixed[o] & (1 << a) != 0)
            .all(|a| (chi & (1 << a) != 0) == (c == a))
    }

    /// `sigma_q(c)`: the sign of node `q`'s component `c` in its orbit's class-`chi` vector.
    fn sign(&self, q: usize, c: usize, chi: u8) -> f64 {
        let g = self.from_rep[q];
        let flips = (g & chi).count_ones() + u32::from(g & (1 << c) != 0);
        if flips.is_multiple_of(2) {
            1.0
        } else {
            -1.0
        }
    }

    /// `K` and `M` of class `chi` on the orbit representatives.
    pub fn reduce(&self, model: &FemModel, chi: u8) -> ClassProblem {
        let orbits = self.reps.len();
        let mut row_ptr = Vec::with_capacity(orbits + 1);
        row_ptr.push(0);
        let (mut col, mut k, mut m) = (Vec::new(), Vec::new(), Vec::new());
        let mut slot = vec![u32::MAX; orbits];
        let mut cols = Vec::new();
        let p = &model.pattern;
        for (o, &rep) in self.reps.iter().enumerate() {
            let present: [bool; 3] = std::array::from_fn(|c| self.present(o, c, chi));
            cols.clear();
            for blk in p.row_ptr[rep]..p.row_ptr[rep + 1] {
                let q = self.orbit_of[p.col[blk] as usize];
                if slot[q as usize] == u32::MAX {
                    slot[q as usize] = 0;
                    cols.push(q);
                }
            }
            cols.sort_unstable();
            let start = col.len();
            for (i, &q) in cols.iter().enumerate() {
                slot[q as usize] = (start + i) as u32;
            }
            col.extend_from_slice(&cols);
            k.resize(col.len(), [0.0; 9]);
            m.resize(col.len(), [0.0; 3]);
            for blk in p.row_ptr[rep]..p.row_ptr[rep + 1] {
                let q = p.col[blk] as usize;
                let orbit = self.orbit_of[q] as usize;
                let at = slot[orbit] as usize;
                let w = (f64::from(self.size[o]) / f64::from(self.size[orbit])).sqrt();
                for d in 0..3 {
                    if !self.present(orbit, d, chi) {
                        continue;
                    }
                    let s = w * self.sign(q, d, chi);
                    for c in (0..3).filter(|&c| present[c]) {
                        k[at][3 * c + d] += s * model.k[blk][3 * c + d];
                    }
                    if present[d] {
                        m[at][d] += s * model.m[blk];
                    }
                }
            }
            // An absent DOF: a decoupled row with the whole model's stiffness and no mass (an
            // infinite eigenvalue, which shift-invert never approaches).
            let diag = slot[o] as usize;
            let own = p.find(rep, rep as u32).expect("diagonal block");
            for c in (0..3).filter(|&c| !present[c]) {
                k[diag][4 * c] = model.k[own][4 * c];
            }
            for &q in &cols {
                slot[q as usize] = u32::MAX;
            }
            row_ptr.push(col.len());
        }
        let absent = (0..orbits)
            .flat_map(|o| (0..3).map(move |c| (o, c)))
            .filter(|&(o, c)| !self.present(o, c, chi))
            .map(|(o, c)| 3 * o + c)
            .collect();
        ClassProblem {
            chi,
            pattern: BlockPattern { row_ptr, col },
            k,
            m,
            absent,
        }
    }

    /// The whole model's vectors of class-`chi` vectors `x` (one row per class DOF).
    pub fn lift(&self, chi: u8, x: faer::MatRef<'_, f64>) -> Mat<f64> {
        let n = 3 * self.orbit_of.len();
        // Each whole DOF's class DOF and coefficient (zero where the class lacks it).
        let source: Vec<(usize, f64)> = (0..n)
            .map(|i| {
                let (q, c) = (i / 3, i % 3);
                let o = self.orbit_of[q] as usize;
                if !self.present(o, c, chi) {
                    return (0, 0.0);
                }
                let w = self.sign(q, c, chi) / f64::from(self.size[o]).sqrt();
                (3 * o + c, w)
            })
            .collect();
        let mut out = Mat::zeros(n, x.ncols());
        for j in 0..x.ncols() {
            let (from, to) = (x.col(j), out.col_mut(j));
            for (v, &(i, w)) in to.iter_mut().zip(&source) {
                *v = w * from[i];
            }
        }
        out
    }
}

/// A symmetry swapping two mirrored axes.
struct Swap {
    /// The two axes.
    axes: (usize, usize),
    /// Each node's image.
    map: Vec<u32>,
}

impl Swap {
    /// The class a class-`chi` vector's image lies in.
    fn class(&self, chi: u8) -> u8 {
        let (a, b) = self.axes;
        let (ba, bb) = ((chi >> a) & 1, (chi >> b) & 1);
        (chi & !(1 << a) & !(1 << b)) | (ba << b) | (bb << a)
    }

    /// The images of whole-model vectors `x`: `y(map q)[to c] = x(q)[c]`.
    fn apply(&self, x: &Mat<f64>) -> Mat<f64> {
        let comp = Components::swap(self.axes.0, self.axes.1);
        let mut y = Mat::zeros(x.nrows(), x.ncols());
        for j in 0..x.ncols() {
            for (q, &image) in self.map.iter().enumerate() {
                for c in 0..3 {
                    y[(3 * image as usize + comp.to[c], j)] = x[(3 * q + c, j)];
                }
            }
        }
        y
    }
}

/// One symmetry class's eigenproblem on the orbit representatives.
pub struct ClassProblem {
    /// Its character (bit `a`: odd in the mirror along axis `a`).
    pub chi: u8,
    /// Pattern over the orbits.
    pub pattern: BlockPattern,
    /// Stiffness blocks.
    pub k: Vec<[f64; 9]>,
    /// Mass blocks' diagonals (`M` couples equal components only).
    pub m: Vec<[f64; 3]>,
    /// The DOFs the class does not have.
    pub absent: Vec<usize>,
}

impl ClassProblem {
    /// Its operators, with the whole model's norms and scale (so residuals and the rigid
    /// threshold are the whole model's).
    fn operators<'a>(&'a self, whole: &Operators) -> Operators<'a> {
        Operators {
            pattern: &self.pattern,
            k: &self.k,
            m: &[],
            mass_diagonal: Some(&self.m),
            absent: &self.absent,
            k_norm: whole.k_norm,
            m_norm: whole.m_norm,
            scale: whole.scale,
        }
    }
}

/// Every subset of the bit mask `axes`, the empty one first.
fn subsets(axes: u8) -> impl Iterator<Item = u8> {
    (0..8u8).filter(move |g| g & !axes == 0)
}

/// Node images under a map of lattice coordinates, if every node has one.
fn node_map(
    model: &FemModel,
    coords: &[[i64; 3]],
    image_of: impl Fn([i64; 3]) -> [i64; 3],
) -> Option<Vec<u32>> {
    let dims = model.lattice;
    coords
        .iter()
        .map(|&c| {
            let m = image_of(c);
            if (0..3).any(|a| m[a] < 0 || m[a] >= dims[a] as i64) {
                return None;
            }
            let idx = crate::shape::lattice_index(m.map(|v| v as usize), dims);
            let node = model.lattice_node[idx];
            (node != u32::MAX).then_some(node)
        })
        .collect()
}

/// How a symmetry acts on a displacement's components: component `c` goes to `to[c]`, times
/// `sign[c]`.
#[derive(Clone, Copy)]
struct Components {
    to: [usize; 3],
    sign: [f64; 3],
}

impl Components {
    /// The mirror along `axis`: that component flips.
    fn mirror(axis: usize) -> Self {
        let mut sign = [1.0; 3];
        sign[axis] = -1.0;
        Components {
            to: [0, 1, 2],
            sign,
        }
    }

    /// The swap of axes `a` and `b`.
    fn swap(a: usize, b: usize) -> Self {
        let mut to = [0, 1, 2];
        to.swap(a, b);
        Components { to, sign: [1.0; 3] }
    }
}

/// Whether the symmetry (nodes by `map`, components by `comp`) maps every block of `K` and `M`
/// onto its image: `K(map a, map b)[to c][to d] = sign c sign d K(a, b)[c][d]`. `at` is scratch
/// of one entry per node, all `u32::MAX`, and is left so.
fn maps_matrices(
    model: &FemModel,
    map: &[u32],
    comp: Components,
    (k_max, m_max): (f64, f64),
    at: &mut [u32],
) -> bool {
    let p = &model.pattern;
    (0..p.nodes()).all(|a| {
        // The image row's blocks by column, so each block's image is one lookup.
        let image_row = p.row_ptr[map[a] as usize]..p.row_ptr[map[a] as usize + 1];
        for blk in image_row.clone() {
            at[p.col[blk] as usize] = blk as u32;
        }
        let row = p.row_ptr[a]..p.row_ptr[a + 1];
        let same = row.len() == image_row.len()
            && row.into_iter().all(|blk| {
                let image = at[map[p.col[blk] as usize] as usize];
                if image == u32::MAX {
                    return false;
                }
                let (k, ki) = (&model.k[blk], &model.k[image as usize]);
                let k_ok = (0..9).all(|e| {
                    let (c, d) = (e / 3, e % 3);
                    let want = comp.sign[c] * comp.sign[d] * k[e];
                    (ki[3 * comp.to[c] + comp.to[d]] - want).abs() <= SYMMETRY_TOLERANCE * k_max
                });
                k_ok && (model.m[image as usize] - model.m[blk]).abs() <= SYMMETRY_TOLERANCE * m_max
            });
        for blk in image_row {
            at[p.col[blk] as usize] = u32::MAX;
        }
        same
    })
}

/// A class solved: its pairs and vectors, still on the representatives.
struct ClassAnswer {
    chi: u8,
    /// The swaps mapping it onto each class that is an image of it.
    images: Vec<Vec<usize>>,
    /// What it was asked for.
    asked: ModeCount,
    solution: EigenSolution,
}

/// Solves `model` class by class when it has a mirror and is between [`MIN_DOFS`] and
/// [`MAX_DOFS`], else `None` (the caller solves it whole). A class too small for the request also gives `None`.
pub fn solve_until(
    model: &FemModel,
    options: &EigenOptions,
    stop: Stop,
) -> Option<Result<EigenSolution, EigenError>> {
    if !(MIN_DOFS..=MAX_DOFS).contains(&model.dofs()) {
        return None;
    }
    let t0 = Instant::now();
    let mirrors = Mirrors::detect(model)?;
    match solve_classes(model, &mirrors, options, stop, t0) {
        Err(EigenError::TooFewDofs { .. }) => None,
        answer => Some(answer),
    }
}

/// The class-by-class solve (see the module docs).
fn solve_classes(
    model: &FemModel,
    mirrors: &Mirrors,
    options: &EigenOptions,
    stop: Stop,
    t0: Instant,
) -> Result<EigenSolution, EigenError> {
    let whole = Operators::new(model);
    let shift = -SHIFT_RELATIVE * whole.scale;
    let classes = mirrors.classes();
    let groups_of_classes = mirrors.groups();
    // The first class makes room for 1.5 times its share of the request; the others ask for
    // the modes below what that share reached in it (classes have about equal densities of
    // modes), or below the k-th lowest found so far once that is known.
    let groups = classes.len();
    let (first, share) = match options.count {
        ModeCount::First(k) => (
            ModeCount::First((3 * k).div_ceil(2 * groups).min(k) + 2),
            k.div_ceil(groups),
        ),
        below => (below, BELOW_SHARE.div_ceil(groups)),
    };
    let p = model.kind.order() as i64;
    let coords: Vec<[i64; 3]> = mirrors
        .reps
        .iter()
        .map(|&n| model.node_lattice_coords(n))
        .collect();
    let nodes = ordering::nested_dissection_of(&coords, p);
    let (mut iterate_ms, mut iterations) = (0.0, 0);
    let mut solved: Vec<ClassAnswer> = Vec::with_capacity(groups);
    let mut problems = Vec::with_capacity(groups);
    let mut estimate = None;
    for group in &groups_of_classes {
        let chi = group[0].0;
        let class = mirrors.reduce(model, chi);
        let shifted: Vec<[f64; 9]> = class
            .k
            .iter()
            .zip(&class.m)
            .map(|(k, m)| {
                std::array::from_fn(|e| match e {
                    0 | 4 | 8 => k[e] - shift * m[e / 4],
                    _ => k[e],
                })
            })
            .collect();
        let mut llt = ShiftedCholesky::for_class(&class.pattern, &shifted, &nodes)?;
        drop(shifted);
        stop.check()?;
        let count = match (kth_lowest(&solved, options.count), estimate) {
            (Some(bound), _) => ModeCount::Below(bound * (1.0 + BOUND_MARGIN)),
            (None, Some(e)) => ModeCount::Below(e),
            (None, None) => first,
        };
        let ops = class.operators(&whole);
        let solution = solve_class(&ops, &mut llt, shift, options, count, share, stop)?;
        if estimate.is_none() && matches!(options.count, ModeCount::First(_)) {
            // Where this class holds 1.25 times its share.
            let e = &solution.eigenvalues;
            estimate = e
                .get((5 * share / 4).min(e.len().saturating_sub(1)))
                .copied();
        }
        iterate_ms += solution.timings.iterate_ms;
        iterations += solution.iterations;
        solved.push(ClassAnswer {
            chi,
            images: group[1..].iter().map(|(_, path)| path.clone()).collect(),
            asked: count,
            solution,
        });
        problems.push((class, llt));
    }
    // Until every class holds every mode below the k-th lowest found: a class whose request
    // stopped below that bound is asked again (or, while fewer than k modes are found at
    // all, the classes asked below a bound are asked below a higher one).
    let asks_first = matches!(options.count, ModeCount::First(_));
    for _ in 0..MAX_ROUNDS {
        let bound = kth_lowest(&solved, options.count);
        let mut again = Vec::new();
        for (i, answer) in solved.iter().enumerate() {
            let found = &answer.solution.eigenvalues;
            let top = found.last().copied().unwrap_or(0.0);
            let limit = match (answer.asked, bound) {
                (ModeCount::First(asked), Some(b)) if found.len() >= asked && top <= b => Some(b),
                (ModeCount::Below(l), Some(b)) if l < b => Some(b),
                (ModeCount::Below(l), None) if asks_first => Some(l * RAISE),
                _ => None,
            };
            if let Some(limit) = limit {
                again.push((i, limit * (1.0 + BOUND_MARGIN)));
            }
        }
        if again.is_empty() {
            let total_ms = t0.elapsed().as_secs_f64() * 1e3;
            return Ok(combine(
                mirrors,
                &solved,
                options.count,
                SolveTimings {
                    setup_ms: total_ms - iterate_ms,
                    iterate_ms,
                },
                iterations,
            ));
        }
        for (i, limit) in again {
            let (class, llt) = &mut problems[i];
            let ops = class.operators(&whole);
            let count = ModeCount::Below(limit);
            let room = solved[i].solution.eigenvalues.len() * 3 / 2;
            let solution = solve_class(&ops, llt, shift, options, count, room, stop)?;
            iterate_ms += solution.timings.iterate_ms;
            iterations += solution.iterations;
            solved[i].asked = count;
            solved[i].solution = solution;
        }
    }
    // Never seen: each round either raises a bound or settles every class at it.
    Err(EigenError::TooFewDofs {
        dofs: model.dofs(),
        wanted: match options.count {
            ModeCount::First(k) => k,
            ModeCount::Below(_) => 0,
        },
    })
}

/// One class's Lanczos solve for `count`, with room for about `expected` modes below a bound.
fn solve_class(
    ops: &Operators,
    llt: &mut ShiftedCholesky,
    shift: f64,
    options: &EigenOptions,
    count: ModeCount,
    expected: usize,
    stop: Stop,
) -> Result<EigenSolution, EigenError> {
    // Room for six rigid modes whichever the class holds: the basis needs the slack.
    let room = FirstRoom {
        rigid: RIGID_ROOM,
        below: 2 * expected + RIGID_ROOM,
    };
    let class_options = EigenOptions { count, ..*options };
    lanczos::run_with_room(ops, llt, shift, &class_options, stop, room)
}

/// The k-th lowest mode the classes found, for a "first k" request that has found k: an upper
/// bound on the whole model's k-th.
fn kth_lowest(solved: &[ClassAnswer], count: ModeCount) -> Option<f64> {
    let ModeCount::First(k) = count else {
        return None;
    };
    let mut all: Vec<f64> = solved
        .iter()
        .flat_map(|s| {
            let copies = 1 + s.images.len();
            s.solution
                .eigenvalues
                .iter()
                .flat_map(move |&l| std::iter::repeat_n(l, copies))
        })
        .collect();
    (all.len() >= k).then(|| *all.select_nth_unstable_by(k - 1, f64::total_cmp).1)
}

/// Rounds of asking classes again before giving up on the class-by-class solve.
const MAX_ROUNDS: usize = 8;

/// How much a class's bound is raised while fewer than k modes are found.
const RAISE: f64 = 1.5;

/// A "below" bound is widened by this relative margin, so a mode at the bound itself (its
/// twin in another class, rounded differently) is not missed.
const BOUND_MARGIN: f64 = 1e-9;

/// Modes a "below f_max" request is expected to hold, for the first room of its classes.
const BELOW_SHARE: usize = 20;

/// Pairs of room a class's basis first keeps beyond its modes (a class holds one to three of
/// the six rigid motions): with six, the whole solve's room, the default bowl's first classes
/// filled their bases and restarted once; with twelve none did.
const RIGID_ROOM: usize = 12;

/// A class's answer lifted to the whole model (or mapped onto an image class).
struct Lifted<'a> {
    solution: &'a EigenSolution,
    vectors: Mat<f64>,
    rigid: Mat<f64>,
    guards: Mat<f64>,
}

/// The whole model's answer from its classes': the lowest pairs of all (or those below the
/// bound), lifted, the solved classes' and their images'; rigid modes of every class; the next
/// pairs above as guards.
fn combine(
    mirrors: &Mirrors,
    solved: &[ClassAnswer],
    count: ModeCount,
    timings: SolveTimings,
    iterations: usize,
) -> EigenSolution {
    let mut lifted = Vec::new();
    for s in solved {
        let sol = &s.solution;
        let own = Lifted {
            solution: sol,
            vectors: mirrors.lift(s.chi, sol.vectors.as_ref()),
            rigid: mirrors.lift(s.chi, sol.rigid_vectors.as_ref()),
            guards: mirrors.lift(s.chi, sol.guard_vectors.as_ref()),
        };
        for path in &s.images {
            lifted.push(Lifted {
                solution: sol,
                vectors: mirrors.image_of(own.vectors.clone(), path),
                rigid: mirrors.image_of(own.rigid.clone(), path),
                guards: mirrors.image_of(own.guards.clone(), path),
            });
        }
        lifted.push(own);
    }
    // (eigenvalue, lifted answer, column, residual)
    let mut pairs: Vec<(f64, usize, usize, f64)> = lifted
        .iter()
        .enumerate()
        .flat_map(|(i, l)| {
            let sol = l.solution;
            (0..sol.eigenvalues.len()).map(move |j| (sol.eigenvalues[j], i, j, sol.residuals[j]))
        })
        .collect();
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let keep = match count {
        ModeCount::First(k) => k.min(pairs.len()),
        ModeCount::Below(l) => pairs.iter().take_while(|p| p.0 <= l).count(),
    };
    let n = 3 * mirrors.orbit_of.len();
    let rigid_modes: usize = lifted.iter().map(|l| l.solution.rigid_modes).sum();
    let column = |p: &(f64, usize, usize, f64)| lifted[p.1].vectors.col(p.2);
    let mut guards: Vec<Mat<f64>> = Vec::new();
    let guard_count = warm_guard(rigid_modes + keep);
    let extra = &pairs[keep..pairs.len().min(keep + guard_count)];
    guards.push(columns_of(n, extra, column));
    let mut have = extra.len();
    for l in &lifted {
        if have >= guard_count {
            break;
        }
        let take = l.guards.ncols().min(guard_count - have);
        guards.push(l.guards.get(.., 0..take).to_owned());
        have += take;
    }
    let rigid: Vec<Mat<f64>> = lifted.iter().map(|l| l.rigid.clone()).collect();
    EigenSolution {
        eigenvalues: pairs[..keep].iter().map(|p| p.0).collect(),
        vectors: columns_of(n, &pairs[..keep], column),
        residuals: pairs[..keep].iter().map(|p| p.3).collect(),
        rigid_modes,
        timings,
        iterations,
        solver: SolverKind::Lanczos,
        warm_start: false,
        guard_vectors: concat_columns(n, &guards),
        rigid_vectors: concat_columns(n, &rigid),
    }
}

/// The columns `column(pair)` of `pairs`, side by side.
fn columns_of<'a>(
    n: usize,
    pairs: &[(f64, usize, usize, f64)],
    column: impl Fn(&(f64, usize, usize, f64)) -> faer::ColRef<'a, f64>,
) -> Mat<f64> {
    let mut out = Mat::zeros(n, pairs.len());
    for (j, p) in pairs.iter().enumerate() {
        out.col_mut(j).copy_from(column(p));
    }
    out
}

/// The columns of `parts`, side by side.
fn concat_columns(n: usize, parts: &[Mat<f64>]) -> Mat<f64> {
    let total = parts.iter().map(|p| p.ncols()).sum();
    let mut out = Mat::zeros(n, total);
    let mut at = 0;
    for p in parts {
        out.as_mut().get_mut(.., at..at + p.ncols()).copy_from(p);
        at += p.ncols();
    }
    out
}
