//! The resource limits: how large an input ModalForge accepts, in one place (issue 16).
//!
//! Where it sits: every reader checks a file's size here before it reads a byte
//! ([`check_file_size`]), so a file from a stranger cannot make the product allocate without
//! bound; the other limits live beside the code they protect and are listed here so that one
//! page states them all (the README's "Limits" section quotes this list):
//!
//! | what | limit | where | when it is passed |
//! |---|---|---|---|
//! | grid side | [`crate::shape::MAX_GRID_DIM`] = 256 voxels | `VoxelGrid::new` | refused before the grid is allocated |
//! | occupied voxels | [`crate::shape::MAX_OCCUPIED_VOXELS`] = 300,000 | the FEM mesh | refused before assembly |
//! | Cholesky factor (faer's values and their packed copy) | [`crate::eigen::factor::MAX_FACTOR_BYTES`] = 6 GiB | the symbolic analysis | refused before the numeric factorisation (the error names LOBPCG or a coarser grid) |
//! | modes per solve | [`crate::eigen::MAX_MODES`] = 4,000 | `EigenOptions` | capped |
//! | modes in a recording | [`crate::engine::recorded::MAX_RECORDED_MODES`] = 512 | `RecordedObject::validate` | refused |
//! | recording length | [`crate::analysis::wav::MAX_SECONDS`] = 60 s | `read_mono` | refused from the header, before the samples are read |
//! | Scala notes and keyboard map | [`crate::tuning::MAX_NOTES`], [`crate::tuning::MAX_MAP`] = 4,096 | the parsers | refused |
//! | file sizes | the `MAX_*_BYTES` constants below | [`check_file_size`] | refused before reading |
//!
//! The plugin adds its own: the sculpting box is 32 voxels a side (`plugin/src/sculpt.rs`,
//! larger imports are resampled to fit) and its worker keeps at most one pending request.

use std::path::Path;

/// Largest MagicaVoxel file read: 64 MiB (a full 256^3 model is 64 MiB of voxel records).
pub const MAX_VOX_BYTES: u64 = 64 << 20;
/// Largest OBJ or STL file read: 256 MiB (a binary STL of 5 million triangles).
pub const MAX_MESH_BYTES: u64 = 256 << 20;
/// Largest WAV file read: 512 MiB (a minute of 8 channels of 32-bit audio at 192 kHz is 369 MB).
pub const MAX_WAV_BYTES: u64 = 512 << 20;
/// Largest text file read (mode JSON, material and object preset TOML, Scala `.scl`/`.kbm`,
/// chart CSV): 16 MiB, far beyond any real one (4,000 modes of JSON are under 1 MiB).
pub const MAX_TEXT_BYTES: u64 = 16 << 20;
/// Largest predictor weights file read: 64 MiB (the shipped ones are 1.5 MB).
pub const MAX_WEIGHTS_BYTES: u64 = 64 << 20;

/// A file larger than ModalForge reads for its kind.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FileTooLarge {
    /// The file.
    pub path: String,
    /// Its size, bytes.
    pub size: u64,
    /// The limit, bytes.
    pub max: u64,
    /// What kind of file it is meant to be ("mesh", "WAV", ...).
    pub kind: &'static str,
    /// How to bring it under the limit.
    pub advice: &'static str,
}

impl std::fmt::Display for FileTooLarge {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} is {:.1} MiB; {} files are read up to {} MiB: {}",
            self.path,
            self.size as f64 / (1u64 << 20) as f64,
            self.kind,
            self.max >> 20,
            self.advice
        )
    }
}

impl std::error::Error for FileTooLarge {}

/// Refuses `path` when the file is larger than `max` bytes (a file whose size cannot be read
/// passes: the read that follows reports why it cannot open it).
pub fn check_file_size(
    path: &Path,
    max: u64,
    kind: &'static str,
    advice: &'static str,
) -> Result<(), FileTooLarge> {
    match std::fs::metadata(path) {
        Ok(meta) if meta.len() > max => Err(FileTooLarge {
            path: path.display().to_string(),
            size: meta.len(),
            max,
            kind,
            advice,
        }),
        _ => Ok(()),
    }
}

/// Reads a text file of at most [`MAX_TEXT_BYTES`] (`kind` names it in the error).
pub fn read_text(path: &Path, kind: &'static str) -> Result<String, TextReadError> {
    check_file_size(
        path,
        MAX_TEXT_BYTES,
        kind,
        "this is not the file you meant to open",
    )?;
    std::fs::read_to_string(path).map_err(TextReadError::Io)
}

/// Why [`read_text`] failed.
#[derive(Debug, thiserror::Error)]
pub enum TextReadError {
    /// Over the size limit.
    #[error(transparent)]
    TooLarge(#[from] FileTooLarge),
    /// The file could not be read.
    #[error(transparent)]
    Io(std::io::Error),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_over_its_limit_is_refused_before_reading_with_its_size_and_the_limit() {
        // A sparse file: 17 MiB long, no disk used. 16 MiB of text is the limit.
        let path = std::env::temp_dir().join(format!("modalforge-big-{}.toml", std::process::id()));
        let file = std::fs::File::create(&path).unwrap();
        file.set_len(17 << 20).unwrap();
        let err = read_text(&path, "material").unwrap_err();
        let msg = err.to_string();
        assert!(msg.contains("17.0 MiB"), "{msg}");
        assert!(
            msg.contains("material files are read up to 16 MiB"),
            "{msg}"
        );
        assert_eq!(msg.lines().count(), 1);
        // At the limit it is read.
        std::fs::File::create(&path)
            .unwrap()
            .set_len(MAX_TEXT_BYTES)
            .unwrap();
        assert_eq!(
            read_text(&path, "material").unwrap().len() as u64,
            MAX_TEXT_BYTES
        );
        std::fs::remove_file(&path).unwrap();
    }
}
