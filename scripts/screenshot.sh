#!/usr/bin/env bash
# Renders the plugin window headless and saves a PNG (default docs/editor.png):
#   bash scripts/screenshot.sh [OUT.png]
# Runs the standalone app with the dummy audio backend on an Xvfb display (Mesa software GL),
# waits for the first solve, and grabs the window with xwd. Installs xvfb, x11-apps and netpbm
# when missing.
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-docs/editor.png}"
source scripts/need.sh
apt_need xvfb x11-apps netpbm libasound2-dev libjack-jackd2-dev
cargo build --locked --release -p modalforge-standalone
display=":$((90 + RANDOM % 100))"
Xvfb "$display" -screen 0 1100x760x24 >/dev/null 2>&1 &
xvfb=$!
trap 'kill $app $xvfb 2>/dev/null || true' EXIT
sleep 1
DISPLAY="$display" LIBGL_ALWAYS_SOFTWARE=1 target/release/modalforge-standalone \
  --backend dummy --sample-rate 48000 --period-size 512 >/tmp/modalforge-standalone.log 2>&1 &
app=$!
# The first solve and a few repaints.
sleep "${SCREENSHOT_WAIT_S:-8}"
if ! kill -0 "$app" 2>/dev/null; then
  echo "the standalone app exited early:" >&2
  cat /tmp/modalforge-standalone.log >&2
  exit 1
fi
mkdir -p "$(dirname "$out")"
DISPLAY="$display" xwd -root -silent | xwdtopnm 2>/dev/null | pnmcut -left 0 -top 0 -width 1000 -height 680 | pnmtopng >"$out"
echo "wrote $out"
