//! The `modalforge` command line.
//!
//! Where it sits: the outermost layer. `modes` builds an object ([`object`]: shape, material,
//! element, solver, strike), solves it and prints its modes; `render` takes a mode file or solves
//! an object the same way, culls the modes, renders one strike or scrape with
//! [`modalforge::synth::render`] and writes a WAV with hound. Every failure is one line on stderr and
//! a non-zero exit, never a panic. `chart` ([`chart`]) sweeps the solvers' speed against their
//! accuracy.

pub mod analyze;
pub mod chart;
pub mod object;
pub mod predictor;

use clap::builder::TypedValueParser;
use clap::{Parser, Subcommand};
use modalforge::modes::{CullReport, CullSettings, ModeFileError, ModeSet};
use modalforge::synth::render::{self, BankKind, Performance, RenderError};
use modalforge::synth::{Excitation, ExcitationError, SimdBackend};
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
    /// Solve an object's vibration modes (finite elements) and print them.
    Modes(ModesArgs),
    /// List the material presets.
    Materials,
    /// Sweep shapes, resolutions, elements, solvers and tolerances; write chart.csv and
    /// chart.png (frequency error against solve time).
    Chart(chart::ChartArgs),
    /// Print the analytic Euler-Bernoulli steel bar's modes as JSON (a template for --modes files).
    DemoModes,
    /// Generate the neural predictor's training data: varied objects in a 32^3 box, labelled
    /// by FEM in the band representation (resumable: finished records are kept).
    Dataset(DatasetArgs),
    /// Train the neural predictor on a dataset (CPU; checkpoints each epoch and resumes).
    Train(predictor::TrainArgs),
    /// The neural predictor's tools.
    #[command(subcommand)]
    Predictor(predictor::PredictorCommand),
    /// Find the modes (frequency, decay, amplitude, phase) of a recorded strike.
    Analyze(analyze::AnalyzeArgs),
}

/// Options of `modalforge dataset`.
#[derive(clap::Args, Debug)]
pub struct DatasetArgs {
    /// Output directory (records go to OUT/train/ and OUT/heldout/).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Training objects.
    #[arg(long, value_name = "N", default_value_t = 5000)]
    pub count: usize,
    /// Held-out objects (shape families training never sees).
    #[arg(long, value_name = "N", default_value_t = 500)]
    pub held_out: usize,
    /// Random seed: the same seed makes the same dataset.
    #[arg(long, value_name = "S", default_value_t = 1)]
    pub seed: u64,
    /// Threads [default: every core].
    #[arg(long, value_name = "N")]
    pub threads: Option<usize>,
    /// Finite element the labels are solved with (hex27x2 is the plugin's; the directory's
    /// labels.toml records it, and a resumed run must use the same).
    #[arg(long, value_name = "NAME", default_value_t = modalforge::fem::ElementKind::Hex27Blocks)]
    pub element: modalforge::fem::ElementKind,
}

/// Options of `modalforge modes`.
#[derive(clap::Args, Debug)]
pub struct ModesArgs {
    /// The object.
    #[command(flatten)]
    pub object: object::ObjectArgs,
    /// Number of (non-rigid) modes [default: 20].
    #[arg(long, value_name = "K", conflicts_with = "fmax")]
    pub modes: Option<usize>,
    /// Compute every mode below this frequency instead.
    #[arg(long, value_name = "HZ")]
    pub fmax: Option<f64>,
    /// Print JSON: {"modes":[...], "rigid_modes", "components", "voxels", "dofs", "residuals",
    /// "timings_ms"}; readable by `render --modes`.
    #[arg(long)]
    pub json: bool,
    /// With --solver neural: also print the predicted band representation at the strike
    /// (per band: frequency, masks and log-amplitudes for forces along x, y, z).
    #[arg(long)]
    pub bands: bool,
}

/// Options of `modalforge render`.
#[derive(clap::Args, Debug)]
pub struct RenderArgs {
    /// Mode file: {"modes":[{"freq_hz":F,"decay_per_s":D,"gain":G}, ...]}. Without it the
    /// object given by --shape is solved; with neither, a 32 cm steel bar (64x4x4 voxels).
    #[arg(long, value_name = "FILE.json", conflicts_with = "shape")]
    pub modes: Option<PathBuf>,
    /// The object to solve and strike (ignored with --modes).
    #[command(flatten)]
    pub object: object::ObjectArgs,
    /// Highest mode frequency modelled when solving an object.
    #[arg(long, value_name = "HZ", default_value_t = 10000.0)]
    pub fmax: f64,
    /// Output WAV file.
    #[arg(long, value_name = "OUT.wav", default_value = "impact.wav")]
    pub out: PathBuf,
    /// Length in seconds [default: until the sound has decayed by 60 dB, 0.5 to 30 s].
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    pub seconds: Option<f64>,
    /// Sample rate in Hz.
    #[arg(long, value_name = "HZ", default_value_t = 48000,
          value_parser = clap::value_parser!(u32).range(8000..=384_000))]
    pub rate: u32,
    /// Synthesis bank.
    #[arg(long, value_enum, default_value_t = BankKind::Oscillator)]
    pub bank: BankKind,
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
    #[arg(long, value_name = "BITS", default_value_t = 32,
          value_parser = clap::builder::PossibleValuesParser::new(["16", "24", "32"])
              .map(|b| b.parse::<u16>().expect("a listed value")))]
    pub bits: u16,
    /// Keep the raw amplitudes instead of normalising the peak to -1 dBFS.
    #[arg(long)]
    pub no_normalize: bool,
    /// Print a JSON summary instead of a sentence.
    #[arg(long)]
    pub json: bool,
}

/// Everything the CLI can fail with; each message is one line that says what to fix.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// Reading or validating the mode file.
    #[error(transparent)]
    ModeFile(#[from] ModeFileError),
    /// Culling or mode validation.
    #[error(transparent)]
    Modes(#[from] modalforge::modes::ModeError),
    /// A bad excitation value.
    #[error(transparent)]
    Excitation(#[from] ExcitationError),
    /// A bad option value.
    #[error("{0}")]
    Option(String),
    /// Reading or writing a file or directory.
    #[error("cannot {action} {path}: {source}")]
    Io {
        /// `read`, `write` or `create`.
        action: &'static str,
        /// The file or directory.
        path: PathBuf,
        /// What went wrong.
        source: std::io::Error,
    },
    /// Training, or reading the dataset or the weights.
    #[error(transparent)]
    Train(#[from] modalforge::predictor::train::TrainError),
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
    /// Building or solving an object.
    #[error(transparent)]
    Object(#[from] object::ObjectError),
    /// Reading a recording.
    #[error(transparent)]
    Recording(#[from] modalforge::analysis::wav::WavError),
    /// Analysing a recording.
    #[error(transparent)]
    Analysis(#[from] modalforge::analysis::AnalysisError),
    /// Fitting a material to a recording.
    #[error(transparent)]
    MaterialFit(#[from] modalforge::analysis::material_fit::MaterialFitError),
    /// Playing the modes found in a recording.
    #[error(transparent)]
    Resynth(#[from] modalforge::analysis::resynth::ResynthError),
}

fn dataset_command(args: &DatasetArgs) -> Result<String, CliError> {
    let threads = args
        .threads
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    if threads == 0 {
        return Err(CliError::Option(
            "--threads 0: use at least one thread".into(),
        ));
    }
    let summary = modalforge::predictor::dataset::generate(
        &args.out,
        args.count,
        args.held_out,
        args.seed,
        threads,
        args.element,
    )
    .map_err(|source| CliError::Io {
        action: "write",
        path: args.out.clone(),
        source,
    })?;
    Ok(format!(
        "{}: {} written, {} kept from an earlier run, {} failed",
        args.out.display(),
        summary.written,
        summary.kept,
        summary.failed
    ))
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

/// Runs the CLI; returns the text to print on success.
pub fn run(cli: Cli) -> Result<String, CliError> {
    match cli.command {
        Command::DemoModes => Ok(modalforge::demo::steel_bar().to_json()),
        Command::Materials => Ok(materials_table()),
        Command::Chart(args) => chart::chart_command(&args),
        Command::Dataset(args) => dataset_command(&args),
        Command::Train(args) => predictor::train_command(&args),
        Command::Predictor(predictor::PredictorCommand::Eval(args)) => {
            predictor::eval_command(&args)
        }
        Command::Predictor(predictor::PredictorCommand::Index(args)) => {
            predictor::index_command(&args)
        }
        Command::Predictor(predictor::PredictorCommand::Sweep(args)) => {
            predictor::sweep_command(&args)
        }
        Command::Modes(args) => modes_command(&args),
        Command::Analyze(args) => analyze::analyze_command(&args),
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
                        "from the mode file".to_string()
                    } else {
                        format!(
                            "{} {}",
                            args.object.material,
                            args.object.shape.as_deref().unwrap_or(&format!(
                                "{} ({} m)",
                                object::DEFAULT_SHAPE,
                                modalforge::demo::BAR_LENGTH_M
                            ))
                        )
                    }
                )
            })
        }
    }
}

fn option_error(msg: String) -> CliError {
    CliError::Option(msg)
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

/// `modalforge modes`.
pub fn modes_command(args: &ModesArgs) -> Result<String, CliError> {
    let object = object::Object::from_args(&args.object, args.fmax)?;
    if args.bands && !object.neural {
        return Err(CliError::Option(
            "--bands shows the predictor's bands: add --solver neural".into(),
        ));
    }
    let report = if object.neural {
        let (predicted, hit) = object.predict(&args.object)?;
        object::neural_report(&object, &predicted, &hit, args.modes, args.fmax, args.bands)
    } else {
        let count = object.count(args.modes, args.fmax)?;
        let basis = object.solve(count, args.object.tolerance)?;
        let hit = object.hit(&args.object)?;
        object::report(&object, &basis, &hit)?
    };
    if args.json {
        return Ok(serde_json::to_string_pretty(&report).expect("report serialises"));
    }
    if object.neural {
        return Ok(neural_text(&report));
    }
    let mut out = format!(
        "{} voxels ({}x{}x{}, {:.4} m), {} DOFs, {} {}, {} rigid modes, {} components; \
         assembly {:.0} ms, factor/setup {:.0} ms, iterations {:.0} ms\n",
        report.voxels,
        report.grid[0],
        report.grid[1],
        report.grid[2],
        report.voxel_size_m,
        report.dofs,
        report.element,
        report.solver,
        report.rigid_modes,
        report.components,
        report.timings_ms.assemble,
        report.timings_ms.setup,
        report.timings_ms.iterate
    );
    out.push_str("  #    freq_hz  decay_per_s        gain  residual\n");
    for (i, (m, r)) in report.modes.iter().zip(&report.residuals).enumerate() {
        if m.overdamped {
            out.push_str(&format!(
                "{:>3}  overdamped ({:.1} Hz undamped)\n",
                i + 1,
                m.natural_hz
            ));
        } else {
            out.push_str(&format!(
                "{:>3} {:>10.2} {:>12.3} {:>11.3e} {:>9.1e}\n",
                i + 1,
                m.freq_hz,
                m.decay_per_s,
                m.gain,
                r
            ));
        }
    }
    Ok(out.trim_end().to_string())
}

/// The `modes --solver neural` text: one line per predicted mode (no residuals: a prediction
/// has none), and the bands with `--bands`.
fn neural_text(report: &object::ModesReport) -> String {
    let mut out = format!(
        "{} voxels ({}x{}x{}, {:.4} m), {}; neural predictor, {:.1} ms\n  #    freq_hz  decay_per_s        gain\n",
        report.voxels,
        report.grid[0],
        report.grid[1],
        report.grid[2],
        report.voxel_size_m,
        report.material,
        report.timings_ms.solve
    );
    for (i, m) in report.modes.iter().enumerate() {
        out.push_str(&format!(
            "{:>3} {:>10.2} {:>12.3} {:>11.3e}\n",
            i + 1,
            m.freq_hz,
            m.decay_per_s,
            m.gain
        ));
    }
    if let Some(bands) = &report.bands {
        out.push_str("band    freq_hz  mask x y z  log-amplitude x     y     z\n");
        for b in bands {
            let f = b.freq_hz.map_or("-".to_string(), |f| format!("{f:.2}"));
            let on = |m: bool| if m { '1' } else { '0' };
            out.push_str(&format!(
                "{:>4} {:>10}       {} {} {}  {:>17.3} {:>5.3} {:>5.3}\n",
                b.band,
                f,
                on(b.mask[0]),
                on(b.mask[1]),
                on(b.mask[2]),
                b.log_amplitude[0],
                b.log_amplitude[1],
                b.log_amplitude[2]
            ));
        }
    }
    out.trim_end().to_string()
}

fn materials_table() -> String {
    let mut out = String::from("name            E (Pa)    rho (kg/m3)  nu     damping models\n");
    for name in modalforge::material::preset_names() {
        if let Ok(m) = modalforge::material::Material::preset(name) {
            let models: Vec<&str> = m.damping_models.iter().map(|(n, _)| n.as_str()).collect();
            out.push_str(&format!(
                "{:<15} {:<9.3e} {:<12} {:<6} {}\n",
                name,
                m.youngs_modulus_pa,
                m.density_kg_m3,
                m.poisson_ratio,
                models.join(", ")
            ));
        }
    }
    out.trim_end().to_string()
}
