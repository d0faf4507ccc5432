//! `modalforge train` and `modalforge predictor eval`: fitting the neural predictor and scoring
//! it on the held-out split.
//!
//! Where it sits: between [`modalforge::predictor::dataset`]'s records on disk and
//! [`modalforge::predictor::train`] / [`modalforge::predictor::metrics`].

use super::chart::{methods_to_csv, MethodRow};
use super::CliError;
use modalforge::predictor::band_net::BandNet;
use modalforge::predictor::dataset::{Family, Record};
use modalforge::predictor::pitch_index::PitchIndex;
use modalforge::predictor::{baseline, metrics, train, Nets};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Options of `modalforge train`.
#[derive(clap::Args, Debug)]
pub struct TrainArgs {
    /// Dataset directory (made by `modalforge dataset`); give it more than once to train on
    /// several datasets (made with different seeds, labelled with one element).
    #[arg(long, value_name = "DIR", required = true)]
    pub data: Vec<PathBuf>,
    /// Checkpoint directory: model.bpk, optimizer.bpk, state.json (a run resumes from it).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Epochs in all (a resumed run continues up to this many).
    #[arg(long, value_name = "N", default_value_t = 30, value_parser = clap::value_parser!(u32).range(1..=10_000))]
    pub epochs: u32,
    /// Objects per optimiser step.
    #[arg(long, value_name = "N", default_value_t = 8, value_parser = clap::value_parser!(u32).range(1..=256))]
    pub batch: u32,
    /// Initial learning rate (Adam).
    #[arg(long, value_name = "LR", default_value_t = 2e-3)]
    pub learning_rate: f64,
    /// Epochs between halvings of the learning rate.
    #[arg(long, value_name = "N", default_value_t = 8)]
    pub halve_every: usize,
    /// Held-out objects scored after each epoch.
    #[arg(long, value_name = "N", default_value_t = 100)]
    pub validate: usize,
    /// Shuffling and augmentation seed.
    #[arg(long, value_name = "S", default_value_t = 1)]
    pub seed: u64,
    /// Threads [default: every core].
    #[arg(long, value_name = "N")]
    pub threads: Option<usize>,
    /// Train the band network (which bands hold a mode; `assets/predictor/bandnet.bpk`) on
    /// band presence alone, instead of the cell network (`modenet.bpk`).
    #[arg(long)]
    pub bands_only: bool,
    /// Start a new run from these weights (a model.bpk of the same network, e.g. the shipped
    /// one, to fine-tune it on more data) with a fresh optimiser; a run that resumes ignores it.
    #[arg(long, value_name = "FILE")]
    pub init: Option<PathBuf>,
}

/// `modalforge predictor ...`.
#[derive(clap::Subcommand, Debug)]
pub enum PredictorCommand {
    /// Score the predictor on the held-out split: mask recall and precision, amplitude MSE,
    /// pitch error, inference time; beside the nearest-shape baseline.
    Eval(EvalArgs),
    /// Build the pitch index (the band frequencies of a dataset's training shapes, which the
    /// predictor's bands play at) from a dataset's training split.
    Index(IndexArgs),
    /// Choose the predictor's operating point: its figures on a dataset's training split at
    /// every mask threshold, presence shift and near-twin distance tried (run it on objects of
    /// the training families that training never saw, e.g. `dataset --count 200 --held-out 0
    /// --seed 7`; never on the held-out families).
    Sweep(SweepArgs),
}

/// Options of `modalforge predictor sweep`.
#[derive(clap::Args, Debug)]
pub struct SweepArgs {
    /// Dataset directory (its training split is scored).
    #[arg(long, value_name = "DIR")]
    pub data: PathBuf,
    /// Weights to score (a checkpoint's model.bpk).
    #[arg(long, value_name = "FILE.bpk")]
    pub weights: PathBuf,
    /// Band network weights (a `train --bands-only` checkpoint's model.bpk), which decide which
    /// bands hold a mode [default: none, the cell network's own presence branch; the shipped
    /// predictor's is assets/predictor/bandnet.bpk].
    #[arg(long, value_name = "FILE.bpk")]
    pub band_weights: Option<PathBuf>,
    /// Pitch index the bands play at [default: the shipped one].
    #[arg(long, value_name = "FILE")]
    pub pitch_index: Option<PathBuf>,
}

/// Options of `modalforge predictor index`.
#[derive(clap::Args, Debug)]
pub struct IndexArgs {
    /// Dataset directory (its training split is indexed); give it more than once to index the
    /// training splits of several datasets (made with different seeds), in the order given.
    #[arg(long, value_name = "DIR", required = true)]
    pub data: Vec<PathBuf>,
    /// The index file to write (the shipped one is assets/predictor/pitch-index.bin).
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
}

/// Options of `modalforge predictor eval`.
#[derive(clap::Args, Debug)]
pub struct EvalArgs {
    /// Dataset directory (its held-out split is scored).
    #[arg(long, value_name = "DIR")]
    pub data: PathBuf,
    /// Weights to score (a checkpoint's model.bpk).
    #[arg(long, value_name = "FILE.bpk")]
    pub weights: PathBuf,
    /// Band network weights (a `train --bands-only` checkpoint's model.bpk), which decide which
    /// bands hold a mode [default: none, the cell network's own presence branch; the shipped
    /// predictor's is assets/predictor/bandnet.bpk].
    #[arg(long, value_name = "FILE.bpk")]
    pub band_weights: Option<PathBuf>,
    /// Score at most this many held-out objects [default: all].
    #[arg(long, value_name = "N")]
    pub limit: Option<usize>,
    /// Pitch index the bands play at [default: the shipped one].
    #[arg(long, value_name = "FILE")]
    pub pitch_index: Option<PathBuf>,
    /// Also write each method's figures to this CSV, for `modalforge chart --predictor FILE`.
    #[arg(long, value_name = "FILE.csv")]
    pub csv: Option<PathBuf>,
    /// Score the dataset's training split instead of its held-out one: objects of the training
    /// families that training never saw (`dataset --count 200 --held-out 0 --seed 7`), so the
    /// per-family figures cover every family. No shape matching then.
    #[arg(long)]
    pub training_split: bool,
}

/// Reads a pitch index file, or the shipped one.
fn read_pitch_index(path: Option<&Path>) -> Result<Arc<PitchIndex>, CliError> {
    let bad = |e: &dyn std::fmt::Display, name: &str| {
        CliError::Option(format!("pitch index {name}: {e}"))
    };
    match path {
        None => modalforge::predictor::shipped_pitch_index().map_err(|e| bad(&e, "(shipped)")),
        Some(path) => {
            let name = path.display().to_string();
            modalforge::limits::check_file_size(
                path,
                modalforge::limits::MAX_WEIGHTS_BYTES,
                "pitch index",
                "give a file made by `modalforge predictor index`",
            )
            .map_err(|e| bad(&e, &name))?;
            let bytes = std::fs::read(path).map_err(|source| CliError::Io {
                action: "read",
                path: path.to_path_buf(),
                source,
            })?;
            Ok(Arc::new(
                PitchIndex::from_bytes(&bytes).map_err(|e| bad(&e, &name))?,
            ))
        }
    }
}

/// Runs `modalforge predictor index`.
pub fn index_command(args: &IndexArgs) -> Result<String, CliError> {
    let mut index = PitchIndex::default();
    for data in &args.data {
        let before = index.len();
        // Decoded one at a time: a record's labels are about 2 MB.
        for blob in train::read_split(data, false)? {
            if let Ok(r) = Record::decode(&blob) {
                index.push(&r.grid, &r.labels);
            }
        }
        if index.len() == before {
            return Err(CliError::Option(format!(
                "no training records under {}: make them with `modalforge dataset --out {}`",
                data.display(),
                data.display()
            )));
        }
    }
    let bytes = index.to_bytes();
    std::fs::write(&args.out, &bytes).map_err(|source| CliError::Io {
        action: "write",
        path: args.out.clone(),
        source,
    })?;
    Ok(format!(
        "indexed {} training shapes in {} ({} bytes)",
        index.len(),
        args.out.display(),
        bytes.len()
    ))
}

fn thread_pool(threads: Option<usize>) -> Result<rayon::ThreadPool, CliError> {
    let threads =
        threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    if threads == 0 {
        return Err(CliError::Option(
            "--threads 0: use at least one thread".into(),
        ));
    }
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| CliError::Option(format!("cannot start {threads} threads: {e}")))
}

/// Runs `modalforge train`.
pub fn train_command(args: &TrainArgs) -> Result<String, CliError> {
    let options = train::TrainOptions {
        data: args.data.clone(),
        out: args.out.clone(),
        epochs: args.epochs as usize,
        batch: args.batch as usize,
        learning_rate: args.learning_rate,
        halve_every: args.halve_every,
        validate: args.validate,
        seed: args.seed,
        bands_only: args.bands_only,
        init: args.init.clone(),
    };
    if !(args.learning_rate.is_finite() && args.learning_rate > 0.0 && args.learning_rate < 1.0) {
        return Err(CliError::Option(format!(
            "--learning-rate {}: use a value in (0, 1), e.g. 2e-3",
            args.learning_rate
        )));
    }
    let state = thread_pool(args.threads)?.install(|| train::train(&options))?;
    let last = state.history.last();
    if args.bands_only {
        return Ok(format!(
            "{} epochs, {} steps, {:.0} s of training; band network weights in {}{}",
            state.epoch,
            state.step,
            state.seconds,
            args.out.join("model.bpk").display(),
            last.and_then(|r| r.presence)
                .map(|p| format!("; held-out {p}"))
                .unwrap_or_default()
        ));
    }
    Ok(format!(
        "{} epochs, {} steps, {:.0} s of training; weights in {}{}",
        state.epoch,
        state.step,
        state.seconds,
        args.out.join("model.bpk").display(),
        last.and_then(|r| r.validation.as_ref())
            .map(|m| format!("; held-out: {m}"))
            .unwrap_or_default()
    ))
}

/// The first `limit` records of a dataset's held-out or training split that decode (a damaged
/// one is skipped, as training skips it).
fn decoded_split(data: &Path, held_out: bool, limit: usize) -> Result<Vec<Record>, CliError> {
    Ok(train::read_split(data, held_out)?
        .iter()
        .filter_map(|b| Record::decode(b).ok())
        .take(limit)
        .collect())
}

/// The band network of `--band-weights`, when given.
fn load_bands(
    path: Option<&Path>,
    device: &burn::tensor::Device,
) -> Result<Option<BandNet>, CliError> {
    path.map(|p| train::load_band_net(p, device))
        .transpose()
        .map_err(CliError::from)
}

/// Runs `modalforge predictor eval`.
pub fn eval_command(args: &EvalArgs) -> Result<String, CliError> {
    let device = burn::tensor::Device::flex();
    let model = train::load_model(&args.weights, &device)?;
    let bands = load_bands(args.band_weights.as_deref(), &device)?;
    let nets = Nets {
        cells: &model,
        bands: bands.as_ref(),
    };
    let held_out = !args.training_split;
    let held = decoded_split(&args.data, held_out, args.limit.unwrap_or(usize::MAX))?;
    if held.is_empty() {
        return Err(CliError::Option(format!(
            "no {} records under {}: make them with `modalforge dataset --out {}`",
            if held_out {
                "held-out"
            } else {
                "training-split"
            },
            args.data.display(),
            args.data.display()
        )));
    }
    let pitch = read_pitch_index(args.pitch_index.as_deref())?;
    let one = thread_pool(Some(1))?;
    let timed = |f: &(dyn Fn() -> Vec<metrics::ObjectScore> + Sync)| {
        let t0 = std::time::Instant::now();
        let scores = one.install(f);
        (scores, t0.elapsed().as_secs_f64() * 1e3 / held.len() as f64)
    };
    let (played_each, played_ms) =
        timed(&|| metrics::evaluate_each(nets, Some(&pitch), &held, &device));
    let (alone_each, alone_ms) = timed(&|| metrics::evaluate_each(nets, None, &held, &device));
    let (played, alone) = (
        metrics::summarise(&played_each),
        metrics::summarise(&alone_each),
    );
    let mut rows = vec![
        MethodRow::new("network + pitch index", &played, played_ms),
        MethodRow::new("network alone", &alone, alone_ms),
    ];
    let mut out = format!(
        "network:        {played} ({played_ms:.1} ms per shape scored with its pitch index, batches of 8, one thread)\n\
         network alone:  {alone} (the band frequencies from its own head)\n"
    );
    let train = if held_out {
        decoded_split(&args.data, false, usize::MAX)?
    } else {
        Vec::new()
    };
    if train.is_empty() {
        let _ = writeln!(
            out,
            "shape matching: no training records under {} to match against",
            args.data.display()
        );
    } else {
        let matcher = baseline::ShapeMatch::new(&train);
        let t0 = std::time::Instant::now();
        let scores: Vec<metrics::ObjectScore> = held
            .iter()
            .filter_map(|r| Some(metrics::score(matcher.predict(&r.grid)?, &r.labels)))
            .collect();
        let matched_ms = t0.elapsed().as_secs_f64() * 1e3 / held.len() as f64;
        let matched = metrics::summarise(&scores);
        let _ = writeln!(
            out,
            "shape matching: {matched} (nearest of {} training shapes, {matched_ms:.1} ms per shape)",
            train.len()
        );
        rows.push(MethodRow::new("shape matching", &matched, matched_ms));
    }
    // The product's progressive first answer, as a predictor: FEM at half the resolution.
    let element = modalforge::predictor::SHIPPED_LABEL_ELEMENT;
    let (mut coarse_each, mut times_ms) = (Vec::new(), Vec::new());
    one.install(|| {
        for r in &held {
            let t0 = std::time::Instant::now();
            let answer = baseline::coarse_fem(&r.grid, element);
            let ms = t0.elapsed().as_secs_f64() * 1e3;
            coarse_each.push(answer.ok().map(|encoding| {
                times_ms.push(ms);
                metrics::score(&encoding, &r.labels)
            }));
        }
    });
    let failed = coarse_each.iter().filter(|s| s.is_none()).count();
    let coarse = metrics::summarise(&coarse_each.iter().flatten().cloned().collect::<Vec<_>>());
    let mean_ms = times_ms.iter().sum::<f64>() / times_ms.len().max(1) as f64;
    times_ms.sort_by(f64::total_cmp);
    let median_ms = times_ms
        .get(times_ms.len() / 2)
        .copied()
        .unwrap_or(f64::NAN);
    let _ = writeln!(
        out,
        "coarse FEM:     {coarse} (half resolution, {element}, {mean_ms:.1} ms per shape, median {median_ms:.1}; {failed} shapes without a half-resolution grid)"
    );
    rows.push(MethodRow::new("coarse FEM", &coarse, mean_ms));
    // Per family, worst first (by the network's mask F1), the network beside the coarse FEM.
    let mut families: Vec<(Family, metrics::Metrics, metrics::Metrics)> = Vec::new();
    for family in Family::TRAIN.into_iter().chain(Family::HELD_OUT) {
        let of = |each: &mut dyn Iterator<Item = Option<&metrics::ObjectScore>>| {
            let picked: Vec<metrics::ObjectScore> = (held.iter().zip(each))
                .filter(|(r, _)| r.family == family)
                .filter_map(|(_, s)| s.cloned())
                .collect();
            metrics::summarise(&picked)
        };
        let network = of(&mut played_each.iter().map(Some));
        if network.objects > 0 {
            families.push((
                family,
                network,
                of(&mut coarse_each.iter().map(Option::as_ref)),
            ));
        }
    }
    families.sort_by(|a, b| a.1.mask_f1().total_cmp(&b.1.mask_f1()));
    out += "by family, worst first (network + pitch index | coarse FEM):";
    for (family, network, coarse) in &families {
        let _ = write!(
            out,
            "\n  {family:?}: {} objects, recall {:.1} %, precision {:.1} %, MSE {:.4}, pitch {:.1} cents | {:.1} %, {:.1} %, {:.4}, {:.1} cents",
            network.objects,
            100.0 * network.mask_recall,
            100.0 * network.mask_precision,
            network.amplitude_mse,
            network.pitch_median_cents,
            100.0 * coarse.mask_recall,
            100.0 * coarse.mask_precision,
            coarse.amplitude_mse,
            coarse.pitch_median_cents
        );
    }
    if let Some(path) = &args.csv {
        std::fs::write(path, methods_to_csv(&rows)).map_err(|source| CliError::Io {
            action: "write",
            path: path.clone(),
            source,
        })?;
        let _ = write!(out, "\nwrote {}", path.display());
    }
    Ok(out)
}

impl MethodRow {
    fn new(method: &str, m: &metrics::Metrics, time_ms: f64) -> Self {
        Self {
            method: method.to_string(),
            objects: m.objects,
            time_ms,
            recall_percent: 100.0 * m.mask_recall,
            precision_percent: 100.0 * m.mask_precision,
            amplitude_mse: m.amplitude_mse,
            pitch_cents: m.pitch_median_cents,
        }
    }
}

/// Runs `modalforge predictor sweep`.
pub fn sweep_command(args: &SweepArgs) -> Result<String, CliError> {
    let device = burn::tensor::Device::flex();
    let model = train::load_model(&args.weights, &device)?;
    let bands = load_bands(args.band_weights.as_deref(), &device)?;
    let nets = Nets {
        cells: &model,
        bands: bands.as_ref(),
    };
    let records = decoded_split(&args.data, false, usize::MAX)?;
    if records.is_empty() {
        return Err(CliError::Option(format!(
            "no training-split records under {}: make them with `modalforge dataset --out {} \
             --count 200 --held-out 0 --seed 7`",
            args.data.display(),
            args.data.display()
        )));
    }
    let pitch = read_pitch_index(args.pitch_index.as_deref())?;
    let (points, cents) = metrics::sweep(nets, &pitch, &records, &device);
    let mut out = format!(
        "{} objects; masks (pitch at near-twin distance {}):\n\
         threshold  presence  recall  precision     F1  amplitude MSE\n",
        records.len(),
        modalforge::predictor::NEAR_TWIN_DISTANCE
    );
    let best = points
        .iter()
        .map(|p| p.f1())
        .fold(f64::NEG_INFINITY, f64::max);
    for p in &points {
        out += &format!(
            "{:>9.2}  {:>8.1}  {:>5.1} %  {:>7.1} %  {:.3}  {:>13.4}{}\n",
            p.threshold,
            p.presence,
            100.0 * p.metrics.mask_recall,
            100.0 * p.metrics.mask_precision,
            p.f1(),
            p.metrics.amplitude_mse,
            if p.f1() == best { "  <- best F1" } else { "" }
        );
    }
    out += "pitch, median over every band both fill, by near-twin distance:\n";
    for (twin, c) in cents {
        let twin = match twin {
            t if t == f32::NEG_INFINITY => "never".to_string(),
            t if t == f32::INFINITY => "always".to_string(),
            t => format!("{t:.2}"),
        };
        out += &format!("{twin:>9}  {c:.1} cents\n");
    }
    Ok(out.trim_end().to_string())
}
