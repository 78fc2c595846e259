//! Arcs whose end point is not at the start point's distance from the centre (CAM output
//! rounded to a few decimals, within the interpreter's tolerance) run as LinuxCNC runs them:
//! a spiral whose radius changes linearly with the angle from the start radius to the end
//! radius (LinuxCNC's `pmCirclePoint`: radius + spiral · θ / angle), the helix rise linear in
//! the angle too. The reference here is that closed form.

use crate::common::*;
use rtcnc_motion::{AxisVec, MotionError, Move, PathMode};
use std::f64::consts::{FRAC_PI_2, PI, TAU};

const V: f64 = 100.0;
const A: f64 = 1000.0;
const J: f64 = 50_000.0;

/// A spiral in the plane spanned by the unit vectors `e1`, `e2` (normal `e1 × e2`, the
/// counter-clockwise sense), around `c`: from radius `r0` at angle 0 to `r1` at `sweep`,
/// rising `rise` along the normal.
#[derive(Clone, Copy)]
struct Spiral {
    c: [f64; 3],
    e1: [f64; 3],
    e2: [f64; 3],
    r0: f64,
    r1: f64,
    sweep: f64,
    rise: f64,
}

impl Spiral {
    fn normal(&self) -> [f64; 3] {
        let (a, b) = (self.e1, self.e2);
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    }
    fn at(&self, th: f64) -> AxisVec {
        let r = self.r0 + (self.r1 - self.r0) * th / self.sweep;
        let h = self.rise * th / self.sweep;
        let n = self.normal();
        let (s, co) = th.sin_cos();
        let q: Vec<f64> = (0..3)
            .map(|i| self.c[i] + r * (co * self.e1[i] + s * self.e2[i]) + h * n[i])
            .collect();
        p3(q[0], q[1], q[2])
    }
    /// Distance of `p` from the spiral: at the angle of `p` (unwrapped near `hint`), the
    /// offsets from the spiral's radius and height there.
    fn error(&self, p: &AxisVec, hint: f64) -> (f64, f64) {
        let n = self.normal();
        let d: Vec<f64> = (0..3).map(|i| p[i] - self.c[i]).collect();
        let a1 = d[0] * self.e1[0] + d[1] * self.e1[1] + d[2] * self.e1[2];
        let a2 = d[0] * self.e2[0] + d[1] * self.e2[1] + d[2] * self.e2[2];
        let h = d[0] * n[0] + d[1] * n[1] + d[2] * n[2];
        let mut th = a2.atan2(a1);
        th += TAU * ((hint - th) / TAU).round();
        let th = th.clamp(0.0, self.sweep);
        let r = self.r0 + (self.r1 - self.r0) * th / self.sweep;
        let rise = self.rise * th / self.sweep;
        ((a1.hypot(a2) - r).abs(), (h - rise).abs())
    }
    fn arc_move(&self, feed: f64, mode: PathMode, tolerance: f64) -> Move {
        let turns = ((self.sweep - 1e-9) / TAU).floor() as u32;
        Move::arc(
            self.at(self.sweep),
            self.c,
            self.normal(),
            turns,
            feed,
            mode,
            1,
        )
        .with_radius_tolerance(tolerance)
    }
}

fn run_spiral(sp: &Spiral, feed: f64) -> Trace {
    let start = sp.at(0.0);
    let lim = limits(V, A, J);
    let mut pl = planner(&lim, start, 64);
    let diff = (sp.r1 - sp.r0).abs();
    let tr = run(
        &mut pl,
        &[sp.arc_move(feed, PathMode::ExactStop, diff)],
        400_000,
    );
    assert_limits(&tr, V, A, J);
    assert_eq!(pl.stats().limit_violations, 0);
    let last = *tr.pts.last().unwrap();
    assert!(dist(&last, &sp.at(sp.sweep)) <= 1e-9, "end {last:?}");
    // Every set-point on the spiral (the angle only grows: unwrap along the way).
    let mut hint = 0.0;
    for p in &tr.pts {
        let (dr, dh) = sp.error(p, hint);
        assert!(dr <= 1e-9 && dh <= 1e-9, "{dr} {dh} at {p:?}");
        let d: Vec<f64> = (0..3).map(|i| p[i] - sp.c[i]).collect();
        let a1 = d[0] * sp.e1[0] + d[1] * sp.e1[1] + d[2] * sp.e1[2];
        let a2 = d[0] * sp.e2[0] + d[1] * sp.e2[1] + d[2] * sp.e2[2];
        let th = a2.atan2(a1);
        hint = (th + TAU * ((hint - th) / TAU).round()).clamp(0.0, sp.sweep);
    }
    tr
}

const XY: ([f64; 3], [f64; 3]) = ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
const ZX: ([f64; 3], [f64; 3]) = ([0.0, 0.0, 1.0], [1.0, 0.0, 0.0]);
const YZ: ([f64; 3], [f64; 3]) = ([0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);

#[test]
fn arcs_off_by_what_cam_rounding_leaves_run_as_spirals_in_every_plane() {
    // (plane, r0, r1, sweep, rise, feed): the largest differences LinuxCNC's interpreter
    // accepts (0.028 mm at any radius, 0.1 % of the radius up to 2.8 mm), 0.5 µm as in the
    // case of the defect list, clockwise (e2 reversed) and counter-clockwise, helices, and
    // two turns.
    let cases = [
        (XY, 10.0, 10.0005, FRAC_PI_2, 0.0, 20.0),
        (XY, 10.0, 10.028, PI, 0.0, 50.0),
        (XY, 10.028, 10.0, 1.5 * PI, 0.0, 50.0),
        (ZX, 100.0, 100.1, 0.5, 0.0, 100.0),
        (YZ, 5.0, 5.02, TAU + 1.0, 3.0, 30.0),
        (XY, 2.0, 2.028, 2.0 * TAU, -4.0, 40.0),
        (ZX, 400.0, 399.6, 0.1, 1.0, 100.0),
    ];
    for (k, ((e1, e2), r0, r1, sweep, rise, feed)) in cases.into_iter().enumerate() {
        for cw in [false, true] {
            let e2 = if cw { e2.map(|x| -x) } else { e2 };
            let sp = Spiral {
                c: [1.0, -2.0, 3.0],
                e1,
                e2,
                r0,
                r1,
                sweep,
                rise,
            };
            let tr = run_spiral(&sp, feed);
            assert!(never_stops(&tr), "case {k}");
        }
    }
}

#[test]
fn a_strong_spiral_within_the_absolute_tolerance_keeps_the_limits() {
    // Radius 0.002 mm to 0.030 mm in half a turn (LinuxCNC accepts any radius change up to
    // 0.028 mm): the curvature changes fifteenfold along it.
    let sp = Spiral {
        c: [0.0, 0.0, 0.0],
        e1: XY.0,
        e2: XY.1,
        r0: 0.002,
        r1: 0.030,
        sweep: PI,
        rise: 0.0,
    };
    run_spiral(&sp, 10.0);
    let sp = Spiral {
        r0: 0.030,
        r1: 0.002,
        ..sp
    };
    run_spiral(&sp, 10.0);
}

#[test]
fn a_radius_difference_beyond_the_moves_tolerance_is_refused() {
    let sp = Spiral {
        c: [0.0, 0.0, 0.0],
        e1: XY.0,
        e2: XY.1,
        r0: 10.0,
        r1: 10.001,
        sweep: 1.0,
        rise: 0.0,
    };
    let lim = limits(V, A, J);
    for (tolerance, accepted) in [(0.0, false), (0.0009, false), (0.001 * (1.0 + 1e-9), true)] {
        let mut pl = planner(&lim, sp.at(0.0), 64);
        let r = pl.push(&sp.arc_move(10.0, PathMode::ExactStop, tolerance));
        match r {
            Ok(()) => assert!(accepted, "{tolerance}"),
            Err(e @ MotionError::ArcRadiusMismatch { .. }) => {
                assert!(!accepted, "{tolerance}");
                assert_eq!(e.code(), "MOTION-005");
            }
            Err(e) => panic!("{e}"),
        }
    }
    // An exact circle: rounding of the coordinates is no mismatch.
    let circle = Spiral {
        r1: 10.0 * (1.0 + 1e-14),
        ..sp
    };
    let mut pl = planner(&lim, circle.at(0.0), 64);
    pl.push(&circle.arc_move(10.0, PathMode::ExactStop, 0.0))
        .unwrap();
}

#[test]
fn a_spiral_between_lines_is_blended_within_p() {
    // A line into a spiral of R 5 -> 5.02 over a quarter turn and out along a line, corners
    // of 30° at both ends, G64 P0.1: no stop, within P of the programmed path.
    let sp = Spiral {
        c: [0.0, 0.0, 0.0],
        e1: XY.0,
        e2: XY.1,
        r0: 5.0,
        r1: 5.02,
        sweep: FRAC_PI_2,
        rise: 0.0,
    };
    let p = 0.1;
    let mode = blend(p);
    let a = sp.at(0.0);
    let b = sp.at(sp.sweep);
    // Lines meeting the spiral's tangents ((0, 1) at its start, (−1, 0) at its end) at 30°.
    let (s30, c30) = (0.5, 0.75f64.sqrt());
    let before = p3(a[0] - 5.0 * s30, a[1] - 5.0 * c30, 0.0);
    let after = p3(b[0] - 5.0 * c30, b[1] + 5.0 * s30, 0.0);
    let moves = [
        Move::line(a, 30.0, mode, 1),
        sp.arc_move(30.0, mode, 0.02),
        Move::line(after, 30.0, mode, 3),
    ];
    let lim = limits(V, A, J);
    let mut pl = planner(&lim, before, 64);
    let tr = run(&mut pl, &moves, 100_000);
    assert_limits(&tr, V, A, J);
    assert!(pl.geometry_stats().blends >= 2, "{:?}", pl.geometry_stats());
    assert!(never_stops(&tr));
    // Within P of the two lines or the spiral.
    let mut hint = 0.0;
    for q in &tr.pts {
        let dl = seg_dist(q, &before, &a).min(seg_dist(q, &b, &after));
        let (dr, _) = sp.error(q, hint);
        assert!(dl.min(dr) <= p * (1.0 + 1e-9), "{dl} {dr} at {q:?}");
        hint = q[1].atan2(q[0]).clamp(0.0, sp.sweep);
    }
    assert!(dist(tr.pts.last().unwrap(), &after) <= 1e-9);
}
