#!/usr/bin/env bash
# Builds the VST3/CLAP bundles and runs the plugin in real third-party hosts: pedalboard,
# checking its spectrum against `modalforge modes` and torturing it (plugin/tests/host_test.py),
# and DawDreamer, automating every parameter every block (plugin/tests/dawdreamer_torture.py).
# Installs what it needs: a Python venv with both hosts (and, off Linux, cargo-nice-plug).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/bundle.sh
# `--tests` resolves features as `cargo test --release` does (dev-dependencies included), so
# after scripts/test.sh's test run this builds nothing; a plain `--bin` build recompiled faer.
cargo build --release --locked --bin modalforge --tests
source scripts/need.sh
host_venv_need
VENV=target/host-venv
"$VENV/bin/python" plugin/tests/host_test.py target/bundled/ModalForge.vst3 target/release/modalforge
"$VENV/bin/python" plugin/tests/dawdreamer_torture.py target/bundled/ModalForge.vst3
