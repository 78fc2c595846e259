#!/usr/bin/env python3
"""Generates CAM-like G-code programs in families, for measuring the path planner on the
kind of output CAM systems write (bench/cam-like.sh): dense polylines of 0.1-0.5 mm
segments with many small direction changes, corners, pockets and 3-D rasters, coordinates
rounded to 3 decimals as CAM posts print them.

  cam_like.py OUT_DIR [SEEDS]      (default seeds 1-6; one program per family and seed)

Families (each program some 10-40 s on the benchmark machine):
  contour   closed smooth blobs (random Fourier radii) as polylines at a chord tolerance of
            2-10 µm, two depth passes, G64 P0.01 / P0.02 / plain G64 (any family)
  pocket    a rectangular pocket with rounded corners: offset rings as polylines or G2/G3
            arcs, then a zigzag raster with 90° link corners
  raster    3-D surfacing: z = f(x, y) sampled every 0.2-0.5 mm along X, rows 1 mm apart
            in Y, zigzag
  trochoid  adaptive-clearing-like loops (circles advancing along a line) as polylines of
            0.1-0.3 mm, with G0 links between passes
  engrave   text-like strokes: polylines with sharp corners, plunges and retracts
  zigzag    sawtooth polylines: every vertex turns by the same angle (2-120°, one per row)
            on segments of one length (0.1-2 mm, one per row), five rows per program
"""
import math
import os
import random
import sys


def fmt(v):
    s = "%.3f" % v
    return "0.000" if s == "-0.000" else s


class Prog:
    def __init__(self, title, mode):
        self.lines = ["(%s)" % title, "G21 G90 G17 G40 G49 G80", mode, "G0 Z5.000"]
        self.pos = None

    def g(self, code, x=None, y=None, z=None, f=None, extra=""):
        words = [code]
        for letter, v in (("X", x), ("Y", y), ("Z", z)):
            if v is not None:
                words.append(letter + fmt(v))
        if extra:
            words.append(extra)
        if f is not None:
            words.append("F%.1f" % f)
        self.lines.append(" ".join(words))

    def text(self):
        return "\n".join(self.lines + ["G0 Z5.000", "M2", ""])


def chord_polyline(fn, t0, t1, tol, max_seg):
    """Points of the curve fn(t) on [t0, t1] with chord sagitta <= tol and segments <=
    max_seg (as a CAM system discretises a curve)."""
    pts = [fn(t0)]
    t = t0
    step = (t1 - t0) / 1000.0
    while t < t1:
        h = step * 4
        while True:
            tn = min(t + h, t1)
            a, b, m = fn(t), fn(tn), fn(0.5 * (t + tn))
            chord = math.dist(a, b)
            # distance of the mid point from the chord
            if chord > 0:
                cross = abs((b[0] - a[0]) * (m[1] - a[1]) - (b[1] - a[1]) * (m[0] - a[0])) / chord
            else:
                cross = 0.0
            if (cross <= tol and chord <= max_seg) or h < 1e-9:
                break
            h *= 0.7
        t = tn
        pts.append(fn(t))
    return pts


def mode_for(rng):
    return rng.choice(["G64 P0.01", "G64 P0.02", "G64"])


def contour(rng, seed):
    n = rng.randint(3, 6)
    amps = [rng.uniform(0.05, 0.25) / (k + 1) for k in range(n)]
    phases = [rng.uniform(0, 2 * math.pi) for _ in range(n)]
    r0 = rng.uniform(15, 30)
    cx, cy = 60.0, 50.0
    def fn(t):
        r = r0 * (1 + sum(a * math.sin((k + 2) * t + p) for k, (a, p) in enumerate(zip(amps, phases))))
        return (cx + r * math.cos(t), cy + r * math.sin(t))
    tol = rng.uniform(0.002, 0.01)
    pts = chord_polyline(fn, 0.0, 2 * math.pi, tol, 0.5)
    p = Prog("contour seed %d: %d points, chord tolerance %.4f" % (seed, len(pts), tol), mode_for(rng))
    feed = rng.choice([1000, 1500, 2000, 3000])
    p.g("G0", *pts[0])
    for depth in (-1.0, -2.0):
        p.g("G1", z=depth, f=300)
        for q in pts[1:]:
            p.g("G1", q[0], q[1], f=feed)
    return p


def pocket(rng, seed):
    w, h = rng.uniform(30, 50), rng.uniform(20, 30)
    r = rng.uniform(3, 8)
    step = rng.uniform(2, 4)
    arcs = rng.random() < 0.5
    p = Prog("pocket seed %d: %.1f x %.1f, corner R %.1f, %s" % (seed, w, h, r, "arcs" if arcs else "polylines"), mode_for(rng))
    feed = rng.choice([1200, 1800, 2400])
    x0, y0 = 20.0, 20.0
    p.g("G0", x0 + w / 2, y0 + h / 2)
    p.g("G1", z=-2.0, f=300)
    k = int(min(w, h) / 2 / step) - 1
    for i in range(k, -1, -1):
        off = i * step
        rr = max(r - off, 0.5)
        xa, xb, ya, yb = x0 + off, x0 + w - off, y0 + off, y0 + h - off
        if xb - xa < 2 * rr or yb - ya < 2 * rr:
            continue
        p.g("G1", xa + rr, ya, f=feed)
        corners = [((xb - rr, ya), (xb - rr, ya + rr), (xb, ya + rr), (xb, yb - rr)),
                   ((xb, yb - rr), (xb - rr, yb - rr), (xb - rr, yb), (xa + rr, yb)),
                   ((xa + rr, yb), (xa + rr, yb - rr), (xa, yb - rr), (xa, ya + rr)),
                   ((xa, ya + rr), (xa + rr, ya + rr), (xa + rr, ya), (xa + rr, ya))]
        for (sx, sy), (ccx, ccy), (ex, ey), (nx, ny) in corners:
            p.g("G1", sx, sy, f=feed)
            if arcs:
                p.g("G3", ex, ey, extra="I%s J%s" % (fmt(ccx - sx), fmt(ccy - sy)), f=feed)
            else:
                a0 = math.atan2(sy - ccy, sx - ccx)
                for j in range(1, 9):
                    a = a0 + (math.pi / 2) * j / 8
                    p.g("G1", ccx + rr * math.cos(a), ccy + rr * math.sin(a), f=feed)
            p.g("G1", nx, ny, f=feed)
    # zigzag raster over the floor
    y = y0 + 2
    left = True
    p.g("G0", z=1.0)
    p.g("G0", x0 + 2, y)
    p.g("G1", z=-2.5, f=300)
    while y < y0 + h - 2:
        p.g("G1", (x0 + w - 2) if left else (x0 + 2), y, f=feed)
        y += step
        p.g("G1", y=min(y, y0 + h - 2), f=feed)
        left = not left
    return p


def raster(rng, seed):
    dx = rng.uniform(0.2, 0.5)
    a1, a2 = rng.uniform(1, 4), rng.uniform(1, 4)
    k1, k2 = rng.uniform(0.05, 0.15), rng.uniform(0.05, 0.15)
    def z(x, y):
        return -5 + a1 * math.sin(k1 * x) * math.cos(k2 * y) + a2 * math.exp(-((x - 30) ** 2 + (y - 20) ** 2) / 200)
    p = Prog("raster seed %d: dx %.2f" % (seed, dx), mode_for(rng))
    feed = rng.choice([1500, 2000, 3000])
    y = 0.0
    fwd = True
    xs = [i * dx for i in range(int(60 / dx) + 1)]
    p.g("G0", 0.0, 0.0)
    p.g("G1", z=z(0, 0), f=500)
    while y <= 12.0:
        seq = xs if fwd else xs[::-1]
        for x in seq:
            p.g("G1", x, y, z(x, y), f=feed)
        y += 1.0
        p.g("G1", seq[-1], y, z(seq[-1], y), f=feed)
        fwd = not fwd
    return p


def trochoid(rng, seed):
    rt = rng.uniform(1.5, 4)
    adv = rng.uniform(0.3, 1.0)
    seg = rng.uniform(0.1, 0.3)
    p = Prog("trochoid seed %d: loop R %.2f, advance %.2f, segments %.2f" % (seed, rt, adv, seg), mode_for(rng))
    feed = rng.choice([1500, 2000, 3000])
    n = max(8, int(2 * math.pi * rt / seg))
    x, y = 10.0, 30.0
    p.g("G0", x + rt, y)
    p.g("G1", z=-3.0, f=300)
    for row in range(2):
        for loop in range(int(10 / adv)):
            cx = x + loop * adv
            for j in range(1, n + 1):
                a = 2 * math.pi * j / n
                p.g("G1", cx + rt * math.cos(a) + adv * j / n, y + rt * math.sin(a), f=feed)
        # link to the next row: rapid up, across, down
        p.g("G0", z=1.0)
        y += 2 * rt
        p.g("G0", x + rt, y)
        p.g("G1", z=-3.0, f=300)
    return p


def engrave(rng, seed):
    p = Prog("engrave seed %d" % seed, mode_for(rng))
    feed = rng.choice([600, 900, 1200])
    for stroke in range(6):
        x, y = rng.uniform(10, 100), rng.uniform(10, 60)
        p.g("G0", x, y)
        p.g("G1", z=-0.5, f=200)
        heading = rng.uniform(0, 2 * math.pi)
        for k in range(rng.randint(20, 60)):
            if rng.random() < 0.15:
                heading += rng.choice([-1, 1]) * rng.uniform(0.6, 2.4)   # a sharp corner
            else:
                heading += rng.gauss(0, 0.15)                              # a curve
            l = rng.uniform(0.15, 1.2)
            x += l * math.cos(heading)
            y += l * math.sin(heading)
            p.g("G1", x, y, f=feed)
        p.g("G0", z=2.0)
    return p


def zigzag(rng, seed):
    rows = [(rng.choice([0.1, 0.25, 0.5, 1.0, 2.0]), rng.choice([2, 5, 10, 20, 45, 90, 120]))
            for _ in range(5)]
    p = Prog("zigzag seed %d: segment mm / turn degrees %s" % (
        seed, ", ".join("%g/%d" % r for r in rows)), mode_for(rng))
    feed = rng.choice([1000, 2000, 3000])
    y = 10.0
    for seg, turn_deg in rows:
        turn = math.radians(turn_deg)
        # Alternate headings of ±turn/2 about +X: each vertex turns by `turn`.
        n = max(10, int(40 / (seg * math.cos(turn / 2))))
        x = 10.0
        p.g("G0", x, y)
        p.g("G1", z=-1.0, f=300)
        for k in range(n):
            h = turn / 2 if k % 2 == 0 else -turn / 2
            x += seg * math.cos(h)
            p.g("G1", x, y + (seg * math.sin(turn / 2) if k % 2 == 0 else 0.0), f=feed)
        p.g("G0", z=2.0)
        y += 8.0
    return p


FAMILIES = {"contour": contour, "pocket": pocket, "raster": raster, "trochoid": trochoid, "engrave": engrave, "zigzag": zigzag}


def main():
    out = sys.argv[1]
    seeds = [int(s) for s in sys.argv[2].split(",")] if len(sys.argv) > 2 else range(1, 7)
    os.makedirs(out, exist_ok=True)
    for name, make in FAMILIES.items():
        for seed in seeds:
            rng = random.Random("%s-%d" % (name, seed))
            with open(os.path.join(out, "%s-%d.ngc" % (name, seed)), "w") as f:
                f.write(make(rng, seed).text())


if __name__ == "__main__":
    main()
