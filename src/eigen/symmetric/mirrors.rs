//! The mirrors and axis swaps of a model, its node orbits under them, and one symmetry class's
//! reduced `K` and `M` and lifted vectors (see [`super`] for the theory and the solve).

use super::check::{maps_matrices, Components};
use super::reduced::ReducedPattern;
use crate::eigen::Operators;
use crate::fem::sparse::BlockPattern;
use crate::fem::FemModel;
use faer::Mat;

/// A mirror is accepted when every mapped block of `K` and `M` matches to this fraction of the
/// matrix's largest entry: rounding in the refined fills of cut elements, not a real
/// asymmetry (whose effect on the frequencies would be of the same relative size).
pub const SYMMETRY_TOLERANCE: f64 = 1e-11;

/// The mirror symmetries of a model and its node orbits under them.
pub struct Mirrors {
    /// Mirrored axes as a bit mask (bit `a`: the plane normal to axis `a`).
    pub(super) axes: u8,
    /// Swaps of two mirrored axes that are symmetries too.
    swaps: Vec<Swap>,
    /// Orbit of each node.
    pub(super) orbit_of: Vec<u32>,
    /// The group element (a mask of mirrored axes) mapping its orbit's representative to
    /// each node.
    from_rep: Vec<u8>,
    /// Representative node of each orbit.
    pub(super) reps: Vec<usize>,
    /// Nodes in each orbit.
    size: Vec<u8>,
    /// Each orbit representative's stabiliser: the mirrors whose plane holds it.
    fixed: Vec<u8>,
    /// The classes' common pattern, made by the first reduction.
    class_pattern: std::sync::OnceLock<ReducedPattern>,
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
        // K and M are positive semi-definite, so no entry exceeds the largest diagonal one.
        let p = &model.pattern;
        let (mut k_max, mut m_max) = (0.0f64, 0.0f64);
        for a in 0..nodes {
            let d = p.find(a, a as u32).expect("diagonal block");
            k_max = k_max
                .max(model.k()[d][0])
                .max(model.k()[d][4])
                .max(model.k()[d][8]);
            m_max = m_max.max(model.m()[d]);
        }
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
            class_pattern: std::sync::OnceLock::new(),
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

    /// The first swap that maps class `chi` onto itself (the class is even in both of its
    /// axes' mirrors or odd in both), which splits it in two ([`super::split`]).
    pub fn splitting_swap(&self, chi: u8) -> Option<usize> {
        self.swaps.iter().position(|s| s.class(chi) == chi)
    }

    /// The two axes of swap number `swap`.
    pub(super) fn swap_axes(&self, swap: usize) -> (usize, usize) {
        self.swaps[swap].axes
    }

    /// Node `node`'s image under swap number `swap`.
    pub(super) fn swap_image(&self, swap: usize, node: usize) -> usize {
        self.swaps[swap].map[node] as usize
    }

    /// The symmetry classes: one character per subset of the mirrors (bit `a` set: odd in
    /// the mirror along axis `a`).
    pub fn classes(&self) -> Vec<u8> {
        subsets(self.axes).collect()
    }

    /// The classes in groups that the axis swaps map onto one another: each group's first
    /// class is solved, the others are images of it (each with the swaps, in order, that map
    /// the first onto it).
    pub(super) fn groups(&self) -> Vec<Vec<(u8, Vec<usize>)>> {
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

    /// Whether the DOF `c` of orbit `o` exists in class `chi`: every mirror that fixes the
    /// representative must map its basis vector to itself times `chi`.
    pub(super) fn present(&self, o: usize, c: usize, chi: u8) -> bool {
        (0..3)
            .filter(|a| self.fixed[o] & (1 << a) != 0)
            .all(|a| (chi & (1 << a) != 0) == (c == a))
    }

    /// `sigma_q(c)`: the sign of node `q`'s component `c` in its orbit's class-`chi` vector.
    pub(super) fn sign(&self, q: usize, c: usize, chi: u8) -> f64 {
        element_sign(self.from_rep[q], c, chi)
    }

    /// The classes' common pattern, made on the first call (see [`ReducedPattern`]).
    fn class_pattern(&self, model: &FemModel) -> &ReducedPattern {
        self.class_pattern
            .get_or_init(|| ReducedPattern::new(&model.pattern, &self.reps, |q| self.orbit_of[q]))
    }

    /// `K` and `M` of class `chi` on the orbit representatives.
    pub fn reduce(&self, model: &FemModel, chi: u8) -> ClassProblem {
        let orbits = self.reps.len();
        let p = &model.pattern;
        let plan = self.class_pattern(model);
        let blocks = plan.pattern.col.len();
        let (mut k, mut m) = (vec![[0.0; 9]; blocks], vec![[0.0; 3]; blocks]);
        // The factors of the sum, as tables: whether each orbit has each component in this
        // class (1 or 0), each node's signs (by the group element that maps its orbit's
        // representative onto it) and `sqrt(size_o / size_orbit)` by the sizes' logarithms
        // (orbits hold 1, 2, 4 or 8 nodes). Multiplied by them, a block's sum has no
        // branches, and each entry the class has gets the product `w sigma` it always had.
        let has: Vec<[f64; 3]> = (0..orbits)
            .map(|o| std::array::from_fn(|c| f64::from(u8::from(self.present(o, c, chi)))))
            .collect();
        let signs: [[f64; 3]; 8] =
            std::array::from_fn(|g| std::array::from_fn(|c| element_sign(g as u8, c, chi)));
        let roots: [[f64; 4]; 4] = std::array::from_fn(|i| {
            std::array::from_fn(|j| (f64::from(1u8 << i) / f64::from(1u8 << j)).sqrt())
        });
        let log_size: Vec<u8> = self.size.iter().map(|s| s.trailing_zeros() as u8).collect();
        let mut target = plan.target.iter();
        for (o, &rep) in self.reps.iter().enumerate() {
            let own = has[o];
            let w_row = &roots[usize::from(log_size[o])];
            for blk in p.row_ptr[rep]..p.row_ptr[rep + 1] {
                let q = p.col[blk] as usize;
                let orbit = self.orbit_of[q] as usize;
                let at = *target.next().expect("a target per block") as usize;
                let w = w_row[usize::from(log_size[orbit])];
                let (sign, there) = (&signs[usize::from(self.from_rep[q])], &has[orbit]);
                // Column d's factor: w sigma_q(d) where the orbit has component d, else 0.
                let s: [f64; 3] = std::array::from_fn(|d| (w * sign[d]) * there[d]);
                let (kb, kr) = (&model.k()[blk], &mut k[at]);
                for c in 0..3 {
                    for d in 0..3 {
                        kr[3 * c + d] += (s[d] * own[c]) * kb[3 * c + d];
                    }
                }
                let mr = &mut m[at];
                for d in 0..3 {
                    mr[d] += (s[d] * own[d]) * model.m()[blk];
                }
            }
            // An absent DOF: a decoupled row with the whole model's stiffness and no mass (an
            // infinite eigenvalue, which shift-invert never approaches).
            let (diag, own_blk) = plan.diagonal[o];
            for c in (0..3).filter(|&c| own[c] == 0.0) {
                k[diag as usize][4 * c] = model.k()[own_blk as usize][4 * c];
            }
        }
        let absent = (0..orbits)
            .flat_map(|o| (0..3).map(move |c| (o, c)))
            .filter(|&(o, c)| !self.present(o, c, chi))
            .map(|(o, c)| 3 * o + c)
            .collect();
        ClassProblem {
            chi,
            pattern: plan.pattern.clone(),
            k,
            m,
            mass_extra: Vec::new(),
            absent,
        }
    }

    /// The whole model's vectors of class-`chi` vectors `x` (one row per class DOF).
    pub fn lift(&self, chi: u8, x: faer::MatRef<'_, f64>) -> Mat<f64> {
        Lifting::new(self, chi).apply(x)
    }
}

/// Each whole-model DOF's class DOF and coefficient in one class's basis (zero where the class
/// lacks it): what lifting a class's vectors reads, made once per class.
pub(super) struct Lifting(Vec<(usize, f64)>);

impl Lifting {
    /// The lifting of class `chi`.
    pub(super) fn new(mirrors: &Mirrors, chi: u8) -> Self {
        let n = 3 * mirrors.orbit_of.len();
        Lifting(
            (0..n)
                .map(|i| {
                    let (q, c) = (i / 3, i % 3);
                    let o = mirrors.orbit_of[q] as usize;
                    if !mirrors.present(o, c, chi) {
                        return (0, 0.0);
                    }
                    let w = mirrors.sign(q, c, chi) / f64::from(mirrors.size[o]).sqrt();
                    (3 * o + c, w)
                })
                .collect(),
        )
    }

    /// This lifting followed by the swaps `path`, in order: the lifting of the class that
    /// `path` maps this one onto ([`Mirrors::groups`]), whose vectors are the images of this
    /// class's (a swap permutes the whole model's DOFs: `y(map q)[to c] = x(q)[c]`).
    pub(super) fn mapped(&self, mirrors: &Mirrors, path: &[usize]) -> Self {
        let mut lifting = self.0.clone();
        let mut image = vec![(0, 0.0); lifting.len()];
        for &i in path {
            let swap = &mirrors.swaps[i];
            let to = Components::swap(swap.axes.0, swap.axes.1).to;
            for (q, &at) in swap.map.iter().enumerate() {
                for (c, &tc) in to.iter().enumerate() {
                    image[3 * at as usize + tc] = lifting[3 * q + c];
                }
            }
            std::mem::swap(&mut lifting, &mut image);
        }
        Lifting(lifting)
    }

    /// This lifting followed by `map`, which takes each class DOF to the DOF and coefficient
    /// of a smaller problem's basis ([`super::split::Split`]).
    pub(super) fn then(self, map: impl Fn(usize) -> (usize, f64)) -> Self {
        Lifting(
            (self.0.into_iter())
                .map(|(i, w)| {
                    if w == 0.0 {
                        return (0, 0.0);
                    }
                    let (j, v) = map(i);
                    (j, w * v)
                })
                .collect(),
        )
    }

    /// The whole model's vectors of class vectors `x`.
    pub(super) fn apply(&self, x: faer::MatRef<'_, f64>) -> Mat<f64> {
        let mut out = Mat::zeros(self.0.len(), x.ncols());
        for j in 0..x.ncols() {
            let to = out
                .col_mut(j)
                .try_as_col_major_mut()
                .expect("a fresh matrix's column");
            self.column(x.col(j), to.as_slice_mut());
        }
        out
    }

    /// The whole model's vector `out` of class vector `x`.
    pub(super) fn column(&self, x: faer::ColRef<'_, f64>, out: &mut [f64]) {
        let x = x
            .try_as_col_major()
            .expect("a class vector's column is contiguous");
        let x = x.as_slice();
        for (v, &(i, w)) in out.iter_mut().zip(&self.0) {
            *v = w * x[i];
        }
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
}

/// One symmetry class's eigenproblem on the orbit representatives.
pub struct ClassProblem {
    /// Its character (bit `a`: odd in the mirror along axis `a`).
    pub chi: u8,
    /// Pattern over the orbits.
    pub pattern: BlockPattern,
    /// Stiffness blocks.
    pub k: Vec<[f64; 9]>,
    /// Mass blocks' diagonals.
    pub m: Vec<[f64; 3]>,
    /// The mass's entries off the blocks' diagonals, as `(row DOF, column DOF, value)`, both
    /// triangles: none in a mirror class (its `M` couples equal components only), a few in
    /// a half of one split by a swap ([`super::split`]).
    pub mass_extra: Vec<(u32, u32, f64)>,
    /// The DOFs the class does not have.
    pub absent: Vec<usize>,
}

impl ClassProblem {
    /// Its operators, with the whole model's norms and scale (so residuals and the rigid
    /// threshold are the whole model's).
    pub(super) fn operators<'a>(&'a self, whole: &Operators) -> Operators<'a> {
        Operators {
            pattern: &self.pattern,
            k: &self.k,
            m: &[],
            mass_diagonal: Some(&self.m),
            mass_extra: &self.mass_extra,
            absent: &self.absent,
            k_norm: whole.k_norm,
            m_norm: whole.m_norm,
            scale: whole.scale,
        }
    }
}

/// `chi(g) [R_g]_cc`: the sign a class-`chi` vector's component `c` takes at the image of its
/// orbit's representative under `g` (a mask of mirrored axes; [`super`]'s `sigma_q(c)`).
fn element_sign(g: u8, c: usize, chi: u8) -> f64 {
    let flips = (g & chi).count_ones() + u32::from(g & (1 << c) != 0);
    if flips.is_multiple_of(2) {
        1.0
    } else {
        -1.0
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
