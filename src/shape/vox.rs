//! MagicaVoxel `.vox` import and export (the `dot_vox` crate).
//!
//! Import reads the file's first model; every voxel, whatever its colour, is solid. A `.vox`
//! file carries no physical scale, so the voxel edge comes from the caller (`--voxel-size` or
//! `--size`). Export writes one model with the default palette, colour index 1.

use super::{ShapeError, VoxelGrid};
use std::path::Path;

/// Why a `.vox` file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum VoxError {
    /// The file could not be read or written.
    #[error("cannot access {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The bytes are not a valid `.vox` file.
    #[error("{path} is not a valid MagicaVoxel .vox file ({reason})")]
    Parse {
        /// The file.
        path: String,
        /// The parser's reason.
        reason: &'static str,
    },
    /// The file holds no model.
    #[error("{0} holds no voxel model")]
    NoModel(String),
    /// The file is larger than [`crate::limits::MAX_VOX_BYTES`].
    #[error(transparent)]
    FileTooLarge(#[from] crate::limits::FileTooLarge),
    /// The grid is too large for the format (256 voxels per axis).
    #[error("a .vox model holds at most 256 voxels per axis; this grid is {0:?}")]
    TooLarge([usize; 3]),
    /// The voxels do not make a valid grid.
    #[error("{path}: {source}")]
    Shape {
        /// The file.
        path: String,
        /// What is wrong.
        source: ShapeError,
    },
}

/// Reads the first model of a `.vox` file.
pub fn read_vox(path: &Path, voxel_size_m: f64) -> Result<VoxelGrid, VoxError> {
    let name = path.display().to_string();
    crate::limits::check_file_size(
        path,
        crate::limits::MAX_VOX_BYTES,
        "MagicaVoxel",
        "it holds more than one 256^3 model; save the one you want alone",
    )?;
    let bytes = std::fs::read(path).map_err(|source| VoxError::Io {
        path: name.clone(),
        source,
    })?;
    parse_vox(&bytes, &name, voxel_size_m)
}

/// Parses `.vox` bytes; `name` labels errors.
pub fn parse_vox(bytes: &[u8], name: &str, voxel_size_m: f64) -> Result<VoxelGrid, VoxError> {
    // dot_vox trusts the counts in the file and reserves memory for them before reading: a
    // corrupt count asked for 73 GB and aborted the process (found by `tests/fuzz.rs`). Every
    // count is checked against the bytes that follow it first.
    structure::check(bytes).map_err(|reason| VoxError::Parse {
        path: name.to_string(),
        reason,
    })?;
    // dot_vox's parser is nom-based; guard against a panic on hostile input all the same.
    let parsed =
        std::panic::catch_unwind(|| dot_vox::load_bytes(bytes)).unwrap_or(Err("parser failed"));
    let data = parsed.map_err(|reason| VoxError::Parse {
        path: name.to_string(),
        // dot_vox's usual reason repeats the message itself; say what to do instead.
        reason: if reason.eq_ignore_ascii_case("not a valid magicavoxel .vox file") {
            "no 'VOX ' header and chunks: save or export it from MagicaVoxel again"
        } else {
            reason
        },
    })?;
    let model = data
        .models
        .first()
        .ok_or_else(|| VoxError::NoModel(name.to_string()))?;
    let dims = [
        model.size.x as usize,
        model.size.y as usize,
        model.size.z as usize,
    ];
    let shape_err = |source| VoxError::Shape {
        path: name.to_string(),
        source,
    };
    let mut grid = VoxelGrid::new(dims, voxel_size_m).map_err(shape_err)?;
    for v in &model.voxels {
        let (x, y, z) = (v.x as usize, v.y as usize, v.z as usize);
        if x < dims[0] && y < dims[1] && z < dims[2] {
            grid.set(x, y, z, true);
        }
    }
    Ok(grid)
}

/// Half full: a partial voxel at least this full is solid in a `.vox` file, emptier ones are
/// left out. MagicaVoxel voxels are binary; this keeps the filled volume closest to the true
/// one (a voxel is kept when most of it is material).
pub const VOX_EXPORT_THRESHOLD: f64 = 0.5;

/// Encodes a grid as `.vox` bytes; partial voxels are thresholded at
/// [`VOX_EXPORT_THRESHOLD`] (the format has no fractions).
pub fn encode_vox(grid: &VoxelGrid) -> Result<Vec<u8>, VoxError> {
    let dims = grid.dims();
    if dims.iter().any(|&d| d > 256) {
        return Err(VoxError::TooLarge(dims));
    }
    let voxels = grid
        .thresholded(VOX_EXPORT_THRESHOLD)
        .solid_voxels()
        .into_iter()
        .map(|[x, y, z]| dot_vox::Voxel {
            x: x as u8,
            y: y as u8,
            z: z as u8,
            i: 1,
        })
        .collect();
    let data = dot_vox::DotVoxData {
        version: 150,
        index_map: (0..=255).collect(),
        models: vec![dot_vox::Model {
            size: dot_vox::Size {
                x: dims[0] as u32,
                y: dims[1] as u32,
                z: dims[2] as u32,
            },
            voxels,
        }],
        palette: dot_vox::DEFAULT_PALETTE.to_vec(),
        materials: Vec::new(),
        scenes: Vec::new(),
        layers: Vec::new(),
    };
    let mut out = Vec::new();
    data.write_vox(&mut out).map_err(|source| VoxError::Io {
        path: "<memory>".into(),
        source,
    })?;
    Ok(out)
}

/// Writes a grid to a `.vox` file.
pub fn write_vox(grid: &VoxelGrid, path: &Path) -> Result<(), VoxError> {
    let bytes = encode_vox(grid)?;
    std::fs::write(path, bytes).map_err(|source| VoxError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// A structural check of `.vox` bytes before dot_vox reads them: every chunk lies inside its
/// parent, and every count in a chunk the format defines (voxels, dictionary entries, string
/// lengths, frames, children, models, names) fits in the bytes that follow it, so nothing
/// reserves more memory than the file holds. Layout: the MagicaVoxel format description
/// (`VOX `, version, then chunks of id, content size, children size).
mod structure {
    /// Nesting deeper than MAIN > children is not in the format.
    const MAX_DEPTH: usize = 4;

    const BAD: &str = "a chunk or a count runs past the end of the file: the file is damaged; \
                       export it from MagicaVoxel again";

    /// `Err` with a one-line reason where the bytes cannot be a `.vox` file dot_vox may read.
    pub fn check(bytes: &[u8]) -> Result<(), &'static str> {
        if bytes.len() < 8 || &bytes[..4] != b"VOX " {
            // dot_vox refuses it without reading further.
            return Ok(());
        }
        chunks(&bytes[8..], 0)
    }

    fn chunks(mut b: &[u8], depth: usize) -> Result<(), &'static str> {
        if depth > MAX_DEPTH {
            return Err(BAD);
        }
        while !b.is_empty() {
            let mut r = Reader(b);
            let id = r.take(4)?;
            let content = r.u32()? as usize;
            let children = r.u32()? as usize;
            let content = r.take(content)?;
            let children = r.take(children)?;
            contents(id, content)?;
            chunks(children, depth + 1)?;
            b = r.0;
        }
        Ok(())
    }

    fn contents(id: &[u8], b: &[u8]) -> Result<(), &'static str> {
        let mut r = Reader(b);
        match id {
            b"XYZI" => {
                let n = r.u32()? as usize;
                r.take(n.checked_mul(4).ok_or(BAD)?)?;
            }
            b"nTRN" => {
                r.u32()?;
                r.dict()?;
                r.take(12)?;
                let frames = r.count(4)?;
                for _ in 0..frames {
                    r.dict()?;
                }
            }
            b"nGRP" => {
                r.u32()?;
                r.dict()?;
                let n = r.count(4)?;
                r.take(n * 4)?;
            }
            b"nSHP" => {
                r.u32()?;
                r.dict()?;
                let n = r.count(8)?;
                for _ in 0..n {
                    r.u32()?;
                    r.dict()?;
                }
            }
            b"MATL" | b"LAYR" | b"rCAM" => {
                r.u32()?;
                r.dict()?;
            }
            b"rOBJ" => r.dict()?,
            b"NOTE" => {
                let n = r.count(4)?;
                for _ in 0..n {
                    r.string()?;
                }
            }
            _ => {}
        }
        Ok(())
    }

    struct Reader<'a>(&'a [u8]);

    impl<'a> Reader<'a> {
        fn take(&mut self, n: usize) -> Result<&'a [u8], &'static str> {
            if n > self.0.len() {
                return Err(BAD);
            }
            let (head, rest) = self.0.split_at(n);
            self.0 = rest;
            Ok(head)
        }

        fn u32(&mut self) -> Result<u32, &'static str> {
            let b = self.take(4)?;
            Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        }

        /// A count of items at least `min_bytes` long each, checked against what is left.
        fn count(&mut self, min_bytes: usize) -> Result<usize, &'static str> {
            let n = self.u32()? as usize;
            if n.saturating_mul(min_bytes) > self.0.len() {
                return Err(BAD);
            }
            Ok(n)
        }

        fn string(&mut self) -> Result<(), &'static str> {
            let n = self.u32()? as usize;
            self.take(n).map(|_| ())
        }

        fn dict(&mut self) -> Result<(), &'static str> {
            let n = self.count(8)?;
            for _ in 0..n {
                self.string()?;
                self.string()?;
            }
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shape::primitives::Primitive;

    #[test]
    fn round_trip_keeps_every_voxel() {
        let bowl = Primitive::Bowl {
            diameter: 16.0,
            wall: 2.0,
        };
        let grid = bowl.rasterize_staircase(1.0, 0.01).unwrap();
        let bytes = encode_vox(&grid).unwrap();
        let back = parse_vox(&bytes, "mem", 0.01).unwrap();
        assert_eq!(back, grid);
        // Partial voxels are written solid when at least half full.
        let smooth = bowl.rasterize(1.0, 0.01).unwrap();
        assert!(!smooth.is_binary());
        let back = parse_vox(&encode_vox(&smooth).unwrap(), "mem", 0.01).unwrap();
        assert_eq!(back, smooth.thresholded(VOX_EXPORT_THRESHOLD));
        assert!(back.count() < smooth.count());
    }

    #[test]
    fn garbage_is_a_clear_error() {
        for bytes in [&b""[..], b"VOX ", b"not a vox file at all", &[0xff; 64]] {
            let e = parse_vox(bytes, "junk.vox", 0.01).unwrap_err();
            assert!(e.to_string().contains("junk.vox"), "{e}");
        }
    }
}
