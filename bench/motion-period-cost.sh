#!/usr/bin/env bash
# Instructions per servo period of the path interpolation (`Planner::next`, three axes) on
# the four benchmark polylines of bench/motion-paths.sh, counted by callgrind (independent
# of the load of the machine, unlike wall time), with the number of set-points the speed
# model's jerk search evaluates. The goal of the motion issue is 50 ns per axis per period.
#
# Needs valgrind (skips without it) and the peers' bench-paths programs ($RTCNC_PEERS or
# ../shared/peers from the repository root; skips when absent). Optional argument: a
# second bench_paths binary (for example one built from an older commit) measured in the
# same run, for the ratio.
set -euo pipefail
cd "$(dirname "$0")/.."
peers="${RTCNC_PEERS:-../shared/peers}"
dir="$peers/bench-paths"
if [[ ! -d "$dir" ]]; then
  echo "peer benchmark programs not found ($dir): skipping"
  exit 0
fi
if ! command -v valgrind >/dev/null; then
  echo "valgrind not found: skipping"
  exit 0
fi
cargo build -q --release -p rtcnc-motion --example bench_paths
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
measure() {
  local bin=$1 out=$tmp/cg.$RANDOM
  # bench_paths ends with the number of servo periods (calls of Planner::next) it ran.
  local calls
  calls=$(valgrind --tool=callgrind --callgrind-out-file="$out" '--toggle-collect=*Planner*next*' \
    "$bin" "$dir" 2>/dev/null | sed -n 's/.*; \([0-9]*\) servo periods$/\1/p')
  local total
  total=$(callgrind_annotate "$out" | awk '/PROGRAM TOTALS/ && !n++ {gsub(",", "", $1); print $1}')
  echo "$total ${calls:-0}"
}
read -r total calls < <(measure target/release/examples/bench_paths)
echo "Planner::next: $total instructions in $calls periods: $((total / calls)) per period"
if [[ $# -ge 1 ]]; then
  # An older binary may not print its period count: then the same number of periods.
  read -r total0 calls0 < <(measure "$1")
  [[ $calls0 -gt 0 ]] || calls0=$calls
  echo "$1: $total0 instructions in $calls0 periods: $((total0 / calls0)) per period"
  awk -v a="$total0" -v b="$total" 'BEGIN { printf "ratio %.2f\n", a / b }'
fi
