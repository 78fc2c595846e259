#!/usr/bin/env bash
# Time to compute a time-optimal jerk-limited profile: rtcnc-motion's OTG against ruckig
# 0.19.4 on the same 1000 rest-to-rest cases (crates/motion/tests/data/ruckig_cases.json).
#
# ruckig is timed through its Python bindings from the peers' venv, so two ruckig figures
# are printed: the best-pass wall time of one Python calculate() call (includes the Python
# binding overhead, so it is an upper bound of ruckig's own cost) and the median of ruckig's
# C++ calculation_duration over one cold update() per case (indicative only).
# Our figure is the criterion mean over the whole set divided by 1000 (native Rust).
# Needs ../shared/peers (or $RTCNC_PEERS) and ~/.cache/rtcnc-peers/venv; skips ruckig if absent.
set -euo pipefail
cd "$(dirname "$0")/.."
peers="${RTCNC_PEERS:-../shared/peers}"
python="${RTCNC_PEERS_PYTHON:-$HOME/.cache/rtcnc-peers/venv/bin/python}"
cases=crates/motion/tests/data/ruckig_cases.json

echo "== rtcnc-motion (criterion, release)"
ours_us=$(cargo bench -q -p rtcnc-motion --bench otg -- "1000 ruckig" 2>/dev/null \
  | awk '/time:/ { v=$4; u=$5; if (u=="ms") v*=1000; else if (u=="ns") v/=1000; print v/1000; exit }')
echo "rtcnc-motion: ${ours_us} us per profile (mean over the 1000 cases)"

if [[ ! -d "$peers" || ! -x "$python" ]]; then
  echo "ruckig peer not found ($peers, $python): skipping the comparison"
  exit 0
fi
echo "== ruckig 0.19.4 (peer, $peers; Python bindings)"
read -r py_us cpp_us < <("$python" - "$cases" <<'PY'
import json, sys, time, statistics
from ruckig import InputParameter, OutputParameter, Ruckig, Trajectory
cases = json.load(open(sys.argv[1]))["cases"]
inputs = []
for c in cases:
    inp = InputParameter(1)
    inp.current_position, inp.target_position = [0.0], [c["pf"]]
    inp.current_velocity = inp.current_acceleration = [0.0]
    inp.target_velocity = inp.target_acceleration = [0.0]
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = [c["vmax"]], [c["amax"]], [c["jmax"]]
    inputs.append(inp)
otg, tr = Ruckig(1), Trajectory(1)
passes = []
for _ in range(20):
    t0 = time.perf_counter_ns()
    for inp in inputs:
        otg.calculate(inp, tr)
    passes.append((time.perf_counter_ns() - t0) / 1e3 / len(inputs))
internal = []
for inp in inputs:
    o = Ruckig(1, 1e-3); out = OutputParameter(1)
    o.update(inp, out)
    internal.append(out.calculation_duration)
print(min(passes), statistics.median(internal))
PY
)
echo "ruckig python calculate(): ${py_us} us per profile (includes Python binding overhead)"
echo "ruckig C++ calculation_duration: ${cpp_us} us per profile (ruckig's own timer, median of one cold update() per case)"
awk -v o="$ours_us" -v p="$py_us" -v c="$cpp_us" 'BEGIN {
  printf "ratio ours / ruckig via python = %.2f (ruckig figure includes the python call overhead)\n", o/p;
  printf "ratio ours / ruckig C++ timer  = %.2f (cold single calls: indicative only)\n", o/c }'
