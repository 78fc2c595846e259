"""The two processes and their loss: kill -9 of the API process in the middle of a program
(the machine goes on, or holds, as the machine file says; a jog stops), kill -9 of the
machine process (503, then the API attaches again), and kill -9 of the API while it writes
the tool table (the file is the old one or the new one, never a torn one)."""

from __future__ import annotations

import os
import signal
import time

import pytest

import rtcnc
from conftest import Server, wait_state

LONG = "G21 G90\nG1 X150 F1200\nG1 X0\nM2\n"


def operator_with_lease(server: Server) -> rtcnc.Client:
    c = server.client("operator")
    c.acquire_lease(take_over=False) if server.client("viewer").lease().holder is None else None
    if not c.lease().mine:
        admin = server.client("admin")
        admin.acquire_lease(take_over=True)
        admin.release_lease()
        c.acquire_lease()
    if c.status().state != "idle":
        c.reset().wait(10)
    wait_state(c, lambda s: s.state == "idle")
    return c


def test_kill_9_of_the_api_mid_program_the_machine_goes_on_and_a_jog_stops(server):
    c = operator_with_lease(server)
    c.upload_program("long.ngc", LONG)
    c.load_program("long.ngc").wait(5)
    c.cycle_start()
    before = wait_state(c, lambda s: s.state == "running" and s.machine_position["X"] > 5)
    server.kill_api()
    server.wait_ready()
    c = server.client("viewer")
    after = c.status()
    # on_loss = "continue": the program went on while no API process was there.
    assert after.link.client_losses >= 1
    assert after.state in ("running", "idle") and not after.state == "held"
    assert after.machine_position["X"] != before.machine_position["X"] or after.program_ended
    wait_state(c, lambda s: s.program_ended and s.state == "idle", 60)
    # A continuous jog stops with its API process.
    op = operator_with_lease(server)
    op.jog("X", velocity=20.0)
    wait_state(op, lambda s: s.state == "running")
    server.kill_api()
    server.wait_ready()
    viewer = server.client("viewer")
    s1 = wait_state(viewer, lambda s: s.state == "idle", 10)
    time.sleep(0.3)
    s2 = viewer.status()
    assert s2.state == "idle" and s2.machine_position["X"] == s1.machine_position["X"]


def test_kill_9_of_the_machine_gives_503_then_the_api_attaches_again(server):
    c = server.client("viewer")
    assert c.status().connected
    old = server.machine_pid
    os.kill(old, signal.SIGKILL)
    # Until `rtcnc serve` has a new machine running: 503 with a problem document.
    end = time.monotonic() + 10
    saw_503 = False
    while time.monotonic() < end and not saw_503:
        try:
            c.status()
        except rtcnc.MachineUnavailable as e:
            saw_503 = e.status == 503 and e.code == "machine.unavailable"
        time.sleep(0.02)
    assert saw_503
    server.wait_for(lambda: server.machine_pid != old)
    server.wait_ready()
    s = c.status()
    assert s.connected and s.state in ("estop", "idle")
    kinds = [e.kind for e in c.events(0).events]
    assert "machine_lost" in kinds and kinds.count("machine_attached") >= 2


def test_kill_9_of_the_api_while_it_writes_the_tool_table_leaves_the_old_or_the_new(server):
    folder = server.folder
    table = folder / "sim-mill.tbl"
    op = operator_with_lease(server)
    op.release_lease()
    tables = []
    for kills in range(5):
        setter = server.client("setter")
        n = 20 + kills
        tools = [rtcnc.models.Tool(number=i, pocket=i, offset={"Z": -float(i)}, diameter=float(n))
                 for i in range(1, n)]
        tables.append(n)
        import threading
        stop = threading.Event()

        def hammer():
            while not stop.is_set():
                try:
                    setter.set_tools(tools)
                except Exception:
                    return
        old = table.read_text()
        t = threading.Thread(target=hammer)
        t.start()
        time.sleep(0.05 + 0.03 * kills)
        server.kill_api()
        stop.set()
        t.join(10)
        text = table.read_text()
        if text != old:
            # The new: one write whole, one diameter and every tool of it. (On a loaded
            # machine the kill can come before the first write: the old table stays.)
            parsed = [line for line in text.splitlines() if line.startswith("T")]
            diameters = {float(line.split(" D")[1].split()[0]) for line in parsed if " D" in line}
            assert len(diameters) == 1, text
            d = int(diameters.pop())
            assert d in tables and len(parsed) == d - 1
        server.wait_ready()


@pytest.fixture(scope="module")
def holding_server(tmp_path_factory):
    s = Server(tmp_path_factory.mktemp("serve-hold"), on_loss="hold")
    yield s
    s.stop()


def test_with_on_loss_hold_the_program_holds_when_the_api_dies(holding_server):
    server = holding_server
    c = operator_with_lease(server)
    c.upload_program("long.ngc", LONG)
    c.load_program("long.ngc").wait(5)
    c.cycle_start()
    wait_state(c, lambda s: s.state == "running" and s.machine_position["X"] > 5)
    server.kill_api()
    server.wait_ready()
    viewer = server.client("viewer")
    s = wait_state(viewer, lambda s: s.state == "held", 10)
    assert not s.program_ended and s.link.client_losses >= 1
    x = s.machine_position["X"]
    time.sleep(0.3)
    assert viewer.status().machine_position["X"] == x
