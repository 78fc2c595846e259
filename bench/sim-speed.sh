#!/usr/bin/env bash
# Virtual-time speed of the motion kernel: how many times faster than real time `rtcnc sim`
# runs a program (goal: >= 1000x for the mill). Runs examples/bracket.ngc on the simulated
# mill (then once more with the per-task host-time profile), examples/gantry-12.ngc on the
# 12-drive gantry and, when the peers folder is present (../shared/peers or $RTCNC_PEERS),
# the four 1 um benchmark polylines on configs/bench-xyz.toml
# (their cycle times are the motion issue's figures; toppra's optimum and LinuxCNC's times
# are in ../shared/peers/README.md).
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --locked -p rtcnc
run() {
    local machine=$1 program=$2
    local out
    out=$(target/release/rtcnc sim "$program" --machine "$machine" -q || true)
    printf '%-28s %-22s %s | %s | %s\n' "$(basename "$program")" "$(basename "$machine")" \
        "$(grep '^cycle time' <<<"$out")" "$(grep '^simulated' <<<"$out")" \
        "$(grep '^limits' <<<"$out")"
}
run configs/sim-mill.toml examples/bracket.ngc
# Where the host time of the mill run goes, per task (the planner works inside
# "interpolation" and "look-ahead"); measuring adds two clock readings per task run.
target/release/rtcnc sim examples/bracket.ngc --machine configs/sim-mill.toml -q --profile |
    sed -n '/^host time/,$p'
run configs/sim-gantry-12.toml examples/gantry-12.ngc
peers=${RTCNC_PEERS:-../shared/peers}
if [ -d "$peers/bench-paths" ]; then
    for p in circle ellipse helix lemniscate; do
        run configs/bench-xyz.toml "$peers/bench-paths/$p.ngc"
    done
else
    echo "peers folder not found ($peers): benchmark paths skipped"
fi
