# Builds the FreeCAD parts of the CAM corpus and writes one LinuxCNC program per part with
# FreeCAD's Path workbench and its linuxcnc post-processor, headless:
#
#   CAM_OUT=examples/cam-corpus freecadcmd scripts/cam-corpus/freecad_parts.py
#
# Every part is a Part (or Sketcher) solid with its top at Z0, inside X 0..250, Y 0..180 (the
# corpus runs on configs/bench-xyz.toml). Tool numbers are those of
# examples/cam-corpus/tools.tbl. CAM_ONLY=name1,name2 builds only those parts. For each
# program a line "name<TAB>operation<TAB>units<TAB>path mode" goes to CAM_OUT/freecad.tsv.

import math
import os
import sys
import traceback

import FreeCAD
import Part
import Sketcher
from FreeCAD import Vector

from PathScripts import (
    PathAdaptive,
    PathDeburr,
    PathDressupDogbone,
    PathDressupHoldingTags,
    PathDressupLeadInOut,
    PathDressupRampEntry,
    PathDrilling,
    PathEngrave,
    PathHelix,
    PathJob,
    PathMillFace,
    PathPocketShape,
    PathProfile,
    PathSurface,
    PathToolBit,
    PathToolController,
    PathVcarve,
    PathWaterline,
)
from PathScripts.post import linuxcnc_post

OUT = os.environ.get("CAM_OUT", "examples/cam-corpus")
ONLY = [n for n in os.environ.get("CAM_ONLY", "").split(",") if n]
FONT = "/usr/share/fonts/truetype/dejavu/DejaVuSans-Bold.ttf"

# Tool number -> (bit shape, properties), as examples/cam-corpus/tools.tbl describes them.
TOOLS = {
    1: ("endmill.fcstd", {"Diameter": 6.0, "CuttingEdgeHeight": 20.0, "Length": 40.0}),
    2: ("endmill.fcstd", {"Diameter": 3.0, "CuttingEdgeHeight": 12.0, "Length": 35.0}),
    3: ("endmill.fcstd", {"Diameter": 10.0, "CuttingEdgeHeight": 25.0, "Length": 50.0}),
    4: ("ballend.fcstd", {"Diameter": 6.0, "CuttingEdgeHeight": 20.0, "Length": 42.0}),
    5: ("ballend.fcstd", {"Diameter": 3.0, "CuttingEdgeHeight": 12.0, "Length": 38.0}),
    6: ("v-bit.fcstd", {"Diameter": 10.0, "CuttingEdgeAngle": 60.0, "TipDiameter": 0.2,
                        "CuttingEdgeHeight": 9.0, "Length": 45.0}),
    7: ("v-bit.fcstd", {"Diameter": 12.0, "CuttingEdgeAngle": 90.0, "TipDiameter": 0.2,
                        "CuttingEdgeHeight": 6.0, "Length": 47.0}),
    8: ("drill.fcstd", {"Diameter": 5.0, "TipAngle": 118.0, "Length": 60.0}),
    9: ("drill.fcstd", {"Diameter": 3.0, "TipAngle": 118.0, "Length": 55.0}),
    10: ("chamfer.fcstd", {"Diameter": 12.0, "CuttingEdgeAngle": 45.0, "TipDiameter": 4.0,
                           "CuttingEdgeHeight": 6.0, "Length": 48.0}),
    11: ("endmill.fcstd", {"Diameter": 6.35, "CuttingEdgeHeight": 19.0, "Length": 41.0}),
    12: ("endmill.fcstd", {"Diameter": 3.175, "CuttingEdgeHeight": 12.0, "Length": 36.0}),
    13: ("ballend.fcstd", {"Diameter": 6.35, "CuttingEdgeHeight": 19.0, "Length": 43.0}),
    14: ("endmill.fcstd", {"Diameter": 8.0, "CuttingEdgeHeight": 22.0, "Length": 46.0}),
    15: ("endmill.fcstd", {"Diameter": 2.0, "CuttingEdgeHeight": 8.0, "Length": 30.0}),
}

PREAMBLE = "G17 G54 G40 G49 G80 G90"


# ---------------------------------------------------------------- geometry helpers
def rounded_rect(x0, y0, w, h, r, z0, z1):
    """A prism with rounded vertical edges, from z0 up to z1."""
    box = Part.makeBox(w, h, z1 - z0, Vector(x0, y0, z0))
    if r > 0:
        edges = [e for e in box.Edges
                 if abs(e.Vertexes[0].Point.x - e.Vertexes[1].Point.x) < 1e-9
                 and abs(e.Vertexes[0].Point.y - e.Vertexes[1].Point.y) < 1e-9]
        box = box.makeFillet(r, edges)
    return box


def cylinder(x, y, r, z0, z1):
    return Part.makeCylinder(r, z1 - z0, Vector(x, y, z0))


def faces_at(model, z, up=True):
    """Names of the model's horizontal faces at height z facing up (or down)."""
    names = []
    for i, f in enumerate(model.Shape.Faces):
        if f.Surface.__class__.__name__ != "Plane":
            continue
        n = f.normalAt(0, 0)
        if abs(abs(n.z) - 1) > 1e-9 or (n.z > 0) != up:
            continue
        if abs(f.BoundBox.ZMin - z) < 1e-6 and abs(f.BoundBox.ZMax - z) < 1e-6:
            names.append("Face%d" % (i + 1))
    return names


def cyl_faces(model, radius=None):
    """Names of the model's cylindrical faces (holes), optionally of one radius."""
    names = []
    for i, f in enumerate(model.Shape.Faces):
        if f.Surface.__class__.__name__ == "Cylinder":
            if radius is None or abs(f.Surface.Radius - radius) < 1e-6:
                names.append("Face%d" % (i + 1))
    return names


def nonplanar_faces(model):
    return ["Face%d" % (i + 1) for i, f in enumerate(model.Shape.Faces)
            if f.Surface.__class__.__name__ != "Plane"]


# ---------------------------------------------------------------- job helpers
class Job:
    def __init__(self, name, shape, stock_extra=(1.0, 1.0, 0.0)):
        self.name = name
        self.doc = FreeCAD.newDocument(name.replace("-", "_"))
        self.part = self.doc.addObject("Part::Feature", "Part")
        self.part.Shape = shape
        self.doc.recompute()
        self.job = PathJob.Create("Job", [self.part], None)
        # Remove the default tool controller: tools come from TOOLS.
        for tc in list(self.job.Tools.Group):
            self.job.Tools.removeObject(tc)
            self.doc.removeObject(tc.Name)
        stock = self.job.Stock
        for side, v in (("X", stock_extra[0]), ("Y", stock_extra[1])):
            setattr(stock, "ExtXneg" if side == "X" else "ExtYneg", v)
            setattr(stock, "ExtXpos" if side == "X" else "ExtYpos", v)
        stock.ExtZpos = stock_extra[2]
        self.doc.recompute()
        self.model = self.job.Model.Group[0]
        self.tcs = {}
        self.ops = []  # (tool controller, op object) in machining order

    def tool(self, number, feed, plunge, rpm):
        shape, props = TOOLS[number]
        bit = PathToolBit.Factory.Create("T%d" % number, shape)
        for k, v in props.items():
            setattr(bit, k, v)
        tc = PathToolController.Create("TC%d" % number, bit, number)
        tc.HorizFeed = "%g mm/min" % feed
        tc.VertFeed = "%g mm/min" % plunge
        tc.SpindleSpeed = float(rpm)
        self.job.Tools.addObject(tc)
        self.doc.recompute()
        self.tcs[number] = tc
        return tc

    def create(self, module, name):
        """Creates an op while the job holds one tool controller: with several, FreeCAD
        would ask the user which one to take (and fails headless)."""
        group = list(self.job.Tools.Group)
        self.job.Tools.Group = group[:1]
        op = module.Create(name)
        self.job.Tools.Group = group
        return op

    def add(self, op, tc, **props):
        op.ToolController = tc
        for k, v in props.items():
            if k in ("StartDepth", "FinalDepth", "StepDown", "SafeHeight", "ClearanceHeight"):
                op.setExpression(k, None)
            setattr(op, k, v)
        self.doc.recompute()
        self.ops.append((tc, op))
        return op

    def replace_last(self, dressup):
        """A dressup takes the place of the op it wraps in the output."""
        tc, _ = self.ops[-1]
        self.doc.recompute()
        self.ops[-1] = (tc, dressup)

    def post(self, units="mm", g64="G64", coolant=None):
        """Writes OUT/<name>.ngc through linuxcnc_post in the order FreeCAD's own post
        command uses for one fixture: fixture, then each tool controller before its ops."""
        class Fixture:
            pass
        fixture = Fixture()
        fixture.Label = "G54"
        import Path
        fixture.Path = Path.Path([
            Path.Command("G54"),
            Path.Command("G0", {"Z": self.job.Stock.Shape.BoundBox.ZMax
                                + self.job.SetupSheet.ClearanceHeightOffset.Value}),
        ])
        objects = [fixture]
        current = None
        for tc, op in self.ops:
            if coolant:
                op.CoolantMode = coolant
            if tc is not current:
                objects.append(tc)
                current = tc
            objects.append(op)
        self.doc.recompute()
        args = "--no-header --no-show-editor --preamble '%s\n%s'" % (PREAMBLE, g64)
        if units == "inch":
            args += " --inches"
        path = os.path.join(OUT, self.name + ".ngc")
        # The post keeps its settings in module globals; start from its defaults each time.
        import importlib
        importlib.reload(linuxcnc_post)
        text = linuxcnc_post.export(objects, "-", args)
        if not text:
            raise RuntimeError("post-processor produced nothing")
        with open(path, "w") as f:
            f.write("(%s: FreeCAD %s Path workbench, linuxcnc_post %s)\n"
                    % (self.name, ".".join(FreeCAD.Version()[:3]), args.replace("\n", " ")))
            f.write(text)
        for op_tc, op in self.ops:
            if not op.Path.Commands:
                raise RuntimeError("operation %s produced no path" % op.Label)
        return path

    def close(self):
        FreeCAD.closeDocument(self.doc.Name)


# ---------------------------------------------------------------- the parts
PARTS = []


def part(operation, units="mm", g64="G64"):
    def wrap(fn):
        PARTS.append((fn.__name__.replace("_", "-"), fn, operation, units, g64))
        return fn
    return wrap


def plate_with_pocket(x0, y0, w, h, pw, ph, pr, depth, thick=12.0):
    plate = Part.makeBox(w, h, thick, Vector(x0, y0, -thick))
    pocket = rounded_rect(x0 + (w - pw) / 2, y0 + (h - ph) / 2, pw, ph, pr, -depth, 1.0)
    return plate.cut(pocket)


def pocket_job(name, shape, depth, tool, feed, plunge, rpm, g64, units, **props):
    j = Job(name, shape)
    tc = j.tool(tool, feed, plunge, rpm)
    op = PathPocketShape.Create("Pocket")
    op.Base = [(j.model, faces_at(j.model, -depth))]
    j.add(op, tc, **props)
    j.post(units, g64)
    j.close()


@part("pocket, zigzag, 6 mm, 50 % step-over, 1.5 mm step-down", g64="G64")
def pocket_zigzag_6mm():
    pocket_job("pocket-zigzag-6mm", plate_with_pocket(20, 20, 120, 90, 80, 50, 0, 3.0),
               3.0, 1, 1500, 300, 12000, "G64", "mm", OffsetPattern="ZigZag", StepOver=50,
               StepDown=1.5, ZigZagAngle=0)


@part("pocket, offset, 6 mm, 40 %, rounded corners R8", g64="G64 P0.01")
def pocket_offset_6mm():
    pocket_job("pocket-offset-6mm", plate_with_pocket(20, 20, 120, 90, 80, 50, 8, 4.0),
               4.0, 1, 2000, 300, 14000, "G64 P0.01", "mm", OffsetPattern="Offset",
               StepOver=40, StepDown=2.0)


@part("pocket, zigzag-offset, 10 mm, 60 %, 45 degree zigzag", g64="G64 P0.02")
def pocket_zigzagoffset_10mm():
    pocket_job("pocket-zigzagoffset-10mm",
               plate_with_pocket(10, 10, 180, 140, 140, 100, 12, 4.0, 15.0), 4.0, 3, 2000,
               400, 10000, "G64 P0.02", "mm", OffsetPattern="ZigZagOffset", StepOver=60,
               StepDown=4.0, ZigZagAngle=45)


@part("pocket, offset, 3 mm, circular pocket D36", g64="G64 P0.005")
def pocket_circle_3mm():
    plate = Part.makeBox(80, 80, 10, Vector(20, 20, -10))
    shape = plate.cut(cylinder(60, 60, 18, -3.0, 1.0))
    pocket_job("pocket-circle-3mm", shape, 3.0, 2, 1500, 200, 18000, "G64 P0.005", "mm",
               OffsetPattern="Offset", StepOver=45, StepDown=1.5)


@part("pocket with island (boss), offset, 1/4 in, inch", units="inch", g64="G64 P0.0005")
def pocket_island_inch():
    plate = Part.makeBox(127, 101.6, 19.05, Vector(25.4, 25.4, -19.05))
    pocket = rounded_rect(50.8, 44.45, 76.2, 50.8, 6.35, -3.175, 1.0)
    boss = cylinder(88.9, 69.85, 12.7, -3.175, 0.0)
    shape = plate.cut(pocket).fuse(boss).removeSplitter()
    pocket_job("pocket-island-inch", shape, 3.175, 11, 1524, 381, 12000, "G64 P0.0005", "inch",
               OffsetPattern="Offset", StepOver=40, StepDown=3.175)


@part("pocket, line pattern (one-way), 8 mm", g64="G64")
def pocket_line_8mm():
    pocket_job("pocket-line-8mm", plate_with_pocket(30, 30, 150, 110, 110, 70, 5, 3.0), 3.0,
               14, 1800, 400, 11000, "G64", "mm", OffsetPattern="Line", StepOver=55,
               StepDown=3.0, ZigZagAngle=90)


@part("pocket + dogbone dressup, 6 mm, square corners", g64="G64 P0.01")
def pocket_dogbone():
    j = Job("pocket-dogbone", plate_with_pocket(20, 20, 110, 80, 70, 45, 0, 5.0))
    tc = j.tool(1, 1800, 300, 12000)
    op = PathPocketShape.Create("Pocket")
    op.Base = [(j.model, faces_at(j.model, -5.0))]
    j.add(op, tc, OffsetPattern="Offset", StepOver=45, StepDown=2.5)
    prof = PathProfile.Create("Profile")
    prof.Base = [(j.model, faces_at(j.model, -5.0))]
    j.add(prof, tc, Side="Inside", StepDown=2.5, processPerimeter=True)
    dog = PathDressupDogbone.Create(prof)
    j.replace_last(dog)
    j.post("mm", "G64 P0.01")
    j.close()


def plate(x0, y0, w, h, r, thick, holes=()):
    shape = rounded_rect(x0, y0, w, h, r, -thick, 0.0)
    for (x, y, d) in holes:
        shape = shape.cut(cylinder(x, y, d / 2, -thick - 1, 1.0))
    return shape


def profile_job(name, shape, tool, feed, plunge, rpm, g64, units, props, dressups=(),
                faces=None, coolant=None):
    j = Job(name, shape, stock_extra=(8.0, 8.0, 0.0))
    tc = j.tool(tool, feed, plunge, rpm)
    op = PathProfile.Create("Profile")
    if faces is not None:
        op.Base = [(j.model, faces(j.model))]
    j.add(op, tc, **props)
    for d in dressups:
        j.replace_last(d(op))
    j.post(units, g64, coolant)
    j.close()


def attach_dressup(module, op, name):
    """A dressup object set up as FreeCAD's own dressup commands do it."""
    from PathScripts import PathUtils
    obj = FreeCAD.ActiveDocument.addObject("Path::FeaturePython", name)
    dressup = module.ObjectDressup(obj)
    obj.Base = op
    PathUtils.findParentJob(op).Proxy.addOperation(obj, op)
    dressup.setup(obj)
    return obj


def ramp(op):
    obj = attach_dressup(PathDressupRampEntry, op, "RampEntryDressup")
    obj.Angle = 15
    FreeCAD.ActiveDocument.recompute()
    return obj


def tags(op):
    obj = PathDressupHoldingTags.Create(op)
    FreeCAD.ActiveDocument.recompute()
    return obj


def lead_in_out(op):
    obj = attach_dressup(PathDressupLeadInOut, op, "LeadInOutDressup")
    FreeCAD.ActiveDocument.recompute()
    return obj


def machine_crc(op):
    """Lead-in/out with the machine's cutter compensation: G41/G42 D<tool>, G40."""
    obj = attach_dressup(PathDressupLeadInOut, op, "LeadInOutCRCDressup")
    obj.UseMachineCRC = True
    obj.StyleOn = "Tangent"
    obj.StyleOff = "Tangent"
    obj.Length = 2 * op.ToolController.Tool.Diameter
    FreeCAD.ActiveDocument.recompute()
    return obj


@part("profile outside, 6 mm, 3 step-downs, CW, R10 corners", g64="G64 P0.05")
def profile_outside_6mm():
    profile_job("profile-outside-6mm", plate(30, 30, 120, 80, 10, 6.0), 1, 1200, 300, 12000,
                "G64 P0.05", "mm", dict(Side="Outside", Direction="CW", StepDown=2.0,
                                        processHoles=False, processPerimeter=True))


@part("profile outside + inside holes, 3 mm, CCW", g64="G64")
def profile_holes_3mm():
    holes = [(50, 50, 12), (130, 50, 12), (50, 100, 16), (130, 100, 16), (90, 75, 25)]
    profile_job("profile-holes-3mm", plate(30, 30, 120, 90, 6, 4.0, holes), 2, 1200, 200,
                18000, "G64", "mm", dict(Side="Outside", Direction="CCW", StepDown=2.0,
                                         processHoles=True, processCircles=True,
                                         processPerimeter=True))


@part("profile + ramp entry dressup + holding tags, 6 mm", g64="G64 P0.01")
def profile_ramp_tags():
    profile_job("profile-ramp-tags", plate(40, 40, 140, 90, 15, 9.0), 1, 1500, 300, 14000,
                "G64 P0.01", "mm", dict(Side="Outside", Direction="CW", StepDown=3.0,
                                        processHoles=False, processPerimeter=True),
                dressups=(ramp, tags))


@part("profile + arc lead-in/lead-out dressup, 1/8 in, inch", units="inch", g64="G64")
def profile_leadinout_inch():
    profile_job("profile-leadinout-inch", plate(25.4, 25.4, 101.6, 63.5, 12.7, 6.35), 12, 1270,
                254, 16000, "G64", "inch", dict(Side="Outside", Direction="CW", StepDown=1.5875,
                                                processHoles=False, processPerimeter=True),
                dressups=(lead_in_out,))


@part("profile with the machine's cutter compensation (G41 D1, tangent lead-in/out)",
      g64="G64 P0.01")
def profile_crc_g41():
    profile_job("profile-crc-g41", plate(40, 40, 130, 85, 12, 6.0), 1, 1200, 300, 12000,
                "G64 P0.01", "mm", dict(Side="Outside", Direction="CW", StepDown=2.0,
                                        UseComp=False, processHoles=False,
                                        processPerimeter=True),
                dressups=(machine_crc,))


@part("profile of holes with the machine's cutter compensation (G42), inch", units="inch",
      g64="G64")
def profile_crc_holes_inch():
    holes = [(63.5, 63.5, 25.4), (127, 63.5, 31.75)]
    profile_job("profile-crc-holes-inch", plate(38.1, 38.1, 114.3, 50.8, 6.35, 6.35, holes),
                11, 1016, 254, 12000, "G64", "inch",
                dict(Side="Inside", Direction="CCW", StepDown=3.175, UseComp=False,
                     processHoles=True, processCircles=True, processPerimeter=False),
                dressups=(machine_crc,))


@part("profile of a sketched cam outline (lines and arcs), 10 mm, flood coolant",
      g64="G64 P0.02")
def profile_sketch_cam():
    doc = FreeCAD.newDocument("sk")
    sk = doc.addObject("Sketcher::SketchObject", "Cam")
    # A cam: a big arc, a small arc and two tangent lines (lines and arcs, no constraints
    # needed for the geometry itself).
    c1, r1, c2, r2 = Vector(90, 90, 0), 45.0, Vector(170, 90, 0), 18.0
    d = (c2 - c1).Length
    a = math.acos((r1 - r2) / d)
    p1 = c1 + Vector(math.cos(a), math.sin(a), 0) * r1
    p2 = c2 + Vector(math.cos(a), math.sin(a), 0) * r2
    q1 = c1 + Vector(math.cos(-a), math.sin(-a), 0) * r1
    q2 = c2 + Vector(math.cos(-a), math.sin(-a), 0) * r2
    sk.addGeometry(Part.ArcOfCircle(Part.Circle(c1, Vector(0, 0, 1), r1), a, 2 * math.pi - a))
    sk.addGeometry(Part.LineSegment(q1, q2))
    sk.addGeometry(Part.ArcOfCircle(Part.Circle(c2, Vector(0, 0, 1), r2), -a, a))
    sk.addGeometry(Part.LineSegment(p2, p1))
    doc.recompute()
    face = Part.Face(Part.Wire(Part.__sortEdges__(sk.Shape.Edges)))
    shape = face.extrude(Vector(0, 0, 8)).translated(Vector(0, 0, -8))
    bore = cylinder(90, 90, 12, -9, 1)
    shape = shape.cut(bore)
    FreeCAD.closeDocument(doc.Name)
    profile_job("profile-sketch-cam", shape, 3, 1800, 400, 9000, "G64 P0.02", "mm",
                dict(Side="Outside", Direction="CW", StepDown=2.0, processHoles=True,
                     processCircles=True, processPerimeter=True), coolant="Flood")


def adaptive_job(name, shape, face_fn, tool, feed, plunge, rpm, g64, units, **props):
    j = Job(name, shape, stock_extra=(5.0, 5.0, 0.0))
    tc = j.tool(tool, feed, plunge, rpm)
    op = PathAdaptive.Create("Adaptive")
    op.Base = [(j.model, face_fn(j.model))]
    j.add(op, tc, **props)
    j.post(units, g64)
    j.close()


@part("adaptive clearing, inside pocket, 6 mm, 20 % step-over, helix entry",
      g64="G64 P0.01")
def adaptive_pocket_6mm():
    adaptive_job("adaptive-pocket-6mm", plate_with_pocket(20, 20, 100, 80, 60, 40, 6, 4.5),
                 lambda m: faces_at(m, -4.5), 1, 2400, 400, 16000, "G64 P0.01", "mm",
                 OperationType="Clearing", Side="Inside", StepOver=20, StepDown=2.25,
                 HelixAngle=5, HelixDiameterLimit=0, Tolerance=0.1)


@part("adaptive clearing, inside pocket, 3 mm, 18 %, fine tolerance", g64="G64")
def adaptive_pocket_3mm():
    adaptive_job("adaptive-pocket-3mm", plate_with_pocket(20, 20, 84, 60, 44, 30, 4, 1.5),
                 lambda m: faces_at(m, -1.5), 2, 2000, 250, 20000, "G64", "mm",
                 OperationType="Clearing", Side="Inside", StepOver=18, StepDown=1.5,
                 HelixAngle=3, Tolerance=0.05)


@part("adaptive clearing outside a boss, 1/4 in, inch", units="inch", g64="G64 P0.001")
def adaptive_boss_inch():
    base = Part.makeBox(101.6, 76.2, 12.7, Vector(25.4, 25.4, -19.05))
    boss = rounded_rect(50.8, 44.45, 50.8, 38.1, 12.7, -6.35, 0.0)
    shape = base.fuse(boss).removeSplitter()
    adaptive_job("adaptive-boss-inch", shape, lambda m: faces_at(m, 0.0), 11, 2540, 381,
                 15000, "G64 P0.001", "inch", OperationType="Clearing", Side="Outside",
                 StepOver=25, StepDown=3.175, Tolerance=0.1)


@part("adaptive profiling (finishing wall) of a pocket, 8 mm", g64="G64 P0.02")
def adaptive_profile_8mm():
    adaptive_job("adaptive-profile-8mm", plate_with_pocket(20, 20, 120, 90, 80, 50, 10, 5.0),
                 lambda m: faces_at(m, -5.0), 14, 2000, 400, 12000, "G64 P0.02", "mm",
                 OperationType="Profiling", Side="Inside", StepOver=30, StepDown=5.0,
                 Tolerance=0.1)


def helix_job(name, shape, radius_sel, tool, feed, plunge, rpm, g64, units, **props):
    j = Job(name, shape)
    tc = j.tool(tool, feed, plunge, rpm)
    op = PathHelix.Create("Helix")
    op.Base = [(j.model, [f for r in radius_sel for f in cyl_faces(j.model, r)])]
    j.add(op, tc, **props)
    j.post(units, g64)
    j.close()


@part("helix bores D12/D16/D20, 6 mm, 1 mm pitch", g64="G64")
def helix_bores_6mm():
    holes = [(50, 50, 12), (90, 50, 16), (140, 50, 20), (70, 95, 20), (120, 95, 12)]
    shape = plate(25, 25, 140, 95, 5, 6.0, holes)
    helix_job("helix-bores-6mm", shape, (6, 8, 10), 1, 1500, 200, 12000, "G64", "mm",
              Direction="CCW", StartSide="Inside", StepOver=50, StepDown=1.0)


@part("helix bores, 1/8 in, 0.05 in pitch, inch, CW", units="inch", g64="G64 P0.0005")
def helix_bores_inch():
    holes = [(50.8, 50.8, 9.525), (88.9, 50.8, 12.7), (127, 50.8, 15.875)]
    shape = plate(25.4, 25.4, 127, 50.8, 3.175, 6.35, holes)
    helix_job("helix-bores-inch", shape, (4.7625, 6.35, 7.9375), 12, 1016, 254, 16000, "G64 P0.0005", "inch",
              Direction="CW", StartSide="Inside", StepOver=40, StepDown=1.27)


def drill_job(name, shape, radius, tool, feed, rpm, g64, units, **props):
    j = Job(name, shape)
    tc = j.tool(tool, feed, feed, rpm)
    op = PathDrilling.Create("Drilling")
    op.Base = [(j.model, cyl_faces(j.model, radius))]
    j.add(op, tc, **props)
    j.post(units, g64)
    j.close()


def hole_grid(x0, y0, nx, ny, pitch, d):
    return [(x0 + i * pitch, y0 + j * pitch, d) for j in range(ny) for i in range(nx)]


@part("drilling G81, 5 mm drill, 6 x 4 grid", g64="G64 P0.1")
def drill_g81_grid():
    holes = hole_grid(40, 40, 6, 4, 20, 5.0)
    drill_job("drill-g81-grid", plate(25, 25, 130, 90, 4, 8.0, holes), 2.5, 8, 250, 3000,
              "G64 P0.1", "mm", ReturnLevel="G99")


@part("peck drilling G83, 3 mm drill, 1.5 mm pecks, G98", g64="G64")
def drill_g83_peck():
    holes = hole_grid(40, 40, 5, 3, 15, 3.0) + hole_grid(45, 90, 4, 1, 15, 3.0)
    drill_job("drill-g83-peck", plate(25, 25, 100, 85, 4, 9.0, holes), 1.5, 9, 300, 4500,
              "G64", "mm", PeckEnabled=True, PeckDepth=1.5, ReturnLevel="G98")


@part("drilling G82 with dwell, inch", units="inch", g64="G64 P0.001")
def drill_g82_inch():
    holes = [(38.1 + 25.4 * i, 38.1 + 25.4 * j, 5.0) for j in range(3) for i in range(4)]
    drill_job("drill-g82-inch", plate(25.4, 25.4, 101.6, 76.2, 3, 6.35, holes), 2.5, 8, 200,
              3000, "G64 P0.001", "inch", DwellEnabled=True, DwellTime=0.3)


def dome(cx, cy, r, h, base, thick):
    """A spherical cap of height h on a rectangular base."""
    R = (r * r + h * h) / (2 * h)
    sphere = Part.makeSphere(R, Vector(cx, cy, h - R))
    cap = sphere.common(Part.makeBox(4 * R, 4 * R, h + 1, Vector(cx - 2 * R, cy - 2 * R, 0)))
    block = Part.makeBox(base[0], base[1], thick, Vector(cx - base[0] / 2, cy - base[1] / 2,
                                                          -thick))
    return block.fuse(cap).removeSplitter().translated(Vector(0, 0, -h))


def wave_surface(x0, y0, w, h, amp, periods, thick):
    """A solid whose top is a smooth wave (B-spline surface through a grid of points)."""
    n = 13
    pts = []
    for i in range(n):
        row = []
        for jj in range(n):
            x = x0 + w * i / (n - 1)
            y = y0 + h * jj / (n - 1)
            z = amp * math.sin(2 * math.pi * periods * i / (n - 1)) * math.cos(
                math.pi * periods * jj / (n - 1)) - amp
            row.append(Vector(x, y, z))
        pts.append(row)
    surf = Part.BSplineSurface()
    surf.interpolate(pts)
    top = surf.toShape()
    bottom_z = -2 * amp - thick
    solid = Part.makeBox(w, h, 2 * amp + thick + 2, Vector(x0, y0, bottom_z))
    # Cut the block with the surface extruded upwards.
    cutter = top.extrude(Vector(0, 0, 3 * amp + 10))
    return solid.cut(cutter).removeSplitter()


def surface_job(name, shape, tool, feed, plunge, rpm, g64, units, op_kind="surface",
                **props):
    j = Job(name, shape, stock_extra=(2.0, 2.0, 0.0))
    tc = j.tool(tool, feed, plunge, rpm)
    if op_kind == "surface":
        op = PathSurface.Create("Surface")
    else:
        op = PathWaterline.Create("Waterline")
    op.Base = [(j.model, nonplanar_faces(j.model))]
    j.add(op, tc, **props)
    j.post(units, g64)
    j.close()


@part("3-D surface (OCL drop-cutter), dome, 6 mm ball, zigzag 1 mm step-over",
      g64="G64 P0.02")
def surface_dome_6mm():
    surface_job("surface-dome-6mm", dome(80, 70, 35, 12, (90, 90), 5), 4, 2000, 400, 14000,
                "G64 P0.02", "mm", CutPattern="ZigZag", StepOver=17, SampleInterval=0.5,
                LayerMode="Single-pass", BoundBox="BaseBoundBox", DropCutterDir="X")


@part("3-D surface, dome, 3 mm ball, circular pattern", g64="G64 P0.005")
def surface_dome_circular():
    surface_job("surface-dome-circular", dome(70, 70, 25, 8, (60, 60), 5), 5, 1500, 300, 18000,
                "G64 P0.005", "mm", CutPattern="Circular", StepOver=35, SampleInterval=0.4,
                LayerMode="Single-pass", BoundBox="BaseBoundBox")


@part("3-D surface, wave relief, 1/4 in ball, line pattern, inch", units="inch",
      g64="G64 P0.001")
def surface_wave_inch():
    surface_job("surface-wave-inch", wave_surface(30, 30, 100, 70, 4, 1.5, 6), 13, 2540, 508,
                15000, "G64 P0.001", "inch", CutPattern="Line", StepOver=20,
                SampleInterval=0.5, LayerMode="Single-pass", BoundBox="BaseBoundBox")


@part("3-D surface, wave relief, 6 mm ball, multi-pass zigzag", g64="G64")
def surface_wave_multipass():
    surface_job("surface-wave-multipass", wave_surface(30, 30, 90, 60, 5, 1.0, 6), 4, 2400,
                500, 15000, "G64", "mm", CutPattern="ZigZag", StepOver=35, SampleInterval=0.8,
                LayerMode="Multi-pass", StepDown=5.0, BoundBox="BaseBoundBox")


@part("waterline (OCL), dome, 6 mm ball", g64="G64 P0.01")
def waterline_dome():
    surface_job("waterline-dome", dome(80, 80, 30, 14, (80, 80), 5), 4, 1800, 400, 14000,
                "G64 P0.01", "mm", op_kind="waterline", StepOver=50, SampleInterval=0.5,
                StepDown=1.0, BoundBox="BaseBoundBox", Algorithm="OCL Dropcutter")


def text_part(text, x, y, size, depth, thick=6.0, plate_wh=(170, 50)):
    """A plate with the text's outline cut `depth` deep, and the text's faces."""
    import Draft
    doc = FreeCAD.ActiveDocument
    ss = Draft.make_shapestring(String=text, FontFile=FONT, Size=size, Tracking=0)
    doc.recompute()
    faces = ss.Shape.Faces
    letters = Part.makeCompound(faces).translated(Vector(x, y, 0))
    block = Part.makeBox(plate_wh[0], plate_wh[1], thick, Vector(x - 10, y - 12, -thick))
    doc.removeObject(ss.Name)
    return block, letters


def engrave_job(name, text, size, tool, feed, plunge, rpm, g64, units, vcarve, depth):
    doc = FreeCAD.newDocument(name.replace("-", "_") + "_text")
    block, letters = text_part(text, 20, 20, size, depth)
    FreeCAD.closeDocument(doc.Name)
    j = Job(name, block, stock_extra=(0.0, 0.0, 0.0))
    text_obj = j.doc.addObject("Part::Feature", "Text")
    text_obj.Shape = letters
    j.doc.recompute()
    tc = j.tool(tool, feed, plunge, rpm)
    if vcarve:
        op = PathVcarve.Create("Vcarve")
        op.Base = [(text_obj, ["Face%d" % (i + 1) for i in range(len(letters.Faces))])]
        j.add(op, tc, Discretize=0.25, Colinear=10.0)
    else:
        op = PathEngrave.Create("Engrave")
        op.BaseShapes = [text_obj]
        j.add(op, tc, StartDepth=0.0, FinalDepth=-depth, StepDown=depth)
    j.post(units, g64)
    j.close()


@part("engraving text outlines, 60 degree V-bit, 0.5 mm deep", g64="G64")
def engrave_text():
    engrave_job("engrave-text", "RTCNC 2.9", 22, 6, 900, 200, 16000, "G64", "mm", False, 0.5)


@part("engraving text outlines, 2 mm end mill, inch", units="inch", g64="G64 P0.001")
def engrave_text_inch():
    engrave_job("engrave-text-inch", "G-CODE", 25, 15, 762, 127, 20000, "G64 P0.001", "inch",
                False, 0.6)


@part("V-carving text (Voronoi medial axis), 90 degree V-bit", g64="G64 P0.01")
def vcarve_text():
    engrave_job("vcarve-text", "CNC", 30, 7, 1200, 300, 18000, "G64 P0.01", "mm", True, 0)


@part("V-carving text, 60 degree V-bit, small letters", g64="G64")
def vcarve_text_small():
    engrave_job("vcarve-text-small", "LinuxCNC", 14, 6, 1000, 250, 18000, "G64", "mm", True, 0)


@part("face milling, 10 mm, zigzag 70 %, one 1 mm pass", g64="G64 P0.05")
def face_mill_10mm():
    shape = Part.makeBox(160, 110, 20, Vector(20, 20, -21))
    j = Job("face-mill-10mm", shape, stock_extra=(2.0, 2.0, 1.0))
    tc = j.tool(3, 2500, 500, 9000)
    op = PathMillFace.Create("Face")
    op.Base = [(j.model, faces_at(j.model, -1.0))]
    j.add(op, tc, OffsetPattern="ZigZag", StepOver=70, StepDown=1.0, BoundaryShape="Stock")
    j.post("mm", "G64 P0.05")
    j.close()


@part("chamfer/deburr of outside edges and holes, 45 degree chamfer mill", g64="G64")
def deburr_plate():
    holes = [(60, 60, 14), (140, 60, 14), (100, 95, 20)]
    shape = plate(30, 30, 140, 90, 8, 8.0, holes)
    chamfered = shape
    j = Job("deburr-plate", chamfered)
    tc = j.tool(10, 1000, 300, 10000)
    op = PathDeburr.Create("Deburr")
    top = faces_at(j.model, 0.0)
    op.Base = [(j.model, top)]
    j.add(op, tc, Width=1.0, ExtraDepth=0.2)
    j.post("mm", "G64")
    j.close()


@part("full job: face, adaptive pocket, profile, drill, chamfer; 4 tool changes, flood",
      g64="G64 P0.02")
def bracket_full_job():
    base = rounded_rect(20, 20, 110, 70, 10, -8, 0)
    pocket = rounded_rect(45, 40, 60, 30, 8, -4, 1)
    holes = [(32, 32, 6.6), (118, 32, 6.6), (32, 78, 6.6), (118, 78, 6.6)]
    shape = base.cut(pocket)
    for (x, y, d) in holes:
        shape = shape.cut(cylinder(x, y, d / 2, -9, 1))
    j = Job("bracket-full-job", shape, stock_extra=(5.0, 5.0, 1.0))
    t3 = j.tool(3, 2500, 500, 9000)
    t1 = j.tool(1, 2000, 400, 14000)
    t8 = j.tool(8, 250, 250, 3000)
    t10 = j.tool(10, 1200, 300, 10000)
    face = j.create(PathMillFace, "Face")
    face.Base = [(j.model, faces_at(j.model, 0.0))]
    j.add(face, t3, OffsetPattern="ZigZag", StepOver=70, StepDown=1.0, BoundaryShape="Stock")
    adaptive = j.create(PathAdaptive, "Adaptive")
    adaptive.Base = [(j.model, faces_at(j.model, -4.0))]
    j.add(adaptive, t1, OperationType="Clearing", Side="Inside", StepOver=25, StepDown=4.0,
          Tolerance=0.1)
    prof = j.create(PathProfile, "Profile")
    j.add(prof, t1, Side="Outside", Direction="CW", StepDown=4.0, processHoles=False,
          processPerimeter=True)
    drill = j.create(PathDrilling, "Drilling")
    drill.Base = [(j.model, cyl_faces(j.model, 3.3))]
    j.add(drill, t8, PeckEnabled=True, PeckDepth=4.0, ReturnLevel="G99")
    deburr = j.create(PathDeburr, "Deburr")
    deburr.Base = [(j.model, faces_at(j.model, 0.0))]
    j.add(deburr, t10, Width=0.8, ExtraDepth=0.2)
    j.post("mm", "G64 P0.02", coolant="Flood")
    j.close()


def main():
    os.makedirs(OUT, exist_ok=True)
    rows = []
    failed = []
    for name, fn, operation, units, g64 in PARTS:
        if ONLY and name not in ONLY:
            continue
        try:
            fn()
            rows.append("%s\t%s\t%s\t%s\n" % (name, operation, units, g64))
            print("made %s" % name)
        except Exception:
            failed.append(name)
            print("FAILED %s" % name)
            traceback.print_exc()
            for d in list(FreeCAD.listDocuments()):
                FreeCAD.closeDocument(d)
    with open(os.path.join(OUT, "freecad.tsv"), "w" if not ONLY else "a") as f:
        f.writelines(rows)
    if failed:
        print("freecad_parts: failed: %s" % " ".join(failed))
        sys.exit(1)


main()
