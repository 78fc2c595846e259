"""The endpoints the web HMI added to the API, against a real `rtcnc serve`: the HMI at `/`,
checking a text as the editor types, the binary preview, the handwheel, the machine file
(written by an admin after the start-up checks), the PLC program's variable list."""

from __future__ import annotations

import struct

import httpx
import pytest

import rtcnc
from conftest import wait_state

PROGRAM = "G21 G90\nG0 X10 Y10\nG1 X20 F600\nG2 X30 Y10 I5 J0\nG1 Y0\nM2\n"


def test_the_hmi_is_served_at_the_root_and_unknown_api_paths_stay_problems(server):
    page = httpx.get(server.url + "/")
    assert page.status_code == 200 and page.headers["content-type"].startswith("text/html")
    assert '<div id="app">' in page.text
    # A screen's address is the same page (the HMI routes in the browser).
    assert httpx.get(server.url + "/operate").text == page.text
    r = httpx.get(server.url + "/api/no/such/thing")
    assert r.status_code == 404 and r.headers["content-type"] == "application/problem+json"
    assert r.json()["code"] == "api.not_found"


def test_a_text_is_checked_with_every_error_at_its_line_and_nothing_is_stored(server):
    viewer = server.client("viewer")
    c = viewer.check_program("draft.ngc", "G21\nG1 X10 F600 Q\nG0 X(\nM2\n")
    assert [(e.line, e.column) for e in c.errors] == [(2, 14), (3, 5)] and c.lines == 4
    assert viewer.check_program("draft.ngc", PROGRAM).errors == []
    assert "draft.ngc" not in [p.name for p in viewer.programs()]


def test_the_binary_preview_holds_the_points_of_the_json_preview(server, operator):
    operator.upload_program("binary.ngc", PROGRAM)
    p = operator.preview("binary.ngc")
    b = operator.preview_binary("binary.ngc")
    assert b[:8] == b"RTCNCPV1"
    n, m = struct.unpack_from("<II", b, 8)
    chain = [p.paths[0].points[0]] + [pt for path in p.paths for pt in path.points[1:]]
    assert n == len(chain)
    xyz = struct.unpack_from(f"<{3 * n}f", b, 40)
    for i, pt in enumerate(chain):
        assert xyz[3 * i:3 * i + 3] == pytest.approx(pt, abs=1e-4)
    lines = struct.unpack_from(f"<{n}I", b, 40 + 12 * n)
    kinds = b[40 + 16 * n:40 + 17 * n]
    assert lines[1:] == tuple(line for path in p.paths for line in path.lines)
    assert kinds[0] == 0 and set(kinds[1:]) == {1, 2}
    assert b[40 + 17 * n:] == b"[]" and m == 2
    with pytest.raises(rtcnc.RtcncError) as e:
        operator._request("GET", "/api/programs/binary.ngc/preview", params={"format": "xml"})
    assert e.value.status == 400


def test_the_handwheel_goes_on_an_axis_and_is_released(server, operator):
    assert operator.handwheel("X", 10).state in ("accepted", "done")
    assert operator.status().mode == "manual"
    assert operator.handwheel(None).state in ("accepted", "done")
    with pytest.raises(rtcnc.Unprocessable) as e:
        operator.handwheel("B")
    assert e.value.code == "command.bad_axis"
    with pytest.raises(rtcnc.Unprocessable):
        operator.handwheel("X", 0)


def test_the_machine_file_is_written_by_an_admin_only_after_the_start_up_checks(server, operator):
    setter = server.client("setter")
    admin = server.client("admin")
    f = setter.machine_file()
    assert "[machine]" in f.text and not f.changed_since_start
    assert f.handwheel_units_per_count == pytest.approx(0.001)
    with pytest.raises(rtcnc.Forbidden):
        setter.set_machine_file(f.text)
    bad = f.text.replace("max_velocity = 100.0", "max_velocity = -5.0", 1)
    with pytest.raises(rtcnc.Unprocessable) as e:
        admin.set_machine_file(bad)
    assert e.value.code == "setup.machine_invalid" and "max_velocity" in e.value.detail
    assert server.config.read_text() == f.text
    saved = admin.set_machine_file(f.text + "\n# checked by the HMI tests\n")
    assert saved.applies_at_next_start
    again = setter.machine_file()
    assert again.changed_since_start and again.text.endswith("# checked by the HMI tests\n")
    # Back as it was: the machine restarts in other tests read it.
    admin.set_machine_file(f.text)
    wait_state(operator, lambda s: s.connected)


def test_the_plc_programs_variables_are_listed_with_their_types(server):
    vars = {v.path.upper(): v for v in server.client("viewer").plc_variables()}
    assert vars["MILL.DOOR_CLOSED"].type_name == "BOOL"
    assert vars["MILL.DOOR_CLOSED"].location == "%IX0.1"
