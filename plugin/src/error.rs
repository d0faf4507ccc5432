//! The plugin's one error type: why an object edit, a stored object, a preset or a file was
//! refused. Every message is one line that says what to do; the editor shows it as it is.

use crate::sculpt::MAX_SIDE;
use modalforge::material::MaterialError;
use modalforge::shape::spec::SpecError;
use modalforge::shape::vox::VoxError;
use modalforge::shape::{PartialRecordError, ShapeError};
use std::path::PathBuf;

/// Why the plugin refused an object, a preset or a file.
#[derive(Debug, thiserror::Error)]
pub enum PluginError {
    /// A bad shape spec.
    #[error(transparent)]
    Spec(#[from] SpecError),
    /// A grid the shape library refused.
    #[error(transparent)]
    Shape(#[from] ShapeError),
    /// A material the library refused.
    #[error(transparent)]
    Material(#[from] MaterialError),
    /// A `.vox` file that cannot be read or written.
    #[error(transparent)]
    Vox(#[from] VoxError),
    /// A file over its size limit (`modalforge::limits`).
    #[error(transparent)]
    FileTooLarge(#[from] modalforge::limits::FileTooLarge),
    /// A spec names a file where a built-in shape is needed.
    #[error("'{0}' is a file, not a built-in shape: load it with Load .vox")]
    FileSpec(String),
    /// Nothing is solid; the text says what to do.
    #[error("the object is empty: {0}")]
    Empty(&'static str),
    /// A primitive with no voxel at the asked resolution.
    #[error("'{spec}' at {side} voxels is empty: raise the resolution")]
    EmptyAt {
        /// The shape spec.
        spec: String,
        /// Voxels along its longest side.
        side: usize,
    },
    /// Larger than the working box.
    #[error("the object is {0} voxels long, over the editor's {MAX_SIDE}: resample it first")]
    TooLong(usize),
    /// Hollowing would change nothing.
    #[error("the object is already at most {0} voxels thick")]
    AlreadyThin(usize),
    /// Resampling lost every voxel.
    #[error("at {0} voxels the object vanishes: use more")]
    Vanishes(usize),
    /// A stored object whose sizes do not add up.
    #[error("stored object {dims:?} with {bytes} bytes is malformed (sides 1..={MAX_SIDE})")]
    Malformed {
        /// Its dimensions.
        dims: [usize; 3],
        /// Its occupancy bytes.
        bytes: usize,
    },
    /// A stored object's partial voxels do not fit it.
    #[error("stored object's {0}")]
    StoredFill(#[from] PartialRecordError),
    /// A hex field of a stored object is not hex.
    #[error("object.{0} is not hex")]
    NotHex(&'static str),
    /// A preset with both or neither of `shape` and `object`.
    #[error("give exactly one of `shape` or `object`")]
    ShapeOrObject,
    /// Not a preset file at all.
    #[error("not a preset ({0}): see presets/objects/ for the format")]
    NotAPreset(String),
    /// A preset names a material that is not one of the plugin's.
    #[error("unknown material '{name}': use one of {known}")]
    UnknownMaterial {
        /// The name given.
        name: String,
        /// The names known.
        known: String,
    },
    /// A preset value outside its range.
    #[error("{field} {value} is outside {range}")]
    OutOfRange {
        /// The preset key.
        field: &'static str,
        /// The value, as written.
        value: String,
        /// The allowed range, with units.
        range: &'static str,
    },
    /// A material whose damping law the engine cannot voice live.
    #[error("the material's damping model cannot be voiced live")]
    NotLive,
    /// What went wrong in a preset file, with the file.
    #[error("{origin}: {source}")]
    InPreset {
        /// The preset's file (or name).
        origin: String,
        /// What is wrong in it.
        source: Box<PluginError>,
    },
    /// Reading or writing a file.
    #[error("cannot {action} {path}: {source}")]
    Io {
        /// `read` or `write`.
        action: &'static str,
        /// The file.
        path: PathBuf,
        /// What went wrong.
        source: std::io::Error,
    },
    /// A recording that cannot be matched or played: unreadable, not audio, or nothing to fit.
    #[error("cannot use recording {file}: {reason}")]
    Recording {
        /// The recording.
        file: String,
        /// What went wrong (one line).
        reason: String,
    },
}
