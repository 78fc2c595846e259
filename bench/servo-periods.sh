#!/usr/bin/env bash
# The same program at servo periods of 100 us to 4 ms, changing only the task periods of the
# machine file: per program and period, the cycle time, the largest v/a/j ratio to the limits
# and the largest distance of the path from the 100 us run's (bench/compare-paths.py).
# Programs: the shipped examples on their machines, the defect list's cases
# (crates/kernel/tests/data/cases) on the benchmark machine and, when the peers folder is
# present (../shared/peers or $RTCNC_PEERS), the four 1 um benchmark polylines.
#
#   bench/servo-periods.sh [--quick]     # --quick: the examples only
set -euo pipefail
cd "$(dirname "$0")/.."
quick=${1:-}
cargo build --release --locked -q -p rtcnc
rtcnc=target/release/rtcnc
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
periods=(100us 250us 500us 1ms 2ms 4ms)

# The machine file `$1` with every task period set to `$2`, its relative files resolved.
machine_at() {
    local file=$1 period=$2 out="$work/$(basename "$1" .toml)-$2.toml"
    local dir
    dir=$(cd "$(dirname "$file")" && pwd)
    python3 - "$file" "$period" "$dir" >"$out" <<'EOF'
import re, sys
text = open(sys.argv[1]).read()
period, base = sys.argv[2], sys.argv[3]
text = re.sub(r'(\b(?:program|tool_table|parameters)\s*=\s*")(?!/)([^"]+)"', lambda m: f'{m.group(1)}{base}/{m.group(2)}"', text)
# The defaults of docs/configuration.md's [tasks], at the period.
tasks = [('fieldbus', 126, ''), ('machine_logic', 125, ''), ('interpolation', 124, ''),
         ('look_ahead', 120, ', runs = 4'), ('command_parsing', 117, ', runs = 4'),
         ('status_feedback', 110, '')]
if re.search(r'^\[tasks\]', text, re.M):
    text = re.sub(r'period = "[^"]+"', f'period = "{period}"', text)
else:
    text += '\n[tasks]\n' + ''.join(f'{t} = {{ period = "{period}", priority = {p}{r} }}\n' for t, p, r in tasks)
print(text)
EOF
    echo "$out"
}

sweep() {
    local machine=$1 program=$2 name
    name=$(basename "$program" .ngc)
    echo "== $name on $(basename "$machine")"
    for p in "${periods[@]}"; do
        local out="$work/$name-$p" report
        report=$("$rtcnc" sim "$program" --machine "$(machine_at "$machine" "$p")" -q --out "$out" \
            --resume-after-pause 0 2>&1 || true)
        local ratio path="(reference)"
        ratio=$(python3 - "$out/summary.json" <<'EOF'
import json, sys
s = json.load(open(sys.argv[1]))
worst = 0.0
for a in s["axes"].values():
    for k in ("velocity", "acceleration", "jerk"):
        lim = a.get(f"limit_{k}") or 0
        if lim:
            worst = max(worst, a[f"max_{k}"] / lim)
print(f"{worst:.4f}")
EOF
) || ratio="n/a ($(grep -m1 'error' <<<"$report" || echo 'no summary'))"
        if [ "$p" != 100us ]; then
            path=$(python3 bench/compare-paths.py "$work/$name-100us" "$out" 2>&1 | sed 's/^path *//' || true)
        fi
        printf '  %-6s %s  v/a/j %s  %s  %s\n' "$p" "$(grep '^cycle time' <<<"$report")" "$ratio" \
            "$(grep '^faults' <<<"$report")" "$path"
        [ "$p" = 100us ] || rm -rf "$out"
    done
    rm -rf "$work/$name-100us"
}

sweep configs/sim-mill.toml examples/bracket.ngc
sweep configs/sim-lathe.toml examples/lathe-shaft.ngc
sweep configs/sim-gantry-12.toml examples/gantry-12.ngc
[ "$quick" = --quick ] && exit 0
for case in crates/kernel/tests/data/cases/*.ngc; do
    sweep configs/bench-xyz.toml "$case"
done
peers=${RTCNC_PEERS:-../shared/peers}
if [ -d "$peers/bench-paths" ]; then
    for p in circle ellipse helix lemniscate; do
        sweep configs/bench-xyz.toml "$peers/bench-paths/$p.ngc"
    done
else
    echo "peers folder not found ($peers): benchmark paths skipped"
fi
