#!/usr/bin/env bash
# bench/compensation.sh [RUNS] - cutter radius compensation throughput against LinuxCNC.
#
# Generates a 200 000-move zig-zag contour (every corner alternately convex and concave)
# under G41.1, and the same program without compensation, and times (median of RUNS,
# default 5, interleaved):
#   compensate PROGRAM > /dev/null   interpreter -> compensation stage -> rs274 text
#                                    (crates/gcode/examples/compensate.rs)
#   canon.sh PROGRAM > /dev/null     LinuxCNC 2.9 rs274 (compensates in its interpreter)
# with and without G41.1, prints moves/s, ratios and what compensation costs each, and
# checks that both print the same number of lines. Then the stage alone:
# cargo bench --bench compensation.
# The LinuxCNC peer is found in $RTCNC_PEERS or ../shared/peers next to the repository;
# without it (or without rs274) the peer is skipped and said so.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
RUNS=${1:-5}
if [ -z "${RTCNC_PEERS:-}" ]; then
  for d in "$ROOT/../shared/peers" "$ROOT/../../shared/peers"; do
    [ -d "$d" ] && RTCNC_PEERS=$d && break
  done
fi
CANON=${RTCNC_PEERS:-/nonexistent}/linuxcnc/canon.sh
cargo build --release -q -p rtcnc-gcode --example compensate --manifest-path "$ROOT/Cargo.toml"
COMP=$ROOT/target/release/examples/compensate
TMP=$(mktemp -d /tmp/rtcnc-comp-bench.XXXXXX)
trap 'rm -rf "$TMP"' EXIT
MOVES=200000
python3 - "$TMP" "$MOVES" <<'PY'
import math, sys
d, n = sys.argv[1], int(sys.argv[2])
for name, start, stop in (("comp", "G41.1 D1 ", "G40 "), ("plain", "", "")):
    with open(f"{d}/{name}.ngc", "w") as f:
        f.write("G21 G17 G90 G94 G64\nG0 X0 Y0\nF3000\n")
        for i in range(n):
            t = i * 2 * math.pi / 50
            r = 50.0 if i % 2 == 0 else 47.0
            f.write(f"{start if i == 0 else ''}G1 X{r * math.cos(t):.3f} Y{r * math.sin(t):.3f}\n")
        f.write(f"{stop}G1 X0 Y0\nM2\n")
PY
have_peer=0
if [ -x "$CANON" ] && command -v rs274 >/dev/null; then have_peer=1
else echo "LinuxCNC peer not found (RTCNC_PEERS=${RTCNC_PEERS:-unset}): rs274 skipped"; fi

median() { sort -n | awk '{a[NR]=$1} END{print a[int((NR+1)/2)]}'; }
now() { date +%s.%N; }
declare -A T
for run in $(seq "$RUNS"); do
  for prog in comp plain; do
    s=$(now); "$COMP" "$TMP/$prog.ngc" > /dev/null; e=$(now)
    echo "$e - $s" | bc >> "$TMP/ours_$prog"
    if [ $have_peer = 1 ]; then
      s=$(now); "$CANON" "$TMP/$prog.ngc" > /dev/null; e=$(now)
      echo "$e - $s" | bc >> "$TMP/rs274_$prog"
    fi
  done
done
report() {  # name file
  local t; t=$(median < "$2")
  printf '%-34s %8.3f s  %10.0f moves/s\n' "$1" "$t" "$(echo "$MOVES / $t" | bc -l)"
  T[$1]=$t
}
echo "== $MOVES-move zig-zag contour, median of $RUNS runs"
report "rtcnc interpreter+comp (G41.1)" "$TMP/ours_comp"
report "rtcnc interpreter (no comp)" "$TMP/ours_plain"
if [ $have_peer = 1 ]; then
  report "rs274 (G41.1)" "$TMP/rs274_comp"
  report "rs274 (no comp)" "$TMP/rs274_plain"
  printf 'speed-up with compensation: %.1fx rs274\n' \
    "$(echo "${T[rs274 (G41.1)]} / ${T[rtcnc interpreter+comp (G41.1)]}" | bc -l)"
  printf 'cost of compensation: rtcnc %+.3f s, rs274 %+.3f s\n' \
    "$(echo "${T[rtcnc interpreter+comp (G41.1)]} - ${T[rtcnc interpreter (no comp)]}" | bc -l)" \
    "$(echo "${T[rs274 (G41.1)]} - ${T[rs274 (no comp)]}" | bc -l)"
  "$COMP" "$TMP/comp.ngc" > "$TMP/ours.canon"; "$CANON" "$TMP/comp.ngc" > "$TMP/rs274.canon"
  python3 - "$TMP/ours.canon" "$TMP/rs274.canon" <<'PY'
import re, sys
a, b = (open(p).read().splitlines() for p in sys.argv[1:3])
tok = lambda l: re.split(r"[(), ]+", l)
def same(x, y):
    tx, ty = tok(x), tok(y)
    if len(tx) != len(ty):
        return False
    for p, q in zip(tx, ty):
        if p == q:
            continue
        try:
            if abs(float(p) - float(q)) > 1.0001e-4:
                return False
        except ValueError:
            return False
    return True
bad = next((i for i, (x, y) in enumerate(zip(a, b)) if not same(x, y)), None)
if bad is None and len(a) == len(b):
    print(f"outputs equal within 1e-4: {len(a)} lines")
else:
    i = bad if bad is not None else min(len(a), len(b))
    print(f"outputs differ at line {i + 1}: rtcnc {a[i] if i < len(a) else '<end>'!r}, rs274 {b[i] if i < len(b) else '<end>'!r}")
PY
fi
echo "== the stage alone"
cargo bench -q -p rtcnc-gcode --bench compensation --manifest-path "$ROOT/Cargo.toml" 2>&1 \
  | grep -E "compensation/|time:|thrpt:"
