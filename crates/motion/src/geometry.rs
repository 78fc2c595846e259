//! Path pieces with analytic evaluation: lines, helices (arcs are helices without rise) and
//! polynomial curves (corner blends and smoothing spans). Every piece is evaluated at its
//! arc length `s` (9-axis Euclidean length) through an exact map for lines and helices and a
//! tabulated monotone map for polynomial curves; the set-point is always exactly on the
//! curve, only the speed along it depends on the map.

use crate::axes::{AXES, AxisVec, add_scaled, dot, norm, scale};

/// Value and first three derivatives with respect to the piece's own parameter.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Deriv {
    pub p: AxisVec,
    pub d1: AxisVec,
    pub d2: AxisVec,
    pub d3: AxisVec,
}

/// Shape of one piece.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Shape {
    /// `start + dir * u`, u in [0, len] (dir unit).
    Line { start: AxisVec, dir: AxisVec },
    /// Helix/arc; u in [0, 1].
    Helix(Helix),
    /// Polynomial `sum c[k] u^k`, u in [0, 1], degree ≤ 5.
    Poly { c: [AxisVec; 6] },
}

/// Arc or helix around `centre` (in the plane of the start point), from `e1` towards `e2`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Helix {
    pub centre: [f64; 3],
    pub e1: [f64; 3],
    pub e2: [f64; 3],
    pub n: [f64; 3],
    pub r0: f64,
    pub dr: f64,
    pub sweep: f64,
    pub rise: f64,
    /// Start of the axes A..W (indices 3..9) and their change.
    pub other0: AxisVec,
    pub other_delta: AxisVec,
}

impl Shape {
    pub fn eval(&self, u: f64) -> Deriv {
        match self {
            Shape::Line { start, dir } => Deriv {
                p: add_scaled(start, dir, u),
                d1: *dir,
                d2: [0.0; AXES],
                d3: [0.0; AXES],
            },
            Shape::Helix(h) => h.eval(u),
            Shape::Poly { c } => {
                let mut d = Deriv::default();
                for i in 0..AXES {
                    let (c0, c1, c2, c3, c4, c5) =
                        (c[0][i], c[1][i], c[2][i], c[3][i], c[4][i], c[5][i]);
                    // An axis the curve does not move (most of the nine): its value, and
                    // derivatives of exactly zero.
                    if c1 == 0.0 && c2 == 0.0 && c3 == 0.0 && c4 == 0.0 && c5 == 0.0 {
                        d.p[i] = c0;
                        continue;
                    }
                    d.p[i] = c0 + u * (c1 + u * (c2 + u * (c3 + u * (c4 + u * c5))));
                    d.d1[i] = c1 + u * (2.0 * c2 + u * (3.0 * c3 + u * (4.0 * c4 + u * 5.0 * c5)));
                    d.d2[i] = 2.0 * c2 + u * (6.0 * c3 + u * (12.0 * c4 + u * 20.0 * c5));
                    d.d3[i] = 6.0 * c3 + u * (24.0 * c4 + u * 60.0 * c5);
                }
                d
            }
        }
    }

    /// Axes the shape moves, one bit each: for a polynomial those with a coefficient of
    /// degree one or more that is not zero, the others all nine.
    pub fn moving_axes(&self) -> u16 {
        match self {
            Shape::Poly { c } => (0..AXES)
                .filter(|i| (1..6).any(|k| c[k][*i] != 0.0))
                .fold(0, |m, i| m | 1 << i),
            _ => (1 << AXES) - 1,
        }
    }

    /// `eval` that visits only the axes in `moving` (from [`Shape::moving_axes`]): the
    /// same numbers (the others keep their value with derivatives of exactly zero).
    #[inline]
    pub fn eval_axes(&self, u: f64, moving: u16) -> Deriv {
        let Shape::Poly { c } = self else {
            return self.eval(u);
        };
        let mut d = Deriv::default();
        for i in 0..AXES {
            d.p[i] = c[0][i];
        }
        let mut m = moving;
        while m != 0 {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            let (c0, c1, c2, c3, c4, c5) = (c[0][i], c[1][i], c[2][i], c[3][i], c[4][i], c[5][i]);
            d.p[i] = c0 + u * (c1 + u * (c2 + u * (c3 + u * (c4 + u * c5))));
            d.d1[i] = c1 + u * (2.0 * c2 + u * (3.0 * c3 + u * (4.0 * c4 + u * 5.0 * c5)));
            d.d2[i] = 2.0 * c2 + u * (6.0 * c3 + u * (12.0 * c4 + u * 20.0 * c5));
            d.d3[i] = 6.0 * c3 + u * (24.0 * c4 + u * 60.0 * c5);
        }
        d
    }

    /// Position only (cheaper).
    pub fn pos(&self, u: f64) -> AxisVec {
        match self {
            Shape::Line { start, dir } => add_scaled(start, dir, u),
            Shape::Helix(h) => h.pos(u),
            Shape::Poly { c } => {
                let mut p = [0.0; AXES];
                for i in 0..AXES {
                    p[i] = c[0][i]
                        + u * (c[1][i]
                            + u * (c[2][i] + u * (c[3][i] + u * (c[4][i] + u * c[5][i]))));
                }
                p
            }
        }
    }

    /// Speed |dp/du|.
    pub fn speed(&self, u: f64) -> f64 {
        match self {
            // The first derivative only (the arc-length tables call this most).
            Shape::Poly { c } => {
                let mut s2 = 0.0;
                for i in 0..AXES {
                    let (c1, c2, c3, c4, c5) = (c[1][i], c[2][i], c[3][i], c[4][i], c[5][i]);
                    let d = c1 + u * (2.0 * c2 + u * (3.0 * c3 + u * (4.0 * c4 + u * 5.0 * c5)));
                    s2 += d * d;
                }
                s2.sqrt()
            }
            _ => norm(&self.eval(u).d1),
        }
    }

    /// `speed` prepared for many evaluations (the arc-length tables).
    fn speed_fn(&self) -> SpeedFn<'_> {
        match self {
            Shape::Poly { c } => SpeedFn::Poly(PolySpeed::new(c)),
            _ => SpeedFn::Other(self),
        }
    }
}

/// Parametric speed of one shape, evaluated many times (a local, never moved).
#[allow(clippy::large_enum_variant)]
enum SpeedFn<'a> {
    Poly(PolySpeed),
    Other(&'a Shape),
}

impl SpeedFn<'_> {
    #[inline]
    fn at(&self, u: f64) -> f64 {
        match self {
            SpeedFn::Poly(p) => p.at(u),
            SpeedFn::Other(s) => s.speed(u),
        }
    }

    /// `out[k] = self.at(us[k])`, the same values; for polynomials axis by axis over all
    /// the parameters, independent chains the processor overlaps.
    fn fill<const N: usize>(&self, us: &[f64; N], out: &mut [f64; N]) {
        match self {
            SpeedFn::Poly(p) => {
                let mut s2 = [0.0f64; N];
                for &[c1, c2, c3, c4, c5] in &p.c[..p.n] {
                    for (acc, &u) in s2.iter_mut().zip(us) {
                        let d =
                            c1 + u * (2.0 * c2 + u * (3.0 * c3 + u * (4.0 * c4 + u * 5.0 * c5)));
                        *acc += d * d;
                    }
                }
                for (o, x) in out.iter_mut().zip(s2) {
                    *o = x.sqrt();
                }
            }
            SpeedFn::Other(s) => {
                for (o, &u) in out.iter_mut().zip(us) {
                    *o = s.speed(u);
                }
            }
        }
    }
}

/// |dp/du| of a polynomial shape over the axes it moves along only. An axis whose
/// derivative coefficients are all zero adds exactly 0 to the sum of squares, so the value
/// is bit for bit that of `Shape::speed` (same operations, same order), at the cost of the
/// moving axes (two or three of the nine on most paths).
struct PolySpeed {
    /// Derivative coefficients c1..c5 of each moving axis, in axis order.
    c: [[f64; 5]; AXES],
    n: usize,
}

impl PolySpeed {
    fn new(c: &[AxisVec; 6]) -> PolySpeed {
        let mut d = [[0.0; 5]; AXES];
        let mut n = 0;
        for i in 0..AXES {
            let ci = [c[1][i], c[2][i], c[3][i], c[4][i], c[5][i]];
            if ci.iter().any(|&x| x != 0.0) {
                d[n] = ci;
                n += 1;
            }
        }
        PolySpeed { c: d, n }
    }

    #[inline]
    fn at(&self, u: f64) -> f64 {
        let mut s2 = 0.0;
        for &[c1, c2, c3, c4, c5] in &self.c[..self.n] {
            let d = c1 + u * (2.0 * c2 + u * (3.0 * c3 + u * (4.0 * c4 + u * 5.0 * c5)));
            s2 += d * d;
        }
        s2.sqrt()
    }
}

impl Helix {
    /// The part of this helix between parameters `u0` and `u1`, as a helix of its own
    /// (parameter 0..1): the same exact curve, trimmed by angle.
    pub fn sub(&self, u0: f64, u1: f64) -> Helix {
        let (s, c) = (self.sweep * u0).sin_cos();
        let du = u1 - u0;
        let mut h = *self;
        for i in 0..3 {
            h.e1[i] = c * self.e1[i] + s * self.e2[i];
            h.e2[i] = -s * self.e1[i] + c * self.e2[i];
            h.centre[i] = self.centre[i] + self.rise * u0 * self.n[i];
        }
        h.r0 = self.r0 + self.dr * u0;
        h.dr = self.dr * du;
        h.sweep = self.sweep * du;
        h.rise = self.rise * du;
        for i in 3..AXES {
            h.other0[i] = self.other0[i] + self.other_delta[i] * u0;
            h.other_delta[i] = self.other_delta[i] * du;
        }
        h
    }

    fn pos(&self, u: f64) -> AxisVec {
        let (s, c) = (self.sweep * u).sin_cos();
        let r = self.r0 + self.dr * u;
        let mut p = [0.0; AXES];
        for i in 0..3 {
            p[i] =
                self.centre[i] + r * (c * self.e1[i] + s * self.e2[i]) + self.rise * u * self.n[i];
        }
        for i in 3..AXES {
            p[i] = self.other0[i] + self.other_delta[i] * u;
        }
        p
    }

    fn eval(&self, u: f64) -> Deriv {
        let th = self.sweep * u;
        let (s, c) = th.sin_cos();
        let r = self.r0 + self.dr * u;
        let sw = self.sweep;
        let mut d = Deriv::default();
        for i in 0..3 {
            let radial = c * self.e1[i] + s * self.e2[i];
            let tang = -s * self.e1[i] + c * self.e2[i];
            d.p[i] = self.centre[i] + r * radial + self.rise * u * self.n[i];
            d.d1[i] = self.dr * radial + r * sw * tang + self.rise * self.n[i];
            d.d2[i] = 2.0 * self.dr * sw * tang - r * sw * sw * radial;
            d.d3[i] = -3.0 * self.dr * sw * sw * radial - r * sw * sw * sw * tang;
        }
        for i in 3..AXES {
            d.p[i] = self.other0[i] + self.other_delta[i] * u;
            d.d1[i] = self.other_delta[i];
        }
        d
    }
}

/// Number of intervals of the arc-length table of curved pieces.
pub(crate) const MAP_N: usize = 8;

/// Map from arc length to the shape parameter.
// Pieces are plain data in a preallocated ring: no boxing of the larger table.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Copy)]
pub(crate) enum ArcMap {
    /// u = s * k.
    Linear { k: f64 },
    /// Nodes at uniform u (`u_k = k / MAP_N`) with their arc length and du/ds; between nodes
    /// u(s) is the cubic Hermite interpolant (monotone for the smooth, regular pieces used).
    Table {
        s: [f64; MAP_N + 1],
        duds: [f64; MAP_N + 1],
    },
    /// Finer nodes `u_k`, placed where the parametric speed changes (equal steps of
    /// u + |Δ ln |dp/du||), with their arc length, du/ds and d²u/ds²; between nodes u(s) is
    /// the quintic Hermite interpolant, so the path speed, acceleration and jerk the map
    /// implies are continuous (spline pieces, whose parametric speed varies much more than
    /// that of blends).
    Quintic {
        u: [f64; MAP_FINE_N + 1],
        s: [f64; MAP_FINE_N + 1],
        duds: [f64; MAP_FINE_N + 1],
        d2uds2: [f64; MAP_FINE_N + 1],
    },
}

/// Number of intervals of the quintic arc-length table.
pub(crate) const MAP_FINE_N: usize = 32;

/// Three-point Gauss-Legendre on [0, 1].
const GL_X: [f64; 3] = [0.112_701_665_379_258_31, 0.5, 0.887_298_334_620_741_7];
const GL_W: [f64; 3] = [5.0 / 18.0, 8.0 / 18.0, 5.0 / 18.0];

impl ArcMap {
    /// Builds the table of a curved shape over u in [0, 1]; returns it with the total length.
    pub fn table(shape: &Shape) -> (ArcMap, f64) {
        let mut s = [0.0; MAP_N + 1];
        let mut duds = [0.0; MAP_N + 1];
        let h = 1.0 / MAP_N as f64;
        // The parametric speed at the nodes and at the Gauss points of each interval (the
        // parameters computed once, at compile time, with the same operations).
        const NU: usize = 4 * MAP_N + 1;
        const US: [f64; NU] = {
            let h = 1.0 / MAP_N as f64;
            let mut us = [0.0; NU];
            let mut k = 0;
            while k <= MAP_N {
                us[k] = k as f64 * h;
                if k > 0 {
                    let u0 = (k - 1) as f64 * h;
                    let mut g = 0;
                    while g < 3 {
                        us[MAP_N + 1 + 3 * (k - 1) + g] = u0 + GL_X[g] * h;
                        g += 1;
                    }
                }
                k += 1;
            }
            us
        };
        let mut sp = [0.0; NU];
        shape.speed_fn().fill(&US, &mut sp);
        for k in 0..=MAP_N {
            duds[k] = if sp[k] > 0.0 { 1.0 / sp[k] } else { 0.0 };
            if k > 0 {
                let mut acc = 0.0;
                for g in 0..3 {
                    acc += GL_W[g] * sp[MAP_N + 1 + 3 * (k - 1) + g];
                }
                s[k] = s[k - 1] + acc * h;
            }
        }
        let len = s[MAP_N];
        (ArcMap::Table { s, duds }, len)
    }

    /// Builds the quintic table of a regular curved shape over u in [0, 1] (its parametric
    /// speed must not vanish); returns it with the total length.
    pub fn quintic_table(shape: &Shape) -> (ArcMap, f64) {
        // Node placement: equal steps of u + |Δ ln σ| on a fine grid (σ = |dp/du|), so
        // that nodes gather where du/ds = 1/σ changes fast.
        const FINE: usize = 8 * MAP_FINE_N;
        let mut cum = [0.0; FINE + 1];
        // (Spline pieces are regular: the floor only keeps a degenerate shape finite.)
        let speed = shape.speed_fn();
        let mut sp = [0.0; FINE + 1];
        {
            let mut us = [0.0; FINE + 1];
            for (k, u) in us.iter_mut().enumerate() {
                *u = k as f64 / FINE as f64;
            }
            speed.fill(&us, &mut sp);
        }
        let log_speed = |k: usize| sp[k].max(1e-300).ln();
        let mut prev = log_speed(0);
        for k in 1..=FINE {
            let ls = log_speed(k);
            cum[k] = cum[k - 1] + 1.0 / FINE as f64 + (ls - prev).abs();
            prev = ls;
        }
        let mut u = [1.0; MAP_FINE_N + 1];
        u[0] = 0.0;
        let mut j = 0;
        for k in 1..MAP_FINE_N {
            let target = cum[FINE] * k as f64 / MAP_FINE_N as f64;
            while j < FINE && cum[j + 1] < target {
                j += 1;
            }
            let span = cum[j + 1] - cum[j];
            let f = if span > 0.0 {
                (target - cum[j]) / span
            } else {
                0.0
            };
            u[k] = (j as f64 + f) / FINE as f64;
        }
        let mut s = [0.0; MAP_FINE_N + 1];
        let mut duds = [0.0; MAP_FINE_N + 1];
        let mut d2uds2 = [0.0; MAP_FINE_N + 1];
        for k in 0..=MAP_FINE_N {
            let d = shape.eval(u[k]);
            let sig = norm(&d.d1);
            if sig > 0.0 {
                let sig_u = dot(&d.d1, &d.d2) / sig;
                duds[k] = 1.0 / sig;
                d2uds2[k] = -sig_u / (sig * sig * sig);
            }
            if k > 0 {
                // Two three-point Gauss-Legendre halves per interval.
                let (u0, h) = (u[k - 1], u[k] - u[k - 1]);
                let mut acc = 0.0;
                for half in 0..2 {
                    for g in 0..3 {
                        acc += GL_W[g] * speed.at(u0 + (half as f64 + GL_X[g]) * 0.5 * h);
                    }
                }
                s[k] = s[k - 1] + acc * 0.5 * h;
            }
        }
        let len = s[MAP_FINE_N];
        (ArcMap::Quintic { u, s, duds, d2uds2 }, len)
    }

    /// Shape parameter at arc length `s_q` (clamped to the piece).
    #[inline]
    pub fn u(&self, s_q: f64) -> f64 {
        match self {
            ArcMap::Linear { k } => s_q * k,
            ArcMap::Table { s, duds } => {
                let h = 1.0 / MAP_N as f64;
                let mut k = 0;
                while k + 1 < MAP_N && s_q > s[k + 1] {
                    k += 1;
                }
                let ds = s[k + 1] - s[k];
                if ds <= 0.0 {
                    return k as f64 * h;
                }
                let t = ((s_q - s[k]) / ds).clamp(0.0, 1.0);
                let (m0, m1) = (duds[k] * ds / h, duds[k + 1] * ds / h);
                let t2 = t * t;
                let t3 = t2 * t;
                let frac = (-2.0 * t3 + 3.0 * t2) + m0 * (t3 - 2.0 * t2 + t) + m1 * (t3 - t2);
                (k as f64 + frac) * h
            }
            ArcMap::Quintic { u, s, duds, d2uds2 } => {
                // Binary search of the interval holding s_q.
                let (mut lo, mut hi) = (0, MAP_FINE_N);
                while hi - lo > 1 {
                    let mid = (lo + hi) / 2;
                    if s_q > s[mid] {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                let k = lo;
                let ds = s[k + 1] - s[k];
                if ds <= 0.0 {
                    return u[k];
                }
                let t = ((s_q - s[k]) / ds).clamp(0.0, 1.0);
                let (t2, t3) = (t * t, t * t * t);
                let (t4, t5) = (t3 * t, t3 * t2);
                let h1 = t - 6.0 * t3 + 8.0 * t4 - 3.0 * t5;
                let h2 = 0.5 * (t2 - 3.0 * t3 + 3.0 * t4 - t5);
                let h3 = 10.0 * t3 - 15.0 * t4 + 6.0 * t5;
                let h4 = -4.0 * t3 + 7.0 * t4 - 3.0 * t5;
                let h5 = 0.5 * (t3 - 2.0 * t4 + t5);
                let du = h1 * ds * duds[k]
                    + h2 * ds * ds * d2uds2[k]
                    + h3 * (u[k + 1] - u[k])
                    + h4 * ds * duds[k + 1]
                    + h5 * ds * ds * d2uds2[k + 1];
                u[k] + du
            }
        }
    }
}

/// Derivatives with respect to arc length: tangent T, curvature vector K = d²p/ds², and
/// dK/ds, from derivatives with respect to any regular parameter.
pub(crate) fn arc_derivs(d: &Deriv) -> (AxisVec, AxisVec, AxisVec) {
    let sig2 = dot(&d.d1, &d.d1);
    let sig = sig2.sqrt();
    if !(sig > 0.0) {
        return ([0.0; AXES], [0.0; AXES], [0.0; AXES]);
    }
    let sig_u = dot(&d.d1, &d.d2) / sig;
    let sig_uu = (dot(&d.d2, &d.d2) + dot(&d.d1, &d.d3)) / sig - sig_u * sig_u / sig;
    let u1 = 1.0 / sig;
    let u2 = -sig_u / (sig2 * sig);
    let u3 = -sig_uu / (sig2 * sig2) + 3.0 * sig_u * sig_u / (sig2 * sig2 * sig);
    let mut t = [0.0; AXES];
    let mut k = [0.0; AXES];
    let mut kp = [0.0; AXES];
    for i in 0..AXES {
        t[i] = d.d1[i] * u1;
        k[i] = d.d2[i] * u1 * u1 + d.d1[i] * u2;
        kp[i] = d.d3[i] * u1 * u1 * u1 + 3.0 * d.d2[i] * u1 * u2 + d.d1[i] * u3;
    }
    (t, k, kp)
}

/// The axes a polynomial moves along (some derivative coefficient non-zero), in axis
/// order, and how many: on the others every derivative is exactly zero.
pub(crate) fn poly_moving_axes(c: &[AxisVec; 6]) -> ([usize; AXES], usize) {
    let mut axes = [0; AXES];
    let mut n = 0;
    for i in 0..AXES {
        if (1..6).any(|k| c[k][i] != 0.0) {
            axes[n] = i;
            n += 1;
        }
    }
    (axes, n)
}

/// `arc_derivs(&Shape::Poly { c }.eval(u))` over the moving axes `axes` of the polynomial
/// (from [`poly_moving_axes`]), written to `t`, `k`, `kp`, bit for bit: the other axes add
/// exact zeros to the sums (in the same order) and their T, K and dK/ds are +0, as
/// `arc_derivs` gives them. False, with the outputs unspecified, in the degenerate case
/// where the parameter derivatives overflow (there the full evaluation gives NaN on the
/// still axes): the caller then takes the full path.
pub(crate) fn poly_arc_derivs_into(
    c: &[AxisVec; 6],
    axes: &[usize],
    u: f64,
    t: &mut AxisVec,
    k: &mut AxisVec,
    kp: &mut AxisVec,
) -> bool {
    // d/du, d²/du², d³/du³ go to t, k, kp first, then become the arc-length derivatives.
    *t = [0.0; AXES];
    *k = [0.0; AXES];
    *kp = [0.0; AXES];
    let (mut s11, mut s12, mut s22, mut s13) = (0.0, 0.0, 0.0, 0.0);
    for &i in axes {
        let (c1, c2, c3, c4, c5) = (c[1][i], c[2][i], c[3][i], c[4][i], c[5][i]);
        let a = c1 + u * (2.0 * c2 + u * (3.0 * c3 + u * (4.0 * c4 + u * 5.0 * c5)));
        let b = 2.0 * c2 + u * (6.0 * c3 + u * (12.0 * c4 + u * 20.0 * c5));
        let e = 6.0 * c3 + u * (24.0 * c4 + u * 60.0 * c5);
        (t[i], k[i], kp[i]) = (a, b, e);
        s11 += a * a;
        s12 += a * b;
        s22 += b * b;
        s13 += a * e;
    }
    let sig2 = s11;
    let sig = sig2.sqrt();
    if !(sig > 0.0) {
        *t = [0.0; AXES];
        *k = [0.0; AXES];
        *kp = [0.0; AXES];
        return true;
    }
    let sig_u = s12 / sig;
    let sig_uu = (s22 + s13) / sig - sig_u * sig_u / sig;
    let u1 = 1.0 / sig;
    let u2 = -sig_u / (sig2 * sig);
    let u3 = -sig_uu / (sig2 * sig2) + 3.0 * sig_u * sig_u / (sig2 * sig2 * sig);
    if !(u1.is_finite() && u2.is_finite() && u3.is_finite()) {
        return false;
    }
    for &i in axes {
        let (d1, d2, d3) = (t[i], k[i], kp[i]);
        t[i] = d1 * u1;
        k[i] = d2 * u1 * u1 + d1 * u2;
        kp[i] = d3 * u1 * u1 * u1 + 3.0 * d2 * u1 * u2 + d1 * u3;
    }
    true
}

/// `arc_derivs` over the axes in `moving` only, for a `Deriv` that is zero on the others
/// ([`Shape::eval_axes`]): the same numbers (the sums skip terms that are exactly zero).
#[inline]
pub(crate) fn arc_derivs_axes(d: &Deriv, moving: u16) -> (AxisVec, AxisVec, AxisVec) {
    if moving == (1 << AXES) - 1 {
        return arc_derivs(d);
    }
    let dot_m = |a: &AxisVec, b: &AxisVec| {
        let (mut s, mut m) = (0.0, moving);
        while m != 0 {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            s += a[i] * b[i];
        }
        s
    };
    let sig2 = dot_m(&d.d1, &d.d1);
    let sig = sig2.sqrt();
    if !(sig > 0.0) {
        return ([0.0; AXES], [0.0; AXES], [0.0; AXES]);
    }
    let sig_u = dot_m(&d.d1, &d.d2) / sig;
    let sig_uu = (dot_m(&d.d2, &d.d2) + dot_m(&d.d1, &d.d3)) / sig - sig_u * sig_u / sig;
    let u1 = 1.0 / sig;
    let u2 = -sig_u / (sig2 * sig);
    let u3 = -sig_uu / (sig2 * sig2) + 3.0 * sig_u * sig_u / (sig2 * sig2 * sig);
    let mut t = [0.0; AXES];
    let mut k = [0.0; AXES];
    let mut kp = [0.0; AXES];
    let mut m = moving;
    while m != 0 {
        let i = m.trailing_zeros() as usize;
        m &= m - 1;
        t[i] = d.d1[i] * u1;
        k[i] = d.d2[i] * u1 * u1 + d.d1[i] * u2;
        kp[i] = d.d3[i] * u1 * u1 * u1 + 3.0 * d.d2[i] * u1 * u2 + d.d1[i] * u3;
    }
    (t, k, kp)
}

/// Quintic Hermite curve matching position, first and second derivative at both ends
/// (derivatives with respect to u in [0, 1]).
pub(crate) fn quintic(
    p0: &AxisVec,
    d0: &AxisVec,
    dd0: &AxisVec,
    p1: &AxisVec,
    d1: &AxisVec,
    dd1: &AxisVec,
) -> Shape {
    let mut c = [[0.0; AXES]; 6];
    for i in 0..AXES {
        let ci = quintic_axis(p0[i], d0[i], dd0[i], p1[i], d1[i], dd1[i]);
        for k in 0..6 {
            c[k][i] = ci[k];
        }
    }
    Shape::Poly { c }
}

/// The power-basis coefficients of one axis of [`quintic`].
#[inline]
pub(crate) fn quintic_axis(p0: f64, d0: f64, dd0: f64, p1: f64, d1: f64, dd1: f64) -> [f64; 6] {
    [
        p0,
        d0,
        0.5 * dd0,
        -10.0 * p0 - 6.0 * d0 - 1.5 * dd0 + 0.5 * dd1 - 4.0 * d1 + 10.0 * p1,
        15.0 * p0 + 8.0 * d0 + 1.5 * dd0 - dd1 + 7.0 * d1 - 15.0 * p1,
        -6.0 * p0 - 3.0 * d0 - 0.5 * dd0 + 0.5 * dd1 - 3.0 * d1 + 6.0 * p1,
    ]
}

/// Inner control points of a corner blend, as fractions of its reach `d` along each line:
/// the quintic Bézier V − d·a, V − 0.59·d·a, V − 0.15·d·a, V + 0.15·d·b, V + 0.59·d·b,
/// V + d·b (a, b: the unit directions into and out of the corner V). Three control points
/// on each line make its curvature zero at both ends (G2 with the lines). The fractions
/// minimise the largest curvature change |dK/ds|, which bounds the speed through the blend
/// (v³·|dK/ds| within the jerk), for a given distance from the path (≈ 0.78 × that of the
/// cubic with both inner points on the corner, used before) and for a given reach (0.41 ×;
/// a pair of clothoids, the optimum, 0.37 ×).
const CORNER_INNER: [f64; 2] = [0.59, 0.15];

/// Distance of a corner blend's middle (its farthest point from both lines) from the
/// corner, over d·sin(θ/2): (1 + 5·0.59 + 10·0.15) / 16.
pub(crate) const CORNER_MIDDLE: f64 = (1.0 + 5.0 * CORNER_INNER[0] + 10.0 * CORNER_INNER[1]) / 16.0;

/// The corner blend from `v − d·a` to `v + d·b` ([`CORNER_INNER`]).
pub(crate) fn corner_blend(v: &AxisVec, a: &AxisVec, b: &AxisVec, d: f64) -> Shape {
    // The Bernstein form's derivatives at the ends: p' = 5 (P1 − P0), p'' = 20 (P2 − 2 P1 + P0).
    let [d1, d2] = CORNER_INNER;
    let (t0, k0) = (5.0 * (1.0 - d1) * d, 20.0 * (2.0 * d1 - d2 - 1.0) * d);
    let mut p0 = [0.0; AXES];
    let mut p1 = [0.0; AXES];
    for i in 0..AXES {
        p0[i] = v[i] - d * a[i];
        p1[i] = v[i] + d * b[i];
    }
    quintic(
        &p0,
        &scale(a, t0),
        &scale(a, k0),
        &p1,
        &scale(b, t0),
        &scale(b, -k0),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator (no dependency for a few numbers).
    fn lcg(state: &mut u64) -> f64 {
        *state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (*state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }

    /// The derivatives over the moving axes only are those of the full nine-axis
    /// evaluation, bit for bit, still axes (+0) included: random quintics moving along one
    /// to nine axes, at parameters across [0, 1] and at its ends.
    #[test]
    fn derivatives_over_the_moving_axes_are_the_full_ones() {
        let mut st = 7u64;
        for case in 0..400 {
            let mut c = [[0.0; AXES]; 6];
            for i in 0..AXES {
                c[0][i] = 20.0 * lcg(&mut st);
                // About half the axes still (their derivative coefficients exactly zero).
                if lcg(&mut st) > 0.0 || i == case % AXES {
                    for row in c.iter_mut().skip(1) {
                        row[i] = 3.0 * lcg(&mut st);
                    }
                }
            }
            let (axes, n) = poly_moving_axes(&c);
            for u in [0.0, 1.0, 0.5 + 0.5 * lcg(&mut st), 0.5 + 0.5 * lcg(&mut st)] {
                let (t, k, kp) = arc_derivs(&Shape::Poly { c }.eval(u));
                let (mut t2, mut k2, mut kp2) = ([1.0; AXES], [1.0; AXES], [1.0; AXES]);
                assert!(poly_arc_derivs_into(
                    &c,
                    &axes[..n],
                    u,
                    &mut t2,
                    &mut k2,
                    &mut kp2
                ));
                for i in 0..AXES {
                    assert_eq!(t[i].to_bits(), t2[i].to_bits(), "case {case} u {u} T{i}");
                    assert_eq!(k[i].to_bits(), k2[i].to_bits(), "case {case} u {u} K{i}");
                    assert_eq!(kp[i].to_bits(), kp2[i].to_bits(), "case {case} u {u} K'{i}");
                }
            }
        }
    }

    /// A polynomial that does not move at all: every derivative zero, as `arc_derivs`.
    #[test]
    fn a_still_polynomial_has_zero_derivatives() {
        let mut c = [[0.0; AXES]; 6];
        c[0][0] = 3.0;
        let (axes, n) = poly_moving_axes(&c);
        assert_eq!(n, 0);
        let (mut t, mut k, mut kp) = ([1.0; AXES], [1.0; AXES], [1.0; AXES]);
        assert!(poly_arc_derivs_into(
            &c,
            &axes[..n],
            0.3,
            &mut t,
            &mut k,
            &mut kp
        ));
        assert_eq!((t, k, kp), ([0.0; AXES], [0.0; AXES], [0.0; AXES]));
    }
}
