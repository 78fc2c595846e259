#!/usr/bin/python3
"""Writes the reference of crates/kernel/tests/program.rs for examples/gcode/splines.ngc:
the points LinuxCNC 2.9's interpreter (its Python `gcode` module, the one the AXIS preview
uses) gives for every feed move, in mm: "LINE X Y Z" per point. LinuxCNC turns G5/G5.1 into
a NURBS curve of order 4/3 and samples it at equal parameter steps (t = i/n, i = 1..n), so
the points of a spline determine its control points.

usage (needs linuxcnc-uspace; the peer harness of ../shared/peers/linuxcnc):
  INI_FILE_NAME=canon.ini /usr/bin/python3 linuxcnc_splines.py PROGRAM.ngc PARAMS.var > splines.linuxcnc
"""
import sys

import gcode


class Canon:
    def __init__(self, parameter_file):
        self.parameter_file = parameter_file
        self.line = 0
        self.points = []

    def next_line(self, state):
        self.line = state.sequence_number

    def straight_feed(self, *a):
        # The module works in inches.
        self.points.append((self.line, a[0] * 25.4, a[1] * 25.4, a[2] * 25.4))

    def get_external_length_units(self):
        return 1 / 25.4

    def get_external_angular_units(self):
        return 1.0

    def get_axis_mask(self):
        return 7

    def get_tool(self, t):
        return (t,) + (0,) * 13

    def get_block_delete(self):
        return False

    def check_abort(self):
        return False

    def __getattr__(self, name):
        if name.startswith("__"):
            raise AttributeError(name)
        return lambda *a, **k: None


canon = Canon(sys.argv[2])
gcode.parse(sys.argv[1], canon, "", "")
for line, x, y, z in canon.points:
    print(line, repr(x), repr(y), repr(z))
