#!/usr/bin/env bash
# Regenerates the expected outputs of the programs under tests/data/*/ with LinuxCNC 2.9's
# stand-alone interpreter rs274, through the peer harness canon.sh (found as ../shared/peers
# next to the repository, or in $RTCNC_PEERS), with the corpus's tool table and parameter
# file. For every FOLDER/NAME.ngc it writes
#   NAME.canon  rs274's canonical command stream (stdout of canon.sh)
#   NAME.err    rs274's error report (message and offending block), empty when none
# `regenerate.sh FOLDER...` does only those folders. The tests never need rs274.
set -euo pipefail
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
ROOT=$(cd "$HERE/../../../.." && pwd)
CORPUS=$HERE/../corpus
if [ -z "${RTCNC_PEERS:-}" ]; then
  for d in "$ROOT/../shared/peers" "$ROOT/../../shared/peers"; do
    [ -d "$d" ] && RTCNC_PEERS=$d && break
  done
fi
CANON=${RTCNC_PEERS:-$ROOT/../shared/peers}/linuxcnc/canon.sh
if [ ! -x "$CANON" ] || ! command -v rs274 >/dev/null; then
  echo "regenerate.sh: needs rs274 and $CANON (set RTCNC_PEERS)" >&2
  exit 2
fi
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
cp "$CORPUS/canon.var" "$TMP/canon.var"
printf '[RS274NGC]\nPARAMETER_FILE = canon.var\n' > "$TMP/data.ini"
if [ $# -gt 0 ]; then folders=("$@"); else folders=("$HERE"/*/); fi
n=0
for folder in "${folders[@]}"; do
  for f in "${folder%/}"/*.ngc; do
    b=${f%.ngc}
    # rs274 always prints its start-up lines; an empty output means it did not run (a
    # busy machine): try again.
    for attempt in 1 2 3 4 5; do
      "$CANON" -t "$CORPUS/canon.tbl" -i "$TMP/data.ini" "$f" > "$b.canon" 2> "$b.err" || true
      [ -s "$b.canon" ] && break
      sleep 1
    done
    [ -s "$b.canon" ] || { echo "regenerate.sh: rs274 gave no output for $f" >&2; exit 1; }
    n=$((n + 1))
  done
done
echo "regenerated $n expected outputs"
