#!/usr/bin/env bash
# The web HMI's figures (docs/hmi.md): frame time in headless Chromium with status at 50 Hz,
# time to load and draw the preview of a 1 000 000-segment program, the bundle's size.
# Release build of rtcnc; SEGMENTS and SECONDS change the sizes.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh chromium-headless-shell
cargo build --release -p rtcnc --locked
scripts/hmi.sh check >/dev/null
echo "host: $(nproc) cores, load average $(cut -d' ' -f1-3 /proc/loadavg)"
RTCNC_BIN="$PWD/target/release/rtcnc" node web/bench/measure.mjs
