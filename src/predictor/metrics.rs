//! How close a predicted band encoding is to FEM's: the figures `modalforge predictor eval`
//! and each training epoch print.
//!
//! Where it sits: [`score`] compares two [`BandEncoding`]s of one object (the prediction and
//! the FEM labels); [`evaluate`] runs the network over held-out records and averages. The
//! definitions follow Deep-Modal (Jin et al. 2020, sec. 5.2, Table 1): recall and
//! precision of the masks and the mean squared error of the normalised log-amplitudes, each
//! averaged per object, here over every struck cell and force direction of the object (the
//! paper draws one random contact position per object: the same expectation, less noise). The
//! predicted amplitude counts only where its mask is on (the paper's eq. 9). Beyond the paper:
//! the pitch error, in cents, of each predicted band frequency against the FEM mode it stands
//! for (bands FEM and the prediction both fill), reported as a median.

use super::bands::{band_edges_hz, BandEncoding, BANDS};
use super::dataset::Record;
use super::pitch_index::PitchIndex;
use burn::tensor::Device;

/// Held-out figures (see the module docs).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Metrics {
    /// Objects scored.
    pub objects: usize,
    /// Mean over objects of the masks' recall.
    pub mask_recall: f64,
    /// Mean over objects of the masks' precision.
    pub mask_precision: f64,
    /// Mean over objects of the log-amplitudes' squared error.
    pub amplitude_mse: f64,
    /// Median pitch error of the band frequencies, cents (absolute).
    pub pitch_median_cents: f64,
    /// Median pitch error had the bands been played at their centres, cents.
    pub band_centre_median_cents: f64,
}

impl Metrics {
    /// The masks' F1 score (harmonic mean of the mean recall and mean precision).
    pub fn mask_f1(&self) -> f64 {
        let (r, p) = (self.mask_recall, self.mask_precision);
        if r + p > 0.0 {
            2.0 * r * p / (r + p)
        } else {
            0.0
        }
    }
}

impl std::fmt::Display for Metrics {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "recall {:.1} %, precision {:.1} %, amplitude MSE {:.4}, pitch median {:.1} cents (band centres {:.1}), {} objects",
            100.0 * self.mask_recall,
            100.0 * self.mask_precision,
            self.amplitude_mse,
            self.pitch_median_cents,
            self.band_centre_median_cents,
            self.objects
        )
    }
}

/// Where `log10(hz)` lies in band `b`: 0 at its lower edge, 1 at its upper, in log frequency.
pub fn band_position(b: usize, log_hz: f64) -> f64 {
    let e = band_edges_hz();
    let (lo, hi) = (e[b].log10(), e[b + 1].log10());
    ((log_hz - lo) / (hi - lo)).clamp(0.0, 1.0)
}

/// `log10(Hz)` of position `p` in band `b` (the inverse of [`band_position`]).
pub fn band_log_hz(b: usize, p: f64) -> f64 {
    let e = band_edges_hz();
    let (lo, hi) = (e[b].log10(), e[b + 1].log10());
    lo + p.clamp(0.0, 1.0) * (hi - lo)
}

/// One object's comparison.
#[derive(Clone, Debug, Default)]
pub struct ObjectScore {
    /// Mask entries on in both.
    pub true_positive: usize,
    /// On in the prediction only.
    pub false_positive: usize,
    /// On in the labels only.
    pub false_negative: usize,
    /// Sum of squared log-amplitude errors over struck entries.
    pub squared_error: f64,
    /// Struck entries (cells x directions x bands).
    pub entries: usize,
    /// Cents off, per band both fill.
    pub cents: Vec<f64>,
    /// Cents off had the band been played at its centre, same bands.
    pub centre_cents: Vec<f64>,
}

/// Compares a prediction with the labels of the same object (struck cells from the labels).
pub fn score(predicted: &BandEncoding, truth: &BandEncoding) -> ObjectScore {
    let mut s = ObjectScore::default();
    let per_cell = truth.mask.len() / truth.struck.len().max(1);
    for (cell, _) in truth.struck.iter().enumerate().filter(|(_, &on)| on) {
        for i in cell * per_cell..(cell + 1) * per_cell {
            let (p, t) = (predicted.mask[i], truth.mask[i]);
            match (p, t) {
                (true, true) => s.true_positive += 1,
                (true, false) => s.false_positive += 1,
                (false, true) => s.false_negative += 1,
                (false, false) => {}
            }
            let pa = if p { predicted.log_amplitude[i] } else { 0.0 };
            let ta = if t { truth.log_amplitude[i] } else { 0.0 };
            s.squared_error += ((pa - ta) as f64).powi(2);
            s.entries += 1;
        }
    }
    (s.cents, s.centre_cents) = band_cents(&predicted.band_log_hz, &truth.band_log_hz);
    s
}

/// Cents off of each band both fill: the predicted frequency's, and the band centre's.
fn band_cents(
    predicted: &[Option<f32>; BANDS],
    truth: &[Option<f32>; BANDS],
) -> (Vec<f64>, Vec<f64>) {
    let e = band_edges_hz();
    let (mut off, mut centre) = (Vec::new(), Vec::new());
    for b in 0..BANDS {
        if let (Some(p), Some(t)) = (predicted[b], truth[b]) {
            let cents =
                |log_hz: f64| (1200.0 * (log_hz - t as f64) * std::f64::consts::LOG2_10).abs();
            off.push(cents(p as f64));
            centre.push(cents((e[b] * e[b + 1]).sqrt().log10()));
        }
    }
    (off, centre)
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Averages per-object scores into [`Metrics`] (an object with no predicted positive adds no
/// precision; one with no true positive adds no recall).
pub fn summarise(scores: &[ObjectScore]) -> Metrics {
    let mean = |v: Vec<f64>| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let recall = scores
        .iter()
        .filter(|s| s.true_positive + s.false_negative > 0)
        .map(|s| s.true_positive as f64 / (s.true_positive + s.false_negative) as f64)
        .collect();
    let precision = scores
        .iter()
        .filter(|s| s.true_positive + s.false_positive > 0)
        .map(|s| s.true_positive as f64 / (s.true_positive + s.false_positive) as f64)
        .collect();
    let mse = scores
        .iter()
        .filter(|s| s.entries > 0)
        .map(|s| s.squared_error / s.entries as f64)
        .collect();
    Metrics {
        objects: scores.len(),
        mask_recall: mean(recall),
        mask_precision: mean(precision),
        amplitude_mse: mean(mse),
        pitch_median_cents: median(scores.iter().flat_map(|s| s.cents.clone()).collect()),
        band_centre_median_cents: median(
            scores.iter().flat_map(|s| s.centre_cents.clone()).collect(),
        ),
    }
}

/// Scores the network on `records` (batches of 8 on `device`, which must not be an autodiff
/// one), its band frequencies from `pitch` where given (as [`super::Predictor`] plays them)
/// or from its own head.
pub fn evaluate(
    nets: super::Nets<'_>,
    pitch: Option<&PitchIndex>,
    records: &[Record],
    device: &Device,
) -> Metrics {
    summarise(&evaluate_each(nets, pitch, records, device))
}

/// [`evaluate`]'s per-object scores, in the order of `records`.
pub fn evaluate_each(
    nets: super::Nets<'_>,
    pitch: Option<&PitchIndex>,
    records: &[Record],
    device: &Device,
) -> Vec<ObjectScore> {
    let mut scores = Vec::with_capacity(records.len());
    for chunk in records.chunks(8) {
        let grids: Vec<&crate::shape::VoxelGrid> = chunk.iter().map(|r| &r.grid).collect();
        let predicted = super::predict_batch(nets, &grids, device);
        for (mut p, r) in predicted.into_iter().zip(chunk) {
            if let Some(index) = pitch {
                p.retune(index, &r.grid);
            }
            scores.push(score(&p.to_encoding(), &r.labels));
        }
    }
    scores
}

/// The masks' operating points [`sweep`] tries: logit thresholds.
pub const SWEEP_THRESHOLDS: [f32; 7] = [0.0, -0.5, -0.75, -1.0, -1.25, -1.5, -2.0];
/// ... and how far the nearest training shape moves a band's presence logit.
pub const SWEEP_PRESENCE: [f32; 4] = [0.0, 0.5, 1.0, 2.0];
/// ... and the near-twin distances under which a band plays at the index's frequency
/// (`-inf`: never, the network's own; `inf`: always).
pub const SWEEP_TWIN: [f32; 7] = [f32::NEG_INFINITY, 0.01, 0.05, 0.1, 0.2, 0.3, f32::INFINITY];

/// One operating point's figures from [`sweep`].
#[derive(Clone, Debug)]
pub struct SweepPoint {
    /// Mask logit threshold.
    pub threshold: f32,
    /// Presence logit shift from the nearest training shape.
    pub presence: f32,
    /// The figures there (pitch at the shipped near-twin distance).
    pub metrics: Metrics,
}

impl SweepPoint {
    /// The masks' F1 score (harmonic mean of the mean recall and mean precision).
    pub fn f1(&self) -> f64 {
        self.metrics.mask_f1()
    }
}

/// The figures of the network and `pitch` on `records` at every masks' operating point
/// ([`SWEEP_THRESHOLDS`] x [`SWEEP_PRESENCE`]) and the median pitch error at every near-twin
/// distance ([`SWEEP_TWIN`]): how `MASK_LOGIT_THRESHOLD`, `NEIGHBOUR_PRESENCE_LOGIT` and
/// `NEAR_TWIN_DISTANCE` are chosen, on objects of the training families that training never
/// saw (never on the held-out families). The network runs once per record.
pub fn sweep(
    nets: super::Nets<'_>,
    pitch: &PitchIndex,
    records: &[Record],
    device: &Device,
) -> (Vec<SweepPoint>, Vec<(f32, f64)>) {
    let points = SWEEP_THRESHOLDS.len() * SWEEP_PRESENCE.len();
    let mut scores: Vec<Vec<ObjectScore>> = vec![Vec::with_capacity(records.len()); points];
    let mut cents: Vec<Vec<f64>> = vec![Vec::new(); SWEEP_TWIN.len()];
    for chunk in records.chunks(8) {
        let grids: Vec<&crate::shape::VoxelGrid> = chunk.iter().map(|r| &r.grid).collect();
        let predicted = super::predict_batch(nets, &grids, device);
        for (mut p, r) in predicted.into_iter().zip(chunk) {
            let found = pitch.query(&r.grid);
            for (&twin_at, cents) in SWEEP_TWIN.iter().zip(cents.iter_mut()) {
                let bands = super::twin_bands(&p.band_log_hz, &found, twin_at);
                cents.extend(band_cents(&bands, &r.labels.band_log_hz).0);
            }
            // As played: the shipped near-twin gate.
            p.band_log_hz = super::twin_bands(&p.band_log_hz, &found, super::NEAR_TWIN_DISTANCE);
            let mut k = 0;
            for &presence in &SWEEP_PRESENCE {
                let mut biased = p.clone();
                biased.bias_bands(&super::presence_bias(&found, presence));
                for &threshold in &SWEEP_THRESHOLDS {
                    scores[k].push(score(&biased.to_encoding_at(threshold), &r.labels));
                    k += 1;
                }
            }
        }
    }
    let mut out = Vec::with_capacity(points);
    let mut k = 0;
    for &presence in &SWEEP_PRESENCE {
        for &threshold in &SWEEP_THRESHOLDS {
            out.push(SweepPoint {
                threshold,
                presence,
                metrics: summarise(&scores[k]),
            });
            k += 1;
        }
    }
    let pitch = SWEEP_TWIN
        .iter()
        .zip(cents)
        .map(|(&t, c)| (t, median(c)))
        .collect();
    (out, pitch)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::predictor::bands::{CELLS_PER_AXIS, DIRECTIONS};

    fn encoding() -> BandEncoding {
        let cells = CELLS_PER_AXIS.pow(3);
        let mut e = BandEncoding {
            struck: vec![false; cells],
            mask: vec![false; cells * DIRECTIONS * BANDS],
            log_amplitude: vec![0.0; cells * DIRECTIONS * BANDS],
            band_log_hz: [None; BANDS],
        };
        e.struck[0] = true;
        for b in [3, 4, 10] {
            e.mask[b] = true;
            e.log_amplitude[b] = 0.5;
        }
        e.band_log_hz[10] = Some(band_log_hz(10, 0.25) as f32);
        e
    }

    #[test]
    fn scores_follow_their_definitions() {
        let truth = encoding();
        let same = summarise(&[score(&truth, &truth)]);
        assert_eq!((same.mask_recall, same.mask_precision), (1.0, 1.0));
        assert_eq!((same.amplitude_mse, same.pitch_median_cents), (0.0, 0.0));
        // Band 4 dropped, band 20 added at 0.5, band 3 at 0.7; the band frequency a tenth of
        // the band higher: recall 2/3, precision 2/3, squared errors 0.25 + 0.25 + 0.04 over
        // the 96 entries of the one struck cell.
        let mut p = encoding();
        p.mask[4] = false;
        p.mask[20] = true;
        p.log_amplitude[20] = 0.5;
        p.log_amplitude[3] = 0.7;
        p.band_log_hz[10] = Some(band_log_hz(10, 0.35) as f32);
        let m = summarise(&[score(&p, &truth)]);
        assert!((m.mask_recall - 2.0 / 3.0).abs() < 1e-12);
        assert!((m.mask_precision - 2.0 / 3.0).abs() < 1e-12);
        assert!(
            (m.amplitude_mse - 0.54 / 96.0).abs() < 1e-7,
            "{}",
            m.amplitude_mse
        );
        // A tenth of band 10 in cents: 1200 log2(e11 / e10) / 10, from the edges.
        let e = band_edges_hz();
        let tenth = 120.0 * (e[11] / e[10]).log2();
        assert!(
            (m.pitch_median_cents - tenth).abs() < 0.01,
            "{}",
            m.pitch_median_cents
        );
        // The band centre is at position 0.5: a quarter band from 0.25.
        assert!((m.band_centre_median_cents - 2.5 * tenth).abs() < 0.01);
    }

    /// The sweep scores what is played: at the shipped operating point its figures are
    /// [`evaluate`]'s with the same index, exactly (same predictions, same decode), and its
    /// pitch at the shipped near-twin distance is `evaluate`'s median.
    #[test]
    fn the_sweep_at_the_shipped_point_is_what_evaluate_scores() {
        use crate::fem::ElementKind;
        use crate::predictor::dataset;
        let device = Device::flex();
        let model = crate::predictor::network::ModeNet::new(
            crate::predictor::network::Widths::SHIPPED,
            &device,
        );
        // Two training-family objects (modes in the bands at the reference size).
        let records: Vec<Record> = (0..2)
            .map(|i| {
                let (family, grid) = dataset::object(3, false, i);
                Record::label(family, grid, ElementKind::Hex8Incompatible).unwrap()
            })
            .collect();
        let index = PitchIndex::from_labels([(&records[0].grid, &records[0].labels)]);
        let want = evaluate((&model).into(), Some(&index), &records, &device);
        let (points, cents) = sweep((&model).into(), &index, &records, &device);
        let at = points
            .iter()
            .find(|p| {
                p.threshold == crate::predictor::MASK_LOGIT_THRESHOLD
                    && p.presence == crate::predictor::NEIGHBOUR_PRESENCE_LOGIT
            })
            .expect("the shipped point is swept");
        assert!(
            want.mask_recall > 0.0 && want.pitch_median_cents.is_finite(),
            "{want}"
        );
        assert_eq!(at.metrics, want);
        let (_, pitch) = cents
            .iter()
            .find(|(t, _)| *t == crate::predictor::NEAR_TWIN_DISTANCE)
            .expect("the shipped distance is swept");
        assert_eq!(*pitch, want.pitch_median_cents);
        assert_eq!(points.len(), SWEEP_THRESHOLDS.len() * SWEEP_PRESENCE.len());
    }
}
