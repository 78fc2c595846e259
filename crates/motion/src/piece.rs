//! A piece of the planned path with its velocity-limit samples and braking curve.

use crate::axes::{AXES, AxisVec, norm_xyz};
use crate::geometry::{
    ArcMap, Shape, arc_derivs, arc_derivs_axes, poly_arc_derivs_into, poly_moving_axes,
};
use crate::limits::Lim;

/// Most sub-intervals of one piece's velocity-limit samples.
pub(crate) const NS_MAX: usize = 4;

/// Share of each axis's jerk the velocity limit leaves to the curvature-change term
/// v³·|dK/ds| (the rest serves the tangential jerk and the 3·v·a·K coupling).
pub(crate) const JERK_SHARE_CURVATURE: f64 = 0.8;
/// The same on corner blends, whose curvature rises and falls within a short length.
pub(crate) const JERK_SHARE_CURVATURE_BLEND: f64 = 0.4;
/// Share of J·T an acceleration step at a curvature discontinuity may use (a step Δa
/// shows up as Δa/T in the sampled jerk).
pub(crate) const JERK_SHARE_JUMP: f64 = 0.5;
/// Share of the available deceleration and jerk the braking model uses on curved pieces
/// (straight pieces use all of it): the margin lets the jerk-limited controller follow a
/// braking curve whose slope changes along the curve.
pub(crate) const BRAKE_SHARE_CURVED: f64 = 0.9;
/// The same on straight pieces: just below one, so that the controller (which may use the
/// full limits) keeps some room to follow the braking model exactly in discrete time.
pub(crate) const BRAKE_SHARE_STRAIGHT: f64 = 0.99;

/// Geometry of the path at one sample.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Sample {
    /// Unit tangent (d p / d s).
    pub t: AxisVec,
    /// Curvature vector (d² p / d s²).
    pub k: AxisVec,
    /// Its derivative d K / d s.
    pub kp: AxisVec,
    /// Speed bound from axis velocities.
    pub v_axis: f64,
    /// Speed bound from centripetal acceleration and curvature change (it holds around
    /// the sample: the speed limit of the sub-intervals next to it).
    pub v_curve: f64,
    /// Speed bound at the sample's point alone: the step of the tangent or the curvature
    /// at a junction (infinite elsewhere). It must not cap the sub-intervals next to it: a
    /// line between two tangent arcs (a CAM profile's rounded corners) has one
    /// sub-interval, which ran at the junctions' speed from end to end.
    pub v_point: f64,
    /// |T_xyz| (feed applies to the XYZ speed); 0 when XYZ does not move.
    pub t_xyz: f64,
}

/// One piece of path in the look-ahead window.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Piece {
    pub shape: Shape,
    /// Axes the shape moves ([`Shape::moving_axes`]): the per-period geometry visits only
    /// these.
    pub moving: u16,
    pub map: ArcMap,
    pub len: f64,
    pub start: AxisVec,
    pub end: AxisVec,
    /// Feed ceiling (mm/s of XYZ, or of the whole path when XYZ does not move); infinite for rapids.
    pub feed: f64,
    pub rapid: bool,
    pub line: u32,
    /// The path stops at the end of this piece (exact stop, corner, dwell, program end).
    pub stop_at_end: bool,
    /// Dwell time (the piece has zero length).
    pub dwell: f64,
    pub straight: bool,
    /// A corner blend (as opposed to a line, arc or smoothing span).
    pub corner_blend: bool,
    /// Speed bounds at the samples cover the whole interval around them (spline pieces,
    /// whose curvature may peak between samples).
    pub dense_bounds: bool,
    /// Ceilings of the velocity-limit samples from a dense analysis of the curve by the
    /// builder (arc corner blends, whose curvature change peaks between the samples);
    /// infinite otherwise.
    pub v_cap: [f64; NS_MAX + 1],
    pub ns: usize,
    pub smp: [Sample; NS_MAX + 1],
    /// Braking curve (maximal speed) at the samples.
    pub w: [f64; NS_MAX + 1],
    /// Deceleration the braking curve uses on each sub-interval.
    pub a_sub: [f64; NS_MAX],
    /// Acceleration the forward pass allows on each sub-interval.
    pub acc_sub: [f64; NS_MAX],
    /// Speed limit on each sub-interval under the current overrides (the lower of its two
    /// samples), kept by the forward pass, which runs over every piece whose samples or
    /// overrides change.
    pub vl_sub: [f64; NS_MAX],
    /// Smallest deceleration from this piece to the next stop, within the stop's reach.
    pub a_to_stop: f64,
    /// Smallest braking jerk from this piece to the next stop.
    pub j_to_stop: f64,
    /// Braking jerk of this piece.
    pub j_brake: f64,
    /// Path position of the start of this piece (counted from the planner's moving
    /// origin, `Planner::rebase`).
    pub cum_start: f64,
    /// The next stop at or after this piece: (path position,
    /// deceleration and jerk of the braking into it).
    pub stop_ahead: (f64, f64, f64),
    /// First valley of the braking curve inside this piece: (local s, speed, deceleration
    /// and jerk of the braking before it), where a
    /// braking section ends on a lower limit; the controller must arrive there with its
    /// deceleration released.
    pub valley_in: Option<(f64, f64, f64, f64)>,
    /// The next valley after this piece: (path position, speed,
    /// deceleration, jerk).
    pub valley_next: Option<(f64, f64, f64, f64)>,
    /// Lowest value of the braking curve on this piece (a lower bound of `w_at` over the
    /// piece, not counting the stop's jerk-limited shape near a stop).
    pub w_low: f64,
    /// Largest tangential acceleration and jerk on this piece (axis limits projected on
    /// the tangent; normal and quick-stop limits), filled with the samples.
    pub a_proj: [f64; 2],
    pub j_proj: [f64; 2],
    /// The samples are filled ([`Piece::sample`]; a corner blend is sampled by the builder,
    /// which weighs it against a stop, and not again in the window).
    pub sampled: bool,
}

impl Piece {
    pub fn new(
        shape: Shape,
        start: AxisVec,
        end: AxisVec,
        feed: f64,
        rapid: bool,
        line: u32,
    ) -> Piece {
        let (map, len, straight) = match shape {
            Shape::Line { .. } => {
                let mut l = 0.0;
                for i in 0..AXES {
                    l += (end[i] - start[i]) * (end[i] - start[i]);
                }
                (ArcMap::Linear { k: 1.0 }, l.sqrt(), true)
            }
            Shape::Helix(h) if h.dr == 0.0 => {
                let sp = shape.speed(0.0);
                let len = sp;
                (ArcMap::Linear { k: 1.0 / sp }, len, false)
            }
            _ => {
                let (m, l) = ArcMap::table(&shape);
                (m, l, false)
            }
        };
        Piece {
            shape,
            moving: shape.moving_axes(),
            map,
            len,
            start,
            end,
            feed,
            rapid,
            line,
            stop_at_end: false,
            dwell: 0.0,
            straight,
            corner_blend: false,
            dense_bounds: false,
            v_cap: [f64::INFINITY; NS_MAX + 1],
            ns: if straight { 1 } else { NS_MAX },
            smp: [Sample {
                v_point: f64::INFINITY,
                ..Sample::default()
            }; NS_MAX + 1],
            w: [0.0; NS_MAX + 1],
            a_sub: [0.0; NS_MAX],
            acc_sub: [f64::INFINITY; NS_MAX],
            vl_sub: [f64::INFINITY; NS_MAX],
            a_to_stop: f64::INFINITY,
            j_to_stop: f64::INFINITY,
            j_brake: f64::INFINITY,
            cum_start: 0.0,
            stop_ahead: (f64::INFINITY, 0.0, 0.0),
            valley_in: None,
            valley_next: None,
            w_low: 0.0,
            a_proj: [1.0; 2],
            j_proj: [1.0; 2],
            sampled: false,
        }
    }

    pub fn dwell(at: AxisVec, seconds: f64, line: u32) -> Piece {
        let mut p = Piece::new(
            Shape::Line {
                start: at,
                dir: [0.0; AXES],
            },
            at,
            at,
            1.0,
            false,
            line,
        );
        p.len = 0.0;
        p.dwell = seconds;
        p.stop_at_end = true;
        p
    }

    /// Position at arc length `s` (exact end point at and beyond the end).
    #[inline]
    pub fn pos(&self, s: f64) -> AxisVec {
        if s >= self.len {
            return self.end;
        }
        if s <= 0.0 {
            return self.start;
        }
        self.shape.pos(self.map.u(s))
    }

    /// Position and unit tangent at arc length `s`.
    pub fn pos_tangent(&self, s: f64) -> (AxisVec, AxisVec) {
        let s_c = s.clamp(0.0, self.len);
        let d = self.shape.eval(self.map.u(s_c));
        let (t, _, _) = arc_derivs(&d);
        let p = if s >= self.len {
            self.end
        } else if s <= 0.0 {
            self.start
        } else {
            d.p
        };
        (p, t)
    }

    /// Tangent, curvature vector and its derivative at local arc length `s`.
    #[inline]
    pub fn geo_at(&self, s: f64) -> (AxisVec, AxisVec, AxisVec) {
        if let Shape::Line { dir, .. } = &self.shape {
            return (*dir, [0.0; AXES], [0.0; AXES]);
        }
        let d = self
            .shape
            .eval_axes(self.map.u(s.clamp(0.0, self.len)), self.moving);
        arc_derivs_axes(&d, self.moving)
    }

    /// Fills the samples (geometry and speed bounds) from the machine limits.
    pub fn sample(&mut self, lim: &Lim) {
        // Polynomials (blends, smoothing spans, splines) move along two or three of the
        // nine axes: their derivatives are evaluated over those only, with the same values.
        let moving = match &self.shape {
            Shape::Poly { c } => Some(poly_moving_axes(c)),
            _ => None,
        };
        for k in 0..=self.ns {
            let s = self.len * k as f64 / self.ns as f64;
            let u = self.map.u(s);
            let sm = &mut self.smp[k];
            let fast = match (&self.shape, &moving) {
                (Shape::Poly { c }, Some((axes, n))) => {
                    poly_arc_derivs_into(c, &axes[..*n], u, &mut sm.t, &mut sm.k, &mut sm.kp)
                }
                _ => false,
            };
            if !fast {
                (sm.t, sm.k, sm.kp) = arc_derivs(&self.shape.eval(u));
            }
            let sm = &self.smp[k];
            let (v_axis, v_curve) = self.point_bounds(&sm.t, &sm.k, &sm.kp, lim);
            let sm = &mut self.smp[k];
            sm.v_axis = v_axis;
            sm.v_curve = v_curve.min(self.v_cap[k]);
            sm.t_xyz = norm_xyz(&sm.t);
        }
        if self.dense_bounds {
            self.tighten_bounds_between_samples(lim);
        }
        self.sampled = true;
    }

    /// Speed bounds (axis velocities; centripetal acceleration and curvature change) at a
    /// point with tangent `t`, curvature vector `kv` and its derivative `kp`.
    pub(crate) fn point_bounds(
        &self,
        t: &AxisVec,
        kv: &AxisVec,
        kp: &AxisVec,
        lim: &Lim,
    ) -> (f64, f64) {
        let mut v_axis = f64::INFINITY;
        let mut v2_curve = f64::INFINITY;
        let mut v_jerk3 = f64::INFINITY;
        for &i in lim.present_axes() {
            // Arcs: the per-axis projections of the in-plane parts rotate along the arc; use
            // their amplitude so that the bound holds on the whole sub-interval. The parts
            // along the normal do not rotate (a helix's rise; on a spiral, whose speed
            // changes with the radius, the curvature has one too).
            let (ti, ki, kpi) = match &self.shape {
                Shape::Helix(h) if i < 3 => {
                    let amp = (h.e1[i] * h.e1[i] + h.e2[i] * h.e2[i]).sqrt();
                    let on_axis = |v: &AxisVec| {
                        let vn = v[0] * h.n[0] + v[1] * h.n[1] + v[2] * h.n[2];
                        let all = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
                        (all - vn * vn).max(0.0).sqrt() * amp + (vn * h.n[i]).abs()
                    };
                    (on_axis(t).min(1.0), on_axis(kv), on_axis(kp))
                }
                _ => (t[i].abs(), kv[i].abs(), kp[i].abs()),
            };
            if ti > 0.0 {
                v_axis = v_axis.min(lim.v[i] / ti);
            }
            // The roots are taken once, of the smallest ratio (they are monotone: the same
            // bound as the smallest root, at a fraction of the cost).
            if ki > 0.0 {
                v2_curve = v2_curve.min(lim.a[i] / ki);
            }
            if kpi > 0.0 {
                let share = if self.corner_blend {
                    JERK_SHARE_CURVATURE_BLEND
                } else {
                    JERK_SHARE_CURVATURE
                };
                v_jerk3 = v_jerk3.min(share * lim.j[i] / kpi);
            }
        }
        // The cube root only when it can be the smaller: cbrt is within an ulp, so a cube
        // 1e-12 below v_jerk3 leaves the centripetal bound the minimum, as computed in full.
        let v_centripetal = v2_curve.sqrt();
        if v_centripetal.is_finite()
            && v_centripetal * v_centripetal * v_centripetal * (1.0 + 1e-12) < v_jerk3
        {
            return (v_axis, v_centripetal);
        }
        (v_axis, v_centripetal.min(v_jerk3.cbrt()))
    }

    /// Speed limit at sample `k` under the given overrides: around it
    /// ([`Piece::vlc_span`]) and at its point (a junction's step).
    #[inline]
    pub fn vlc(&self, k: usize, feed_override: f64, rapid_override: f64) -> f64 {
        self.vlc_span(k, feed_override, rapid_override)
            .min(self.smp[k].v_point)
    }

    /// Speed limit around sample `k` under the given overrides (feed, axis speeds,
    /// centripetal acceleration and curvature change): the sub-intervals next to it are
    /// capped by the lower of their two samples' limits.
    #[inline]
    pub fn vlc_span(&self, k: usize, feed_override: f64, rapid_override: f64) -> f64 {
        let sm = &self.smp[k];
        if self.rapid {
            return (sm.v_axis * rapid_override).min(sm.v_curve);
        }
        let f = if sm.t_xyz > 1e-9 {
            self.feed * feed_override / sm.t_xyz
        } else {
            self.feed * feed_override
        };
        f.min(sm.v_axis).min(sm.v_curve)
    }

    /// Largest tangential deceleration available at sample `k` at speed `v`, scaled by the
    /// braking share.
    pub fn decel_available(&self, k: usize, v: f64, lim: &Lim) -> f64 {
        let sm = &self.smp[k];
        let mut d = f64::INFINITY;
        for &i in lim.present_axes() {
            let ti = sm.t[i];
            let c = v * v * sm.k[i];
            let bound = if ti > 1e-12 {
                (lim.a[i] + c) / ti
            } else if ti < -1e-12 {
                (lim.a[i] - c) / -ti
            } else {
                f64::INFINITY
            };
            d = d.min(bound);
        }
        if !d.is_finite() {
            d = lim
                .a
                .iter()
                .zip(lim.present.iter())
                .filter(|(_, p)| **p)
                .fold(f64::INFINITY, |m, (a, _)| m.min(*a));
        }
        let share = if self.straight {
            BRAKE_SHARE_STRAIGHT
        } else {
            BRAKE_SHARE_CURVED
        };
        d.max(0.0) * share
    }

    /// `decel_available(k, v).min(decel_available(k + 1, v))`, the deceleration of the
    /// sub-interval after sample `k`, in one pass over the axes (the same values).
    pub fn decel_available_pair(&self, k: usize, v: f64, lim: &Lim) -> f64 {
        let (s0, s1) = (&self.smp[k], &self.smp[k + 1]);
        let (mut d0, mut d1) = (f64::INFINITY, f64::INFINITY);
        let bound = |ti: f64, c: f64, a: f64| {
            if ti > 1e-12 {
                (a + c) / ti
            } else if ti < -1e-12 {
                (a - c) / -ti
            } else {
                f64::INFINITY
            }
        };
        let v2 = v * v;
        for &i in lim.present_axes() {
            d0 = d0.min(bound(s0.t[i], v2 * s0.k[i], lim.a[i]));
            d1 = d1.min(bound(s1.t[i], v2 * s1.k[i], lim.a[i]));
        }
        let finish = |d: f64| {
            let d = if d.is_finite() {
                d
            } else {
                lim.present_axes()
                    .iter()
                    .fold(f64::INFINITY, |m, &i| m.min(lim.a[i]))
            };
            let share = if self.straight {
                BRAKE_SHARE_STRAIGHT
            } else {
                BRAKE_SHARE_CURVED
            };
            d.max(0.0) * share
        };
        finish(d0).min(finish(d1))
    }

    /// Largest tangential acceleration available at speed `v` over the sub-interval after
    /// sample `k` (the lower of its two samples), scaled like the deceleration.
    pub fn accel_available_pair(&self, k: usize, v: f64, lim: &Lim) -> f64 {
        let (s0, s1) = (&self.smp[k], &self.smp[k + 1]);
        let (mut d0, mut d1) = (f64::INFINITY, f64::INFINITY);
        let bound = |ti: f64, c: f64, a: f64| {
            if ti > 1e-12 {
                (a - c) / ti
            } else if ti < -1e-12 {
                (a + c) / -ti
            } else {
                f64::INFINITY
            }
        };
        let v2 = v * v;
        for &i in lim.present_axes() {
            d0 = d0.min(bound(s0.t[i], v2 * s0.k[i], lim.a[i]));
            d1 = d1.min(bound(s1.t[i], v2 * s1.k[i], lim.a[i]));
        }
        (d0.max(0.0) * BRAKE_SHARE_STRAIGHT).min(d1.max(0.0) * BRAKE_SHARE_STRAIGHT)
    }

    /// Fills the tangential limits of the piece from its samples: `j_brake`, the largest
    /// tangential jerk the braking model may use (each axis's jerk limit, on arcs less what
    /// the curvature change takes at the piece's speed limit, K'·v³, on splines at the speed
    /// where stops are jerk-dominated, projected on the tangent), and `a_proj`, `j_proj`,
    /// the largest tangential acceleration and jerk (normal and quick-stop limits projected
    /// on the tangent, ignoring centripetal load; the per-sample check enforces the rest).
    /// One pass over the samples and the present axes.
    pub fn set_tangent_limits(&mut self, lim: &Lim) {
        let mut jm = f64::INFINITY;
        let (mut am, mut qam, mut hjm, mut qjm) =
            (f64::INFINITY, f64::INFINITY, f64::INFINITY, f64::INFINITY);
        let helix = matches!(self.shape, Shape::Helix(_));
        for k in 0..=self.ns {
            let sm = &self.smp[k];
            // Only arcs and helices keep their curvature at speed; on blends and smoothing
            // spans the per-period bounds take care of the curvature change.
            let vs = sm.v_axis.min(sm.v_curve);
            let v3 = if vs.is_finite() && helix {
                vs * vs * vs
            } else {
                0.0
            };
            for &i in lim.present_axes() {
                let ti = sm.t[i].abs();
                if ti > 1e-12 {
                    // Splines: the stop model this jerk feeds matters where the stop is
                    // jerk-dominated, below 2·A²/J; reserve the curvature change there.
                    // (Without it, stops at the end of random splines overran in 14 of
                    // 88 programs; with it at the piece's speed limit, stops far from
                    // the curve's bends became ten times too cautious.)
                    let v3 = if self.dense_bounds && vs.is_finite() {
                        let v = vs.min(2.0 * lim.a[i] * lim.a[i] / lim.j[i]);
                        v * v * v
                    } else {
                        v3
                    };
                    let room = (lim.j[i] - sm.kp[i].abs() * v3).max(0.1 * lim.j[i]);
                    jm = jm.min(room / ti);
                    am = am.min(lim.a[i] / ti);
                    qam = qam.min(lim.qa[i] / ti);
                    hjm = hjm.min(lim.j[i] / ti);
                    qjm = qjm.min(lim.qj[i] / ti);
                }
            }
        }
        if !jm.is_finite() {
            jm = lim
                .j
                .iter()
                .zip(lim.present.iter())
                .filter(|(_, p)| **p)
                .fold(f64::INFINITY, |m, (a, _)| m.min(*a));
        }
        self.j_brake = if self.straight {
            jm * BRAKE_SHARE_STRAIGHT
        } else {
            jm * BRAKE_SHARE_CURVED
        };
        let or_one = |x: f64| if x.is_finite() { x } else { 1.0 };
        self.a_proj = [or_one(am), or_one(qam)];
        self.j_proj = [or_one(hjm), or_one(qjm)];
    }

    /// Braking-curve speed at local arc length `s` and its deceleration there (0 where the
    /// curve is at the speed limit, i.e. flat).
    #[inline]
    pub fn w_at(&self, s: f64) -> (f64, f64) {
        if self.len <= 0.0 {
            return (self.w[0], 0.0);
        }
        let h = self.len / self.ns as f64;
        let mut k = (s / h) as usize;
        if k >= self.ns {
            k = self.ns - 1;
        }
        let s1 = h * (k + 1) as f64;
        let vl = self.vl_sub[k];
        let wn = self.w[k + 1];
        let d = (s1 - s).max(0.0);
        let wb = (wn * wn + 2.0 * self.a_sub[k] * d).sqrt();
        let w0 = self.w[k];
        let wf = (w0 * w0 + 2.0 * self.acc_sub[k] * (s - h * k as f64).max(0.0)).sqrt();
        let cap = vl.min(wf);
        let (mut w, mut slope) = if wb < cap {
            (wb, self.a_sub[k])
        } else {
            (cap, 0.0)
        };
        // Near a stop the curve follows the jerk-limited stop, whose deceleration returns
        // to zero at the stop (an acceleration-limited curve cannot be followed there).
        let (stop_pos, sa, sj) = self.stop_ahead;
        if stop_pos.is_finite() && sa > 0.0 && sj > 0.0 {
            let dist = stop_pos - (self.cum_start + s);
            if dist >= 0.0 {
                let (wj, aj) = jerk_stop_speed(dist, sa, sj);
                if wj < w {
                    w = wj;
                    slope = aj;
                }
            }
        }
        // Likewise before a valley, which the controller must reach with its deceleration
        // released: an acceleration-limited curve into it has the jerk-limited path arrive
        // braking, and it undershoots the valley by far (down to a near stop between two
        // corners of a dense polyline).
        if let Some((dist, v0, a, j)) = self.valley_ahead(s)
            && !jerk_valley_speed_is_above(dist, v0, a, j, w)
        {
            let (wv, av) = jerk_valley_speed(dist, v0, a, j);
            if wv < w {
                w = wv;
                slope = av;
            }
        }
        (w, slope)
    }

    /// The next valley of the braking curve from local arc length `s`: its distance,
    /// speed, deceleration and jerk.
    #[inline]
    pub fn valley_ahead(&self, s: f64) -> Option<(f64, f64, f64, f64)> {
        let (dist, v0, a, j) = match (self.valley_in, self.valley_next) {
            (Some((sv, v0, a, j)), _) if s <= sv => (sv - s, v0, a, j),
            (_, Some((at, v0, a, j))) => (at - (self.cum_start + s), v0, a, j),
            _ => return None,
        };
        (dist >= 0.0 && v0 > 0.0 && a > 0.0 && j > 0.0 && a.is_finite() && j.is_finite())
            .then_some((dist, v0, a, j))
    }
}

/// Speed of the time-optimal jerk-limited deceleration (deceleration `a`, jerk `j`) that
/// arrives at speed `v0` with no deceleration left, at distance `d` before it, and its
/// deceleration there: the jerk-limited stop's speed profile raised by `v0`, over the
/// time τ still to go. Within the jerk phase (τ ≤ a/j) d = v0·τ + j·τ³/6, solved by
/// Newton's method from above (the cubic is convex for τ ≥ 0, so the iterates fall
/// monotonically to the root; 8 steps at most over speeds, decelerations and jerks of
/// ten decades); beyond it d is quadratic in τ. (A 40-step bisection took a third of
/// the planner's time on CAM polylines, where most pieces lie before a valley.)
pub(crate) fn jerk_valley_speed(d: f64, v0: f64, a: f64, j: f64) -> (f64, f64) {
    let t1 = a / j;
    let d1 = v0 * t1 + j * t1 * t1 * t1 / 6.0;
    if d <= d1 {
        // Every term is an upper bound of the root.
        let mut tau = (d / v0).min((6.0 * d / j).cbrt()).min(t1).max(0.0);
        for _ in 0..12 {
            let f = j * tau * tau * tau / 6.0 + v0 * tau - d;
            let next = tau - f / (v0 + 0.5 * j * tau * tau);
            if !(next < tau) {
                break;
            }
            tau = next.max(0.0);
        }
        return (v0 + 0.5 * j * tau * tau, j * tau);
    }
    // (a/2)·τ² + (v0 − a·t1/2)·τ + a·t1²/6 − d = 0, c < 0: the positive root, in the
    // form without cancellation.
    let b = v0 - 0.5 * a * t1;
    let c = a * t1 * t1 / 6.0 - d;
    let disc = (b * b - 2.0 * a * c).max(0.0).sqrt();
    let tau = if b >= 0.0 {
        -2.0 * c / (b + disc)
    } else {
        (disc - b) / a
    };
    (v0 + a * tau - 0.5 * a * t1, a)
}

/// Whether `jerk_valley_speed(d, v0, a, j)` certainly returns a speed above `w` (so it
/// cannot lower a curve at `w`), decided without solving for the time before the valley:
/// far from a valley the valley's curve is never the lower one. "Certainly" leaves a
/// margin far above the speed's rounding, so skipping it never changes a result.
#[inline]
pub(crate) fn jerk_valley_speed_is_above(d: f64, v0: f64, a: f64, j: f64, w: f64) -> bool {
    if !(w.is_finite() && d.is_finite()) {
        return false;
    }
    if w <= v0 {
        // The valley's curve never falls below its own speed.
        return true;
    }
    let t1 = a / j;
    // The time before the valley at which the curve reaches w (raised by a margin far
    // above rounding), then the distance the curve covers in that time.
    let rise = (w - v0) + 1e-9 * w;
    let tau_w = if rise <= 0.5 * a * t1 {
        (2.0 * rise / j).sqrt()
    } else {
        rise / a + 0.5 * t1
    };
    let hi_stop = if d <= a * a * a / (6.0 * j * j) {
        (6.0 * d / j).cbrt()
    } else {
        t1 + (2.0 * d / a).sqrt()
    };
    let hi = (d / v0).min(hi_stop);
    // Beyond the bisection's resolution (hi / 2^40) with room to spare.
    let tau = tau_w * (1.0 + 1e-9) + hi * 2f64.powi(-38);
    if !(tau < hi * (1.0 - 2f64.powi(-38))) {
        return false;
    }
    let covered = if tau <= t1 {
        j * tau * tau * tau / 6.0
    } else {
        a * a * a / (6.0 * j * j) + 0.5 * a * (tau * tau - t1 * t1) - 0.5 * a * t1 * (tau - t1)
    };
    v0 * tau + covered < d
}

/// Speed of the time-optimal jerk-limited stop (deceleration `a`, jerk `j`) at distance `d`
/// before the stop, and its deceleration there.
pub(crate) fn jerk_stop_speed(d: f64, a: f64, j: f64) -> (f64, f64) {
    // Final jerk phase (deceleration falling from a to 0): d = j τ³ / 6, v = j τ² / 2.
    let d3 = a * a * a / (6.0 * j * j);
    if d <= d3 {
        let tau = (6.0 * d / j).cbrt();
        (0.5 * j * tau * tau, j * tau)
    } else {
        let v3 = a * a / (2.0 * j);
        ((v3 * v3 + 2.0 * a * (d - d3)).sqrt(), a)
    }
}

#[cfg(test)]
mod tests {
    //! The look-ahead's fast paths (derivatives over the moving axes, the cube root taken
    //! only when it can bound, the fused per-axis passes) against the computations written
    //! out plainly over all nine axes: the same bits.

    use super::*;
    use crate::axes::Axis;
    use crate::geometry::{Helix, corner_blend, quintic};
    use crate::limits::{AxisLimits, MachineLimits};
    use std::f64::consts::PI;

    fn lcg(state: &mut u64) -> f64 {
        *state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (*state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }

    /// Axis-velocity, centripetal and curvature-change bounds.
    fn plain_bounds(
        p: &Piece,
        t: &AxisVec,
        kv: &AxisVec,
        kp: &AxisVec,
        lim: &Lim,
    ) -> (f64, f64, f64) {
        let (mut v_axis, mut v2, mut vj3) = (f64::INFINITY, f64::INFINITY, f64::INFINITY);
        for i in 0..AXES {
            if !lim.present[i] {
                continue;
            }
            let (ti, ki, kpi) = match &p.shape {
                Shape::Helix(h) if i < 3 => {
                    // In-plane part times its amplitude on the axis, plus the normal part.
                    let amp = (h.e1[i] * h.e1[i] + h.e2[i] * h.e2[i]).sqrt();
                    let bound = |v: &AxisVec| {
                        let vn = v[0] * h.n[0] + v[1] * h.n[1] + v[2] * h.n[2];
                        let all = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
                        (all - vn * vn).max(0.0).sqrt() * amp + (vn * h.n[i]).abs()
                    };
                    (bound(t).min(1.0), bound(kv), bound(kp))
                }
                _ => (t[i].abs(), kv[i].abs(), kp[i].abs()),
            };
            if ti > 0.0 {
                v_axis = v_axis.min(lim.v[i] / ti);
            }
            if ki > 0.0 {
                v2 = v2.min(lim.a[i] / ki);
            }
            if kpi > 0.0 {
                let share = if p.corner_blend {
                    JERK_SHARE_CURVATURE_BLEND
                } else {
                    JERK_SHARE_CURVATURE
                };
                vj3 = vj3.min(share * lim.j[i] / kpi);
            }
        }
        (v_axis, v2.sqrt(), vj3.cbrt())
    }

    /// The braking jerk of a piece, over all nine axes.
    fn plain_jerk_available(p: &Piece, lim: &Lim) -> f64 {
        let mut jm = f64::INFINITY;
        for k in 0..=p.ns {
            let sm = &p.smp[k];
            let vs = sm.v_axis.min(sm.v_curve);
            let v3 = if vs.is_finite() && matches!(p.shape, Shape::Helix(_)) {
                vs * vs * vs
            } else {
                0.0
            };
            for i in 0..AXES {
                let ti = sm.t[i].abs();
                if lim.present[i] && ti > 1e-12 {
                    let v3 = if p.dense_bounds && vs.is_finite() {
                        let v = vs.min(2.0 * lim.a[i] * lim.a[i] / lim.j[i]);
                        v * v * v
                    } else {
                        v3
                    };
                    let room = (lim.j[i] - sm.kp[i].abs() * v3).max(0.1 * lim.j[i]);
                    jm = jm.min(room / ti);
                }
            }
        }
        if !jm.is_finite() {
            jm = (0..AXES)
                .filter(|i| lim.present[*i])
                .fold(f64::INFINITY, |m, i| m.min(lim.j[i]));
        }
        jm * if p.straight {
            BRAKE_SHARE_STRAIGHT
        } else {
            BRAKE_SHARE_CURVED
        }
    }

    /// Deceleration (`sign` 1) or acceleration (−1) at one sample, over all nine axes.
    fn plain_tangential(p: &Piece, k: usize, v: f64, lim: &Lim, sign: f64) -> f64 {
        let sm = &p.smp[k];
        let mut d = f64::INFINITY;
        for i in 0..AXES {
            if !lim.present[i] {
                continue;
            }
            let (ti, c) = (sm.t[i], v * v * sm.k[i]);
            let bound = if ti > 1e-12 {
                (lim.a[i] + sign * c) / ti
            } else if ti < -1e-12 {
                (lim.a[i] - sign * c) / -ti
            } else {
                f64::INFINITY
            };
            d = d.min(bound);
        }
        if sign < 0.0 {
            return d.max(0.0) * BRAKE_SHARE_STRAIGHT;
        }
        if !d.is_finite() {
            d = (0..AXES)
                .filter(|i| lim.present[*i])
                .fold(f64::INFINITY, |m, i| m.min(lim.a[i]));
        }
        let share = if p.straight {
            BRAKE_SHARE_STRAIGHT
        } else {
            BRAKE_SHARE_CURVED
        };
        d.max(0.0) * share
    }

    /// Largest tangential value of the per-axis `limit` over the samples.
    fn plain_head(p: &Piece, lim: &Lim, limit: &AxisVec) -> f64 {
        let mut m = f64::INFINITY;
        for k in 0..=p.ns {
            for i in 0..AXES {
                let ti = p.smp[k].t[i].abs();
                if lim.present[i] && ti > 1e-12 {
                    m = m.min(limit[i] / ti);
                }
            }
        }
        if m.is_finite() { m } else { 1.0 }
    }

    fn pieces(st: &mut u64) -> Vec<Piece> {
        let mut out = Vec::new();
        for n in 0..60 {
            let z = if n % 3 == 0 { 1.0 } else { 0.0 };
            let mut v = |s: f64| {
                let mut a = [0.0; AXES];
                a[0] = s * lcg(st);
                a[1] = s * lcg(st);
                a[2] = z * s * lcg(st);
                a
            };
            let (p0, d0, dd0, p1, d1, dd1) = (v(5.0), v(1.0), v(0.5), v(5.0), v(1.0), v(0.5));
            let shape = quintic(&p0, &d0, &dd0, &p1, &d1, &dd1);
            out.push(Piece::new(shape, p0, p1, 50.0, false, n));
            let (c, ta, tb) = (v(2.0), v(1.0), v(1.0));
            let (ta, tb) = (
                crate::axes::scale(&ta, 1.0 / crate::axes::norm(&ta)),
                crate::axes::scale(&tb, 1.0 / crate::axes::norm(&tb)),
            );
            let (a, b) = (
                crate::axes::add_scaled(&c, &ta, -1.5),
                crate::axes::add_scaled(&c, &tb, 1.5),
            );
            let mut blend = Piece::new(corner_blend(&c, &ta, &tb, 1.5), a, b, 80.0, false, n);
            blend.corner_blend = true;
            out.push(blend);
        }
        // Spans along circles (as in dense CAM polylines): centripetally bounded.
        for n in 0..20 {
            let (r, phi) = (2.0 + n as f64, 0.02 + 0.01 * n as f64);
            let at = |th: f64, s: f64| {
                let mut a = [0.0; AXES];
                a[0] = s * th.cos();
                a[1] = s * th.sin();
                a
            };
            let (p0, p1) = (at(0.0, r), at(phi, r));
            let (t0, t1) = (at(0.5 * PI, r * phi), at(0.5 * PI + phi, r * phi));
            let (k0, k1) = (at(PI, r * phi * phi), at(PI + phi, r * phi * phi));
            let shape = quintic(&p0, &t0, &k0, &p1, &t1, &k1);
            out.push(Piece::new(shape, p0, p1, 200.0, false, 200 + n));
        }
        let h = Helix {
            centre: [0.0; 3],
            e1: [1.0, 0.0, 0.0],
            e2: [0.0, 1.0, 0.0],
            n: [0.0, 0.0, 1.0],
            r0: 2.0,
            dr: 0.0,
            sweep: 1.3,
            rise: 0.4,
            other0: [0.0; AXES],
            other_delta: [0.0; AXES],
        };
        let (a, b) = (Shape::Helix(h).pos(0.0), Shape::Helix(h).pos(1.0));
        out.push(Piece::new(Shape::Helix(h), a, b, 30.0, false, 99));
        out
    }

    #[test]
    fn fast_paths_give_the_plain_values() {
        let lim = Lim::from(&MachineLimits::uniform(
            &[Axis::X, Axis::Y, Axis::Z],
            AxisLimits::new(100.0, 1000.0, 50_000.0, -1e3, 1e3),
        ));
        let mut st = 11u64;
        // Samples bounded by the centripetal acceleration (the cube root skipped) and by
        // the curvature change (taken).
        let (mut centripetal, mut curvature_change) = (0, 0);
        for mut p in pieces(&mut st) {
            p.sample(&lim);
            p.set_tangent_limits(&lim);
            for k in 0..=p.ns {
                let u = p.map.u(p.len * k as f64 / p.ns as f64);
                let (t, kv, kp) = arc_derivs(&p.shape.eval(u));
                let sm = p.smp[k];
                for i in 0..AXES {
                    assert_eq!(sm.t[i].to_bits(), t[i].to_bits());
                    assert_eq!(sm.k[i].to_bits(), kv[i].to_bits());
                    assert_eq!(sm.kp[i].to_bits(), kp[i].to_bits());
                }
                let (va, vc, vj) = plain_bounds(&p, &t, &kv, &kp, &lim);
                assert_eq!(sm.v_axis.to_bits(), va.to_bits());
                assert_eq!(sm.v_curve.to_bits(), vc.min(vj).to_bits());
                centripetal += usize::from(vc < vj);
                curvature_change += usize::from(vj < vc);
            }
            for k in 0..p.ns {
                for v in [0.0, 3.0, 40.0 * (1.0 + lcg(&mut st)), 400.0] {
                    let d = plain_tangential(&p, k, v, &lim, 1.0).min(plain_tangential(
                        &p,
                        k + 1,
                        v,
                        &lim,
                        1.0,
                    ));
                    assert_eq!(p.decel_available_pair(k, v, &lim).to_bits(), d.to_bits());
                    assert_eq!(
                        p.decel_available(k, v, &lim).to_bits(),
                        plain_tangential(&p, k, v, &lim, 1.0).to_bits()
                    );
                    let a = plain_tangential(&p, k, v, &lim, -1.0).min(plain_tangential(
                        &p,
                        k + 1,
                        v,
                        &lim,
                        -1.0,
                    ));
                    assert_eq!(p.accel_available_pair(k, v, &lim).to_bits(), a.to_bits());
                }
            }
            assert_eq!(
                p.j_brake.to_bits(),
                plain_jerk_available(&p, &lim).to_bits()
            );
            assert_eq!(
                p.a_proj[0].to_bits(),
                plain_head(&p, &lim, &lim.a).to_bits()
            );
            assert_eq!(
                p.a_proj[1].to_bits(),
                plain_head(&p, &lim, &lim.qa).to_bits()
            );
            assert_eq!(
                p.j_proj[0].to_bits(),
                plain_head(&p, &lim, &lim.j).to_bits()
            );
            assert_eq!(
                p.j_proj[1].to_bits(),
                plain_head(&p, &lim, &lim.qj).to_bits()
            );
        }
        assert!(
            centripetal > 20 && curvature_change > 20,
            "{centripetal} {curvature_change}"
        );
    }

    /// The valley's speed at the distance the jerk-limited deceleration covers in the time
    /// τ before the valley (d = v0·τ + j·τ³/6 within the jerk phase, then
    /// a³/(6j²) + a(τ² − t1²)/2 − a·t1(τ − t1)/2 more than v0·τ, t1 = a/j) is that
    /// profile's speed v0 + j·τ²/2, then v0 + a·τ − a·t1/2, over ten decades of each
    /// quantity.
    #[test]
    fn the_valley_speed_is_the_profiles_at_its_distance() {
        let mut state = 11u64;
        for _ in 0..200_000 {
            let v0 = 10f64.powf(2.5 * lcg(&mut state));
            let a = 10f64.powf(2.5 + 1.5 * lcg(&mut state));
            let j = 10f64.powf(5.5 + 2.5 * lcg(&mut state));
            let t1 = a / j;
            let tau = t1 * 10f64.powf(3.0 * lcg(&mut state));
            let (d, v, decel) = if tau <= t1 {
                (
                    v0 * tau + j * tau * tau * tau / 6.0,
                    v0 + 0.5 * j * tau * tau,
                    j * tau,
                )
            } else {
                let covered = a * a * a / (6.0 * j * j) + 0.5 * a * (tau * tau - t1 * t1)
                    - 0.5 * a * t1 * (tau - t1);
                (v0 * tau + covered, v0 + a * tau - 0.5 * a * t1, a)
            };
            let (w, wd) = jerk_valley_speed(d, v0, a, j);
            assert!(
                (w - v).abs() <= 1e-12 * v,
                "d {d} v0 {v0} a {a} j {j}: {w} {v}"
            );
            assert!(
                (wd - decel).abs() <= 1e-9 * a,
                "d {d} v0 {v0} a {a} j {j}: {wd} {decel}"
            );
        }
    }

    /// The closed-form test that skips the valley's speed says "above" only where that
    /// speed is not below the curve's: skipping never changes `w_at`. Speeds
    /// are drawn close to the valley's own (the boundary) as well as far from it.
    #[test]
    fn the_valley_is_skipped_only_where_it_cannot_lower_the_curve() {
        let mut state = 7u64;
        let (mut skipped, mut kept) = (0, 0);
        for case in 0..300_000 {
            let d = 10f64.powf(3.0 * lcg(&mut state) - 1.0);
            let v0 = 10f64.powf(2.0 * lcg(&mut state));
            let a = 10f64.powf(1.0 + 2.0 * lcg(&mut state));
            let j = 10f64.powf(3.0 + 3.0 * lcg(&mut state));
            let (wv, _) = jerk_valley_speed(d, v0, a, j);
            let w = match case % 3 {
                0 => wv * (1.0 + 1e-7 * lcg(&mut state)),
                1 => wv * (1.0 + lcg(&mut state)),
                _ => wv + (wv - v0) * 1e-8 * lcg(&mut state),
            };
            if jerk_valley_speed_is_above(d, v0, a, j, w) {
                assert!(wv >= w, "d {d} v0 {v0} a {a} j {j} w {w}: valley {wv}");
                skipped += 1;
            } else {
                kept += 1;
            }
        }
        assert!(
            skipped > 50_000 && kept > 50_000,
            "{skipped} skipped, {kept} kept"
        );
    }
}
