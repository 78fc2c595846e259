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
# the interpreter crate).
#
# Then the curve families of bench/motion_curves.py (34 smooth curves: rhodonea roses, epi-
# and hypotrochoids, Lissajous figures, 3-D knots, spirals, random Fourier curves and cubic
# B-splines; 1 µm polylines, G64 P0.001, F6000, generated here from fixed seeds): per curve
# our time, toppra's optimum and LinuxCNC 2.9's time with the ratios, and the largest |v|,
# |a|, |j| of any axis over its limit; then the median and the worst ratio, naming the
# curve. The peers' figures come from bench/data/motion-curves.json (measured once with
# `--refs`, which needs ../shared/peers: toppra through the peers' venv, LinuxCNC's
# simulator in real time, some 5 minutes). Then the criterion benches of the planner's cost.
#
#   bench/motion-paths.sh [--refs] [--no-criterion]
set -euo pipefail
cd "$(dirname "$0")/.."
peers="${RTCNC_PEERS:-../shared/peers}"
dir="$peers/bench-paths"
refs=0
criterion=1
for arg in "$@"; do
  case "$arg" in
    --refs) refs=1 ;;
    --no-criterion) criterion=0 ;;
  esac
done
if [[ ! -d "$dir" ]]; then
  echo "peer benchmark programs not found ($dir): skipping the cycle-time comparison"
else
  cargo run -q --release -p rtcnc-motion --example bench_paths -- "$dir"
fi

echo "== curve families (bench/motion_curves.py)"
data=bench/data/motion-curves.json
if [[ $refs == 1 ]]; then
  venv="${RTCNC_PEERS_VENV:-$HOME/.cache/rtcnc-peers/venv}"
  if [[ -x "$venv/bin/python" && -d "$peers/traj" && -x "$peers/linuxcnc/run_sim.sh" ]]; then
    PYTHONPATH="$peers/traj" RTCNC_PEERS="$peers" "$venv/bin/python" bench/motion_curves.py refs "$data"
  else
    echo "peers not found ($peers, $venv): the figures of $data are used"
  fi
fi
work=$(mktemp -d /tmp/motion-curves.XXXXXX)
trap 'rm -rf "$work"' EXIT
python3 bench/motion_curves.py write "$work/programs"
cargo run -q --release -p rtcnc-motion --example bench_paths -- --programs "$work/programs" > "$work/ours.tsv"
python3 bench/motion_curves.py report "$data" "$work/ours.tsv"
if [[ $criterion == 1 ]]; then
  echo "== planner cost (criterion)"
  cargo bench -q -p rtcnc-motion --bench planner 2>/dev/null | grep -E "^planner/|time:|thrpt:" || true
fi
