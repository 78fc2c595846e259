"""Writes the DXF drawings of the CAM corpus's dxf2gcode and bCNC parts (ezdxf).

    python3 scripts/cam-corpus/dxf_parts.py OUTDIR

Drawings are in millimetres ($INSUNITS 4) unless their name ends in "-inch" (inches,
$INSUNITS 1). Layer names carry dxf2gcode's layer parameters with "#" as the separator
(DXF layer names cannot hold ":" or "="): "MILL#1 Md#-3 Sd#-1 Tn#1 FeedXY#1200 FeedZ#300";
bCNC ignores them.
"""

import math
import os
import sys

import ezdxf


def new(units_inch=False):
    doc = ezdxf.new("R2010")
    doc.header["$INSUNITS"] = 1 if units_inch else 4
    doc.header["$MEASUREMENT"] = 0 if units_inch else 1
    return doc, doc.modelspace()


def layer(doc, name):
    if name not in doc.layers:
        doc.layers.add(name)
    return {"layer": name}


def rounded_rect(msp, x0, y0, w, h, r, attrs):
    """A closed polyline with arc corners (bulges)."""
    b = math.tan(math.radians(90) / 4)  # bulge of a 90 degree arc
    pts = [
        (x0 + r, y0, 0), (x0 + w - r, y0, b),
        (x0 + w, y0 + r, 0), (x0 + w, y0 + h - r, b),
        (x0 + w - r, y0 + h, 0), (x0 + r, y0 + h, b),
        (x0, y0 + h - r, 0), (x0, y0 + r, b),
    ]
    msp.add_lwpolyline(pts, format="xyb", close=True, dxfattribs=attrs)


def gear(msp, cx, cy, teeth, r_root, r_tip, attrs):
    """A gear-like closed polyline: trapezoid teeth, straight flanks."""
    pts = []
    for i in range(teeth):
        a0 = 2 * math.pi * i / teeth
        step = 2 * math.pi / teeth
        for frac, r in ((0.0, r_root), (0.25, r_tip), (0.5, r_tip), (0.75, r_root)):
            a = a0 + frac * step
            pts.append((cx + r * math.cos(a), cy + r * math.sin(a)))
    msp.add_lwpolyline(pts, close=True, dxfattribs=attrs)


def star(msp, cx, cy, n, r_out, r_in, rot, attrs):
    pts = []
    for i in range(2 * n):
        r = r_out if i % 2 == 0 else r_in
        a = rot + math.pi * i / n
        pts.append((cx + r * math.cos(a), cy + r * math.sin(a)))
    msp.add_lwpolyline(pts, close=True, dxfattribs=attrs)


def wave_spline(msp, x0, y0, length, amp, waves, attrs, closed=False):
    fit = [(x0 + length * i / (8 * waves), y0 + amp * math.sin(2 * math.pi * i / 8))
           for i in range(8 * waves + 1)]
    msp.add_spline_control_frame(fit, degree=3, dxfattribs=attrs)


def plate_g41(path, inch=False):
    """A flange plate: rounded outline, four bolt holes, a central star-shaped window."""
    s = 25.4 if inch else 1.0
    doc, msp = new(inch)
    if inch:
        outer = layer(doc, "MILL#1 Md#-0.25 Sd#-0.125 Tn#11 FeedXY#50 FeedZ#12 Rh#0.5 Sm#0.1")
        inner = layer(doc, "MILL#2 Md#-0.25 Sd#-0.125 Tn#12 FeedXY#35 FeedZ#10 Rh#0.5 Sm#0.1")
        u = 1 / 25.4
    else:
        outer = layer(doc, "MILL#1 Md#-4 Sd#-2 Tn#1 FeedXY#1500 FeedZ#300 Rh#10 Sm#2")
        inner = layer(doc, "MILL#2 Md#-4 Sd#-2 Tn#2 FeedXY#1200 FeedZ#250 Rh#10 Sm#2")
        u = 1.0
    rounded_rect(msp, 20 * u, 20 * u, 140 * u, 100 * u, 14 * u, outer)
    for (x, y) in ((40, 40), (140, 40), (40, 100), (140, 100)):
        msp.add_circle((x * u, y * u), 6 * u, dxfattribs=inner)
    star(msp, 90 * u, 70 * u, 5, 30 * u, 14 * u, math.pi / 2, inner)
    doc.saveas(path)
    del s


def splines(path):
    """Engraving: wave splines, an ellipse and arcs (dxf2gcode fits splines with biarcs)."""
    doc, msp = new()
    a = layer(doc, "MILL#1 Md#-0.5 Sd#-0.5 Tn#6 FeedXY#1200 FeedZ#300 Rh#5 Sm#1")
    for k in range(5):
        wave_spline(msp, 20, 30 + 18 * k, 140, 5 + k, 3 + k % 2, a)
    msp.add_ellipse((90, 140), major_axis=(45, 0), ratio=0.45, dxfattribs=a)
    msp.add_ellipse((90, 140), major_axis=(0, 22), ratio=0.6, dxfattribs=a)
    for k in range(6):
        msp.add_arc((30 + 24 * k, 175), 10, 200, 340, dxfattribs=a)
    doc.saveas(path)


def gears(path, inch=False):
    doc, msp = new(inch)
    u = 1 / 25.4 if inch else 1.0
    if inch:
        a = layer(doc, "MILL#1 Md#-0.2 Sd#-0.1 Tn#12 FeedXY#40 FeedZ#10 Rh#0.4 Sm#0.1")
    else:
        a = layer(doc, "MILL#1 Md#-4 Sd#-2 Tn#2 FeedXY#1000 FeedZ#250 Rh#8 Sm#2")
    gear(msp, 60 * u, 60 * u, 18, 30 * u, 36 * u, a)
    gear(msp, 135 * u, 60 * u, 12, 20 * u, 26 * u, a)
    msp.add_circle((60 * u, 60 * u), 8 * u, dxfattribs=a)
    msp.add_circle((135 * u, 60 * u), 6 * u, dxfattribs=a)
    doc.saveas(path)


def drill_points(path):
    doc, msp = new()
    a = layer(doc, "DRILL#1 Md#-8 Sd#-2.5 Tn#8 FeedZ#400 Rh#10 Sm#2")
    b = layer(doc, "DRILL#2 Md#-5 Sd#-5 Tn#9 FeedZ#300 Rh#10 Sm#2")
    for j in range(3):
        for i in range(6):
            msp.add_point((30 + 18 * i, 30 + 18 * j), dxfattribs=a)
    for k in range(10):
        ang = 2 * math.pi * k / 10
        msp.add_point((100 + 40 * math.cos(ang), 140 + 40 * math.sin(ang)), dxfattribs=b)
    doc.saveas(path)


def tabs(path):
    """An outline with holding tabs (dxf2gcode's BREAKS layer: lines across the contour)."""
    doc, msp = new()
    a = layer(doc, "MILL#1 Md#-6 Sd#-3 Tn#1 FeedXY#1500 FeedZ#300 Rh#10 Sm#2")
    br = layer(doc, "BREAKS#1 Md#-4 FeedXY#1000 FeedZ#300")
    rounded_rect(msp, 30, 30, 130, 90, 20, a)
    msp.add_circle((95, 75), 25, dxfattribs=a)
    for (x0, y0, x1, y1) in ((95, 20, 95, 40), (95, 110, 95, 130), (20, 75, 40, 75),
                             (150, 75, 170, 75)):
        msp.add_line((x0, y0), (x1, y1), dxfattribs=br)
    doc.saveas(path)


def spiral_art(path):
    """Decorative engraving: an Archimedean spiral of arcs and a rosette of circles."""
    doc, msp = new()
    a = layer(doc, "MILL#1 Md#-0.4 Sd#-0.4 Tn#15 FeedXY#1500 FeedZ#400 Rh#4 Sm#1")
    # Spiral from arcs of growing radius about alternating centres (a classic "spiral of
    # semicircles").
    cx, cy, r = 90.0, 90.0, 3.0
    for k in range(14):
        if k % 2 == 0:
            msp.add_arc((cx, cy), r, 0, 180, dxfattribs=a)
            cx -= 2.0
        else:
            msp.add_arc((cx + 2.0, cy), r + 2.0, 180, 360, dxfattribs=a)
            cx += 2.0
        r += 2.0
    for k in range(8):
        ang = 2 * math.pi * k / 8
        msp.add_circle((90 + 55 * math.cos(ang), 90 + 55 * math.sin(ang)), 12,
                       dxfattribs=a)
    doc.saveas(path)


def bcnc_plate(path, inch=False):
    """bCNC's parts: an outline, round windows, a slot (bCNC reads lines, arcs, circles,
    polylines)."""
    doc, msp = new(inch)
    u = 1 / 25.4 if inch else 1.0
    a = layer(doc, "0")
    rounded_rect(msp, 20 * u, 20 * u, 120 * u, 80 * u, 10 * u, a)
    msp.add_circle((50 * u, 60 * u), 15 * u, dxfattribs=a)
    # A plain rectangle: bCNC's pocket offsets arcs inwards until their radius changes sign
    # and then writes nonsense, so the window has sharp corners.
    msp.add_lwpolyline([(80 * u, 45 * u), (125 * u, 45 * u), (125 * u, 75 * u),
                        (80 * u, 75 * u)], close=True, dxfattribs=a)
    doc.saveas(path)


def bcnc_holes(path):
    doc, msp = new()
    a = layer(doc, "0")
    for j in range(3):
        for i in range(6):
            msp.add_circle((30 + 20 * i, 30 + 25 * j), 2.5, dxfattribs=a)
    doc.saveas(path)


def bcnc_waves(path):
    doc, msp = new()
    a = layer(doc, "0")
    for k in range(4):
        wave_spline(msp, 20, 30 + 20 * k, 120, 6, 2 + k, a)
    doc.saveas(path)


DRAWINGS = {
    "d2g-plate-g41": lambda p: plate_g41(p),
    "d2g-plate-offset": lambda p: plate_g41(p),
    "d2g-plate-g41-inch": lambda p: plate_g41(p, inch=True),
    "d2g-splines": splines,
    "d2g-gears": lambda p: gears(p),
    "d2g-gears-inch": lambda p: gears(p, inch=True),
    "d2g-drill": drill_points,
    "d2g-tabs": tabs,
    "d2g-spiral-art": spiral_art,
    "bcnc-plate": lambda p: bcnc_plate(p),
    "bcnc-plate-inch": lambda p: bcnc_plate(p, inch=True),
    "bcnc-holes": bcnc_holes,
    "bcnc-waves": bcnc_waves,
}


def main():
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)
    for name, fn in DRAWINGS.items():
        fn(os.path.join(out, name + ".dxf"))


if __name__ == "__main__":
    main()
