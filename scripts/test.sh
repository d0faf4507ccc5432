#!/usr/bin/env bash
# The whole test suite: the Rust tests (library, CLI, engine, FEM accuracy), then the plugin
# bundles in a real third-party host (scripts/plugin-host-test.sh), then the plugin's own tests.
# The Rust tests run in the release profile: the plugin bundle and the `modalforge` binary the
# host test needs are release builds too, so the dependency tree (faer above all) compiles once
# instead of twice (the test profile is a separate build of every dependency).
#
# What runs beside what (2 cores; ARCHITECTURE.md, "The test command..."): the host tests'
# Python venv installs from PyPI while everything compiles (network, not CPU); the plugin's
# bundle and test binaries compile while the Rust tests run; the two-minute soak, which plays
# in real time on about 3/4 of a core, runs beside both instead of after the other tests.
set -euo pipefail
cd "$(dirname "$0")/.."
# No debug info in the test builds (Cargo.toml keeps line tables in release for profiling): the
# clean-clone suite went from 16.2 to 13.7 min without it (burn included; the goal is 15 min).
export CARGO_PROFILE_RELEASE_DEBUG=0
mkdir -p target
jobs_started=()
cleanup() {
  for pid in "${jobs_started[@]}"; do
    kill -- "-$pid" 2>/dev/null || true
  done
}
trap cleanup EXIT
setsid bash -c 'source scripts/need.sh && host_venv_need' >target/host-venv.log 2>&1 &
venv=$!
jobs_started+=("$venv")
cargo test --locked --release --no-run
# The soak's test binary, run directly (a second `cargo test` would wait for the bundle's
# build to release the build directory's lock).
soak_exe=$(cargo test --locked --release --no-run --test soak --message-format=json 2>/dev/null |
  python3 -c '
import json, sys
for line in sys.stdin:
    m = json.loads(line)
    if m.get("reason") == "compiler-artifact" and m["target"]["name"] == "soak" and m.get("executable"):
        print(m["executable"])')
[ -x "$soak_exe" ] || { echo "the soak test binary was not found"; exit 1; }
# The plugin's bundle and test binaries compile while the Rust tests run (cargo does not lock
# the build directory while tests run). Measured: about 45 s less on this 2-core machine than
# after them (the bundle's 3 minutes of compiling stretch to 5 beside the tests).
setsid bash -c 'bash scripts/bundle.sh && cargo test --locked --release -p modalforge-plugin --no-run' \
  >target/plugin-build.log 2>&1 &
plugin_build=$!
jobs_started+=("$plugin_build")
setsid "$soak_exe" --nocapture >target/soak.log 2>&1 &
soak=$!
jobs_started+=("$soak")
# Every other Rust test (the soak's one test is skipped by name here; it is running above).
cargo test --locked --release -- --skip two_minutes_of_notes_automation_and_edits
built=0
wait "$plugin_build" || built=$?
cat target/plugin-build.log
[ "$built" = 0 ] || { echo "the plugin build failed (exit $built)"; exit 1; }
installed=0
wait "$venv" || installed=$?
[ "$installed" = 0 ] || { cat target/host-venv.log; echo "the host venv failed"; exit 1; }
bash scripts/plugin-host-test.sh
cargo test --locked --release -p modalforge-plugin
soaked=0
wait "$soak" || soaked=$?
echo "--- tests/soak.rs (run beside the others)"
cat target/soak.log
[ "$soaked" = 0 ] || { echo "the soak failed (exit $soaked)"; exit 1; }
jobs_started=()
