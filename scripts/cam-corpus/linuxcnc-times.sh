#!/usr/bin/env bash
# Cycle times of the CAM corpus on LinuxCNC 2.9's simulator (the peers' run_sim.sh: trivkins
# XYZ, 1 ms servo period, perfect servo loop, G64 at start-up) with the limits of
# configs/bench-xyz.toml (100 mm/s and 1000 mm/s² per axis; LinuxCNC has no jerk limit) and
# the corpus's tool table. Writes examples/cam-corpus/linuxcnc-times.tsv: program, seconds
# (run_sim.sh's motion_time_s: from the servo period before the first move to the last
# moving period), how measured. Runs in real time: about 45 minutes for the whole corpus.
#
#   scripts/cam-corpus/linuxcnc-times.sh [PROGRAM.ngc ...]   (default: every corpus program)
set -euo pipefail
cd "$(dirname "$0")/../.."
peers="${RTCNC_PEERS:-../shared/peers}"
run_sim="$peers/linuxcnc/run_sim.sh"
if [ ! -x "$run_sim" ]; then
  echo "linuxcnc-times: $run_sim not found (set RTCNC_PEERS): cycle times not measured" >&2
  exit 1
fi
corpus=examples/cam-corpus
out=$corpus/linuxcnc-times.tsv
version=$(dpkg-query -W -f='${Version}' linuxcnc-uspace 2>/dev/null || echo unknown)
how="run_sim.sh --vel 100 --acc 1000 (bench-xyz limits), tools.tbl, motion_time_s; linuxcnc-uspace $version"
programs=("$@")
[ ${#programs[@]} -gt 0 ] || programs=("$corpus"/*.ngc)
work=$(mktemp -d /tmp/cam-corpus-lcnc.XXXXXX)
trap 'rm -rf "$work"' EXIT
[ -f "$out" ] || printf 'program\tseconds\thow measured\n' > "$out"
for ngc in "${programs[@]}"; do
  name=$(basename "$ngc" .ngc)
  dir="$work/$name"
  # A run counts when run_sim.sh reports OK and the last line LinuxCNC moved on is within
  # five lines of the program's last line with an axis word (CAM output repeats its last
  # retract, which does not move): on a loaded machine its user-space motion module
  # can miss a command ("USRMOT: ERROR: command timeout") and stop the program early while
  # the run still looks finished. Such a run is tried again, twice at most.
  last_move=$(grep -n -i '^[^(;]*[XYZ] *[-+.0-9]' "$ngc" | tail -1 | cut -d: -f1)
  seconds=NA
  for attempt in 1 2 3; do
    rm -rf "$dir"
    if "$run_sim" "$ngc" --vel 100 --acc 1000 --timeout 900 \
         --set "EMCIO.TOOL_TABLE=$(readlink -f $corpus/tools.tbl)" --out "$dir" > "$dir.log" 2>&1 \
       && python3 -c 'import json,sys; sys.exit(json.load(open(sys.argv[1]))["last_program_line"] < int(sys.argv[2]) - 5)' \
            "$dir/summary.json" "$last_move"; then
      seconds=$(python3 -c 'import json,sys; print("%.3f" % json.load(open(sys.argv[1]))["motion_time_s"])' "$dir/summary.json")
      break
    fi
    echo "linuxcnc-times: $name (attempt $attempt): $(grep -h '^result=\|^error=' "$dir/run_status.txt" 2>/dev/null | tr '\n' ' ') $(grep -h 'ERROR' "$dir/linuxcnc.log" 2>/dev/null | head -1)" >&2
  done
  # Replace the program's row, keep the others.
  grep -v -P "^\Q$name\E\t" "$out" > "$work/tsv" || true
  printf '%s\t%s\t%s\n' "$name" "$seconds" "$how" >> "$work/tsv"
  { head -1 "$work/tsv"; tail -n +2 "$work/tsv" | sort; } > "$out"
  printf '%-28s %s\n' "$name" "$seconds"
done
