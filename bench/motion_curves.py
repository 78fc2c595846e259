#!/usr/bin/env python3
"""Smooth curves in families, written as 1 µm polylines (G64 P0.001, F6000), for measuring
the path planner on motion along any path (bench/motion-paths.sh), in the style of the peer
harness's paths.py / make_polyline.py: each curve is analytic with exact first and second
derivatives, the vertices lie on the curve and every chord is within 1 µm of it.

  motion_curves.py list                      the curves: name, length, segments
  motion_curves.py write OUT_DIR             one NAME.ngc per curve (plain Python, no numpy)
  motion_curves.py refs DATA.json            toppra's optimum and LinuxCNC 2.9's time of every
                                             curve into DATA.json (needs the peers: run it with
                                             the peers' venv python, ../shared/peers/traj on
                                             the path; LinuxCNC's simulator runs in real time)
  motion_curves.py report DATA.json OURS.tsv the table and the distribution of our times
                                             (OURS.tsv: bench_paths --programs output)

Families (34 curves, all deterministic; the random ones from fixed seeds):
  rose      rhodonea r = R cos(kθ), k = 2..7, 3/2, 5/2: curvature from near 0 at the centre
            to (1 + k²)/R at the petal tips
  epi/hypo  epi- and hypotrochoids, some with small loops (radii of a few mm)
  lissajous x = A sin(a t + δ), y = B sin(b t)
  knot      3-D: trefoil, figure eight, torus knots (2,5), (3,5), (3,7)
  spiral    Archimedean spirals (one from a tight centre), a conical helix
  fourier   random closed 3-D Fourier curves (5 harmonics, seeds 1-4)
  bspline   random closed cubic B-splines through 8-12 control points (seeds 1-4)
"""
import json
import math
import os
import random
import sys

CHORD_TOL = float(os.environ.get("CURVES_CHORD_TOL", "0.001"))
BLEND_TOL = 0.001
FEED = 6000.0


class Trig:
    """Sum of terms c · t^p · cos(w t + φ) per axis (p = 0 or 1): every family but the
    B-splines. Works on floats (math) and on numpy arrays (np)."""

    def __init__(self, name, terms, t_end):
        self.name = name
        self.terms = terms  # [(axis, c, p, w, phi)]
        self.u_end = t_end

    def eval_axes(self, t, order, m):
        out = [t * 0.0, t * 0.0, t * 0.0]
        for axis, c, p, w, phi in self.terms:
            a = w * t + phi
            cs, sn = m.cos(a), m.sin(a)
            if p == 0:
                v = (cs, -w * sn, -w * w * cs)[order]
            else:
                v = (t * cs, cs - w * t * sn, -2.0 * w * sn - w * w * t * cs)[order]
            out[axis] = out[axis] + c * v
        return out


class BSpline:
    """Closed uniform cubic B-spline through control points `ctrl`, t in [0, len(ctrl)]."""

    def __init__(self, name, ctrl):
        self.name = name
        self.ctrl = ctrl
        self.u_end = float(len(ctrl))

    @staticmethod
    def basis(u, order):
        if order == 0:
            return ((1 - u) ** 3 / 6, (3 * u**3 - 6 * u**2 + 4) / 6,
                    (-3 * u**3 + 3 * u**2 + 3 * u + 1) / 6, u**3 / 6)
        if order == 1:
            return (-((1 - u) ** 2) / 2, (3 * u**2 - 4 * u) / 2,
                    (-3 * u**2 + 2 * u + 1) / 2, u**2 / 2)
        return (1 - u, 3 * u - 2, -3 * u + 1, u)

    def point(self, t, order):
        n = len(self.ctrl)
        i = min(int(math.floor(t)), n - 1)
        b = self.basis(t - i, order)
        return [sum(b[k] * self.ctrl[(i + k) % n][ax] for k in range(4)) for ax in range(3)]

    def eval_axes(self, t, order, m):
        if m is math:
            return self.point(t, order)
        return [m.array([self.point(float(x), order)[ax] for x in t]) for ax in range(3)]


def sin_term(axis, c, p, w, phi=0.0):
    return (axis, c, p, w, phi - math.pi / 2)


def cos_term(axis, c, p, w, phi=0.0):
    return (axis, c, p, w, phi)


def rose(k_num, k_den, R=20.0):
    k = k_num / k_den
    # r = R cos(kθ): x = R/2 [cos((k+1)θ) + cos((k-1)θ)], y = R/2 [sin((k+1)θ) - sin((k-1)θ)].
    terms = [cos_term(0, R / 2, 0, k + 1), cos_term(0, R / 2, 0, k - 1),
             sin_term(1, R / 2, 0, k + 1), sin_term(1, -R / 2, 0, k - 1)]
    period = math.pi * k_den if (k_num * k_den) % 2 == 1 else 2 * math.pi * k_den
    name = "rose-%d" % k_num if k_den == 1 else "rose-%d_%d" % (k_num, k_den)
    return Trig(name, terms, period)


def epitrochoid(R, r, d, turns):
    q = (R + r) / r
    terms = [cos_term(0, R + r, 0, 1), cos_term(0, -d, 0, q),
             sin_term(1, R + r, 0, 1), sin_term(1, -d, 0, q)]
    return Trig("epi-%g-%g-%g" % (R, r, d), terms, 2 * math.pi * turns)


def hypotrochoid(R, r, d, turns):
    q = (R - r) / r
    terms = [cos_term(0, R - r, 0, 1), cos_term(0, d, 0, q),
             sin_term(1, R - r, 0, 1), sin_term(1, -d, 0, q)]
    return Trig("hypo-%g-%g-%g" % (R, r, d), terms, 2 * math.pi * turns)


def lissajous(a, b, delta, A=20.0, B=20.0):
    terms = [sin_term(0, A, 0, a, delta), sin_term(1, B, 0, b)]
    return Trig("lissajous-%d-%d" % (a, b), terms, 2 * math.pi)


def torus_knot(p, q, R=15.0, r=5.0):
    # ((R + r cos qt) cos pt, (R + r cos qt) sin pt, r sin qt), products expanded.
    terms = [cos_term(0, R, 0, p), cos_term(0, r / 2, 0, q - p), cos_term(0, r / 2, 0, q + p),
             sin_term(1, R, 0, p), sin_term(1, -r / 2, 0, q - p), sin_term(1, r / 2, 0, q + p),
             sin_term(2, r, 0, q)]
    return Trig("knot-torus-%d-%d" % (p, q), terms, 2 * math.pi)


def trefoil(s=8.0):
    terms = [sin_term(0, s, 0, 1), sin_term(0, 2 * s, 0, 2),
             cos_term(1, s, 0, 1), cos_term(1, -2 * s, 0, 2), sin_term(2, -s, 0, 3)]
    return Trig("knot-trefoil", terms, 2 * math.pi)


def figure_eight(s=8.0):
    # ((2 + cos 2t) cos 3t, (2 + cos 2t) sin 3t, sin 4t) · s
    terms = [cos_term(0, 2 * s, 0, 3), cos_term(0, s / 2, 0, 1), cos_term(0, s / 2, 0, 5),
             sin_term(1, 2 * s, 0, 3), sin_term(1, s / 2, 0, 1), sin_term(1, s / 2, 0, 5),
             sin_term(2, s, 0, 4)]
    return Trig("knot-figure8", terms, 2 * math.pi)


def spiral(name, a, b, turns, rise=0.0):
    # r = a + b t: ((a + b t) cos t, (a + b t) sin t, rise · t)
    terms = [cos_term(0, a, 0, 1), cos_term(0, b, 1, 1), sin_term(1, a, 0, 1), sin_term(1, b, 1, 1)]
    if rise:
        terms.append((2, rise, 1, 0.0, 0.0))
    return Trig(name, terms, 2 * math.pi * turns)


def fourier(seed):
    rng = random.Random(seed)
    terms = []
    for axis in range(3):
        scale = 20.0 if axis < 2 else 5.0
        for n in range(1, 6):
            c = scale * rng.uniform(-1, 1) / n**1.5
            terms.append(cos_term(axis, c, 0, n, rng.uniform(0, 2 * math.pi)))
    return Trig("fourier-%d" % seed, terms, 2 * math.pi)


def bspline(seed):
    rng = random.Random(100 + seed)
    n = rng.randint(8, 12)
    ctrl = [(rng.uniform(-25, 25), rng.uniform(-25, 25), rng.uniform(-5, 5)) for _ in range(n)]
    return BSpline("bspline-%d" % seed, ctrl)


def curves():
    out = [rose(k, 1) for k in (2, 3, 4, 5, 6, 7)] + [rose(3, 2), rose(5, 2)]
    out += [epitrochoid(10, 2, 3, 1), epitrochoid(12, 3, 5, 1), epitrochoid(10, 2, 2.5, 1),
            hypotrochoid(15, 3, 5, 1), hypotrochoid(16, 4, 6, 1), hypotrochoid(10, 2, 2.5, 1)]
    out += [lissajous(1, 2, math.pi / 4), lissajous(3, 2, math.pi / 2),
            lissajous(3, 4, math.pi / 4), lissajous(5, 4, math.pi / 2)]
    out += [trefoil(), figure_eight(), torus_knot(2, 5), torus_knot(3, 5), torus_knot(3, 7)]
    out += [spiral("spiral-archimedes", 1.0, 1.0, 4), spiral("spiral-tight", 0.3, 0.6, 6),
            spiral("spiral-conical", 5.0, 0.5, 4, rise=0.8)]
    out += [fourier(s) for s in (1, 2, 3, 4)] + [bspline(s) for s in (1, 2, 3, 4)]
    return out


# Chords within CHORD_TOL (plain Python, as CAM systems discretise a curve).

def pos(c, t):
    return c.eval_axes(t, 0, math)


def deviation(c, t0, t1, m=16):
    a, b = pos(c, t0), pos(c, t1)
    d = [b[i] - a[i] for i in range(3)]
    l2 = sum(x * x for x in d)
    worst = 0.0
    for k in range(1, m):
        p = pos(c, t0 + (t1 - t0) * k / m)
        w = [p[i] - a[i] for i in range(3)]
        s = max(0.0, min(1.0, sum(w[i] * d[i] for i in range(3)) / l2)) if l2 > 0 else 0.0
        worst = max(worst, math.sqrt(sum((w[i] - s * d[i]) ** 2 for i in range(3))))
    return worst


def step_guess(c, t):
    d1, d2 = c.eval_axes(t, 1, math), c.eval_axes(t, 2, math)
    sp = math.sqrt(sum(x * x for x in d1))
    cr = [d1[1] * d2[2] - d1[2] * d2[1], d1[2] * d2[0] - d1[0] * d2[2], d1[0] * d2[1] - d1[1] * d2[0]]
    kappa = math.sqrt(sum(x * x for x in cr)) / sp**3
    return math.sqrt(8.0 * CHORD_TOL / max(kappa, 1e-9)) / sp


def polyline(c):
    """Parameters of the vertices: each chord the longest within CHORD_TOL (greedy with a
    bracket and bisection)."""
    ts = [0.0]
    t = 0.0
    while t < c.u_end:
        if deviation(c, t, c.u_end) <= CHORD_TOL:
            ts.append(c.u_end)
            break
        hi = min(c.u_end, t + 1.5 * step_guess(c, t))
        lo = t
        while deviation(c, t, hi) <= CHORD_TOL and hi < c.u_end:
            lo, hi = hi, min(c.u_end, t + 2 * (hi - t))
        for _ in range(14):
            mid = 0.5 * (lo + hi)
            if deviation(c, t, mid) <= CHORD_TOL:
                lo = mid
            else:
                hi = mid
        t = lo if lo > t else 0.5 * (t + hi)
        ts.append(t)
    return ts


def program(c):
    ts = polyline(c)
    pts = [pos(c, t) for t in ts]
    length = sum(math.dist(pts[i], pts[i + 1]) for i in range(len(pts) - 1))
    lines = ["(motion_curves.py: %s, %d segments, polyline length %.6f mm)" % (c.name, len(pts) - 1, length),
             "(chord tolerance %g mm; feed 100 mm/s = F%g)" % (CHORD_TOL, FEED),
             "G21 G90 G64 P%g" % BLEND_TOL, "G17",
             "G0 X%.6f Y%.6f Z%.6f" % tuple(pts[0])]
    for i, p in enumerate(pts[1:]):
        lines.append("G1 X%.6f Y%.6f Z%.6f" % tuple(p) + (" F%g" % FEED if i == 0 else ""))
    lines.append("M2")
    return "\n".join(lines) + "\n", len(pts) - 1, length


def cmd_write(out_dir):
    os.makedirs(out_dir, exist_ok=True)
    for c in curves():
        text, _, _ = program(c)
        with open(os.path.join(out_dir, c.name + ".ngc"), "w") as f:
            f.write(text)


class ToppraCurve:
    """A curve through the peers' path interface (numpy arrays)."""

    def __init__(self, c):
        import numpy as np
        self.np = np
        self.c = c
        self.name = c.name
        self.u_end = c.u_end
        self.params = {}

    def eval(self, u, order=0):
        np = self.np
        scalar = np.ndim(u) == 0
        uu = np.atleast_1d(np.asarray(u, dtype=float))
        out = np.stack(self.c.eval_axes(uu, order, np), axis=1)
        return out[0] if scalar else out

    def describe(self):
        return {"path": self.name, "u_range": [0.0, self.u_end]}


def motion_time(samples):
    """First change to last change (> 1e-9 mm) of LinuxCNC's samples, as cam-like.sh."""
    first = last = None
    prev = None
    for t, p in samples:
        if prev is not None and max(abs(a - b) for a, b in zip(p, prev[1])) > 1e-9:
            if first is None:
                first = prev[0]
            last = t
        prev = (t, p)
    return (last - first) if first is not None else float("nan")


def cmd_refs(data_path):
    import csv
    import subprocess
    import tempfile
    import toppra_path  # the peers' harness (../shared/peers/traj on PYTHONPATH)

    peers = os.environ.get("RTCNC_PEERS", os.path.join(os.path.dirname(__file__), "../../shared/peers"))
    run_sim = os.path.join(peers, "linuxcnc/run_sim.sh")
    only = os.environ.get("CURVES_ONLY")
    data = {}
    if os.path.exists(data_path):
        data = json.load(open(data_path))
    work = tempfile.mkdtemp(prefix="motion-curves.")
    for c in curves():
        if only and c.name not in only.split(","):
            continue
        text, segs, length = program(c)
        ngc = os.path.join(work, c.name + ".ngc")
        open(ngc, "w").write(text)
        n = max(8000, int(40 * length))
        r = toppra_path.run_case(ToppraCurve(c), 100.0, 1000.0, 100.0, None, n)
        row = {"segments": segs, "length_mm": round(length, 6),
               "toppra_s": r.get("time_s_richardson"), "toppra_grid_s": r.get("time_s"),
               "toppra_gridpoints": n}
        out = os.path.join(work, "lcnc-" + c.name)
        subprocess.run([run_sim, ngc, "--vel", "100", "--acc", "1000", "--timeout", "300", "--out", out],
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            ok = "result=OK" in open(out + "/run_status.txt").read()
            with open(out + "/samples.csv") as f:
                rd = csv.reader(f)
                next(rd)
                t_lc = motion_time((float(r_[0]), [float(x) for x in r_[1:4]]) for r_ in rd)
            row["linuxcnc_s"] = round(t_lc, 4) if ok else None
        except OSError:
            row["linuxcnc_s"] = None
        data[c.name] = row
        print("%-22s %5d seg %8.2f mm  toppra %.4f s  linuxcnc %s s" % (
            c.name, segs, length, row["toppra_s"] or float("nan"), row["linuxcnc_s"]), flush=True)
        with open(data_path, "w") as f:
            json.dump(data, f, indent=1, sort_keys=True)
            f.write("\n")
    subprocess.run(["rm", "-rf", work])


def cmd_report(data_path, ours_path):
    import statistics
    data = json.load(open(data_path))
    rows = []
    for line in open(ours_path):
        f = line.split()
        if len(f) < 6 or f[0] == "program":
            continue
        name, t, v, a, j, viol = f[0], float(f[1]), float(f[2]), float(f[3]), float(f[4]), int(f[5])
        ref = data.get(name, {})
        tp, lc = ref.get("toppra_s"), ref.get("linuxcnc_s")
        rows.append((name, t, tp, lc, t / tp if tp else float("nan"), t / lc if lc else float("nan"),
                     max(v, a, j), viol))
    print("%-22s %8s %8s %8s %8s %8s %9s %5s" % ("curve", "ours[s]", "toppra", "ours/tp", "lcnc", "ours/lc",
                                                 "vaj/lim", "viol"))
    for r in rows:
        print("%-22s %8.3f %8.3f %8.3f %8.3f %8.3f %9.6f %5d" % (
            r[0], r[1], r[2] or float("nan"), r[4], r[3] or float("nan"), r[5], r[6], r[7]))
    tp = [(r[4], r[0]) for r in rows if not math.isnan(r[4])]
    lc = [(r[5], r[0]) for r in rows if not math.isnan(r[5])]
    if tp:
        w = max(tp)
        print("ours/toppra over %d curves: median %.3f, worst %.3f (%s); %d within 1.05" % (
            len(tp), statistics.median(x for x, _ in tp), w[0], w[1], sum(x <= 1.05 for x, _ in tp)))
    if lc:
        w = max(lc)
        print("ours/LinuxCNC over %d curves: median %.3f, worst %.3f (%s); %d faster" % (
            len(lc), statistics.median(x for x, _ in lc), w[0], w[1], sum(x < 1.0 for x, _ in lc)))
    worst_lim = max(rows, key=lambda r: r[6]) if rows else None
    if worst_lim:
        print("largest |v|, |a| or |j| of any axis over its limit: %.6f (%s); limit violations counted: %d" % (
            worst_lim[6], worst_lim[0], sum(r[7] for r in rows)))


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    cmd = sys.argv[1]
    if cmd == "list":
        for c in curves():
            _, segs, length = program(c)
            print("%-22s %6d segments %9.3f mm" % (c.name, segs, length))
    elif cmd == "write" and len(sys.argv) == 3:
        cmd_write(sys.argv[2])
    elif cmd == "refs" and len(sys.argv) == 3:
        cmd_refs(sys.argv[2])
    elif cmd == "report" and len(sys.argv) == 4:
        cmd_report(sys.argv[2], sys.argv[3])
    else:
        sys.exit(__doc__)


if __name__ == "__main__":
    main()
