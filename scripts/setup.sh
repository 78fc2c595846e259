#!/usr/bin/env bash
# Installs what building and testing rtcnc needs on a Debian machine with Rust present.
# Safe to run again; does nothing when everything is there.
set -euo pipefail

if command -v rustup >/dev/null 2>&1; then
  for component in rustfmt clippy; do
    rustup component list --installed 2>/dev/null | grep "^$component" >/dev/null \
      || rustup component add "$component"
  done
fi

# Debian packages, installed only when missing. Extra ones can be named on the command line
# (the benchmark scripts ask for rt-tests and stress-ng this way). The EtherCAT tests need
# iproute2 (veth pairs), util-linux (unshare) and python3-venv (pysoem, below).
missing=()
for package in iproute2 util-linux python3-venv "$@"; do
  dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep "install ok installed" >/dev/null \
    || missing+=("$package")
done
if [ ${#missing[@]} -gt 0 ]; then
  sudo_cmd=""
  [ "$(id -u)" -eq 0 ] || sudo_cmd="sudo"
  $sudo_cmd apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y -qq "${missing[@]}" >/dev/null
fi

# pysoem (SOEM, an independent EtherCAT master) for the simulator's tests, in a venv under
# the user's cache; RTCNC_PYSOEM_PYTHON names another Python that has it.
pysoem_venv="${HOME}/.cache/rtcnc/venv-ethercat"
if ! "${pysoem_venv}/bin/python" -c "import pysoem" >/dev/null 2>&1; then
  python3 -m venv "${pysoem_venv}"
  "${pysoem_venv}/bin/pip" install -q pysoem
fi
