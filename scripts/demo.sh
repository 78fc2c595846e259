#!/usr/bin/env bash
# Sets up, builds and runs the main job: the example part program examples/bracket.ngc on
# the simulated 3-axis mill (configs/sim-mill.toml) in virtual time. Prints cycle time,
# limits, following errors and faults; writes CSV, an SVG plot, the trace and summary.json
# into out/demo.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
cargo build --release --locked -p rtcnc
exec target/release/rtcnc sim examples/bracket.ngc --out out/demo "$@"
