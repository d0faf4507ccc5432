//! The time from a sculpting edit to exact modes, on one core: what a sound designer waits for.
//!
//! `cargo bench --bench interactive` prints, for the plugin's default object and every preset
//! in `presets/objects/` (60 modes and hex27x2, the plugin's defaults, or `-- --element
//! hex8i`; the preset's material's Poisson's ratio; residual 1e-6):
//! - **cold**: assembly + a solve from scratch (the time split, the solver that ran), the
//!   median of [`COLD_RUNS`] runs;
//! - **ritz / warm**: after a one-voxel brush stroke (a voxel added on the surface, then one
//!   removed), the instant carried answer as the engine plays it
//!   ([`ModeBasis::carried_ritz_factored`]) and the exact modes refined from the previous
//!   shape's ([`ModeBasis::solve_warm`]) with its iterations, each with the largest
//!   frequency difference from a cold solve of the same edited shape;
//! - **exact~**: the exact answer (the chain's, element cache included) to a stroke made in
//!   the editor's mirror mode on the object as loaded: the added voxel and its images across
//!   every centre plane the object is symmetric in, which keeps its mirrors (a lone stroke's
//!   exact answer is a whole solve, `exact+`);
//! - **coarse**: the progressive first answer ([`modalforge::engine::solve_coarse`]: the
//!   object at half the resolution, its known stiffening divided out), its time
//!   (marked `*` where the chain plays it: the exact solve is predicted to take longer than
//!   [`PROGRESSIVE_BUDGET_MS`]) and the mean frequency error of its lowest 10 modes against
//!   the exact ones.
//!
//! `-- --quick` runs the default object only, `-- --only NAME` the objects whose name holds
//! NAME (`-- --only cup`); `-- --scipy DIR` exports the matrices and this
//! solver's answers for the SciPy comparison (`scripts/scipy-compare.sh`).
//!
//! `-- --drag [INTERVAL_MS] [--strokes K]` measures the engine as the plugin runs it: a drag
//! of K (default 24) one-voxel strokes on the default object (or `--only NAME`'s), one every
//! INTERVAL_MS (default 60), through the plugin's solver chain on the worker thread; for each
//! stroke, the time from its request until an answer to it (or to a later stroke) plays, the
//! largest frequency error of each carried answer played against the exact modes of its
//! shape, and the time from the last stroke to its exact answer playing: with the worker
//! leaving an exact solve that a newer stroke has made obsolete on its helper thread (stopped
//! at its next poll, or finished when the solver asks: the engine as the plugin runs it), and
//! for comparison with every obsolete run stopped (the engine before the exact solver
//! finished some), with the worker waiting for that solve's next poll (in place) and with
//! every solve run to its end; and the carried answer's largest error after 1, 4 and 12
//! strokes from the exact answer before the drag (what a drag that keeps interrupting played
//! before).

use modalforge::basis::ModeBasis;
use modalforge::eigen::{EigenOptions, ModeCount, SolverKind, Stop};
use modalforge::engine::{predicted_cold_ms, solve_coarse, PROGRESSIVE_BUDGET_MS};
use modalforge::fem::{ElementCache, ElementKind, FemModel};
use modalforge::material::Material;
use modalforge::shape::spec::{self, ShapeSpec};
use modalforge::shape::VoxelGrid;
use std::time::Instant;

/// The plugin's default mode count.
const MODES: usize = 60;

/// Cold solves per object; the median is reported.
const COLD_RUNS: usize = 3;

/// The voxels of a built-in shape as the plugin and the command line make them for `kind`
/// (centred on its blocks for hex27x2: `spec::primitive_voxels`).
fn grid_of(spec: &str, kind: ElementKind) -> VoxelGrid {
    match spec.parse::<ShapeSpec>().expect("shape spec") {
        ShapeSpec::Primitive { shape, hollow } => {
            spec::primitive_voxels(&shape, hollow, 1.0, kind.voxels_per_element())
                .expect("rasterise")
        }
        _ => panic!("presets use built-in shapes"),
    }
}

/// `(name, shape spec, Poisson's ratio)` of the default object and every object preset.
fn objects(quick: bool) -> Vec<(String, String, f64)> {
    let glass = Material::preset("glass").expect("glass").poisson_ratio;
    let mut out = vec![("default".to_string(), "bowl:d=16,wall=2".to_string(), glass)];
    if quick {
        return out;
    }
    // Larger thick-walled and solid objects, where the coarse first answer applies.
    let steel = Material::preset("steel").expect("steel").poisson_ratio;
    out.push(("sphere d=24".into(), "sphere:d=24".into(), steel));
    out.push(("bowl d=32 w=4".into(), "bowl:d=32,wall=4".into(), glass));
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/presets/objects");
    let mut files: Vec<_> = std::fs::read_dir(dir)
        .expect("presets")
        .map(|e| e.expect("entry").path())
        .collect();
    files.sort();
    for path in files {
        let text = std::fs::read_to_string(&path).expect("preset");
        let table: toml::Table = text.parse().expect("preset TOML");
        let (Some(shape), Some(material)) = (
            table.get("shape").and_then(|v| v.as_str()),
            table.get("material").and_then(|v| v.as_str()),
        ) else {
            continue;
        };
        let nu = Material::preset(material).expect("material").poisson_ratio;
        let name = path.file_stem().unwrap().to_string_lossy().to_string();
        out.push((name, shape.to_string(), nu));
    }
    out
}

/// A one-voxel stroke: adds (or removes) the surface voxel nearest the grid's top-front
/// quarter point, deterministically.
fn stroke(grid: &VoxelGrid, add: bool) -> VoxelGrid {
    let d = grid.dims();
    let target = [d[0] as f64 * 0.3, d[1] as f64 * 0.7, d[2] as f64];
    let mut best: Option<([usize; 3], f64)> = None;
    for x in 0..d[0] {
        for y in 0..d[1] {
            for z in 0..d[2] {
                let (xi, yi, zi) = (x as isize, y as isize, z as isize);
                let solid = grid.get(xi, yi, zi);
                let nb = [
                    (1, 0, 0),
                    (-1, 0, 0),
                    (0, 1, 0),
                    (0, -1, 0),
                    (0, 0, 1),
                    (0, 0, -1),
                ];
                let touching = nb.iter().any(|(a, b, c)| grid.get(xi + a, yi + b, zi + c));
                let exposed = nb.iter().any(|(a, b, c)| !grid.get(xi + a, yi + b, zi + c));
                let ok = if add {
                    !solid && touching
                } else {
                    solid && exposed
                };
                if ok {
                    let dist = (x as f64 - target[0]).powi(2)
                        + (y as f64 - target[1]).powi(2)
                        + (z as f64 - target[2]).powi(2);
                    if best.is_none_or(|b| dist < b.1) {
                        best = Some(([x, y, z], dist));
                    }
                }
            }
        }
    }
    let Some(([x, y, z], _)) = best else {
        // A full box (a plate, a bar): grow the grid by a layer on top and add the voxel
        // there, every voxel below keeping its fill (a centred bar's faces are half full).
        let mut out = VoxelGrid::new([d[0], d[1], d[2] + 1], grid.voxel_size_m()).expect("grid");
        for [x, y, z] in grid.solid_voxels() {
            out.set_fill(x, y, z, grid.fill_at(x as isize, y as isize, z as isize));
        }
        out.set(d[0] * 3 / 10, d[1] * 7 / 10, d[2], true);
        return out;
    };
    let mut out = grid.clone();
    out.set(x, y, z, add);
    out
}

/// The chain's exact answer to `grid` (a cold solve whose assembly reuses the cut elements
/// in `cache`) and its time, ms.
fn chain_exact(
    grid: &VoxelGrid,
    kind: ElementKind,
    nu: f64,
    options: &EigenOptions,
    cache: &mut ElementCache,
) -> (ModeBasis, f64) {
    let t = Instant::now();
    let exact = ModeBasis::solve_cached(
        grid,
        kind,
        nu,
        SolverKind::Auto,
        options,
        Some(cache),
        modalforge::eigen::Stop::NEVER,
    )
    .expect("exact");
    (exact, t.elapsed().as_secs_f64() * 1e3)
}

/// [`stroke`]'s added voxel with its images across each centre plane of the grid that the
/// grid is a mirror image in (fills compared by fraction): the editor's mirror mode on a
/// symmetric object, which keeps the object's mirrors, so the exact answer to the stroke is
/// solved class by class (`eigen::symmetric`) where a lone stroke's is solved whole.
fn mirrored_stroke(grid: &VoxelGrid) -> VoxelGrid {
    let one = stroke(grid, true);
    let d = grid.dims();
    if one.dims() != d {
        return one; // the grown plate
    }
    let flip = |v: [usize; 3], a: usize| {
        let mut m = v;
        m[a] = d[a] - 1 - v[a];
        m
    };
    let at = |g: &VoxelGrid, v: [usize; 3]| g.fraction(v[0] as isize, v[1] as isize, v[2] as isize);
    let solid = grid.solid_voxels();
    let planes: Vec<usize> = (0..3)
        .filter(|&a| solid.iter().all(|&v| at(grid, v) == at(grid, flip(v, a))))
        .collect();
    let mut out = one.clone();
    for v in one.solid_voxels() {
        if at(grid, v) > 0.0 {
            continue;
        }
        let mut images = vec![v];
        for &a in &planes {
            images = images.iter().flat_map(|&u| [u, flip(u, a)]).collect();
        }
        for u in images {
            out.set(u[0], u[1], u[2], true);
        }
    }
    out
}

/// `--quick`: the carried answer with the chain's element cache and without one, interleaved,
/// the median of five each (what [`ElementCache`] saves, measured side by side on a shared
/// machine whose absolute times drift).
fn cache_effect(
    edited: &VoxelGrid,
    kind: ElementKind,
    nu: f64,
    previous: &ModeBasis,
    cache: &ElementCache,
) {
    let (mut with, mut without) = (Vec::new(), Vec::new());
    for _ in 0..5 {
        for cached in [true, false] {
            let mut chain_cache = cache.clone();
            let t = Instant::now();
            let c = ModeBasis::carried_ritz(
                edited,
                kind,
                nu,
                MODES,
                previous,
                cached.then_some(&mut chain_cache),
            );
            let ms = t.elapsed().as_secs_f64() * 1e3;
            assert!(matches!(c, Some(Ok(_))), "a carried answer");
            if cached { &mut with } else { &mut without }.push(ms);
        }
    }
    with.sort_by(f64::total_cmp);
    without.sort_by(f64::total_cmp);
    println!(
        "  carried answer with the chain's element cache {:.1} ms, without {:.1} ms (median of 5)",
        with[2], without[2]
    );
}

fn max_relative_difference(a: &ModeBasis, b: &ModeBasis) -> f64 {
    let (la, lb) = (&a.solution.eigenvalues, &b.solution.eigenvalues);
    la.iter()
        .zip(lb)
        .map(|(x, y)| ((x.sqrt() - y.sqrt()) / y.sqrt()).abs())
        .fold(0.0, f64::max)
}

/// `--scipy DIR`: the matrices of objects from 1k to 60k DOFs in Matrix Market files (reference
/// units, hex8i), with this solver's time and eigenvalues for 20 and 60 modes in
/// `DIR/ours.csv`, for `scripts/scipy-compare.sh` to solve the same problems with SciPy.
fn export_for_scipy(dir: &std::path::Path) {
    /// Problems under this many DOFs are timed as the best of three runs, on both sides.
    const REPEATED_BELOW_DOFS: usize = 10_000;
    use modalforge::fem::sparse::{mass_as_blocks, permuted_shifted_csc, BlockMass};
    use std::io::Write;
    std::fs::create_dir_all(dir).expect("output folder");
    let mut csv = std::fs::File::create(dir.join("ours.csv")).expect("ours.csv");
    writeln!(csv, "name,dofs,modes,solver,ms,max_residual,eigenvalues").unwrap();
    let nu = 0.3;
    let objects = [
        ("bar-1k", "bar:l=30,w=3,h=3"),
        ("bowl-4k", "bowl:d=16,wall=2"),
        ("bowl-15k", "bowl:d=32,wall=2"),
        ("sphere-8k", "sphere:d=16"),
        ("sphere-59k", "sphere:d=32"),
    ];
    for (name, spec) in objects {
        let grid = grid_of(spec, ElementKind::Hex8Incompatible);
        let model = FemModel::assemble(&grid, ElementKind::Hex8Incompatible, nu).expect("model");
        // The mass as 3x3 blocks, for the same CSC writer (`K - 0 M` is `K`).
        let mass_blocks = mass_as_blocks(model.m());
        let in_order: Vec<usize> = (0..model.nodes()).collect();
        for (which, a) in [("K", model.k()), ("M", &mass_blocks)] {
            let upper = permuted_shifted_csc(
                &model.pattern,
                a,
                BlockMass::Scalar(model.m()),
                0.0,
                &in_order,
                faer::Side::Upper,
            );
            let path = dir.join(format!("{name}-{which}.mtx"));
            let mut f = std::io::BufWriter::new(std::fs::File::create(path).expect("mtx"));
            let n = upper.nrows();
            let (cp, ri, v) = (
                upper.symbolic().col_ptr(),
                upper.symbolic().row_idx(),
                upper.val(),
            );
            writeln!(f, "%%MatrixMarket matrix coordinate real symmetric").unwrap();
            // Upper triangle by column = lower triangle by row of the symmetric matrix.
            writeln!(f, "{n} {n} {}", v.len()).unwrap();
            for c in 0..n {
                for k in cp[c]..cp[c + 1] {
                    writeln!(f, "{} {} {:.17e}", c + 1, ri[k] + 1, v[k]).unwrap();
                }
            }
        }
        for modes in [20usize, 60] {
            let options = EigenOptions {
                count: ModeCount::First(modes),
                ..Default::default()
            };
            // The best of three runs under 10k DOFs (a first run in the process pays for
            // fresh memory and caches; `scipy_eigsh.py` times its side the same way).
            let runs = if model.dofs() < REPEATED_BELOW_DOFS {
                3
            } else {
                1
            };
            let (mut ms, mut sol) = (f64::INFINITY, None);
            for _ in 0..runs {
                let t = Instant::now();
                let s =
                    modalforge::eigen::solve(&model, SolverKind::Auto, &options).expect("solve");
                ms = ms.min(t.elapsed().as_secs_f64() * 1e3);
                sol = Some(s);
            }
            let sol = sol.expect("one run");
            let worst = sol.residuals.iter().cloned().fold(0.0, f64::max);
            let values: Vec<String> = sol
                .eigenvalues
                .iter()
                .map(|l| format!("{l:.12e}"))
                .collect();
            writeln!(
                csv,
                "{name},{},{modes},{},{ms:.1},{worst:.2e},{}",
                model.dofs(),
                sol.solver,
                values.join(" ")
            )
            .unwrap();
            println!(
                "{name:<12} {:>6} DOFs {modes:>3} modes: {ms:>8.1} ms ({})",
                model.dofs(),
                sol.solver
            );
        }
    }
}

fn main() {
    faer::set_global_parallelism(faer::Par::Seq);
    let args: Vec<String> = std::env::args().collect();
    if let Some(i) = args.iter().position(|a| a == "--drag") {
        let interval_ms = args.get(i + 1).and_then(|v| v.parse().ok()).unwrap_or(60);
        // `--only NAME`: the first object whose name holds NAME, else the default object.
        let only = args
            .iter()
            .position(|a| a == "--only")
            .and_then(|i| args.get(i + 1));
        let (name, spec, nu) = objects(only.is_none())
            .into_iter()
            .find(|(name, _, _)| only.is_none_or(|o| name.contains(o.as_str())))
            .expect("--only: no object by that name");
        let strokes = args
            .iter()
            .position(|a| a == "--strokes")
            .and_then(|i| args.get(i + 1))
            .map(|k| k.parse().expect("--strokes K"))
            .unwrap_or(drag::STROKES);
        drag::run(interval_ms, strokes, &name, &spec, nu);
        return;
    }
    if let Some(i) = args.iter().position(|a| a == "--scipy") {
        export_for_scipy(std::path::Path::new(args.get(i + 1).expect("--scipy DIR")));
        return;
    }
    let quick = args.iter().any(|a| a == "--quick");
    let options = EigenOptions {
        count: ModeCount::First(MODES),
        ..Default::default()
    };
    let kind = args
        .iter()
        .position(|a| a == "--element")
        .and_then(|i| args.get(i + 1))
        .map(|name| {
            <ElementKind as clap::ValueEnum>::from_str(name, true).expect("--element hex8i|...")
        })
        .unwrap_or(ElementKind::Hex27Blocks);
    println!("\nedit-to-modes, one core, {MODES} modes, residual 1e-6 (ms), {kind}");
    println!(
        "{:<16} {:>6} | {:>6} {:>6} {:>6} {:>7} {:>8} | {:>6} {:>7} {:>5} {:>7} {:>7} {:>4} {:>8} | {:>6} {:>7} {:>5} {:>7} {:>7} {:>4} {:>8} | {:>7} | {:>7} {:>7}",
        "object", "dofs", "asm", "setup", "iter", "cold", "solver", "ritz+", "err", "asm+",
        "exact+", "warm+", "its", "err", "ritz-", "err", "asm-", "exact-", "warm-", "its", "err",
        "exact~", "coarse", "err10"
    );
    let only = args
        .iter()
        .position(|a| a == "--only")
        .map(|i| args.get(i + 1).expect("--only NAME").clone());
    let wanted = objects(quick)
        .into_iter()
        .filter(|(name, _, _)| only.as_ref().is_none_or(|o| name.contains(o.as_str())));
    for (name, spec, nu) in wanted {
        let grid = grid_of(&spec, kind);
        // The median of a few cold solves: one run varies by 10 % on a shared machine.
        let mut colds: Vec<(f64, ModeBasis)> = (0..COLD_RUNS)
            .map(|_| {
                let t = Instant::now();
                let cold =
                    ModeBasis::solve(&grid, kind, nu, SolverKind::Auto, &options).expect("cold");
                (t.elapsed().as_secs_f64() * 1e3, cold)
            })
            .collect();
        colds.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (cold_ms, cold) = colds.swap_remove(COLD_RUNS / 2);
        // The chain's element cache, as the cold answer leaves it.
        let mut cache = ElementCache::new();
        FemModel::assemble_cached(&grid, kind, nu, Some(&mut cache)).expect("model");
        let mut warm_cols = Vec::new();
        // Shared, as the engine's chain holds it: the carried answer keeps its vectors as
        // factors over it (`ModeBasis::carried_ritz_factored`).
        let mut previous = std::sync::Arc::new(cold.clone());
        let mut current = grid.clone();
        for add in [true, false] {
            let edited = stroke(&current, add);
            // The median of a few carried answers, each from the cache as the chain has it
            // before the stroke (one run varies by tens of percent on a shared machine). Each
            // answer is dropped once the next one is made, as the engine's worker frees a
            // played answer once the audio thread retires it: the next but one reuses its
            // matrices' memory (`crate::buffer`).
            // The engine's exact solver keeps these after its solve, outside a stroke's time.
            previous.exact_grams();
            let mut carried_runs = Vec::with_capacity(COLD_RUNS);
            let mut last = None;
            for _ in 0..COLD_RUNS {
                let mut chain_cache = cache.clone();
                let t = Instant::now();
                let carried = ModeBasis::carried_ritz_factored(
                    &edited,
                    kind,
                    nu,
                    MODES,
                    &previous,
                    Some(&mut chain_cache),
                )
                .expect("comparable");
                carried_runs.push(t.elapsed().as_secs_f64() * 1e3);
                last = Some((carried, chain_cache));
            }
            carried_runs.sort_by(f64::total_cmp);
            let carried_ms = carried_runs[COLD_RUNS / 2];
            let (carried, after) = last.expect("runs");
            if quick {
                cache_effect(&edited, kind, nu, &previous, &cache);
            }
            cache = after;
            // The chain's exact answer: a cold solve, its assembly reusing the cut elements.
            let (exact, exact_ms) = chain_exact(&edited, kind, nu, &options, &mut cache);
            let t = Instant::now();
            let warm =
                ModeBasis::solve_warm(&edited, kind, nu, SolverKind::Auto, &options, &previous)
                    .expect("warm");
            let warm_ms = t.elapsed().as_secs_f64() * 1e3;
            let reference = ModeBasis::solve(&edited, kind, nu, SolverKind::Lanczos, &options)
                .expect("cold of the edit");
            let tag = if warm.solution.warm_start { "" } else { "*" };
            // No carried answer where the stroke joins or splits parts.
            let (carried_ms, carried_err) = match &carried {
                Ok(c) => (
                    format!("{carried_ms:>6.1}"),
                    format!("{:>7.1e}", max_relative_difference(c, &reference)),
                ),
                Err(_) => (format!("{:>6}", "-"), format!("{:>7}", "-")),
            };
            let exact_err = max_relative_difference(&exact, &reference);
            assert!(
                exact_err < 1e-7,
                "the cached assembly's modes: {exact_err:e}"
            );
            warm_cols.push(format!(
                "{carried_ms} {carried_err} {:>5.1} {:>7.1} {:>7.1} {:>3}{tag:1} {:>8.1e}",
                exact.assemble_ms,
                exact_ms,
                warm_ms,
                warm.solution.iterations,
                max_relative_difference(&warm, &reference)
            ));
            previous = std::sync::Arc::new(warm);
            current = edited;
        }
        // The editor's mirror mode: the stroke and its images, from the object as loaded.
        let mirrored = mirrored_stroke(&grid);
        let (_, mirrored_ms) = chain_exact(&mirrored, kind, nu, &options, &mut cache);
        let t = Instant::now();
        let coarse = solve_coarse(
            &grid,
            kind,
            nu,
            SolverKind::Auto,
            &options,
            None,
            Stop::NEVER,
        )
        .ok();
        let coarse_ms = t.elapsed().as_secs_f64() * 1e3;
        let (coarse_ms, err) = match &coarse {
            Some(c) => {
                // Reference units differ by the voxel size: frequency scales by 1/h, the
                // coarse voxel is twice the edge.
                let pairs = c
                    .solution
                    .eigenvalues
                    .iter()
                    .zip(&cold.solution.eigenvalues);
                let errs: Vec<f64> = pairs
                    .take(10)
                    .map(|(c, f)| ((c.sqrt() / 2.0 - f.sqrt()) / f.sqrt()).abs())
                    .collect();
                // `*`: the chain plays it (the exact solve is predicted over the budget).
                let played = predicted_cold_ms(&grid, kind, options.count) > PROGRESSIVE_BUDGET_MS;
                (
                    format!("{coarse_ms:>6.1}{}", if played { "*" } else { " " }),
                    format!(
                        "{:>6.1}%",
                        100.0 * errs.iter().sum::<f64>() / errs.len() as f64
                    ),
                )
            }
            None => (format!("{:>7}", "-"), format!("{:>7}", "-")),
        };
        println!(
            "{:<16} {:>6} | {:>6.1} {:>6.1} {:>6.1} {:>7.1} {:>8} | {} | {} | {:>7.1} | {} {}",
            name,
            cold.model.dofs(),
            cold.assemble_ms,
            cold.solution.timings.setup_ms,
            cold.solution.timings.iterate_ms,
            cold_ms,
            cold.solver,
            warm_cols[0],
            warm_cols[1],
            mirrored_ms,
            coarse_ms,
            err
        );
    }
    println!(
        "+: a voxel added, -: then one removed. ritz: the instant carried answer; asm, exact: the \
         chain's exact answer (a cold solve whose assembly reuses the untouched cut elements, \
         ElementCache) and its assembly; warm: the exact warm-started solve (* = fell back to \
         cold); err: largest relative frequency difference from a cold solve of the edited shape; \
         exact~: the exact answer to a voxel added in the editor's mirror mode (with its mirror \
         images, so the object keeps its mirrors); coarse: the progressive first answer (half \
         the resolution, fills kept), * where the chain plays it before the exact one"
    );
}

/// `--drag`: edit-to-sound latency of a sculpting drag through the engine's worker.
#[path = "interactive/drag.rs"]
mod drag;
