//! Reading a recording: any WAV hound reads (8-32-bit integer or 32-bit float PCM, any rate,
//! any channel count), mixed to mono, in full-scale units (`[-1, 1]`); and writing one (a
//! resynthesis) as mono 32-bit float.
//!
//! Where it sits: the first step of `modalforge analyze` ([`super::extract`] takes the samples).

use std::path::{Path, PathBuf};

/// Why a recording could not be read.
#[derive(Debug, thiserror::Error)]
pub enum WavError {
    /// Not a WAV file hound can read (or unreadable).
    #[error("{path}: not a readable WAV file ({source}); give a PCM or float WAV recording")]
    Read {
        /// The file.
        path: PathBuf,
        /// What hound said.
        source: hound::Error,
    },
    /// The file could not be written.
    #[error("cannot write {path}: {source}")]
    Write {
        /// The file.
        path: PathBuf,
        /// What hound said.
        source: hound::Error,
    },
    /// The file is larger than [`crate::limits::MAX_WAV_BYTES`].
    #[error(transparent)]
    TooLarge(#[from] crate::limits::FileTooLarge),
    /// A format hound reads but no strike can be in.
    #[error("{path}: {what}")]
    Unsupported {
        /// The file.
        path: PathBuf,
        /// What is wrong and what would do.
        what: String,
    },
}

/// Longest recording read, seconds: a struck object has died away long before.
pub const MAX_SECONDS: f64 = 60.0;

/// The recording at `path` mixed to mono, and its sample rate in Hz.
pub fn read_mono(path: &Path) -> Result<(Vec<f64>, f64), WavError> {
    let read = |source| WavError::Read {
        path: path.to_path_buf(),
        source,
    };
    let unsupported = |what: String| WavError::Unsupported {
        path: path.to_path_buf(),
        what,
    };
    crate::limits::check_file_size(
        path,
        crate::limits::MAX_WAV_BYTES,
        "WAV",
        "cut it to the strike and mix it to mono first",
    )?;
    let mut reader = hound::WavReader::open(path).map_err(read)?;
    let spec = reader.spec();
    let channels = spec.channels as usize;
    if channels == 0 || spec.sample_rate == 0 {
        return Err(unsupported(format!(
            "{} channels at {} Hz: the header is corrupt",
            spec.channels, spec.sample_rate
        )));
    }
    let frames = reader.duration() as usize;
    let max_frames = (MAX_SECONDS * spec.sample_rate as f64) as usize;
    if frames > max_frames {
        return Err(unsupported(format!(
            "{:.0} s long; cut it to the strike (at most {MAX_SECONDS:.0} s)",
            frames as f64 / spec.sample_rate as f64
        )));
    }
    let interleaved: Vec<f64> = match spec.sample_format {
        hound::SampleFormat::Float => reader
            .samples::<f32>()
            .map(|s| s.map(f64::from))
            .collect::<Result<_, _>>()
            .map_err(read)?,
        hound::SampleFormat::Int => {
            if !(1..=32).contains(&spec.bits_per_sample) {
                return Err(unsupported(format!(
                    "{}-bit integer samples: give 8 to 32 bits",
                    spec.bits_per_sample
                )));
            }
            let scale = 1.0 / 2f64.powi(spec.bits_per_sample as i32 - 1);
            reader
                .samples::<i32>()
                .map(|s| s.map(|v| v as f64 * scale))
                .collect::<Result<_, _>>()
                .map_err(read)?
        }
    };
    if let Some(i) = interleaved.iter().position(|v| !v.is_finite()) {
        return Err(unsupported(format!(
            "sample {i} is not a number (NaN or infinite): the file is corrupt; export it again"
        )));
    }
    let mono = interleaved
        .chunks_exact(channels)
        .map(|frame| frame.iter().sum::<f64>() / channels as f64)
        .collect();
    Ok((mono, spec.sample_rate as f64))
}

/// Writes `samples` (full-scale units) to `path` as a mono 32-bit float WAV at `rate_hz`.
pub fn write_mono(path: &Path, rate_hz: f64, samples: &[f64]) -> Result<(), WavError> {
    let write = |source| WavError::Write {
        path: path.to_path_buf(),
        source,
    };
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: rate_hz.round() as u32,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let mut w = hound::WavWriter::create(path, spec).map_err(write)?;
    for &v in samples {
        w.write_sample(v as f32).map_err(write)?;
    }
    w.finalize().map_err(write)
}
