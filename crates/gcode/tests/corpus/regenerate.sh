#!/usr/bin/env bash
# Regenerates the expected outputs of the corpus with LinuxCNC 2.9's stand-alone
# interpreter rs274, through the peer harness canon.sh (found as ../shared/peers next to
# the repository, or in $RTCNC_PEERS). For every NAME.ngc it writes
#   NAME.canon  rs274's canonical command stream (stdout of canon.sh)
#   NAME.err    rs274's error report (message and offending block), empty when none
# The tests compare against these files and never need rs274 themselves.
set -euo pipefail
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
ROOT=$(cd "$HERE/../../../.." && pwd)
if [ -z "${RTCNC_PEERS:-}" ]; then
  # ../shared next to the repository (or next to the folder of worktrees).
  for d in "$ROOT/../shared/peers" "$ROOT/../../shared/peers"; do
    [ -d "$d" ] && RTCNC_PEERS=$d && break
  done
fi
PEERS=${RTCNC_PEERS:-$ROOT/../shared/peers}
CANON=$PEERS/linuxcnc/canon.sh
if [ ! -x "$CANON" ] || ! command -v rs274 >/dev/null; then
  echo "regenerate.sh: needs rs274 and $CANON (set RTCNC_PEERS)" >&2
  exit 2
fi
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
cp "$HERE/canon.var" "$TMP/canon.var"
printf '[RS274NGC]\nPARAMETER_FILE = canon.var\nSUBROUTINE_PATH = %s\n' "$HERE/subs" > "$TMP/corpus.ini"
n=0
for f in "$HERE"/*.ngc; do
  b=${f%.ngc}
  # A program may come with its own parameter file NAME.var.
  if [ -f "$b.var" ]; then cp "$b.var" "$TMP/canon.var"; else cp "$HERE/canon.var" "$TMP/canon.var"; fi
  # rs274 always prints its start-up lines; an empty output means it did not run (e.g. a
  # busy machine): try again.
  for attempt in 1 2 3 4 5; do
    "$CANON" -t "$HERE/canon.tbl" -i "$TMP/corpus.ini" "$f" > "$b.canon" 2> "$b.err" || true
    [ -s "$b.canon" ] && break
    sleep 1
  done
  [ -s "$b.canon" ] || { echo "regenerate.sh: rs274 gave no output for $f" >&2; exit 1; }
  n=$((n + 1))
done
echo "regenerated $n expected outputs"
