#!/usr/bin/env python3
"""Jogs Z down until it stands at a given height, then touches off: sets G54 so that the
position reached is the work's Z0 (what an operator does with a paper feeler).

    python3 examples/python/jog_touch_off.py http://127.0.0.1:8080 USER PASSWORD [Z_TARGET]

A setter (or admin) may write the offsets; the jog needs the lease.
"""

import sys
import time

import rtcnc


def main(url: str, user: str, password: str, target: float) -> None:
    c = rtcnc.Client(url)
    c.login(user, password)
    c.acquire_lease()
    if c.status().state != "idle":
        c.reset().wait(10)
    # A continuous jog, kept alive every 100 ms (it stops 200 ms after the last keep-alive).
    # A late keep-alive (a loaded computer) stops the jog: then it starts again.
    deadline = time.monotonic() + 60
    while True:
        s = c.status()
        z = s.machine_position["Z"]
        if abs(z - target) <= 0.5 or time.monotonic() > deadline:
            break
        if s.state == "idle":
            c.jog("Z", velocity=-5.0 if z > target else 5.0)
        else:
            c.jog_keep_alive("Z")
        time.sleep(0.05)
    c.jog_stop("Z")
    while c.status().state != "idle":
        time.sleep(0.05)
    # The last bit as an incremental jog.
    rest = target - c.status().machine_position["Z"]
    c.jog("Z", distance=rest).wait(10)
    z = c.status().machine_position["Z"]
    offsets = {o.system: o for o in c.offsets()}
    g54 = dict(offsets["G54"].offset)
    g54["Z"] = z
    c.set_offset("G54", g54)
    s = c.status()
    print(f"touched off at machine Z {z:.4f}: G54 Z = {g54['Z']:.4f}, work Z now {s.work_position['Z']:.4f}")


if __name__ == "__main__":
    if len(sys.argv) not in (4, 5):
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4]) if len(sys.argv) == 5 else -10.0)
