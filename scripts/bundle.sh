#!/usr/bin/env bash
# Builds the plugin bundles: target/bundled/ModalForge.vst3 and target/bundled/ModalForge.clap.
#   bash scripts/bundle.sh [--debug] [cargo build options, e.g. --features assert_process_allocs]
# A release build unless --debug. The name comes from bundler.toml.
#
# On Linux a plugin bundle is the plugin's shared library under its format's name: the CLAP
# file is the library itself, the VST3 bundle a folder with the library at
# Contents/<arch>-linux/<name>.so (the VST3 SDK's layout). This script lays them out after
# `cargo build`, as nice-plug's bundler does on Linux (nice-plug-xtask 0.1.1, `bundle_plugin`),
# and checks, as it does, that the library exports each format's entry point. Elsewhere
# (macOS bundles need an Info.plist and signing) it runs that bundler, cargo-nice-plug from
# crates.io, installed once. Not compiling the bundler on Linux takes its 100 s build out of
# the test command's critical path (scripts/test.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/need.sh
# The profile's folder and its cargo option; `${build[@]+"${build[@]}"}` below expands an
# empty array under `set -u` in macOS's bash 3.2 too.
profile=release
build=(--release)
if [ "${1:-}" = --debug ]; then
  profile=debug
  build=()
  shift
fi
name=$(sed -n 's/^name = "\(.*\)"$/\1/p' bundler.toml)
[ -n "$name" ] || { echo "bundle.sh: bundler.toml names no bundle (name = \"...\")"; exit 1; }
arch=""
if [ "$(uname -s)" = Linux ]; then
  case "$(uname -m)" in
    x86_64) arch=x86_64-linux ;;
    aarch64) arch=aarch64-linux ;;
  esac
fi
if [ -z "$arch" ]; then
  nice_plug_need
  cargo nice-plug bundle modalforge-plugin ${build[@]+"${build[@]}"} "$@"
  ls -d target/bundled/*
  exit 0
fi
cargo build --locked -p modalforge-plugin --lib ${build[@]+"${build[@]}"} "$@"
lib="${CARGO_TARGET_DIR:-target}/$profile/libmodalforge_plugin.so"
command -v nm >/dev/null || apt_need binutils
exports=$(nm -D --defined-only "$lib")
for entry in clap_entry GetPluginFactory; do
  grep -qw "$entry" <<<"$exports" || {
    echo "bundle.sh: $lib does not export $entry (is the plugin's nice_export_clap!/vst3! gone?)"
    exit 1
  }
done
rm -rf "target/bundled/$name.clap" "target/bundled/$name.vst3"
mkdir -p "target/bundled/$name.vst3/Contents/$arch"
cp "$lib" "target/bundled/$name.clap"
cp "$lib" "target/bundled/$name.vst3/Contents/$arch/$name.so"
echo "Created a CLAP bundle at 'target/bundled/$name.clap'"
echo "Created a VST3 bundle at 'target/bundled/$name.vst3'"
