#!/usr/bin/env bash
# bench/interpreter.sh [RUNS] - G-code interpreter throughput and memory.
#
# Generates a 200 000-line G1 program (the shape of the LinuxCNC peer's big200k.ngc:
# "G1 X.. Y.. Z.." with 3 decimals, F3000, G64) and times, median of RUNS (default 7)
# interleaved runs:
#   rtcnc check --canon PROGRAM > /dev/null   (canonical text output)
#   rtcnc check PROGRAM > /dev/null           (interpretation only)
#   canon.sh PROGRAM > /dev/null              (LinuxCNC 2.9 rs274 through the peer harness)
# and prints lines/s and the ratios. Then it measures the peak RSS of rtcnc check --canon
# on a 10 000 000-line program (streamed, generated on disk).
# The LinuxCNC peer is found in $RTCNC_PEERS or ../shared/peers next to the repository;
# without it (or without rs274) the peer is skipped and said so.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
RUNS=${1:-7}
if [ -z "${RTCNC_PEERS:-}" ]; then
  for d in "$ROOT/../shared/peers" "$ROOT/../../shared/peers"; do
    [ -d "$d" ] && RTCNC_PEERS=$d && break
  done
fi
CANON=${RTCNC_PEERS:-/nonexistent}/linuxcnc/canon.sh
cargo build --release -q -p rtcnc --manifest-path "$ROOT/Cargo.toml"
RTCNC=$ROOT/target/release/rtcnc
TMP=$(mktemp -d /tmp/rtcnc-bench.XXXXXX)
trap 'rm -rf "$TMP"' EXIT

python3 - "$TMP" <<'PY'
import math, random, sys
d = sys.argv[1]
def write(path, n):
    rnd = random.Random(1)
    with open(path, 'w', buffering=1 << 20) as f:
        f.write('G21 G90 G64 F3000\n')
        for i in range(n):
            x = round(100 * math.sin(i * 0.001) + rnd.uniform(-1, 1), 3)
            y = round(100 * math.cos(i * 0.0013) + rnd.uniform(-1, 1), 3)
            z = round(-5 + 5 * math.sin(i * 0.0007), 3)
            f.write('G1 X%.3f Y%.3f Z%.3f\n' % (x, y, z))
        f.write('M2\n')
write(d + '/big200k.ngc', 200000)
PY
PROG=$TMP/big200k.ngc
LINES=$(wc -l < "$PROG")

have_peer=0
if [ -x "$CANON" ] && command -v rs274 >/dev/null; then have_peer=1; else
  echo "LinuxCNC peer not found (RTCNC_PEERS=${RTCNC_PEERS:-unset}): timing rtcnc only"; fi

python3 - "$RUNS" "$LINES" "$RTCNC" "$PROG" "$CANON" "$have_peer" <<'PY'
import statistics, subprocess, sys, time
runs, lines, rtcnc, prog, canon, have_peer = int(sys.argv[1]), int(sys.argv[2]), *sys.argv[3:6], sys.argv[6] == '1'
cases = [('rtcnc check --canon', [rtcnc, 'check', '--canon', prog]),
         ('rtcnc check', [rtcnc, 'check', prog])]
if have_peer:
    cases.append(('rs274 (canon.sh)', [canon, prog]))
t = {name: [] for name, _ in cases}
for _ in range(runs):
    for name, cmd in cases:
        s = time.perf_counter()
        r = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        t[name].append(time.perf_counter() - s)
        if r.returncode != 0:
            sys.exit('%s failed with status %d' % (name, r.returncode))
print('program: %d lines, median of %d runs' % (lines, runs))
med = {}
for name, _ in cases:
    m = statistics.median(t[name]); med[name] = m
    print('  %-22s %7.3f s  %10.0f lines/s  (best %.3f s)' % (name, m, lines / m, min(t[name])))
if have_peer:
    ref = med['rs274 (canon.sh)']
    print('  ratio rtcnc check --canon / rs274: %.1fx (goal >= 10x)' % (ref / med['rtcnc check --canon']))
    print('  ratio rtcnc check / rs274:         %.1fx (goal >= 20x)' % (ref / med['rtcnc check']))
PY

if [ $have_peer = 1 ]; then
  "$CANON" "$PROG" > "$TMP/rs274.canon" 2>/dev/null || true
  "$RTCNC" check --canon "$PROG" > "$TMP/rtcnc.canon"
  if cmp -s "$TMP/rs274.canon" "$TMP/rtcnc.canon"; then
    echo "  canonical outputs identical ($(wc -l < "$TMP/rtcnc.canon") lines)"
  else
    echo "  canonical outputs DIFFER: $(cmp "$TMP/rs274.canon" "$TMP/rtcnc.canon" | head -1)"
  fi
fi

# Peak memory on a 10 M-line program: the interpreter streams, memory must stay flat.
BIG=$TMP/big10m.ngc
python3 - "$BIG" <<'PY'
import sys
with open(sys.argv[1], 'w', buffering=1 << 20) as f:
    f.write('G21 G90 G64 F3000\n')
    line = 'G1 X%.3f Y%.3f Z%.3f\n'
    for i in range(10_000_000):
        f.write(line % (i % 1000 * 0.1, (i * 7) % 1000 * 0.1, -(i % 50) * 0.01))
    f.write('M2\n')
PY
if [ -x /usr/bin/time ]; then
  /usr/bin/time -v "$RTCNC" check --canon "$BIG" > /dev/null 2> "$TMP/time.txt"
  rss=$(sed -n 's/.*Maximum resident set size (kbytes): //p' "$TMP/time.txt")
  secs=$(sed -n 's/.*Elapsed (wall clock) time.*: //p' "$TMP/time.txt")
else
  # Fallback: sample /proc while it runs.
  "$RTCNC" check --canon "$BIG" > /dev/null & pid=$!
  rss=0
  while kill -0 $pid 2>/dev/null; do
    r=$(sed -n 's/^VmHWM:[[:space:]]*\([0-9]*\).*/\1/p' /proc/$pid/status 2>/dev/null || true)
    [ -n "$r" ] && [ "$r" -gt "$rss" ] && rss=$r
    sleep 0.2
  done
  secs="n/a"
fi
echo "10 000 002-line program: peak RSS $((rss / 1024)) MB (goal <= 64 MB), wall $secs"
