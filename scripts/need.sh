# Sourced by the scripts that install what they need, so each install is written once:
#   apt_need PKG...            system packages that are missing (apt, as root or through sudo)
#   nice_plug_need             cargo-nice-plug from crates.io (nice-plug's bundler), once
#   venv_need DIR PKG...       a Python venv at DIR (python3-venv from apt when missing) with
#                              PKG... installed from PyPI; `$DIR/bin/python` runs it
#   host_venv_need             the plugin host tests' venv: target/host-venv with pedalboard
#                              and DawDreamer

apt_need() {
  local need=() p sudo=""
  for p in "$@"; do
    dpkg -s "$p" >/dev/null 2>&1 || need+=("$p")
  done
  if ((${#need[@]})); then
    [ "$(id -u)" = 0 ] || sudo="sudo"
    $sudo apt-get update -qq && $sudo apt-get install -y -qq "${need[@]}"
  fi
}

nice_plug_need() {
  if ! cargo nice-plug --help >/dev/null 2>&1; then
    cargo install cargo-nice-plug --version 0.1.1 --locked
  fi
}

venv_need() {
  local dir="$1"
  shift
  if [ ! -x "$dir/bin/python" ]; then
    python3 -m venv "$dir" 2>/dev/null || { apt_need python3-venv && python3 -m venv "$dir"; }
  fi
  "$dir/bin/pip" install -q --disable-pip-version-check "$@"
}

host_venv_need() {
  venv_need target/host-venv 'pedalboard==0.9.*' 'dawdreamer==0.9.0' mido numpy
}
