"""Homing one axis, the mode switch and the distance to go, against a real `rtcnc serve`."""

from __future__ import annotations

import pytest

import rtcnc
from conftest import wait_state

# In machine coordinates (G53, no tool length offset), whatever offsets other tests set.
PROGRAM = "G21 G90 G61.1 G49\nG53 G0 X0 Y0 Z0\nG53 G1 X60 F600\nG53 G1 Y40 Z-2\nM2\n"


def test_one_axis_is_homed_and_the_others_keep_their_state(server, operator):
    before = {j.name: j.homed for j in operator.status().joints}
    operator.set_mode("manual").wait(5)
    operator.jog("Z", distance=-3.0).wait(10)
    operator.home("Z").wait(60)
    s = wait_state(operator, lambda s: s.state == "idle")
    after = {j.name: j.homed for j in s.joints}
    assert after["Z"] is True
    assert {k: v for k, v in after.items() if k != "Z"} == {k: v for k, v in before.items() if k != "Z"}
    # Z's home position in configs/sim-mill.toml is 0.
    assert s.machine_position["Z"] == pytest.approx(0.0, abs=1e-9)
    with pytest.raises(rtcnc.Unprocessable) as e:
        operator.home("B")
    assert e.value.code == "command.bad_axis"


def test_the_mode_switches_when_idle_and_not_while_a_program_runs(server, operator):
    for mode in ("mdi", "auto", "manual"):
        operator.set_mode(mode).wait(5)
        # The acknowledgement may come a status period before the status shows it.
        wait_state(operator, lambda s: s.mode == mode, timeout=1.0)
    operator.upload_program("togo.ngc", PROGRAM)
    operator.load_program("togo.ngc").wait(5)
    operator.cycle_start()
    wait_state(operator, lambda s: s.state == "running" and s.line == 3)
    with pytest.raises(rtcnc.RtcncError) as e:
        operator.set_mode("manual")
    assert e.value.status == 409 and e.value.code == "command.busy"
    assert operator.status().mode == "auto"
    operator.stop()
    wait_state(operator, lambda s: s.state == "idle")


def test_the_distance_to_go_is_from_the_position_to_the_programmed_end_of_the_line(server, operator):
    operator.upload_program("togo.ngc", PROGRAM)
    operator.load_program("togo.ngc").wait(5)
    operator.cycle_start()
    ends = {3: {"X": 60.0, "Y": 0.0, "Z": 0.0}, 4: {"X": 60.0, "Y": 40.0, "Z": -2.0}}
    seen = set()
    for line, end in ends.items():
        wait_state(operator, lambda s: s.line == line and s.path_speed > 1.0)
        for _ in range(5):
            s = operator.status()
            if s.line != line:
                break
            seen.add(line)
            # Both from the same snapshot: the set-point plus what is left is the line's end.
            for a, e in end.items():
                assert s.machine_position[a] + s.distance_to_go[a] == pytest.approx(e, abs=1e-9)
    assert seen == {3, 4}
    s = wait_state(operator, lambda s: s.program_ended and s.state == "idle")
    assert all(v == 0.0 for v in s.distance_to_go.values())
