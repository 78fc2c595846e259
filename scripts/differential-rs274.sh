#!/usr/bin/env bash
# scripts/differential-rs274.sh [COUNT] - random differential test against LinuxCNC's rs274:
# generates COUNT (default 200) random programs (moves, arcs, offsets, G92, G53, cycles,
# parameters, units of a mill), runs each through rs274 (peer harness canon.sh) and
# `rtcnc check --canon`, and counts programs whose canonical output is byte-identical
# or equal with numbers within 1e-4 (including the ones both stop with an error at the
# same block).
# Needs rs274 and the peer folder ($RTCNC_PEERS or ../shared/peers next to the repository).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
COUNT=${1:-200}
if [ -z "${RTCNC_PEERS:-}" ]; then
  for d in "$ROOT/../shared/peers" "$ROOT/../../shared/peers"; do
    [ -d "$d" ] && RTCNC_PEERS=$d && break
  done
fi
CANON=${RTCNC_PEERS:-/nonexistent}/linuxcnc/canon.sh
if [ ! -x "$CANON" ] || ! command -v rs274 >/dev/null; then
  echo "needs rs274 and $CANON" >&2
  exit 2
fi
cargo build --release -q -p rtcnc --manifest-path "$ROOT/Cargo.toml"
RTCNC=$ROOT/target/release/rtcnc
TBL=$ROOT/crates/gcode/tests/corpus/canon.tbl
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
KEEP=${KEEP:-}   # set KEEP=dir to keep the programs that differ
python3 - "$TMP" "$COUNT" <<'PY'
import math, random, sys
out, n = sys.argv[1], int(sys.argv[2])
for seed in range(n):
    r = random.Random(seed)
    L = [r.choice(["G21", "G20"]) + " G90 G17 F" + str(r.randint(10, 900))]
    x = y = 0.0
    known = True  # the generator knows the current XY (arcs by centre need it)
    for _ in range(r.randint(5, 40)):
        if seed % 3 == 2 and r.random() < 0.3:
            # A third family: control flow, subroutines, parameters, lathe threading (each
            # o-word label used once, as LinuxCNC requires).
            n = r.randint(1, 3)
            lab = 10 + len(L)
            L.append(r.choice([
                "o%d repeat [%d]\nG91 G1 X%.2f Y%.2f\nG90\no%d endrepeat" % (lab, n, r.uniform(-3, 3), r.uniform(-3, 3), lab),
                "#20 = 0\no%d while [#20 lt %d]\nG1 X[#20 * 2] Y#20\n#20 = [#20 + 1]\no%d endwhile" % (lab, n, lab),
                "o%d if [#1 gt 0]\nG0 X1\no%d elseif [#1 lt -1]\nG0 Y1\no%d else\nG0 Z1\no%d endif" % (lab, lab, lab, lab),
                "o<s%d> call [%.2f] [%.2f]" % (seed, r.uniform(-9, 9), r.uniform(-9, 9)),
                "#<_g> = [#<_g> + %d]\nG1 X#<_g> F100" % n,
                "M98 P900 L%d" % n,
                "G18 S500 M3\nG0 X1 Z1\nG33 Z-1 K0.1\nG76 P0.05 Z-1 I-0.1 J0.01 K0.05\nG17",
                "#1 = [%.3f]\n#2 = [#1 ** 2 + sqrt[abs[#1]]]\nG1 X[#2 mod 7] Y[atan[#1]/[2]] F100" % r.uniform(-9, 9),
            ]))
            continue
        if seed % 2 and r.random() < 0.3:
            # A second family: planes, units, radius arcs, other cycles, G52/G92 family,
            # inverse time, probing, polar words, state save/restore.
            L.append(r.choice([
                "G18", "G19", "G17", "G20", "G21", "G91.1", "G90.1", "G7", "G8",
                "G2 X%.3f Y%.3f R%.3f" % (r.uniform(-9, 9), r.uniform(-9, 9), r.uniform(10, 30)),
                "G3 X%.3f Z%.3f R-%.3f" % (r.uniform(-9, 9), r.uniform(-9, 9), r.uniform(10, 30)),
                "G83 X%.3f Y%.3f Z-3 R1 Q0.7" % (r.uniform(-9, 9), r.uniform(-9, 9)),
                "G73 X%.3f Y%.3f Z-2 R1 Q0.5 L2" % (r.uniform(-9, 9), r.uniform(-9, 9)),
                "G82 X1 Y2 Z-1 R2 P0.2", "G85 X2 Y1 Z-1 R2", "G80",
                "G91 G81 X1 Y1 Z-2 R1 L3", "G90",
                "G52 X%.3f Y%.3f" % (r.uniform(-5, 5), r.uniform(-5, 5)), "G92.2", "G92.3",
                "G93 G1 X%.3f Y%.3f F2" % (r.uniform(-9, 9), r.uniform(-9, 9)), "G94 F100",
                "G38.3 Z-%.3f F50" % r.uniform(1, 5), "G0 Z5",
                "G1 @%.3f ^%.1f F100" % (r.uniform(1, 9), r.uniform(0, 360)),
                "M70", "M72", "G30.1", "G53 G0 X0", "G10 L20 P0 X%.2f" % r.uniform(-5, 5),
            ]))
            continue
        if len(L) > 1 and not L[-1].startswith(("G90 G0", "G90 G1", "G90 G2", "G90 G3")):
            known = False
        k = r.random()
        if k < 0.25:
            x, y = r.uniform(-50, 50), r.uniform(-50, 50)
            L.append("G90 G%d X%.3f Y%.3f Z%.3f" % (r.choice([0, 1]), x, y, r.uniform(-10, 10)))
            known = True
        elif k < 0.40 and not known:
            L.append("G90 G%d X%.3f Y%.3f R%.3f" % (r.choice([2, 3]), r.uniform(-50, 50),
                                                   r.uniform(-50, 50), r.uniform(80, 120)))
        elif k < 0.40:
            cx, cy = x + r.uniform(-20, 20), y + r.uniform(-20, 20)
            rad = math.hypot(x - cx, y - cy)
            a = r.uniform(0, 2 * math.pi)
            ex, ey = cx + rad * math.cos(a), cy + rad * math.sin(a)
            L.append("G90 G%d X%.4f Y%.4f I%.4f J%.4f" % (r.choice([2, 3]), ex, ey, cx - x, cy - y))
            x, y = float("%.4f" % ex), float("%.4f" % ey)
        elif k < 0.48:
            L.append("G10 L2 P%d X%.3f Y%.3f R%s" % (r.randint(1, 3), r.uniform(-20, 20),
                                                    r.uniform(-20, 20), r.choice(["0", "15", "90"])))
        elif k < 0.55:
            L.append(r.choice(["G54", "G55", "G56", "G92 X%.3f" % r.uniform(-9, 9), "G92.1"]))
        elif k < 0.62:
            L.append(r.choice(["G91 G1 X1 Y-1", "G90", "G61", "G64 P0.01", "G61.1"]))
        elif k < 0.70:
            L.append("G81 X%.3f Y%.3f Z%.3f R%.3f" % (r.uniform(-20, 20), r.uniform(-20, 20),
                                                     r.uniform(-5, -1), r.uniform(1, 3)))
            L.append(r.choice(["X%.2f" % r.uniform(-9, 9), "G80"]))
            L.append("G80")
        elif k < 0.76:
            L.append("S%d M%d %s" % (r.randint(100, 5000), r.choice([3, 4, 5]), r.choice(["M8", "M9", ""])))
        elif k < 0.82:
            L.append(r.choice(["G53 G0 Z%.3f" % r.uniform(-5, 0), "G28.1", "G28", "G30 Z2"]))
        elif k < 0.90:
            L.append("#%d = [%.3f * %d + #%d]" % (r.randint(1, 9), r.uniform(-5, 5), r.randint(1, 4), r.randint(1, 9)))
            L.append("G1 X#%d Y[#%d / 2]" % (r.randint(1, 9), r.randint(1, 9)))
        elif k < 0.93:
            L.append(r.choice(["T%d M6 G43" % r.randint(1, 6), "G49", "G43.1 Z0.2", "M61 Q%d" % r.randint(0, 6),
                               "G43 H%d" % r.randint(0, 6)]))
        else:
            L.append(r.choice(["G4 P0.5", "M7", "M9", "G64 P0.05 Q0.02", "G98", "G99"]))
    L.append("M2")
    if seed % 3 == 2:
        # Subroutines first (LinuxCNC's forward search has quirks of its own), and the
        # global the program adds to.
        L.insert(0, "#<_g> = 0\no<s%d> sub\nG1 X#1 Y#2 F200\no<s%d> return [#1 + #2]\no<s%d> endsub" % (seed, seed, seed))
        L.append("O900\nG91 G0 X0.5\nG90\nM99")
    open("%s/r%04d.ngc" % (out, seed), "w").write("\n".join(L) + "\n")
PY
# Lines equal with numbers within 1e-4 (the corpus test's rule).
cat > "$TMP/close.py" <<'PY'
import re, sys
a, b = (open(f).read().splitlines() for f in sys.argv[1:3])
num = re.compile(r"-?\d+\.\d+|-?\d+")
def same(x, y):
    if num.sub("#", x) != num.sub("#", y):
        return False
    return all(abs(float(p) - float(q)) <= 1e-4 + 1e-12 for p, q in zip(num.findall(x), num.findall(y)))
sys.exit(0 if len(a) == len(b) and all(same(x, y) for x, y in zip(a, b)) else 1)
PY
same=0
exact=0
with_error=0
total=0
for f in "$TMP"/r*.ngc; do
  b=${f%.ngc}
  total=$((total + 1))
  "$CANON" -t "$TBL" "$f" > "$b.exp" 2> "$b.experr" || true
  "$RTCNC" check --canon --user-units inch --tool-table "$TBL" "$f" > "$b.out" 2> "$b.err" || true
  theirs_failed=0; ours_failed=0
  [ -s "$b.experr" ] && theirs_failed=1
  [ -s "$b.err" ] && ours_failed=1
  if [ $theirs_failed = $ours_failed ] && { cmp -s "$b.exp" "$b.out" || python3 "$TMP/close.py" "$b.exp" "$b.out"; }; then
    same=$((same + 1))
    cmp -s "$b.exp" "$b.out" && exact=$((exact + 1))
    [ -s "$b.err" ] && with_error=$((with_error + 1))
  else
    echo "differs: $(basename "$f")"
    [ -n "$KEEP" ] && mkdir -p "$KEEP" && cp "$f" "$KEEP/"
    (diff "$b.exp" "$b.out" || true) | head -4 | sed 's/^/    /'
    echo "    rs274: $(head -1 "$b.experr" | cut -c1-100)"
    echo "    rtcnc: $(head -1 "$b.err" | cut -c1-100)"
  fi
done
echo "equal within 1e-4: $same of $total random programs ($exact byte-identical, $with_error stop with the same error)"
