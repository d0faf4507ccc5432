#!/usr/bin/env bash
# Builds the plugin bundles: target/bundled/ModalForge.vst3 and target/bundled/ModalForge.clap.
# Uses cargo-nice-plug from crates.io (nice-plug's bundler; no git-only tool), installed once.
set -euo pipefail
cd "$(dirname "$0")/.."
if ! cargo nice-plug --help >/dev/null 2>&1; then
  cargo install cargo-nice-plug --version 0.1.1 --locked
fi
cargo nice-plug bundle modalforge-plugin --release "$@"
ls -d target/bundled/*
