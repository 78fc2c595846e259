#!/usr/bin/env bash
# Creates the Python environment of the client's tests (target/python-venv) and installs
# the client (sdk/python) with its test requirements (pytest; asyncua and paho-mqtt, the
# independent OPC UA and MQTT clients) into it. Safe to run again.
set -euo pipefail
cd "$(dirname "$0")/.."
venv=target/python-venv
if [ ! -x "$venv/bin/python" ]; then
  # Debian's python3 needs its venv module as a package of its own.
  python3 -m venv "$venv" 2>/dev/null || { rm -rf "$venv"; scripts/setup.sh python3-venv; python3 -m venv "$venv"; }
fi
stamp="$venv/.installed"
if [ ! -f "$stamp" ] || [ sdk/python/pyproject.toml -nt "$stamp" ]; then
  "$venv/bin/python" -m pip install -q --upgrade pip >/dev/null
  "$venv/bin/python" -m pip install -q -e "./sdk/python[test]"
  touch "$stamp"
fi
