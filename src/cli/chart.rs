//! `modalforge chart`: the speed-versus-accuracy sweep, the start of the product's chart.
//!
//! Where it sits: a CLI command over [`modalforge::fem`] and [`modalforge::eigen`]. It solves benchmark
//! shapes (a solid sphere, a hemispherical bowl with a wall of 1/16 of its diameter, a plate of
//! thickness 1/16 of its side; steel, 0.2 m) over voxel resolutions, elements and solvers
//! (residual 1e-6, LOBPCG's floor), and writes every run to `chart.csv` and a log-log plot of frequency
//! error against solve time to `chart.png`. The shipped neural predictor adds its point to each
//! shape ([`predictor`]); `--predictor FILE` adds a panel of the held-out split's mask recall
//! and precision against time, from `modalforge predictor eval --csv FILE`.
//!
//! Error: the mean and the largest relative difference of the lowest [`CHART_MODES`]
//! frequencies from the shape's reference, which is the same shape solved with quadratic
//! elements (hex27) at the sweep's finest resolution (plate and bowl 64, sphere 32; 0.4-0.7M
//! DOFs) by LOBPCG at residual 1e-7 (`--quick`: resolution 10, Lanczos at 1e-9). Points at the
//! reference resolution measure discretisation error only; coarser points also carry the
//! staircase's geometric error, which is what a user choosing a resolution pays. Plate and bowl
//! resolutions keep their wall a whole number of voxels, so each is the same physical object.

mod predictor;

pub use predictor::{methods_from_csv, methods_to_csv, MethodRow};

use super::CliError;
use modalforge::eigen::{self, EigenOptions, ModeCount, SolverKind};
use modalforge::fem::{ElementKind, FemModel};
use modalforge::material::Material;
use modalforge::shape::primitives::Primitive;
use plotters::prelude::*;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The first line of `chart.csv`.
pub const CSV_HEADER: &str =
    "shape,resolution,element,solver,tolerance,dofs,time_ms,mean_error_percent,max_error_percent";

/// Frequencies compared per run.
pub const CHART_MODES: usize = 10;

/// Sweep runs whose model has more degrees of freedom than this are skipped (a 48^3 solid
/// through a direct factorisation takes minutes). References are not capped.
pub const MAX_CHART_DOFS: usize = 100_000;

/// The benchmark shapes' largest extent, m (steel).
const SIZE_M: f64 = 0.2;

/// The bundled font (DejaVu Sans, Bitstream Vera licence, `assets/fonts/`).
const FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// Options of `modalforge chart`.
#[derive(clap::Args, Debug)]
pub struct ChartArgs {
    /// Folder for chart.csv and chart.png (created if missing).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// A small sweep (resolutions 6 and 8, reference 10) that runs in seconds.
    #[arg(long)]
    pub quick: bool,
    /// Plot an existing chart CSV (e.g. one that other methods appended rows to) instead of
    /// running the sweep; writes DIR/chart.png only.
    #[arg(long, value_name = "CSV", conflicts_with = "quick")]
    pub from: Option<PathBuf>,
    /// Add a panel of the neural predictor's and its comparison methods' mask recall and
    /// precision against time on the held-out split, from `modalforge predictor eval --csv`.
    #[arg(long, value_name = "CSV")]
    pub predictor: Option<PathBuf>,
}

/// One solve of the sweep.
#[derive(Clone, Debug)]
pub struct ChartPoint {
    /// Benchmark shape.
    pub shape: String,
    /// Voxels along the longest side.
    pub resolution: usize,
    /// Element name.
    pub element: String,
    /// Solver name.
    pub solver: String,
    /// Residual tolerance.
    pub tolerance: f64,
    /// Degrees of freedom.
    pub dofs: usize,
    /// Assembly plus solve, milliseconds (one core).
    pub time_ms: f64,
    /// Mean relative frequency error, percent.
    pub mean_error_percent: f64,
    /// Largest relative frequency error, percent.
    pub max_error_percent: f64,
}

fn shape(name: &str, n: usize) -> Primitive {
    let d = n as f64;
    match name {
        "sphere" => Primitive::Sphere { diameter: d },
        "bowl" => Primitive::Bowl {
            diameter: d,
            wall: (d / 16.0).max(1.0),
        },
        _ => Primitive::Plate {
            length: d,
            width: d,
            thickness: (d / 16.0).max(1.0),
        },
    }
}

/// The lowest `CHART_MODES` frequencies (Hz) and the time (ms) of one solve.
fn solve(
    name: &str,
    n: usize,
    kind: ElementKind,
    solver: SolverKind,
    tolerance: f64,
    max_dofs: usize,
) -> Result<Option<(Vec<f64>, usize, f64)>, CliError> {
    let fail = |e: &dyn std::fmt::Display| CliError::Option(format!("chart: {name} {n}: {e}"));
    let steel = Material::parse("steel").map_err(|e| fail(&e))?;
    let grid = shape(name, n)
        .rasterize(1.0, SIZE_M / n as f64)
        .map_err(|e| fail(&e))?;
    let t = Instant::now();
    let model = FemModel::assemble(&grid, kind, steel.poisson_ratio).map_err(|e| fail(&e))?;
    if model.dofs() > max_dofs {
        return Ok(None);
    }
    let options = EigenOptions {
        count: ModeCount::First(CHART_MODES),
        tolerance,
        ..Default::default()
    };
    let sol = eigen::solve(&model, solver, &options).map_err(|e| fail(&e))?;
    let ms = t.elapsed().as_secs_f64() * 1e3;
    let h = grid.voxel_size_m();
    let scale = steel.youngs_modulus_pa / (steel.density_kg_m3 * h * h);
    let freqs = sol
        .eigenvalues
        .iter()
        .map(|l| (l * scale).sqrt() / (2.0 * std::f64::consts::PI))
        .collect();
    Ok(Some((freqs, model.dofs(), ms)))
}

/// Runs the sweep; `progress` hears about each point.
pub fn sweep(
    quick: bool,
    mut progress: impl FnMut(&ChartPoint),
) -> Result<Vec<ChartPoint>, CliError> {
    // (shape, resolutions, reference resolution). Plate and bowl resolutions keep the wall a
    // whole number of voxels (1/16 of the size), so every point is the same physical object.
    let (shapes, reference_solver, reference_tolerance): (&[(&str, &[usize], usize)], _, _) =
        if quick {
            (
                &[("plate", &[6, 8], 10), ("bowl", &[6, 8], 10)],
                SolverKind::Lanczos,
                1e-9,
            )
        } else {
            (
                &[
                    ("plate", &[16, 32, 48, 64], 64),
                    ("bowl", &[16, 32, 48, 64], 64),
                    ("sphere", &[8, 12, 16, 24, 32], 32),
                ],
                SolverKind::Lobpcg,
                1e-7,
            )
        };
    let runs: &[(ElementKind, SolverKind, f64)] = &[
        (ElementKind::Hex8, SolverKind::Lanczos, 1e-6),
        (ElementKind::Hex8Incompatible, SolverKind::Lanczos, 1e-6),
        (ElementKind::Hex8Incompatible, SolverKind::Lobpcg, 1e-6),
        (ElementKind::Hex27Blocks, SolverKind::Lanczos, 1e-6),
        (ElementKind::Hex27, SolverKind::Lanczos, 1e-6),
        (ElementKind::Hex27, SolverKind::Lobpcg, 1e-6),
    ];
    let neural = modalforge::predictor::Predictor::shipped()
        .map_err(|e| CliError::Option(format!("chart: the shipped predictor: {e}")))?;
    let mut points = Vec::new();
    for &(name, resolutions, n_ref) in shapes {
        let (reference, ..) = solve(
            name,
            n_ref,
            ElementKind::Hex27,
            reference_solver,
            reference_tolerance,
            usize::MAX,
        )?
        .ok_or_else(|| {
            CliError::Option(format!(
                "chart: the {name} reference is over the size limit"
            ))
        })?;
        for &n in resolutions {
            for &(kind, solver, tolerance) in runs {
                let Some((freqs, dofs, ms)) =
                    solve(name, n, kind, solver, tolerance, MAX_CHART_DOFS)?
                else {
                    continue;
                };
                let errors: Vec<f64> = freqs
                    .iter()
                    .zip(&reference)
                    .map(|(f, r)| 100.0 * (f - r).abs() / r)
                    .collect();
                let point = ChartPoint {
                    shape: name.to_string(),
                    resolution: n,
                    element: kind.to_string(),
                    solver: solver.to_string(),
                    tolerance,
                    dofs,
                    time_ms: ms,
                    mean_error_percent: errors.iter().sum::<f64>() / errors.len() as f64,
                    max_error_percent: errors.iter().cloned().fold(0.0, f64::max),
                };
                progress(&point);
                points.push(point);
            }
        }
        let point = predictor::neural_point(&neural, name, SIZE_M, &reference)?;
        progress(&point);
        points.push(point);
    }
    Ok(points)
}

/// The CSV text of a sweep.
pub fn to_csv(points: &[ChartPoint]) -> String {
    let mut out = format!("{CSV_HEADER}\n");
    for p in points {
        let _ = writeln!(
            out,
            "{},{},{},{},{:e},{},{:.1},{:.4},{:.4}",
            p.shape,
            p.resolution,
            p.element,
            p.solver,
            p.tolerance,
            p.dofs,
            p.time_ms,
            p.mean_error_percent,
            p.max_error_percent
        );
    }
    out
}

/// Parses a chart CSV (the format [`to_csv`] writes; extra rows from other methods welcome).
pub fn from_csv(text: &str) -> Result<Vec<ChartPoint>, String> {
    let mut points = Vec::new();
    for (row, f) in csv_rows(text, CSV_HEADER, 9)? {
        let num = |k: usize| csv_number(&f, k, row, false);
        points.push(ChartPoint {
            shape: f[0].to_string(),
            resolution: num(1)? as usize,
            element: f[2].to_string(),
            solver: f[3].to_string(),
            tolerance: num(4)?,
            dofs: num(5)? as usize,
            time_ms: num(6)?,
            mean_error_percent: num(7)?,
            max_error_percent: num(8)?,
        });
    }
    Ok(points)
}

/// The data lines of a CSV with `header` as its first line, each as its line number and its
/// `fields` trimmed fields (blank lines skipped), else the error line.
fn csv_rows<'a>(
    text: &'a str,
    header: &str,
    fields: usize,
) -> Result<Vec<(usize, Vec<&'a str>)>, String> {
    let mut lines = text.lines();
    if lines.next().unwrap_or_default().trim() != header {
        return Err(format!("the first line must be the header '{header}'"));
    }
    let mut rows = Vec::new();
    for (i, line) in lines.enumerate().filter(|(_, l)| !l.trim().is_empty()) {
        let row = i + 2;
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        if f.len() != fields {
            return Err(format!(
                "line {row}: expected {fields} comma-separated fields, found {}",
                f.len()
            ));
        }
        rows.push((row, f));
    }
    Ok(rows)
}

/// Field `k` of CSV line `row` as a number >= 0 (or NaN where `nan_ok`), else the error line.
fn csv_number(fields: &[&str], k: usize, row: usize, nan_ok: bool) -> Result<f64, String> {
    fields[k]
        .parse::<f64>()
        .ok()
        .filter(|v| (v.is_finite() && *v >= 0.0) || (nan_ok && v.is_nan()))
        .ok_or_else(|| {
            format!(
                "line {row}: field {} ('{}') is not a number >= 0",
                k + 1,
                fields[k]
            )
        })
}

/// Draws one log-log panel per shape, mean error against time: colour per element, marker per
/// solver, and a line through each (element, solver, tolerance) series in resolution order;
/// then, where `methods` holds rows, the held-out split's panel ([`predictor`]).
pub fn plot(points: &[ChartPoint], methods: &[MethodRow], path: &Path) -> Result<(), CliError> {
    let fail = |e: &dyn std::fmt::Display| {
        CliError::Option(format!("chart: drawing {}: {e}", path.display()))
    };
    if points.is_empty() {
        return Err(CliError::Option("chart: no point to draw".into()));
    }
    plotters::style::register_font("sans-serif", FontStyle::Normal, FONT)
        .map_err(|_| CliError::Option("chart: the bundled font is unreadable".into()))?;
    let span = |value: &dyn Fn(&ChartPoint) -> f64| {
        let (lo, hi) = points.iter().fold((f64::MAX, f64::MIN), |(lo, hi), p| {
            (lo.min(value(p)), hi.max(value(p)))
        });
        (lo * 0.7)..(hi * 1.4)
    };
    let axes = (span(&plotted_time), span(&plotted_error));
    let mut shapes: Vec<&str> = Vec::new();
    for p in points {
        if !shapes.contains(&p.shape.as_str()) {
            shapes.push(&p.shape);
        }
    }
    let panels = shapes.len() + usize::from(!methods.is_empty());
    let root = BitMapBackend::new(path, (600 * panels as u32 + 40, 760)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| fail(&e))?;
    let root = root
        .titled(
            "ModalForge: mean error of the lowest 10 frequencies vs assembly + solve time (one core)",
            ("sans-serif", 24),
        )
        .map_err(|e| fail(&e))?;
    let split = root.split_evenly((1, panels));
    for (panel, shape) in split.iter().zip(&shapes) {
        draw_panel(panel, shape, points, axes.clone()).map_err(|e| fail(&e))?;
    }
    if let Some(panel) = split.get(shapes.len()).filter(|_| !methods.is_empty()) {
        predictor::draw_methods(panel, methods).map_err(|e| fail(&e))?;
    }
    root.present().map_err(|e| fail(&e))?;
    Ok(())
}

/// A point's time on the chart, ms (at least 0.1: the axis is logarithmic).
fn plotted_time(p: &ChartPoint) -> f64 {
    p.time_ms.max(0.1)
}

/// A point's error on the chart, % (at least 1e-3: the axis is logarithmic).
fn plotted_error(p: &ChartPoint) -> f64 {
    p.mean_error_percent.max(1e-3)
}

/// The colour of an element's series.
fn colour_of(element: &str) -> RGBColor {
    match element {
        "hex8" => RGBColor(214, 39, 40),
        "hex8i" => RGBColor(31, 119, 180),
        "hex27" => RGBColor(44, 160, 44),
        "hex27x2" => RGBColor(148, 103, 189),
        "neural" => RGBColor(227, 119, 194),
        _ => RGBColor(120, 120, 120),
    }
}

type Panel<'a> = DrawingArea<BitMapBackend<'a>, plotters::coord::Shift>;
type LogChart<'a, 'b> =
    ChartContext<'a, BitMapBackend<'b>, Cartesian2d<LogCoord<f64>, LogCoord<f64>>>;

/// One shape's panel: axes, a series per (element, solver, tolerance), the legend.
fn draw_panel(
    panel: &Panel<'_>,
    shape: &str,
    points: &[ChartPoint],
    (time_ms, error_percent): (std::ops::Range<f64>, std::ops::Range<f64>),
) -> Result<(), String> {
    let text = |e: &dyn std::fmt::Display| e.to_string();
    let mut chart = ChartBuilder::on(panel)
        .caption(shape, ("sans-serif", 22))
        .margin(15)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(time_ms.log_scale(), error_percent.log_scale())
        .map_err(|e| text(&e))?;
    chart
        .configure_mesh()
        .x_desc("time (ms)")
        .x_label_formatter(&|v| format!("{v:.0}"))
        .y_label_formatter(&|v| format!("{v:.2}"))
        .y_desc("mean frequency error (%)")
        .label_style(("sans-serif", 15))
        .draw()
        .map_err(|e| text(&e))?;
    let mut series: Vec<(&str, &str, f64)> = Vec::new();
    for p in points.iter().filter(|p| p.shape == shape) {
        let key = (p.element.as_str(), p.solver.as_str(), p.tolerance);
        if !series.contains(&key) {
            series.push(key);
        }
    }
    for (element, solver, tolerance) in series {
        let mut run: Vec<&ChartPoint> = points
            .iter()
            .filter(|p| {
                p.shape == shape
                    && p.element == element
                    && p.solver == solver
                    && p.tolerance == tolerance
            })
            .collect();
        run.sort_by_key(|p| p.resolution);
        draw_run(&mut chart, &run).map_err(|e| text(&e))?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        .draw()
        .map_err(|e| text(&e))?;
    Ok(())
}

/// One series (same element, solver and tolerance, by resolution): a line, markers (circles
/// for Lanczos, triangles otherwise) with a legend entry, and the resolution beside the points
/// of the accurate iterative runs and of hex8.
fn draw_run(
    chart: &mut LogChart<'_, '_>,
    run: &[&ChartPoint],
) -> Result<(), Box<dyn std::error::Error>> {
    let Some(first) = run.first() else {
        return Ok(());
    };
    let (element, solver, tolerance) = (
        first.element.as_str(),
        first.solver.as_str(),
        first.tolerance,
    );
    let xy: Vec<(f64, f64)> = run
        .iter()
        .map(|p| (plotted_time(p), plotted_error(p)))
        .collect();
    let colour = colour_of(element);
    let line = if tolerance > 1e-5 {
        colour.mix(0.35).stroke_width(1)
    } else {
        colour.mix(0.8).stroke_width(2)
    };
    chart.draw_series(LineSeries::new(xy.clone(), line))?;
    let style = colour.filled();
    let label = format!("{element} {solver} {tolerance:.0e}");
    if element == "neural" {
        chart
            .draw_series(xy.iter().map(|&p| Cross::new(p, 7, colour.stroke_width(3))))?
            .label("neural predictor (32^3)")
            .legend(move |(x, y)| Cross::new((x, y), 5, colour.stroke_width(3)));
    } else if solver == "lanczos" {
        chart
            .draw_series(xy.iter().map(|&p| Circle::new(p, 5, style)))?
            .label(label)
            .legend(move |(x, y)| Circle::new((x, y), 5, style));
    } else {
        chart
            .draw_series(xy.iter().map(|&p| TriangleMarker::new(p, 6, style)))?
            .label(label)
            .legend(move |(x, y)| TriangleMarker::new((x, y), 6, style));
    }
    if tolerance <= 1e-5 && solver != "lanczos" || element == "hex8" {
        chart.draw_series(run.iter().zip(&xy).map(|(p, &(x, y))| {
            Text::new(
                format!("{}", p.resolution),
                (x * 1.08, y),
                ("sans-serif", 12).into_font().color(&colour),
            )
        }))?;
    }
    Ok(())
}

/// Reads a CSV file (size-limited) for `modalforge chart`.
fn read_csv(csv: &Path, what: &'static str) -> Result<String, CliError> {
    modalforge::limits::read_text(csv, what).map_err(|e| match e {
        modalforge::limits::TextReadError::TooLarge(e) => CliError::Option(e.to_string()),
        modalforge::limits::TextReadError::Io(source) => CliError::Io {
            action: "read",
            path: csv.to_path_buf(),
            source,
        },
    })
}

/// Runs `modalforge chart`.
pub fn chart_command(args: &ChartArgs) -> Result<String, CliError> {
    std::fs::create_dir_all(&args.out).map_err(|source| CliError::Io {
        action: "create",
        path: args.out.clone(),
        source,
    })?;
    let methods = match &args.predictor {
        Some(csv) => {
            let text = read_csv(csv, "predictor CSV")?;
            methods_from_csv(&text)
                .map_err(|e| CliError::Option(format!("{}: {e}", csv.display())))?
        }
        None => Vec::new(),
    };
    if let Some(csv) = &args.from {
        let text = read_csv(csv, "chart CSV")?;
        let points =
            from_csv(&text).map_err(|e| CliError::Option(format!("{}: {e}", csv.display())))?;
        let png = args.out.join("chart.png");
        plot(&points, &methods, &png)?;
        return Ok(format!("wrote {} ({} runs)", png.display(), points.len()));
    }
    let points = sweep(args.quick, |p| {
        eprintln!(
            "{} {}^3 {} {} tol {:e}: {} dofs, {:.0} ms, mean error {:.3} %",
            p.shape,
            p.resolution,
            p.element,
            p.solver,
            p.tolerance,
            p.dofs,
            p.time_ms,
            p.mean_error_percent
        )
    })?;
    let csv = args.out.join("chart.csv");
    std::fs::write(&csv, to_csv(&points)).map_err(|source| CliError::Io {
        action: "write",
        path: csv.clone(),
        source,
    })?;
    let png = args.out.join("chart.png");
    plot(&points, &methods, &png)?;
    Ok(format!(
        "wrote {} and {} ({} runs)",
        csv.display(),
        png.display(),
        points.len()
    ))
}
