#!/usr/bin/env bash
# Runs the host test (plugin/tests/host_test.py in pedalboard) on a build with nice-plug's
# `assert_process_allocs`: debug assertions on, so any allocation or free inside `process`
# aborts the host and fails the run. Optimised (opt-level 2) so the solves stay quick.
# The checked VST3 is copied to target/bundled-alloc-check/; target/bundled/ then holds this
# debug build: run scripts/bundle.sh again for release bundles.
set -euo pipefail
cd "$(dirname "$0")/.."
if ! cargo nice-plug --help >/dev/null 2>&1; then
  cargo install cargo-nice-plug --version 0.1.1 --locked
fi
export CARGO_PROFILE_DEV_OPT_LEVEL=2
cargo nice-plug bundle modalforge-plugin --features assert_process_allocs
rm -rf target/bundled-alloc-check
mkdir -p target/bundled-alloc-check
cp -r target/bundled/ModalForge.vst3 target/bundled-alloc-check/
cargo build --release --locked --bin modalforge
VENV=target/host-venv
if [ ! -x "$VENV/bin/python" ]; then
  python3 -m venv "$VENV" || { apt-get update -qq && apt-get install -y -qq python3-venv && python3 -m venv "$VENV"; }
fi
"$VENV/bin/pip" install -q --disable-pip-version-check pedalboard==0.9.* mido numpy
"$VENV/bin/python" plugin/tests/host_test.py target/bundled-alloc-check/ModalForge.vst3 target/release/modalforge
echo "no allocation in process (assert_process_allocs build)"
