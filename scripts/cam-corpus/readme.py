"""Writes examples/cam-corpus/README.md from programs.tsv, linuxcnc-times.tsv and the
programs themselves ("what it exercises" is read off each program's words).

    python3 scripts/cam-corpus/readme.py examples/cam-corpus
"""

import os
import re
import statistics
import sys

HEAD = """# CAM corpus

Programs written by CAM systems that install on Debian, on parts designed for the corpus,
for measuring rtcnc on real CAM output (issue 12): {count} programs, {by_tool}.
`scripts/cam-corpus/make.sh` regenerates everything here from nothing (the parts are
scripts: FreeCAD Part/Sketcher solids in `freecad_parts.py`, DXF drawings written with
ezdxf in `dxf_parts.py`; the CAM runs are `freecad_parts.py`, `dxf2gcode_parts.py` and
`bcnc_parts.py`).

- Machine: `configs/bench-xyz.toml` (X Y Z, 100 mm/s, 1000 mm/s², 50 000 mm/s³, ideal
  drives, ±1000 mm) with `tools.tbl` here as its tool table (`[files] tool_table`). Every
  part lies in X 0..250, Y 0..200, Z -25..+15 of the work coordinates; tool lengths are 30
  to 60 mm, so Z stays within -25..+75 on the machine.
- `PROGRAM.canon`: LinuxCNC 2.9's `rs274` canonical output (peers' `canon.sh -t`, with
  `tools.tbl` converted to inches, as rs274 reads a tool table in inches).
- `linuxcnc-times.tsv`: LinuxCNC 2.9's simulator (peers' `run_sim.sh --vel 100 --acc 1000`,
  the corpus tool table): `motion_time_s`, from the servo period before the first move to
  the last moving one. LinuxCNC has no jerk limit, no spindle model (M3 does not wait for
  the spindle) and changes tools in no time.
- `programs.tsv`: how each program was made (CAM tool, operation, units, path mode).
- A program's first line is a comment naming it and how it was made; the rest is the CAM
  tool's output, unchanged except that FreeCAD's header (`--no-header`) and dxf2gcode's
  "(Time: ...)" line, which carry the date, are left out.
- Regenerating gives byte-identical programs except three of FreeCAD's adaptive clearing
  (`adaptive-boss-inch`, `adaptive-pocket-3mm`, `adaptive-profile-8mm`), whose paths differ
  slightly from run to run; make.sh then rewrites their canonical output and times too.
- `bench/cam-corpus.sh` runs all of them with `rtcnc sim`;
  `crates/kernel/tests/cam_corpus.rs` runs them in the tests.

| program | CAM tool: operation | units | path mode | lines | LinuxCNC s | what it exercises |
|---|---|---|---|---:|---:|---|
"""


def exercises(text):
    words = re.findall(r"\b([GM])\s*(\d+(?:\.\d)?)", re.sub(r"\([^)]*\)", "", text.upper()))
    codes = {"%s%s" % (a, b.lstrip("0") or "0") for a, b in words}
    out = []
    arcs = len(re.findall(r"^\s*(?:N\d+\s*)?G0?[23]\b", text, re.M | re.I))
    helical = 0
    for line in text.splitlines():
        u = line.upper()
        if re.match(r"\s*(N\d+\s*)?G0?[23]\b", u) and " Z" in u:
            helical += 1
    if arcs:
        out.append("%d arcs" % arcs)
    for cycle in ("G73", "G81", "G82", "G83"):
        if cycle in codes:
            out.append(cycle)
    if "G41" in codes or "G42" in codes:
        out.append("cutter compensation G41/G42")
    if "G43" in codes:
        out.append("G43")
    if "G4" in codes:
        out.append("dwell")
    tools = len(re.findall(r"\bM0?6\b", text, re.I))
    if tools > 1:
        out.append("%d tool changes" % tools)
    if "M8" in codes or "M7" in codes:
        out.append("coolant")
    if "M30" in codes:
        out.append("M30")
    if "G98" in codes or "G99" in codes:
        out.append("G98" if "G98" in codes else "G99")
    return ", ".join(out)


def main():
    corpus = sys.argv[1]
    rows = [line.rstrip("\n").split("\t") for line in open(os.path.join(corpus, "programs.tsv"))][1:]
    times = {}
    path = os.path.join(corpus, "linuxcnc-times.tsv")
    if os.path.exists(path):
        for line in list(open(path))[1:]:
            f = line.rstrip("\n").split("\t")
            times[f[0]] = f[1]
    by_tool = {}
    for r in rows:
        by_tool[r[1].split()[0]] = by_tool.get(r[1].split()[0], 0) + 1
    out = [HEAD.format(count=len(rows), by_tool=", ".join(
        "%d by %s" % (n, t) for t, n in sorted(by_tool.items(), key=lambda x: -x[1])))]
    total_lines = []
    for name, tool, operation, units, path_mode in rows:
        text = open(os.path.join(corpus, name + ".ngc")).read()
        lines = text.count("\n")
        total_lines.append(lines)
        out.append("| %s | %s: %s | %s | %s | %d | %s | %s |\n" % (
            name, tool.split(" + ")[0], operation, units, path_mode, lines,
            times.get(name, "-"), exercises(text)))
    known = [float(t) for t in times.values() if t not in ("NA", "-")]
    out.append("\n%d lines in all (median %d); LinuxCNC's cycle times add up to %.0f s.\n" % (
        sum(total_lines), statistics.median(total_lines), sum(known)))
    with open(os.path.join(corpus, "README.md"), "w") as f:
        f.writelines(out)


if __name__ == "__main__":
    main()
