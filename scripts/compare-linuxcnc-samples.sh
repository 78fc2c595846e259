#!/usr/bin/env bash
# scripts/compare-linuxcnc-samples.sh [DIR] - runs every *.ngc of LinuxCNC's sample programs
# (default /usr/share/linuxcnc/ncfiles, installed with linuxcnc-uspace) through rs274 (the
# peer harness canon.sh) and `rtcnc check --canon`, and prints which outputs are
# byte-identical and, for the others, the first difference and both error messages.
# Needs rs274 and the peer folder ($RTCNC_PEERS or ../shared/peers next to the repository).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
DIR=${1:-/usr/share/linuxcnc/ncfiles}
if [ -z "${RTCNC_PEERS:-}" ]; then
  for d in "$ROOT/../shared/peers" "$ROOT/../../shared/peers"; do
    [ -d "$d" ] && RTCNC_PEERS=$d && break
  done
fi
CANON=${RTCNC_PEERS:-/nonexistent}/linuxcnc/canon.sh
if [ ! -x "$CANON" ] || ! command -v rs274 >/dev/null || [ ! -d "$DIR" ]; then
  echo "needs rs274, $CANON and $DIR" >&2
  exit 2
fi
cargo build --release -q -p rtcnc --manifest-path "$ROOT/Cargo.toml"
RTCNC=$ROOT/target/release/rtcnc
TBL=$ROOT/crates/gcode/tests/corpus/canon.tbl
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
cp "$ROOT/crates/gcode/tests/corpus/canon.var" "$TMP/"
printf '[RS274NGC]\nPARAMETER_FILE = canon.var\nSUBROUTINE_PATH = %s\n' "$DIR" > "$TMP/nc.ini"
same=0
total=0
for f in "$DIR"/*.ngc; do
  b=$(basename "$f" .ngc)
  total=$((total + 1))
  timeout 60 "$CANON" -t "$TBL" -i "$TMP/nc.ini" "$f" > "$TMP/$b.exp" 2> "$TMP/$b.experr" || true
  timeout 60 "$RTCNC" check --canon --user-units inch --tool-table "$TBL" \
    --subroutine-path "$DIR" "$f" > "$TMP/$b.out" 2> "$TMP/$b.err" || true
  if cmp -s "$TMP/$b.exp" "$TMP/$b.out"; then
    same=$((same + 1))
  else
    first=$( (diff "$TMP/$b.exp" "$TMP/$b.out" || true) | sed -n '2p;4p' | tr '\n' ' ' | cut -c1-140)
    echo "differs $b: $first"
    echo "    rs274: $(head -1 "$TMP/$b.experr" | cut -c1-100)"
    echo "    rtcnc: $(head -1 "$TMP/$b.err" | cut -c1-100)"
  fi
done
echo "byte-identical: $same of $total programs"
