#!/usr/bin/env python3
"""The API's figures (bench/api.sh runs this): urgent latency in servo periods, REST status
round trip, 100 WebSocket clients at 50 Hz while a program runs at 1 kHz (deadline misses and
worst wake-up latency beside the same run without clients), RSS of both processes."""

from __future__ import annotations

import asyncio
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(REPO / "sdk" / "python" / "tests"))
os.environ.setdefault("RTCNC_BIN", str(REPO / "target" / "release" / "rtcnc"))

import rtcnc  # noqa: E402
import websockets  # noqa: E402
from conftest import Server, wait_state  # noqa: E402

DURATION = float(os.environ.get("API_BENCH_SECONDS", "60"))
CLIENTS = int(os.environ.get("API_BENCH_CLIENTS", "100"))
RATE = float(os.environ.get("API_BENCH_RATE", "50"))

# A program that keeps the machine moving for longer than the measurement.
PROGRAM = "G21 G90 G64 P0.01\n" + "o100 repeat [400]\n  G1 X50 Y0 F3000\n  G1 X50 Y50\n  G2 X0 Y50 I-25 J0\n  G1 X0 Y0\no100 endrepeat\nM2\n"


def pct(values: list[float], p: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, int(round(p / 100 * (len(s) - 1))))]


def rss_kib(pid: int) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    return 0


def operator(server: Server) -> rtcnc.Client:
    c = server.client("operator")
    c.acquire_lease()
    c.reset().wait(10)
    wait_state(c, lambda s: s.state == "idle")
    return c


def timing_summary(c: rtcnc.Client) -> tuple[int, float]:
    t = c.timing()
    rt = [x for x in t.tasks if x.name in ("position control", "drive io", "interpolation", "machine logic",
                                           "look-ahead", "command parsing", "status feedback")]
    return sum(x.deadline_misses for x in rt), max(x.lateness_max_us for x in rt)


def run_program_phase(with_clients: bool) -> dict:
    folder = Path(tempfile.mkdtemp(prefix="rtcnc-api-bench-"))
    server = Server(folder, loose_following_error=False)
    try:
        c = operator(server)
        c.upload_program("bench.ngc", PROGRAM)
        c.load_program("bench.ngc").wait(10)
        misses0, _ = timing_summary(c)
        c.cycle_start()
        wait_state(c, lambda s: s.state == "running")
        received = [0]
        result: dict = {}

        async def ws_client(token: str, stop: float) -> None:
            # Raw messages, not parsed into models: the figure is the server's, not pydantic's.
            url = server.url.replace("http://", "ws://") + f"/api/ws?token={token}"
            async with websockets.connect(url, max_size=2**24) as ws:
                await ws.send(json.dumps({"type": "subscribe", "rate_hz": RATE, "events": True}))
                async for text in ws:
                    if '"type":"status"' in text:
                        received[0] += 1
                    if time.monotonic() > stop:
                        return

        async def clients() -> None:
            stop = time.monotonic() + DURATION
            tokens = [server.client("viewer").token for _ in range(CLIENTS)]
            await asyncio.gather(*(ws_client(t, stop) for t in tokens))

        start = time.monotonic()
        if with_clients:
            rss_probe: list[tuple[int, int]] = []

            async def probe() -> None:
                while time.monotonic() < start + DURATION:
                    await asyncio.sleep(5)
                    rss_probe.append((rss_kib(server.machine_pid), rss_kib(server.api_pid)))

            async def both() -> None:
                await asyncio.gather(clients(), probe())

            asyncio.run(both())
            result["ws_messages_per_s"] = received[0] / DURATION
            result["rss_machine_kib"] = max(r[0] for r in rss_probe)
            result["rss_api_kib"] = max(r[1] for r in rss_probe)
        else:
            time.sleep(DURATION)
            result["rss_machine_kib"] = rss_kib(server.machine_pid)
            result["rss_api_kib"] = rss_kib(server.api_pid)
        s = c.status()
        misses1, worst = timing_summary(c)
        result["still_running"] = s.state == "running"
        result["end_state"] = f"{s.state}" + (f" ({s.last_fault})" if s.last_fault else "")
        result["deadline_misses"] = misses1 - misses0
        result["worst_wakeup_us"] = worst
        c.stop()
        return result
    finally:
        server.stop()


def latency_and_round_trip() -> dict:
    folder = Path(tempfile.mkdtemp(prefix="rtcnc-api-bench-"))
    server = Server(folder)
    try:
        c = operator(server)
        periods, ns = [], []
        for i in range(1000):
            a = c.set_overrides(feed=1.0 if i % 2 else 0.99)[0]
            periods.append(a.latency_periods)
            ns.append(a.latency_ns)
        rtt = []
        for _ in range(2000):
            t0 = time.perf_counter()
            c.status()
            rtt.append((time.perf_counter() - t0) * 1e6)
        return {
            "urgent_periods_p50": pct(periods, 50),
            "urgent_periods_p99": pct(periods, 99),
            "urgent_periods_max": max(periods),
            "urgent_us_p50": pct(ns, 50) / 1e3,
            "urgent_us_p99": pct(ns, 99) / 1e3,
            "urgent_us_max": max(ns) / 1e3,
            "rest_status_us_p50": statistics.median(rtt),
            "rest_status_us_p99": pct(rtt, 99),
        }
    finally:
        server.stop()


def main() -> None:
    a = latency_and_round_trip()
    print("urgent command, API process write -> kernel acting (1 kHz servo period, 1000 samples):")
    print(f"  servo periods  p50 {a['urgent_periods_p50']}  p99 {a['urgent_periods_p99']}  max {a['urgent_periods_max']}"
          "   (1 = read by the next interpolation run)")
    print(f"  microseconds   p50 {a['urgent_us_p50']:.0f}  p99 {a['urgent_us_p99']:.0f}  max {a['urgent_us_max']:.0f}")
    print(f"REST GET /api/status round trip (2000): p50 {a['rest_status_us_p50']:.0f} us  p99 {a['rest_status_us_p99']:.0f} us")
    quiet = run_program_phase(False)
    busy = run_program_phase(True)
    print(f"program at 1 kHz for {DURATION:.0f} s:            deadline misses   worst wake-up   RSS machine   RSS api")
    print(f"  without clients                        {quiet['deadline_misses']:8d}   {quiet['worst_wakeup_us']:10.0f} us"
          f"   {quiet['rss_machine_kib'] / 1024:8.1f} MiB  {quiet['rss_api_kib'] / 1024:6.1f} MiB")
    print(f"  {CLIENTS} WebSocket clients at {RATE:.0f} Hz          {busy['deadline_misses']:8d}   {busy['worst_wakeup_us']:10.0f} us"
          f"   {busy['rss_machine_kib'] / 1024:8.1f} MiB  {busy['rss_api_kib'] / 1024:6.1f} MiB")
    print(f"  status messages received: {busy['ws_messages_per_s']:.0f}/s of {CLIENTS * RATE:.0f}/s asked")
    print(f"  machine state at the end: {quiet['end_state']} / {busy['end_state']}")
    print(f"  load average of this host: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
