"""The examples of examples/python/ run against the real server."""

from __future__ import annotations

import subprocess
import sys

from conftest import PASSWORDS, REPO, wait_state


def release(server) -> None:
    admin = server.client("admin")
    admin.acquire_lease(take_over=True)
    admin.release_lease()


def test_jog_and_touch_off_makes_the_reached_z_the_work_zero(server):
    release(server)
    r = subprocess.run([sys.executable, str(REPO / "examples/python/jog_touch_off.py"), server.url,
                        "admin", PASSWORDS["admin"][1], "-3"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    viewer = server.client("viewer")
    s = wait_state(viewer, lambda s: s.state == "idle")
    assert abs(s.machine_position["Z"] + 3) < 1e-6
    assert abs(s.work_position["Z"]) < 1e-6, "touched off: the work Z is 0 where the tool stands"
    g54 = {o.system: o for o in viewer.offsets()}["G54"]
    assert abs(g54.offset["Z"] + 3) < 1e-6
    admin = server.client("admin")
    admin.acquire_lease(take_over=True)
    admin.set_offset("G54", {"X": 0, "Y": 0, "Z": 0})
    admin.release_lease()


def test_run_a_program_and_log_the_following_error(server, tmp_path):
    release(server)
    program = tmp_path / "small.ngc"
    program.write_text("G21 G90\nG1 X5 Y5 F1200\nG0 X0 Y0\nM2\n")
    r = subprocess.run([sys.executable, str(REPO / "examples/python/run_program.py"), server.url,
                        "operator", PASSWORDS["operator"][1], str(program)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "largest following error: X" in r.stdout
    release(server)
