#!/usr/bin/env bash
# Prints a LinuxCNC tool table with its lengths (Z) and diameters (D) converted from mm to
# inches: LinuxCNC's stand-alone rs274 reads a tool table in inches.
set -euo pipefail
awk '{
  out = ""
  for (i = 1; i <= NF; i++) {
    w = $i
    if (w ~ /^;/) { out = out " " substr($0, index($0, ";")); break }
    if (w ~ /^Z[+-]?[0-9.]+$/) w = sprintf("Z%+.6f", substr(w, 2) / 25.4)
    else if (w ~ /^D[0-9.]+$/) w = sprintf("D%.6f", substr(w, 2) / 25.4)
    out = (out == "" ? w : out " " w)
  }
  print out
}' "$1"
