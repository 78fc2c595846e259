#!/usr/bin/env python3
"""Derivation of the polynomial coefficients used in position.rs (step one).

Each family of the up-down-down-up profile is written as a list of constant-jerk phases
whose durations depend on one unknown; the end-position equation becomes a polynomial in
that unknown (the velocity and acceleration equations are satisfied by construction).
Prints the coefficients, divided by the leading one, as Rust expressions.

    python3 -m venv /tmp/sympy && /tmp/sympy/bin/pip install sympy
    /tmp/sympy/bin/python crates/motion/src/otg/derive_polynomials.py

Symbols: a0, v0 start acceleration and velocity; af, vf target ones; pd position
difference; j jerk limit; a_max, a_min acceleration limits. K = 2 j (vf - v0) + a0² - af².
"""
import sympy as sp

a0, v0, vf, af, pd, J, amax, amin, t, h = sp.symbols("a0 v0 vf af pd j a_max a_min t h", real=True)
K = 2 * J * (vf - v0) + a0**2 - af**2


def run(segs):
    """End state after (jerk, duration) phases from (0, v0, a0)."""
    p, v, a = 0, v0, a0
    for jj, d in segs:
        p = p + v * d + a * d**2 / 2 + jj * d**3 / 6
        v = v + a * d + jj * d**2 / 2
        a = a + jj * d
    return p, v, a


def rs_poly(expr):
    expr = sp.expand(expr)
    if expr == 0:
        return "0.0"
    if not expr.free_symbols:
        return f"{float(expr)}"
    poly = sp.Poly(expr, *sorted(expr.free_symbols, key=str))
    terms = []
    for mon, c in poly.terms():
        c = sp.Rational(c)
        factors = [str(s) if k == 1 else f"{s}.powi({k})" for s, k in zip(poly.gens, mon) if k]
        num = f"{float(c.p)}" if c.q == 1 else f"({float(c.p)} / {float(c.q)})"
        terms.append("*".join([num] + factors))
    return " + ".join(terms).replace("+ -", "- ")


def emit(name, expr, var):
    num, _ = sp.fraction(sp.together(sp.expand(expr)))
    poly = sp.Poly(sp.expand(num), var)
    coeffs = poly.all_coeffs()
    print(f"// {name}: degree {poly.degree()} in {var}, divided by {coeffs[0]}")
    for i, c in enumerate(coeffs):
        n, d = sp.fraction(sp.factor(c / coeffs[0]))
        print(f"let c{poly.degree() - i} = ({rs_poly(n)}) / ({rs_poly(d)});")


def check(name, segs):
    _, v, a = run(segs)
    assert sp.simplify(v - vf) == 0 and sp.simplify(a - af) == 0, name


# Both acceleration limits, no cruise: +j to a_max, hold h, -j to a_min, hold h3, +j to af.
C = (K - 2 * amax**2 + 2 * amin**2) / (2 * J)
segs = [(J, (amax - a0) / J), (0, h), (-J, (amax - amin) / J), (0, (C - amax * h) / amin),
        (J, (af - amin) / J)]
check("ACC0_ACC1", segs)
emit("both accelerations (ACC0_ACC1), first hold h", run(segs)[0] - pd, h)

# No limit: +j to a1, -j for t to a3, +j to af; a1 - a3 = j t, a1 + a3 = K / (2 j t).
a1 = (J * t + K / (2 * J * t)) / 2
a3 = a1 - J * t
segs = [(J, (a1 - a0) / J), (-J, t), (J, (af - a3) / J)]
check("NONE", segs)
emit("no limit (NONE), -j ramp time t (times t)", (run(segs)[0] - pd) * t, t)

# Upper limit only: +j to a_max, hold, -j for t to a3, +j to af.
a3 = amax - J * t
segs = [(J, (amax - a0) / J), (0, (K - 2 * amax**2 + 2 * a3**2) / (2 * J * amax)), (-J, t),
        (J, (af - a3) / J)]
check("ACC0", segs)
emit("upper acceleration (ACC0), -j ramp time t", run(segs)[0] - pd, t)

# Lower limit only: +j for t to a1, -j to a_min, hold, +j to af.
a1 = a0 + J * t
segs = [(J, t), (-J, (a1 - amin) / J), (0, (K - 2 * a1**2 + 2 * amin**2) / (2 * J * amin)),
        (J, (af - amin) / J)]
check("ACC1", segs)
emit("lower acceleration (ACC1), first ramp time t", run(segs)[0] - pd, t)
