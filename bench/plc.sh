#!/usr/bin/env bash
# Scan time of the soft PLC (criterion, wall time and the thread's CPU time, which a loaded
# machine does not inflate): the simulated mill's logic (examples/plc/mill.st), a generated
# 2000-rung ladder with 500 TON timers, and 50 object-oriented stations driven through an
# interface (examples/plc/stations.st: METHODs, PROPERTYs, EXTENDS with SUPER^, virtual
# calls), plus the ladder's compile time. Prints per-statement cost of the ladder and the
# ratio of the stations' scan to the mill's. Goals: mill <= 5 us, 2000 rungs <= 200 us.
set -euo pipefail
cd "$(dirname "$0")/.."
out=$(cargo bench -q -p rtcnc-plc --bench scan 2>/dev/null | grep -E "^(mill|2000|compile|50-station)|time:" || true)
echo "$out"
# criterion prints "name\n time: [low mid high]"; take the middle estimates (in us).
mid() {
  echo "$out" | grep -A1 "^$1" | grep "time:" | head -1 |
    awk '{ v = $4; u = $5; if (u == "ns") v /= 1000; else if (u == "ms") v *= 1000; print v }'
}
mill=$(mid "mill.st scan (thread CPU time)")
ladder=$(mid "2000-rung scan (thread CPU time)")
stations=$(mid "50-station method scan (thread CPU time)")
if [[ -n "$mill" && -n "$ladder" && -n "$stations" ]]; then
  awk -v m="$mill" -v l="$ladder" -v s="$stations" 'BEGIN {
    printf "CPU per scan: mill %.2f us, 2000 rungs %.1f us (%.0f ns per statement), 50 stations %.1f us (%.1f x the mill)\n", m, l, l * 1000 / 2000, s, s / m
  }'
fi
