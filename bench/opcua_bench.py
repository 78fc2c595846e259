#!/usr/bin/env python3
"""The OPC UA server's figures (bench/opcua.sh runs this): the update rate of a subscription
to X's position while X moves (sampling 1 ms and 10 ms), the latency of a change (a feed override) to an OPC UA client
(p50, p99), and 50 OPC UA clients subscribed while a program runs at 1 kHz beside the same
run without them (deadline misses and worst wake-up of the real-time tasks)."""

from __future__ import annotations

import asyncio
import os
import socket
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(REPO / "sdk" / "python" / "tests"))
os.environ.setdefault("RTCNC_BIN", str(REPO / "target" / "release" / "rtcnc"))

import rtcnc  # noqa: E402
from asyncua import Client, ua  # noqa: E402
from asyncua.crypto.cert_gen import setup_self_signed_certificate  # noqa: E402
from asyncua.crypto.security_policies import SecurityPolicyBasic256Sha256  # noqa: E402
from cryptography.x509.oid import ExtendedKeyUsageOID  # noqa: E402
from conftest import PASSWORDS, Server, machine_file, wait_state  # noqa: E402

DURATION = float(os.environ.get("OPCUA_BENCH_SECONDS", "60"))
CLIENTS = int(os.environ.get("OPCUA_BENCH_CLIENTS", "50"))
PUBLISH_MS = float(os.environ.get("OPCUA_BENCH_PUBLISH_MS", "100"))
CNC = "http://opcfoundation.org/UA/CNC"
APP_URI = "urn:rtcnc:opcua-bench"
PROGRAM = "G21 G90 G64 P0.01\n" + "o100 repeat [400]\n  G1 X50 Y0 F3000\n  G1 X50 Y50\n  G2 X0 Y50 I-25 J0\n  G1 X0 Y0\no100 endrepeat\nM2\n"
TASKS = ("position control", "drive io", "interpolation", "machine logic", "look-ahead", "command parsing",
         "status feedback")


def pct(values: list[float], p: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, int(round(p / 100 * (len(s) - 1))))]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Bench:
    def __init__(self, opcua: bool):
        self.folder = Path(tempfile.mkdtemp(prefix="rtcnc-opcua-bench-"))
        self.port = free_port()
        config = machine_file(self.folder)
        if opcua:
            # Client certificates are admitted without the pki/trusted step here: a bench.
            config.write_text(config.read_text() + f'\n[opcua]\nenabled = true\nlisten = "127.0.0.1:{self.port}"\n'
                              "trust_all_clients = true\n")
        self.server = Server(self.folder, config=config)
        self.url = f"opc.tcp://127.0.0.1:{self.port}/"
        self.key, self.cert = self.folder / "key.pem", self.folder / "cert.der"
        asyncio.run(setup_self_signed_certificate(
            self.key, self.cert, APP_URI, "localhost", [ExtendedKeyUsageOID.CLIENT_AUTH], {"commonName": "bench"}))
        self.op = self.server.client("operator")
        self.op.acquire_lease()
        self.op.reset().wait(10)
        wait_state(self.op, lambda s: s.state == "idle")

    async def client(self) -> Client:
        c = Client(self.url, timeout=30)
        c.application_uri = APP_URI
        c.set_user("viewer")
        c.set_password(PASSWORDS["viewer"][1])
        await c.set_security(SecurityPolicyBasic256Sha256, str(self.cert), str(self.key),
                             mode=ua.MessageSecurityMode.SignAndEncrypt)
        await c.connect()
        return c

    def stop(self) -> None:
        self.server.stop()


async def node(c: Client, *path: str):
    ns = await c.get_namespace_index(CNC)
    return await c.nodes.objects.get_child([f"{ns}:{p}" for p in path])


class Notes:
    def __init__(self):
        self.items: list[tuple[float, float, object]] = []

    def datachange_notification(self, node, val, data):
        self.items.append((time.monotonic(), time.time(), val, data.monitored_item.Value.SourceTimestamp))


def rate_and_latency(b: Bench) -> dict:
    async def run() -> dict:
        c = await b.client()
        try:
            # Update rate: X's position while it moves, sampled every 1 ms and every 10 ms
            # (published every 10 ms): distinct values per second of source time.
            rates = {}
            for sampling_ms in (1, 10):
                notes = Notes()
                sub = await c.create_subscription(10, notes)
                await sub.subscribe_data_change(
                    await node(c, "CncInterface", "CncAxisList", "X", "PosIndirect", "ActPos"),
                    sampling_interval=sampling_ms, queuesize=100)
                await asyncio.sleep(0.5)
                # 200 mm at X's 100 mm/s from either end: about 2 s of motion; the middle
                # 1.5 s is counted.
                target = 200 if sampling_ms == 1 else 0
                await asyncio.to_thread(b.op.mdi, f"G1 X{target} F6000")
                await asyncio.sleep(0.3)
                t0 = time.time()
                await asyncio.sleep(1.7)
                moving = {n[2] for n in notes.items if t0 < n[3].timestamp() <= t0 + 1.5}
                rates[sampling_ms] = len(moving) / 1.5
                await asyncio.to_thread(wait_state, b.op, lambda s: s.state == "idle")
                await sub.delete()
            # Latency: a feed override set over the API until the client has the new value.
            notes = Notes()
            # Sampled every 1 ms: the server reads the machine's snapshot itself.
            sub = await c.create_subscription(10, notes)
            await sub.subscribe_data_change(await node(c, "CncInterface", "CncChannelList", "Channel1", "ActOverride"),
                                            sampling_interval=1)
            await asyncio.sleep(0.5)
            end_to_end, from_source, lost = [], [], 0
            for i in range(200):
                value = 90.0 + (i % 2)
                start = time.monotonic()
                await asyncio.to_thread(b.op.set_overrides, feed=value / 100)
                while not any(n[2] == value and n[0] >= start for n in notes.items):
                    if time.monotonic() - start > 2.0:
                        break
                    await asyncio.sleep(0.0005)
                got = next((n for n in notes.items if n[2] == value and n[0] >= start), None)
                if got is None:
                    lost += 1
                    continue
                end_to_end.append((got[0] - start) * 1e3)
                from_source.append((got[1] - got[3].timestamp()) * 1e3)
                notes.items.clear()
            await sub.delete()
            return {"rates": rates, "e2e": end_to_end, "src": from_source, "lost": lost}
        finally:
            await c.disconnect()

    return asyncio.run(run())


def timing(c: rtcnc.Client) -> tuple[int, float]:
    t = c.timing()
    rt = [x for x in t.tasks if x.name in TASKS]
    return sum(x.deadline_misses for x in rt), max(x.lateness_max_us for x in rt)


def program_phase(b: Bench, clients: int) -> dict:
    b.op.upload_program("bench.ngc", PROGRAM)
    b.op.load_program("bench.ngc").wait(10)
    received = [0]

    failed = [0]

    async def one(stop_at: float) -> None:
        try:
            await session(stop_at)
        except Exception as e:  # noqa: BLE001 - counted: a client the server could not keep
            failed[0] += 1
            print(f"  a client failed: {e!r}", file=sys.stderr)

    async def session(stop_at: float) -> None:
        c = await b.client()
        try:
            class H:
                def datachange_notification(self, node, val, data):
                    received[0] += 1
            sub = await c.create_subscription(PUBLISH_MS, H())
            for path in (("CncAxisList", "X", "PosIndirect", "ActPos"), ("CncAxisList", "Y", "PosIndirect", "ActPos"),
                         ("CncChannelList", "Channel1", "ActOverride")):
                await sub.subscribe_data_change(await node(c, "CncInterface", *path), sampling_interval=10)
            while time.monotonic() < stop_at:
                await asyncio.sleep(0.5)
        finally:
            await c.disconnect()

    async def all_clients(stop_at: float) -> float:
        t = time.monotonic()
        tasks = [asyncio.create_task(one(stop_at)) for _ in range(clients)]
        await asyncio.gather(*tasks)
        return time.monotonic() - t

    misses0, _ = timing(b.op)
    b.op.cycle_start()
    wait_state(b.op, lambda s: s.state == "running")
    if clients:
        asyncio.run(all_clients(time.monotonic() + DURATION))
    else:
        time.sleep(DURATION)
    s = b.op.status()
    misses1, worst = timing(b.op)
    b.op.stop()
    wait_state(b.op, lambda s: s.state == "idle")
    return {"misses": misses1 - misses0, "worst_us": worst, "state": s.state + (f" ({s.last_fault})" if s.last_fault else ""),
            "notifications_per_s": received[0] / DURATION, "failed": failed[0]}


def main() -> None:
    b = Bench(opcua=True)
    try:
        r = rate_and_latency(b)
    finally:
        b.stop()
    print("OPC UA subscription to X's position while it moves (publishing 10 ms), distinct values/s:")
    print(f"  sampling  1 ms: {r['rates'][1]:.0f}/s (the machine's trace has a sample every servo period)")
    print(f"  sampling 10 ms: {r['rates'][10]:.0f}/s (the API's status comes at 100/s)")
    print(f"  ratio 1 ms / 10 ms: {r['rates'][1] / max(r['rates'][10], 1e-9):.1f}")
    print(f"feed override set over the API -> the OPC UA client has the new ActOverride (sampling 1 ms, publishing 10 ms) "
          f"({len(r['e2e'])} samples, {r['lost']} not seen within 2 s):")
    print(f"  end to end        p50 {pct(r['e2e'], 50):.1f} ms  p99 {pct(r['e2e'], 99):.1f} ms  max {max(r['e2e']):.1f} ms")
    print(f"  from the value's source timestamp (the machine's snapshot) p50 {pct(r['src'], 50):.1f} ms"
          f"  p99 {pct(r['src'], 99):.1f} ms")
    # Each run in processes of its own (the OPC UA server on in both), so each run's worst
    # wake-up is its own.
    phases = []
    for clients in (0, CLIENTS):
        b = Bench(opcua=True)
        try:
            phases.append(program_phase(b, clients))
        finally:
            b.stop()
    quiet, busy = phases
    print(f"program at 1 kHz for {DURATION:.0f} s:                         deadline misses   worst wake-up   end state")
    print(f"  without OPC UA clients                             {quiet['misses']:8d}   {quiet['worst_us']:10.0f} us   {quiet['state']}")
    print(f"  {CLIENTS} clients (Basic256Sha256, 3 items, {PUBLISH_MS:.0f} ms)       {busy['misses']:8d}"
          f"   {busy['worst_us']:10.0f} us   {busy['state']}")
    print(f"  notifications received: {busy['notifications_per_s']:.0f}/s; clients that failed: {busy['failed']}")
    print(f"  load average of this host: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
