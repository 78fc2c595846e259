#!/usr/bin/env bash
# Regenerates the CAM corpus (examples/cam-corpus) from nothing: installs the CAM tools
# (Debian: freecad, dxf2gcode, bcnc, python3-ezdxf; OpenCamLib for FreeCAD's 3-D ops from
# PyPI into ~/.cache/rtcnc-cam), draws the parts, runs FreeCAD's Path workbench, dxf2gcode
# and bCNC on them, writes each program's rs274 canonical output (PROGRAM.canon) and
# LinuxCNC 2.9's cycle times (linuxcnc-times.tsv), then README.md's table.
#
#   scripts/cam-corpus/make.sh [--no-times] [--only NAME,NAME]
#
# The canonical output and the cycle times need the peers' LinuxCNC helpers
# ($RTCNC_PEERS, default ../shared/peers); without them those steps are skipped with a
# message and the committed files stay as they are. --no-times skips the cycle times (they
# run in real time, about 45 minutes). --only regenerates the named programs.
set -euo pipefail
cd "$(dirname "$0")/../.."
here=scripts/cam-corpus
corpus=examples/cam-corpus
peers="${RTCNC_PEERS:-../shared/peers}"
times=1
only=""
while [ $# -gt 0 ]; do
  case "$1" in
    --no-times) times=0; shift;;
    --only) only=$2; shift 2;;
    *) sed -n '2,13p' "$0" >&2; exit 2;;
  esac
done

scripts/setup.sh freecad dxf2gcode bcnc python3-ezdxf python3-configobj fonts-dejavu-core
# OpenCamLib (FreeCAD's Surface and Waterline ops import "ocl"). 2022.12.18: the cp311 wheel
# of 2023.1.11 lacks the compiled module.
ocl=$HOME/.cache/rtcnc-cam/pylib
if ! PYTHONPATH=$ocl/opencamlib /usr/bin/python3 -c 'import ocl' 2>/dev/null; then
  /usr/bin/python3 -m pip install -q --target "$ocl" opencamlib==2022.12.18
fi

work=$(mktemp -d /tmp/cam-corpus.XXXXXX)
trap 'rm -rf "$work"' EXIT
mkdir -p "$corpus"
if [ -z "$only" ]; then
  rm -f "$corpus"/*.ngc "$corpus"/*.canon "$corpus"/programs.tsv
fi

echo "== drawings (ezdxf)"
/usr/bin/python3 $here/dxf_parts.py "$work/dxf"
echo "== FreeCAD Path workbench"
CAM_ONLY=$only CAM_OUT="$work/out" PYTHONPATH="$ocl/opencamlib" \
  freecadcmd $here/freecad_parts.py > "$work/freecad.log" 2>&1 \
  || { grep -a "FAILED\|Error" "$work/freecad.log" >&2; exit 1; }
grep -a "^made" "$work/freecad.log" || true
echo "== dxf2gcode"
CAM_ONLY=$only /usr/bin/python3 $here/dxf2gcode_parts.py "$work/dxf" "$work/out" "$corpus/tools.tbl"
echo "== bCNC"
CAM_ONLY=$only /usr/bin/python3 $here/bcnc_parts.py "$work/dxf" "$work/out" 2>&1 | grep -v '^new-config'
cp "$work"/out/*.ngc "$corpus"/
# programs.tsv: program, CAM tool, operation, units, path mode.
{
  if [ -n "$only" ] && [ -f "$corpus/programs.tsv" ]; then
    tail -n +2 "$corpus/programs.tsv" | awk -F'\t' -v only="$only" \
      'BEGIN { n = split(only, a, ","); for (i = 1; i <= n; i++) skip[a[i]] = 1 } !($1 in skip)'
  fi
  sed 's/^\([^\t]*\)\t/\1\tFreeCAD 0.20.2 Path + linuxcnc_post\t/' "$work/out/freecad.tsv"
  sed 's/^\([^\t]*\)\t/\1\tdxf2gcode 20191025\t/' "$work/out/dxf2gcode.tsv"
  sed 's/^\([^\t]*\)\t/\1\tbCNC 0.9.14\t/' "$work/out/bcnc.tsv"
} | sort -u > "$work/programs"
{ printf 'program\tCAM tool\toperation\tunits\tpath mode\n'; cat "$work/programs"; } \
  > "$corpus/programs.tsv"

if [ -x "$peers/linuxcnc/canon.sh" ]; then
  echo "== rs274 canonical output"
  # rs274 reads a tool table in inches: give it the corpus table converted, so that it sees
  # the same tools as a millimetre machine does.
  $here/tools-in-inches.sh "$corpus/tools.tbl" > "$work/tools-inch.tbl"
  for ngc in "$corpus"/*.ngc; do
    name=$(basename "$ngc" .ngc)
    if [ -n "$only" ] && ! grep -q -x -F "$name" <(tr ',' '\n' <<<"$only"); then continue; fi
    "$peers/linuxcnc/canon.sh" -t "$work/tools-inch.tbl" "$ngc" > "${ngc%.ngc}.canon" \
      || echo "rs274 refused $ngc" >&2
  done
else
  echo "peers not found ($peers): canonical output not regenerated" >&2
fi

if [ $times = 1 ]; then
  if [ -x "$peers/linuxcnc/run_sim.sh" ]; then
    echo "== LinuxCNC cycle times (real time)"
    if [ -n "$only" ]; then
      args=(); for n in ${only//,/ }; do args+=("$corpus/$n.ngc"); done
      RTCNC_PEERS=$peers $here/linuxcnc-times.sh "${args[@]}"
    else
      rm -f "$corpus/linuxcnc-times.tsv"
      RTCNC_PEERS=$peers $here/linuxcnc-times.sh
    fi
  else
    echo "peers not found ($peers): cycle times not measured" >&2
  fi
fi

echo "== README.md"
/usr/bin/python3 $here/readme.py "$corpus"
