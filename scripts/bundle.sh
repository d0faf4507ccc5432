#!/usr/bin/env bash
# Builds the plugin bundles: target/bundled/ModalForge.vst3 and target/bundled/ModalForge.clap.
# Uses cargo-nice-plug from crates.io (nice-plug's bundler; no git-only tool), installed once.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/need.sh
nice_plug_need
cargo nice-plug bundle modalforge-plugin --release "$@"
ls -d target/bundled/*
