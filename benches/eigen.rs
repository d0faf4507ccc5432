//! Modal-analysis speed: the kernels (block SpMM, one multigrid V-cycle) and whole solves of the
//! papers' 32^3 benchmark objects.
//!
//! `cargo bench --bench eigen` runs criterion over the kernels, then prints a table of whole
//! solves (time split: assembly, factorisation or multigrid setup, iterations) for a solid
//! sphere and a hollow bowl (wall 2 voxels) in a 32^3 grid, 20 and 80 modes, residual 1e-6
//! (Jin et al. 2022, Table 1), every solver and element, plus the 64^3 sphere.
//! `cargo bench --bench eigen -- --table` prints only the table; `--quick` only the 32^3 rows
//! with 20 modes; a criterion filter (`-- factor_bowl16`, `-- solve_bowl16`) only the kernels
//! it names.

use criterion::{BenchmarkId, Criterion, Throughput};
use faer::Par;
use modalforge::eigen::factor::ShiftedCholesky;
use modalforge::eigen::multigrid::Multigrid;
use modalforge::eigen::{self, EigenOptions, ModeCount, SolverKind, Stop};
use modalforge::fem::sparse::{self, RowBlock};
use modalforge::fem::{ElementKind, FemModel};
use modalforge::shape::primitives::Primitive;
use modalforge::shape::VoxelGrid;
use std::hint::black_box;
use std::time::Instant;

fn sphere(n: usize) -> VoxelGrid {
    let diameter = n as f64;
    Primitive::Sphere { diameter }
        .rasterize(1.0, 1.0)
        .expect("sphere")
}

fn bowl(n: usize) -> VoxelGrid {
    let diameter = n as f64;
    Primitive::Bowl {
        diameter,
        wall: 2.0,
    }
    .rasterize(1.0, 1.0)
    .expect("bowl")
}

fn kernels(c: &mut Criterion) {
    let model = FemModel::assemble(&sphere(32), ElementKind::Hex8, 0.3).expect("model");
    let n = model.dofs();
    let mut group = c.benchmark_group("spmm_sphere32_hex8");
    for width in [1usize, 8, 32] {
        let x = vec![1.0; n * width];
        let mut y = vec![0.0; n * width];
        group.throughput(Throughput::Elements(
            (model.pattern.col.len() * 9 * width) as u64,
        ));
        group.bench_with_input(BenchmarkId::from_parameter(width), &width, |b, &w| {
            b.iter(|| {
                sparse::spmm(
                    &model.pattern,
                    model.k(),
                    black_box(&x),
                    &mut y,
                    RowBlock::dense(w),
                )
            })
        });
    }
    group.finish();
    // The mass product, on general 3x3 blocks against its own scalars (`M_ab I3`), on the
    // plugin's default object and element, for a Lanczos block (8) and the instant answer's
    // carried block (74 columns).
    let bowl16 = FemModel::assemble(&bowl(16), ElementKind::Hex27Blocks, 0.24).expect("model");
    let nb = bowl16.dofs();
    let mass_blocks = sparse::mass_as_blocks(bowl16.m());
    let mut group = c.benchmark_group("mass_spmm_bowl16_hex27x2");
    for width in [8usize, 74] {
        let x = vec![1.0; nb * width];
        let mut y = vec![0.0; nb * width];
        let layout = RowBlock::dense(width);
        group.bench_with_input(BenchmarkId::new("blocks", width), &width, |b, _| {
            b.iter(|| sparse::spmm(&bowl16.pattern, &mass_blocks, black_box(&x), &mut y, layout))
        });
        group.bench_with_input(BenchmarkId::new("scalar", width), &width, |b, _| {
            b.iter(|| sparse::spmm_mass(&bowl16.pattern, bowl16.m(), black_box(&x), &mut y, layout))
        });
    }
    group.finish();
    // The shifted Cholesky factor of the same object: symbolic and numeric, against the
    // numeric factorisation alone on a pattern factored before (`ShiftedCholesky::new` keeps
    // the symbolic factorisation of the last patterns: a stroke inside a hex27x2 block that
    // stays occupied, another Poisson's ratio).
    let shift = -1e-3 * eigen::Operators::new(&bowl16).scale;
    let nodes = modalforge::fem::ordering::nested_dissection(&bowl16);
    let mut group = c.benchmark_group("factor_bowl16_hex27x2");
    group.sample_size(10);
    group.bench_function("symbolic_and_numeric", |b| {
        b.iter(|| {
            ShiftedCholesky::from_blocks(&bowl16.pattern, bowl16.k(), bowl16.m(), shift, &nodes)
                .expect("factor")
        })
    });
    group.bench_function("kept_symbolic", |b| {
        b.iter(|| ShiftedCholesky::new(&bowl16, shift, Stop::NEVER).expect("factor"))
    });
    group.finish();
    // One Lanczos block's triangular solves with that factor (the whole model's: a lone
    // stroke's exact answer solves it whole), on the packed panels (`eigen/factor/rows.rs`).
    let mut llt = ShiftedCholesky::new(&bowl16, shift, Stop::NEVER).expect("factor");
    let mut group = c.benchmark_group("solve_bowl16_hex27x2");
    let width = 8;
    // Each solve starts from the same block (solving in place again and again would scale it
    // towards overflow or subnormals); the copy is ~1 % of the solve.
    let rhs = faer::Mat::<f64>::from_fn(nb, width, |i, j| ((i * 7 + j * 13) % 17) as f64);
    let mut x = rhs.clone();
    group.bench_with_input(BenchmarkId::from_parameter(width), &width, |b, _| {
        b.iter(|| {
            x.copy_from(&rhs);
            llt.solve_in_place(black_box(x.as_mut()))
        })
    });
    group.finish();
    let mut mg = Multigrid::new(&model, 32).expect("hierarchy");
    let mut group = c.benchmark_group("vcycle_sphere32_hex8");
    group.sample_size(10);
    for width in [8usize, 32] {
        let r = vec![1.0; n * width];
        let mut z = vec![0.0; n * width];
        group.bench_with_input(BenchmarkId::from_parameter(width), &width, |b, &w| {
            b.iter(|| {
                mg.apply(
                    black_box(&r),
                    RowBlock::dense(w),
                    &mut z,
                    RowBlock::dense(w),
                )
            })
        });
    }
    group.finish();
}

fn table(quick: bool) {
    faer::set_global_parallelism(Par::Seq);
    println!("\nwhole solves, one core, residual 1e-6 (ms)");
    println!(
        "{:<12} {:>6} {:>6} {:>8} {:>8} {:>9} {:>9} {:>9} {:>9} {:>6}",
        "object",
        "elem",
        "modes",
        "solver",
        "dofs",
        "assemble",
        "setup",
        "iterate",
        "total",
        "iters"
    );
    let mut cases: Vec<(&str, VoxelGrid, ElementKind, usize)> = Vec::new();
    for count in [20usize, 80] {
        if quick && count == 80 {
            continue;
        }
        for kind in [ElementKind::Hex8, ElementKind::Hex8Incompatible] {
            cases.push(("sphere 32^3", sphere(32), kind, count));
            cases.push(("bowl 32^3", bowl(32), kind, count));
        }
        cases.push(("bowl 32^3", bowl(32), ElementKind::Hex27, count));
    }
    if !quick {
        cases.push(("sphere 64^3", sphere(64), ElementKind::Hex8Incompatible, 20));
    }
    for (name, grid, kind, count) in cases {
        for solver in [SolverKind::Lobpcg, SolverKind::Lanczos] {
            let t = Instant::now();
            let model = FemModel::assemble(&grid, kind, 0.3).expect("model");
            let assemble_ms = t.elapsed().as_secs_f64() * 1e3;
            let options = EigenOptions {
                count: ModeCount::First(count),
                ..Default::default()
            };
            let t = Instant::now();
            match eigen::solve(&model, solver, &options) {
                Ok(s) => println!(
                    "{:<12} {:>6} {:>6} {:>8} {:>8} {:>9.0} {:>9.0} {:>9.0} {:>9.0} {:>6}",
                    name,
                    kind,
                    count,
                    solver,
                    model.dofs(),
                    assemble_ms,
                    s.timings.setup_ms,
                    s.timings.iterate_ms,
                    assemble_ms + t.elapsed().as_secs_f64() * 1e3,
                    s.iterations
                ),
                Err(e) => println!(
                    "{name:<12} {:>6} {count:>6} {:>8} failed: {e}",
                    kind, solver
                ),
            }
        }
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let quick = args.iter().any(|a| a == "--quick");
    if !(quick || args.iter().any(|a| a == "--table")) {
        let mut c = Criterion::default().configure_from_args();
        kernels(&mut c);
        c.final_summary();
    }
    // A criterion filter (`-- factor_bowl16`) runs the kernels it names, not the table.
    if !args.iter().skip(1).any(|a| !a.starts_with('-')) {
        table(quick);
    }
}
