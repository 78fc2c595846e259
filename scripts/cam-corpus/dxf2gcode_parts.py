"""Runs dxf2gcode (Debian's, headless: -q, Qt's offscreen platform) on the corpus drawings
and writes one LinuxCNC program per part.

    python3 scripts/cam-corpus/dxf2gcode_parts.py DXFDIR OUTDIR TOOLTABLE

Each part gets a fresh configuration folder (HOME) written from dxf2gcode's own defaults
with these settings changed: "#" as the layer-parameter separator, the tools of the corpus's
tool table, the 3-D view (mode3d: the 2-D canvas of this version fails on Python 3.11's
PyQt5 and so stops the export; the output does not depend on the view), and per part the
cutter compensation, the path mode (code_begin) and the program end. A line per program
goes to OUTDIR/dxf2gcode.tsv. The "(Time: ...)" comment of the header is left out so that
regenerating gives the same file.
"""

import os
import re
import shutil
import subprocess
import sys
import tempfile

from configobj import ConfigObj

# name, drawing, operation, automatic compensation, done by the machine, path mode, end
PARTS = [
    ("d2g-plate-g41", "d2g-plate-g41",
     "contours with the machine's cutter compensation (G41/G42), 3 passes, 2 tools", True,
     True, "G64", "M2"),
    ("d2g-plate-offset", "d2g-plate-offset",
     "contours offset by dxf2gcode (G40), 3 passes, 2 tools", True, False, "G64 P0.01",
     "M30"),
    ("d2g-plate-g41-inch", "d2g-plate-g41-inch",
     "contours with G41/G42, inch, 2 passes, 2 tools", True, True, "G64 P0.001", "M2"),
    ("d2g-splines", "d2g-splines",
     "engraving of splines (biarc fit) and ellipses, V-bit, no compensation", False, True,
     "G64 P0.005", "M2"),
    ("d2g-gears", "d2g-gears", "gear outlines (dense polylines) with G41/G42, 2 passes", True,
     True, "G64", "M30"),
    ("d2g-gears-inch", "d2g-gears-inch", "gear outlines offset by dxf2gcode, inch", True,
     False, "G64", "M2"),
    ("d2g-drill", "d2g-drill", "drilling points (plunge moves), 2 tools", False, True,
     "G64 P0.05", "M2"),
    ("d2g-tabs", "d2g-tabs", "outline and hole with holding tabs (BREAKS layer), G41/G42",
     True, True, "G64 P0.02", "M2"),
    ("d2g-spiral-art", "d2g-spiral-art", "engraving of an arc spiral and circles, 2 mm",
     False, True, "G61", "M2"),
]


def tools(table):
    """Tool number -> diameter (mm) from a LinuxCNC tool table."""
    out = {}
    for line in open(table):
        m = re.match(r"\s*T(\d+)\s.*?D([0-9.]+)", line)
        if m:
            out[int(m.group(1))] = float(m.group(2))
    return out


def configure(home, tool_table, compensation, by_machine, path_mode, end):
    cfg_dir = os.path.join(home, ".config", "dxf2gcode")
    cfg_path = os.path.join(cfg_dir, "config", "config.cfg")
    post_path = os.path.join(cfg_dir, "postpro_config", "postpro_config.cfg")
    cfg = ConfigObj(cfg_path)
    cfg["General"]["mode3d"] = True
    cfg["General"]["automatic_cutter_compensation"] = compensation
    cfg["General"]["tool_units"] = "mm"
    cfg["Cutter_Compensation"]["done_by_machine"] = by_machine
    cfg["Layer_Options"]["id_float_separator"] = "#"
    cfg["Tool_Parameters"] = {}
    for number, diameter in sorted(tools(tool_table).items()):
        cfg["Tool_Parameters"][str(number)] = {
            "diameter": diameter, "speed": 12000.0, "start_radius": round(diameter / 2, 3)}
    cfg.write()
    post = ConfigObj(post_path)
    post["General"]["code_begin"] = (
        "%s (Path mode) G17 (XY plane) G40 (Cancel radius comp.) G49 (Cancel length comp.)"
        % path_mode)
    post["General"]["code_end"] = "%s (Program end)" % end
    post["Program"]["tool_change"] = "T%tool_nr M6%nlG43 H%tool_nr%nlS%speed%nl"
    post.write()


def main():
    dxf_dir, out_dir, tool_table = sys.argv[1:4]
    only = [n for n in os.environ.get("CAM_ONLY", "").split(",") if n]
    os.makedirs(out_dir, exist_ok=True)
    env = dict(os.environ, QT_QPA_PLATFORM="offscreen")
    rows = []
    failed = []
    for name, drawing, operation, comp, by_machine, path_mode, end in PARTS:
        if only and name not in only:
            continue
        home = tempfile.mkdtemp(prefix="dxf2gcode-")
        env["HOME"] = home
        env["XDG_RUNTIME_DIR"] = home
        try:
            # A first run writes dxf2gcode's default configuration, which is then edited.
            subprocess.run(["dxf2gcode", "-q"], env=env, cwd=home, capture_output=True,
                           timeout=120)
            configure(home, tool_table, comp, by_machine, path_mode, end)
            dxf = os.path.join(dxf_dir, drawing + ".dxf")
            shutil.copy(dxf, os.path.join(home, name + ".dxf"))
            raw = os.path.join(home, name + ".ngc")
            subprocess.run(["dxf2gcode", name + ".dxf", "-e", raw, "-q"], env=env, cwd=home,
                           capture_output=True, timeout=300)
            if not os.path.exists(raw):
                raise RuntimeError("dxf2gcode wrote no program")
            text = [line for line in open(raw) if not line.startswith("(Time:")]
            with open(os.path.join(out_dir, name + ".ngc"), "w") as f:
                f.write("(%s: dxf2gcode 20191025 of Debian, drawing %s.dxf from "
                        "scripts/cam-corpus/dxf_parts.py)\n" % (name, drawing))
                f.writelines(text)
            units = "inch" if "G20" in "".join(text[:12]) else "mm"
            rows.append("%s\t%s\t%s\t%s\n" % (name, operation, units, path_mode))
            print("made %s" % name)
        except Exception as e:  # report and go on with the next part
            failed.append(name)
            print("FAILED %s: %s" % (name, e))
        finally:
            shutil.rmtree(home, ignore_errors=True)
    with open(os.path.join(out_dir, "dxf2gcode.tsv"), "a" if only else "w") as f:
        f.writelines(rows)
    if failed:
        print("dxf2gcode_parts: failed: %s" % " ".join(failed))
        sys.exit(1)


if __name__ == "__main__":
    main()
