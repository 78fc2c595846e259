//! G64 P corners where a spline (G5/G5.1) meets a line, an arc or another spline: limits,
//! distance from the exact programmed path (the Bézier curve from its own Bernstein form,
//! circles and segments in closed form), exact end points, no stop at the corner in G64 (a
//! stop in G61).

use crate::common::*;
use rtcnc_motion::{AxisVec, Bezier, Move, PathMode};

const V: f64 = 100.0;
const A: f64 = 1000.0;
const J: f64 = 50_000.0;

type V2 = [f64; 2];

fn rot(v: V2, ang: f64) -> V2 {
    let (s, c) = ang.sin_cos();
    [c * v[0] - s * v[1], s * v[0] + c * v[1]]
}
fn add(a: V2, b: V2, k: f64) -> V2 {
    [a[0] + k * b[0], a[1] + k * b[1]]
}
fn pt(v: V2) -> AxisVec {
    p3(v[0], v[1], 0.0)
}
fn len(v: V2) -> f64 {
    v[0].hypot(v[1])
}

#[derive(Clone, Copy, Debug)]
enum Elem {
    Line {
        a: V2,
        b: V2,
    },
    /// Counter-clockwise about +Z: centre, radius, start angle, sweep.
    Arc {
        c: V2,
        r: f64,
        a0: f64,
        sweep: f64,
    },
    Cubic {
        p: [V2; 4],
    },
}

impl Elem {
    /// An element of kind `kind` starting at `s` along unit `t`.
    fn new(kind: &str, s: V2, t: V2) -> Elem {
        match kind {
            "line" => Elem::Line {
                a: s,
                b: add(s, t, 10.0),
            },
            "arc" => {
                let r = 10.0;
                let c = add(s, [-t[1], t[0]], r);
                Elem::Arc {
                    c,
                    r,
                    a0: (s[1] - c[1]).atan2(s[0] - c[0]),
                    sweep: 1.0,
                }
            }
            _ => {
                let p1 = add(s, t, 3.0);
                let p2 = add(p1, rot(t, 0.5), 4.0);
                let p3 = add(p2, rot(t, 0.9), 3.0);
                Elem::Cubic { p: [s, p1, p2, p3] }
            }
        }
    }
    fn at(&self, u: f64) -> V2 {
        match *self {
            Elem::Line { a, b } => add(a, [b[0] - a[0], b[1] - a[1]], u),
            Elem::Arc { c, r, a0, sweep } => {
                let th = a0 + sweep * u;
                [c[0] + r * th.cos(), c[1] + r * th.sin()]
            }
            Elem::Cubic { p } => {
                let w = [
                    (1.0 - u).powi(3),
                    3.0 * u * (1.0 - u).powi(2),
                    3.0 * u * u * (1.0 - u),
                    u.powi(3),
                ];
                let mut q = [0.0; 2];
                for k in 0..4 {
                    q = add(q, p[k], w[k]);
                }
                q
            }
        }
    }
    fn end_tangent(&self) -> V2 {
        let d = match *self {
            Elem::Line { a, b } => [b[0] - a[0], b[1] - a[1]],
            Elem::Arc { a0, sweep, .. } => {
                let th = a0 + sweep;
                [-th.sin(), th.cos()]
            }
            Elem::Cubic { p } => [p[3][0] - p[2][0], p[3][1] - p[2][1]],
        };
        let n = len(d);
        [d[0] / n, d[1] / n]
    }
    fn to_move(self, mode: PathMode, feed: f64, line: u32) -> Move {
        let end = pt(self.at(1.0));
        match self {
            Elem::Line { .. } => Move::line(end, feed, mode, line),
            Elem::Arc { c, .. } => {
                Move::arc(end, [c[0], c[1], 0.0], [0.0, 0.0, 1.0], 0, feed, mode, line)
            }
            Elem::Cubic { p } => {
                Move::spline(end, Bezier::Cubic([pt(p[1]), pt(p[2])]), feed, mode, line)
            }
        }
    }
    /// Distance of `q`: segments and circles in closed form; the cubic by a scan of 4000
    /// parameters and a golden-section search around the nearest.
    fn dist(&self, q: V2) -> f64 {
        let d = |x: V2| len([q[0] - x[0], q[1] - x[1]]);
        match *self {
            Elem::Line { a, b } => seg_dist(&pt(q), &pt(a), &pt(b)),
            Elem::Arc { c, r, a0, sweep } => {
                let phi = (q[1] - c[1]).atan2(q[0] - c[0]);
                let mid = a0 + 0.5 * sweep;
                let dphi = (phi - mid + std::f64::consts::PI)
                    .rem_euclid(2.0 * std::f64::consts::PI)
                    - std::f64::consts::PI;
                let u = (0.5 + dphi / sweep).clamp(0.0, 1.0);
                let _ = r;
                d(self.at(u))
            }
            Elem::Cubic { .. } => {
                let n = 4000;
                let (mut kb, mut best) = (0, f64::INFINITY);
                for k in 0..=n {
                    let v = d(self.at(k as f64 / n as f64));
                    if v < best {
                        best = v;
                        kb = k;
                    }
                }
                let h = 1.0 / n as f64;
                let (mut x0, mut x3) = (((kb as f64) - 1.0) * h, ((kb as f64) + 1.0) * h);
                x0 = x0.max(0.0);
                x3 = x3.min(1.0);
                let g = 0.5 * (5f64.sqrt() - 1.0);
                for _ in 0..60 {
                    let x1 = x3 - g * (x3 - x0);
                    let x2 = x0 + g * (x3 - x0);
                    if d(self.at(x1)) < d(self.at(x2)) {
                        x3 = x2;
                    } else {
                        x0 = x1;
                    }
                }
                best.min(d(self.at(0.5 * (x0 + x3))))
            }
        }
    }
}

/// Two elements meeting at a corner that turns by `turn` rad (counter-clockwise).
fn corner(first: &str, second: &str, turn: f64) -> [Elem; 2] {
    let e0 = Elem::new(first, [0.0, 0.0], [1.0, 0.0]);
    let e1 = Elem::new(second, e0.at(1.0), rot(e0.end_tangent(), turn));
    [e0, e1]
}

/// Runs the elements in `mode` at `feed`; checks limits, end point and distance from the
/// programmed path; returns the trace and the geometry statistics.
fn run_prog(
    elems: &[Elem],
    mode: PathMode,
    p: f64,
    feed: f64,
) -> (Trace, rtcnc_motion::GeometryStats) {
    let lim = limits(V, A, J);
    let mut pl = planner(&lim, pt(elems[0].at(0.0)), 256);
    let moves: Vec<Move> = elems
        .iter()
        .enumerate()
        .map(|(i, e)| e.to_move(mode, feed, i as u32 + 1))
        .collect();
    let tr = run(&mut pl, &moves, 100_000);
    let (rv, ra, rj) = ratios(&tr, V, A, J);
    let tol = 1.0 + 1e-9;
    assert!(
        rv <= tol && ra <= tol && rj <= tol,
        "{mode:?}: v {rv} a {ra} j {rj}"
    );
    assert_eq!(pl.stats().limit_violations, 0);
    let end = pt(elems.last().unwrap().at(1.0));
    let last = *tr.pts.last().unwrap();
    assert!(
        dist(&last, &end) <= 1e-9,
        "end point off by {}",
        dist(&last, &end)
    );
    let worst = tr
        .pts
        .iter()
        .map(|q| {
            elems
                .iter()
                .map(|e| e.dist([q[0], q[1]]))
                .fold(f64::INFINITY, f64::min)
        })
        .fold(0.0, f64::max);
    assert!(worst <= p + 1e-9, "deviation {worst} > P {p}");
    (tr, pl.geometry_stats())
}

fn stops_at(tr: &Trace, c: V2) -> bool {
    tr.speed
        .iter()
        .enumerate()
        .any(|(k, v)| *v == 0.0 && dist(&tr.pts[k + 3], &pt(c)) <= 1e-9)
}

/// Tolerances and feeds at which these 0.35 rad corners' blends take less time than a stop.
const TOLS: [(f64, f64); 3] = [(0.001, 2.0), (0.01, 10.0), (0.1, 30.0)];

/// All of them in release builds; debug builds leave out the slow run at F 2.
fn tols() -> &'static [(f64, f64)] {
    if cfg!(debug_assertions) {
        &TOLS[1..]
    } else {
        &TOLS
    }
}

fn check_corner(first: &str, second: &str) {
    let elems = corner(first, second, 0.35);
    let o = elems[0].at(1.0);
    for &(p, feed) in tols() {
        let (tr, gs) = run_prog(&elems, blend(p), p, feed);
        assert_eq!(gs.blends, 1, "{first}-{second} P {p}: {gs:?}");
        assert_eq!(gs.stops, 0, "{first}-{second} P {p}: {gs:?}");
        assert!(never_stops(&tr), "{first}-{second} P {p}: stopped");
        assert!(!stops_at(&tr, o));
    }
    for mode in [PathMode::ExactPath, PathMode::ExactStop] {
        let (tr, gs) = run_prog(&elems, mode, 0.0, 30.0);
        assert_eq!(gs.stops, 1);
        assert!(
            stops_at(&tr, o),
            "{first}-{second}: {mode:?} passes the corner"
        );
    }
}

#[test]
fn line_to_spline_is_blended_within_p() {
    check_corner("line", "cubic");
}

#[test]
fn spline_to_line_is_blended_within_p() {
    check_corner("cubic", "line");
}

#[test]
fn spline_to_arc_and_arc_to_spline_are_blended_within_p() {
    check_corner("cubic", "arc");
    check_corner("arc", "cubic");
}

#[test]
fn spline_to_spline_is_blended_within_p() {
    check_corner("cubic", "cubic");
}

/// A spline between two blended corners is trimmed at both ends: line, spline, line.
#[test]
fn a_spline_trimmed_at_both_ends_keeps_p_and_the_limits() {
    let e0 = Elem::new("line", [0.0, 0.0], [1.0, 0.0]);
    let e1 = Elem::new("cubic", e0.at(1.0), rot(e0.end_tangent(), 0.35));
    let e2 = Elem::new("line", e1.at(1.0), rot(e1.end_tangent(), -0.35));
    for &(p, feed) in tols() {
        let (tr, gs) = run_prog(&[e0, e1, e2], blend(p), p, feed);
        assert_eq!((gs.blends, gs.stops), (2, 0), "P {p}: {gs:?}");
        assert!(never_stops(&tr));
    }
}

/// A small deterministic generator (xorshift), so that every run checks the same programs.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Random chains of three elements, at least one a cubic with random control points
/// (scaled, turned), meeting at corners of up to 1.2 rad either way, P 0.001 to 0.1, F 5 to
/// 60: every set-point within P of the exact elements and within the limits, exact end
/// points, whatever the blend-or-stop choice decides; in all, no slower than G61.
#[test]
fn random_spline_corners_keep_p_the_limits_and_the_end_point() {
    let n = if cfg!(debug_assertions) { 6 } else { 200 };
    let mut rng = Rng(0x5DEE_CE66_D1CE_4E5B);
    let kinds = ["line", "arc", "cubic"];
    let (mut blends, mut stops) = (0, 0);
    let (mut periods_g64, mut periods_g61, mut slower) = (0, 0, 0);
    for _ in 0..n {
        let mut elems: Vec<Elem> = Vec::new();
        let (mut at, mut t) = ([0.0, 0.0], [1.0, 0.0]);
        for k in 0..3 {
            let kind = if k == 1 {
                "cubic"
            } else {
                kinds[(rng.next() * 3.0) as usize]
            };
            if k > 0 {
                t = rot(t, (rng.next() - 0.5) * 2.4);
            }
            let e = match Elem::new(kind, at, t) {
                Elem::Cubic { p } => {
                    // Scaled by 0.3 to 2 and the inner turns varied.
                    let s = 0.3 + 1.7 * rng.next();
                    let p1 = add(p[0], t, 3.0 * s);
                    let p2 = add(p1, rot(t, (rng.next() - 0.5) * 2.0), 4.0 * s);
                    let p3 = add(p2, rot(t, (rng.next() - 0.5) * 2.0), 3.0 * s);
                    Elem::Cubic {
                        p: [p[0], p1, p2, p3],
                    }
                }
                e => e,
            };
            at = e.at(1.0);
            t = e.end_tangent();
            elems.push(e);
        }
        let p = [0.001, 0.01, 0.1][(rng.next() * 3.0) as usize];
        let feed = 5.0 + 55.0 * rng.next();
        let lim = limits(V, A, J);
        let mut probe = planner(&lim, pt(elems[0].at(0.0)), 256);
        let moves: Vec<Move> = elems
            .iter()
            .enumerate()
            .map(|(i, e)| e.to_move(blend(p), feed, i as u32 + 1))
            .collect();
        // A curve refused as a (near) cusp is skipped.
        if moves.iter().any(|m| probe.push(m).is_err()) {
            continue;
        }
        let (tr, gs) = run_prog(&elems, blend(p), p, feed);
        blends += gs.blends;
        stops += gs.stops;
        let (exact, _) = run_prog(&elems, PathMode::ExactPath, 0.0, feed);
        periods_g64 += tr.speed.len();
        periods_g61 += exact.speed.len();
        slower += usize::from(tr.speed.len() > exact.speed.len());
    }
    println!(
        "{n} programs: {blends} corners blended, {stops} stopped; \
         {periods_g64} periods in G64, {periods_g61} in G61, {slower} programs slower in G64"
    );
    // Each choice is an estimate (the speed controller may pass a valley more slowly than
    // the jerk-limited profile it assumes): the sum must not be slower.
    assert!(periods_g64 <= periods_g61);
    // Both choices are exercised: the checks above cover real blends at splines.
    assert!(blends > 0 && stops > 0, "{blends} blended, {stops} stopped");
}
