//! G64 P corners where an arc, helix or spline meets a line, an arc or a spline.
//!
//! Both neighbours are trimmed by the same length `d` next to the corner (an arc by angle,
//! so it stays an exact helix; a spline by parameter, so it stays the exact polynomial),
//! and a quintic joins the two trim points matching position,
//! tangent and curvature vector on both sides (derivatives `L·T` and `L²·K` for a common
//! parameter length `L`): the path is curvature-continuous (G2) and the curvature at each
//! end of the blend is its neighbour's (the arc's, or zero on a line). `d` is the largest
//! (up to half of a line, 45 % of an arc and half a radian of its turn) whose blend stays
//! within P of the programmed path, i.e. of the two neighbours up to the corner, with the
//! distance measured to the exact segment and helix. A few parameter lengths are tried and
//! the one with the highest speed limit (centripetal acceleration and curvature change of
//! every axis) is kept, or a shorter blend within 10 % of that speed that takes less time.
//! The blend's dense speed estimate caps the planner's velocity-limit samples.

use super::{Builder, Prim, State, V_RAPID_REF};
use crate::axes::{AXES, AxisVec, add_scaled, dot, norm, scale, sub};
use crate::geometry::{ArcMap, Deriv, Helix, Shape, arc_derivs, quintic};
use crate::limits::Lim;
use crate::piece::{JERK_SHARE_CURVATURE_BLEND, NS_MAX, Piece};
use crate::scurve;

/// Parameter lengths tried, relative to the chord between the trim points.
const L_FACTORS: [f64; 3] = [1.0, 1.25, 1.5];
/// Blends slower than this share of the fastest found are not chosen for a shorter time.
const SPEED_PREFERENCE: f64 = 0.9;
/// The parameter length of a tangent junction's blend, relative to the chord: from 0.8 of
/// the chord up, the quintic from a line into an arc bends the wrong way first and crosses
/// the line's side (by 2.5 nm at 0.8, 0.5 µm at 0.9, for 1 mm trims at a radius of 5 mm; a
/// pocket wall or a soft limit may lie there); at 0.75 its curvature stays between the two
/// neighbours' signs, so the blend stays on the inside, peaking at about 1.6 times the
/// arc's curvature.
const TANGENT_L_FACTORS: [f64; 1] = [0.75];
/// Sample intervals of a blend for its speed estimate and soft limits...
const NSAMP: usize = 32;
/// ... and for its deviation.
const NDEV: usize = 64;
/// Largest share of an arc trimmed at one end (the rest stays a piece of its own).
const ARC_TRIM_MAX: f64 = 0.45;
/// Largest turn trimmed from an arc (rad): the quintic follows the arc's curvature over a
/// moderate turn only.
const ARC_TRIM_ANGLE: f64 = 0.5;
/// The measured deviation stays this much (relative) below P: the refined sampling finds
/// the peak to far better than that.
const DEV_MARGIN: f64 = 1e-3;
/// Smallest |dp/du| of a blend relative to `L` (a blend that nearly stops is refused).
const MIN_PARAM_SPEED: f64 = 0.1;
/// A blend is chosen only when estimated this much (relative) faster than a stop: the
/// speed controller passes a slow valley less well than the jerk-limited profile the
/// estimate assumes (on 200 random chains around splines, 5 came out slower than G61
/// without the margin, by up to 0.8 %, 1 with it).
const BLEND_TIME_MARGIN: f64 = 0.1;
/// A tangent junction's curvature step is blended only where the blend is this much faster
/// than passing the step: the planner passes a short slow blend less well than its estimate.
const TANGENT_BLEND_GAIN: f64 = 1.2;
/// Iterations of the search for `d` per parameter length.
const D_ITER: usize = 12;

/// The programmed path between a trim point and the corner.
#[derive(Debug, Clone, Copy)]
enum Near {
    Seg {
        a: AxisVec,
        b: AxisVec,
    },
    Arc {
        h: Helix,
        lo: f64,
        hi: f64,
    },
    /// A spline's polynomial `c0 + c1 u + c2 u² + c3 u³` over [lo, hi].
    Poly {
        c: [AxisVec; 4],
        lo: f64,
        hi: f64,
    },
}

/// One neighbour trimmed by `d`: the state at the trim point, its helix parameter (arcs),
/// and the programmed part from there to the corner.
#[derive(Debug, Clone, Copy)]
struct Trim {
    st: State,
    u: f64,
    near: Near,
}

/// A blend found for a corner.
#[derive(Debug, Clone, Copy)]
struct ArcBlend {
    shape: Shape,
    from: Trim,
    to: Trim,
    /// Trim length on both sides.
    d: f64,
    /// Largest distance from the programmed path, as measured.
    deviation: f64,
    /// Speed limit estimated from the curvature and its change along the blend.
    speed: f64,
}

impl Builder {
    /// Rounds the corner between `prev` (whose remaining part starts at `st` if a line)
    /// and `cur` within `tol`, emitting `prev` up to the blend and the blend; returns `cur`
    /// as it remains after the blend. None (nothing emitted) when the corner must stop:
    /// no blend within the tolerance, one leaving the soft limits, or one slower than the
    /// threshold line corners use.
    pub(super) fn arc_corner(
        &mut self,
        prev: &Prim,
        st: Option<State>,
        cur: &Prim,
        tol: f64,
        lim: &Lim,
        out: &mut Vec<Piece>,
    ) -> Option<(Prim, Option<State>)> {
        let (bl, b) = blend_within(prev, st.as_ref(), cur, tol, &L_FACTORS, lim)?;
        // Blend only where that takes no longer than stopping; the time through the blend
        // as the planner limits it (each interval at the lower of its two sample caps).
        let h = b.len / b.ns as f64;
        let pass_time = b.v_cap[..=b.ns]
            .windows(2)
            .map(|w| h / w[0].min(w[1]).min(b.feed))
            .sum();
        let choice = corner_choice(prev, st.as_ref(), cur, b.feed, &bl, pass_time)?;
        if !choice.blend_pays(lim) {
            return None;
        }
        Some(self.emit_blend(prev, st, cur, &bl, b, tol, lim, out))
    }

    /// Rounds a tangent junction where the curvature steps (a line into an arc, arcs of
    /// different radii) within `tol`, when the blend's lowest speed limit is above
    /// `v_pass`, the speed at which the step itself can be passed. Passed as it is, the step
    /// of the centripetal acceleration happens within one servo period, so its speed falls
    /// with the period (v²·|ΔK| ≤ J·T/2); the blend's curvature changes along its length
    /// instead, at a speed that does not depend on the period. Same returns as
    /// [`arc_corner`](Self::arc_corner).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn tangent_corner(
        &mut self,
        prev: &Prim,
        st: Option<State>,
        cur: &Prim,
        tol: f64,
        v_pass: f64,
        lim: &Lim,
        out: &mut Vec<Piece>,
    ) -> Option<(Prim, Option<State>)> {
        let (bl, b) = blend_within(prev, st.as_ref(), cur, tol, &TANGENT_L_FACTORS, lim)?;
        let v_blend = b.v_cap[..=b.ns]
            .iter()
            .fold(f64::INFINITY, |m, &v| m.min(v));
        if !(v_blend > TANGENT_BLEND_GAIN * v_pass) {
            return None;
        }
        Some(self.emit_blend(prev, st, cur, &bl, b, tol, lim, out))
    }

    /// Emits `prev` up to the blend `bl` and the blend's piece `b`; returns `cur` as it
    /// remains after the blend.
    #[allow(clippy::too_many_arguments)]
    fn emit_blend(
        &mut self,
        prev: &Prim,
        st: Option<State>,
        cur: &Prim,
        bl: &ArcBlend,
        b: Piece,
        tol: f64,
        lim: &Lim,
        out: &mut Vec<Piece>,
    ) -> (Prim, Option<State>) {
        match prev {
            Prim::Line(lp) => {
                let start = st.unwrap_or(State {
                    p: lp.a,
                    t: lp.dir,
                    k: [0.0; AXES],
                });
                let end = State {
                    p: bl.from.st.p,
                    t: lp.dir,
                    k: [0.0; AXES],
                };
                for pc in self
                    .span_or_exceed(lp, &start, &end, tol, lim)
                    .iter()
                    .flatten()
                {
                    out.push(pc.piece());
                }
            }
            Prim::Arc {
                h,
                a,
                u0,
                feed,
                line,
                ..
            } => out.push(Piece::new(
                Shape::Helix(h.sub(*u0, bl.from.u)),
                *a,
                bl.from.st.p,
                *feed,
                false,
                *line,
            )),
            Prim::Spline(sp) => {
                let mut sp = *sp;
                sp.u1 = bl.from.u;
                sp.emit(&self.spline_maps[sp.slot], false, out);
            }
        }
        out.push(b);
        self.stats.blends += 1;
        match *cur {
            Prim::Line(lc) => (
                Prim::Line(lc),
                Some(State {
                    p: bl.to.st.p,
                    t: lc.dir,
                    k: [0.0; AXES],
                }),
            ),
            Prim::Arc {
                h,
                b,
                feed,
                mode,
                line,
                ..
            } => (
                Prim::Arc {
                    h,
                    a: bl.to.st.p,
                    u0: bl.to.u,
                    b,
                    feed,
                    mode,
                    line,
                },
                None,
            ),
            Prim::Spline(mut sp) => {
                sp.u0 = bl.to.u;
                (Prim::Spline(sp), None)
            }
        }
    }
}

/// The blend of the corner between `prev` and `cur` within `tol` and inside the soft
/// limits, and its piece with the dense speed caps: the planner samples a piece's speed
/// limit at five points, which miss the peak of the curvature change of a short blend.
fn blend_within(
    prev: &Prim,
    st: Option<&State>,
    cur: &Prim,
    tol: f64,
    factors: &[f64],
    lim: &Lim,
) -> Option<(ArcBlend, Piece)> {
    let feed = feed_of(prev).min(feed_of(cur)).min(V_RAPID_REF);
    let bl = solve(prev, st, cur, tol, feed, factors, lim)?;
    for k in 0..=NSAMP {
        let p = bl.shape.pos(k as f64 / NSAMP as f64);
        for i in 0..AXES {
            if lim.present[i] && (p[i] < lim.min[i] || p[i] > lim.max[i]) {
                return None;
            }
        }
    }
    let mut b = Piece::new(
        bl.shape,
        bl.from.st.p,
        bl.to.st.p,
        feed_of(prev).min(feed_of(cur)),
        false,
        line_of(prev),
    );
    b.corner_blend = true;
    b.v_cap = sample_caps(&b, lim);
    Some((bl, b))
}

/// The curvature vectors at the end of `prev` and the start of `cur`.
pub(super) fn junction_curvatures(prev: &Prim, cur: &Prim) -> (AxisVec, AxisVec) {
    (trim(prev, 0.0, true).st.k, trim(cur, 0.0, false).st.k)
}

/// Path limits (speed, acceleration, jerk) along unit tangent `t`: the axis that reaches
/// its own limit first.
fn path_limits(t: &AxisVec, lim: &Lim) -> (f64, f64, f64) {
    let (mut v, mut a, mut j) = (f64::INFINITY, f64::INFINITY, f64::INFINITY);
    for i in 0..AXES {
        let c = t[i].abs();
        if lim.present[i] && c > 0.0 {
            v = v.min(lim.v[i] / c);
            a = a.min(lim.a[i] / c);
            j = j.min(lim.j[i] / c);
        }
    }
    (v, a, j)
}

/// A corner and the blend offered for it, as the choice between blending and stopping
/// sees them.
#[derive(Debug, Clone, Copy)]
pub(super) struct CornerChoice {
    /// Programmed feed of the slower neighbour (mm/s; rapids: infinite): the blend's.
    pub feed: f64,
    /// Programmed feeds of the incoming and the outgoing neighbour: a stop runs each half
    /// of the replaced path at its own (a rapid into a slow plunge).
    pub feeds: [f64; 2],
    /// Lowest speed limit along the blend.
    pub v_blend: f64,
    /// Length of the blend.
    pub blend_len: f64,
    /// Time through the blend following its speed limit, capped at the feed.
    pub pass_time: f64,
    /// Length of the programmed path the blend replaces (both trims).
    pub replaced_len: f64,
    /// Length of the shorter neighbour: the room to brake and to speed up again.
    pub reach: f64,
    /// Unit tangents into and out of the corner.
    pub t_in: AxisVec,
    pub t_out: AxisVec,
}

impl CornerChoice {
    /// Estimated times (s) of the corner region when stopped and when blended, each
    /// counted from cruising at the speed `F` the neighbours reach (the feed, or less when
    /// the shorter neighbour cannot brake from it) and with the jerk-limited speed changes
    /// of the path (S-curve from rest or between speeds, [`scurve::stop`]):
    /// - stop: the replaced path at `F`, plus a stop and a restart: 2·t(F) − 2·s(F)/F,
    ///   where t(Δv), s(Δv) are the time and distance of a jerk-limited speed change Δv
    ///   from zero acceleration;
    /// - blend: the blend following its speed limit (at most `F`), plus slowing from `F` to
    ///   its lowest limit `v` and back: 2·(t(F−v) − (v·t(F−v) + s(F−v))/F). For a blend
    ///   whose limit is `v` all along this is exactly the time of the jerk-limited profile
    ///   that passes it at `v`; where the limit rises away from its lowest point the speed
    ///   changes partly overlap the blend and the estimate errs towards the blend's cost.
    ///
    /// Where the neighbours' feeds differ, each half counts with its own speed `F`: the
    /// stop runs its half of the replaced path at it, the blend slows from the incoming
    /// `F` and speeds up to the outgoing one, and runs at most at the slower feed.
    ///
    /// Acceleration and jerk are the path's along the two tangents, the lower of the two.
    pub fn times(&self, lim: &Lim) -> (f64, f64) {
        let (v1, a1, j1) = path_limits(&self.t_in, lim);
        let (v2, a2, j2) = path_limits(&self.t_out, lim);
        let (a, j) = (a1.min(a2), j1.min(j2));
        // The speed from which the path can stop within the shorter neighbour, each side.
        let side = |feed: f64| {
            let f = feed.min(v1).min(v2);
            speed_stopping_within(f.min(V_RAPID_REF), self.reach, a, j)
        };
        let fs = [side(self.feeds[0]), side(self.feeds[1])];
        let f_blend = side(self.feed).min(fs[0]).min(fs[1]);
        if !(f_blend > 0.0) {
            return (0.0, f64::INFINITY);
        }
        let mut stop = 0.0;
        for f in fs {
            let (s_stop, t_stop) = scurve::stop(f, 0.0, a, j);
            stop += 0.5 * self.replaced_len / f + t_stop - s_stop / f;
        }
        let v = self.v_blend.min(f_blend);
        if !(v > 0.0) {
            return (stop, f64::INFINITY);
        }
        let mut blend = self.pass_time.max(self.blend_len / f_blend);
        for f in fs {
            let (s_dv, t_dv) = scurve::stop(f - v, 0.0, a, j);
            blend += t_dv - (v * t_dv + s_dv) / f;
        }
        (stop, blend)
    }

    /// Whether blending is estimated to take less time than stopping, by at least
    /// [`BLEND_TIME_MARGIN`].
    pub fn blend_pays(&self, lim: &Lim) -> bool {
        let (stop, blend) = self.times(lim);
        blend <= (1.0 - BLEND_TIME_MARGIN) * stop
    }
}

/// `f`, or when the jerk-limited stop from `f` (deceleration `a`, jerk `j`) takes more than
/// `reach`, the speed whose stop takes it (bisection to the last bit, from below).
///
/// The closed-form speed for the distance ([`stop_speed_for_distance`]) decides the steps
/// far from it (the distance grows at least as fast as the speed, so 1e-10 relative is far
/// beyond rounding); the steps near it evaluate the stop: the same steps, so the same
/// result as evaluating every step, with a quarter of the evaluations.
fn speed_stopping_within(f: f64, reach: f64, a: f64, j: f64) -> f64 {
    if !(scurve::stop(f, 0.0, a, j).0 > reach) {
        return f;
    }
    let root = stop_speed_for_distance(reach, a, j);
    let (mut lo, mut hi) = (0.0, f);
    for _ in 0..48 {
        let mid = 0.5 * (lo + hi);
        let beyond = if root.is_finite() && mid < root * (1.0 - 1e-10) {
            false
        } else if root.is_finite() && mid > root * (1.0 + 1e-10) {
            true
        } else {
            scurve::stop(mid, 0.0, a, j).0 > reach
        };
        if beyond {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    lo
}

/// The speed from which the jerk-limited stop of [`scurve::stop`] (from zero
/// acceleration, deceleration `a`, jerk `j`) takes the distance `s`: s = v·√(v/J) below
/// v = A²/J, s = v·(v/A + A/J)/2 above.
fn stop_speed_for_distance(s: f64, a: f64, j: f64) -> f64 {
    if s <= a * a * a / (j * j) {
        (s * j.sqrt()).powf(2.0 / 3.0)
    } else {
        let b = a * a / (2.0 * j);
        -b + (b * b + 2.0 * a * s).sqrt()
    }
}

pub(super) fn feed_of(p: &Prim) -> f64 {
    match p {
        Prim::Line(l) => l.feed,
        Prim::Arc { feed, .. } => *feed,
        Prim::Spline(sp) => sp.feed,
    }
}

fn line_of(p: &Prim) -> u32 {
    match p {
        Prim::Line(l) => l.line,
        Prim::Arc { line, .. } => *line,
        Prim::Spline(sp) => sp.line,
    }
}

/// Length of what is left of `prim` (`st`: where a line's remaining part starts).
fn remaining_len(prim: &Prim, st: Option<&State>) -> f64 {
    match prim {
        Prim::Line(l) => norm(&sub(&l.b, &st.map_or(l.a, |s| s.p))),
        Prim::Arc { h, u0, .. } => helix_len(h) * (1.0 - u0),
        Prim::Spline(sp) => sp.arc_len(sp.u0, sp.u1),
    }
}

/// The blend `bl` of the corner between `prev` and `cur` as the choice between blending
/// and stopping sees it; None when the blend is not regular.
fn corner_choice(
    prev: &Prim,
    st: Option<&State>,
    cur: &Prim,
    feed: f64,
    bl: &ArcBlend,
    pass_time: f64,
) -> Option<CornerChoice> {
    let (_, blend_len) = blend_speed(&bl.shape, 0.0, None, NSAMP)?;
    Some(CornerChoice {
        feed,
        feeds: [feed_of(prev), feed_of(cur)],
        v_blend: bl.speed,
        blend_len,
        pass_time,
        replaced_len: 2.0 * bl.d,
        reach: remaining_len(prev, st).min(remaining_len(cur, None)),
        t_in: trim(prev, 0.0, true).st.t,
        t_out: trim(cur, 0.0, false).st.t,
    })
}

/// Length of a whole helix.
fn helix_len(h: &Helix) -> f64 {
    let sh = Shape::Helix(*h);
    if h.dr == 0.0 {
        sh.speed(0.0)
    } else {
        ArcMap::table(&sh).1
    }
}

/// Longest trim of `prim` at its end (`at_end`) or its start.
fn max_trim(prim: &Prim, st: Option<&State>, at_end: bool) -> f64 {
    match prim {
        Prim::Line(l) => {
            let left = if at_end {
                norm(&sub(&l.b, &st.map_or(l.a, |s| s.p)))
            } else {
                l.len
            };
            (0.5 * l.len).min(left)
        }
        Prim::Arc { h, .. } => {
            // A start trim takes at most 45 %, so an end trim of 45 % leaves a tenth.
            let u = if at_end { 1.0 } else { 0.0 };
            let (_, k, _) = arc_derivs(&Shape::Helix(*h).eval(u));
            let kn = norm(&k);
            let d = ARC_TRIM_MAX * helix_len(h);
            if kn > 0.0 {
                d.min(ARC_TRIM_ANGLE / kn)
            } else {
                d
            }
        }
        Prim::Spline(sp) => {
            // As an arc: at most 45 % of what remains, and half a radian at the end's
            // curvature (a start trim takes at most 45 %, so an end trim leaves a tenth).
            let d = ARC_TRIM_MAX * sp.arc_len(sp.u0, sp.u1);
            let (_, _, k) = sp.state(if at_end { sp.u1 } else { sp.u0 });
            let kn = norm(&k);
            if kn > 0.0 {
                d.min(ARC_TRIM_ANGLE / kn)
            } else {
                d
            }
        }
    }
}

/// `prim` trimmed by `d` at its end or start.
fn trim(prim: &Prim, d: f64, at_end: bool) -> Trim {
    match prim {
        Prim::Line(l) => {
            let (p, near) = if at_end {
                let p = add_scaled(&l.b, &l.dir, -d);
                (p, Near::Seg { a: p, b: l.b })
            } else {
                let p = add_scaled(&l.a, &l.dir, d);
                (p, Near::Seg { a: l.a, b: p })
            };
            Trim {
                st: State {
                    p,
                    t: l.dir,
                    k: [0.0; AXES],
                },
                u: 0.0,
                near,
            }
        }
        Prim::Arc { h, .. } => {
            let du = d / helix_len(h);
            let (u, near) = if at_end {
                let u = 1.0 - du;
                (
                    u,
                    Near::Arc {
                        h: *h,
                        lo: u,
                        hi: 1.0,
                    },
                )
            } else {
                (
                    du,
                    Near::Arc {
                        h: *h,
                        lo: 0.0,
                        hi: du,
                    },
                )
            };
            let dv = Shape::Helix(*h).eval(u);
            let (t, k, _) = arc_derivs(&dv);
            Trim {
                st: State { p: dv.p, t, k },
                u,
                near,
            }
        }
        // By parameter: the remaining curve is the exact polynomial over the rest.
        Prim::Spline(sp) => {
            let u = if d == 0.0 {
                if at_end { sp.u1 } else { sp.u0 }
            } else {
                sp.param_at(d, at_end)
            };
            let (p, t, k) = sp.state(u);
            let (lo, hi) = if at_end { (u, sp.u1) } else { (sp.u0, u) };
            Trim {
                st: State { p, t, k },
                u,
                near: Near::Poly { c: sp.c, lo, hi },
            }
        }
    }
}

/// Distance of `x` from the programmed part `n` (exact for segments; for a helix the
/// nearest point in the plane, refined by Newton steps on the squared distance for the
/// rise, radius change and other axes; never below the true distance).
fn dist_near(x: &AxisVec, n: &Near) -> f64 {
    match n {
        Near::Seg { a, b } => {
            let d = sub(b, a);
            let w = sub(x, a);
            let l2 = dot(&d, &d);
            let t = if l2 > 0.0 {
                (dot(&w, &d) / l2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            norm(&add_scaled(&w, &d, -t))
        }
        Near::Poly { c, lo, hi } => dist_poly(x, c, *lo, *hi),
        Near::Arc { h, lo, hi } => {
            let sh = Shape::Helix(*h);
            let q = [x[0] - h.centre[0], x[1] - h.centre[1], x[2] - h.centre[2]];
            let a1 = q[0] * h.e1[0] + q[1] * h.e1[1] + q[2] * h.e1[2];
            let a2 = q[0] * h.e2[0] + q[1] * h.e2[1] + q[2] * h.e2[2];
            let (tlo, thi) = (h.sweep * lo, h.sweep * hi);
            let mid = 0.5 * (tlo + thi);
            let tau = 2.0 * std::f64::consts::PI;
            let dphi = (a2.atan2(a1) - mid + 0.5 * tau).rem_euclid(tau) - 0.5 * tau;
            let mut u = (mid + dphi.clamp(tlo - mid, thi - mid)) / h.sweep;
            if h.rise == 0.0 && h.dr == 0.0 && h.other_delta.iter().all(|v| *v == 0.0) {
                // A circle: the point at the projection's angle (or the nearer end of the
                // part) is the nearest.
                return norm(&sub(x, &sh.pos(u)));
            }
            for _ in 0..4 {
                let dv = sh.eval(u);
                let r = sub(&dv.p, x);
                let g = dot(&r, &dv.d1);
                let hs = dot(&dv.d1, &dv.d1) + dot(&r, &dv.d2);
                if !(hs > 0.0) {
                    break;
                }
                u = (u - g / hs).clamp(*lo, *hi);
            }
            [u, *lo, *hi]
                .iter()
                .map(|v| norm(&sub(x, &sh.pos(*v))))
                .fold(f64::INFINITY, f64::min)
        }
    }
}

/// Distance of `x` from the cubic `c` over [lo, hi]: the nearest of 17 samples, refined by
/// Newton steps on the squared distance (clamped to the range); the distance to a point of
/// the curve, so never below the true distance.
fn dist_poly(x: &AxisVec, c: &[AxisVec; 4], lo: f64, hi: f64) -> f64 {
    let eval = |u: f64| {
        let mut p = [0.0; AXES];
        let mut d1 = [0.0; AXES];
        let mut d2 = [0.0; AXES];
        for i in 0..AXES {
            p[i] = c[0][i] + u * (c[1][i] + u * (c[2][i] + u * c[3][i]));
            d1[i] = c[1][i] + u * (2.0 * c[2][i] + u * 3.0 * c[3][i]);
            d2[i] = 2.0 * c[2][i] + 6.0 * c[3][i] * u;
        }
        (p, d1, d2)
    };
    const N: usize = 16;
    let (mut best_u, mut best) = (lo, f64::INFINITY);
    for k in 0..=N {
        let u = lo + (hi - lo) * k as f64 / N as f64;
        let dd = norm(&sub(x, &eval(u).0));
        if dd < best {
            best = dd;
            best_u = u;
        }
    }
    let mut u = best_u;
    for _ in 0..6 {
        let (p, d1, d2) = eval(u);
        let r = sub(&p, x);
        let g = dot(&r, &d1);
        let hs = dot(&d1, &d1) + dot(&r, &d2);
        if !(hs > 0.0) {
            break;
        }
        u = (u - g / hs).clamp(lo, hi);
        best = best.min(norm(&sub(x, &eval(u).0)));
    }
    best
}

/// Largest distance of the blend from the programmed path near the corner: samples, then
/// a golden-section search around every local maximum among them (the distance has a
/// narrow peak near the corner on long blends, and may have more than one). `fine`: the
/// resolution that decides; the coarse one (a quarter of the samples, no search) steers
/// the search for the trim.
fn deviation(shape: &Shape, a: &Near, b: &Near, fine: bool) -> f64 {
    let f = |u: f64| {
        let p = shape.pos(u);
        dist_near(&p, a).min(dist_near(&p, b))
    };
    let (n, iters) = if fine { (NDEV, 24) } else { (NDEV / 4, 0) };
    let h = 1.0 / n as f64;
    let mut y = [0.0f64; NDEV + 1];
    for (k, v) in y.iter_mut().enumerate().take(n + 1) {
        *v = f(k as f64 * h);
    }
    let mut worst = y.iter().fold(0.0f64, |m, v| m.max(*v));
    let g = 0.5 * (5f64.sqrt() - 1.0);
    for k in 1..n {
        if iters == 0 {
            break;
        }
        if !(y[k] >= y[k - 1] && y[k] >= y[k + 1] && y[k] > 0.0) {
            continue;
        }
        let (mut x0, mut x3) = ((k - 1) as f64 * h, (k + 1) as f64 * h);
        let mut x1 = x3 - g * (x3 - x0);
        let mut x2 = x0 + g * (x3 - x0);
        let (mut f1, mut f2) = (f(x1), f(x2));
        for _ in 0..iters {
            if f1 > f2 {
                x3 = x2;
                x2 = x1;
                f2 = f1;
                x1 = x3 - g * (x3 - x0);
                f1 = f(x1);
            } else {
                x0 = x1;
                x1 = x2;
                f1 = f2;
                x2 = x0 + g * (x3 - x0);
                f2 = f(x2);
            }
        }
        worst = worst.max(f1).max(f2);
    }
    worst
}

/// Speed limit at one point of a curve from each axis's centripetal acceleration and
/// curvature change (the shares the planner uses on corner blends).
fn speed_at(d: &Deriv, lim: &Lim) -> f64 {
    let (_, kv, kp) = arc_derivs(d);
    let mut v = f64::INFINITY;
    for i in 0..AXES {
        if !lim.present[i] {
            continue;
        }
        if kv[i] != 0.0 {
            v = v.min((lim.a[i] / kv[i].abs()).sqrt());
        }
        if kp[i] != 0.0 {
            v = v.min((JERK_SHARE_CURVATURE_BLEND * lim.j[i] / kp[i].abs()).cbrt());
        }
    }
    v
}

/// Lowest speed limit along the blend over `n` intervals (with `lim`, else 0) and its
/// length; None when the curve is not regular enough (|dp/du| below a tenth of `l`).
fn blend_speed(shape: &Shape, l: f64, lim: Option<&Lim>, n: usize) -> Option<(f64, f64)> {
    let mut v = f64::INFINITY;
    let mut len = 0.0;
    for k in 0..=n {
        let dv = shape.eval(k as f64 / n as f64);
        let sp = norm(&dv.d1);
        if !(sp >= MIN_PARAM_SPEED * l) {
            return None;
        }
        len += if k == 0 || k == n { 0.5 * sp } else { sp };
        v = match lim {
            Some(lim) => v.min(speed_at(&dv, lim)),
            None => 0.0,
        };
    }
    Some((v, len / n as f64))
}

/// Time through a blend following its speed limit, capped at `feed` (trapezoidal rule on
/// the samples of its speed estimate).
fn pass_time(shape: &Shape, lim: &Lim, feed: f64) -> f64 {
    let h = 1.0 / NSAMP as f64;
    let mut t = 0.0;
    for k in 0..=NSAMP {
        let dv = shape.eval(k as f64 * h);
        let w = if k == 0 || k == NSAMP { 0.5 } else { 1.0 };
        t += w * h * norm(&dv.d1) / speed_at(&dv, lim).min(feed);
    }
    t
}

/// Ceilings for the piece's velocity-limit samples: the planner takes the lower of two
/// neighbouring samples over the interval between them, so each sample gets the lowest
/// dense limit over the intervals it bounds.
fn sample_caps(b: &Piece, lim: &Lim) -> [f64; NS_MAX + 1] {
    let sub = NSAMP / b.ns;
    let h = b.len / b.ns as f64;
    let mut interval = [f64::INFINITY; NS_MAX];
    for (j, iv) in interval.iter_mut().enumerate().take(b.ns) {
        for m in 0..=sub {
            let s = h * (j as f64 + m as f64 / sub as f64);
            *iv = iv.min(speed_at(&b.shape.eval(b.map.u(s)), lim));
        }
    }
    let mut caps = [f64::INFINITY; NS_MAX + 1];
    for (k, c) in caps.iter_mut().enumerate().take(b.ns + 1) {
        if k > 0 {
            *c = c.min(interval[k - 1]);
        }
        if k < b.ns {
            *c = c.min(interval[k]);
        }
    }
    caps
}

/// The blend trimming both neighbours by `d`, with parameter length `f`·chord; its
/// deviation and speed limit measured finely (`fine`), or its deviation coarsely.
fn candidate(prev: &Prim, cur: &Prim, d: f64, f: f64, lim: &Lim, fine: bool) -> Option<ArcBlend> {
    let from = trim(prev, d, true);
    let to = trim(cur, d, false);
    let (s0, s1) = (&from.st, &to.st);
    let l = f * norm(&sub(&s1.p, &s0.p));
    if !(l > 0.0) {
        return None;
    }
    let shape = quintic(
        &s0.p,
        &scale(&s0.t, l),
        &scale(&s0.k, l * l),
        &s1.p,
        &scale(&s1.t, l),
        &scale(&s1.k, l * l),
    );
    let (speed, _) = blend_speed(&shape, l, fine.then_some(lim), NSAMP)?;
    Some(ArcBlend {
        shape,
        from,
        to,
        d,
        deviation: deviation(&shape, &from.near, &to.near, fine),
        speed,
    })
}

/// The blend of the corner between `prev` and `cur` within `tol`: for each parameter
/// length the largest trim found within the tolerance, then the fastest of those.
fn solve(
    prev: &Prim,
    st: Option<&State>,
    cur: &Prim,
    tol: f64,
    feed: f64,
    factors: &[f64],
    lim: &Lim,
) -> Option<ArcBlend> {
    let d_max = max_trim(prev, st, true).min(max_trim(cur, None, false));
    if !(d_max > 1e-9 && tol > 0.0) {
        return None;
    }
    let target = tol * (1.0 - DEV_MARGIN);
    // First guess: the reach of a line corner's blend of the same turn, then the reach
    // found for the previous parameter length.
    let turn = dot(&trim(prev, 0.0, true).st.t, &trim(cur, 0.0, false).st.t)
        .clamp(-1.0, 1.0)
        .acos();
    let mut d_start = (4.0 * tol / (0.5 * turn).sin().max(1e-6)).min(d_max);
    // Per parameter length: the blend, the factor, its lowest speed limit and its length.
    let mut found: [Option<(ArcBlend, f64, f64, f64)>; L_FACTORS.len()] = [None; L_FACTORS.len()];
    for (slot, &f) in found.iter_mut().zip(factors) {
        // The deviation grows about linearly with d: secant steps towards the target,
        // bracketed by the largest d found within it and the smallest found beyond it.
        let mut ok: Option<ArcBlend> = None;
        let mut d_bad = f64::INFINITY;
        let mut d = d_start;
        for _ in 0..D_ITER {
            let c = candidate(prev, cur, d, f, lim, false);
            match c {
                Some(c) if c.deviation <= target => {
                    if ok.is_none_or(|o| c.d > o.d) {
                        ok = Some(c);
                    }
                    if d >= d_max || c.deviation >= 0.95 * target {
                        break;
                    }
                    let next = (d * 0.99 * target / c.deviation.max(1e-300)).min(d_max);
                    d = if d_bad.is_finite() {
                        next.min(0.5 * (d + d_bad))
                    } else {
                        next
                    };
                }
                _ => {
                    d_bad = d_bad.min(d);
                    let lo = ok.map_or(0.0, |o| o.d);
                    let next = match c {
                        Some(c) => d * (0.99 * target / c.deviation).clamp(0.05, 0.95),
                        None => 0.5 * d,
                    };
                    d = if lo > 0.0 {
                        next.max(0.5 * (lo + d))
                    } else {
                        next
                    };
                }
            }
            if d < 1e-9 {
                break;
            }
        }
        if let Some(o) = ok {
            d_start = o.d;
            *slot = blend_speed(&o.shape, 0.0, Some(lim), NSAMP / 2).map(|(v, len)| (o, f, v, len));
        }
    }
    // Of the blends whose lowest speed limit is near the highest found, the one estimated
    // to take the least time (the blend at that speed and the speed changes into and out
    // of it): a long blend at a low speed can cost more than a sharper short one. (A slow
    // valley is also what the speed controller follows worst, hence the preference for
    // speed.) Whether the chosen one beats a stop is decided by the caller.
    let v_top = found.iter().flatten().fold(0.0f64, |m, c| m.max(c.2));
    let mut best: Option<(ArcBlend, f64, f64)> = None;
    for &(o, f, v, _) in found.iter().flatten() {
        if v < SPEED_PREFERENCE * v_top {
            continue;
        }
        let cost = corner_choice(
            prev,
            st,
            cur,
            feed,
            &ArcBlend { speed: v, ..o },
            pass_time(&o.shape, lim, feed),
        )?
        .times(lim)
        .1;
        if best.is_none_or(|(_, _, c)| cost < c) {
            best = Some((o, f, cost));
        }
    }
    // The fine measure decides; where it finds more than the coarse one, shorten.
    let (o, f, _) = best?;
    let mut d = o.d;
    for _ in 0..D_ITER {
        let fine = candidate(prev, cur, d, f, lim, true)?;
        if fine.deviation <= target {
            return Some(fine);
        }
        d *= (0.99 * target / fine.deviation).clamp(0.05, 0.99);
        if d < 1e-9 {
            break;
        }
    }
    None
}

#[cfg(test)]
mod tests;
