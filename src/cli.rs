//! The `modalforge` command line.
//!
//! Where it sits: the outermost layer. It reads a mode file (or takes the [`crate::demo`] bar),
//! culls it, renders one strike or scrape with [`crate::synth::render`] and writes a WAV with
//! hound. Every failure is one line on stderr and a non-zero exit, never a panic.

use crate::modes::{CullReport, CullSettings, ModeFileError, ModeSet};
use crate::synth::render::{self, BankKind, Performance, RenderError};
use crate::synth::{Excitation, ExcitationError, SimdBackend};
use clap::{Parser, Subcommand, ValueEnum};
use std::path::PathBuf;

/// Longest render accepted, in seconds.
pub const MAX_SECONDS: f64 = 600.0;

/// Physically based impact sounds: strike an object, get its sound.
#[derive(Parser, Debug)]
#[command(name = "modalforge", version, about)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Subcommand, Debug)]
pub enum Command {
    /// Render a struck (or scraped) object to a WAV file.
    Render(RenderArgs),
    /// Print the built-in demo object's modes as JSON (a template for --modes files).
    DemoModes,
}

/// Options of `modalforge render`.
#[derive(clap::Args, Debug)]
pub struct RenderArgs {
    /// Mode file: {"modes":[{"freq_hz":F,"decay_per_s":D,"gain":G}, ...]}. Without it, the
    /// built-in demo: a 32 cm free-free steel bar struck near one end.
    #[arg(long, value_name = "FILE.json")]
    pub modes: Option<PathBuf>,
    /// Output WAV file.
    #[arg(long, value_name = "OUT.wav", default_value = "impact.wav")]
    pub out: PathBuf,
    /// Length in seconds [default: until the sound has decayed by 60 dB, 0.5 to 30 s].
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    pub seconds: Option<f64>,
    /// Sample rate in Hz (8000 to 384000).
    #[arg(long, value_name = "HZ", default_value_t = 48000)]
    pub rate: u32,
    /// Synthesis bank.
    #[arg(long, value_enum, default_value_t = BankArg::Oscillator)]
    pub bank: BankArg,
    /// Mallet contact time in seconds: 0 is an ideal impulse, longer is softer (up to 0.1).
    #[arg(
        long,
        value_name = "SECONDS",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub hardness: f64,
    /// Strike velocity, a force multiplier from 0 to 100 (1 = the modes' own gains).
    #[arg(
        long,
        value_name = "V",
        default_value_t = 1.0,
        allow_negative_numbers = true
    )]
    pub velocity: f64,
    /// Scrape the object with noise for this many seconds instead of striking it (biquad bank).
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    pub scrape: Option<f64>,
    /// Bits per sample: 32 (float), 24 or 16 (integer).
    #[arg(long, value_name = "BITS", default_value_t = 32)]
    pub bits: u16,
    /// Keep the raw amplitudes instead of normalising the peak to -1 dBFS.
    #[arg(long)]
    pub no_normalize: bool,
    /// Print a JSON summary instead of a sentence.
    #[arg(long)]
    pub json: bool,
}

/// `--bank` values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum BankArg {
    /// Damped oscillators: exact, fastest, strikes only.
    Oscillator,
    /// Biquad resonators: driven by any force signal.
    Biquad,
}

/// Everything the CLI can fail with; each message is one line that says what to fix.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// Reading or validating the mode file.
    #[error(transparent)]
    ModeFile(#[from] ModeFileError),
    /// Culling or mode validation.
    #[error(transparent)]
    Modes(#[from] crate::modes::ModeError),
    /// A bad excitation value.
    #[error(transparent)]
    Excitation(#[from] ExcitationError),
    /// A bad option value.
    #[error("{0}")]
    Option(String),
    /// Creating or writing the WAV file.
    #[error("cannot write {path}: {source}")]
    Wav {
        /// The output file.
        path: PathBuf,
        /// What went wrong.
        source: hound::Error,
    },
    /// Rendering.
    #[error(transparent)]
    Render(#[from] RenderError<hound::Error>),
}

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
    pub bank: &'static str,
    /// SIMD backend used.
    pub backend: &'static str,
    /// Culling counts.
    pub modes: CullReport,
    /// Peak absolute sample before normalisation.
    pub raw_peak: f32,
    /// Gain applied to reach -1 dBFS (1 with --no-normalize).
    pub gain: f32,
}

/// Runs the CLI; returns the text to print on success.
pub fn run(cli: Cli) -> Result<String, CliError> {
    match cli.command {
        Command::DemoModes => Ok(crate::demo::steel_bar().to_json()),
        Command::Render(args) => {
            let json = args.json;
            let summary = render_command(&args)?;
            Ok(if json {
                serde_json::to_string_pretty(&summary).expect("summary serialises")
            } else {
                format!(
                    "wrote {} ({:.2} s, {} Hz, {}-bit, {} {} modes, {})",
                    summary.out.display(),
                    summary.seconds,
                    summary.sample_rate_hz,
                    summary.bits,
                    summary.modes.kept,
                    summary.bank,
                    if args.modes.is_some() {
                        "from the mode file"
                    } else {
                        "demo steel bar"
                    }
                )
            })
        }
    }
}

fn option_error(msg: String) -> CliError {
    CliError::Option(msg)
}

/// `modalforge render`.
pub fn render_command(args: &RenderArgs) -> Result<RenderSummary, CliError> {
    if !(8000..=384_000).contains(&args.rate) {
        return Err(option_error(format!(
            "--rate {} is out of range: use 8000 to 384000 Hz",
            args.rate
        )));
    }
    if ![16, 24, 32].contains(&args.bits) {
        return Err(option_error(format!(
            "--bits {} is not supported: use 16, 24 or 32",
            args.bits
        )));
    }
    let fs = args.rate as f64;
    let excitation = Excitation::mallet(args.hardness)?;
    crate::synth::oscillator::check_velocity(args.velocity)?;
    let modes = match &args.modes {
        Some(path) => ModeSet::from_json_file(path)?,
        None => crate::demo::steel_bar(),
    };
    let (playable, report) = modes.playable(fs, &CullSettings::default())?;
    let performance = match args.scrape {
        None => Performance::Strike {
            excitation,
            velocity: args.velocity,
        },
        Some(s) if s.is_finite() && s > 0.0 && s <= MAX_SECONDS => Performance::Scrape {
            seconds: s,
            level: 0.05 * args.velocity,
            cutoff_hz: 4000.0,
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
    let bank = match args.bank {
        BankArg::Oscillator => BankKind::Oscillator,
        BankArg::Biquad => BankKind::Biquad,
    };
    let n = (seconds * fs).round().max(1.0) as usize;
    let fade = ((0.01 * fs) as usize).min(n / 4);

    // Pass 1: the peak, for normalisation (rendering is deterministic and cheap).
    let mut raw_peak = 0f32;
    if !args.no_normalize {
        render::render::<hound::Error>(&playable, bank, performance, n, fade, |b| {
            raw_peak = b.iter().fold(raw_peak, |p, x| p.max(x.abs()));
            Ok(())
        })?;
    }
    let gain = if args.no_normalize || raw_peak == 0.0 {
        1.0
    } else {
        0.891_250_9 / raw_peak
    };

    // Pass 2: write.
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
    render::render::<hound::Error>(&playable, bank, performance, n, fade, |b| {
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
    if args.no_normalize {
        raw_peak = peak;
    }
    Ok(RenderSummary {
        out: args.out.clone(),
        seconds: n as f64 / fs,
        sample_rate_hz: args.rate,
        bits: args.bits,
        bank: match bank {
            BankKind::Oscillator => "oscillator",
            BankKind::Biquad => "biquad",
        },
        backend: SimdBackend::detect().name(),
        modes: report,
        raw_peak,
        gain,
    })
}

fn to_int(y: f32, full_scale: f32) -> i32 {
    (y.clamp(-1.0, 1.0) * full_scale).round() as i32
}
