//! Stage 1 of the material fit: the recording's modes and the model's compared on the
//! log-frequency axis as the model slides by `s`, by optimal transport (the 1-D Wasserstein
//! distance, scanned from a bad start), a two-sided trimmed loss, and the pairs stage 2 fits.
//!
//! Where it sits: called by [`super::fit_material`]; the module docs of [`super`] give the
//! method (DiffSound, Jin et al. 2024, sec. 4.2, eq. 11).

use super::{Point, Spectrum, TRIM};

/// Steps either side of the transport's optimum [`aligned`] scans: 60 of 0.25 %, 15 %.
const LOCAL_STEPS: usize = 60;

/// Step of [`aligned`]'s local scan in `s`.
const LOCAL_STEP: f64 = 0.0025;

/// Rounds of match-and-recentre in [`aligned`].
const ALIGN_ROUNDS: usize = 4;

/// Step of the optimal-transport scan in `s = ln(E/rho) / 2`: 0.5 % in frequency.
const SCAN_STEP: f64 = 0.005;

/// Widest log-frequency gap a recorded mode is matched across: 6 % (a semitone).
const MATCH_TOLERANCE: f64 = 0.06;

/// The 1-D Wasserstein distance (`W1`, in log-frequency) between the recording and the model
/// slid by `s`, over the span both can show: up to the lower of the recording's highest mode
/// and the model's highest computed one. Each side's weights are normalised over that span.
/// Infinite when either side has nothing there.
pub(super) fn transport_loss(points: &[Point], model: &Spectrum, s: f64) -> f64 {
    let top_recorded = points.last().map_or(f64::NEG_INFINITY, |p| p.log_hz);
    let top = (model.top() + s).min(top_recorded) + MATCH_TOLERANCE;
    let a: Vec<(f64, f64)> = points
        .iter()
        .filter(|p| p.log_hz <= top)
        .map(|p| (p.log_hz, p.weight))
        .collect();
    let mut b: Vec<(f64, f64)> = model
        .log_hz
        .iter()
        .zip(&model.weights)
        .map(|(&l, &w)| (l + s, w))
        .filter(|&(l, w)| l <= top && w > 0.0)
        .collect();
    b.sort_by(|x, y| x.0.total_cmp(&y.0));
    wasserstein_1d(&a, &b)
}

/// `W1 = int |F_a - F_b| dx` of two weighted point sets, each sorted by position and
/// normalised to unit mass; infinite when either is empty.
pub(super) fn wasserstein_1d(a: &[(f64, f64)], b: &[(f64, f64)]) -> f64 {
    let (ma, mb) = (
        a.iter().map(|p| p.1).sum::<f64>(),
        b.iter().map(|p| p.1).sum::<f64>(),
    );
    if !(ma > 0.0 && mb > 0.0) {
        return f64::INFINITY;
    }
    let (mut i, mut j) = (0, 0);
    let (mut fa, mut fb) = (0.0f64, 0.0f64);
    let mut x = a[0].0.min(b[0].0);
    let mut total = 0.0;
    while i < a.len() || j < b.len() {
        let next = match (a.get(i), b.get(j)) {
            (Some(p), Some(q)) => p.0.min(q.0),
            (Some(p), None) => p.0,
            (None, Some(q)) => q.0,
            (None, None) => break,
        };
        total += (fa - fb).abs() * (next - x);
        x = next;
        while i < a.len() && a[i].0 <= x {
            fa += a[i].1 / ma;
            i += 1;
        }
        while j < b.len() && b[j].0 <= x {
            fb += b[j].1 / mb;
            j += 1;
        }
    }
    total
}

/// Scans `s` over `s0 +- half_span` for the least transport loss: `(s, loss)`.
pub(super) fn transport_scan(
    points: &[Point],
    model: &Spectrum,
    s0: f64,
    half_span: f64,
) -> (f64, f64) {
    let steps = (2.0 * half_span / SCAN_STEP).ceil() as usize;
    (0..=steps)
        .map(|k| s0 - half_span + k as f64 * SCAN_STEP)
        .map(|s| (s, transport_loss(points, model, s)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap_or((s0, f64::INFINITY))
}

/// Aligns the model on the recording mode by mode from `s` and scores the alignment
/// ([`trimmed_loss`]): a local scan of `s` (the transport's optimum is the right basin, not
/// always the right spot in it: on a dense spectrum a shift by one mode spacing moves little
/// mass far), then a few rounds of matching and moving `s` to the matched pairs' weighted
/// mean residual.
pub(super) fn aligned(points: &[Point], model: &Spectrum, s: f64) -> (f64, f64) {
    let mut s = (0..=2 * LOCAL_STEPS)
        .map(|k| s + (k as f64 - LOCAL_STEPS as f64) * LOCAL_STEP)
        .map(|s| (s, trimmed_loss(points, model, s)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map_or(s, |b| b.0);
    for _ in 0..ALIGN_ROUNDS {
        let pairs = matches(points, model, s);
        let (mut sum, mut w) = (0.0, 0.0);
        for &(j, k) in &pairs {
            let r = points[j].log_hz - (model.log_hz[k] + s);
            if r.abs() < TRIM {
                sum += points[j].weight * r;
                w += points[j].weight;
            }
        }
        if w == 0.0 {
            break;
        }
        s += sum / w;
    }
    (s, trimmed_loss(points, model, s))
}

/// A two-sided robust loss at `s`: the weighted mean of `min(r^2, TRIM^2)` over the
/// recorded modes below the model's highest (`r` to its matched model mode; unmatched,
/// `TRIM^2`), averaged with the same over the model's modes inside the recorded span (`r` to
/// the nearest recorded mode), weighted by their loudness at the hit. The first side is what
/// a few wrong neighbours cannot pull; the second is what rules out a stiffness that puts a
/// handful of model modes on the recording's few and many more where it has none.
pub(super) fn trimmed_loss(points: &[Point], model: &Spectrum, s: f64) -> f64 {
    let top = model.top() + s;
    let pairs = matches(points, model, s);
    let mut residual = vec![f64::INFINITY; points.len()];
    for &(j, k) in &pairs {
        residual[j] = points[j].log_hz - (model.log_hz[k] + s);
    }
    let (mut recorded, mut w) = (0.0, 0.0);
    for (p, r) in points.iter().zip(&residual) {
        if p.log_hz <= top + MATCH_TOLERANCE {
            recorded += p.weight * (r * r).min(TRIM * TRIM);
            w += p.weight;
        }
    }
    if w == 0.0 {
        return f64::INFINITY;
    }
    let (low, high) = match (points.first(), points.last()) {
        (Some(a), Some(b)) => (a.log_hz - TRIM, b.log_hz + TRIM),
        _ => return f64::INFINITY,
    };
    let (mut modelled, mut v) = (0.0, 0.0);
    for (&l, &weight) in model.log_hz.iter().zip(&model.weights) {
        let x = l + s;
        if (low..=high).contains(&x) {
            let i = points.partition_point(|p| p.log_hz < x);
            let r = [i.checked_sub(1), (i < points.len()).then_some(i)]
                .into_iter()
                .flatten()
                .map(|j| (points[j].log_hz - x).abs())
                .fold(f64::INFINITY, f64::min);
            modelled += weight * (r * r).min(TRIM * TRIM);
            v += weight;
        }
    }
    let modelled = if v > 0.0 { modelled / v } else { TRIM * TRIM };
    0.5 * (recorded / w + modelled)
}

/// Each recorded mode (index into `points`) paired with its nearest free model mode at `s`,
/// within [`MATCH_TOLERANCE`], loudest recorded modes first; sorted by recorded mode.
pub(super) fn matches(points: &[Point], model: &Spectrum, s: f64) -> Vec<(usize, usize)> {
    let mut order: Vec<usize> = (0..points.len()).collect();
    order.sort_by(|&a, &b| points[b].weight.total_cmp(&points[a].weight));
    let mut taken = vec![false; model.log_hz.len()];
    let mut pairs = Vec::new();
    for j in order {
        let x = points[j].log_hz - s;
        let best = model
            .log_hz
            .iter()
            .enumerate()
            .filter(|(k, _)| !taken[*k])
            .map(|(k, &v)| (k, (v - x).abs()))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((k, d)) = best {
            if d <= MATCH_TOLERANCE {
                taken[k] = true;
                pairs.push((j, k));
            }
        }
    }
    pairs.sort_unstable();
    pairs
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wasserstein_of_shifted_sets_is_the_shift() {
        let a = [(0.0, 1.0), (1.0, 2.0), (3.0, 1.0)];
        let b: Vec<(f64, f64)> = a.iter().map(|&(x, w)| (x + 0.25, w)).collect();
        assert!((wasserstein_1d(&a, &b) - 0.25).abs() < 1e-12);
        // Two unit masses at 0 and 1 against one at 0.5: each half travels 0.5.
        let c = [(0.0, 1.0), (1.0, 1.0)];
        let d = [(0.5, 3.0)];
        assert!((wasserstein_1d(&c, &d) - 0.5).abs() < 1e-12);
        assert!(wasserstein_1d(&c, &[]).is_infinite());
    }
}
