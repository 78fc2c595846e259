#!/usr/bin/env python3
"""Replaces cutter compensation codes of a corpus program by marker comments.

G41/G42 (radius from the tool table, D word = tool number, else the tool of the last M6),
G41.1/G42.1 (D = diameter, L = lathe orientation) and G40 become
(RTCNC,COMP,LEFT|RIGHT,radius,orientation) and (RTCNC,COMP,OFF). The radius is in program
units; rs274 reads the tool table in inches. Handles the corpus's simple programs only:
one compensation code per line, no expressions in its words.
"""
import re
import sys

table = {}
orientations = {}
for line in open(sys.argv[1]):
    t = re.search(r"\bT(\d+)", line)
    d = re.search(r"\bD([-+0-9.]+)", line)
    q = re.search(r"\bQ(\d+)", line)
    if t and d:
        table[int(t.group(1))] = float(d.group(1))
        orientations[int(t.group(1))] = int(q.group(1)) if q else 0

inch = False
tool = 0
comp = re.compile(r"G\s*4\s*([012])(\s*\.\s*1)?(?![0-9])", re.I)
for line in sys.stdin:
    code = line.split("(")[0].split(";")[0]
    if re.search(r"G\s*20(?![0-9])", code, re.I):
        inch = True
    if re.search(r"G\s*21(?![0-9])", code, re.I):
        inch = False
    m6 = re.search(r"M\s*6(?![0-9])", code, re.I)
    t = re.search(r"T\s*(\d+)", code, re.I)
    if m6 and t:
        tool = int(t.group(1))
    m = comp.search(code)
    if not m:
        sys.stdout.write(line)
        continue
    kind, dot = m.group(1), bool(m.group(2))
    rest = code[: m.start()] + code[m.end():]
    d = re.search(r"D\s*([-+0-9.]+)", rest, re.I)
    l = re.search(r"L\s*([-+0-9]+)", rest, re.I)
    rest = re.sub(r"[DL]\s*[-+0-9.]+", "", rest, flags=re.I)
    if kind == "0":
        marker = "(RTCNC,COMP,OFF)"
    else:
        side = "LEFT" if kind == "1" else "RIGHT"
        orientation = 0
        if dot:
            radius = float(d.group(1)) / 2
            if l:
                orientation = int(l.group(1))
        else:
            number = int(float(d.group(1))) if d else tool
            radius = table.get(number, 0.0) / 2 * (1.0 if inch else 25.4)
            orientation = orientations.get(number, 0)
        if radius < 0:
            radius = -radius
            side = "RIGHT" if side == "LEFT" else "LEFT"
        marker = "(RTCNC,COMP,%s,%.10g,%d)" % (side, radius, orientation)
    n = re.match(r"\s*(N\s*\d+)", rest, re.I)
    if n:
        rest = rest[: n.end()] + " " + marker + rest[n.end():]
    else:
        rest = marker + " " + rest
    sys.stdout.write(rest.rstrip() + "\n")
