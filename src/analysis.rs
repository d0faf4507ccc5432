//! Listening to real objects: the damped modes of a recorded strike.
//!
//! Where it sits: beside the FEM path. A recording ([`wav::read_mono`]) goes through
//! [`extract`]: the strike's onset, then a band split ([`bands`]) and the matrix pencil
//! ([`pencil`]) in each band, and out come [`ExtractedMode`]s (frequency, decay rate, amplitude
//! and phase at the onset) in the same units as the mode files `render --modes` plays
//! ([`crate::modes`]). The method is a subspace one (matrix pencil, Hua and Sarkar 1990;
//! ESPRIT, Roy and Kailath 1989), band-split so it scales to long recordings: a band holds a
//! few modes and a few hundred decimated samples, so its SVD is small.
//!
//! A strike rings as `x(t) = sum_i a_i e^(-d_i t) cos(2 pi f_i t + phi_i)` from its onset
//! (Sterling and Lin 2016, sec. 4: the modal model a recording is fitted with). What the modes
//! do not explain is reported (`residual_db`), and so is the noise level (`noise_floor_db`):
//! a mode whose amplitude at the onset lies below it is not reported.
//!
//! The modes' decay rates are then fitted by the damping laws ([`damping_fit`]).
//!
//! Given the struck object's shape, size and hit, [`material_fit`] then finds its material's
//! `E/rho` and Poisson's ratio from the modes.
//!
//! [`resynth`] plays the modes back through the oscillator bank and measures how far that
//! sounds from the recording.
//!
//! A second method, iterative spectral peak picking with subtraction ([`peaks`], Sterling and
//! Lin 2016), is one option away ([`Method`]); the pencil is the default, the more accurate
//! on strikes with known modes (ARCHITECTURE.md, "Recording analysis decisions").
//!
//! [`refine`] then optionally moves the modes to fit the recording's spectrum more closely.
//!
//! The plugin's "Match recording" uses the same steps (`plugin/src/editor/matching.rs`).
//!
//! Not yet built (issue 14): playing a recording's modes in the plugin as the object.

pub mod bands;
pub mod damping_fit;
pub mod fft;
pub mod material_fit;
pub mod peaks;
pub mod pencil;
pub mod refine;
pub mod resynth;
pub mod synthetic;
pub mod wav;

use faer::c64;
use std::f64::consts::TAU;

/// One mode found in a recording: `a e^(-d t) cos(2 pi f t + phi)`, `t` from the onset.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ExtractedMode {
    /// Frequency, Hz.
    pub freq_hz: f64,
    /// Amplitude decay rate, 1/s.
    pub decay_per_s: f64,
    /// Amplitude at the onset, in the recording's full-scale units.
    pub gain: f64,
    /// Phase at the onset, radians.
    pub phase: f64,
}

/// What [`extract`] found.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Analysis {
    /// The modes, by frequency.
    pub modes: Vec<ExtractedMode>,
    /// Seconds from the recording's start to the strike.
    pub onset_s: f64,
    /// Energy the modes leave unexplained over the analysed span, dB relative to its energy.
    pub residual_db: f64,
    /// The noise level (RMS per sample), dB relative to the recording's peak.
    pub noise_floor_db: f64,
    /// Damping laws fitted to the modes ([`damping_fit`]).
    pub damping: damping_fit::DampingFits,
}

/// How [`extract`] finds the modes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Method {
    /// Band-split matrix pencil (a subspace method; resolves pairs 2 Hz apart): the default,
    /// the better of the two on the synthetic strikes and the real recordings (ARCHITECTURE.md).
    #[default]
    Pencil,
    /// Iterative spectral peak picking with local fits and subtraction (Sterling and Lin 2016).
    Peaks,
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        crate::cli_name(self, f)
    }
}

/// Settings of [`extract`].
#[derive(Clone, Copy, Debug)]
pub struct AnalysisOptions {
    /// Which method finds the modes.
    pub method: Method,
    /// Most modes reported (the loudest at the onset).
    pub max_modes: usize,
    /// Lowest frequency analysed, Hz.
    pub low_hz: f64,
    /// Highest frequency analysed, Hz (capped at 0.45 of the sample rate).
    pub high_hz: f64,
}

impl Default for AnalysisOptions {
    fn default() -> Self {
        AnalysisOptions {
            method: Method::Pencil,
            max_modes: 200,
            low_hz: 40.0,
            high_hz: 20_000.0,
        }
    }
}

/// Why a recording could not be analysed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum AnalysisError {
    /// Fewer samples than the shortest strike worth analysing.
    #[error("the recording is {0:.3} s long; give at least 50 ms of a struck object ringing")]
    TooShort(f64),
    /// A NaN or infinite sample.
    #[error("sample {0} is not a finite number; the file is corrupt")]
    NonFinite(usize),
    /// Nothing but silence (or DC).
    #[error("the recording is silent (or only a constant offset): nothing rings in it")]
    Silent,
    /// The sample rate cannot be right.
    #[error("sample rate {0} Hz: give a recording at 8 kHz or more")]
    BadRate(f64),
}

/// Shortest recording accepted, seconds.
pub const MIN_DURATION_S: f64 = 0.05;

/// Onset frames are this long, seconds.
const FRAME_S: f64 = 0.001;

/// The onset is the first frame within this many dB of the loudest frame's energy.
const ONSET_DB: f64 = 20.0;

/// Band layout of the finest level: each band a fifth of its lower edge wide, 12-400 Hz.
const BAND_RELATIVE_WIDTH: f64 = 0.2;
const BAND_WIDTH_HZ: (f64, f64) = (12.0, 250.0);

/// Levels of bands, each [`LEVEL_FACTOR`] times wider than the one before. A band `w` wide
/// sees its modes from `6 / w` s after the onset on (the filter's half-length,
/// [`bands::HALF_LENGTH_PER_INVERSE_WIDTH`]): fine bands resolve modes 2 Hz apart but lose
/// the ones that die within that time, which wider bands catch. Each level answers for the
/// decay rates it sees best (see [`extract`]).
const LEVELS: usize = 4;
const LEVEL_FACTOR: f64 = 4.0;

/// At most this many poles per band: a band the width of a few semitones seldom holds more.
const MAX_POLES_PER_BAND: usize = 40;

/// Modes more than this many dB below the loudest are not reported: the band filters
/// (Blackman-windowed sincs) reject a neighbouring band's modes by ~74 dB, and what leaks
/// through can look like a mode.
const DYNAMIC_RANGE_DB: f64 = 70.0;

/// Modes reported must stand this many dB above the noise at the onset.
const MIN_SNR_DB: f64 = 6.0;

/// Largest amplitude at the onset a reported mode may have, relative to the recording's
/// peak: modes that cancel at the onset can each exceed the peak a little, never by this.
const MAX_GAIN_OVER_PEAK: f64 = 2.0;

/// The modes of a recorded strike (module docs).
pub fn extract(
    samples: &[f64],
    sample_rate_hz: f64,
    options: &AnalysisOptions,
) -> Result<Analysis, AnalysisError> {
    let fs = sample_rate_hz;
    if !(fs >= 8_000.0 && fs.is_finite()) {
        return Err(AnalysisError::BadRate(fs));
    }
    if let Some(i) = samples.iter().position(|v| !v.is_finite()) {
        return Err(AnalysisError::NonFinite(i));
    }
    let duration = samples.len() as f64 / fs;
    if duration < MIN_DURATION_S {
        return Err(AnalysisError::TooShort(duration));
    }
    let x = centred(samples);
    let peak = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if peak.is_nan() || peak <= 1e-9 {
        return Err(AnalysisError::Silent);
    }
    let start = onset(&x, fs);
    let onset_s = start as f64 / fs;
    let high = options.high_hz.min(0.45 * fs);
    let (mut modes, noise_rms) = match options.method {
        Method::Pencil => pencil_modes(&x, fs, start, (options.low_hz, high)),
        Method::Peaks => {
            let noise_rms = noise_before(&x, start, fs);
            let modes = peaks::peaks(
                &x,
                fs,
                start,
                (options.low_hz, high),
                noise_rms,
                options.max_modes,
            );
            (modes, noise_rms)
        }
    };
    // A mode louder at the onset than the recording ever gets is a fast decay seen late (in a
    // wide band) and extrapolated back: real recordings have them (a 0.4 s bell gave a 200 Hz
    // "mode" at 290x its peak); never a mode.
    modes.retain(|m| m.gain <= MAX_GAIN_OVER_PEAK * peak);
    // A mode whose decay rate lies at a boundary of two levels' windows can be taken from
    // both (their estimates fall on either side of it): kept once.
    modes.sort_by(|a, b| a.freq_hz.total_cmp(&b.freq_hz));
    modes.dedup_by(|b, a| {
        (b.freq_hz - a.freq_hz).abs() < 1e-4 * a.freq_hz
            && (b.decay_per_s - a.decay_per_s).abs() < 0.1 * a.decay_per_s
    });
    // Below the loudest mode by more than the band filters reject, a "mode" may be a strong
    // neighbour's leakage.
    let loudest = modes.iter().map(|m| m.gain).fold(0.0, f64::max);
    modes.retain(|m| m.gain >= loudest * 10f64.powf(-DYNAMIC_RANGE_DB / 20.0));
    modes.sort_by(|a, b| b.gain.total_cmp(&a.gain));
    modes.truncate(options.max_modes);
    modes.sort_by(|a, b| a.freq_hz.total_cmp(&b.freq_hz));
    let residual_db = residual_db(&x[start..], fs, &modes);
    let damping = damping_fit::fit(
        &modes
            .iter()
            .map(|m| (m.freq_hz, m.decay_per_s))
            .collect::<Vec<_>>(),
    );
    Ok(Analysis {
        damping,
        modes,
        onset_s,
        residual_db,
        noise_floor_db: 20.0 * (noise_rms.max(1e-300) / peak).log10(),
    })
}

/// The band-split matrix pencil's modes (module docs), and the noise's RMS per sample (the
/// median over the finest bands).
fn pencil_modes(
    x: &[f64],
    fs: f64,
    start: usize,
    (low_hz, high_hz): (f64, f64),
) -> (Vec<ExtractedMode>, f64) {
    let mut modes = Vec::new();
    let mut noise = Vec::new();
    for level in 0..LEVELS {
        let scale = LEVEL_FACTOR.powi(level as i32);
        let widths = (BAND_WIDTH_HZ.0 * scale, BAND_WIDTH_HZ.1 * scale);
        let edges = bands::edges(low_hz, high_hz, BAND_RELATIVE_WIDTH * scale, widths);
        for w in edges.windows(2) {
            let band = bands::band(x, fs, start, w[0], w[1]);
            let Some((terms, noise_rms)) = pencil::pencil(&band.samples, MAX_POLES_PER_BAND) else {
                continue;
            };
            if level == 0 {
                // The band's noise per full-rate sample: white noise of RMS sigma leaves
                // sigma sqrt(2 width / fs) in a band `width` wide (complex, both sides).
                noise.push(noise_rms / (2.0 * (w[1] - w[0]) / fs).sqrt());
            }
            for t in terms {
                let Some(m) = mode_of(&t, &band) else {
                    continue;
                };
                // Above the band's noise at its first sample (the amplitude there is |c|).
                let snr = 20.0 * (t.amplitude.norm() / noise_rms.max(1e-300)).log10();
                let inside = m.freq_hz >= w[0] && m.freq_hz < w[1];
                let decays = decay_window(m.freq_hz, level);
                if inside && snr >= MIN_SNR_DB && (decays.0..decays.1).contains(&m.decay_per_s) {
                    modes.push(m);
                }
            }
        }
    }
    noise.sort_by(f64::total_cmp);
    (modes, noise.get(noise.len() / 2).copied().unwrap_or(0.0))
}

/// The noise's RMS per sample for the peak picker: the quietest of the lead-in before the
/// onset and the recording's last 20 ms (where the strike has died, or mostly).
fn noise_before(x: &[f64], start: usize, fs: f64) -> f64 {
    let rms = |s: &[f64]| (s.iter().map(|v| v * v).sum::<f64>() / s.len().max(1) as f64).sqrt();
    let tail = &x[x.len().saturating_sub((0.02 * fs) as usize)..];
    let lead = &x[..start.saturating_sub((0.001 * fs) as usize)];
    if lead.len() >= 64 {
        rms(lead).min(rms(tail))
    } else {
        rms(tail)
    }
}

/// The recording less its mean (its DC offset): what [`extract`] analyses and what a
/// resynthesis is compared with.
pub fn centred(samples: &[f64]) -> Vec<f64> {
    let mean = samples.iter().sum::<f64>() / samples.len().max(1) as f64;
    samples.iter().map(|v| v - mean).collect()
}

/// The decay rates level `level` answers for at `freq_hz`: from where the level below (bands
/// a quarter as wide, whose first sample comes four times later) has lost one neper of a mode
/// to where this one has; the finest level from zero, the widest to any. The windows tile
/// the decay axis at every frequency, so each mode is taken from one level.
fn decay_window(freq_hz: f64, level: usize) -> (f64, f64) {
    let scale = LEVEL_FACTOR.powi(level as i32);
    let width = (freq_hz * BAND_RELATIVE_WIDTH).clamp(BAND_WIDTH_HZ.0, BAND_WIDTH_HZ.1) * scale;
    // A band `width` wide starts `HALF_LENGTH_PER_INVERSE_WIDTH / width` s after the onset.
    let lost_here = width / bands::HALF_LENGTH_PER_INVERSE_WIDTH;
    (
        if level == 0 {
            0.0
        } else {
            lost_here / LEVEL_FACTOR
        },
        if level + 1 == LEVELS {
            f64::INFINITY
        } else {
            lost_here
        },
    )
}

/// The sample where the strike begins: the start of the first 1 ms frame whose energy is
/// within [`ONSET_DB`] of the loudest frame's and halfway (in dB) from the noise (the 10th
/// percentile of the frames: the tail of a strike has died into it) to the loudest.
fn onset(x: &[f64], fs: f64) -> usize {
    let frame = ((FRAME_S * fs) as usize).max(1);
    let energies: Vec<f64> = x
        .chunks(frame)
        .map(|c| c.iter().map(|v| v * v).sum::<f64>())
        .collect();
    let loudest = energies.iter().cloned().fold(0.0, f64::max);
    let mut sorted = energies.clone();
    sorted.sort_by(f64::total_cmp);
    let noise = sorted[sorted.len() / 10];
    let threshold = (loudest * 10f64.powf(-ONSET_DB / 10.0)).max((loudest * noise).sqrt());
    let k = energies.iter().position(|&e| e >= threshold).unwrap_or(0);
    // To the sample: the first one in this frame or the one before that stands out of the
    // noise (5 sigma) and is a tenth of the frame's peak.
    let from = k.saturating_sub(1) * frame;
    let to = ((k + 1) * frame).min(x.len());
    let sigma = (noise / frame as f64).sqrt();
    let peak = x[k * frame..to].iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let level = (5.0 * sigma).max(0.1 * peak);
    (from..to)
        .find(|&i| x[i].abs() >= level)
        .unwrap_or(k * frame)
}

/// The mode a band's term stands for, with its amplitude and phase carried back to the
/// analysis start (the onset). `None` for a growing or non-finite term.
fn mode_of(t: &pencil::Term, band: &bands::Band) -> Option<ExtractedMode> {
    let ln = t.pole.ln();
    let decay = -ln.re * band.rate_hz;
    let freq = band.centre_hz + ln.im * band.rate_hz / TAU;
    if !(decay > 0.0 && decay.is_finite() && freq > 0.0) {
        return None;
    }
    // c = (a / 2) e^(i phi) e^((-d + i 2 pi (f - f_c)) t0) at the band's first instant t0.
    let t0 = band.start_s;
    let back = c64::from_polar((decay * t0).exp(), -TAU * (freq - band.centre_hz) * t0);
    let at_onset = t.amplitude * back * 2.0;
    Some(ExtractedMode {
        freq_hz: freq,
        decay_per_s: decay,
        gain: at_onset.norm(),
        phase: at_onset.arg(),
    })
}

/// `10 log10` of the energy `x` keeps after the modes are subtracted, over its energy (first
/// second at most).
fn residual_db(x: &[f64], fs: f64, modes: &[ExtractedMode]) -> f64 {
    let n = x.len().min(fs as usize);
    let (mut total, mut left) = (0.0, 0.0);
    for (i, &v) in x.iter().take(n).enumerate() {
        let t = i as f64 / fs;
        let model: f64 = modes
            .iter()
            .map(|m| m.gain * (-m.decay_per_s * t).exp() * (TAU * m.freq_hz * t + m.phase).cos())
            .sum();
        total += v * v;
        left += (v - model) * (v - model);
    }
    10.0 * (left.max(1e-300) / total.max(1e-300)).log10()
}
