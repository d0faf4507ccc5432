//! `modalforge analyze`: the modes of a recorded strike ([`modalforge::analysis`]).
//!
//! Where it sits: beside `modes`; its JSON is itself a mode file for `render --modes` (the
//! `phase` field, which mode files do not have, is ignored there).

use super::CliError;
use modalforge::analysis::{self, AnalysisOptions};
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
    /// Most modes reported (the loudest at the onset).
    #[arg(long, value_name = "N", default_value_t = 200,
          value_parser = clap::value_parser!(u32).range(1..=4000))]
    pub max_modes: u32,
}

/// Runs `modalforge analyze`.
pub fn analyze_command(args: &AnalyzeArgs) -> Result<String, CliError> {
    let (samples, rate) = analysis::wav::read_mono(&args.recording)?;
    let options = AnalysisOptions {
        max_modes: args.max_modes as usize,
        ..AnalysisOptions::default()
    };
    let found = analysis::extract(&samples, rate, &options)?;
    if args.json {
        return Ok(serde_json::to_string_pretty(&found).expect("the analysis serialises"));
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
    Ok(out)
}
