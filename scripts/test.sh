#!/usr/bin/env bash
# The whole test suite: the Rust tests (library, CLI, engine, FEM accuracy), then the plugin
# bundles in a real third-party host (scripts/plugin-host-test.sh), then the plugin's own tests.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo test --locked
bash scripts/plugin-host-test.sh
cargo test --locked --release -p modalforge-plugin
