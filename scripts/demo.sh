#!/usr/bin/env bash
# Sets up, builds and runs the main job: for now the executive's wake-up latency
# measurement (1 ms period, 10 s), with a histogram written to out/latency.svg.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
cargo build --release --locked -p rtcnc
mkdir -p out
exec target/release/rtcnc latency --period 1ms --duration 10s --svg out/latency.svg "$@"
