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

mod shapes;

use super::bands::{self, BandEncoding, BANDS, CELLS_PER_AXIS, DIRECTIONS, INPUT_SIDE};
use crate::basis::ModeBasis;
use crate::eigen::{EigenOptions, ModeCount, SolverKind};
use crate::fem::ElementKind;
use crate::shape::{VoxelGrid, PARTIAL_RECORD_BYTES};
pub use shapes::object;
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

/// The buffer budget ([`crate::buffer::set_kept_bytes`]) of a process that labels objects
/// (`modalforge dataset`): their whole factors, a few hundred MB for an object filling the box,
/// stay mapped from one object to the next instead of coming back as fresh memory the kernel
/// zeroes (perf: 35 % of the labelling time in the kernel's `clear_page_erms`). On two
/// threads, against the 64 MB default: 64 objects (`dataset --count 64 --held-out 0 --seed
/// 5`) 68.4 -> 61.1 s (0.89x), 32 objects (`--seed 4`) 23.4-25.0 -> 21.5-23.0 s in three
/// pairs of runs; the same labels byte for byte; peak resident memory 2.7 -> 3.9 GB and 1.8
/// -> 2.9 GB.
pub const KEPT_BYTES_WHILE_LABELLING: usize = 2 << 30;

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
    use crate::shape::ops;
    use crate::shape::primitives::Primitive;

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
    fn a_held_out_plate_has_its_holes() {
        // Truth: a plain plate fills its whole bounding box; every hole removes voxels. The
        // holes were once placed anywhere in the box and mostly missed the plate.
        let mut plates = 0;
        for index in 0..40 {
            let (family, grid) = object(2, true, index);
            if family == Family::PlateWithHoles {
                plates += 1;
                let box_voxels: usize = grid.dims().iter().product();
                assert!(grid.count() < box_voxels, "plate {index}: no hole");
            }
        }
        assert!(plates >= 10, "{plates} plates");
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
