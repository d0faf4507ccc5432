//! The mirrors and axis swaps of a model, its node orbits under them, and one symmetry class's
//! reduced `K` and `M` and lifted vectors (see [`super`] for the theory and the solve).

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

/// The pattern of a reduction (a model's onto its classes', a class's onto its halves') and
/// where each block of the representatives' rows is summed. Every class of a model has the
/// same pattern over its orbits (the classes' DOFs differ, not their blocks), and so have
/// the halves of the classes one swap splits: it is worked out by the first reduction and
/// read by the others'.
pub(super) struct ReducedPattern {
    pub(super) pattern: BlockPattern,
    /// The reduced block each block of the representatives' rows is summed into, row by row.
    pub(super) target: Vec<u32>,
    /// Each reduced node's diagonal block and its representative's in the pattern reduced.
    pub(super) diagonal: Vec<(u32, u32)>,
}

impl ReducedPattern {
    /// The reduction of `p`'s rows `reps` (reduced node `r` from row `reps[r]`) onto
    /// `nodes` nodes, column `q` going to reduced node `node_of(q)` (so `node_of(reps[r]) =
    /// r`).
    pub(super) fn new(
        p: &BlockPattern,
        reps: &[usize],
        nodes: usize,
        node_of: impl Fn(usize) -> u32,
    ) -> Self {
        // The representatives' rows bound the reduced rows' lengths (nodes merge columns):
        // reserved once, the growing rows are not copied by reallocation.
        let bound: usize = reps.iter().map(|&r| p.row_ptr[r + 1] - p.row_ptr[r]).sum();
        let mut row_ptr = Vec::with_capacity(nodes + 1);
        row_ptr.push(0);
        let (mut col, mut target) = (Vec::with_capacity(bound), Vec::with_capacity(bound));
        let mut diagonal = Vec::with_capacity(nodes);
        let mut row = ReducedRow::new(nodes);
        for &rep in reps {
            let blocks = p.row_ptr[rep]..p.row_ptr[rep + 1];
            let columns = p.col[blocks.clone()].iter();
            row.open(columns.map(|&q| node_of(q as usize)), &mut col);
            target.extend(blocks.map(|blk| row.at(node_of(p.col[blk] as usize) as usize) as u32));
            let own = p.find(rep, rep as u32).expect("diagonal block");
            diagonal.push((row.at(node_of(rep) as usize) as u32, own as u32));
            row.close();
            row_ptr.push(col.len());
        }
        ReducedPattern {
            pattern: BlockPattern { row_ptr, col },
            target,
            diagonal,
        }
    }
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
                .max(model.k[d][0])
                .max(model.k[d][4])
                .max(model.k[d][8]);
            m_max = m_max.max(model.m[d]);
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

    /// Maps a whole-model vector of class `group[0]` onto class `member` by its swaps `path`,
    /// in place.
    pub(super) fn map_column(&self, x: &mut [f64], path: &[usize]) {
        if path.is_empty() {
            return;
        }
        let mut image = vec![0.0; x.len()];
        for &i in path {
            self.swaps[i].apply(x, &mut image);
            x.copy_from_slice(&image);
        }
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
        let g = self.from_rep[q];
        let flips = (g & chi).count_ones() + u32::from(g & (1 << c) != 0);
        if flips.is_multiple_of(2) {
            1.0
        } else {
            -1.0
        }
    }

    /// The classes' common pattern, made on the first call (see [`ReducedPattern`]).
    fn class_pattern(&self, model: &FemModel) -> &ReducedPattern {
        self.class_pattern.get_or_init(|| {
            ReducedPattern::new(&model.pattern, &self.reps, self.reps.len(), |q| {
                self.orbit_of[q]
            })
        })
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
        let signs: [[f64; 3]; 8] = std::array::from_fn(|g| {
            std::array::from_fn(|c| {
                let flips = (g as u8 & chi).count_ones() + u32::from(g & (1 << c) != 0);
                if flips.is_multiple_of(2) {
                    1.0
                } else {
                    -1.0
                }
            })
        });
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
                let (kb, kr) = (&model.k[blk], &mut k[at]);
                for c in 0..3 {
                    for d in 0..3 {
                        kr[3 * c + d] += (s[d] * own[c]) * kb[3 * c + d];
                    }
                }
                let mr = &mut m[at];
                for d in 0..3 {
                    mr[d] += (s[d] * own[d]) * model.m[blk];
                }
            }
            // An absent DOF: a decoupled row with the whole model's stiffness and no mass (an
            // infinite eigenvalue, which shift-invert never approaches).
            let (diag, own_blk) = plan.diagonal[o];
            for c in (0..3).filter(|&c| own[c] == 0.0) {
                k[diag as usize][4 * c] = model.k[own_blk as usize][4 * c];
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

    /// The image `y` of a whole-model vector `x`: `y(map q)[to c] = x(q)[c]`.
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        let comp = Components::swap(self.axes.0, self.axes.1);
        for (q, &image) in self.map.iter().enumerate() {
            for c in 0..3 {
                y[3 * image as usize + comp.to[c]] = x[3 * q + c];
            }
        }
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

/// Where each column of the reduced row being built sits, for a reduction that sums the
/// blocks of several original columns into one (orbits of nodes, pairs of orbits).
pub(super) struct ReducedRow {
    /// Block index of each reduced column in the open row; `u32::MAX` elsewhere.
    slot: Vec<u32>,
    /// The open row's reduced columns, sorted.
    cols: Vec<u32>,
}

impl ReducedRow {
    /// For reductions onto `columns` reduced columns.
    pub(super) fn new(columns: usize) -> Self {
        ReducedRow {
            slot: vec![u32::MAX; columns],
            cols: Vec::new(),
        }
    }

    /// Opens the next row, whose blocks fall in the reduced columns `targets` (repeats
    /// allowed): appends them, distinct and sorted, to the pattern's `col`.
    pub(super) fn open(&mut self, targets: impl Iterator<Item = u32>, col: &mut Vec<u32>) {
        self.cols.clear();
        for t in targets {
            if self.slot[t as usize] == u32::MAX {
                self.slot[t as usize] = 0;
                self.cols.push(t);
            }
        }
        self.cols.sort_unstable();
        let start = col.len();
        for (i, &t) in self.cols.iter().enumerate() {
            self.slot[t as usize] = (start + i) as u32;
        }
        col.extend_from_slice(&self.cols);
    }

    /// The block index of reduced column `t` in the open row.
    pub(super) fn at(&self, t: usize) -> usize {
        self.slot[t] as usize
    }

    /// Closes the open row.
    pub(super) fn close(&mut self) {
        for &t in &self.cols {
            self.slot[t as usize] = u32::MAX;
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
    // Entry `e = 3c + d` of a block goes to `to[e]`, times `sign[e]`.
    let to: [usize; 9] = std::array::from_fn(|e| 3 * comp.to[e / 3] + comp.to[e % 3]);
    let sign: [f64; 9] = std::array::from_fn(|e| comp.sign[e / 3] * comp.sign[e % 3]);
    let (k_tol, m_tol) = (SYMMETRY_TOLERANCE * k_max, SYMMETRY_TOLERANCE * m_max);
    // The symmetries are involutions, and `K` and `M` are symmetric (a block's transpose is
    // stored at the transposed place), so a block, its image, its transpose and its image's
    // transpose are all right when one of them is: the one with the largest row or column,
    // which is a block of row `a` at or before the diagonal, where `map[a] <= a`. Only those
    // are compared (about a quarter of the blocks: a half from each row of half the rows).
    (0..p.nodes()).all(|a| {
        if map[a] as usize > a {
            return true;
        }
        let image_row = p.row_ptr[map[a] as usize]..p.row_ptr[map[a] as usize + 1];
        let row = p.row_ptr[a]..p.row_ptr[a + 1];
        if row.len() != image_row.len() {
            return false;
        }
        for blk in image_row.clone() {
            at[p.col[blk] as usize] = blk as u32;
        }
        let lower = row.start..row.start + p.col[row].partition_point(|&b| b as usize <= a);
        // The image row's blocks by column, so each block's image is one lookup; they are
        // visited in the order of row `a`'s mapped columns, which the hardware does not
        // prefetch, so they are asked for first (the tin can's four passes over every row
        // and its whole image: 12.4 -> 7.1 ms).
        let image_of = |blk: usize| at[map[p.col[blk] as usize] as usize];
        for blk in lower.clone() {
            if let Some(block) = model.k.get(image_of(blk) as usize) {
                prefetch(block);
            }
        }
        let same = lower.into_iter().all(|blk| {
            let image = image_of(blk);
            if image == u32::MAX {
                return false;
            }
            let (k, ki) = (&model.k[blk], &model.k[image as usize]);
            // Branch-free over the block: one comparison per block, not per entry.
            let worst = (0..9).fold(0.0f64, |w, e| w.max((ki[to[e]] - sign[e] * k[e]).abs()));
            worst <= k_tol && (model.m[image as usize] - model.m[blk]).abs() <= m_tol
        });
        for blk in image_row {
            at[p.col[blk] as usize] = u32::MAX;
        }
        same
    })
}

/// Asks the cache for `block` ahead of its use.
#[inline(always)]
fn prefetch(block: &[f64; 9]) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let start = block.as_ptr().cast::<i8>();
        // SAFETY: a prefetch is a hint that never faults or changes memory; both addresses
        // lie within the 72-byte block (its first byte and the first of the next cache line
        // it may span).
        unsafe {
            _mm_prefetch::<_MM_HINT_T0>(start);
            _mm_prefetch::<_MM_HINT_T0>(start.add(64));
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = block;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::ElementKind;

    /// The check compares about a quarter of the blocks (`maps_matrices`), standing for the
    /// rest by the symmetry of `K`. Independent truth: a box with three mirrors and the x-y
    /// swap, every pair of transposed blocks changed in turn (one entry off the diagonal, and
    /// its transpose, by 1e-8 of the largest entry: far above the 1e-11 tolerance, so no
    /// mirror holds it exactly), and each time some mirror or swap must be refused. A check
    /// that skipped any block's orbit would keep all of them for that block.
    #[test]
    fn a_change_in_any_block_breaks_a_symmetry() {
        let model = crate::fem::test_model("box:x=4,y=4,z=3", ElementKind::Hex8Incompatible, 0.3);
        let before = Mirrors::detect(&model).expect("mirrors");
        assert_eq!((before.axes(), before.swaps()), (0b111, vec![(0, 1)]));
        let k_max = model.k.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
        let p = &model.pattern;
        let mut changed = model.clone();
        for a in 0..p.nodes() {
            for blk in p.row_ptr[a]..p.row_ptr[a + 1] {
                let b = p.col[blk] as usize;
                if b > a {
                    continue;
                }
                let transposed = p.find(b, a as u32).expect("a symmetric pattern");
                let delta = 1e-8 * k_max;
                changed.k[blk][1] += delta;
                changed.k[transposed][3] += delta;
                let after = Mirrors::detect(&changed);
                let kept = after
                    .as_ref()
                    .map_or((0, vec![]), |m| (m.axes(), m.swaps()));
                assert_ne!(kept, (0b111, vec![(0, 1)]), "block ({a}, {b}) changed");
                changed.k[blk] = model.k[blk];
                changed.k[transposed] = model.k[transposed];
            }
        }
    }
}
