#!/usr/bin/env bash
# The shipped example in real time on this machine: `rtcnc run examples/bracket.ngc` on the
# simulated mill, RUNS times idle and RUNS times under `stress-ng --cpu 2` (two processes
# keeping both processors busy at normal priority), with the default set-point lead.
# Prints one line per run (ended, whether its path is `rtcnc sim`'s (bench/compare-paths.py
# on both recordings, within 1 µm), set-point underruns, the longest gap between two runs of
# interpolation, the latest start of interpolation and of position control after their
# release, deadline misses) and the completed count of each series.
#
#   bench/run-realtime.sh [RUNS] [PROGRAM] [MACHINE]    (defaults: 10, the bracket, sim-mill)
#
# Needs SCHED_FIFO (root or CAP_SYS_NICE) for meaningful figures; without it the runs still
# work and say so. Installs stress-ng (Debian) through scripts/setup.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
runs=${1:-10}
program=${2:-examples/bracket.ngc}
machine=${3:-configs/sim-mill.toml}
scripts/setup.sh stress-ng >/dev/null
cargo build --release --locked -p rtcnc >/dev/null 2>&1
bin=target/release/rtcnc
tmp=$(mktemp -d)
stress_pid=""
cleanup() {
  [ -n "$stress_pid" ] && kill "$stress_pid" 2>/dev/null || true
  rm -rf "$tmp"
}
trap cleanup EXIT

"$bin" sim "$program" --machine "$machine" -q --out "$tmp/sim" >/dev/null || true

one_run() {
  local out="$tmp/run.txt"
  rm -rf "$tmp/run"
  timeout 600 "$bin" run "$program" --machine "$machine" --out "$tmp/run" >"$out" 2>"$tmp/stderr.txt" || true
  local path
  path=$(bench/compare-paths.py "$tmp/sim" "$tmp/run" 0.001 >/dev/null 2>&1 && echo "same path" || echo "OTHER PATH")
  local ended underruns gap latest misses
  ended=$(grep -c '^program ended' "$out" || true)
  underruns=$(sed -n 's/^set-point underruns (periods without a set-point): \([0-9]*\)/\1/p' "$out")
  gap=$(sed -n 's/.*longest gap between interpolation runs \([0-9]*\) periods.*/\1/p' "$out")
  latest=$(sed -n 's/^latest start after release: *//p' "$out")
  misses=$(awk '/^task /{t=1; next} t && NF>=7 && $NF ~ /^[0-9]+$/ {m+=$NF} END {print m+0}' "$out")
  local fault
  fault=$(grep -m1 '^fault' "$out" | cut -c1-110 || true)
  printf '%-6s %-10s underruns %-4s longest gap %-4s periods  latest start: %s  deadline misses %s %s\n' \
    "$([ "$ended" = 1 ] && echo ended || echo FAILED)" "$path" "${underruns:-?}" "${gap:-?}" \
    "${latest:-?}" "$misses" "$fault"
  [ "$ended" = 1 ] && [ "$path" = "same path" ]
}

series() {
  local name=$1 ok=0
  echo "== $name: $runs runs of $program on $machine"
  for i in $(seq 1 "$runs"); do
    if one_run; then ok=$((ok + 1)); fi
  done
  echo "== $name: $ok of $runs ended on the path of rtcnc sim"
}

grep -m1 -q . /proc/cpuinfo && echo "processors: $(nproc)"
series idle
stress-ng --cpu 2 --quiet &
stress_pid=$!
sleep 1
series "under stress-ng --cpu 2"
