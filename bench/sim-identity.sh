#!/usr/bin/env bash
# Fingerprints of what `rtcnc sim --out` records (set-points and feedback, sha256 of the CSV
# files) for the shipped examples on their machines, the bracket on the mill with every
# task period at 100 us, and, when the peers folder is present
# ($RTCNC_PEERS or ../shared/peers), the four benchmark polylines on configs/bench-xyz.toml.
# A change that is meant to make the simulation faster, not different, keeps every line:
#
#   bench/sim-identity.sh > before.txt   # on the commit before
#   bench/sim-identity.sh > after.txt    # on the change
#   diff before.txt after.txt
#
# Optional argument: the rtcnc binary to run (default: target/release/rtcnc, built here).
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-}
if [[ -z $bin ]]; then
    cargo build -q --release --locked -p rtcnc
    bin=target/release/rtcnc
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# The mill at 100 us (as bench/sim-speed.sh makes it).
sed -e 's/period = "1ms"/period = "100us"/' \
    -e "s#\"\.\./examples/#\"$PWD/examples/#" \
    -e "s#\"sim-mill.tbl\"#\"$PWD/configs/sim-mill.tbl\"#" \
    configs/sim-mill.toml >"$tmp/sim-mill-100us.toml"
runs=(
    "configs/sim-mill.toml examples/bracket.ngc"
    "$tmp/sim-mill-100us.toml examples/bracket.ngc"
    "configs/sim-lathe.toml examples/lathe-shaft.ngc"
    "configs/sim-gantry-12.toml examples/gantry-12.ngc"
    "configs/experiment-1.toml examples/experiment-1.ngc"
)
peers=${RTCNC_PEERS:-../shared/peers}
if [[ -d $peers/bench-paths ]]; then
    for p in circle ellipse helix lemniscate; do
        runs+=("configs/bench-xyz.toml $peers/bench-paths/$p.ngc")
    done
else
    echo "# peers folder not found ($peers): benchmark paths skipped"
fi
for r in "${runs[@]}"; do
    read -r machine program <<<"$r"
    out=$tmp/out
    rm -rf "$out"
    # A program may end with a fault or a limit (exit status 1): its recording still counts.
    "$bin" sim "$program" --machine "$machine" -q --out "$out" >/dev/null 2>&1 || true
    for f in setpoints.csv feedback.csv; do
        if [[ -f $out/$f ]]; then
            sum=$(sha256sum "$out/$f" | cut -d' ' -f1)
        else
            sum=missing
        fi
        printf '%s %s %s %s\n' "$sum" "$f" "$(basename "$machine")" "$(basename "$program")"
    done
done
