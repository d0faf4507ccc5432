//! `modalforge render`: the modes (a mode file, or an object solved), culled for the sample
//! rate, rendered to a WAV file with hound.
//!
//! Where it sits: [`super::run`] calls [`render_command`] with the parsed [`RenderArgs`]; the
//! object path goes through [`super::object`], the synthesis through
//! [`modalforge::synth::render`].

use super::{object, option_error, CliError, RenderArgs, MAX_SECONDS};
use modalforge::modes::{CullReport, CullSettings, ModeSet};
use modalforge::synth::render::{self, Performance, RenderError};
use modalforge::synth::{Excitation, SimdBackend};
use std::path::PathBuf;

/// What `render` did, for the summary line or `--json`.
#[derive(Debug, serde::Serialize)]
pub struct RenderSummary {
    /// The WAV file written.
    pub out: PathBuf,
    /// Length in seconds.
    pub seconds: f64,
    /// Sample rate in Hz.
    pub sample_rate_hz: u32,
    /// Bits per sample.
    pub bits: u16,
    /// `oscillator` or `biquad`.
    pub bank: String,
    /// SIMD backend used.
    pub backend: &'static str,
    /// Culling counts.
    pub modes: CullReport,
    /// Peak absolute sample before normalisation.
    pub raw_peak: f32,
    /// Gain applied to reach -1 dBFS (1 with --no-normalize).
    pub gain: f32,
}

/// The peak a normalised render reaches: -1 dBFS, `10^(-1/20)`.
const NORMALIZED_PEAK: f32 = 0.891_250_9;

/// Scraping noise: its level per unit of velocity and its low-pass cutoff.
const SCRAPE_LEVEL_PER_VELOCITY: f64 = 0.05;
const SCRAPE_CUTOFF_HZ: f64 = 4000.0;

/// `modalforge render`: the modes (a file, or an object solved), culled for the sample rate,
/// rendered twice (the peak for normalisation, then the WAV).
pub fn render_command(args: &RenderArgs) -> Result<RenderSummary, CliError> {
    let fs = args.rate as f64;
    let excitation = Excitation::mallet(args.hardness)?;
    modalforge::synth::oscillator::check_velocity(args.velocity)?;
    let modes = render_modes(args)?;
    let (playable, report) = modes.playable(fs, &CullSettings::default())?;
    let performance = match args.scrape {
        None => Performance::Strike {
            excitation,
            velocity: args.velocity,
        },
        Some(s) if s.is_finite() && s > 0.0 && s <= MAX_SECONDS => Performance::Scrape {
            seconds: s,
            level: SCRAPE_LEVEL_PER_VELOCITY * args.velocity,
            cutoff_hz: SCRAPE_CUTOFF_HZ,
        },
        Some(s) => {
            return Err(option_error(format!(
                "--scrape {s} is invalid: use a duration from 0 to {MAX_SECONDS} s"
            )))
        }
    };
    let onset_s = args.scrape.unwrap_or(0.0) + args.hardness;
    let seconds = match args.seconds {
        Some(s) if s.is_finite() && s > 0.0 && s <= MAX_SECONDS => s,
        Some(s) => {
            return Err(option_error(format!(
                "--seconds {s} is invalid: use a length from 0 to {MAX_SECONDS} s"
            )))
        }
        None => (onset_s + playable.ring_time_s(60.0)).clamp(0.5, 30.0),
    };
    let n = (seconds * fs).round().max(1.0) as usize;
    let fade = ((0.01 * fs) as usize).min(n / 4);
    let render = |sink: &mut dyn FnMut(&[f32]) -> Result<(), hound::Error>| {
        render::render::<hound::Error>(&playable, args.bank, performance, n, fade, sink)
    };

    // Pass 1: the peak, for normalisation (rendering is deterministic and cheap).
    let mut raw_peak = 0f32;
    if !args.no_normalize {
        render(&mut |b| {
            raw_peak = b.iter().fold(raw_peak, |p, x| p.max(x.abs()));
            Ok(())
        })?;
    }
    let gain = if args.no_normalize || raw_peak == 0.0 {
        1.0
    } else {
        NORMALIZED_PEAK / raw_peak
    };
    // Pass 2: the WAV.
    let peak = write_wav(args, gain, render)?;
    if args.no_normalize {
        raw_peak = peak;
    }
    Ok(RenderSummary {
        out: args.out.clone(),
        seconds: n as f64 / fs,
        sample_rate_hz: args.rate,
        bits: args.bits,
        bank: args.bank.to_string(),
        backend: SimdBackend::detect().name(),
        modes: report,
        raw_peak,
        gain,
    })
}

/// The modes `render` plays: the mode file, or the object (default: the demo bar's shape and
/// length) solved by FEM or predicted, voiced for the strike.
fn render_modes(args: &RenderArgs) -> Result<ModeSet, CliError> {
    if let Some(path) = &args.modes {
        return Ok(ModeSet::from_json_file(path)?);
    }
    let mut object_args = args.object.clone();
    if object_args.shape.is_none() && object_args.size.is_none() && object_args.voxel_size.is_none()
    {
        object_args.size = Some(modalforge::demo::BAR_LENGTH_M);
    }
    let object = object::Object::from_args(&object_args, Some(args.fmax))?;
    if object.neural {
        let (predicted, hit) = object.predict(&object_args)?;
        let report = object::neural_report(&object, &predicted, &hit, None, Some(args.fmax), false);
        let (mut f, mut d, mut g) = (Vec::new(), Vec::new(), Vec::new());
        for m in report.modes.iter().filter(|m| !m.overdamped) {
            f.push(m.freq_hz);
            d.push(m.decay_per_s);
            g.push(m.gain);
        }
        return Ok(ModeSet::new(f, d, g)?);
    }
    let count = object.count(None, Some(args.fmax))?;
    let basis = object.solve(count, object_args.tolerance)?;
    let hit = object.hit(&object_args)?;
    Ok(basis
        .mode_set(&object.material, object.grid.voxel_size_m(), &hit)
        .map_err(object::ObjectError::from)?)
}

/// Writes `render`'s samples times `gain` to `args.out` in the format `--bits` asks for;
/// returns the peak written.
fn write_wav(
    args: &RenderArgs,
    gain: f32,
    render: impl Fn(
        &mut dyn FnMut(&[f32]) -> Result<(), hound::Error>,
    ) -> Result<(), RenderError<hound::Error>>,
) -> Result<f32, CliError> {
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: args.rate,
        bits_per_sample: args.bits,
        sample_format: if args.bits == 32 {
            hound::SampleFormat::Float
        } else {
            hound::SampleFormat::Int
        },
    };
    let wav_err = |source| CliError::Wav {
        path: args.out.clone(),
        source,
    };
    let mut writer = hound::WavWriter::create(&args.out, spec).map_err(wav_err)?;
    let bits = args.bits;
    let mut peak = 0f32;
    render(&mut |b| {
        for &x in b {
            let y = x * gain;
            peak = peak.max(y.abs());
            match bits {
                32 => writer.write_sample(y)?,
                24 => writer.write_sample(to_int(y, 8_388_607.0))?,
                _ => writer.write_sample(to_int(y, 32_767.0) as i16)?,
            }
        }
        Ok(())
    })?;
    writer.finalize().map_err(wav_err)?;
    Ok(peak)
}

fn to_int(y: f32, full_scale: f32) -> i32 {
    (y.clamp(-1.0, 1.0) * full_scale).round() as i32
}
