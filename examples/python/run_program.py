#!/usr/bin/env python3
"""Runs a program through the API and logs the largest following error of every joint while
it runs (from the WebSocket's status at 50 Hz).

    python3 examples/python/run_program.py http://127.0.0.1:8080 USER PASSWORD examples/bracket.ngc
"""

import asyncio
import sys
from pathlib import Path

import rtcnc


async def main(url: str, user: str, password: str, program: Path) -> None:
    client = rtcnc.AsyncClient(url)
    await client.login(user, password)
    await client.acquire_lease()
    status = await client.status()
    if status.state != "idle":
        await (await client.reset()).wait(10)
    await client.upload_program(program.name, program.read_text())
    await (await client.load_program(program.name)).wait(10)
    worst: dict[str, float] = {}
    started = False
    async for m in client.subscribe(rate_hz=50):
        if m.type == "snapshot":
            await client.cycle_start()
            started = True
        if m.status is None or not started:
            continue
        for j in m.status.joints:
            worst[j.name] = max(worst.get(j.name, 0.0), abs(j.following_error))
        print(f"line {m.status.line:5d}  state {m.status.state:8s}  " +
              "  ".join(f"{j.name} {j.following_error * 1000:+8.3f} um" for j in m.status.joints))
        if m.status.program_ended and m.status.state == "idle":
            break
        if m.status.state in ("fault", "estop"):
            print(f"stopped: {m.status.last_fault}")
            break
    print("largest following error:", ", ".join(f"{k} {v * 1000:.3f} um" for k, v in worst.items()))
    await client.aclose()


if __name__ == "__main__":
    if len(sys.argv) != 5:
        sys.exit(__doc__)
    asyncio.run(main(sys.argv[1], sys.argv[2], sys.argv[3], Path(sys.argv[4])))
