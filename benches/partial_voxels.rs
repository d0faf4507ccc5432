//! Partial voxels against the smooth geometry (issue 19): for every curved primitive with a
//! smooth reference (`tests/data/smooth_references.json`, `scripts/smooth_reference.py`), the
//! staircase and the partial-voxel (finite cell) rasterisations with each element kind:
//! - **split**: the largest frequency split of a degenerate group of the smooth solid among
//!   the lowest 12 modes (exactly 0 for the true object);
//! - **error**: the worst frequency error of the lowest 10 modes against the reference;
//! - **assembly**: the median time of `FemModel::assemble` (5 runs, one core), and the DOFs;
//! - **solve**: assembly and the solve of 16 modes to a residual of 1e-8 (one run, one core).
//!
//! `cargo bench --bench partial_voxels` (all shapes, hex8i, hex27x2 and hex27; hex27 only up to
//! 150k DOFs);
//! `-- --quick` for the two bowls, `-- --hex8i` without hex27; `-- --assembly [ELEMENT]`
//! times assembly alone on the two bowls, partial voxels against the staircase of the same
//! bowl (issue 19's "assembly within 2x"), for ELEMENT or all three; `--repeat N` repeats each
//! measurement N times, staircase and partial alternately, and keeps the fastest. `--assembly`
//! first tells glibc's allocator to keep freed memory (`mallopt`): otherwise whether an
//! assembly's matrices land in recycled memory or in fresh pages (a page fault per 4 kB) is
//! the allocator's luck, which moved the staircase's 16-voxel hex8i assembly between 1.0 and
//! 6.3 ms on a 2-core VM. Kept memory is also what a long-running worker re-assembling
//! after every edit gets; what remains is the work itself, zeroing the matrices included.

#[path = "../tests/common/smooth.rs"]
mod smooth;

use modalforge::basis::ModeBasis;
use modalforge::eigen::{EigenOptions, ModeCount, SolverKind};
use modalforge::fem::{ElementKind, FemModel};
use modalforge::shape::spec::ShapeSpec;
use modalforge::shape::VoxelGrid;
use std::time::Instant;

/// Largest hex27 model the full run solves (the 32-voxel bowl's is 137k DOFs, ~10 s).
const MAX_HEX27_DOFS: usize = 150_000;

fn median_assembly_ms(grid: &VoxelGrid, kind: ElementKind) -> (f64, usize) {
    let mut times = Vec::new();
    let mut dofs = 0;
    for _ in 0..5 {
        let t = Instant::now();
        let model = FemModel::assemble(grid, kind, smooth::NU).expect("assemble");
        times.push(t.elapsed().as_secs_f64() * 1e3);
        dofs = model.dofs();
    }
    times.sort_by(f64::total_cmp);
    (times[2], dofs)
}

fn main() {
    faer::set_global_parallelism(faer::Par::Seq);
    let quick = std::env::args().any(|a| a == "--quick");
    let only_hex8i = std::env::args().any(|a| a == "--hex8i");
    if std::env::args().any(|a| a == "--assembly") {
        keep_freed_memory();
        assembly_ratios();
        return;
    }
    println!(
        "{:<24} {:<9} {:<8} {:>7} {:>9} {:>9} {:>12} {:>9}",
        "shape", "voxels", "element", "DOFs", "split %", "error %", "assembly ms", "solve ms"
    );
    for spec in smooth::specs() {
        if quick && !spec.starts_with("bowl") {
            continue;
        }
        let want = smooth::reference(&spec);
        let ShapeSpec::Primitive { shape, .. } = spec.parse::<ShapeSpec>().expect("spec") else {
            panic!("{spec}: not a primitive")
        };
        for (voxels, grid) in [
            (
                "staircase",
                shape.rasterize_staircase(1.0, 1.0).expect("raster"),
            ),
            ("partial", shape.rasterize(1.0, 1.0).expect("raster")),
        ] {
            for kind in [
                ElementKind::Hex8Incompatible,
                ElementKind::Hex27Blocks,
                ElementKind::Hex27,
            ] {
                if only_hex8i && kind == ElementKind::Hex27 {
                    continue;
                }
                let (ms, dofs) = median_assembly_ms(&grid, kind);
                if kind == ElementKind::Hex27 && dofs > MAX_HEX27_DOFS {
                    continue;
                }
                let options = EigenOptions {
                    count: ModeCount::First(16),
                    tolerance: 1e-8,
                    ..EigenOptions::default()
                };
                let t = Instant::now();
                let basis = ModeBasis::solve(&grid, kind, smooth::NU, SolverKind::Auto, &options)
                    .expect("solve");
                let solve_ms = t.elapsed().as_secs_f64() * 1e3;
                let got = &basis.solution.eigenvalues;
                let (split, _) = smooth::worst_split(got, &want, 12);
                let error = smooth::worst(&smooth::frequency_errors(got, &want, 10));
                println!(
                    "{spec:<24} {voxels:<9} {:<8} {dofs:>7} {split:>9.3} {error:>9.2} {ms:>12.1} \
                     {solve_ms:>9.0}",
                    kind.to_string()
                );
            }
        }
    }
}

/// Makes glibc keep freed memory for reuse: no allocation is served by a fresh `mmap` and the
/// heap is never trimmed, so every assembly after the first works in recycled memory.
fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: `mallopt` only changes the allocator's thresholds; it is called before any
    // other thread exists (faer is sequential here), as glibc asks.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 1 << 30);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 1 << 30);
    }
}

/// `--assembly [ELEMENT] [--repeat N]`: the two bowls' assembly, partial voxels over staircase.
fn assembly_ratios() {
    let args: Vec<String> = std::env::args().collect();
    let after = |flag: &str| {
        args.iter()
            .skip_while(|a| *a != flag)
            .nth(1)
            .map(String::as_str)
    };
    let kinds: Vec<ElementKind> = match after("--assembly")
        .and_then(|name| <ElementKind as clap::ValueEnum>::from_str(name, true).ok())
    {
        Some(kind) => vec![kind],
        None => vec![
            ElementKind::Hex8Incompatible,
            ElementKind::Hex27Blocks,
            ElementKind::Hex27,
        ],
    };
    let repeat: usize = after("--repeat").and_then(|n| n.parse().ok()).unwrap_or(1);
    println!(
        "{:<18} {:<8} {:>13} {:>11} {:>6}",
        "shape", "element", "staircase ms", "partial ms", "ratio"
    );
    for spec in ["bowl:d=16,wall=2", "bowl:d=32,wall=2"] {
        let ShapeSpec::Primitive { shape, .. } = spec.parse::<ShapeSpec>().expect("spec") else {
            unreachable!()
        };
        let staircase = shape.rasterize_staircase(1.0, 1.0).expect("raster");
        let partial = shape.rasterize(1.0, 1.0).expect("raster");
        for &kind in &kinds {
            // Alternately, so that the machine's drift falls on both alike.
            let (mut s, mut p) = (f64::INFINITY, f64::INFINITY);
            for _ in 0..repeat {
                s = s.min(median_assembly_ms(&staircase, kind).0);
                p = p.min(median_assembly_ms(&partial, kind).0);
            }
            println!(
                "{spec:<18} {:<8} {s:>13.1} {p:>11.1} {:>6.2}",
                kind.to_string(),
                p / s
            );
        }
    }
}
