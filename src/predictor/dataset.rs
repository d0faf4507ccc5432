//! The predictor's training data: varied objects in the 32^3 input box, labelled by FEM.
//!
//! Where it sits: `modalforge dataset` calls [`generate`]; training (not built yet) reads the
//! records back with [`Record::decode`]. Every object comes from its own random stream, seeded
//! by `(seed, split, index)` ([`object`]), so a dataset is reproducible from its seed, objects
//! can be made in any order on any number of threads, and a run that stops resumes where it
//! was (finished records are kept). Labels come from the product's own FEM path (partial
//! voxels, the chosen element, every mode up to the top band at the reference), encoded as
//! [`BandEncoding`]; the element is named in the directory's [`MANIFEST`].
//!
//! The held-out split holds whole shape families training never sees ([`Family::held_out`]):
//! plates with holes and objects with handles.

use super::bands::{self, BandEncoding, BANDS, CELLS_PER_AXIS, DIRECTIONS, INPUT_SIDE};
use crate::basis::ModeBasis;
use crate::eigen::{EigenOptions, ModeCount, SolverKind};
use crate::fem::ElementKind;
use crate::rng::SplitMix64;
use crate::shape::primitives::Primitive;
use crate::shape::{ops, VoxelGrid, PARTIAL_RECORD_BYTES};
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

/// Poisson's ratio the labels are solved with (steel, the reference material).
pub const REFERENCE_POISSON: f64 = 0.29;

/// A family of generated shapes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Family {
    /// A solid primitive with random proportions.
    Solid,
    /// A thin-walled primitive: bowl, cup, tube, bell, or a hollowed box or sphere.
    Shell,
    /// Two to four solid primitives joined.
    Union,
    /// A solid primitive with one to three others cut out of it.
    Difference,
    /// Thresholded smooth noise.
    Blob,
    /// A plate with round holes (held out).
    PlateWithHoles,
    /// A cup or tube with a bar handle (held out).
    Handle,
}

impl Family {
    /// The training families.
    pub const TRAIN: [Family; 5] = [
        Family::Solid,
        Family::Shell,
        Family::Union,
        Family::Difference,
        Family::Blob,
    ];
    /// The held-out families.
    pub const HELD_OUT: [Family; 2] = [Family::PlateWithHoles, Family::Handle];

    /// Whether training never sees this family.
    pub fn held_out(self) -> bool {
        Self::HELD_OUT.contains(&self)
    }

    fn id(self) -> u8 {
        self as u8
    }

    fn from_id(id: u8) -> Option<Self> {
        Self::TRAIN
            .into_iter()
            .chain(Self::HELD_OUT)
            .find(|f| f.id() == id)
    }
}

/// The random stream of object `index` of a split: the dataset's seed, the split and the
/// index mixed into one SplitMix64 state, so objects are independent of the order (and the
/// threads) that make them.
fn stream(seed: u64, split: u64, index: u64) -> SplitMix64 {
    let state = seed
        ^ split.wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ index.wrapping_mul(0xD1B5_4A32_D192_ED03);
    let mut s = SplitMix64::new(state);
    s.next_u64();
    s
}

fn empty_box() -> VoxelGrid {
    VoxelGrid::new([INPUT_SIDE; 3], 1.0).expect("the input box is a valid grid")
}

/// `shape` rasterised to fit `max_side` voxels, placed at a random position in `into`.
fn place(into: &VoxelGrid, shape: &VoxelGrid, rng: &mut SplitMix64, join: bool) -> VoxelGrid {
    let d = shape.dims();
    let offset = [0, 1, 2].map(|a| rng.int(0, INPUT_SIDE.saturating_sub(d[a])));
    let op = if join { ops::union } else { ops::difference };
    op(into, shape, offset).unwrap_or_else(|_| into.clone())
}

/// A random solid primitive no longer than `max_side` voxels, its longest side at least 0.6 of
/// that. The product scales an object to fill the box before it predicts (the size scaling law
/// of Deep-Modal eq. 11 then maps it back), and a small solid rings above the top band at the
/// reference: labels of small solids would be empty.
fn solid_primitive(rng: &mut SplitMix64, max_side: f64) -> VoxelGrid {
    let s = |rng: &mut SplitMix64| rng.range(3.0, max_side);
    let big = rng.range(0.6 * max_side, max_side);
    let shape = match rng.int(0, 4) {
        0 => Primitive::Box {
            x: big,
            y: s(rng),
            z: s(rng),
        },
        1 => Primitive::Sphere { diameter: big },
        2 => {
            let other = s(rng);
            let (diameter, height) = if rng.int(0, 1) == 0 {
                (big, other)
            } else {
                (other, big)
            };
            Primitive::Cylinder { diameter, height }
        }
        3 => Primitive::Bar {
            length: big,
            width: rng.range(2.0, 8.0),
            height: rng.range(2.0, 8.0),
        },
        // A thin plate: the held-out plates with holes are these with holes cut.
        _ => Primitive::Plate {
            length: big,
            width: rng.range(0.4 * max_side, max_side),
            thickness: rng.range(1.0, 3.0),
        },
    };
    shape.rasterize(1.0, 1.0).expect("fits the box")
}

/// A random thin-walled primitive.
fn shell_primitive(rng: &mut SplitMix64) -> VoxelGrid {
    let wall = rng.range(1.0, 3.0);
    let d = rng.range(12.0, 32.0);
    let h = rng.range(8.0, 32.0);
    let shape = match rng.int(0, 5) {
        0 => Primitive::Bowl { diameter: d, wall },
        1 => Primitive::Cup {
            diameter: d,
            height: h,
            wall,
        },
        2 => Primitive::Tube {
            diameter: d,
            height: h,
            wall,
        },
        3 => Primitive::Bell {
            diameter: d,
            height: h.max(10.0),
            wall,
        },
        4 => {
            let grid = Primitive::Box {
                x: d,
                y: rng.range(8.0, 32.0),
                z: h,
            }
            .rasterize(1.0, 1.0)
            .expect("fits");
            return ops::hollow(&grid, wall.round() as usize);
        }
        _ => {
            let grid = Primitive::Sphere { diameter: d }
                .rasterize(1.0, 1.0)
                .expect("fits");
            return ops::hollow(&grid, wall.round() as usize);
        }
    };
    shape.rasterize(1.0, 1.0).expect("fits the box")
}

/// Thresholded trilinear value noise on a 5^3 lattice plus a random share of a central lump
/// (`1 - (r / r0)^2`): a smooth random blob, from a porous sponge (no lump) to a knobbly
/// stone (a strong one).
fn blob(rng: &mut SplitMix64) -> VoxelGrid {
    const N: usize = 5;
    let values: Vec<f64> = (0..N * N * N).map(|_| rng.range(-1.0, 1.0)).collect();
    let threshold = rng.range(-0.1, 0.3);
    let lump = rng.range(0.0, 1.5);
    let lump_radius = rng.range(10.0, 18.0);
    let scale = (N - 1) as f64 / INPUT_SIDE as f64;
    let centre = INPUT_SIDE as f64 / 2.0;
    let noise = move |x: f64, y: f64, z: f64| {
        let p = [x * scale, y * scale, z * scale];
        let i = p.map(|v| (v.floor() as usize).min(N - 2));
        let t = [0, 1, 2].map(|a| p[a] - i[a] as f64);
        let mut v = 0.0;
        for c in 0..8 {
            let o = [c & 1, (c >> 1) & 1, c >> 2];
            let w: f64 = (0..3)
                .map(|a| if o[a] == 1 { t[a] } else { 1.0 - t[a] })
                .product();
            v += w * values[(i[0] + o[0]) + N * ((i[1] + o[1]) + N * (i[2] + o[2]))];
        }
        let r2 = (x - centre).powi(2) + (y - centre).powi(2) + (z - centre).powi(2);
        v + lump * (1.0 - r2 / (lump_radius * lump_radius))
    };
    VoxelGrid::from_fn([INPUT_SIDE; 3], 1.0, |x, y, z| noise(x, y, z) > threshold).expect("the box")
}

/// A plate with round holes.
fn plate_with_holes(rng: &mut SplitMix64) -> VoxelGrid {
    let (l, w, t) = (
        rng.range(16.0, 32.0),
        rng.range(12.0, 32.0),
        rng.range(1.0, 3.0),
    );
    let mut grid = Primitive::Plate {
        length: l,
        width: w,
        thickness: t,
    }
    .rasterize(1.0, 1.0)
    .expect("fits");
    for _ in 0..rng.int(1, 4) {
        let hole = Primitive::Cylinder {
            diameter: rng.range(2.0, 8.0),
            height: t.round().max(1.0),
        }
        .rasterize(1.0, 1.0)
        .expect("fits");
        grid = place(&grid, &hole, rng, false);
    }
    grid
}

/// A cup or tube with a bar handle on its side.
fn handle(rng: &mut SplitMix64) -> VoxelGrid {
    let d = rng.range(12.0, 22.0);
    let h = rng.range(12.0, 30.0);
    let wall = rng.range(1.5, 3.0);
    let body = if rng.int(0, 1) == 0 {
        Primitive::Cup {
            diameter: d,
            height: h,
            wall,
        }
    } else {
        Primitive::Tube {
            diameter: d,
            height: h,
            wall,
        }
    }
    .rasterize(1.0, 1.0)
    .expect("fits");
    let mut grid = empty_box();
    grid = ops::union(&grid, &body, [0, 0, 0]).unwrap_or(grid);
    // A C-shaped handle of three bars on the +x side.
    let bd = body.dims();
    let reach = (INPUT_SIDE - bd[0]).min(rng.int(3, 8)).max(2);
    let (z0, z1) = (bd[2] / 4, (3 * bd[2] / 4).max(bd[2] / 4 + 3));
    let y = bd[1] / 2 - 1;
    let x0 = bd[0] - 1;
    let top = z1.min(INPUT_SIDE - 2);
    grid = add_bar(grid, [reach + 1, 2, 2], [x0, y, z0]);
    grid = add_bar(grid, [reach + 1, 2, 2], [x0, y, top]);
    add_bar(
        grid,
        [2, 2, top - z0 + 2],
        [(x0 + reach).min(INPUT_SIDE - 2), y, z0],
    )
}

/// `grid` with a solid bar of `dims` at `at` (unchanged where it would not fit).
fn add_bar(grid: VoxelGrid, dims: [usize; 3], at: [usize; 3]) -> VoxelGrid {
    let bar = VoxelGrid::from_fn(dims, 1.0, |_, _, _| true).expect("a bar");
    ops::union(&grid, &bar, at).unwrap_or(grid)
}

/// Object `index` of `split` (0 = training, 1 = held out) of the dataset with `seed`: its
/// family and its grid (at most 32^3, one face-connected piece, cropped).
pub fn object(seed: u64, held_out: bool, index: usize) -> (Family, VoxelGrid) {
    let families: &[Family] = if held_out {
        &Family::HELD_OUT
    } else {
        &Family::TRAIN
    };
    let family = families[index % families.len()];
    for attempt in 0..64u64 {
        let mut rng = stream(seed, held_out as u64, (index as u64) << 8 | attempt);
        let grid = match family {
            Family::Solid => solid_primitive(&mut rng, 32.0),
            Family::Shell => shell_primitive(&mut rng),
            Family::Union => {
                let mut g = empty_box();
                for _ in 0..rng.int(2, 4) {
                    let p = solid_primitive(&mut rng, 20.0);
                    g = place(&g, &p, &mut rng, true);
                }
                g
            }
            Family::Difference => {
                let mut g = ops::union(&empty_box(), &solid_primitive(&mut rng, 32.0), [0; 3])
                    .unwrap_or_else(|_| empty_box());
                for _ in 0..rng.int(1, 3) {
                    let p = solid_primitive(&mut rng, 16.0);
                    g = place(&g, &p, &mut rng, false);
                }
                g
            }
            Family::Blob => blob(&mut rng),
            Family::PlateWithHoles => plate_with_holes(&mut rng),
            Family::Handle => handle(&mut rng),
        };
        let grid = grid.cropped();
        // One piece of at least 27 voxels (a free-free FEM object, not dust).
        if grid.count() >= 27 && ops::components(&grid).1 == 1 {
            return (family, grid);
        }
    }
    // Every family makes a valid object long before 64 attempts; a cube keeps the index.
    let cube = VoxelGrid::from_fn([8; 3], 1.0, |_, _, _| true).expect("cube");
    (family, cube)
}

/// One labelled object.
#[derive(Clone, Debug, PartialEq)]
pub struct Record {
    /// Its family.
    pub family: Family,
    /// The object (voxel edge 1), at most 32^3, partial voxels kept: the network's input.
    pub grid: VoxelGrid,
    /// The FEM labels.
    pub labels: BandEncoding,
}

/// Why an object could not be labelled.
#[derive(Debug, thiserror::Error)]
pub enum LabelError {
    /// The FEM solve failed.
    #[error(transparent)]
    Modal(#[from] crate::basis::BasisError),
    /// The modes could not be encoded.
    #[error(transparent)]
    Encode(#[from] bands::EncodeError),
}

/// Why a record could not be read.
#[derive(Debug, thiserror::Error)]
#[error("not a dataset record ({0}): regenerate it with `modalforge dataset`")]
pub struct RecordError(&'static str);

const MAGIC: &[u8; 4] = b"MFD1";

fn push_bits(out: &mut Vec<u8>, bits: &[bool]) {
    for chunk in bits.chunks(8) {
        out.push(
            chunk
                .iter()
                .enumerate()
                .fold(0u8, |b, (i, &v)| b | (v as u8) << i),
        );
    }
}

fn read_bits(bytes: &[u8], n: usize) -> Vec<bool> {
    (0..n).map(|i| bytes[i / 8] >> (i % 8) & 1 == 1).collect()
}

impl Record {
    /// Labels an object by FEM (the product's path: partial voxels, `element`, every mode up
    /// to the top band at the reference).
    pub fn label(
        family: Family,
        grid: VoxelGrid,
        element: ElementKind,
    ) -> Result<Self, LabelError> {
        let options = EigenOptions {
            count: ModeCount::Below(bands::reference_eigenvalue(bands::HIGH_HZ)),
            ..EigenOptions::default()
        };
        let basis = ModeBasis::solve(
            &grid,
            element,
            REFERENCE_POISSON,
            SolverKind::Auto,
            &options,
        )?;
        let labels = BandEncoding::encode(&basis, &grid)?;
        Ok(Self {
            family,
            grid,
            labels,
        })
    }

    /// The compact binary form: occupancy and masks as bits, partial fills and masked
    /// log-amplitudes as bytes (1/255), band frequencies as f32: 50-200 kB.
    pub fn encode(&self) -> Vec<u8> {
        let mut out = MAGIC.to_vec();
        out.push(self.family.id());
        out.extend(self.grid.dims().map(|d| d as u8));
        push_bits(&mut out, self.grid.occupancy());
        let partial = self.grid.partial_records();
        out.extend(((partial.len() / PARTIAL_RECORD_BYTES) as u32).to_le_bytes());
        out.extend(partial);
        push_bits(&mut out, &self.labels.struck);
        push_bits(&mut out, &self.labels.mask);
        for (m, a) in self.labels.mask.iter().zip(&self.labels.log_amplitude) {
            if *m {
                out.push((a.clamp(0.0, 1.0) * 255.0).round() as u8);
            }
        }
        for f in self.labels.band_log_hz {
            out.extend(f.unwrap_or(f32::NAN).to_le_bytes());
        }
        out
    }

    /// Reads [`Record::encode`]'s form back (log-amplitudes to 1/255).
    pub fn decode(bytes: &[u8]) -> Result<Self, RecordError> {
        let mut at = 0usize;
        let mut take = |n: usize| -> Result<&[u8], RecordError> {
            let s = bytes.get(at..at + n).ok_or(RecordError("truncated"))?;
            at += n;
            Ok(s)
        };
        if take(4)? != MAGIC {
            return Err(RecordError("bad magic"));
        }
        let family = Family::from_id(take(1)?[0]).ok_or(RecordError("unknown family"))?;
        let d = take(3)?;
        let dims = [d[0] as usize, d[1] as usize, d[2] as usize];
        if dims.iter().any(|&d| d == 0 || d > INPUT_SIDE) {
            return Err(RecordError("bad dimensions"));
        }
        let n = dims.iter().product::<usize>();
        let occupancy = read_bits(take(n.div_ceil(8))?, n);
        let mut grid =
            VoxelGrid::from_occupancy(dims, 1.0, occupancy).map_err(|_| RecordError("grid"))?;
        let partial = u32::from_le_bytes(take(4)?.try_into().expect("4")) as usize;
        if partial > n {
            return Err(RecordError("more partial voxels than voxels"));
        }
        grid.set_partial_records(take(partial * PARTIAL_RECORD_BYTES)?)
            .map_err(|_| RecordError("partial voxel outside the object"))?;
        let cells = CELLS_PER_AXIS.pow(3);
        let struck = read_bits(take(cells.div_ceil(8))?, cells);
        let entries = cells * DIRECTIONS * BANDS;
        let mask = read_bits(take(entries.div_ceil(8))?, entries);
        let mut log_amplitude = vec![0.0f32; entries];
        for (m, a) in mask.iter().zip(log_amplitude.iter_mut()) {
            if *m {
                *a = take(1)?[0] as f32 / 255.0;
            }
        }
        let mut band_log_hz = [None; BANDS];
        for f in band_log_hz.iter_mut() {
            let v = f32::from_le_bytes(take(4)?.try_into().expect("4"));
            *f = v.is_finite().then_some(v);
        }
        Ok(Self {
            family,
            grid,
            labels: BandEncoding {
                struck,
                mask,
                log_amplitude,
                band_log_hz,
            },
        })
    }
}

/// What [`generate`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Summary {
    /// Records written by this run.
    pub written: usize,
    /// Records already there (a resumed run).
    pub kept: usize,
    /// Objects whose FEM failed (reported, skipped).
    pub failed: usize,
}

/// The file in a dataset's directory that names the element its labels were solved with
/// (one line, `element = "hex27x2"`). A directory without one holds hex8i labels (datasets
/// made before the element was a choice).
pub const MANIFEST: &str = "labels.toml";

/// The element a dataset's labels were solved with: its [`MANIFEST`], or hex8i where there is
/// none. An unreadable or unknown manifest is an error naming the file.
pub fn labelled_element(dir: &Path) -> std::io::Result<ElementKind> {
    use clap::ValueEnum;
    let path = dir.join(MANIFEST);
    let text = match std::fs::read_to_string(&path) {
        Ok(text) => text,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Ok(ElementKind::Hex8Incompatible)
        }
        Err(e) => return Err(e),
    };
    let bad = || {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!(
                "{}: expected one line `element = \"NAME\"` (hex8, hex8i, hex27 or hex27x2)",
                path.display()
            ),
        )
    };
    let table: toml::Table = text.parse().map_err(|_| bad())?;
    let name = table
        .get("element")
        .and_then(|v| v.as_str())
        .ok_or_else(bad)?;
    ElementKind::from_str(name, false).map_err(|_| bad())
}

/// The record file of object `index`.
pub fn record_path(out: &Path, held_out: bool, index: usize) -> std::path::PathBuf {
    let split = if held_out { "heldout" } else { "train" };
    out.join(split).join(format!("{index:06}.mfd"))
}

/// Makes `count` training objects and `held_out` held-out ones under `out` (`train/`,
/// `heldout/`), labelling them with `element` on `threads` threads; records already present
/// are kept, so a stopped run resumes. A directory whose labels were solved with another
/// element ([`labelled_element`]) is refused rather than mixed. Prints progress and an ETA to
/// stderr.
pub fn generate(
    out: &Path,
    count: usize,
    held_out: usize,
    seed: u64,
    threads: usize,
    element: ElementKind,
) -> std::io::Result<Summary> {
    let has_records = ["train", "heldout"]
        .iter()
        .any(|split| std::fs::read_dir(out.join(split)).is_ok_and(|mut d| d.next().is_some()));
    if has_records || out.join(MANIFEST).exists() {
        let found = labelled_element(out)?;
        if found != element {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                format!(
                    "{} holds labels solved with {found}, not {element}: choose another \
                     directory or --element {found}",
                    out.display()
                ),
            ));
        }
    }
    std::fs::create_dir_all(out.join("train"))?;
    std::fs::create_dir_all(out.join("heldout"))?;
    std::fs::write(out.join(MANIFEST), format!("element = \"{element}\"\n"))?;
    let jobs: Vec<(bool, usize)> = (0..count)
        .map(|i| (false, i))
        .chain((0..held_out).map(|i| (true, i)))
        .collect();
    let next = AtomicUsize::new(0);
    let (written, kept, failed) = (
        AtomicUsize::new(0),
        AtomicUsize::new(0),
        AtomicUsize::new(0),
    );
    let start = Instant::now();
    let error: std::sync::Mutex<Option<std::io::Error>> = std::sync::Mutex::new(None);
    std::thread::scope(|s| {
        for _ in 0..threads.max(1) {
            s.spawn(|| loop {
                let j = next.fetch_add(1, Ordering::Relaxed);
                let Some(&(held, index)) = jobs.get(j) else {
                    break;
                };
                let path = record_path(out, held, index);
                if path.exists() {
                    kept.fetch_add(1, Ordering::Relaxed);
                    continue;
                }
                let (family, grid) = object(seed, held, index);
                match Record::label(family, grid, element) {
                    Ok(record) => {
                        // Written under a temporary name, then renamed: a killed run never
                        // leaves a half record that a resumed run would keep.
                        let tmp = path.with_extension("tmp");
                        let result = std::fs::write(&tmp, record.encode())
                            .and_then(|_| std::fs::rename(&tmp, &path));
                        if let Err(e) = result {
                            *error.lock().expect("not poisoned") = Some(e);
                            break;
                        }
                        let done = written.fetch_add(1, Ordering::Relaxed) + 1;
                        let total = jobs.len() - kept.load(Ordering::Relaxed);
                        let per = start.elapsed().as_secs_f64() / done as f64;
                        let eta = per * total.saturating_sub(done) as f64;
                        eprintln!(
                            "{done}/{total} ({:?} {index}), {:.1} s each, ETA {:.0} min",
                            family,
                            per * threads.max(1) as f64,
                            eta / 60.0
                        );
                    }
                    Err(e) => {
                        failed.fetch_add(1, Ordering::Relaxed);
                        eprintln!("object {index} ({family:?}) skipped: {e}");
                    }
                }
            });
        }
    });
    if let Some(e) = error.into_inner().expect("not poisoned") {
        return Err(e);
    }
    Ok(Summary {
        written: written.into_inner(),
        kept: kept.into_inner(),
        failed: failed.into_inner(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn objects_are_reproducible_valid_and_varied() {
        // Same seed, same object; every family yields one face-connected piece that fits the
        // box; a different seed gives a different object.
        for held in [false, true] {
            for index in 0..14 {
                let (family, grid) = object(7, held, index);
                assert_eq!(family.held_out(), held);
                assert_eq!(object(7, held, index), (family, grid.clone()));
                assert!(grid.dims().iter().all(|&d| d <= INPUT_SIDE));
                assert!(grid.count() >= 27, "{family:?} {index}");
                assert_eq!(ops::components(&grid).1, 1);
            }
        }
        assert_ne!(object(7, false, 3).1, object(8, false, 3).1);
    }

    #[test]
    fn records_round_trip_and_refuse_garbage() {
        // A labelled bowl (its lowest modes near 2-3 kHz at the reference): the record reads
        // back equal (log-amplitudes to 1/255).
        let grid = Primitive::Bowl {
            diameter: 20.0,
            wall: 2.0,
        }
        .rasterize(1.0, 1.0)
        .unwrap();
        let record = Record::label(Family::Shell, grid, ElementKind::Hex8Incompatible).unwrap();
        assert!(record.labels.mask.iter().any(|&m| m));
        let bytes = record.encode();
        let back = Record::decode(&bytes).unwrap();
        assert_eq!(back.grid, record.grid);
        assert_eq!(back.labels.mask, record.labels.mask);
        assert_eq!(back.labels.band_log_hz, record.labels.band_log_hz);
        let worst = back
            .labels
            .log_amplitude
            .iter()
            .zip(&record.labels.log_amplitude)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(worst <= 0.5 / 255.0 + 1e-6, "{worst}");
        // The masks are 48 KiB of bits; a masked entry costs a byte: under 200 kB, so 5,500
        // records stay near 1 GB.
        assert!(bytes.len() < 200_000, "{} bytes", bytes.len());
        assert!(Record::decode(&bytes[..bytes.len() - 3]).is_err());
        assert!(Record::decode(b"junk").is_err());
    }
}
