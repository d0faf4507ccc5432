# Sourced by the scripts that need system packages: `apt_need PKG...` installs those of them
# that are missing (apt, as root or through sudo).
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
