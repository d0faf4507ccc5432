//! The `modalforge` command line.
//!
//! Where it sits: the outermost layer. `modes` builds an object ([`object`]: shape, material,
//! element, solver, strike), solves it and prints its modes; `render` ([`render`]) takes a mode file or solves
//! an object the same way, culls the modes, renders one strike or scrape with
//! [`modalforge::synth::render`] and writes a WAV with hound. Every failure is one line on stderr and
//! a non-zero exit, never a panic. `chart` ([`chart`]) sweeps the solvers' speed against their
//! accuracy.

pub mod analyze;
pub mod chart;
pub mod object;
pub mod predictor;
pub mod render;

use clap::builder::TypedValueParser;
use clap::{Parser, Subcommand};
use modalforge::modes::ModeFileError;
use modalforge::synth::render::{BankKind, RenderError};
use modalforge::synth::ExcitationError;
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
    // This process only labels: keep the large factors' memory between objects.
    modalforge::eigen::keep_buffers_up_to(
        modalforge::predictor::dataset::KEPT_BYTES_WHILE_LABELLING,
    );
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
            let summary = render::render_command(&args)?;
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
