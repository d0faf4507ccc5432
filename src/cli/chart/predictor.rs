//! The neural predictor on `modalforge chart`: its point on each benchmark shape's panel
//! (frequency error against time, like every solver's), and a panel of the held-out split's
//! mask recall and precision against time for the predictor and the methods it is compared
//! with, read from the CSV `modalforge predictor eval --csv` writes.
//!
//! Where it sits: beside [`super::sweep`], which calls [`neural_point`] once per shape with
//! that shape's reference frequencies, and [`super::plot`], which draws [`draw_methods`] as a
//! last panel when it is given method rows.

use super::{shape, ChartPoint, CHART_MODES};
use crate::cli::CliError;
use modalforge::material::Material;
use modalforge::predictor::bands::{self, BANDS, DIRECTIONS};
use modalforge::predictor::Predictor;
use plotters::prelude::*;
use std::fmt::Write as _;

/// The first line of the methods CSV (`modalforge predictor eval --csv`).
pub const METHODS_CSV_HEADER: &str =
    "method,objects,time_ms,recall_percent,precision_percent,amplitude_mse,pitch_cents";

/// Resolution the predictor's chart point is taken at: its input box's side, so the shape goes
/// in as it is.
pub const NEURAL_RESOLUTION: usize = bands::INPUT_SIDE;

/// One method's figures on the held-out split (`modalforge predictor eval`).
#[derive(Clone, Debug, PartialEq)]
pub struct MethodRow {
    /// What was scored (the network, shape matching, the coarse FEM answer).
    pub method: String,
    /// Held-out objects scored.
    pub objects: usize,
    /// Mean time per shape, ms (one core).
    pub time_ms: f64,
    /// Mean mask recall, percent.
    pub recall_percent: f64,
    /// Mean mask precision, percent.
    pub precision_percent: f64,
    /// Mean squared error of the normalised log-amplitudes.
    pub amplitude_mse: f64,
    /// Median pitch error of the band frequencies, cents.
    pub pitch_cents: f64,
}

/// The CSV text of method rows.
pub fn methods_to_csv(rows: &[MethodRow]) -> String {
    let mut out = format!("{METHODS_CSV_HEADER}\n");
    for r in rows {
        let _ = writeln!(
            out,
            "{},{},{:.2},{:.2},{:.2},{:.5},{:.2}",
            r.method.replace(',', ";"),
            r.objects,
            r.time_ms,
            r.recall_percent,
            r.precision_percent,
            r.amplitude_mse,
            r.pitch_cents
        );
    }
    out
}

/// Parses a methods CSV (the format [`methods_to_csv`] writes).
pub fn methods_from_csv(text: &str) -> Result<Vec<MethodRow>, String> {
    let mut rows = Vec::new();
    for (row, f) in super::csv_rows(text, METHODS_CSV_HEADER, 7)? {
        // The pitch is NaN where no band was scored; every other figure is a number >= 0.
        let num = |k: usize, nan_ok: bool| super::csv_number(&f, k, row, nan_ok);
        rows.push(MethodRow {
            method: f[0].to_string(),
            objects: num(1, false)? as usize,
            time_ms: num(2, false)?,
            recall_percent: num(3, false)?,
            precision_percent: num(4, false)?,
            amplitude_mse: num(5, false)?,
            pitch_cents: num(6, true)?,
        });
    }
    Ok(rows)
}

/// The shipped predictor on benchmark shape `name` (steel, `size_m`, at
/// [`NEURAL_RESOLUTION`]): the mean and largest distance, in percent, from each of the
/// reference's lowest [`CHART_MODES`] frequencies to the nearest frequency the predictor plays
/// (a band whose mask is on at any strike of the shape, or a Ritz mode), and the predictor's
/// time.
pub(super) fn neural_point(
    predictor: &Predictor,
    name: &str,
    size_m: f64,
    reference_hz: &[f64],
) -> Result<ChartPoint, CliError> {
    let fail = |e: &dyn std::fmt::Display| CliError::Option(format!("chart: {name} neural: {e}"));
    let n = NEURAL_RESOLUTION;
    let steel = Material::parse("steel").map_err(|e| fail(&e))?;
    let grid = shape(name, n)
        .rasterize(1.0, size_m / n as f64)
        .map_err(|e| fail(&e))?;
    let predicted = predictor.predict(&grid).map_err(|e| fail(&e))?;
    let encoding = predicted.prediction.to_encoding();
    let per_cell = DIRECTIONS * BANDS;
    let played: Vec<usize> = (0..BANDS)
        .filter(|&b| {
            (encoding.struck.iter().enumerate())
                .filter(|(_, &on)| on)
                .any(|(c, _)| (0..DIRECTIONS).any(|d| encoding.mask[c * per_cell + d * BANDS + b]))
        })
        .collect();
    // Each played band's mode, in the shape's voxels (Deep-Modal eq. 11), at steel.
    let h = grid.voxel_size_m();
    let scale = steel.youngs_modulus_pa / (steel.density_kg_m3 * h * h);
    // The network's modes in played bands, then every Ritz mode (compact shapes: a mode
    // shape, heard wherever it is not at a node).
    let network = predicted.bands().len();
    let hz: Vec<f64> = (predicted.eigenvalues.iter().enumerate())
        .filter(|&(i, _)| i >= network || played.contains(&predicted.bands()[i]))
        .map(|(_, lambda)| (lambda * scale).sqrt() / std::f64::consts::TAU)
        .collect();
    let errors: Vec<f64> = (reference_hz.iter().take(CHART_MODES))
        .map(|&r| {
            let nearest = hz
                .iter()
                .map(|f| (f - r).abs())
                .fold(f64::INFINITY, f64::min);
            (100.0 * nearest / r).min(100.0)
        })
        .collect();
    Ok(ChartPoint {
        shape: name.to_string(),
        resolution: n,
        element: "neural".into(),
        solver: "predictor".into(),
        tolerance: 0.0,
        dofs: 0,
        time_ms: predicted.inference_ms,
        mean_error_percent: errors.iter().sum::<f64>() / errors.len().max(1) as f64,
        max_error_percent: errors.iter().copied().fold(0.0, f64::max),
    })
}

/// Colours of the method panel's rows, in order.
const METHOD_COLOURS: [RGBColor; 5] = [
    RGBColor(227, 119, 194),
    RGBColor(255, 127, 14),
    RGBColor(127, 127, 127),
    RGBColor(148, 103, 189),
    RGBColor(23, 190, 207),
];

/// The held-out split's panel: each method's mask recall (circle) and precision (triangle)
/// against its time per shape, and issue 12's 75 % goal as a line.
pub(super) fn draw_methods(
    panel: &super::Panel<'_>,
    rows: &[MethodRow],
) -> Result<(), Box<dyn std::error::Error>> {
    let (lo, hi) = rows.iter().fold((f64::MAX, f64::MIN), |(lo, hi), r| {
        (lo.min(r.time_ms.max(0.1)), hi.max(r.time_ms.max(0.1)))
    });
    let objects = rows.iter().map(|r| r.objects).max().unwrap_or(0);
    let mut chart = ChartBuilder::on(panel)
        .caption(
            format!("predictor, {objects} held-out shapes"),
            ("sans-serif", 22),
        )
        .margin(15)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(((lo * 0.5)..(hi * 2.0)).log_scale(), 0.0..100.0)?;
    chart
        .configure_mesh()
        .x_desc("time per shape, scored (ms)")
        .x_label_formatter(&|v| format!("{v:.0}"))
        .y_desc("mask recall (o) and precision (^), %")
        .label_style(("sans-serif", 15))
        .draw()?;
    let goal = [(lo * 0.5, 75.0), (hi * 2.0, 75.0)];
    chart
        .draw_series(LineSeries::new(goal, BLACK.mix(0.5).stroke_width(1)))?
        .label("goal: 75 %")
        .legend(|(x, y)| PathElement::new([(x - 8, y), (x + 8, y)], BLACK.mix(0.5)));
    for (r, colour) in rows.iter().zip(METHOD_COLOURS.iter().cycle()) {
        let style = colour.filled();
        let t = r.time_ms.max(0.1);
        chart.draw_series(std::iter::once(TriangleMarker::new(
            (t, r.precision_percent),
            7,
            style,
        )))?;
        chart
            .draw_series(std::iter::once(Circle::new(
                (t, r.recall_percent),
                6,
                style,
            )))?
            .label(format!(
                "{}: {:.0} / {:.0} %, {:.0} cents",
                r.method, r.recall_percent, r.precision_percent, r.pitch_cents
            ))
            .legend(move |(x, y)| Circle::new((x, y), 5, style));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        .draw()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn method_rows_survive_their_csv() {
        let rows = vec![
            MethodRow {
                method: "network + pitch index".into(),
                objects: 500,
                time_ms: 5.25,
                recall_percent: 66.9,
                precision_percent: 59.8,
                amplitude_mse: 0.104,
                pitch_cents: 26.2,
            },
            MethodRow {
                method: "nothing scored".into(),
                objects: 0,
                time_ms: 0.0,
                recall_percent: 0.0,
                precision_percent: 0.0,
                amplitude_mse: 0.0,
                pitch_cents: f64::NAN,
            },
        ];
        let back = methods_from_csv(&methods_to_csv(&rows)).expect("parses");
        assert_eq!(back[0], rows[0]);
        assert!(back[1].pitch_cents.is_nan());
        let bad = format!("{METHODS_CSV_HEADER}\nnetwork,5,-1,0,0,0,0\n");
        let e = methods_from_csv(&bad).unwrap_err();
        assert!(e.contains("line 2: field 3"), "{e}");
        assert!(methods_from_csv("method,time\n").is_err());
    }
}
