//! Spline moves (G5 cubic, G5.1 quadratic Bézier): every set-point on the analytic curve,
//! exact end points, limits kept, tangent junctions passed without a stop, soft limits on
//! the curve's bulge, bad input refused.

use crate::common::*;
use rtcnc_motion::{
    AXES, Axis, AxisLimits, AxisVec, Bezier, CurvePart, MachineLimits, Move, MoveKind, PathMode,
};

const V: f64 = 100.0;
const A: f64 = 1000.0;
const J: f64 = 50_000.0;

/// The Bézier curve through `pts` (3 or 4 points) at parameter t, in Bernstein form (the
/// textbook definition, independent of the planner's power basis).
fn bezier(pts: &[AxisVec], t: f64) -> AxisVec {
    let s = 1.0 - t;
    let (w, n) = match pts.len() {
        3 => ([s * s, 2.0 * s * t, t * t, 0.0], 3),
        4 => ([s * s * s, 3.0 * s * s * t, 3.0 * s * t * t, t * t * t], 4),
        _ => unreachable!(),
    };
    let mut p = [0.0; AXES];
    for k in 0..n {
        for i in 0..AXES {
            p[i] += w[k] * pts[k][i];
        }
    }
    p
}

/// Distance of `p` from the curve: every local minimum of the distance on a grid (a loop
/// brings two branches close), refined by a ternary search within the grid cells next to
/// it.
fn distance_to_curve(pts: &[AxisVec], p: &AxisVec) -> f64 {
    let d2 = |t: f64| {
        let b = bezier(pts, t);
        (0..AXES).map(|i| (b[i] - p[i]).powi(2)).sum::<f64>()
    };
    let n = 300;
    let h = 1.0 / n as f64;
    let grid: Vec<f64> = (0..=n).map(|k| d2(k as f64 * h)).collect();
    let mut best = f64::INFINITY;
    for k in 0..=n {
        let left = k == 0 || grid[k] <= grid[k - 1];
        let right = k == n || grid[k] <= grid[k + 1];
        if !(left && right) {
            continue;
        }
        let (mut lo, mut hi) = ((k as f64 * h - h).max(0.0), (k as f64 * h + h).min(1.0));
        for _ in 0..100 {
            let (a, b) = (lo + (hi - lo) / 3.0, hi - (hi - lo) / 3.0);
            if d2(a) < d2(b) {
                hi = b;
            } else {
                lo = a;
            }
        }
        best = best.min(d2(0.5 * (lo + hi))).min(grid[k]);
    }
    best.sqrt()
}

fn check_on_curve(tr: &Trace, pts: &[AxisVec]) {
    let mut worst = 0.0f64;
    for p in &tr.pts {
        worst = worst.max(distance_to_curve(pts, p));
    }
    assert!(worst <= 1e-9, "a set-point is {worst} mm off the curve");
}

fn spline_run(moves: &[Move], start: AxisVec) -> Trace {
    let lim = limits(V, A, J);
    let mut pl = planner(&lim, start, 256);
    let tr = run(&mut pl, moves, 50_000);
    assert_limits(&tr, V, A, J);
    assert_eq!(pl.stats().limit_violations, 0);
    tr
}

#[test]
fn cubic_spline_set_points_lie_on_the_bezier_and_end_exactly() {
    // An S curve with an inflection: its curvature peaks away from the ends.
    let pts = [
        p3(0.0, 0.0, 0.0),
        p3(10.0, 15.0, 0.0),
        p3(20.0, -15.0, 0.0),
        p3(30.0, 0.0, 0.0),
    ];
    let mv = Move::spline(
        pts[3],
        Bezier::Cubic([pts[1], pts[2]]),
        100.0,
        PathMode::ExactPath,
        1,
    );
    let tr = spline_run(&[mv], pts[0]);
    check_on_curve(&tr, &pts);
    assert!(dist(tr.pts.last().unwrap(), &pts[3]) <= 1e-12);
}

#[test]
fn quadratic_spline_set_points_lie_on_the_parabola_and_end_exactly() {
    let pts = [p3(1.0, 2.0, 0.0), p3(6.0, 12.0, 0.0), p3(11.0, 2.0, 0.0)];
    let mv = Move::spline(
        pts[2],
        Bezier::Quadratic(pts[1]),
        80.0,
        PathMode::ExactPath,
        1,
    );
    let tr = spline_run(&[mv], pts[0]);
    check_on_curve(&tr, &pts);
    assert!(dist(tr.pts.last().unwrap(), &pts[2]) <= 1e-12);
}

/// A cubic whose inner control points cross: a hairpin at t = 1/2.
fn hairpin(c1x: f64, c2x: f64, line: u32) -> (Move, [AxisVec; 4]) {
    let pts = [
        p3(0.0, 0.0, 0.0),
        p3(c1x, 8.0, 0.0),
        p3(c2x, 8.0, 0.0),
        p3(10.0, 0.0, 0.0),
    ];
    let mv = Move::spline(
        pts[3],
        Bezier::Cubic([pts[1], pts[2]]),
        100.0,
        PathMode::ExactPath,
        line,
    );
    (mv, pts)
}

#[test]
fn a_tight_spline_slows_down_to_its_curvature_and_keeps_the_limits() {
    // At t = 1/2: B' = (6, 0), B'' = (0, -48): radius 0.75 mm, so the centripetal limit
    // there is sqrt(1000 · 0.75) = 27.4 mm/s.
    let (mv, pts) = hairpin(6.0, 4.0, 3);
    let tr = spline_run(&[mv], pts[0]);
    check_on_curve(&tr, &pts);
    assert!(dist(tr.pts.last().unwrap(), &pts[3]) <= 1e-12);
    let apex = p3(5.0, 6.0, 0.0);
    let v_apex = speed_near(&tr, &apex);
    assert!(v_apex <= (A * 0.75f64).sqrt() * (1.0 + 1e-6), "{v_apex}");
    // Hairpins down to a radius of 0.19 mm (B' = (3, 0), B'' = (0, -48) at the apex),
    // at two feeds: on the curve, within the limits, at rest at the end.
    for (c1x, c2x) in [(12.0, -2.0), (6.0, 0.0), (10.0, 2.0), (14.0, -4.0)] {
        for feed in [30.0, 100.0] {
            let (mut mv, pts) = hairpin(c1x, c2x, 4);
            mv.feed = rtcnc_motion::Feed::UnitsPerSecond(feed);
            let tr = spline_run(&[mv], pts[0]);
            check_on_curve(&tr, &pts);
            assert!(dist(tr.pts.last().unwrap(), &pts[3]) <= 1e-12);
        }
    }
}

#[test]
fn a_spline_with_z_moving_linearly_is_a_helix_like_curve() {
    // XY cubic; Z from 0 to 3 with control values at thirds: linear in the parameter.
    let pts = [
        p3(0.0, 0.0, 0.0),
        p3(5.0, 5.0, 1.0),
        p3(10.0, 5.0, 2.0),
        p3(15.0, 0.0, 3.0),
    ];
    let mv = Move::spline(
        pts[3],
        Bezier::Cubic([pts[1], pts[2]]),
        60.0,
        PathMode::ExactPath,
        1,
    );
    let tr = spline_run(&[mv], pts[0]);
    check_on_curve(&tr, &pts);
    assert!(dist(tr.pts.last().unwrap(), &pts[3]) <= 1e-12);
}

/// Whether the trace comes to rest exactly at `c` (see [`rests_at`]).
fn stops_at(tr: &Trace, c: &AxisVec) -> bool {
    rests_at(tr, c, J * T * T * T)
}

/// Path speed (from set-point steps) where the trace passes nearest to `c`.
fn speed_near(tr: &Trace, c: &AxisVec) -> f64 {
    let k = (1..tr.pts.len())
        .min_by(|a, b| {
            dist(&tr.pts[*a], c)
                .partial_cmp(&dist(&tr.pts[*b], c))
                .unwrap()
        })
        .unwrap();
    dist(&tr.pts[k], &tr.pts[k - 1]) / T
}

#[test]
fn tangent_junctions_do_not_stop_and_corners_do() {
    // Line along +X, then a G5 chain leaving along +X (first control point on the line's
    // direction), the second G5 starting with the reflection of the first one's last
    // control point about their common point (as G5 without I J does), then a line along
    // the last tangent, then a corner. The curvature steps at these junctions (the curves
    // bend at their ends) bound the speed there (v²·|ΔK| ≤ J·T/2), but nothing stops.
    let p0 = p3(0.0, 0.0, 0.0);
    let p1 = p3(10.0, 0.0, 0.0);
    let s1 = [p3(14.0, 0.0, 0.0), p3(16.0, 6.0, 0.0), p3(20.0, 6.0, 0.0)];
    let s2 = [p3(24.0, 6.0, 0.0), p3(26.0, 0.0, 0.0), p3(30.0, 0.0, 0.0)];
    let p2 = p3(40.0, 0.0, 0.0);
    let p3_ = p3(40.0, 10.0, 0.0);
    for mode in [
        PathMode::ExactPath,
        PathMode::Blend {
            tolerance: 0.01,
            merge_tolerance: 0.0,
        },
    ] {
        let moves = [
            Move::line(p1, 80.0, mode, 1),
            Move::spline(s1[2], Bezier::Cubic([s1[0], s1[1]]), 80.0, mode, 2),
            Move::spline(s2[2], Bezier::Cubic([s2[0], s2[1]]), 80.0, mode, 3),
            Move::line(p2, 80.0, mode, 4),
            Move::line(p3_, 80.0, mode, 5),
        ];
        let tr = spline_run(&moves, p0);
        for c in [p1, s1[2], s2[2]] {
            assert!(
                !stops_at(&tr, &c),
                "{mode:?}: stopped at tangent junction {c:?}"
            );
            assert!(speed_near(&tr, &c) > 1.0, "{mode:?}: crawled through {c:?}");
        }
        if mode == PathMode::ExactPath {
            assert!(stops_at(&tr, &p2));
        }
        assert!(dist(tr.pts.last().unwrap(), &p3_) <= 1e-12);
    }
    // Curvature-continuous junctions: a cubic with both inner control points on the corner
    // of two lines has zero curvature at its ends (it meets the lines without a step), so
    // the junctions are passed fast: only the curve's own curvature slows the path.
    let corner = p3(15.0, 0.0, 0.0);
    let moves = [
        Move::line(p1, 80.0, PathMode::ExactPath, 1),
        Move::spline(
            p3(15.0, 5.0, 0.0),
            Bezier::Cubic([corner, corner]),
            80.0,
            PathMode::ExactPath,
            2,
        ),
        Move::line(p3(15.0, 20.0, 0.0), 80.0, PathMode::ExactPath, 3),
    ];
    let tr = spline_run(&moves, p0);
    for c in [p1, p3(15.0, 5.0, 0.0)] {
        assert!(
            speed_near(&tr, &c) > 30.0,
            "slow at {c:?}: {}",
            speed_near(&tr, &c)
        );
    }
    // A spline that does not leave along the line's direction: a corner, a stop in G61;
    // G64 P 0.1 blends it (`spline_blends.rs`), the path passes it without stopping.
    for mode in [
        PathMode::ExactPath,
        PathMode::Blend {
            tolerance: 0.1,
            merge_tolerance: 0.0,
        },
    ] {
        let moves = [
            Move::line(p1, 80.0, mode, 1),
            Move::spline(
                s1[2],
                Bezier::Cubic([p3(14.0, 1.0, 0.0), s1[1]]),
                80.0,
                mode,
                2,
            ),
        ];
        let tr = spline_run(&moves, p0);
        let exact = mode == PathMode::ExactPath;
        assert_eq!(stops_at(&tr, &p1), exact, "{mode:?}: stop at the corner");
    }
}

fn enveloped() -> rtcnc_motion::Planner<rtcnc_motion::TrivialKinematics> {
    let lim = MachineLimits::uniform(
        &[Axis::X, Axis::Y, Axis::Z],
        AxisLimits::new(V, A, J, -50.0, 50.0),
    );
    planner(&lim, p3(0.0, 0.0, 0.0), 64)
}

#[test]
fn soft_limits_check_the_bulge_of_the_curve_not_only_its_ends() {
    // Cubic with both inner control points at height h: the top of the curve is at
    // y = 3/4 h (at t = 1/2), whatever the control points' own height.
    let arch = |h: f64, line| {
        Move::spline(
            p3(40.0, 0.0, 0.0),
            Bezier::Cubic([p3(0.0, h, 0.0), p3(40.0, h, 0.0)]),
            50.0,
            PathMode::ExactPath,
            line,
        )
    };
    let mut pl = enveloped();
    // Control points at y = 60 (outside), curve top at 45 (inside): accepted.
    pl.push(&arch(60.0, 10)).unwrap();
    let mut pl = enveloped();
    let e = pl.push(&arch(70.0, 11)).unwrap_err();
    assert_eq!((e.code(), e.line()), ("MOTION-008", Some(11)));
    match e {
        rtcnc_motion::MotionError::SoftLimit { axis, position, .. } => {
            assert_eq!(axis, 'Y');
            assert!((position - 52.5).abs() <= 1e-12, "{position}");
        }
        _ => unreachable!(),
    }
    // A quadratic's top is at half its control point's height: 104 gives 52.
    let mut pl = enveloped();
    let e = pl
        .push(&Move::spline(
            p3(20.0, 0.0, 0.0),
            Bezier::Quadratic(p3(10.0, 104.0, 0.0)),
            50.0,
            PathMode::ExactPath,
            12,
        ))
        .unwrap_err();
    assert_eq!((e.code(), e.line()), ("MOTION-008", Some(12)));
    // The refused move is not taken: the planner still accepts the next good one.
    pl.push(&arch(40.0, 13)).unwrap();
}

#[test]
fn bad_splines_are_refused_with_a_code_and_the_line() {
    let cubic = |c1: AxisVec, c2: AxisVec, end: AxisVec, line| {
        Move::spline(
            end,
            Bezier::Cubic([c1, c2]),
            50.0,
            PathMode::ExactPath,
            line,
        )
    };
    let o = p3(0.0, 0.0, 0.0);
    let cases = [
        // NaN control point.
        (
            cubic(
                p3(f64::NAN, 0.0, 0.0),
                p3(2.0, 1.0, 0.0),
                p3(3.0, 0.0, 0.0),
                20,
            ),
            "MOTION-002",
        ),
        // Everything on the start point: no motion.
        (cubic(o, o, o, 21), "MOTION-003"),
        // First control point on the start point: no direction (infinite curvature) there.
        (
            cubic(o, p3(2.0, 1.0, 0.0), p3(3.0, 0.0, 0.0), 22),
            "MOTION-012",
        ),
        // Last control point on the end point.
        (
            cubic(p3(1.0, 1.0, 0.0), p3(3.0, 0.0, 0.0), p3(3.0, 0.0, 0.0), 23),
            "MOTION-012",
        ),
        // A cusp: the curve runs out to x = 2.25 and comes back (collinear control points
        // going back and forth).
        (
            cubic(p3(3.0, 0.0, 0.0), p3(3.0, 0.0, 0.0), p3(1.0, 0.0, 0.0), 24),
            "MOTION-012",
        ),
        // A quadratic turning back on itself.
        (
            Move::spline(
                p3(1.0, 0.0, 0.0),
                Bezier::Quadratic(p3(4.0, 0.0, 0.0)),
                50.0,
                PathMode::ExactPath,
                25,
            ),
            "MOTION-012",
        ),
        // An axis the machine does not have (A) moved by a control point.
        (
            {
                let mut c = p3(1.0, 1.0, 0.0);
                c[3] = 5.0;
                cubic(c, p3(2.0, 1.0, 0.0), p3(3.0, 0.0, 0.0), 26)
            },
            "MOTION-008",
        ),
    ];
    for (mv, code) in cases {
        let mut pl = enveloped();
        let e = pl.push(&mv).unwrap_err();
        assert_eq!((e.code(), e.line()), (code, Some(mv.line)), "{e}");
    }
    // A near cusp: the parametric speed falls to 0.26 % of its largest (regular), but the
    // curve turns on a radius of 8 nm there.
    let mut pl = planner(
        &limits(V, A, J),
        p3(3.1887258314998213, 0.7356281137639603, 0.0),
        64,
    );
    let e = pl
        .push(&Move::spline(
            p3(2.215878192136022, 0.1613738554755767, 0.0),
            Bezier::Cubic([
                p3(4.686116984651003, -0.07399006585920931, 0.0),
                p3(0.945332027915605, 0.24124691679413082, 0.0),
            ]),
            50.0,
            PathMode::ExactPath,
            28,
        ))
        .unwrap_err();
    assert_eq!((e.code(), e.line()), ("MOTION-012", Some(28)));
    assert!(e.to_string().contains("0.1 µm"), "{e}");
    // Bad feed on a spline.
    let mut pl = enveloped();
    let mut mv = cubic(p3(1.0, 1.0, 0.0), p3(2.0, 1.0, 0.0), p3(3.0, 0.0, 0.0), 27);
    mv.feed = rtcnc_motion::Feed::UnitsPerSecond(0.0);
    assert_eq!(pl.push(&mv).unwrap_err().code(), "MOTION-004");
    assert!(matches!(mv.kind, MoveKind::Spline { .. }));
}

#[test]
fn a_long_spline_chain_through_the_smallest_window_ends_exactly() {
    // Twenty tangent G5 arches (each leaving along +X and arriving along +X), a dwell after
    // every fifth: a spline and a dwell fill a move's room in the window, and the flush at
    // the end adds the held spline's pieces. The window of 8 pieces must never overrun.
    let mut moves = Vec::new();
    let mut x = 0.0;
    for k in 0..20 {
        let h = if k % 2 == 0 { 3.0 } else { -3.0 };
        moves.push(Move::spline(
            p3(x + 6.0, 0.0, 0.0),
            Bezier::Cubic([p3(x + 2.0, h, 0.0), p3(x + 4.0, h, 0.0)]),
            60.0,
            PathMode::ExactPath,
            k + 1,
        ));
        if k % 5 == 4 {
            moves.push(Move::dwell(0.01, k + 1));
        }
        x += 6.0;
    }
    let lim = limits(V, A, J);
    // Fill the window before the first period, then flush (a program end with the window
    // full): the flush must find room for the held spline.
    let mut pl = planner(&lim, p3(0.0, 0.0, 0.0), 8);
    let mut taken = 0;
    while pl.free() > 0 {
        pl.push(&moves[taken]).unwrap();
        taken += 1;
    }
    pl.flush();
    assert!(pl.window_len() <= 8, "window overrun: {}", pl.window_len());
    let end = match moves[taken - 1].kind {
        MoveKind::Spline { end, .. } => end,
        _ => unreachable!(),
    };
    let tr = run(&mut pl, &[], 100_000);
    assert_limits(&tr, V, A, J);
    assert!(dist(tr.pts.last().unwrap(), &end) <= 1e-12);
    // And the whole chain, pushed as the window drains.
    let mut pl = planner(&lim, p3(0.0, 0.0, 0.0), 8);
    let tr = run(&mut pl, &moves, 100_000);
    assert_limits(&tr, V, A, J);
    assert_eq!(pl.stats().limit_violations, 0);
    assert!(dist(tr.pts.last().unwrap(), &p3(120.0, 0.0, 0.0)) <= 1e-12);
    // Every set-point on its arch.
    let mut worst = 0.0f64;
    for p in &tr.pts {
        let k = ((p[0] / 6.0).floor() as usize).min(19);
        let x0 = 6.0 * k as f64;
        let h = if k % 2 == 0 { 3.0 } else { -3.0 };
        let arch = [
            p3(x0, 0.0, 0.0),
            p3(x0 + 2.0, h, 0.0),
            p3(x0 + 4.0, h, 0.0),
            p3(x0 + 6.0, 0.0, 0.0),
        ];
        worst = worst.max(distance_to_curve(&arch, p));
    }
    assert!(worst <= 1e-9, "{worst}");
}

#[test]
fn hold_resume_and_override_on_a_spline_stay_on_the_curve() {
    let pts = [
        p3(0.0, 0.0, 0.0),
        p3(10.0, 15.0, 0.0),
        p3(20.0, -15.0, 0.0),
        p3(30.0, 0.0, 0.0),
    ];
    let mv = Move::spline(
        pts[3],
        Bezier::Cubic([pts[1], pts[2]]),
        100.0,
        PathMode::ExactPath,
        1,
    );
    let lim = limits(V, A, J);
    let mut pl = planner(&lim, pts[0], 64);
    let tr = run_with(&mut pl, &[mv], 50_000, |n, pl| match n {
        150 => pl.hold(),
        600 => pl.resume(),
        700 => pl.set_feed_override(0.5),
        900 => pl.set_feed_override(1.7),
        _ => {}
    });
    assert_limits(&tr, V, A, J);
    assert_eq!(pl.stats().limit_violations, 0);
    check_on_curve(&tr, &pts);
    // Held: the set-point stands still between the hold's stop and the resume.
    let held = &tr.pts[3 + 450..3 + 600];
    assert!(held.iter().all(|p| p == &held[0]));
    assert!(
        held[0][0] > 1.0 && held[0][0] < 29.0,
        "held at {:?}",
        held[0]
    );
    assert!(dist(tr.pts.last().unwrap(), &pts[3]) <= 1e-12);
}

/// `Bezier::is_followable` says which curves the planner refuses for their shape (the ones
/// above with MOTION-012), and `Bezier::flatten` gives chords within the tolerance of the
/// curve (measured against the Bernstein form) ending exactly at its end.
#[test]
fn a_curve_the_planner_refuses_flattens_into_chords_within_the_tolerance() {
    let o = p3(0.0, 0.0, 0.0);
    // The textbook cusp: the derivative vanishes at t = 0.5.
    let cusp = [o, p3(1.0, 1.0, 0.0), p3(0.0, 1.0, 0.0), p3(1.0, 0.0, 0.0)];
    let arch = [o, p3(1.0, 1.0, 0.0), p3(2.0, 1.0, 0.0), p3(3.0, 0.0, 0.0)];
    let parabola = [o, p3(1.0, 2.0, 0.5), p3(2.0, 0.0, 1.0)];
    let refused_by_the_planner = |pts: &[AxisVec]| {
        let control = match pts.len() {
            3 => Bezier::Quadratic(pts[1]),
            _ => Bezier::Cubic([pts[1], pts[2]]),
        };
        let mut pl = planner(&limits(V, A, J), o, 64);
        let refused = matches!(
            pl.push(&Move::spline(*pts.last().unwrap(), control, 50.0, PathMode::ExactPath, 1)),
            Err(e) if e.code() == "MOTION-012"
        );
        (control, refused)
    };
    for (pts, followable) in [(&cusp[..], false), (&arch[..], true), (&parabola[..], true)] {
        let (control, refused) = refused_by_the_planner(pts);
        let end = *pts.last().unwrap();
        assert_eq!(control.is_followable(&o, &end), followable);
        assert_eq!(refused, !followable);
        for tolerance in [1e-3, 1e-5] {
            let mut points = Vec::new();
            control.flatten(&o, &end, tolerance, &mut points);
            assert_eq!(*points.last().unwrap(), end);
            let mut prev = o;
            for p in &points {
                // Every vertex on the curve, every chord's middle and quarters within the
                // tolerance of it.
                assert!(distance_to_curve(pts, p) <= 1e-12, "{p:?}");
                for f in [0.25, 0.5, 0.75] {
                    let q: AxisVec = std::array::from_fn(|i| prev[i] + f * (p[i] - prev[i]));
                    assert!(distance_to_curve(pts, &q) <= tolerance, "{q:?}");
                }
                prev = *p;
            }
            // And the curve within the tolerance of the chords: as many chords as the
            // curvature asks for, not one per sample.
            assert!(points.len() < 200 || tolerance < 1e-4, "{}", points.len());
        }
    }
}

/// The moves of a curve cut at its cusps (`Bezier::split_at_cusps`), from `a`.
fn cusp_moves(control: Bezier, a: &AxisVec, b: &AxisVec, mode: PathMode) -> Vec<Move> {
    let mut parts = Vec::new();
    assert!(control.split_at_cusps(a, b, 1e-3, &mut parts), "not cut");
    assert!(parts.len() >= 2, "{parts:?}");
    parts
        .iter()
        .map(|part| match *part {
            CurvePart::Curve { end, control } => Move::spline(end, control, 50.0, mode, 1),
            CurvePart::Line { end } => Move::line(end, 50.0, mode, 1),
        })
        .collect()
}

/// A curve that stops and turns back (a cusp) is cut there: the exact curve up to a few
/// tenths of a µm before the cusp, chords into it and out of it, the curve on. The machine
/// comes to rest at the cusp and goes on, every set-point within the chords' tolerance
/// (1 µm) and P of the curve, the limits kept, the end exact. Hand-worked cusps:
/// P0 (0,0), P1 (10,10), P2 (0,10), P3 (10,0):
/// B'(t) = 3[(1-t)²(10,10) + 2t(1-t)(-10,0) + t²(10,-10)] vanishes at t = 1/2, where
/// B = (P0 + 3 P1 + 3 P2 + P3)/8 = (5, 7.5). The quadratic from (0,0) through (10,0) to
/// (5,0) runs out and back along X: B'(t) = 2[(1-t)(10) + t(-5)] vanishes at t = 2/3,
/// B = 4/9·10 + 4/9·5 = 20/3.
#[test]
fn a_spline_with_a_cusp_comes_to_rest_there_and_goes_on() {
    let o = p3(0.0, 0.0, 0.0);
    let cubic = [
        o,
        p3(10.0, 10.0, 0.0),
        p3(0.0, 10.0, 0.0),
        p3(10.0, 0.0, 0.0),
    ];
    let quadratic = [o, p3(10.0, 0.0, 0.0), p3(5.0, 0.0, 0.0)];
    let cases = [
        (
            &cubic[..],
            Bezier::Cubic([cubic[1], cubic[2]]),
            p3(5.0, 7.5, 0.0),
        ),
        (
            &quadratic[..],
            Bezier::Quadratic(quadratic[1]),
            p3(20.0 / 3.0, 0.0, 0.0),
        ),
    ];
    for (pts, control, cusp) in cases {
        let end = *pts.last().unwrap();
        assert!(!control.is_followable(&o, &end));
        for (mode, p) in [(PathMode::ExactPath, 0.0), (blend(0.01), 0.01)] {
            let moves = cusp_moves(control, &o, &end, mode);
            // The chords meet at the cusp, the parts join end to start.
            let corner = moves
                .iter()
                .filter_map(|mv| match mv.kind {
                    MoveKind::Line { end, .. } => Some(end),
                    _ => None,
                })
                .map(|e| dist(&e, &cusp))
                .fold(f64::INFINITY, f64::min);
            assert!(corner <= 1e-12, "no chord ends at the cusp: {corner}");
            let tr = spline_run(&moves, o);
            // At rest on the cusp (the golden-section search finds t within 1e-9 and the
            // curve is still there within 1e-12): a set-point on it whose steps to and
            // from it are at most one period of the jerk (J·T³), as a stop's are.
            let rests = tr.pts.windows(3).any(|w| {
                dist(&w[1], &cusp) <= 1e-9
                    && dist(&w[0], &w[1]) <= J * T * T * T
                    && dist(&w[2], &w[1]) <= J * T * T * T
            });
            assert!(rests, "{mode:?}: does not come to rest at the cusp");
            assert_eq!(*tr.pts.last().unwrap(), end);
            let worst = tr
                .pts
                .iter()
                .map(|q| distance_to_curve(pts, q))
                .fold(0.0, f64::max);
            assert!(
                worst <= 1e-3 + p + 1e-9,
                "a set-point is {worst} mm off the curve"
            );
        }
    }
}

/// Near cusps (the curve turns on a radius below 0.1 µm without stopping) and a control
/// point on an end point are cut the same way; a curve the planner follows is one part.
#[test]
fn near_cusps_and_ends_without_direction_are_cut_and_followable_curves_are_not() {
    let o = p3(0.0, 0.0, 0.0);
    let runs = [
        // P2 a µm off the textbook cusp: the curve turns on a radius far below 0.1 µm.
        [
            o,
            p3(10.0, 10.0, 0.0),
            p3(0.000_001, 10.0, 0.0),
            p3(10.0, 0.0, 0.0),
        ],
        // The first control point on the start point: no direction there.
        [o, o, p3(0.0, 10.0, 0.0), p3(10.0, 10.0, 0.0)],
    ];
    for pts in runs {
        let control = Bezier::Cubic([pts[1], pts[2]]);
        assert!(!control.is_followable(&o, &pts[3]));
        let moves = cusp_moves(control, &o, &pts[3], PathMode::ExactPath);
        let tr = spline_run(&moves, o);
        assert_eq!(*tr.pts.last().unwrap(), pts[3]);
        let worst = tr
            .pts
            .iter()
            .map(|q| distance_to_curve(&pts, q))
            .fold(0.0, f64::max);
        assert!(
            worst <= 1e-3 + 1e-9,
            "a set-point is {worst} mm off the curve"
        );
    }
    let arch = [o, p3(1.0, 1.0, 0.0), p3(2.0, 1.0, 0.0), p3(3.0, 0.0, 0.0)];
    let control = Bezier::Cubic([arch[1], arch[2]]);
    let mut parts = Vec::new();
    assert!(control.split_at_cusps(&o, &arch[3], 1e-3, &mut parts));
    assert_eq!(
        parts,
        [CurvePart::Curve {
            end: arch[3],
            control
        }]
    );
}
