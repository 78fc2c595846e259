"""The client against a real `rtcnc serve` on the simulated mill: a program to its end,
acknowledgements, refusals with their codes, the WebSocket, roles and the lease, uploads,
preview and estimate, setup, PLC variables."""

from __future__ import annotations

import asyncio
import math
import re
import subprocess

import pytest

import rtcnc
from conftest import BIN, REPO, wait_state

PROGRAM = "G21 G90\nG0 X10 Y10\nG1 X20 F600\nG2 X30 Y10 I5 J0\nG1 Y0\nM2\n"


def test_the_committed_models_are_generated_from_the_openapi_document():
    r = subprocess.run(["python3", str(REPO / "scripts" / "gen_python_models.py"), "--check"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


def test_a_program_runs_to_its_end_through_the_api(server, operator):
    operator.upload_program("square.ngc", PROGRAM)
    operator.load_program("square.ngc").wait(5)
    start = operator.cycle_start()
    assert start.state in ("accepted", "done")
    done = start.wait(60)
    assert done.state == "done"
    s = operator.status()
    assert s.program_ended and s.state == "idle" and s.program == "square.ngc"
    # The program's last point, by hand: X30 Y0.
    assert s.machine_position["X"] == pytest.approx(30.0, abs=1e-6)
    assert s.machine_position["Y"] == pytest.approx(0.0, abs=1e-6)
    kinds = [e.kind for e in operator.events(0).events]
    assert "program_end" in kinds


def test_a_refusal_raises_with_the_kernels_code(server, operator):
    with pytest.raises(rtcnc.Unprocessable) as e:
        operator.jog("B", velocity=1.0)
    assert e.value.code == "command.bad_axis"
    operator.upload_program("long.ngc", "G1 X100 F300\nM2\n")
    operator.load_program("long.ngc").wait(5)
    operator.cycle_start()
    wait_state(operator, lambda s: s.state == "running")
    # MDI while a program runs: the kernel refuses, the API says why.
    with pytest.raises(rtcnc.CommandRefused) as e:
        operator.mdi("G0 X0")
    assert e.value.code == "command.busy" and e.value.status == 409
    operator.stop().wait(5)
    wait_state(operator, lambda s: s.state == "idle")


def test_control_needs_a_session_the_role_and_the_lease(server, operator):
    anonymous = rtcnc.Client(server.url)
    with pytest.raises(rtcnc.Unauthorized) as e:
        anonymous.reset()
    assert e.value.status == 401 and e.value.code == "auth.unauthorized"
    viewer = server.client("viewer")
    with pytest.raises(rtcnc.Forbidden) as e:
        viewer.reset()
    assert e.value.status == 403 and e.value.code == "auth.forbidden"
    assert viewer.status().lease_holder == "operator"
    other = server.client("operator2")
    with pytest.raises(rtcnc.LeaseRequired) as e:
        other.mdi("G0 X1")
    assert e.value.status == 409 and e.value.code == "lease.held"
    with pytest.raises(rtcnc.LeaseRequired) as e:
        other.acquire_lease()
    assert e.value.code == "lease.held" and e.value.extra["holder"] == "operator"
    # Feed hold and e-stop: every operator, lease or not.
    assert other.feed_hold().state == "done"
    with pytest.raises(rtcnc.Forbidden):
        viewer.estop()
    # An admin takes the lease over; the operator then watches.
    admin = server.client("admin")
    admin.acquire_lease(take_over=True)
    with pytest.raises(rtcnc.LeaseRequired):
        operator.mdi("G0 X1")
    admin.release_lease()
    with pytest.raises(rtcnc.LeaseRequired) as e:
        other.mdi("G0 X1")
    assert e.value.code == "lease.required"
    operator.acquire_lease()


def test_an_urgent_acknowledgement_reports_its_latency(server, operator):
    acks = operator.set_overrides(feed=0.5)
    assert acks and acks[0].state == "done"
    assert acks[0].latency_periods is not None and acks[0].latency_periods >= 1
    assert operator.status().overrides.feed == 0.5
    operator.set_overrides(feed=1.0)


def test_an_upload_reports_every_error_with_line_and_column(server, operator):
    with pytest.raises(rtcnc.Unprocessable) as e:
        operator.upload_program("bad.ngc", "G21\nG1 X10 F600 Q\nG0 X(\nM2\n")
    errors = e.value.extra["errors"]
    assert [(x["line"], x["column"]) for x in errors] == [(2, 14), (3, 5)]
    with pytest.raises(rtcnc.Unprocessable) as e:
        operator.upload_program("latin1.ngc", "G0 X1 (caf\xe9)\n".encode("latin-1"))
    assert e.value.code == "program.encoding"
    with pytest.raises(rtcnc.RtcncError) as e:
        operator.upload_program("../escape.ngc", "M2\n")
    assert e.value.status in (400, 404)
    names = [p.name for p in operator.programs()]
    assert "bad.ngc" not in names


def test_the_preview_follows_the_programmed_geometry(server, operator):
    operator.upload_program("preview.ngc", PROGRAM)
    p = operator.preview("preview.ngc")
    assert [x.kind for x in p.paths] == ["rapid", "feed"]
    feed = p.paths[1]
    # The G2 arc: centre (25, 10), radius 5, clockwise from (20, 10) over the top to (30, 10).
    arc = [pt for pt, line in zip(feed.points[1:], feed.lines) if line == 4]
    assert len(arc) > 8
    for x, y, _ in arc:
        assert math.hypot(x - 25, y - 10) == pytest.approx(5, abs=1e-9)
        assert y >= 10 - 1e-9
    assert feed.points[-1] == pytest.approx([30, 0, 0])
    assert p.min == pytest.approx([0, 0, 0]) and p.max[0] == pytest.approx(30)


def test_the_estimate_is_the_cycle_time_rtcnc_sim_gives(server, operator, tmp_path):
    program = "G21 G90 G64\nG1 X100 F3000\nG1 X0\nM2\n"
    operator.upload_program("estimate.ngc", program)
    e = operator.estimate("estimate.ngc")
    assert e.ended and not e.faults
    # Closed-form lower bound: 200 mm at 50 mm/s.
    assert e.cycle_time_s >= 4.0
    path = tmp_path / "estimate.ngc"
    path.write_text(program)
    out = subprocess.run([str(BIN), "sim", str(path), "--machine", str(server.config)],
                         capture_output=True, text=True, check=True).stdout
    m = re.search(r"cycle time\s+([0-9.]+) s", out) or re.search(r"([0-9.]+) s", out)
    assert m, out
    assert e.cycle_time_s == pytest.approx(float(m.group(1)), abs=2e-3)


def test_the_tool_table_and_work_offsets_round_trip_and_persist(server, operator):
    setter = server.client("setter")
    tools = setter.tools()
    new = [rtcnc.models.Tool(number=7, pocket=3, offset={"Z": -12.5}, diameter=6.35, comment="drill")]
    with pytest.raises(rtcnc.Forbidden):
        operator.set_tools(new)
    assert setter.set_tools(tools + new).state in ("accepted", "done")
    again = {t.number: t for t in setter.tools()}
    assert again[7].offset["Z"] == -12.5 and again[7].diameter == 6.35 and again[7].comment == "drill"
    text = (server.folder / "sim-mill.tbl").read_text()
    assert "T7 P3" in text and "Z-12.500000" in text
    # The machine reads it: a tool length offset from the new table.
    operator.mdi("T7 M6 G43 H7").wait(30)
    s = wait_state(operator, lambda s: s.modal is not None and s.modal.tool_offset["Z"] == -12.5)
    operator.mdi("G49").wait(10)
    ack = setter.set_offset("G55", {"X": 12.5, "Y": -3.0})
    assert ack.state == "done"
    offsets = {o.system: o for o in setter.offsets()}
    assert offsets["G55"].offset["X"] == 12.5 and offsets["G55"].offset["Y"] == -3.0
    assert "5241\t12.500000" in (server.folder / "sim-mill.var").read_text()
    del s


def test_plc_variables_read_watch_force(server, operator):
    setter = server.client("setter")
    assert setter.plc_read("Mill.air_blast") in ("FALSE", "TRUE")
    with pytest.raises(rtcnc.NotFound) as e:
        setter.plc_read("Mill.no_such_thing")
    assert e.value.code == "plc.unknown-variable"
    setter.plc_watch(["Mill.air_blast", "Mill.door_closed"])
    with pytest.raises(rtcnc.Forbidden):
        operator.plc_force("Mill.air_blast", "TRUE")
    assert setter.plc_force("Mill.air_blast", "TRUE") == "TRUE"
    s = wait_state(setter, lambda s: len(s.plc_watch) == 2 and s.plc_watch[0].forced)
    assert s.plc_watch[0].path == "Mill.air_blast" and s.plc_watch[0].value == 1.0
    assert setter.plc_read("Mill.air_blast") == "TRUE"
    setter.plc_unforce("Mill.air_blast")
    wait_state(setter, lambda s: not s.plc_watch[0].forced)


def test_the_websocket_gives_a_snapshot_then_changes_and_events(server, operator):
    async def run():
        client = rtcnc.AsyncClient(server.url, token=operator.token)
        seen: list[rtcnc.Message] = []
        async def watch():
            async for m in client.subscribe(rate_hz=50):
                seen.append(m)
                ended = any(x.type == "event" and x.event.kind == "program_end" for x in seen)
                if ended and m.status is not None and m.status.program_ended and m.status.state == "idle":
                    return
        task = asyncio.create_task(watch())
        await asyncio.sleep(0.3)
        await client.upload_program("ws.ngc", "G0 X5\nG1 X6 F600\nM2\n")
        await (await client.load_program("ws.ngc")).wait(5)
        await (await client.cycle_start()).wait(30)
        await asyncio.wait_for(task, 30)
        await client.aclose()
        return seen
    seen = asyncio.run(run())
    assert seen[0].type == "snapshot" and seen[0].status is not None
    statuses = [m.status for m in seen if m.type == "status"]
    assert any(s.state == "running" for s in statuses)
    assert statuses[-1].machine_position["X"] == pytest.approx(6.0, abs=1e-6)
    acks = [m.event for m in seen if m.type == "event" and m.event.kind == "ack"]
    assert any(a.ack == "done" for a in acks)


def test_the_faults_have_a_history_that_operators_acknowledge(server, operator):
    operator.estop()
    wait_state(operator, lambda s: s.state == "estop")
    faults = operator.faults()
    estops = [f for f in faults if f.code == "kernel.estop"]
    assert estops and not estops[-1].acknowledged
    after = operator.acknowledge_faults(estops[-1].seq)
    assert all(f.acknowledged for f in after if f.seq <= estops[-1].seq)
    operator.reset().wait(10)
    wait_state(operator, lambda s: s.state == "idle")
    t = operator.timing()
    assert any(x.name == "interpolation" and x.activations > 0 for x in t.tasks)
    trace = operator.trace()
    assert any(e["name"] == "joint X" for e in trace["traceEvents"])
