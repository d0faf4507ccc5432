//! `modalforge analyze`: the modes of a recorded strike ([`modalforge::analysis`]).
//!
//! Where it sits: beside `modes`; its JSON is itself a mode file for `render --modes` (the
//! `phase` field, which mode files do not have, is ignored there). With `--fit-material` it
//! also fits the material of the object the recording was struck from
//! ([`modalforge::analysis::material_fit`]): the object options say its shape, size and hit,
//! `--material` the starting guess.

use super::object::{Object, ObjectArgs};
use super::CliError;
use modalforge::analysis::material_fit::{self, MaterialFitOptions};
use modalforge::analysis::{self, Analysis, AnalysisOptions};
use serde::Serialize;
use std::path::PathBuf;

/// Options of `modalforge analyze`.
#[derive(clap::Args, Debug)]
pub struct AnalyzeArgs {
    /// The recording: a WAV file (8-32-bit PCM or 32-bit float, any rate, mono or stereo).
    #[arg(value_name = "REC.wav")]
    pub recording: PathBuf,
    /// Print JSON: {"modes":[{"freq_hz","decay_per_s","gain","phase"}...], "onset_s",
    /// "residual_db", "noise_floor_db", "damping":{"laws":[...],"best"}}; readable by
    /// `render --modes`.
    #[arg(long)]
    pub json: bool,
    /// How the modes are found.
    #[arg(long, value_name = "NAME", value_enum, default_value_t = analysis::Method::Pencil)]
    pub method: analysis::Method,
    /// Most modes reported (the loudest at the onset).
    #[arg(long, value_name = "N", default_value_t = 200,
          value_parser = clap::value_parser!(u32).range(1..=4000))]
    pub max_modes: u32,
    /// Write the resynthesis (the modes through the oscillator bank, from the onset; 32-bit
    /// float at the recording's rate and length) to this WAV.
    #[arg(long, value_name = "OUT.wav")]
    pub resynth: Option<PathBuf>,
    /// Refine the modes against the recording (frequencies, decays, amplitudes, phases) by a
    /// multi-resolution spectral loss before reporting them (seconds per recording).
    #[arg(long)]
    pub refine: bool,
    /// Fit E/rho and Poisson's ratio of the struck object (its --shape, --size, --hit, as it
    /// was struck; --material is the starting guess, and may be 16x off) to the recording.
    #[arg(long, requires = "shape")]
    pub fit_material: bool,
    /// The struck object, for --fit-material.
    #[command(flatten)]
    pub object: ObjectArgs,
}

/// `analyze`'s JSON: the analysis, and the material when one was fitted.
#[derive(Serialize)]
struct Report<'a> {
    #[serde(flatten)]
    analysis: &'a Analysis,
    resynthesis: Resynthesis,
    #[serde(skip_serializing_if = "Option::is_none")]
    refinement: Option<Refinement>,
    #[serde(skip_serializing_if = "Option::is_none")]
    material: Option<MaterialReport>,
}

/// The spectral loss before and after `--refine` (`analysis::refine`).
#[derive(Serialize)]
struct Refinement {
    loss_before: f64,
    loss_after: f64,
}

/// How the modes sound against the recording (log-mel distance, dB; `analysis::resynth`).
#[derive(Serialize)]
struct Resynthesis {
    /// Every reported mode.
    log_mel_db: f64,
    /// Only the loudest `baseline_modes`.
    baseline_log_mel_db: f64,
    baseline_modes: usize,
}

/// The fitted material as `analyze --json` reports it.
#[derive(Serialize)]
struct MaterialReport {
    /// Young's modulus, Pa: `e_over_rho` times the assumed density.
    youngs_modulus_pa: f64,
    /// The assumed density (frequencies give only `E/rho`): the nearest preset's.
    density_kg_m3: f64,
    poisson_ratio: f64,
    e_over_rho: f64,
    /// The preset nearest the fit, whose density is assumed.
    nearest_preset: String,
    /// One standard deviation of `E/rho` (relative) and Poisson's ratio.
    uncertainty: Uncertainty,
    matched_modes: usize,
    rms_cents: f64,
    solves: usize,
}

#[derive(Serialize)]
struct Uncertainty {
    e_over_rho_relative: f64,
    poisson_ratio: f64,
}

/// Runs `modalforge analyze`.
pub fn analyze_command(args: &AnalyzeArgs) -> Result<String, CliError> {
    let (samples, rate) = analysis::wav::read_mono(&args.recording)?;
    let options = AnalysisOptions {
        method: args.method,
        max_modes: args.max_modes as usize,
        ..AnalysisOptions::default()
    };
    let mut found = analysis::extract(&samples, rate, &options)?;
    let recording = analysis::centred(&samples);
    let refinement = args.refine.then(|| {
        let start = (found.onset_s * rate).round() as usize;
        let refined = analysis::refine::refine(&recording, rate, start, &found.modes);
        found.modes = refined.modes;
        Refinement {
            loss_before: refined.loss_before,
            loss_after: refined.loss_after,
        }
    });
    let (resynthesis, played) = resynthesise(&recording, rate, &found)?;
    if let Some(path) = &args.resynth {
        analysis::wav::write_mono(path, rate, &played)?;
    }
    let material = if args.fit_material {
        Some(fit(&found, &args.object)?)
    } else {
        None
    };
    if args.json {
        let report = Report {
            analysis: &found,
            resynthesis,
            refinement,
            material,
        };
        return Ok(serde_json::to_string_pretty(&report).expect("the analysis serialises"));
    }
    let mut out = format!(
        "{} modes; onset {:.4} s, residual {:.1} dB, noise floor {:.1} dB (re peak)\n{:>12} {:>12} {:>12} {:>8}\n",
        found.modes.len(),
        found.onset_s,
        found.residual_db,
        found.noise_floor_db,
        "freq_hz",
        "decay_per_s",
        "gain",
        "phase"
    );
    for m in &found.modes {
        out.push_str(&format!(
            "{:>12.3} {:>12.3} {:>12.3e} {:>8.3}\n",
            m.freq_hz, m.decay_per_s, m.gain, m.phase
        ));
    }
    out.push_str("damping laws (c = 2 decay against lambda = omega_n^2):\n");
    for law in &found.damping.laws {
        let chosen = if found.damping.best == Some(law.law) {
            "  <- best (BIC)"
        } else {
            ""
        };
        out.push_str(&format!(
            "  {:<10} {:?}: decay rates within {:.1} % RMS{chosen}\n",
            law.law,
            law.parameters,
            100.0 * law.rms_relative_error
        ));
    }
    out.push_str(&format!(
        "resynthesis: log-mel distance {:.2} dB ({} loudest modes only: {:.2} dB)\n",
        resynthesis.log_mel_db, resynthesis.baseline_modes, resynthesis.baseline_log_mel_db
    ));
    if let Some(r) = &refinement {
        out.push_str(&format!(
            "refined: spectral loss {:.4} -> {:.4}\n",
            r.loss_before, r.loss_after
        ));
    }
    if let Some(m) = material {
        out.push_str(&format!(
            "material: E/rho {:.4e} m^2/s^2 (+-{:.2} %), Poisson's ratio {:.3} (+-{:.3}); \
             nearest preset {} ({:.0} kg/m^3 -> E {:.3e} Pa); {} modes matched, {:.1} cents \
             RMS, {} solves\n",
            m.e_over_rho,
            100.0 * m.uncertainty.e_over_rho_relative,
            m.poisson_ratio,
            m.uncertainty.poisson_ratio,
            m.nearest_preset,
            m.density_kg_m3,
            m.youngs_modulus_pa,
            m.matched_modes,
            m.rms_cents,
            m.solves
        ));
    }
    Ok(out)
}

/// The resynthesis of every mode, and the distances of it and of the baseline from the
/// (centred) recording.
fn resynthesise(
    recording: &[f64],
    rate: f64,
    found: &Analysis,
) -> Result<(Resynthesis, Vec<f64>), CliError> {
    use analysis::resynth;
    let start = (found.onset_s * rate).round() as usize;
    let played = resynth::render(&found.modes, rate, found.onset_s, recording.len())?;
    let baseline = resynth::render(
        &resynth::baseline(&found.modes),
        rate,
        found.onset_s,
        recording.len(),
    )?;
    Ok((
        Resynthesis {
            log_mel_db: resynth::log_mel_distance_db(recording, &played, rate, start),
            baseline_log_mel_db: resynth::log_mel_distance_db(recording, &baseline, rate, start),
            baseline_modes: resynth::BASELINE_MODES,
        },
        played,
    ))
}

/// Fits the object's material to the analysed modes, from `--material` as the start.
fn fit(found: &Analysis, object_args: &ObjectArgs) -> Result<MaterialReport, CliError> {
    let object = Object::from_args(object_args, None)?;
    if object.neural {
        return Err(CliError::Option(
            "--fit-material solves the object by FEM: drop --solver neural".into(),
        ));
    }
    let hit = object.hit(object_args)?;
    let start = &object.material;
    let fit = material_fit::fit_material(
        &object.grid,
        object.grid.voxel_size_m(),
        &hit,
        &found.modes,
        &MaterialFitOptions {
            element: object.element,
            start_e_over_rho: start.youngs_modulus_pa / start.density_kg_m3,
            ..MaterialFitOptions::default()
        },
    )?;
    let nearest = material_fit::nearest_preset(&fit);
    Ok(MaterialReport {
        youngs_modulus_pa: fit.e_over_rho * nearest.density_kg_m3,
        density_kg_m3: nearest.density_kg_m3,
        poisson_ratio: fit.poisson_ratio,
        e_over_rho: fit.e_over_rho,
        nearest_preset: nearest.name,
        uncertainty: Uncertainty {
            e_over_rho_relative: fit.e_over_rho_rel_sigma,
            poisson_ratio: fit.poisson_sigma,
        },
        matched_modes: fit.matched,
        rms_cents: fit.rms_cents,
        solves: fit.solves,
    })
}
