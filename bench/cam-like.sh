#!/usr/bin/env bash
# CAM-like generated programs (bench/cam_like.py: contours of dense polylines, pockets,
# 3-D rasters, trochoidal clearing, engraving, zigzags; one program per family and seed) on the
# benchmark machine (configs/bench-xyz.toml) in virtual time with `rtcnc sim`, and, with
# --linuxcnc, on LinuxCNC 2.9's simulator (the peers' run_sim.sh, same limits; it runs in
# real time, some 25 minutes for the default seeds).
#
#   bench/cam-like.sh [--linuxcnc] [SEEDS]      (SEEDS: comma-separated, default 1,2,3,4,5,6)
#
# One line per program: ended or not, the largest |v|, |a|, |j| of any axis as a share of
# its limit, the motion time (from the period before the first move to the last moving one,
# as run_sim.sh measures it), the stops (runs of periods at rest between two motions) and,
# with LinuxCNC, its time, its stops and the ratio. Then the programs over a limit, and the
# median and worst time ratio per family and over all.
set -euo pipefail
cd "$(dirname "$0")/.."
lcnc=0
if [[ "${1:-}" == "--linuxcnc" ]]; then
  lcnc=1
  shift
fi
seeds="${1:-1,2,3,4,5,6}"
peers="${RTCNC_PEERS:-../shared/peers}"
run_sim="$peers/linuxcnc/run_sim.sh"
if [[ $lcnc == 1 && ! -x "$run_sim" ]]; then
  echo "LinuxCNC's simulator not found ($run_sim): rtcnc only"
  lcnc=0
fi
cargo build --release --locked -q -p rtcnc
work=$(mktemp -d /tmp/cam-like.XXXXXX)
trap 'rm -rf "$work"' EXIT
python3 bench/cam_like.py "$work/programs" "$seeds"
rows="$work/rows.tsv"
: > "$rows"
for ngc in "$work"/programs/*.ngc; do
  name=$(basename "$ngc" .ngc)
  out="$work/$name"
  target/release/rtcnc sim "$ngc" --machine configs/bench-xyz.toml --out "$out" -q --limit 1800 \
    > "$out.txt" 2>&1 || true
  lc_dir=""
  if [[ $lcnc == 1 ]]; then
    lc_dir="$work/lcnc-$name"
    "$run_sim" "$ngc" --vel 100 --acc 1000 --timeout 900 --out "$lc_dir" > "$lc_dir.log" 2>&1 || true
  fi
  python3 - "$name" "$out" "$lc_dir" >> "$rows" <<'PY'
import csv, json, sys
name, out, lc_dir = sys.argv[1:4]
try:
    s = json.load(open(out + "/summary.json"))
except OSError:
    print("\t".join([name, "0", "nan", "nan", "nan", "nan", "0", "nan", "0"]))
    sys.exit()
ratios = [max(a["max_%s" % k] / a["limit_%s" % k] for a in s["axes"].values())
          for k in ("velocity", "acceleration", "jerk")]

def motion(points):
    """Motion time (first change to last change, > 1e-9 mm) and stops (runs of periods
    without a change between two changes)."""
    first = last = None
    stops, still, prev = 0, 0, None
    for t, p in points:
        if prev is not None:
            if max(abs(a - b) for a, b in zip(p, prev[1])) > 1e-9:
                if first is None:
                    first = prev[0]
                elif still > 0:
                    stops += 1
                last, still = t, 0
            else:
                still += 1
        prev = (t, p)
    return ((last - first) if first is not None else 0.0), stops

with open(out + "/setpoints.csv") as f:
    rd = csv.reader(f)
    head = next(rd)
    axes = [head.index(a) for a in ("X_setpoint", "Y_setpoint", "Z_setpoint")]
    ours, our_stops = motion((float(r[0]), [float(r[i]) for i in axes]) for r in rd)
lc, lc_stops = float("nan"), 0
if lc_dir:
    try:
        ok = "result=OK" in open(lc_dir + "/run_status.txt").read()
        with open(lc_dir + "/samples.csv") as f:
            rd = csv.reader(f)
            next(rd)
            t_lc, lc_stops = motion((float(r[0]), [float(x) for x in r[1:4]]) for r in rd)
        if ok:
            lc = t_lc
    except OSError:
        pass
print("\t".join([name, "1" if s["ended"] else "0"] + ["%.4f" % r for r in ratios]
                + ["%.3f" % ours, str(our_stops), "%.3f" % lc, str(lc_stops)]))
PY
done

python3 - "$rows" <<'PY'
import math, statistics, sys
rows = [l.rstrip("\n").split("\t") for l in open(sys.argv[1])]
print("%-12s %-6s %7s %7s %7s %9s %6s %9s %6s %7s" % (
    "program", "ended", "v/lim", "a/lim", "j/lim", "ours[s]", "stops", "lcnc[s]", "stops", "ratio"))
fam = {}
over = []
for r in rows:
    name, ended = r[0], r[1] == "1"
    v, a, j, ours, st, lc, lst = float(r[2]), float(r[3]), float(r[4]), float(r[5]), r[6], float(r[7]), r[8]
    ratio = ours / lc if lc > 0 else float("nan")
    if max(v, a, j) > 1 + 1e-9:
        over.append(name)
    print("%-12s %-6s %7.4f %7.4f %7.4f %9.3f %6s %9.3f %6s %7.3f" % (
        name, "yes" if ended else "NO", v, a, j, ours, st, lc, lst, ratio))
    if ended and not math.isnan(ratio):
        fam.setdefault(name.rsplit("-", 1)[0], []).append((ratio, name))
print("ended %d/%d; over a limit: %s" % (sum(r[1] == "1" for r in rows), len(rows), ", ".join(over) or "none"))
every = [x for v in fam.values() for x in v]
for f, v in sorted(fam.items()) + ([("all", every)] if every else []):
    worst = max(v)
    print("%-9s median %.3f, worst %.3f (%s), n %d" % (f, statistics.median(x for x, _ in v), worst[0], worst[1], len(v)))
if not every:
    print("no LinuxCNC times (run with --linuxcnc where the peers are installed)")
PY
