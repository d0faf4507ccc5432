#!/usr/bin/env bash
# Builds and runs the standalone app (the plugin and its editor on JACK/ALSA):
#   bash scripts/standalone.sh                    # default audio backend (JACK, else ALSA)
#   bash scripts/standalone.sh --backend dummy    # no sound card
# Arguments go to the app (`--help` lists them). Installs the ALSA and JACK development
# packages it links against when they are missing (apt, as root or through sudo).
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/need.sh
apt_need libasound2-dev libjack-jackd2-dev
cargo build --locked --release -p modalforge-standalone
exec target/release/modalforge-standalone "$@"
