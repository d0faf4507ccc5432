#!/usr/bin/env bash
# Issue 19's "assembly time within 2x of today's", against the assembly of the day the issue
# was filed: the commit before partial voxels (da66d9f: binary voxels only, no hex27x2) is
# checked out under target/, its assembly of the two staircase bowls timed beside this build's
# `cargo bench --bench partial_voxels -- --assembly` (partial voxels and the staircase), the
# two alternating for ROUNDS rounds on one core, the best of each kept (both sides the best of
# 3 medians of 5, the allocator keeping freed memory). A benchmark, not a test: the old build
# takes about 5 minutes the first time (DAY_TARGET_DIR: where it builds, default
# target/issue-day-build).
#   bash scripts/assembly-vs-issue-day.sh [ROUNDS]     # default 4
set -euo pipefail
cd "$(dirname "$0")/.."
rounds=${1:-4}
day=da66d9f
tree=target/issue-day
if [ ! -f "$tree/Cargo.toml" ]; then
  git worktree prune
  git worktree add --detach -f "$tree" "$day" >/dev/null
fi
mkdir -p "$tree/examples"
# The issue day's API: FemModel::assemble on a rasterised primitive (binary then).
cat >"$tree/examples/assembly_day.rs" <<'EOF'
//! The issue day's assembly of the two bowls (scripts/assembly-vs-issue-day.sh).
use modalforge::fem::{ElementKind, FemModel};
use modalforge::shape::spec::ShapeSpec;
use std::time::Instant;
fn main() {
    // SAFETY: only the allocator's thresholds, before any other thread exists.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 1 << 30);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 1 << 30);
    }
    faer::set_global_parallelism(faer::Par::Seq);
    for spec in ["bowl:d=16,wall=2", "bowl:d=32,wall=2"] {
        let ShapeSpec::Primitive { shape, .. } = spec.parse::<ShapeSpec>().unwrap() else {
            unreachable!()
        };
        let grid = shape.rasterize(1.0, 1.0).unwrap();
        for kind in [ElementKind::Hex8Incompatible, ElementKind::Hex27] {
            let mut best = f64::INFINITY;
            for _ in 0..3 {
                let mut runs: Vec<f64> = (0..5)
                    .map(|_| {
                        let t = Instant::now();
                        let model = FemModel::assemble(&grid, kind, 0.2).unwrap();
                        std::hint::black_box(&model);
                        t.elapsed().as_secs_f64() * 1e3
                    })
                    .collect();
                runs.sort_by(f64::total_cmp);
                best = best.min(runs[2]);
            }
            println!("{spec} {} {best:.2}", kind.name());
        }
    }
}
EOF
day_target=${DAY_TARGET_DIR:-target/issue-day-build}
CARGO_TARGET_DIR="$day_target" cargo build --locked --release --example assembly_day \
  --manifest-path "$tree/Cargo.toml" 2>&1 | tail -1
# The bench's own binary, as cargo names it (tests/partial_voxels.rs builds one of the same
# name into the same directory).
bench=$(cargo bench --locked --bench partial_voxels --no-run 2>&1 |
  sed -n 's/.*Executable benches\/partial_voxels.rs (\(.*\))$/\1/p')
log=target/issue-day.log
: >"$log"
for _ in $(seq "$rounds"); do
  taskset -c 0 "$day_target/release/examples/assembly_day" | sed 's/^/day /' >>"$log"
  taskset -c 0 "$bench" --assembly --repeat 3 | grep '^bowl' | sed 's/^/now /' >>"$log"
done
python3 - "$log" <<'EOF'
import sys
best = {}
for line in open(sys.argv[1]):
    f = line.split()
    cells = [("day", float(f[3]))] if f[0] == "day" else [("staircase", float(f[3])), ("partial", float(f[4]))]
    for tag, ms in cells:
        key = (tag, f[1], f[2])
        best[key] = min(best.get(key, float("inf")), ms)
print(f"{'shape':<18} {'element':<8} {'issue day':>10} {'staircase':>10} {'partial':>8} {'/day':>6} {'/staircase':>10}")
for spec in ["bowl:d=16,wall=2", "bowl:d=32,wall=2"]:
    for kind in ["hex8i", "hex27x2", "hex27"]:
        day = best.get(("day", spec, kind))
        s, p = best[("staircase", spec, kind)], best[("partial", spec, kind)]
        over_day = f"{p / day:6.2f}" if day else "     -"
        day_ms = f"{day:10.1f}" if day else "         -"
        print(f"{spec:<18} {kind:<8} {day_ms} {s:10.1f} {p:8.1f} {over_day} {p / s:10.2f}")
EOF
