//! Cut elements related by a symmetry of the cube share one integration: an assembly
//! integrates one element per orbit of sub-cell fills and maps its matrices to the others.
//!
//! Where it sits: [`crate::fem::FemModel::assemble`] asks [`Orbits::find`] for every cut
//! element before batching it for [`super::CutElement::matrices_batch`]. The primitives
//! (bowls, bells, cups, spheres, tubes) are symmetric under the lattice's reflections and
//! quarter turns about their axes, and their rasterised fills are too, bit for bit: a
//! 16-voxel bowl's partial voxels come in orbits of 8 (48 for a sphere's). A sculpted object
//! keeps the orbits its strokes did not touch.
//!
//! **Why it is exact.** Let `g` be one of the cube's 48 symmetries, acting on points in
//! the element's centred coordinates as `x'_k = s_k x_{sigma(k)}` (a signed permutation `R`,
//! `R_{k sigma(k)} = s_k`), on sub-cells and nodes as the lattice points it maps, and on a fill
//! as `(g f)(g c) = f(c)`. The element's energy is invariant: the elasticity is isotropic,
//! the trilinear (or triquadratic) nodal fields and hex8i's incompatible modes
//! `(1 - xi_k^2) e_j` are mapped onto themselves, and the Taylor correction (the bubbles' mean
//! strain over the filled part, removed) is defined without reference to axes. So
//! `K_{g f}(g a, g b) = R K_f(a, b) R^T` and `M_{g f}(g a, g b) = M_f(a, b)`, to rounding
//! (a test checks all 48 against direct integration).
//!
//! **The orbit's key** is its canonical fill: of the 48 images of an element's sub-cell
//! weights, the smallest in lexicographic order. The key holds every weight exactly, so a
//! match is an equal fill (up to the symmetry), never a near one.

use crate::fem::sparse::ElementBlocks;
use crate::shape::{lattice_coords, lattice_index};
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};
use std::sync::Arc;

use crate::fem::memo::Memo;

/// One symmetry of the cube, as it acts on one element kind's sub-cells and nodes.
#[derive(Clone, Debug)]
struct Symmetry {
    /// `pull[i]`: the sub-cell whose weight lands on sub-cell `i` (`(g f)[i] = f[pull[i]]`).
    pull: Vec<u16>,
    /// Per node pair `p = (a, b)`, `a <= b` ([`ElementBlocks`] order): the pair `(g a, g b)`
    /// sorted, and whether its block is the transpose of the mapped one.
    pairs: Vec<(u32, bool)>,
    /// The mapped block `Y = R X R^T` entry by entry: `Y[i] = sign * X[from]`.
    rotate: [(usize, f64); 9],
    /// The index of the inverse symmetry.
    inverse: usize,
}

/// The 48 symmetries of the cube for one element kind.
#[derive(Clone, Debug)]
pub struct Symmetries {
    ops: Vec<Symmetry>,
    /// Sub-cells per axis.
    cells: usize,
}

/// Lattice point `c` (`n` per axis, x fastest) mapped by the signed axis permutation.
fn map_point(c: [usize; 3], sigma: [usize; 3], flip: [bool; 3], n: usize) -> [usize; 3] {
    std::array::from_fn(|k| {
        let v = c[sigma[k]];
        if flip[k] {
            n - 1 - v
        } else {
            v
        }
    })
}

impl Symmetries {
    /// The symmetries for an element with `nodes_per_axis` nodes and `subcells_per_axis`
    /// sub-cells on each axis (hex8: 2 and 2).
    pub fn new(nodes_per_axis: usize, subcells_per_axis: usize) -> Self {
        // A lattice point's index and coordinates, `n` points per axis.
        let index = |c: [usize; 3], n: usize| lattice_index(c, [n; 3]);
        let coords = |i: usize, n: usize| lattice_coords(i, [n; 3]);
        let mut moves: Vec<([usize; 3], [bool; 3])> = Vec::with_capacity(48);
        for sigma in crate::shape::PERMS {
            for signs in 0..8 {
                moves.push((sigma, [0, 1, 2].map(|k| signs >> k & 1 == 1)));
            }
        }
        let s = subcells_per_axis;
        let n = nodes_per_axis;
        let nodes = n * n * n;
        let pair_index = |a: usize, b: usize| a * nodes - a * a.saturating_sub(1) / 2 + b - a;
        let mut ops: Vec<Symmetry> = moves
            .iter()
            .map(|&(sigma, flip)| {
                let mut pull = vec![0u16; s * s * s];
                for c in 0..s * s * s {
                    pull[index(map_point(coords(c, s), sigma, flip, s), s)] = c as u16;
                }
                let node = |a: usize| index(map_point(coords(a, n), sigma, flip, n), n);
                let mut pairs = Vec::with_capacity(nodes * (nodes + 1) / 2);
                for a in 0..nodes {
                    for b in a..nodes {
                        let (ga, gb) = (node(a), node(b));
                        pairs.push((pair_index(ga.min(gb), ga.max(gb)) as u32, ga > gb));
                    }
                }
                let sign = |k: usize| if flip[k] { -1.0 } else { 1.0 };
                let rotate = std::array::from_fn(|i| {
                    let (k, l) = (i / 3, i % 3);
                    (3 * sigma[k] + sigma[l], sign(k) * sign(l))
                });
                Symmetry {
                    pull,
                    pairs,
                    rotate,
                    inverse: usize::MAX,
                }
            })
            .collect();
        // The inverse of x'_k = s_k x_{sigma(k)}: x_j = s_{sigma^-1(j)} x'_{sigma^-1(j)}.
        for (op, &(sigma, flip)) in ops.iter_mut().zip(&moves) {
            let mut undo = [0; 3];
            for k in 0..3 {
                undo[sigma[k]] = k;
            }
            let inverse = (undo, undo.map(|k| flip[k]));
            op.inverse = moves
                .iter()
                .position(|&m| m == inverse)
                .expect("the symmetries form a group");
        }
        Symmetries { ops, cells: s }
    }

    /// Number of symmetries (48).
    pub fn count(&self) -> usize {
        self.ops.len()
    }

    /// The sub-cell weights `weights` mapped by symmetry `g` into `out`.
    pub fn map_fill(&self, g: usize, weights: &[f64], out: &mut [f64]) {
        for (o, &from) in out.iter_mut().zip(&self.ops[g].pull) {
            *o = weights[from as usize];
        }
    }

    /// The matrices of the mapped element, `K'(g a, g b) = R K(a, b) R^T`, `M'(g a, g b) =
    /// M(a, b)`, into `out`.
    pub fn map_blocks(&self, g: usize, blocks: &ElementBlocks, out: &mut ElementBlocks) {
        let op = &self.ops[g];
        for ((x, &m), &(to, transpose)) in blocks.k.iter().zip(&blocks.m).zip(&op.pairs) {
            let y = &mut out.k[to as usize];
            for (i, &(from, sign)) in op.rotate.iter().enumerate() {
                let at = if transpose { 3 * (i % 3) + i / 3 } else { i };
                y[at] = sign * x[from];
            }
            out.m[to as usize] = m;
        }
    }

    /// The inverse of symmetry `g`.
    pub fn inverse(&self, g: usize) -> usize {
        self.ops[g].inverse
    }

    /// The symmetries that orient `input` by its first moments about the centre: the
    /// image's moments are non-negative and descending along x, y, z (its moment along axis
    /// `k` is `s_k` times the original's along `sigma(k)`). One where the moments are nonzero
    /// and differ in size; where one is zero, or two are equal in size (an element symmetric,
    /// or nearly, under a mirror or a swap), each choice. Integer sums: two images'
    /// orientations agree exactly.
    fn orienting(&self, input: &[u8]) -> impl Iterator<Item = usize> + use<> {
        let s = self.cells;
        let mut moments = [0i64; 3];
        let centred = |c: usize| 2 * c as i64 + 1 - s as i64;
        for (z, plane) in input.chunks_exact(s * s).enumerate() {
            for (y, row) in plane.chunks_exact(s).enumerate() {
                let (mut sum, mut first) = (0i64, 0i64);
                for (x, &w) in row.iter().enumerate() {
                    sum += i64::from(w);
                    first += i64::from(w) * centred(x);
                }
                moments[0] += first;
                moments[1] += sum * centred(y);
                moments[2] += sum * centred(z);
            }
        }
        // `new` lists the moves permutation by permutation, eight sign patterns each.
        (0..48).filter(move |g| {
            let sigma = crate::shape::PERMS[g / 8];
            let image: [i64; 3] = std::array::from_fn(|k| {
                let sign = if (g % 8) >> k & 1 == 1 { -1 } else { 1 };
                sign * moments[sigma[k]]
            });
            image[0] >= image[1] && image[1] >= image[2] && image[2] >= 0
        })
    }

    /// The image of `input` under symmetry `g` into `out`.
    fn map_input(&self, g: usize, input: &[u8], out: &mut Vec<u8>) {
        out.clear();
        out.extend(self.ops[g].pull.iter().map(|&from| input[from as usize]));
    }

    /// The symmetries for `nodes_per_axis` and `subcells_per_axis`, made once per process.
    pub fn shared(nodes_per_axis: usize, subcells_per_axis: usize) -> Arc<Self> {
        static KEPT: Memo<(usize, usize), Symmetries> = Memo::new();
        KEPT.get_or_make((nodes_per_axis, subcells_per_axis), || {
            Self::new(nodes_per_axis, subcells_per_axis)
        })
    }

    /// The symmetry among `candidates` that maps `weights` to the smallest image in
    /// lexicographic order (weights are non-negative, so their bits order them), and that
    /// image's bits into `key`. With every symmetry whose image can be smallest among the
    /// candidates, that image is the orbit's canonical fill.
    fn canonical(
        &self,
        weights: &[f64],
        candidates: impl Iterator<Item = usize>,
        key: &mut Vec<u64>,
    ) -> usize {
        let image = |g: usize, i: usize| weights[self.ops[g].pull[i] as usize].to_bits();
        let mut best = usize::MAX;
        for g in candidates {
            if best == usize::MAX {
                best = g;
                continue;
            }
            for i in 0..weights.len() {
                let (candidate, current) = (image(g, i), image(best, i));
                if candidate != current {
                    if candidate < current {
                        best = g;
                    }
                    break;
                }
            }
        }
        key.clear();
        key.extend((0..weights.len()).map(|i| image(best, i)));
        best
    }
}

/// A 64-bit multiply-xor hash for the orbits' keys (whole `f64` bit patterns: no need for
/// the standard library's DoS-resistant one).
#[derive(Default)]
struct KeyHasher(u64);

impl Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for chunk in bytes.chunks(8) {
            let mut word = [0u8; 8];
            word[..chunk.len()].copy_from_slice(chunk);
            self.0 = (self.0.rotate_left(5) ^ u64::from_le_bytes(word))
                .wrapping_mul(0x9e37_79b9_7f4a_7c15);
        }
    }
}

/// Where an element's matrices come from ([`Orbits::find`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Found {
    /// The first of its orbit: integrate it, then [`Orbits::keep`] its matrices.
    New {
        /// The orbit.
        orbit: usize,
        /// The symmetry from the element's fill to the canonical one.
        g: usize,
    },
    /// An orbit seen before: [`Orbits::matrices`] once it is kept.
    Seen {
        /// The orbit.
        orbit: usize,
        /// The symmetry from the element's fill to the canonical one.
        g: usize,
    },
    /// A new orbit past the memory budget ([`MAX_ORBIT_BYTES`]): integrate it, keep nothing.
    Unkept,
}

/// Most bytes an assembly's orbits keep (keys and canonical matrices): about 21 k hex8i
/// orbits (a 16-voxel bowl has 45, a 32-voxel one 172). A large asymmetric object's cut
/// elements are mostly orbits of one, which would otherwise double the assembly's memory;
/// past the budget new orbits are integrated as before.
pub const MAX_ORBIT_BYTES: usize = 64 << 20;

/// The orbits of one assembly's cut elements and the matrices of their canonical fills.
#[derive(Debug)]
pub struct Orbits {
    symmetries: Arc<Symmetries>,
    /// The symmetries whose image starts with sub-cell `c`'s weight, per `c`.
    starting_at: Vec<Vec<usize>>,
    /// The orbits by canonical sub-cell weights ([`Orbits::find`]) and by canonical input
    /// ([`Orbits::find_input`]).
    index: HashMap<Box<[u64]>, usize, BuildHasherDefault<KeyHasher>>,
    by_input: HashMap<Box<[u8]>, usize, BuildHasherDefault<KeyHasher>>,
    /// Inputs as they were seen, with their orbit and symmetry.
    inputs: HashMap<Box<[u8]>, (usize, usize), BuildHasherDefault<KeyHasher>>,
    /// Per orbit: the canonical fill's matrices, once integrated.
    kept: Vec<Option<ElementBlocks>>,
    /// Bytes the orbits take, and the most they may.
    bytes: usize,
    budget: usize,
    key: Vec<u64>,
    /// The canonical input, and an image being compared with it.
    key_bytes: Vec<u8>,
    image: Vec<u8>,
}

impl Orbits {
    /// No orbits yet, for elements with `nodes_per_axis` nodes and `subcells_per_axis`
    /// sub-cells per axis.
    pub fn new(nodes_per_axis: usize, subcells_per_axis: usize) -> Self {
        let symmetries = Symmetries::shared(nodes_per_axis, subcells_per_axis);
        let mut starting_at = vec![Vec::new(); subcells_per_axis.pow(3)];
        for (g, op) in symmetries.ops.iter().enumerate() {
            starting_at[op.pull[0] as usize].push(g);
        }
        Orbits {
            symmetries,
            starting_at,
            index: HashMap::default(),
            by_input: HashMap::default(),
            inputs: HashMap::default(),
            kept: Vec::new(),
            bytes: 0,
            budget: MAX_ORBIT_BYTES,
            key: Vec::new(),
            key_bytes: Vec::new(),
            image: Vec::new(),
        }
    }

    /// [`Orbits::new`] keeping at most `bytes` of orbits (tests).
    pub fn with_budget(self, bytes: usize) -> Self {
        Orbits {
            budget: bytes,
            ..self
        }
    }

    /// The orbit of an element whose input is `input` (the sub-cell bytes of a hex27x2
    /// block's voxels and their ring): the smallest image among those its first moments
    /// orient ([`Symmetries::orienting`]), one for most elements, not among all 48: ordering
    /// 4096 bytes 48 ways would cost more than an integration.
    pub fn find_input(&mut self, input: &[u8]) -> Found {
        // An input seen before as it is (a plate's blocks, a tube's along its length): its
        // orbit without the search.
        if let Some(&(orbit, g)) = self.inputs.get(input) {
            return Found::Seen { orbit, g };
        }
        let found = self.find_input_image(input);
        if let Found::New { orbit, g } | Found::Seen { orbit, g } = found {
            if self.bytes + input.len() <= self.budget {
                self.bytes += input.len();
                self.inputs.insert(input.into(), (orbit, g));
            }
        }
        found
    }

    /// [`Orbits::find_input`] for an input not seen as it is.
    fn find_input_image(&mut self, input: &[u8]) -> Found {
        let mut best = usize::MAX;
        for g in self.symmetries.orienting(input) {
            self.symmetries.map_input(g, input, &mut self.image);
            if best == usize::MAX || self.image < self.key_bytes {
                best = g;
                std::mem::swap(&mut self.image, &mut self.key_bytes);
            }
        }
        if let Some(&orbit) = self.by_input.get(self.key_bytes.as_slice()) {
            return Found::Seen { orbit, g: best };
        }
        let Some(orbit) = self.new_orbit(self.key_bytes.len()) else {
            return Found::Unkept;
        };
        self.by_input
            .insert(self.key_bytes.as_slice().into(), orbit);
        Found::New { orbit, g: best }
    }

    /// The orbit of a cut element whose sub-cell weights (as the integration uses them,
    /// clamped) are `weights`.
    pub fn find(&mut self, weights: &[f64]) -> Found {
        // The canonical image starts with the smallest weight: only the symmetries that
        // bring a smallest sub-cell first are candidates (6 of the 48 where it is unique).
        let least = weights.iter().map(|w| w.to_bits()).min().unwrap_or(0);
        let candidates = weights
            .iter()
            .enumerate()
            .filter(|(_, w)| w.to_bits() == least)
            .flat_map(|(c, _)| self.starting_at[c].iter().copied());
        let g = self
            .symmetries
            .canonical(weights, candidates, &mut self.key);
        if let Some(&orbit) = self.index.get(self.key.as_slice()) {
            return Found::Seen { orbit, g };
        }
        let Some(orbit) = self.new_orbit(8 * self.key.len()) else {
            return Found::Unkept;
        };
        self.index.insert(self.key.as_slice().into(), orbit);
        Found::New { orbit, g }
    }

    /// A new orbit whose key takes `key_bytes`, or `None` past the budget.
    fn new_orbit(&mut self, key_bytes: usize) -> Option<usize> {
        // The key, the canonical matrices (a 3x3 block and a mass per node pair) and the
        // vectors' and map's own words.
        let pairs = self.symmetries.ops[0].pairs.len();
        let bytes = key_bytes + 80 * pairs + 96;
        if self.bytes + bytes > self.budget {
            return None;
        }
        self.bytes += bytes;
        self.kept.push(None);
        Some(self.kept.len() - 1)
    }

    /// Keeps the matrices of the orbit's first element (`g` maps its fill to the canonical
    /// one).
    pub fn keep(&mut self, orbit: usize, g: usize, blocks: &ElementBlocks) {
        let mut canonical = blocks.clone();
        self.symmetries.map_blocks(g, blocks, &mut canonical);
        self.kept[orbit] = Some(canonical);
    }

    /// The matrices of an element of `orbit` whose fill `g` maps to the canonical one, into
    /// `out`; `false` while the orbit's first element is not integrated yet.
    pub fn matrices(&self, orbit: usize, g: usize, out: &mut ElementBlocks) -> bool {
        let Some(canonical) = &self.kept[orbit] else {
            return false;
        };
        self.symmetries
            .map_blocks(self.symmetries.inverse(g), canonical, out);
        true
    }

    /// Orbits found so far.
    pub fn count(&self) -> usize {
        self.kept.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::cut::{CutElement, EMPTY_SUBCELL_FLOOR};
    use crate::fem::ElementKind;

    fn max_abs(v: impl Iterator<Item = f64>) -> f64 {
        v.fold(0.0f64, |m, x| m.max(x.abs()))
    }

    #[test]
    fn a_mapped_fill_integrates_to_the_mapped_matrices() {
        // The independent truth is the direct integration of every image of an asymmetric
        // fill: for all 48 symmetries, R K R^T (and M) on the mapped nodes equals it to
        // rounding, 1e-13 of the largest entry (the condensation's 9x9 solve and sums of a
        // few dozen terms).
        for kind in [ElementKind::Hex8Incompatible, ElementKind::Hex8] {
            let per_axis = 2;
            let cut = CutElement::new(kind, 0.27, per_axis);
            let symmetries = Symmetries::new(2, per_axis);
            assert_eq!(symmetries.count(), 48);
            let fill = [0.9, 0.05, 0.6, 0.0, 1.0, 0.3, 0.75, 0.2];
            let weights: Vec<f64> = fill
                .iter()
                .map(|f: &f64| f.max(EMPTY_SUBCELL_FLOOR))
                .collect();
            let mut scratch = cut.scratch();
            let integrate = |w: &[f64], scratch: &mut _| {
                let mut out = ElementBlocks::zeros(8);
                cut.matrices_batch(&[w], scratch, |_, b| out.clone_from(b));
                out
            };
            let original = integrate(&weights, &mut scratch);
            let scale = max_abs(original.k.iter().flatten().copied());
            let (mut mapped_fill, mut mapped) = (vec![0.0; 8], ElementBlocks::zeros(8));
            for g in 0..48 {
                symmetries.map_fill(g, &weights, &mut mapped_fill);
                let direct = integrate(&mapped_fill, &mut scratch);
                symmetries.map_blocks(g, &original, &mut mapped);
                let dk = max_abs(
                    direct
                        .k
                        .iter()
                        .flatten()
                        .zip(mapped.k.iter().flatten())
                        .map(|(a, b)| a - b),
                );
                let dm = max_abs(direct.m.iter().zip(&mapped.m).map(|(a, b)| a - b));
                assert!(dk < 1e-13 * scale, "{kind:?} symmetry {g}: {dk}");
                assert!(dm < 1e-15, "{kind:?} symmetry {g}: {dm}");
                // The inverse maps back.
                let mut back = ElementBlocks::zeros(8);
                symmetries.map_blocks(symmetries.inverse(g), &mapped, &mut back);
                assert_eq!(back, original, "{kind:?} symmetry {g}");
            }
        }
    }

    /// Orbits found from a block's input bytes (hex27x2): every image of an input, by all 48
    /// symmetries, is found in the input's orbit and reaches the same canonical input; so
    /// does an input symmetric under a mirror and a swap (its moments tie: several orienting
    /// symmetries, the smallest image among them); another input is another orbit, and an
    /// input seen again as it is comes back with its first finding.
    #[test]
    fn images_of_an_input_share_one_orbit() {
        let symmetries = Symmetries::new(3, 4);
        let asymmetric: Vec<u8> = (0..64u32).map(|i| (i * 37 % 11 * 23) as u8).collect();
        // Symmetric in x (mirror) and under the x-y swap.
        let symmetric: Vec<u8> = (0..64usize)
            .map(|i| {
                let [x, y, z] = lattice_coords(i, [4; 3]);
                let (a, b) = (x.min(3 - x), y.min(3 - y));
                (10 * (a + b) + 3 * z + a * b) as u8
            })
            .collect();
        let mut orbits = Orbits::new(3, 4);
        for input in [&asymmetric, &symmetric] {
            let Found::New { orbit, g } = orbits.find_input(input) else {
                panic!("the first input is new")
            };
            let mut canonical = Vec::new();
            symmetries.map_input(g, input, &mut canonical);
            let mut image = Vec::new();
            for h in 0..48 {
                symmetries.map_input(h, input, &mut image);
                let Found::Seen { orbit: o, g: gh } = orbits.find_input(&image) else {
                    panic!("image {h} is in the orbit")
                };
                assert_eq!(o, orbit, "image {h}");
                let mut again = Vec::new();
                symmetries.map_input(gh, &image, &mut again);
                assert_eq!(again, canonical, "image {h}");
            }
            assert_eq!(orbits.find_input(input), Found::Seen { orbit, g });
        }
        let mut other = asymmetric.clone();
        other[5] += 1;
        assert!(matches!(
            orbits.find_input(&other),
            Found::New { orbit: 2, .. }
        ));
    }

    #[test]
    fn images_share_one_orbit_and_others_do_not() {
        let mut orbits = Orbits::new(2, 2);
        let symmetries = Symmetries::new(2, 2);
        let fill = [0.9, 0.05, 0.6, 0.001, 1.0, 0.3, 0.75, 0.2];
        let Found::New { orbit, g } = orbits.find(&fill) else {
            panic!("the first fill is new")
        };
        let mut image = vec![0.0; 8];
        for h in 0..48 {
            symmetries.map_fill(h, &fill, &mut image);
            let Found::Seen { orbit: o, g: gh } = orbits.find(&image) else {
                panic!("image {h} is in the orbit")
            };
            assert_eq!(o, orbit);
            // Both reach the same canonical fill.
            let (mut a, mut b) = (vec![0.0; 8], vec![0.0; 8]);
            symmetries.map_fill(g, &fill, &mut a);
            symmetries.map_fill(gh, &image, &mut b);
            assert_eq!(a, b, "image {h}");
        }
        let other = [0.9, 0.05, 0.6, 0.001, 1.0, 0.3, 0.75, 0.21];
        assert!(matches!(orbits.find(&other), Found::New { orbit: 1, .. }));
        assert_eq!(orbits.count(), 2);

        // Past the budget a new orbit is not kept; the known ones still are found.
        let mut orbits = Orbits::new(2, 2).with_budget(4000);
        assert!(matches!(orbits.find(&fill), Found::New { orbit: 0, .. }));
        assert_eq!(orbits.find(&other), Found::Unkept);
        symmetries.map_fill(17, &fill, &mut image);
        assert!(matches!(orbits.find(&image), Found::Seen { orbit: 0, .. }));
        assert_eq!(orbits.count(), 1);
    }
}
