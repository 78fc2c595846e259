#!/usr/bin/env bash
# scripts/differential-lathe-cycles.sh [COUNT] - random differential test of the G70-G72
# lathe cycles against LinuxCNC's rs274: generates COUNT (default 300) random profiles
# (lines, quarter arcs both ways, A fillets and C chamfers, in the four quadrants, mm and
# inch) cut by a random G70, G71, G71.1, G71.2, G72, G72.1 or G72.2 (D, I, R, E, P), runs
# each through rs274 (peer harness canon.sh, 10 s limit) and `rtcnc check --canon`, and
# counts programs with equal output (numbers within 1e-4; both stopped by an error at the
# same place counts as equal). rs274's own debugging lines ("Oops ...") are left out of
# its output. Programs where rs274 crashes (no output) or never ends are counted apart:
# rtcnc reports an error for those (docs/gcode.md).
# Needs rs274 and the peer folder ($RTCNC_PEERS or ../shared/peers next to the repository).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
COUNT=${1:-300}
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
import random, re, sys
out, count = sys.argv[1], int(sys.argv[2])

def profile(r):
    """Moves falling in Z from Z0 with X varying, ending above the start."""
    z, x = 0.0, r.uniform(2, 8)
    moves = [f"G1 X{x:.3f} Z{z:.3f}"]
    for _ in range(r.randint(3, 9)):
        dz = -r.uniform(1, 6)
        if r.random() < 0.5:
            x2 = max(0.5, x + r.choice([0, 0, r.uniform(-3, 5)]))
            corner = r.random()
            word = (f" A{r.uniform(0.2, 1):.2f}" if corner < 0.15
                    else f" C{r.uniform(0.2, 1):.2f}" if corner < 0.3 else "")
            moves.append(f"G1 X{x2:.3f} Z{z + dz:.3f}{word}")
            x, z = x2, z + dz
            if r.random() < 0.3:
                x += r.uniform(1, 4)
                moves.append(f"G1 X{x:.3f}")
            continue
        rad = r.uniform(1, 4)
        if r.random() < 0.7:  # a quarter arc rising in X
            if r.random() < 0.5:
                moves.append(f"G2 X{x + rad:.3f} Z{z - rad:.3f} I{rad:.3f} K0")
            else:
                moves.append(f"G3 X{x + rad:.3f} Z{z - rad:.3f} I0 K{-rad:.3f}")
            x, z = x + rad, z - rad
        elif x - rad >= 0.5:  # falling in X
            if r.random() < 0.5:
                moves.append(f"G3 X{x - rad:.3f} Z{z - rad:.3f} I{-rad:.3f} K0")
            else:
                moves.append(f"G2 X{x - rad:.3f} Z{z - rad:.3f} I0 K{-rad:.3f}")
            x, z = x - rad, z - rad
    top = max(x, 10) + r.uniform(1, 4)
    moves.append(f"G1 X{top:.3f}")
    return moves, top

for seed in range(count):
    r = random.Random(seed)
    moves, top = profile(r)
    units = r.choice(["G21", "G21", "G20"])
    s = 1.0 if units == "G21" else 0.04
    fz, fx = r.choice([1, 1, -1]), r.choice([1, 1, -1])  # the four quadrants
    def place(m):
        def scale(w):
            k, v = w.group(1), float(w.group(2))
            v *= fx if k in "XI" else fz if k in "ZK" else 1
            return f"{k}{v * s:.4f}"
        m = re.sub(r"([XZIK])(-?\d+\.?\d*)", scale, m)
        if fx * fz < 0:  # a mirrored arc turns the other way
            m = m.replace("G2 ", "G#").replace("G3 ", "G2 ").replace("G#", "G3 ")
        return m
    sx, sz = (top + r.uniform(0.5, 3)) * fx * s, r.uniform(0.5, 3) * fz * s
    p = [f"(random lathe cycle {seed})", f"G18 {units} G90 F{r.choice([100, 200])}",
         f"G0 X{sx:.4f} Z{sz:.4f}", "o10 sub"] + ["  " + place(m) for m in moves]
    p.append("o10 endsub")
    cycle = r.choice(["G71", "G71.1", "G71.2", "G72", "G72.1", "G72.2", "G70"])
    d = r.choice([0, 0.2, 0.5, 1.0]) * s
    if cycle == "G70":
        p.append(f"G70 Q10 D{d:.4f} E{r.choice([0, 0.1]) * s:.4f} P{r.randint(1, 3)}")
    else:
        p.append(f"{cycle} Q10 D{d:.4f} I{r.choice([0.5, 1, 1.7]) * s:.4f} "
                 f"R{r.choice([0.3, 0.5]) * s:.4f}")
        if r.random() < 0.5:
            p.append(f"G70 Q10 X{sx:.4f} Z{sz:.4f} D{d:.4f}")
    p.append("M2")
    open(f"{out}/r{seed:05d}.ngc", "w").write("\n".join(p) + "\n")
PY
cat > "$TMP/close.py" <<'PY'
import re, sys
a = [l for l in open(sys.argv[1]).read().splitlines() if not l.startswith("Oops")]
b = open(sys.argv[2]).read().splitlines()
num = re.compile(r"-?\d+\.\d+|-?\d+")
def same(x, y):
    if num.split(x) != num.split(y):
        return False
    p, q = num.findall(x), num.findall(y)
    return len(p) == len(q) and all(abs(float(u) - float(v)) <= 1e-4 for u, v in zip(p, q))
sys.exit(0 if len(a) == len(b) and all(same(x, y) for x, y in zip(a, b)) else 1)
PY
same=0; with_error=0; crashed=0; endless=0; differ=0; total=0
for f in "$TMP"/r*.ngc; do
  b=${f%.ngc}
  total=$((total + 1))
  rc=0
  timeout 10 "$CANON" -t "$TBL" "$f" > "$b.exp" 2> "$b.experr" || rc=$?
  "$RTCNC" check --canon --user-units inch --tool-table "$TBL" "$f" > "$b.out" 2> "$b.err" || true
  if [ $rc = 124 ]; then endless=$((endless + 1)); continue; fi
  if [ $rc -ge 128 ]; then crashed=$((crashed + 1)); continue; fi
  theirs_failed=0; ours_failed=0
  [ -s "$b.experr" ] && theirs_failed=1
  [ -s "$b.err" ] && ours_failed=1
  if [ $theirs_failed = $ours_failed ] && python3 "$TMP/close.py" "$b.exp" "$b.out"; then
    same=$((same + 1))
    [ $ours_failed = 1 ] && with_error=$((with_error + 1))
  else
    differ=$((differ + 1))
    echo "differs: $(basename "$f")"
    [ -n "$KEEP" ] && mkdir -p "$KEEP" && cp "$f" "$KEEP/"
  fi
done
echo "equal within 1e-4: $same of $total random lathe cycles ($with_error stop with the same error);" \
  "$differ differ; rs274 crashed on $crashed and never ended on $endless (rtcnc: an error)"
[ $differ = 0 ]
