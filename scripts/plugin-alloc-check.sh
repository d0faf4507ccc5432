#!/usr/bin/env bash
# Runs the host tests (plugin/tests/host_test.py in pedalboard, with its torture run, and
# plugin/tests/dawdreamer_torture.py in DawDreamer) on a build with nice-plug's
# `assert_process_allocs`: debug assertions on, so any allocation or free inside `process`
# aborts the host and fails the run. Optimised (opt-level 2) so the solves stay quick.
# The checked VST3 is copied to target/bundled-alloc-check/; target/bundled/ then holds this
# debug build: run scripts/bundle.sh again for release bundles.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/need.sh
export CARGO_PROFILE_DEV_OPT_LEVEL=2
bash scripts/bundle.sh --debug --features assert_process_allocs
rm -rf target/bundled-alloc-check
mkdir -p target/bundled-alloc-check
cp -r target/bundled/ModalForge.vst3 target/bundled-alloc-check/
cargo build --release --locked --bin modalforge
host_venv_need
VENV=target/host-venv
"$VENV/bin/python" plugin/tests/host_test.py target/bundled-alloc-check/ModalForge.vst3 target/release/modalforge
"$VENV/bin/python" plugin/tests/dawdreamer_torture.py target/bundled-alloc-check/ModalForge.vst3
echo "no allocation in process (assert_process_allocs build)"
