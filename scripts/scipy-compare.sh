#!/usr/bin/env bash
# Side-by-side benchmark (issue 13): this project's eigensolver against SciPy's eigsh
# (ARPACK shift-invert on SuperLU) on the same assembled matrices, at 1k-59k DOFs, 20 and 60
# modes, one core. A benchmark, not a test: SciPy goes into a venv under target/.
#   bash scripts/scipy-compare.sh            # -> target/scipy-compare/report.txt
set -euo pipefail
cd "$(dirname "$0")/.."
out=target/scipy-compare
venv=target/scipy-venv
source scripts/need.sh
venv_need "$venv" scipy numpy
cargo bench --locked --bench interactive -- --scipy "$out"
OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 \
  "$venv/bin/python" scripts/scipy_eigsh.py "$out" | tee "$out/report.txt"
