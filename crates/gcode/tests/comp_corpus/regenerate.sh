#!/usr/bin/env bash
# Regenerates the reference outputs of the cutter compensation corpus with LinuxCNC's rs274
# (through the peers' canon.sh, found at $RTCNC_PEERS/linuxcnc or ../shared/peers/linuxcnc
# beside the repository). For every PROGRAM.ngc it writes
#   PROGRAM.expected  rs274's canonical output of the program (it compensates inside its
#                     interpreter): what the compensation stage must produce;
#   PROGRAM.input     rs274's output of the same program with G41/G42/G41.1/G42.1/G40
#                     replaced by marker comments (RTCNC,COMP,side,radius,orientation):
#                     the uncompensated stream the interpreter hands to the stage.
# Both keep rs274's N-word column (every corpus line has an N word) so the tests can place
# the compensation commands in their blocks. The tool table is PROGRAM.tbl if there is one,
# else canon.tbl in this folder; rs274 reads it in inches (a D3 tool is 76.2 mm across in a
# G21 program).
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
ROOT=$(cd "$HERE/../../../.." && pwd)
PEERS=${RTCNC_PEERS:-$ROOT/../shared/peers}
CANON=$PEERS/linuxcnc/canon.sh
if [ ! -x "$CANON" ] || ! command -v rs274 >/dev/null; then
  echo "regenerate.sh: needs rs274 and $CANON (LinuxCNC peers); nothing done" >&2
  exit 2
fi
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
for ngc in "$HERE"/*.ngc; do
  base=${ngc%.ngc}
  tbl=$HERE/canon.tbl
  [ -f "$base.tbl" ] && tbl=$base.tbl
  "$CANON" -k -e -t "$tbl" "$ngc" > "$base.expected" 2>/dev/null || true
  python3 "$HERE/uncompensate.py" "$tbl" < "$ngc" > "$TMP/input.ngc"
  "$CANON" -k -e -t "$tbl" "$TMP/input.ngc" > "$base.input" 2>/dev/null || true
  echo "$(basename "$ngc"): $(wc -l < "$base.expected") lines expected"
done
