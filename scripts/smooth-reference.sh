#!/usr/bin/env bash
# Smooth-geometry references for the curved primitives (issue 19): gmsh meshes the true
# curved solids, scikit-fem solves them with curved quadratic tetrahedra at two or three mesh
# sizes (scripts/smooth_reference.py). A validation script, not a test dependency: the tests
# read the committed tests/data/smooth_references.json. Takes about 15 minutes.
#   bash scripts/smooth-reference.sh                       # every shape -> target/smooth/
#   bash scripts/smooth-reference.sh bowl:d=16,wall=2      # one shape
#   cp target/smooth/references.json tests/data/smooth_references.json
set -euo pipefail
cd "$(dirname "$0")/.."
venv=target/smooth-venv
source scripts/need.sh
venv_need "$venv" gmsh scikit-fem scipy numpy meshio
mkdir -p target/smooth
"$venv/bin/python" scripts/smooth_reference.py "$@" > target/smooth/references.json
echo "wrote target/smooth/references.json"
