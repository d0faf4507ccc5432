#!/usr/bin/env bash
# The whole test suite: the Rust tests (library, CLI, engine, FEM accuracy), then the plugin
# bundles in a real third-party host (scripts/plugin-host-test.sh), then the plugin's own tests.
# The Rust tests run in the release profile: the plugin bundle and the `modalforge` binary the
# host test needs are release builds too, so the dependency tree (faer above all) compiles once
# instead of twice (the test profile is a separate build of every dependency).
set -euo pipefail
cd "$(dirname "$0")/.."
# No debug info in the test builds (Cargo.toml keeps line tables in release for profiling): the
# clean-clone suite went from 16.2 to 13.7 min without it (burn included; the goal is 15 min).
export CARGO_PROFILE_RELEASE_DEBUG=0
mkdir -p target
# The host tests' Python venv installs from PyPI while everything compiles (network, not CPU).
setsid bash -c 'source scripts/need.sh && host_venv_need' >target/host-venv.log 2>&1 &
venv=$!
cargo test --locked --release --no-run
# The plugin's bundle and test binaries compile while the Rust tests run: those leave part of
# a core idle (the soak plays two minutes in real time on about 3/4 of one), and cargo does not
# lock the build directory while tests run. Measured: about 45 s less on this 2-core machine
# (the bundle's 3 minutes of compiling stretch to 5 beside the tests). It starts once the
# tests do: cargo holds the build directory's lock while it checks the build, and a plugin
# build started beside that check could take the lock first and hold the tests back for its
# whole compile (2.5 minutes in one CI run).
: >target/rust-tests.log
setsid bash -c 'until grep -q "Running" target/rust-tests.log; do sleep 0.5; done
  bash scripts/bundle.sh && cargo test --locked --release -p modalforge-plugin --no-run' \
  >target/plugin-build.log 2>&1 &
plugin_build=$!
if ! cargo test --locked --release 2>&1 | tee target/rust-tests.log; then
  kill -- "-$plugin_build" "-$venv" 2>/dev/null || true
  exit 1
fi
built=0
wait "$plugin_build" || built=$?
cat target/plugin-build.log
[ "$built" = 0 ] || { echo "the plugin build failed (exit $built)"; exit 1; }
installed=0
wait "$venv" || installed=$?
[ "$installed" = 0 ] || { cat target/host-venv.log; echo "the host venv failed"; exit 1; }
bash scripts/plugin-host-test.sh
cargo test --locked --release -p modalforge-plugin
