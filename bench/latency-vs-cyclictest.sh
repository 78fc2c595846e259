#!/usr/bin/env bash
# Wake-up latency of the rtcnc executive next to cyclictest (Debian rt-tests), back to back
# with the same period, priority and duration: idle, then under a stress-ng load. Prints both
# and the ratios rtcnc / cyclictest (goal: p99 and max within 1.1x).
#
#   bench/latency-vs-cyclictest.sh            # 1 ms, priority 80, 10 s per run
#   PERIOD_US=500 PRIORITY=90 DURATION=30 bench/latency-vs-cyclictest.sh
#
# Both tools: absolute clock_nanosleep on CLOCK_MONOTONIC, SCHED_FIFO, mlockall, one thread,
# 1 us histogram bins; p99 is the upper edge of the bin holding the 99th percentile.
set -euo pipefail
cd "$(dirname "$0")/.."

PERIOD_US=${PERIOD_US:-1000}
PRIORITY=${PRIORITY:-80}
DURATION=${DURATION:-10}

scripts/setup.sh rt-tests stress-ng
cargo build -q --release --locked -p rtcnc
rtcnc=target/release/rtcnc
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT

have_cyclictest=1
command -v cyclictest >/dev/null || { echo "cyclictest not found: its runs are skipped"; have_cyclictest=0; }
have_stress=1
command -v stress-ng >/dev/null || { echo "stress-ng not found: the loaded runs are skipped"; have_stress=0; }

# prints "min mean p99 max samples" in microseconds
run_rtcnc() {
  "$rtcnc" latency --period "${PERIOD_US}us" --duration "${DURATION}s" --priority "$PRIORITY" \
    --quiet >"$out/rtcnc.txt" 2>"$out/rtcnc.err"
  awk '/^latency \(us\): samples/ { print $6, $8, $10, $12, $4 }' "$out/rtcnc.txt"
}

run_cyclictest() {
  cyclictest -m -q -t 1 -p "$PRIORITY" -i "$PERIOD_US" -D "$DURATION" -h 10000 \
    >"$out/cyclictest.txt" 2>&1
  awk '
    /^[0-9]+ +[0-9]+$/ { bin[$1 + 0] = $2 + 0; total += $2; if ($1 + 0 > last) last = $1 + 0 }
    /^# Histogram Overflows:/ { total += $4 + 0; overflow = $4 + 0 }
    /^# Min Latencies:/ { min = $4 + 0 }
    /^# Avg Latencies:/ { avg = $4 + 0 }
    /^# Max Latencies:/ { max = $4 + 0 }
    END {
      target = total - int(total / 100); seen = 0; p99 = max
      for (i = 0; i <= last; i++) { seen += bin[i]; if (seen >= target) { p99 = i + 1; break } }
      if (p99 > max) p99 = max
      print min, avg, p99, max, total
    }' "$out/cyclictest.txt"
}

start_load() {
  stress-ng --cpu "$(nproc)" --vm 1 --vm-bytes 256M --io 1 --timeout "$((DURATION + 5))s" \
    >/dev/null 2>&1 &
  load_pid=$!
  sleep 1
}

stop_load() {
  kill "$load_pid" 2>/dev/null || true
  wait "$load_pid" 2>/dev/null || true
}

printf 'period %s us, priority %s, %s s per run, %s CPUs, kernel %s\n\n' \
  "$PERIOD_US" "$PRIORITY" "$DURATION" "$(nproc)" "$(uname -r)"
printf '%-22s %9s %9s %9s %9s %9s\n' "run" "min us" "mean us" "p99 us" "max us" "samples"

declare -A result
for load in idle stress; do
  [ "$load" = stress ] && [ "$have_stress" = 0 ] && continue
  for tool in rtcnc cyclictest; do
    [ "$tool" = cyclictest ] && [ "$have_cyclictest" = 0 ] && continue
    [ "$load" = stress ] && start_load
    line=$(run_$tool)
    [ "$load" = stress ] && stop_load
    result[$tool,$load]=$line
    # shellcheck disable=SC2086
    printf '%-22s %9s %9s %9s %9s %9s\n' "$tool ($load)" $line
  done
done

if [ "$have_cyclictest" = 1 ]; then
  echo
  echo "ratios rtcnc / cyclictest (goal: p99 and max <= 1.1)"
  for load in idle stress; do
    [ -n "${result[rtcnc,$load]:-}" ] && [ -n "${result[cyclictest,$load]:-}" ] || continue
    echo "${result[rtcnc,$load]} ${result[cyclictest,$load]}" | awk -v load="$load" '
      function ratio(a, b) { return b > 0 ? sprintf("%.2f", a / b) : "n/a" }
      { printf "  %-7s p99 %s  max %s  mean %s\n", load, ratio($3, $8), ratio($4, $9), ratio($2, $7) }'
  done
fi
grep -h "warning" "$out/rtcnc.err" 2>/dev/null || true
