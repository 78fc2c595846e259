"""Makes the bCNC programs of the CAM corpus with bCNC's own CAM code, headless: the
GCode class of bCNC (Debian's bcnc package, /usr/share/bcnc/bCNC) imports a DXF and applies
the operations its CAM ribbon applies (profile, pocket, cut with flat, ramped or helical
passes, drill), and its Flatten plug-in surfaces a rectangle. The program is what bCNC's
"Save as .txt" writes for another controller (enabled blocks, upper case, no bCNC comments),
between a header and a footer as bCNC's configuration gives them.

    python3 scripts/cam-corpus/bcnc_parts.py DXFDIR OUTDIR
"""

import builtins
import os
import sys

BCNC = os.environ.get("BCNC_DIR", "/usr/share/bcnc/bCNC")
sys.path[:0] = [BCNC, os.path.join(BCNC, "lib"), os.path.join(BCNC, "plugins")]
builtins._ = lambda s: s  # bCNC's translation hook, normally installed by its GUI

import CNC  # noqa: E402
from CNC import CNC as Machine, GCode, Block  # noqa: E402

PARTS = []


def part(operation, units, path_mode):
    def wrap(fn):
        PARTS.append((fn.__name__.replace("_", "-"), fn, operation, units, path_mode))
        return fn
    return wrap


class StatusOnly:
    """What a bCNC plug-in's make() needs of the application: a status line."""

    def setStatus(self, text):
        print("  bCNC: %s" % text)


def new_program(inch, diameter, stepz, surface, thickness, feed, feedz, stepover=40.0):
    Machine.inch = inch
    Machine.digits = 4
    Machine.vars.update({
        "diameter": diameter, "stepz": stepz, "surface": surface, "thickness": thickness,
        "safe": 0.2 if inch else 5.0, "cutfeed": feed, "cutfeedz": feedz,
        "stepover": stepover,
    })
    return GCode()


def header(g, path_mode, inch, tool, rpm, end):
    units = "G20" if inch else "G21"
    g.header = "\n".join([
        "%s G90 G17 G40 G49 G80 %s" % (units, path_mode),
        "T%d M6" % tool, "G43 H%d" % tool, "M3 S%d" % rpm, "G4 P2",
        "G0 Z%s" % ("0.4" if inch else "10"),
    ])
    g.footer = "\n".join(["G0 Z%s" % ("0.4" if inch else "10"), "M5", end])


def save(g, path, name, how):
    # Importing a drawing into an empty file adds bCNC's header and footer blocks; a plug-in
    # run on an empty file needs them added.
    if not any(b.name() == "Header" for b in g.blocks):
        g.blocks.insert(0, Block("Header"))
        g.blocks[0].extend(g.header.splitlines())
        footer = Block("Footer")
        footer.extend(g.footer.splitlines())
        g.blocks.append(footer)
    g.saveTXT(path)
    text = open(path).read()
    # bCNC's offsets can fail silently (see bcnc_pocket): refuse a program that leaves the
    # drawing's neighbourhood.
    import re
    limit = 400 / (25.4 if Machine.inch else 1)
    for word in re.findall(r"[XY](-?[0-9.]+)", text):
        if abs(float(word)) > limit:
            raise RuntimeError("%s: bCNC wrote a coordinate of %s" % (name, word))
    with open(path, "w") as f:
        f.write("(%s: bCNC 0.9.14 of Debian, %s)\n" % (name, how))
        f.write(text)


def shapes(g):
    return [i for i, b in enumerate(g.blocks) if b.name() not in ("Header", "Footer")]


@part("profile outside (offset 3 mm) with helical descent, 1.5 mm per turn", "mm", "G64 P0.01")
def bcnc_profile_helix(dxf, out, name):
    g = new_program(False, 6.0, 1.5, 0.0, 10.0, 1500, 300)
    header(g, "G64 P0.01", False, 1, 12000, "M2")
    g.importDXF(os.path.join(dxf, "bcnc-plate.dxf"))
    outline = [shapes(g)[0]]
    g.profile(outline, 3.0)
    g.cut(outline, depth=-6.0, stepz=1.5, helix=True, helixBottom=True)
    save(g, out, name, "import bcnc-plate.dxf, profile +3, cut helical to -6")


@part("profile inside (offset -1/16 in), flat passes, inch", "inch", "G64")
def bcnc_profile_inch(dxf, out, name):
    g = new_program(True, 0.125, 0.06, 0.0, 0.4, 40, 10)
    header(g, "G64", True, 12, 16000, "M30")
    g.importDXF(os.path.join(dxf, "bcnc-plate-inch.dxf"))
    inner = shapes(g)[1:]
    g.profile(inner, -0.0625)
    g.cut(inner, depth=-0.18, stepz=0.06)
    save(g, out, name, "import bcnc-plate-inch.dxf, profile -1/16 in, cut to -0.18 in")


@part("pocket (6 mm, 45 % step-over), flat passes", "mm", "G64 P0.02")
def bcnc_pocket(dxf, out, name):
    g = new_program(False, 6.0, 1.5, 0.0, 10.0, 1800, 300)
    header(g, "G64 P0.02", False, 1, 14000, "M2")
    g.importDXF(os.path.join(dxf, "bcnc-plate.dxf"))
    inner = shapes(g)[1:]
    # 45 %: at 40 % and 50 % bCNC's pocket of the 45 x 30 window degenerates (its last
    # offset collapses and it writes arcs of kilometres); save() refuses such output.
    g.pocket(inner, 6.0, 0.45, None)
    g.cut(inner, depth=-3.0, stepz=1.5)
    save(g, out, name, "import bcnc-plate.dxf, pocket D6 45 %, cut to -3")


@part("pocket (3 mm, 60 %), ramped entry (2 x D per step)", "mm", "G64")
def bcnc_pocket_ramp(dxf, out, name):
    g = new_program(False, 3.0, 1.0, 0.0, 10.0, 2000, 300)
    header(g, "G64", False, 2, 18000, "M2")
    g.importDXF(os.path.join(dxf, "bcnc-plate.dxf"))
    window = [shapes(g)[1]]
    g.pocket(window, 3.0, 0.6, None)
    g.cut(window, depth=-2.0, stepz=1.0, helix=True, ramp=2)
    save(g, out, name, "import bcnc-plate.dxf, pocket D3 60 % of the round window, "
                       "cut ramped 2 x D to -2")


@part("drilling with pecks and dwell at circle centres", "mm", "G64 P0.05")
def bcnc_drill_peck(dxf, out, name):
    g = new_program(False, 5.0, 1.0, 0.0, 12.0, 400, 400)
    header(g, "G64 P0.05", False, 8, 3000, "M2")
    g.importDXF(os.path.join(dxf, "bcnc-holes.dxf"))
    g.drill(shapes(g), depth=-6.0, peck=2.0, dwell=0.2, center=True)
    save(g, out, name, "import bcnc-holes.dxf, drill centres to -6, peck 2, dwell 0.2")


@part("engraving of splines (converted to lines by bCNC), 0.5 mm", "mm", "G64 P0.005")
def bcnc_spline_engrave(dxf, out, name):
    g = new_program(False, 2.0, 0.5, 0.0, 5.0, 1500, 300)
    header(g, "G64 P0.005", False, 15, 20000, "M2")
    g.importDXF(os.path.join(dxf, "bcnc-waves.dxf"))
    g.cut(shapes(g), depth=-0.5, stepz=0.5)
    save(g, out, name, "import bcnc-waves.dxf, cut to -0.5")


def flatten(name, out, inch, diameter, width, height, depth, stepz, stepover, pattern,
            feed, feedz, tool, rpm, path_mode, end):
    import flatten as flatten_plugin
    g = new_program(inch, diameter, stepz, 0.0, 5.0, feed, feedz, stepover)
    header(g, path_mode, inch, tool, rpm, end)
    blocks = flatten_plugin.Flatten("Flatten").make(
        StatusOnly(), XStart=20 / (25.4 if inch else 1), YStart=20 / (25.4 if inch else 1),
        FlatWidth=width, FlatHeight=height, FlatDepth=depth, BorderPass=True,
        CutDirection="Climb", PocketType=pattern)
    g.blocks.extend(blocks)
    save(g, out, name, "Flatten plug-in %s, %g x %g, depth %g, step-over %g %%"
         % (pattern, width, height, depth, stepover))


@part("surfacing (Flatten plug-in), raster, 10 mm, border pass", "mm", "G64 P0.05")
def bcnc_flatten_raster(dxf, out, name):
    flatten(name, out, False, 10.0, 140, 100, -1.0, 0.5, 70, "Raster", 2500, 500, 3, 9000,
            "G64 P0.05", "M2")


@part("surfacing (Flatten plug-in), offset pattern, 1/4 in, inch", "inch", "G64")
def bcnc_flatten_offset_inch(dxf, out, name):
    flatten(name, out, True, 0.25, 4.0, 3.0, -0.04, 0.02, 60, "Offset", 100, 15, 11, 15000,
            "G64", "M30")


def main():
    dxf, out_dir = sys.argv[1:3]
    only = [n for n in os.environ.get("CAM_ONLY", "").split(",") if n]
    os.makedirs(out_dir, exist_ok=True)
    rows = []
    for name, fn, operation, units, path_mode in PARTS:
        if only and name not in only:
            continue
        fn(dxf, os.path.join(out_dir, name + ".ngc"), name)
        rows.append("%s\t%s\t%s\t%s\n" % (name, operation, units, path_mode))
        print("made %s" % name)
    with open(os.path.join(out_dir, "bcnc.tsv"), "a" if only else "w") as f:
        f.writelines(rows)


if __name__ == "__main__":
    main()
