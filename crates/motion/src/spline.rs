//! Spline moves (G5 cubic, G5.1 quadratic Bézier): validation, the analytic extent the soft
//! limits are checked on, and the split into pieces that are each the exact polynomial over
//! part of the parameter range (never chords). Runs when moves are pushed.
//!
//! A curve is cut into at most three pieces of equal "difficulty" (the change
//! of the logarithm of the parametric speed plus the turning angle), so that each piece's
//! tabulated arc-length map sees a parametric speed that changes by a bounded factor, and
//! the speed-limit samples of a piece are taken as the smallest bound between them (the
//! curvature of a spline peaks anywhere, not at a sample).

use crate::axes::{AXES, Axis, AxisVec, dot, is_finite, norm, norm_xyz, scale, sub};
use crate::error::MotionError;
use crate::geometry::{ArcMap, MAP_FINE_N, Shape};
use crate::input::{Bezier, PathMode};
use crate::limits::Lim;
use crate::piece::Piece;

/// Most pieces one spline becomes: with a dwell after it, the four pieces the planner
/// reserves per move.
pub(crate) const SPLINE_PIECES: usize = 3;
/// Smallest parametric speed along a curve relative to its largest. Below it the curve
/// nearly stops inside (a cusp) or at an end (a control point on its end point), where the
/// curvature grows without bound and the arc-length map cannot follow the parameter.
const MIN_SPEED_RATIO: f64 = 1e-3;
/// Smallest radius of curvature a spline may have, mm (0.1 µm, the resolution of fine
/// linear scales): a tighter turn is a cusp for a machine, passable only at a crawl.
const MIN_RADIUS: f64 = 1e-4;
/// Largest relative error of the path speed the arc-length map of a piece may make
/// (checked at push time).
const MAP_SPEED_TOL: f64 = 1e-3;
/// Grid on which the split points and the speed range are found.
const GRID: usize = 128;
/// Difficulty (change of ln speed plus turning, rad) one piece takes at most before the
/// curve is cut into more pieces.
const PIECE_COST: f64 = 0.3;
/// Sub-intervals between speed-limit samples on which the bounds are taken.
const DENSE: usize = 8;
/// Share of each axis's acceleration the centripetal bound of a spline may take.
const CENTRIPETAL_SHARE: f64 = 0.9;

/// A validated spline: power-basis coefficients and where its pieces meet.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SplineP {
    /// `p(u) = c0 + c1 u + c2 u² + c3 u³`, u in [0, 1] (c3 = 0 for a quadratic).
    pub c: [AxisVec; 4],
    pub a: AxisVec,
    pub b: AxisVec,
    pub feed: f64,
    pub mode: PathMode,
    pub line: u32,
    /// Arc length (all axes) and its XYZ part.
    pub len: f64,
    pub len_xyz: f64,
    /// Part of [0, 1] still to run: a corner blend (G64 P) trims the curve by parameter
    /// at its start (`u0`) or end (`u1`); what remains is still the exact polynomial.
    pub u0: f64,
    pub u1: f64,
    splits: [f64; SPLINE_PIECES + 1],
    n: usize,
    /// Which of the builder's [`SplineMaps`] holds this curve's tables.
    pub slot: usize,
}

/// Arc-length table and length of each piece of a curve (built once, when checked). Kept
/// by the builder apart from the curve, which is moved through its stages on every push:
/// with the tables inside, each move would copy kilobytes.
pub(crate) type SplineMaps = [(ArcMap, f64); SPLINE_PIECES];

fn unit(v: &AxisVec) -> AxisVec {
    let n = norm(v);
    if n > 0.0 { scale(v, 1.0 / n) } else { *v }
}

impl SplineP {
    /// Validates the curve from `a` through `control` to `b`: finite, inside the envelope
    /// (analytic extent per axis), regular; its tables go to `maps`, to be found there
    /// under `slot`. The feed is set by the caller.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        a: &AxisVec,
        b: &AxisVec,
        control: &Bezier,
        mode: PathMode,
        line: u32,
        lim: &Lim,
        maps: &mut SplineMaps,
        slot: usize,
    ) -> Result<SplineP, MotionError> {
        let ctrl: &[AxisVec] = match control {
            Bezier::Quadratic(p) => std::slice::from_ref(p),
            Bezier::Cubic(p) => p,
        };
        if !ctrl.iter().all(is_finite) {
            return Err(MotionError::NotFinite {
                line,
                what: "spline control point",
            });
        }
        // An axis without limits must not move anywhere along the curve.
        for i in 0..AXES {
            if lim.present[i] {
                continue;
            }
            if let Some(p) = ctrl.iter().find(|p| p[i] != a[i]) {
                return Err(MotionError::SoftLimit {
                    line,
                    axis: Axis::ALL[i].letter(),
                    position: p[i],
                    min: a[i],
                    max: a[i],
                });
            }
        }
        let mut c = [[0.0; AXES]; 4];
        for i in 0..AXES {
            match control {
                Bezier::Quadratic(q) => {
                    c[0][i] = a[i];
                    c[1][i] = 2.0 * (q[i] - a[i]);
                    c[2][i] = a[i] - 2.0 * q[i] + b[i];
                }
                Bezier::Cubic([p1, p2]) => {
                    c[0][i] = a[i];
                    c[1][i] = 3.0 * (p1[i] - a[i]);
                    c[2][i] = 3.0 * (a[i] - 2.0 * p1[i] + p2[i]);
                    c[3][i] = -a[i] + 3.0 * (p1[i] - p2[i]) + b[i];
                }
            }
        }
        let polygon = {
            let mut l = 0.0;
            let mut prev = *a;
            for p in ctrl.iter().chain(std::iter::once(b)) {
                l += norm(&sub(p, &prev));
                prev = *p;
            }
            l
        };
        if !(polygon > 1e-12) {
            return Err(MotionError::ZeroLength { line });
        }
        let mut sp = SplineP {
            c,
            a: *a,
            b: *b,
            feed: 0.0,
            mode,
            line,
            len: 0.0,
            len_xyz: 0.0,
            u0: 0.0,
            u1: 1.0,
            splits: [0.0; SPLINE_PIECES + 1],
            n: 1,
            slot,
        };
        sp.check_regular()?;
        sp.check_extent(lim)?;
        sp.split(false);
        if sp.check_maps(maps).is_err() {
            sp.split(true);
            sp.check_maps(maps)?;
        }
        let (len, len_xyz) = sp.lengths();
        sp.len = len;
        sp.len_xyz = len_xyz;
        Ok(sp)
    }

    /// dp/du.
    fn d1(&self, u: f64) -> AxisVec {
        let c = &self.c;
        let mut d = [0.0; AXES];
        for i in 0..AXES {
            d[i] = c[1][i] + u * (2.0 * c[2][i] + u * 3.0 * c[3][i]);
        }
        d
    }

    /// d²p/du².
    fn d2(&self, u: f64) -> AxisVec {
        let c = &self.c;
        let mut d = [0.0; AXES];
        for i in 0..AXES {
            d[i] = 2.0 * c[2][i] + 6.0 * c[3][i] * u;
        }
        d
    }

    pub fn pos(&self, u: f64) -> AxisVec {
        let c = &self.c;
        let mut p = [0.0; AXES];
        for i in 0..AXES {
            p[i] = c[0][i] + u * (c[1][i] + u * (c[2][i] + u * c[3][i]));
        }
        p
    }

    pub fn end(&self) -> AxisVec {
        self.b
    }

    pub fn start_tangent(&self) -> AxisVec {
        unit(&self.d1(self.u0))
    }

    /// Point, unit tangent and curvature vector at `u`.
    pub fn state(&self, u: f64) -> (AxisVec, AxisVec, AxisVec) {
        let (d1, d2) = (self.d1(u), self.d2(u));
        let t = unit(&d1);
        let s2 = dot(&d1, &d1);
        let mut k = [0.0; AXES];
        if s2 > 0.0 {
            let along = dot(&d2, &t);
            for i in 0..AXES {
                k[i] = (d2[i] - along * t[i]) / s2;
            }
        }
        (self.pos(u), t, k)
    }

    /// Arc length between parameters `u0` ≤ `u1` (Gauss-Legendre, 3 points on each of 16
    /// intervals: the parametric speed of a validated curve is smooth).
    pub fn arc_len(&self, u0: f64, u1: f64) -> f64 {
        const X: [f64; 3] = [0.112_701_665_379_258_31, 0.5, 0.887_298_334_620_741_7];
        const W: [f64; 3] = [5.0 / 18.0, 8.0 / 18.0, 5.0 / 18.0];
        let n = 16;
        let h = (u1 - u0) / n as f64;
        let mut l = 0.0;
        for k in 0..n {
            for g in 0..3 {
                l += W[g] * h * norm(&self.d1(u0 + (k as f64 + X[g]) * h));
            }
        }
        l
    }

    /// The parameter at arc length `d` before the end of the remaining part (`at_end`) or
    /// after its start (bisection on [`SplineP::arc_len`]).
    pub fn param_at(&self, d: f64, at_end: bool) -> f64 {
        let (mut lo, mut hi) = (self.u0, self.u1);
        for _ in 0..52 {
            let mid = 0.5 * (lo + hi);
            let l = if at_end {
                self.arc_len(mid, self.u1)
            } else {
                self.arc_len(self.u0, mid)
            };
            // Before the end, the length shrinks as the parameter grows.
            if (l > d) == at_end {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }

    pub fn end_tangent(&self) -> AxisVec {
        unit(&self.d1(1.0))
    }

    /// Refuses a curve whose parametric speed nearly vanishes somewhere: smallest speed on
    /// a grid, refined by golden-section search around it.
    fn check_regular(&self) -> Result<(), MotionError> {
        let speed = |u: f64| norm(&self.d1(u));
        let (mut k_min, mut s_min, mut s_max) = (0, f64::INFINITY, 0.0f64);
        for k in 0..=GRID {
            let s = speed(k as f64 / GRID as f64);
            if s < s_min {
                s_min = s;
                k_min = k;
            }
            s_max = s_max.max(s);
        }
        let h = 1.0 / GRID as f64;
        let (lo, hi) = slowest_bracket(&speed, k_min);
        let u_min = 0.5 * (lo + hi);
        s_min = s_min.min(speed(u_min));
        if s_min >= MIN_SPEED_RATIO * s_max {
            // Regular, but it may still turn on a point: the smallest radius of curvature
            // (on the grid and where the parametric speed is smallest, where a near cusp
            // has it).
            let radius = |u: f64| {
                let (d1, d2) = (self.d1(u), self.d2(u));
                let (a, b, ab) = (dot(&d1, &d1), dot(&d2, &d2), dot(&d1, &d2));
                let cross = (a * b - ab * ab).max(0.0).sqrt();
                if cross > 0.0 {
                    a * a.sqrt() / cross
                } else {
                    f64::INFINITY
                }
            };
            let r_min = (0..=GRID)
                .map(|k| radius(k as f64 / GRID as f64))
                .fold(radius(u_min), f64::min);
            if r_min < MIN_RADIUS {
                return Err(MotionError::InvalidSpline {
                    line: self.line,
                    why: "the curve turns on a radius below 0.1 µm (it nearly stops and turns back)",
                });
            }
            return Ok(());
        }
        let why = if u_min <= 2.0 * h && speed(0.0) < MIN_SPEED_RATIO * s_max {
            "the first control point is (nearly) on the start point: no direction there"
        } else if u_min >= 1.0 - 2.0 * h && speed(1.0) < MIN_SPEED_RATIO * s_max {
            "the last control point is (nearly) on the end point: no direction there"
        } else {
            "the curve stops and turns back (a cusp)"
        };
        Err(MotionError::InvalidSpline {
            line: self.line,
            why,
        })
    }

    /// Soft limits on the analytic extent: per axis the end points and the polynomial's
    /// extrema inside (roots of its derivative).
    fn check_extent(&self, lim: &Lim) -> Result<(), MotionError> {
        for i in 0..AXES {
            if !lim.present[i] {
                continue;
            }
            let (lo, hi) = self.axis_range(i);
            for x in [lo, hi] {
                if x < lim.min[i] || x > lim.max[i] {
                    return Err(MotionError::SoftLimit {
                        line: self.line,
                        axis: Axis::ALL[i].letter(),
                        position: x,
                        min: lim.min[i],
                        max: lim.max[i],
                    });
                }
            }
        }
        Ok(())
    }

    /// Smallest and largest value axis `i` takes on the curve.
    pub fn axis_range(&self, i: usize) -> (f64, f64) {
        let (c1, c2, c3) = (self.c[1][i], self.c[2][i], self.c[3][i]);
        let mut lo = self.a[i].min(self.b[i]);
        let mut hi = self.a[i].max(self.b[i]);
        let mut take = |u: f64| {
            if u > 0.0 && u < 1.0 {
                let x = self.pos(u)[i];
                lo = lo.min(x);
                hi = hi.max(x);
            }
        };
        // c1 + 2 c2 u + 3 c3 u² = 0.
        let (qa, qb, qc) = (3.0 * c3, 2.0 * c2, c1);
        let scale_q = qa.abs().max(qb.abs()).max(qc.abs());
        if scale_q == 0.0 {
            return (lo, hi);
        }
        if qa.abs() <= 1e-14 * scale_q {
            if qb != 0.0 {
                take(-qc / qb);
            }
        } else {
            let disc = qb * qb - 4.0 * qa * qc;
            if disc >= 0.0 {
                // Numerically stable pair of roots.
                let q = -0.5 * (qb + qb.signum() * disc.sqrt());
                if q != 0.0 {
                    take(q / qa);
                    take(qc / q);
                } else {
                    take(0.0);
                }
            }
        }
        (lo, hi)
    }

    /// Cuts [0, 1] into pieces of equal difficulty (change of ln speed plus turning); with
    /// `at_dip`, one cut goes where the parametric speed is smallest inside (a near cusp
    /// then lies at a piece's end, where its table has a node, not inside a piece).
    fn split(&mut self, at_dip: bool) {
        let mut cum = [0.0; GRID + 1];
        let mut prev_t = unit(&self.d1(0.0));
        let mut prev_ls = norm(&self.d1(0.0)).ln();
        for k in 1..=GRID {
            let d = self.d1(k as f64 / GRID as f64);
            let t = unit(&d);
            let ls = norm(&d).ln();
            let turn = dot(&t, &prev_t).clamp(-1.0, 1.0).acos();
            cum[k] = cum[k - 1] + (ls - prev_ls).abs() + turn;
            prev_t = t;
            prev_ls = ls;
        }
        let total = cum[GRID];
        let n = ((total / PIECE_COST).ceil() as usize).clamp(1, SPLINE_PIECES);
        // The parameter where the cost reaches `target`.
        let at_cost = |target: f64| {
            let k = (0..GRID).find(|k| cum[k + 1] >= target).unwrap_or(GRID - 1);
            let span = cum[k + 1] - cum[k];
            let f = if span > 0.0 {
                ((target - cum[k]) / span).clamp(0.0, 1.0)
            } else {
                0.0
            };
            (k as f64 + f) / GRID as f64
        };
        self.splits = [1.0; SPLINE_PIECES + 1];
        self.splits[0] = 0.0;
        if at_dip && n >= 2 {
            // Cuts at the deepest interior minima of the parametric speed, then at the cost
            // midpoint of the costliest piece. Fixed arrays: this runs inside `push`.
            let mut speed = [0.0; GRID + 1];
            for (k, s) in speed.iter_mut().enumerate() {
                *s = norm(&self.d1(k as f64 / GRID as f64));
            }
            let top = speed.iter().cloned().fold(0.0, f64::max);
            let mut dips = [0usize; GRID];
            let mut n_dips = 0;
            for k in 2..GRID - 1 {
                if speed[k] < speed[k - 1] && speed[k] <= speed[k + 1] && speed[k] < 0.5 * top {
                    dips[n_dips] = k;
                    n_dips += 1;
                }
            }
            // Deepest first, the earlier of equal depths first.
            dips[..n_dips].sort_unstable_by(|a, b| speed[*a].total_cmp(&speed[*b]).then(a.cmp(b)));
            let n_dips = n_dips.min(n - 1);
            // Each minimum refined by golden-section search within its grid cells.
            let mut cuts = [0.0; SPLINE_PIECES];
            for (cut, &k) in cuts.iter_mut().zip(&dips[..n_dips]) {
                let h = 1.0 / GRID as f64;
                let (mut lo, mut hi) = ((k - 1) as f64 * h, (k + 1) as f64 * h);
                let g = 0.5 * (5f64.sqrt() - 1.0);
                for _ in 0..50 {
                    let (x1, x2) = (hi - g * (hi - lo), lo + g * (hi - lo));
                    if norm(&self.d1(x1)) < norm(&self.d1(x2)) {
                        hi = x2;
                    } else {
                        lo = x1;
                    }
                }
                *cut = 0.5 * (lo + hi);
            }
            let mut n_cuts = n_dips;
            let cost_at = |u: f64| cum[((u * GRID as f64).round() as usize).min(GRID)];
            while n_cuts < n - 1 {
                cuts[..n_cuts].sort_unstable_by(f64::total_cmp);
                let mut bounds = [0.0; SPLINE_PIECES + 1];
                bounds[1..=n_cuts].copy_from_slice(&cuts[..n_cuts]);
                bounds[n_cuts + 1] = 1.0;
                let (i, _) = bounds[..n_cuts + 2]
                    .windows(2)
                    .enumerate()
                    .map(|(i, w)| (i, cost_at(w[1]) - cost_at(w[0])))
                    .fold((0, f64::MIN), |m, x| if x.1 > m.1 { x } else { m });
                let mid = 0.5 * (cost_at(bounds[i]) + cost_at(bounds[i + 1]));
                cuts[n_cuts] = at_cost(mid);
                n_cuts += 1;
            }
            let cuts = &mut cuts[..n_cuts];
            cuts.sort_unstable_by(f64::total_cmp);
            for (m, u) in cuts.iter().enumerate() {
                self.splits[m + 1] = *u;
            }
        } else {
            for m in 1..n {
                self.splits[m] = at_cost(total * m as f64 / n as f64);
            }
        }
        self.n = n;
    }

    /// The exact polynomial over [u0, u1], re-parametrised to [0, 1].
    fn piece_shape(&self, u0: f64, u1: f64) -> Shape {
        let h = u1 - u0;
        let p = self.pos(u0);
        let d = self.d1(u0);
        let mut c = [[0.0; AXES]; 6];
        for i in 0..AXES {
            let (c2, c3) = (self.c[2][i], self.c[3][i]);
            c[0][i] = p[i];
            c[1][i] = d[i] * h;
            c[2][i] = (c2 + 3.0 * c3 * u0) * h * h;
            c[3][i] = c3 * h * h * h;
        }
        if u0 == 0.0 {
            c[0] = self.a;
        }
        Shape::Poly { c }
    }

    /// Refuses a curve on which the arc-length map of some piece would misjudge the path
    /// speed by more than [`MAP_SPEED_TOL`] (the split keeps that from happening on curves
    /// that pass [`SplineP::check_regular`]; this is the guarantee).
    fn check_maps(&self, maps: &mut SplineMaps) -> Result<(), MotionError> {
        for m in 0..self.n {
            let shape = self.piece_shape(self.splits[m], self.splits[m + 1]);
            let (map, len) = ArcMap::quintic_table(&shape);
            maps[m] = (map, len);
            if map_speed_error(&shape, &map) > MAP_SPEED_TOL {
                return Err(MotionError::InvalidSpline {
                    line: self.line,
                    why: "its parametric speed changes too fast to be followed (a control point very near an end point, or a near cusp)",
                });
            }
        }
        Ok(())
    }

    /// Arc length of the whole curve and of its XYZ part (Gauss-Legendre, 64 intervals).
    fn lengths(&self) -> (f64, f64) {
        const X: [f64; 3] = [0.112_701_665_379_258_31, 0.5, 0.887_298_334_620_741_7];
        const W: [f64; 3] = [5.0 / 18.0, 8.0 / 18.0, 5.0 / 18.0];
        let n = 64;
        let h = 1.0 / n as f64;
        let (mut l, mut lx) = (0.0, 0.0);
        for k in 0..n {
            for g in 0..3 {
                let d = self.d1((k as f64 + X[g]) * h);
                l += W[g] * h * norm(&d);
                lx += W[g] * h * norm_xyz(&d);
            }
        }
        (l, lx)
    }

    /// The pieces of the curve (tables from `maps`, this curve's slot); the last ends
    /// exactly at the end point and stops there when `stop`. A trimmed curve emits the parts of its pieces inside [u0, u1], each the exact
    /// polynomial with its own arc-length table, from and to the points the blends meet.
    pub fn emit(&self, maps: &SplineMaps, stop: bool, out: &mut Vec<Piece>) {
        if self.u0 > 0.0 || self.u1 < 1.0 {
            // Cuts: the trim points and the piece splits between them (a split within 1e-6
            // of a trim point is dropped: no sliver piece).
            let mut cuts = [0.0; SPLINE_PIECES + 1];
            cuts[0] = self.u0;
            let mut k = 1;
            for &u in &self.splits[1..self.n] {
                if u > self.u0 + 1e-6 && u < self.u1 - 1e-6 {
                    cuts[k] = u;
                    k += 1;
                }
            }
            cuts[k] = self.u1;
            for m in 0..k {
                let (lo, hi) = (cuts[m], cuts[m + 1]);
                let shape = self.piece_shape(lo, hi);
                let start = if lo == 0.0 { self.a } else { self.pos(lo) };
                let last = m + 1 == k;
                let end = if hi == 1.0 { self.b } else { self.pos(hi) };
                let mut pc = Piece::new(shape, start, end, self.feed, false, self.line);
                (pc.map, pc.len) = ArcMap::quintic_table(&shape);
                pc.dense_bounds = true;
                pc.stop_at_end = stop && last;
                out.push(pc);
            }
            return;
        }
        for m in 0..self.n {
            let (u0, u1) = (self.splits[m], self.splits[m + 1]);
            let shape = self.piece_shape(u0, u1);
            let start = if m == 0 { self.a } else { shape.pos(0.0) };
            let end = if m + 1 == self.n {
                self.b
            } else {
                self.piece_shape(u1, self.splits[m + 2]).pos(0.0)
            };
            let mut pc = Piece::new(shape, start, end, self.feed, false, self.line);
            (pc.map, pc.len) = maps[m];
            pc.dense_bounds = true;
            pc.stop_at_end = stop && m + 1 == self.n;
            out.push(pc);
        }
    }
}

/// Largest relative error of the path speed the map makes on a piece: σ(u(s))·du/ds − 1
/// at four points inside every interval of its table.
fn map_speed_error(shape: &Shape, map: &ArcMap) -> f64 {
    let ArcMap::Quintic { s: nodes, .. } = map else {
        return 0.0;
    };
    let mut worst = 0.0f64;
    for k in 0..MAP_FINE_N {
        let (s0, s1) = (nodes[k], nodes[k + 1]);
        for q in 0..4 {
            let s = s0 + (s1 - s0) * (2 * q + 1) as f64 / 8.0;
            let ds = 1e-4 * (s1 - s0);
            let duds = (map.u(s + ds) - map.u(s - ds)) / (2.0 * ds);
            let err = (shape.speed(map.u(s)) * duds - 1.0).abs();
            if !(err <= worst) {
                worst = if err.is_nan() { f64::INFINITY } else { err };
            }
        }
    }
    worst
}

impl Piece {
    /// The speed bounds at each sample become the smallest bound between it and its
    /// neighbours: the braking curve takes the smaller of two neighbouring samples over the
    /// interval between them, so a peak of curvature between samples is not missed. The
    /// centripetal bound leaves [`CENTRIPETAL_SHARE`]'s complement of each axis's
    /// acceleration free: at a curvature peak the path must still be able to brake (with
    /// the whole acceleration taken by the curve the braking model sees no deceleration
    /// there, and a stop after it could not be planned).
    pub(crate) fn tighten_bounds_between_samples(&mut self, lim: &Lim) {
        let mut shared = *lim;
        for a in shared.a.iter_mut() {
            *a *= CENTRIPETAL_SHARE;
        }
        let mut v_axis = [f64::INFINITY; crate::piece::NS_MAX];
        let mut v_curve = [f64::INFINITY; crate::piece::NS_MAX];
        for k in 0..self.ns {
            let u0 = self.map.u(self.len * k as f64 / self.ns as f64);
            let u1 = self.map.u(self.len * (k + 1) as f64 / self.ns as f64);
            for q in 0..=DENSE {
                let u = u0 + (u1 - u0) * q as f64 / DENSE as f64;
                let d = self.shape.eval(u);
                let (t, kv, kp) = crate::geometry::arc_derivs(&d);
                let (va, vc) = self.point_bounds(&t, &kv, &kp, &shared);
                v_axis[k] = v_axis[k].min(va);
                v_curve[k] = v_curve[k].min(vc);
            }
        }
        for k in 0..self.ns {
            for j in [k, k + 1] {
                self.smp[j].v_axis = self.smp[j].v_axis.min(v_axis[k]);
                self.smp[j].v_curve = self.smp[j].v_curve.min(v_curve[k]);
            }
        }
    }
}

impl Bezier {
    /// Whether a planner takes the curve from `a` through these control points to `b` as
    /// a spline, whatever the machine: `false` for the shapes it refuses with MOTION-012
    /// (a cusp or near cusp, a control point on an end point, a parametric speed its
    /// arc-length tables cannot follow). The caller can run such a curve as the lines of
    /// [`Bezier::flatten`] instead, as LinuxCNC runs every spline as arcs.
    pub fn is_followable(&self, a: &AxisVec, b: &AxisVec) -> bool {
        let lim = Lim::unbounded();
        let mut maps = [(ArcMap::Linear { k: 1.0 }, 0.0); SPLINE_PIECES];
        !matches!(
            SplineP::new(a, b, self, PathMode::ExactStop, 0, &lim, &mut maps, 0),
            Err(MotionError::InvalidSpline { .. })
        )
    }

    /// Points along the curve from `a` to `b` (excluding `a`, ending exactly at `b`) whose
    /// chords stay within `tolerance` of it: the curve is halved (de Casteljau) until the
    /// control points of each part lie within `tolerance` of its chord, which bounds the
    /// curve's distance from that chord. At most 2^12 chords.
    pub fn flatten(&self, a: &AxisVec, b: &AxisVec, tolerance: f64, out: &mut Vec<AxisVec>) {
        let cubic = match *self {
            // Degree elevation: the same curve as a cubic.
            Bezier::Quadratic(q) => {
                let mut c1 = [0.0; AXES];
                let mut c2 = [0.0; AXES];
                for i in 0..AXES {
                    c1[i] = a[i] + 2.0 / 3.0 * (q[i] - a[i]);
                    c2[i] = b[i] + 2.0 / 3.0 * (q[i] - b[i]);
                }
                [*a, c1, c2, *b]
            }
            Bezier::Cubic([c1, c2]) => [*a, c1, c2, *b],
        };
        flatten_cubic(&cubic, tolerance, 12, out);
        // The last point is the end point exactly.
        if let Some(last) = out.last_mut() {
            *last = *b;
        }
    }
}

/// Distance of `p` from the segment `a`-`b`.
fn distance_to_segment(p: &AxisVec, a: &AxisVec, b: &AxisVec) -> f64 {
    let ab = sub(b, a);
    let l2 = dot(&ab, &ab);
    let t = if l2 > 0.0 {
        (dot(&sub(p, a), &ab) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let mut q = *a;
    for i in 0..AXES {
        q[i] += t * ab[i];
    }
    norm(&sub(p, &q))
}

fn flatten_cubic(c: &[AxisVec; 4], tolerance: f64, depth: u32, out: &mut Vec<AxisVec>) {
    let flat =
        distance_to_segment(&c[1], &c[0], &c[3]).max(distance_to_segment(&c[2], &c[0], &c[3]));
    if depth == 0 || !(flat > tolerance) {
        out.push(c[3]);
        return;
    }
    let mid = |p: &AxisVec, q: &AxisVec| {
        let mut m = [0.0; AXES];
        for i in 0..AXES {
            m[i] = 0.5 * (p[i] + q[i]);
        }
        m
    };
    let (p01, p12, p23) = (mid(&c[0], &c[1]), mid(&c[1], &c[2]), mid(&c[2], &c[3]));
    let (p012, p123) = (mid(&p01, &p12), mid(&p12, &p23));
    let m = mid(&p012, &p123);
    flatten_cubic(&[c[0], p01, p012, m], tolerance, depth - 1, out);
    flatten_cubic(&[m, p123, p23, c[3]], tolerance, depth - 1, out);
}

/// A part of a curve cut at its cusps ([`Bezier::split_at_cusps`]): the exact curve over
/// part of its range, or a chord into or out of a cusp.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CurvePart {
    /// The curve from the previous part's end (a cubic over part of the range).
    Curve {
        /// Where this part ends.
        end: AxisVec,
        /// Its control points.
        control: Bezier,
    },
    /// A straight chord from the previous part's end.
    Line {
        /// Where the chord ends.
        end: AxisVec,
    },
}

/// Parametric speed, relative to the largest, at which a curve is cut before and after a
/// cusp (tried in turn until the chords keep the tolerance and the parts are followable).
const CUSP_CUT_SPEEDS: [f64; 3] = [0.02, 0.01, 0.005];
/// Cusps (or ends without direction) one curve is cut at, at most: a cubic's derivative
/// vanishes at two parameters at most.
const CUSP_DEPTH: u32 = 3;

/// The cubic's point at the blossom's arguments (de Casteljau with one parameter per
/// level): `blossom(c, [s, s, t])` and its kin are the control points of the curve over
/// [s, t].
fn blossom(c: &[AxisVec; 4], u: [f64; 3]) -> AxisVec {
    let mut p = *c;
    for (level, &t) in u.iter().enumerate() {
        for k in 0..3 - level {
            for i in 0..AXES {
                p[k][i] += t * (p[k + 1][i] - p[k][i]);
            }
        }
    }
    p[0]
}

/// Control points of the cubic over [s, t] (the same polynomial).
fn sub_cubic(c: &[AxisVec; 4], s: f64, t: f64) -> [AxisVec; 4] {
    let mut out = [
        blossom(c, [s, s, s]),
        blossom(c, [s, s, t]),
        blossom(c, [s, t, t]),
        blossom(c, [t, t, t]),
    ];
    // The ends exactly where the curve's are.
    if s == 0.0 {
        out[0] = c[0];
    }
    if t == 1.0 {
        out[3] = c[3];
    }
    out
}

fn cubic_d1(c: &[AxisVec; 4], u: f64) -> AxisVec {
    let s = 1.0 - u;
    let mut d = [0.0; AXES];
    for i in 0..AXES {
        d[i] = 3.0
            * (s * s * (c[1][i] - c[0][i])
                + 2.0 * s * u * (c[2][i] - c[1][i])
                + u * u * (c[3][i] - c[2][i]));
    }
    d
}

/// Whether the cubic over [u0, u1] stays within `tolerance` of the chord between its ends
/// (64 samples: the stretch is a few µm long and nearly straight).
fn chord_keeps(c: &[AxisVec; 4], u0: f64, u1: f64, tolerance: f64) -> bool {
    let (p, q) = (blossom(c, [u0; 3]), blossom(c, [u1; 3]));
    (1..64).all(|k| {
        let u = u0 + (u1 - u0) * k as f64 / 64.0;
        distance_to_segment(&blossom(c, [u; 3]), &p, &q) <= tolerance
    })
}

fn split_cubic(c: &[AxisVec; 4], tolerance: f64, depth: u32, out: &mut Vec<CurvePart>) -> bool {
    let curve = Bezier::Cubic([c[1], c[2]]);
    if curve.is_followable(&c[0], &c[3]) {
        out.push(CurvePart::Curve {
            end: c[3],
            control: curve,
        });
        return true;
    }
    if depth == 0 {
        return false;
    }
    // Where the parametric speed is smallest: the cusp (grid, then golden section).
    let speed = |u: f64| norm(&cubic_d1(c, u));
    let (mut k_min, mut s_max) = (0, 0.0f64);
    for k in 0..=GRID {
        let s = speed(k as f64 / GRID as f64);
        if s < speed(k_min as f64 / GRID as f64) {
            k_min = k;
        }
        s_max = s_max.max(s);
    }
    if !(s_max > 0.0) {
        return false;
    }
    let (lo, hi) = slowest_bracket(&speed, k_min);
    let uc = if k_min == 0 && speed(0.0) <= speed(lo) {
        0.0
    } else if k_min == GRID && speed(1.0) <= speed(hi) {
        1.0
    } else {
        0.5 * (lo + hi)
    };
    for share in CUSP_CUT_SPEEDS {
        // Outwards from the cusp to where the speed is back to `share` of its largest.
        let reach = |dir: f64| {
            let mut d = 0.0;
            let step = 1.0 / (16.0 * GRID as f64);
            while d < 1.0 {
                let u = uc + dir * (d + step);
                if !(0.0..=1.0).contains(&u) {
                    return None;
                }
                d += step;
                if speed(u) >= share * s_max {
                    return Some(uc + dir * d);
                }
            }
            None
        };
        // Without such a point on a side, the chord runs to the curve's end there.
        let ul = reach(-1.0).unwrap_or(0.0);
        let ur = reach(1.0).unwrap_or(1.0);
        if !chord_keeps(c, ul, uc, tolerance) || !chord_keeps(c, uc, ur, tolerance) {
            continue;
        }
        let mark = out.len();
        let ok = (ul == 0.0 || split_cubic(&sub_cubic(c, 0.0, ul), tolerance, depth - 1, out)) && {
            if uc > ul {
                out.push(CurvePart::Line {
                    end: if uc == 1.0 { c[3] } else { blossom(c, [uc; 3]) },
                });
            }
            if ur > uc {
                out.push(CurvePart::Line {
                    end: if ur == 1.0 { c[3] } else { blossom(c, [ur; 3]) },
                });
            }
            ur == 1.0 || split_cubic(&sub_cubic(c, ur, 1.0), tolerance, depth - 1, out)
        };
        if ok {
            return true;
        }
        out.truncate(mark);
    }
    false
}

impl Bezier {
    /// Cuts the curve from `a` to `b` where it stops and turns back (a cusp, or a near
    /// cusp turning on a radius below 0.1 µm), or has no direction at an end (a control
    /// point on the end point), into parts a planner follows and that come to rest at the
    /// cusp: the exact curve up to where its parametric speed is back to 2 % of its
    /// largest (1 %, 0.5 % where that keeps the chords within `tolerance`), a chord to
    /// the cusp's point, a chord from it, the curve on. Each curve part is
    /// [followable](Bezier::is_followable), the chords stay within `tolerance` of the
    /// curve, the last part ends exactly at `b`. False (with `out` as it was) when the
    /// curve cannot be cut so; the caller may then [flatten](Bezier::flatten) it.
    pub fn split_at_cusps(
        &self,
        a: &AxisVec,
        b: &AxisVec,
        tolerance: f64,
        out: &mut Vec<CurvePart>,
    ) -> bool {
        if !is_finite(a) || !is_finite(b) || !(tolerance > 0.0) {
            return false;
        }
        let c = match *self {
            Bezier::Quadratic(q) => {
                let mut c1 = [0.0; AXES];
                let mut c2 = [0.0; AXES];
                for i in 0..AXES {
                    c1[i] = a[i] + 2.0 / 3.0 * (q[i] - a[i]);
                    c2[i] = b[i] + 2.0 / 3.0 * (q[i] - b[i]);
                }
                [*a, c1, c2, *b]
            }
            Bezier::Cubic([c1, c2]) => [*a, c1, c2, *b],
        };
        if !c.iter().all(is_finite) {
            return false;
        }
        let mark = out.len();
        if split_cubic(&c, tolerance, CUSP_DEPTH, out) {
            true
        } else {
            out.truncate(mark);
            false
        }
    }
}

/// The bracket of the slowest parametric speed near grid point `k_min` of a `GRID`-point
/// sampling: its two neighbouring intervals narrowed by 60 golden-section steps.
fn slowest_bracket(speed: &impl Fn(f64) -> f64, k_min: usize) -> (f64, f64) {
    let h = 1.0 / GRID as f64;
    let (mut lo, mut hi) = (
        (k_min as f64 * h - h).max(0.0),
        (k_min as f64 * h + h).min(1.0),
    );
    let g = 0.5 * (5f64.sqrt() - 1.0);
    for _ in 0..60 {
        let (x1, x2) = (hi - g * (hi - lo), lo + g * (hi - lo));
        if speed(x1) < speed(x2) {
            hi = x2;
        } else {
            lo = x1;
        }
    }
    (lo, hi)
}
