"""`rtcnc serve` on the seeds' 12-drive gantry over EtherCAT (configs/ethercat-sim-12.toml:
twelve CiA 402 drives in cyclic synchronous position mode and an I/O terminal, simulated
EtherCAT devices in the machine process, the master bringing the bus to OP at 1 kHz with
distributed clocks): the API process serves it as it serves the simulated mill, and
examples/gantry-12.ngc runs to its end through the API."""

from __future__ import annotations

import pytest

from conftest import REPO, Server, wait_state

GANTRY = ["X0", "X1", "X2", "X3", "Y0", "Y1", "Y2", "Y3", "Z", "P0", "P1", "P2"]


def gantry_file(folder):
    """The shipped file, its following-error limits widened: this shared VM stalls real-time
    threads for milliseconds (docs/kernel.md "Timing"), and this test is about the service on
    the bus, not about the drives' tracking (crates/ethercat's tests check that)."""
    text = (REPO / "configs" / "ethercat-sim-12.toml").read_text()
    widened = text.replace("min_ferror = 0.1, ferror = 0.4", "min_ferror = 5.0, ferror = 5.0")
    assert widened != text
    path = folder / "ethercat-sim-12.toml"
    path.write_text(widened)
    return path


@pytest.fixture(scope="module")
def gantry(tmp_path_factory):
    folder = tmp_path_factory.mktemp("serve-ethercat")
    s = Server(folder, config=gantry_file(folder))
    yield s
    s.stop()


def test_serve_runs_the_gantry_program_on_ethercat_drives(gantry):
    viewer = gantry.client("viewer")
    s = viewer.status()
    assert s.machine == "12-drive gantry on simulated EtherCAT drives"
    assert [j.name for j in s.joints] == GANTRY

    c = gantry.client("operator")
    c.acquire_lease()
    if c.status().state != "idle":
        c.reset().wait(20)
        wait_state(c, lambda s: s.state == "idle")
    c.upload_program("gantry-12.ngc", (REPO / "examples" / "gantry-12.ngc").read_text())
    c.load_program("gantry-12.ngc").wait(5)
    # On its way: the first feed move ends at X250 Y140 Z-20, so the four X drives pass X100.
    start = c.cycle_start()
    moving = wait_state(c, lambda s: s.machine_position["X"] > 100 or s.program_ended, 30)
    assert moving.last_fault is None, moving
    done = start.wait(60)
    assert done.state == "done", gantry.lines[-20:]
    s = c.status()
    assert s.program_ended and s.state == "idle" and s.fault_count == 0, s
    # The program ends with G0 X0 Y0 Z0: every gantry drive (its set-point is the axis's) and
    # its feedback at 0; the three independent joints never moved.
    for axis in ("X", "Y", "Z"):
        assert s.machine_position[axis] == pytest.approx(0.0, abs=1e-9)
    for joint in s.joints:
        assert joint.setpoint == pytest.approx(0.0, abs=1e-9), joint
        assert joint.feedback == pytest.approx(0.0, abs=1e-3), joint
    c.release_lease()
