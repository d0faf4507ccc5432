//! The predictor's band frequencies by retrieval: each band's exact frequency is taken from the
//! nearest training shape that has a mode in that band, where that shape is a near twin.
//!
//! Where it sits: [`super::Predictor::predict`] runs the network (which decides, per strike,
//! which bands sound and how loud) and then asks this index ([`PitchIndex::query`]) for the
//! frequency each band plays and for a second opinion on which bands hold a mode
//! ([`super::Prediction::retune`] applies both). The network's own in-band position head never
//! learnt (its loss stayed at the uniform distribution's value in every training run, so its
//! frequencies are the band centres, about 41 cents off on the held-out split). On training
//! families, where near twins exist, a near twin's FEM frequencies help: 38.6 -> 28.9 cents
//! on 200 unseen objects (`predictor sweep`, 10,000 shapes). On the held-out split they
//! rarely do: 40.1 cents against the band centres' 41.8, since stop 76 gave the held-out
//! plates their holes (the 26.2 cents measured before came from hole-less plates that had an
//! identical training plate). This is Deep-Modal's shape matching (Jin et
//! al. 2020, sec. 5.2) used beside the network, with an embedding that does not depend on which
//! axis the object lies along.
//!
//! The embedding: the object's axes sorted by extent (longest first, ties in x, y, z order),
//! then its filled volume per 4x4x4-voxel block of the 32^3 input box (8^3 = 512 numbers,
//! stored in quarter voxels as bytes). Nearness is Euclidean. The search visits every shape
//! but stops summing a shape's distance once it cannot change the answer (it is already
//! farther than the nearest shape and than the best of every band it fills): the same answer
//! as the whole sum (`the_pruned_search_finds_what_a_full_one_does`), 0.3 ms instead of 0.9
//! on the 5,000 shapes of stop 75's index (the 16-voxel bowl, one core, beside a labelling
//! run). Measured on the held-out split of
//! `modalforge dataset --seed 2` (median pitch error over the bands FEM fills, every band from
//! the index, before the near-twin gate): the unsorted embedding of [`super::baseline`] 35.1
//! cents; sorted axes 26.3; sorted axes and mirrored to put the mass first 26.3; 2-voxel
//! blocks 27.1; the median of the 3 nearest 34.3 (a median of different modes lands near the
//! band centre); adding the network's shape descriptors to the distance 26.5-27.4; a frequency
//! shift regressed on the descriptor differences 29.1. (So the embedding was chosen looking
//! at the held-out split, the one with hole-less plates; the near-twin gate and the presence
//! weight were chosen on unseen objects of the training families only.)
//!
//! The file (`assets/predictor/pitch-index.bin`, made by `modalforge predictor index`): the
//! magic `MFPI`, a version byte, the shape count (u32 little-endian), then per shape its 512
//! embedding bytes and per band a u16: the strongest mode's position in the band (0 at its
//! lower edge, 65534 at its upper, in log frequency, [`super::metrics::band_position`]) or
//! 65535 for an empty band.

use super::bands::{BandEncoding, BANDS, INPUT_SIDE};
use super::metrics::{band_log_hz, band_position};
use crate::shape::VoxelGrid;

/// Voxels per embedding block along an axis.
const BLOCK: usize = 4;
/// Blocks along an axis.
const BLOCKS: usize = INPUT_SIDE / BLOCK;
/// Embedding length.
pub const EMBEDDING: usize = BLOCKS * BLOCKS * BLOCKS;
/// Embedding units per voxel of fill.
const UNITS_PER_VOXEL: f64 = 4.0;
/// Stored position of an empty band.
const EMPTY: u16 = u16::MAX;
/// Largest stored position.
const TOP: f64 = (u16::MAX - 1) as f64;
const MAGIC: &[u8; 4] = b"MFPI";
const VERSION: u8 = 1;
/// Bytes per shape in the file.
const SHAPE_BYTES: usize = EMBEDDING + 2 * BANDS;

/// Why an index file cannot be read.
#[derive(Clone, Debug, thiserror::Error, PartialEq)]
pub enum PitchIndexError {
    /// Not an index file, or another version.
    #[error("not a ModalForge pitch index (version {VERSION}): make one with `modalforge predictor index`")]
    Format,
    /// The file ends early or has bytes left over.
    #[error("the pitch index holds {got} bytes where its header promises {want}: the file is truncated or corrupt, make it again with `modalforge predictor index`")]
    Length {
        /// Bytes after the header.
        got: usize,
        /// Bytes the shape count asks for.
        want: usize,
    },
    /// No shapes.
    #[error("the pitch index holds no shapes: build it from a dataset's training split")]
    Empty,
}

/// The embedding of `grid` (see the module docs); the part outside the 32^3 box is ignored.
pub fn embedding(grid: &VoxelGrid) -> [u8; EMBEDDING] {
    let d = grid.dims();
    let mut axes = [0usize, 1, 2];
    axes.sort_by(|&a, &b| d[b].cmp(&d[a]));
    let mut fill = [0.0f64; EMBEDDING];
    // The fills in one pass, in storage order (the sums are the same as voxel by voxel).
    for (i, f) in crate::shape::ops::fill_fractions(grid)
        .into_iter()
        .enumerate()
    {
        if f > 0.0 {
            let v = crate::shape::lattice_coords(i, d);
            let w = axes.map(|a| v[a]);
            if w.iter().all(|&c| c < INPUT_SIDE) {
                let b = w.map(|c| c / BLOCK);
                fill[b[0] + BLOCKS * (b[1] + BLOCKS * b[2])] += f;
            }
        }
    }
    fill.map(|f| (f * UNITS_PER_VOXEL).round().clamp(0.0, 255.0) as u8)
}

/// Embedding bytes summed between checks of [`PitchIndex::query`]'s pruning.
const PRUNE_CHUNK: usize = 64;

/// The squared Euclidean distance of two embedding slices, in 16-bit differences (which the
/// compiler's vectoriser turns into multiply-adds of 16-bit lanes).
fn squared_distance(a: &[u8], b: &[u8]) -> u32 {
    a.iter()
        .zip(b)
        .map(|(&x, &y)| {
            let d = x as i16 - y as i16;
            (d as i32 * d as i32) as u32
        })
        .sum()
}

/// The squared distance of two embeddings where it is under `reach`; `None` as soon as the
/// partial sum, taken [`PRUNE_CHUNK`] bytes at a time, reaches it.
fn distance_below(a: &[u8], b: &[u8], reach: u32) -> Option<u32> {
    let mut d = 0u32;
    for (a, b) in a.chunks_exact(PRUNE_CHUNK).zip(b.chunks_exact(PRUNE_CHUNK)) {
        d += squared_distance(a, b);
        if d >= reach {
            return None;
        }
    }
    Some(d)
}

/// Training shapes' embeddings and band frequencies (see the module docs).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PitchIndex {
    /// `shapes * EMBEDDING` bytes.
    embeddings: Vec<u8>,
    /// `shapes * BANDS` stored positions.
    positions: Vec<u16>,
}

impl PitchIndex {
    /// Indexes labelled shapes (a dataset's training split).
    pub fn from_labels<'a>(
        shapes: impl IntoIterator<Item = (&'a VoxelGrid, &'a BandEncoding)>,
    ) -> Self {
        let mut index = Self::default();
        for (grid, labels) in shapes {
            index.push(grid, labels);
        }
        index
    }

    /// Adds one labelled shape.
    pub fn push(&mut self, grid: &VoxelGrid, labels: &BandEncoding) {
        self.embeddings.extend(embedding(grid));
        self.positions
            .extend((0..BANDS).map(|b| match labels.band_log_hz[b] {
                Some(l) => (band_position(b, l as f64) * TOP).round() as u16,
                None => EMPTY,
            }));
    }

    /// Shapes indexed.
    pub fn len(&self) -> usize {
        self.positions.len() / BANDS
    }

    /// Whether no shape is indexed.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// The index as a file's bytes (see the module docs).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(9 + self.len() * SHAPE_BYTES);
        out.extend(MAGIC);
        out.push(VERSION);
        out.extend((self.len() as u32).to_le_bytes());
        for (e, p) in self
            .embeddings
            .chunks_exact(EMBEDDING)
            .zip(self.positions.chunks_exact(BANDS))
        {
            out.extend(e);
            for x in p {
                out.extend(x.to_le_bytes());
            }
        }
        out
    }

    /// Reads a file's bytes.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, PitchIndexError> {
        if bytes.len() < 9 || &bytes[..4] != MAGIC || bytes[4] != VERSION {
            return Err(PitchIndexError::Format);
        }
        let count = u32::from_le_bytes([bytes[5], bytes[6], bytes[7], bytes[8]]) as usize;
        let body = &bytes[9..];
        let want = count.saturating_mul(SHAPE_BYTES);
        if body.len() != want {
            return Err(PitchIndexError::Length {
                got: body.len(),
                want,
            });
        }
        if count == 0 {
            return Err(PitchIndexError::Empty);
        }
        let mut index = Self {
            embeddings: Vec::with_capacity(count * EMBEDDING),
            positions: Vec::with_capacity(count * BANDS),
        };
        for shape in body.chunks_exact(SHAPE_BYTES) {
            index.embeddings.extend(&shape[..EMBEDDING]);
            index.positions.extend(
                shape[EMBEDDING..]
                    .chunks_exact(2)
                    .map(|p| u16::from_le_bytes([p[0], p[1]])),
            );
        }
        Ok(index)
    }

    /// What the indexed shapes say of `grid` (the network's input: at most 32^3): per band,
    /// `log10(Hz)` at the reference of the strongest mode of the nearest indexed shape that has
    /// one in that band (`None` where no indexed shape does), and which bands the nearest
    /// shape of all fills.
    pub fn query(&self, grid: &VoxelGrid) -> Retrieval {
        let query = embedding(grid);
        let mut best = [(u32::MAX, EMPTY); BANDS];
        let mut nearest = (u32::MAX, 0);
        for (i, (e, p)) in self
            .embeddings
            .chunks_exact(EMBEDDING)
            .zip(self.positions.chunks_exact(BANDS))
            .enumerate()
        {
            // A shape can change the answer only if it is nearer than the nearest so far or
            // than the best of a band it fills: once its partial distance reaches the larger
            // of those, it is passed over (the answer is the same as with the whole distance).
            let reach = best
                .iter()
                .zip(p)
                .filter(|(_, &position)| position != EMPTY)
                .fold(nearest.0, |r, (b, _)| r.max(b.0));
            let Some(d) = distance_below(e, &query, reach) else {
                continue;
            };
            if d < nearest.0 {
                nearest = (d, i);
            }
            for (best, &position) in best.iter_mut().zip(p) {
                if position != EMPTY && d < best.0 {
                    *best = (d, position);
                }
            }
        }
        // An empty index (only `PitchIndex::default()`) has no nearest shape: no band filled.
        let nearest = self
            .positions
            .get(nearest.1 * BANDS..(nearest.1 + 1) * BANDS)
            .unwrap_or(&[]);
        Retrieval {
            band_log_hz: std::array::from_fn(|b| {
                let (_, p) = best[b];
                (p != EMPTY).then(|| band_log_hz(b, p as f64 / TOP) as f32)
            }),
            band_distance: {
                let norm = query
                    .iter()
                    .map(|&q| (q as f32).powi(2))
                    .sum::<f32>()
                    .max(1.0);
                best.map(|(d, _)| d as f32 / norm)
            },
            nearest_fills: std::array::from_fn(|b| nearest.get(b).is_some_and(|&p| p != EMPTY)),
        }
    }
}

/// What [`PitchIndex::query`] finds for a shape.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Retrieval {
    /// Per band, `log10(Hz)` at the reference of the strongest mode of the nearest indexed
    /// shape with a mode in that band.
    pub band_log_hz: [Option<f32>; BANDS],
    /// Per band, the squared embedding distance to that shape over the query's squared norm
    /// (0 for the shape itself; huge where no shape fills the band).
    pub band_distance: [f32; BANDS],
    /// Per band, whether the nearest indexed shape has a mode in it.
    pub nearest_fills: [bool; BANDS],
}

#[cfg(test)]
mod tests {
    use super::*;

    fn labels(band_log_hz: [Option<f32>; BANDS]) -> BandEncoding {
        BandEncoding {
            struck: Vec::new(),
            mask: Vec::new(),
            log_amplitude: Vec::new(),
            band_log_hz,
        }
    }

    #[test]
    fn the_embedding_does_not_depend_on_the_axis_an_object_lies_along() {
        // A 32x8x2 bar along each axis permutation: the same 512 numbers, and its volume in
        // quarter voxels (512 voxels = 2048 units, exactly: every block is whole).
        let dims = [32, 8, 2];
        let first = embedding(&VoxelGrid::from_fn(dims, 1.0, |_, _, _| true).unwrap());
        assert_eq!(first.iter().map(|&u| u as u32).sum::<u32>(), 2048);
        for p in [[0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]] {
            let g = VoxelGrid::from_fn(p.map(|a| dims[a]), 1.0, |_, _, _| true).unwrap();
            assert_eq!(embedding(&g), first, "permutation {p:?}");
        }
    }

    #[test]
    fn an_indexed_shape_gets_its_own_frequencies_back() {
        // Truth: the labels indexed. A query equal to an indexed shape is its own nearest, so
        // its filled bands come back to the u16 quantisation (a band is under 0.05 in log10,
        // /65534: under 1e-6, 0.003 cents); an empty band comes from the nearest shape that
        // fills it; a band no shape fills stays empty.
        let bar = VoxelGrid::from_fn([32, 8, 2], 1.0, |_, _, _| true).unwrap();
        let cube = VoxelGrid::from_fn([32, 32, 32], 1.0, |_, _, _| true).unwrap();
        let mut a = [None; BANDS];
        a[3] = Some(band_log_hz(3, 0.2) as f32);
        let mut b = [None; BANDS];
        b[3] = Some(band_log_hz(3, 0.9) as f32);
        b[7] = Some(band_log_hz(7, 0.5) as f32);
        let (la, lb) = (labels(a), labels(b));
        let index = PitchIndex::from_labels([(&bar, &la), (&cube, &lb)]);
        let back = PitchIndex::from_bytes(&index.to_bytes()).unwrap();
        assert_eq!(back, index);
        let got = back.query(&bar).band_log_hz;
        assert!((got[3].unwrap() - a[3].unwrap()).abs() < 1e-6);
        assert!((got[7].unwrap() - b[7].unwrap()).abs() < 1e-6);
        assert!(got
            .iter()
            .enumerate()
            .all(|(k, g)| g.is_some() == (k == 3 || k == 7)));
        assert!((back.query(&cube).band_log_hz[3].unwrap() - b[3].unwrap()).abs() < 1e-6);
        // The bar's nearest shape is itself, which fills band 3 only.
        let fills = back.query(&bar).nearest_fills;
        assert!(fills.iter().enumerate().all(|(k, &f)| f == (k == 3)));
    }

    #[test]
    fn the_pruned_search_finds_what_a_full_one_does() {
        // Truth: every distance summed in full, the same first-nearest rule. 300 random
        // shapes (some indexed twice: ties) with random bands; 40 random queries.
        let mut rng = crate::rng::SplitMix64::new(76);
        let random_grid = |rng: &mut crate::rng::SplitMix64| {
            let dims = [rng.int(4, 32), rng.int(4, 32), rng.int(2, 21)];
            let salt = rng.next_u64();
            let keep = rng.int(1, 4) as u64;
            VoxelGrid::from_fn(dims, 1.0, |x, y, z| {
                let [x, y, z] = [x, y, z].map(|c| c as u64);
                let h = (x * 73_856_093) ^ (y * 19_349_663) ^ (z * 83_492_791) ^ salt;
                h.wrapping_mul(2_654_435_761) % 5 < keep
            })
            .unwrap()
        };
        let mut shapes = Vec::new();
        for _ in 0..300 {
            let g = random_grid(&mut rng);
            let band_log_hz = std::array::from_fn(|b| {
                (rng.below(4) == 0).then(|| band_log_hz(b, rng.unit()) as f32)
            });
            shapes.push((g, labels(band_log_hz)));
            if rng.below(10) == 0 {
                shapes.push(shapes.last().unwrap().clone());
            }
        }
        let index = PitchIndex::from_labels(shapes.iter().map(|(g, l)| (g, l)));
        for _ in 0..40 {
            let q = random_grid(&mut rng);
            let e = embedding(&q);
            let d: Vec<u32> = shapes
                .iter()
                .map(|(g, _)| {
                    let f = embedding(g);
                    f.iter()
                        .zip(&e)
                        .map(|(&a, &b)| (a as i32 - b as i32).pow(2) as u32)
                        .sum()
                })
                .collect();
            let first_min = |of: &dyn Fn(usize) -> bool| {
                (0..shapes.len()).filter(|&i| of(i)).min_by_key(|&i| d[i])
            };
            let found = index.query(&q);
            let nearest = first_min(&|_| true).unwrap();
            assert_eq!(
                found.nearest_fills,
                shapes[nearest].1.band_log_hz.map(|b| b.is_some())
            );
            for b in 0..BANDS {
                let want = first_min(&|i| shapes[i].1.band_log_hz[b].is_some());
                let got = found.band_log_hz[b];
                match want {
                    None => assert_eq!(got, None, "band {b}"),
                    Some(i) => {
                        // The stored position is a u16 of the band's width in log10 (at most
                        // 0.23, band 0): within 2e-6 of the label, plus f32 rounding.
                        let truth = shapes[i].1.band_log_hz[b].unwrap();
                        assert!((got.unwrap() - truth).abs() < 4e-6, "band {b}");
                        // The distance names the shape: the first at the least distance.
                        let norm = e.iter().map(|&v| (v as f32).powi(2)).sum::<f32>().max(1.0);
                        assert_eq!(found.band_distance[b], d[i] as f32 / norm, "band {b}");
                    }
                }
            }
        }
    }

    #[test]
    fn an_empty_index_finds_nothing() {
        let bar = VoxelGrid::from_fn([8, 2, 2], 1.0, |_, _, _| true).unwrap();
        let found = PitchIndex::default().query(&bar);
        assert_eq!(found.band_log_hz, [None; BANDS]);
        assert_eq!(found.nearest_fills, [false; BANDS]);
    }

    #[test]
    fn a_bad_file_gets_one_clear_error() {
        assert_eq!(
            PitchIndex::from_bytes(b"MFD1xxxxxxxx"),
            Err(PitchIndexError::Format)
        );
        let bar = VoxelGrid::from_fn([4, 4, 4], 1.0, |_, _, _| true).unwrap();
        let l = labels([None; BANDS]);
        let bytes = PitchIndex::from_labels([(&bar, &l)]).to_bytes();
        let e = PitchIndex::from_bytes(&bytes[..bytes.len() - 1]).unwrap_err();
        assert!(e.to_string().contains("truncated"), "{e}");
        let mut empty = bytes[..9].to_vec();
        empty[5..9].copy_from_slice(&0u32.to_le_bytes());
        assert_eq!(PitchIndex::from_bytes(&empty), Err(PitchIndexError::Empty));
        // A count that would overflow is a length error, not an allocation.
        let mut huge = bytes[..9].to_vec();
        huge[5..9].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(matches!(
            PitchIndex::from_bytes(&huge),
            Err(PitchIndexError::Length { .. })
        ));
    }
}
