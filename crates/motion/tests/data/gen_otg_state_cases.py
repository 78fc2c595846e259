#!/usr/bin/env python3
"""Writes otg_state_cases.json: seeded random state-to-state reference cases from ruckig.

Run with the peers' venv (ruckig 0.19.4), from anywhere:
    ~/.cache/rtcnc-peers/venv/bin/python crates/motion/tests/data/gen_otg_state_cases.py

The tests only read the JSON; they never call ruckig. Families of cases:
  inside        start state inside the limits, target at rest
  target_v      non-zero target velocity, target acceleration zero
  target_va     non-zero target velocity and acceleration
  violating     start velocity and/or acceleration outside the limits (brake first)
  asymmetric    min limits different from -max limits
  asym_violating asymmetric limits and a start outside them
  velocity      velocity interface (no position target)
  sync3         three axes, time synchronisation (all finish together)
  sync3_blocked three axes where ruckig's common duration is longer than every axis's
                minimum: an axis's blocked duration interval decides (rare: searched for)
  sync3_period  three axes, duration rounded up to a whole number of control periods
                (ruckig's discrete duration), period in the field "period"
  straight3     three axes with the same limits, phase synchronisation (a straight line),
                from rest or from a velocity and acceleration along the line, to rest
                (in the list "straight3")
  vsync3        three axes, velocity interface, time synchronisation (all reach their
                target velocity and acceleration together; in the list "vsync3")
"""
import json
import math
import os
import random

import ruckig
from ruckig import (ControlInterface, DurationDiscretization, InputParameter, Result, Ruckig,
                    Synchronization, Trajectory)

import argparse

ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
ap.add_argument("--seed", type=int, default=20261122)
ap.add_argument("--scale", type=int, default=1, help="multiply the number of cases (stress runs)")
ap.add_argument("--out", default=None, help="output file (default: otg_state_cases.json here)")
ARGS = ap.parse_args()
SEED = ARGS.seed
rng = random.Random(SEED)


def lu(lo, hi):
    return 10.0 ** rng.uniform(math.log10(lo), math.log10(hi))


def limits(asymmetric=False):
    vmax, amax, jmax = lu(0.5, 50.0), lu(1.0, 100.0), lu(5.0, 1000.0)
    vmin, amin = -vmax, -amax
    if asymmetric:
        vmin, amin = -vmax * lu(0.3, 3.0), -amax * lu(0.3, 3.0)
    return dict(vmax=vmax, vmin=vmin, amax=amax, amin=amin, jmax=jmax)


def target_state(lim, with_v, with_a):
    af = rng.uniform(lim["amin"], lim["amax"]) * 0.9 if with_a else 0.0
    # keep the target reachable: |af|^2 / 2j must leave room inside the velocity limits
    a_reach = 0.9 * math.sqrt(lim["jmax"] * (lim["vmax"] - lim["vmin"]))
    af = max(-a_reach, min(a_reach, af))
    lo, hi = lim["vmin"], lim["vmax"]
    if af > 0:
        lo = lo + af * af / (2 * lim["jmax"])
    if af < 0:
        hi = hi - af * af / (2 * lim["jmax"])
    vf = rng.uniform(lo, hi) * 0.95 if with_v else 0.0
    return vf, af


def start_state(lim, violating):
    if not violating:
        # inside the limits and not bound to break them
        for _ in range(100):
            a0 = rng.uniform(lim["amin"], lim["amax"]) * 0.9
            v0 = rng.uniform(lim["vmin"], lim["vmax"]) * 0.9
            v_at_zero = v0 + a0 * abs(a0) / (2 * lim["jmax"])
            if lim["vmin"] < v_at_zero < lim["vmax"]:
                return v0, a0
        return 0.0, 0.0
    which = rng.choice(["v", "a", "va", "bound"])
    v0 = rng.uniform(lim["vmin"], lim["vmax"]) * 0.9
    a0 = rng.uniform(lim["amin"], lim["amax"]) * 0.9
    if which in ("v", "va"):
        v0 = rng.choice([lim["vmax"], lim["vmin"]]) * rng.uniform(1.05, 2.0)
    if which in ("a", "va"):
        a0 = rng.choice([lim["amax"], lim["amin"]]) * rng.uniform(1.05, 2.0)
    if which == "bound":
        # inside the limits, but accelerating towards the velocity limit too fast to stop
        a0 = lim["amax"] * rng.uniform(0.5, 0.95)
        v0 = lim["vmax"] - a0 * a0 / (2 * lim["jmax"]) * rng.uniform(0.1, 0.9)
    return v0, a0


def calc(n, p0, v0, a0, pf, vf, af, lims, interface=ControlInterface.Position, period=None,
         sync=Synchronization.Time):
    inp = InputParameter(n)
    inp.current_position, inp.current_velocity, inp.current_acceleration = p0, v0, a0
    inp.target_position, inp.target_velocity, inp.target_acceleration = pf, vf, af
    inp.max_velocity = [l["vmax"] for l in lims]
    inp.min_velocity = [l["vmin"] for l in lims]
    inp.max_acceleration = [l["amax"] for l in lims]
    inp.min_acceleration = [l["amin"] for l in lims]
    inp.max_jerk = [l["jmax"] for l in lims]
    inp.control_interface = interface
    inp.synchronization = sync
    if period is not None:
        inp.duration_discretization = DurationDiscretization.Discrete
    tr = Trajectory(n)
    try:
        res = (Ruckig(n, period) if period is not None else Ruckig(n)).calculate(inp, tr)
    except ruckig.RuckigError:
        return None
    if res not in (Result.Working, Result.Finished):
        return None
    return tr


def one_axis(kind):
    lim = limits(asymmetric=kind in ("asymmetric", "asym_violating"))
    v0, a0 = start_state(lim, violating=kind in ("violating", "asym_violating"))
    with_v = kind in ("target_v", "target_va", "asymmetric", "violating", "velocity", "asym_violating")
    with_a = kind in ("target_va", "velocity") or (kind in ("asymmetric", "asym_violating") and rng.random() < 0.5)
    vf, af = target_state(lim, with_v, with_a)
    if kind == "velocity" and rng.random() < 0.3:
        a0 = rng.choice([lim["amax"], lim["amin"]]) * rng.uniform(1.05, 2.0)
    p0 = rng.uniform(-10, 10)
    pf = p0 + rng.choice([-1, 1]) * lu(1e-3, 50.0)
    interface = ControlInterface.Velocity if kind == "velocity" else ControlInterface.Position
    tr = calc(1, [p0], [v0], [a0], [pf], [vf], [af], [lim], interface)
    if tr is None:
        return None
    case = dict(kind=kind, p0=p0, v0=v0, a0=a0, pf=pf, vf=vf, af=af, **lim, duration=tr.duration)
    if kind == "velocity":
        del case["pf"]
    return case


def three_axes(period=None):
    lims = [limits() for _ in range(3)]
    starts = [start_state(l, violating=False) for l in lims]
    targets = [target_state(l, rng.random() < 0.5, rng.random() < 0.3) for l in lims]
    p0 = [rng.uniform(-10, 10) for _ in range(3)]
    pf = [p + rng.choice([-1, 1]) * lu(1e-3, 50.0) for p in p0]
    tr = calc(3, p0, [s[0] for s in starts], [s[1] for s in starts], pf,
              [t[0] for t in targets], [t[1] for t in targets], lims, period=period)
    if tr is None:
        return None
    blocked = tr.duration > max(tr.independent_min_durations) * (1 + 1e-9)
    kind = "sync3_period" if period is not None else "sync3_blocked" if blocked else "sync3"
    return dict(kind=kind, period=period, p0=p0, v0=[s[0] for s in starts], a0=[s[1] for s in starts], pf=pf,
                vf=[t[0] for t in targets], af=[t[1] for t in targets], limits=lims,
                duration=tr.duration, independent_min_durations=list(tr.independent_min_durations))


def straight_axes(moving):
    lim = limits()
    p0 = [rng.uniform(-10, 10) for _ in range(3)]
    d = [rng.choice([-1, 1]) * lu(1e-3, 50.0) * rng.choice([1.0, rng.random()]) for _ in range(3)]
    pf = [p + x for p, x in zip(p0, d)]
    length = math.sqrt(sum(x * x for x in d))
    u = [x / length for x in d]
    umax = max(abs(x) for x in u)
    # along the line: |u_i| * speed within the limits of every axis
    sv = rng.uniform(-0.9, 0.9) * lim["vmax"] / umax if moving else 0.0
    sa = rng.uniform(-0.5, 0.5) * lim["amax"] / umax if moving else 0.0
    # keep the start safe along the line (not bound to break the velocity limit)
    reach = sa * abs(sa) / (2 * lim["jmax"] / umax)
    if abs(sv + reach) > 0.95 * lim["vmax"] / umax:
        sa = 0.0
    v0 = [sv * x for x in u]
    a0 = [sa * x for x in u]
    tr = calc(3, p0, v0, a0, pf, [0.0] * 3, [0.0] * 3, [lim] * 3, sync=Synchronization.Phase)
    if tr is None:
        return None
    return dict(kind="straight3", p0=p0, v0=v0, a0=a0, pf=pf, vf=[0.0] * 3, af=[0.0] * 3,
                limits=[lim] * 3, duration=tr.duration,
                independent_min_durations=list(tr.independent_min_durations))


def velocity_axes():
    lims = [limits() for _ in range(3)]
    starts = []
    for l in lims:
        v0, a0 = start_state(l, violating=False)
        if rng.random() < 0.2:
            a0 = rng.choice([l["amax"], l["amin"]]) * rng.uniform(1.05, 2.0)
        starts.append((v0, a0))
    targets = [target_state(l, True, rng.random() < 0.5) for l in lims]
    z = [0.0] * 3
    tr = calc(3, z, [s[0] for s in starts], [s[1] for s in starts], z, [t[0] for t in targets],
              [t[1] for t in targets], lims, interface=ControlInterface.Velocity)
    if tr is None:
        return None
    return dict(kind="vsync3", v0=[s[0] for s in starts], a0=[s[1] for s in starts],
                vf=[t[0] for t in targets], af=[t[1] for t in targets], limits=lims,
                duration=tr.duration, independent_min_durations=list(tr.independent_min_durations))


def main():
    k = ARGS.scale
    counts = dict(inside=60 * k, target_v=60 * k, target_va=60 * k, violating=60 * k, asymmetric=60 * k,
                  velocity=60 * k, asym_violating=60 * k)
    cases, skipped = [], 0
    for kind, n in counts.items():
        made = 0
        while made < n:
            c = one_axis(kind)
            if c is None:
                skipped += 1
                continue
            cases.append(c)
            made += 1
    sync = []
    while len(sync) < 60 * k:
        c = three_axes()
        if c is None:
            skipped += 1
            continue
        sync.append(c)
    blocked, tries = [], 0
    while len(blocked) < 12 * k and tries < 100000 * k:
        tries += 1
        c = three_axes()
        if c is not None and c["kind"] == "sync3_blocked":
            blocked.append(c)
    sync += blocked
    made = 0
    while made < 12 * k:
        c = three_axes(period=rng.choice([1e-3, 2e-3, 4e-3, 1e-2]))
        if c is not None:
            sync.append(c)
            made += 1
    straight = []
    while len(straight) < 24 * k:
        c = straight_axes(moving=len(straight) % 2 == 1)
        if c is None:
            skipped += 1
            continue
        straight.append(c)
    vsync = []
    while len(vsync) < 24 * k:
        c = velocity_axes()
        if c is None:
            skipped += 1
            continue
        vsync.append(c)
    doc = {
        "tool": "ruckig", "ruckig_version": ruckig.__version__, "seed": SEED,
        "generator": "crates/motion/tests/data/gen_otg_state_cases.py",
        "description": "state-to-state time-optimal jerk-limited profiles (ruckig position and velocity "
                       "interfaces, time synchronisation for sync3); durations in consistent units",
        "skipped_ruckig_errors": skipped,
        "cases": cases,
        "sync3": sync,
        "straight3": straight,
        "vsync3": vsync,
    }
    out = ARGS.out or os.path.join(os.path.dirname(os.path.abspath(__file__)), "otg_state_cases.json")
    with open(out, "w") as f:
        json.dump(doc, f, indent=1)
    print(f"wrote {out}: {len(cases)} single-axis, {len(sync)} three-axis, {len(straight)} straight-line, "
          f"{len(vsync)} velocity-synchronised cases, {skipped} skipped")


if __name__ == "__main__":
    main()
