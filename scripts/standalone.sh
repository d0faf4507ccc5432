#!/usr/bin/env bash
# Builds and runs the standalone app (the plugin and its editor on JACK/ALSA):
#   bash scripts/standalone.sh                    # default audio backend (JACK, else ALSA)
#   bash scripts/standalone.sh --backend dummy    # no sound card
# Arguments go to the app (`--help` lists them). Installs the ALSA and JACK development
# packages it links against when they are missing (apt, as root or through sudo).
set -euo pipefail
cd "$(dirname "$0")/.."
need=()
for p in libasound2-dev libjack-jackd2-dev; do
  dpkg -s "$p" >/dev/null 2>&1 || need+=("$p")
done
if ((${#need[@]})); then
  sudo=""; [ "$(id -u)" = 0 ] || sudo="sudo"
  $sudo apt-get update -qq && $sudo apt-get install -y -qq "${need[@]}"
fi
cargo build --locked --release -p modalforge-standalone
exec target/release/modalforge-standalone "$@"
