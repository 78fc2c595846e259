#!/usr/bin/env bash
# Cycle time of the four benchmark polylines (1 µm chords, G64 P0.001, F6000; 100 mm/s,
# 1000 mm/s², 50 000 mm/s³ per axis, 1 ms servo period) through rtcnc-motion's planner,
# next to the peers' figures measured on this project's machine: toppra's
# acceleration-limited optimum (no jerk limit, a lower bound) and LinuxCNC 2.9's simulator.
# Prints our time, the ratios, the largest per-axis |v|, |a|, |j| of our set-points (finite
# differences at the servo period), the end-point error and the limit-violation counter.
#
# The programs come from the peers' bench-paths folder ($RTCNC_PEERS/bench-paths, default
# ../shared/peers/bench-paths from the repository root); the script skips when absent. The
# programs are read by a benchmark-only reader of their simple G1 lines (to be replaced by
# the interpreter crate). Then the criterion benches of the planner's cost.
set -euo pipefail
cd "$(dirname "$0")/.."
peers="${RTCNC_PEERS:-../shared/peers}"
dir="$peers/bench-paths"
if [[ ! -d "$dir" ]]; then
  echo "peer benchmark programs not found ($dir): skipping the cycle-time comparison"
else
  cargo run -q --release -p rtcnc-motion --example bench_paths -- "$dir"
fi
if [[ "${1:-}" != "--no-criterion" ]]; then
  echo "== planner cost (criterion)"
  cargo bench -q -p rtcnc-motion --bench planner 2>/dev/null | grep -E "^planner/|time:|thrpt:" || true
fi
