//! Limits, tolerance and end points on a corpus of paths: squares, circles (polylines and
//! arcs), CAM-like polylines, exact-stop modes.

use crate::common::*;
use rtcnc_motion::{Move, PathMode};

const V: f64 = 100.0;
const A: f64 = 1000.0;
const J: f64 = 50_000.0;

fn check_run(moves: &[Move], verts: Option<&[rtcnc_motion::AxisVec]>, p: f64, max: usize) -> Trace {
    let start = verts.map_or(p3(0.0, 0.0, 0.0), |v| v[0]);
    let within = verts.map(|v| (v, p, Nearest::AlongTheRun));
    check_polyline_run((V, A, J), moves, start, within, max).0
}

/// Whether the trace comes to rest exactly at `c` (see [`rests_at`]).
fn stops_at(tr: &Trace, c: &rtcnc_motion::AxisVec) -> bool {
    rests_at(tr, c, J * T * T * T)
}

#[test]
fn square_with_blended_corners_respects_limits_and_tolerance() {
    let verts = [
        p3(0.0, 0.0, 0.0),
        p3(10.0, 0.0, 0.0),
        p3(10.0, 10.0, 0.0),
        p3(0.0, 10.0, 0.0),
        p3(0.0, 0.0, 0.0),
    ];
    for p in [0.001, 0.01, 0.1] {
        check_run(&lines(&verts, 100.0, blend(p)), Some(&verts), p, 5000);
    }
}

#[test]
fn square_in_exact_path_mode_stops_at_every_corner() {
    let verts = [
        p3(0.0, 0.0, 0.0),
        p3(10.0, 0.0, 0.0),
        p3(10.0, 10.0, 0.0),
        p3(0.0, 10.0, 0.0),
    ];
    let tr = check_run(
        &lines(&verts, 100.0, PathMode::ExactPath),
        Some(&verts),
        0.0,
        5000,
    );
    // The corners are passed at rest: a set-point exactly on the corner, reached and left
    // with steps no larger than one jerk-limited step from rest.
    for c in &verts[1..3] {
        assert!(stops_at(&tr, c), "no stop at {c:?}");
    }
}

#[test]
fn exact_path_mode_does_not_stop_between_collinear_segments() {
    let verts = [p3(0.0, 0.0, 0.0), p3(5.0, 0.0, 0.0), p3(10.0, 0.0, 0.0)];
    let tr = check_run(
        &lines(&verts, 50.0, PathMode::ExactPath),
        Some(&verts),
        0.0,
        5000,
    );
    let mid = tr.pts.iter().position(|p| p[0] >= 5.0).unwrap();
    assert!(
        tr.speed[mid - 3] > 49.0,
        "slowed down at a collinear junction"
    );
}

#[test]
fn exact_stop_mode_stops_between_collinear_segments() {
    let verts = [p3(0.0, 0.0, 0.0), p3(5.0, 0.0, 0.0), p3(10.0, 0.0, 0.0)];
    let tr = check_run(
        &lines(&verts, 50.0, PathMode::ExactStop),
        Some(&verts),
        0.0,
        5000,
    );
    assert!(stops_at(&tr, &verts[1]));
}

#[test]
fn circle_polyline_at_one_micron_chord_tolerance() {
    let verts = circle_polyline(10.0, 0.001, 1.0);
    let moves = lines(&verts, 100.0, blend(0.001));
    check_run(&moves, Some(&verts), 0.001, 5000);
}

#[test]
fn ellipse_polyline_at_one_micron_chord_tolerance() {
    let verts = ellipse_polyline(20.0, 10.0, 0.001);
    let moves = lines(&verts, 100.0, blend(0.001));
    check_run(&moves, Some(&verts), 0.001, 5000);
}

#[test]
fn many_tiny_segments_per_period_are_not_a_speed_limit() {
    // 2000 segments of 5 µm on a gentle arc: 10 segments per period at 50 mm/s.
    let r = 1000.0;
    let verts: Vec<_> = (0..=2000)
        .map(|k| {
            let th = 0.005 * k as f64 / r;
            p3(r * th.sin(), r * (1.0 - th.cos()), 0.0)
        })
        .collect();
    let moves = lines(&verts, 50.0, blend(0.001));
    let tr = check_run(&moves, Some(&verts), 0.001, 5000);
    let peak = tr.speed.iter().cloned().fold(0.0, f64::max);
    assert!(peak > 49.9, "peak path speed {peak}");
}

#[test]
fn arcs_and_helix_reach_their_end_points_exactly() {
    // Quarter arc in XY, then a helix turn in YZ (normal along X) with a rise.
    let a1 = Move::arc(
        p3(0.0, 10.0, 0.0),
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 1.0],
        0,
        50.0,
        PathMode::ExactPath,
        1,
    );
    let a2 = Move::arc(
        p3(2.0, 10.0, 0.0),
        [0.0, 10.0, 5.0],
        [1.0, 0.0, 0.0],
        1,
        50.0,
        PathMode::ExactPath,
        2,
    );
    let lim = limits(V, A, J);
    let mut pl = planner(&lim, p3(10.0, 0.0, 0.0), 256);
    let tr = run(&mut pl, &[a1, a2], 20_000);
    assert_limits(&tr, V, A, J);
    assert!(dist(tr.pts.last().unwrap(), &p3(2.0, 10.0, 0.0)) <= 1e-9);
    // The first arc's end is passed exactly (exact path: tangency is not given, so a stop).
    assert!(tr.pts.iter().any(|p| dist(p, &p3(0.0, 10.0, 0.0)) <= 1e-12));
}

#[test]
fn a_long_path_without_stops_reaches_its_end() {
    // 400 segments of 2.5 mm (1000 mm) whose direction alternates by 5e-5 rad: tangent
    // junctions, so the only stop is the end. The running distance to that stop drifts by
    // rounding over such a path (about 1e-11 mm), more than the 1e-12 mm at which the last
    // piece counts as reached: the path used to halt there for ever.
    let mut verts = vec![p3(0.0, 0.0, 0.0)];
    for k in 0..400 {
        let a: f64 = if k % 2 == 0 { 0.3 } else { 0.30005 };
        let last = *verts.last().unwrap();
        verts.push(p3(last[0] + 2.5 * a.cos(), last[1] + 2.5 * a.sin(), 0.0));
    }
    // 10.1 s at 100 mm/s; `check_run` fails if it does not finish within 11 s.
    check_run(
        &lines(&verts, 100.0, PathMode::ExactPath),
        Some(&verts),
        0.0,
        11_000,
    );
}

/// A CAM profile with rounded corners: lines tangent to quarter arcs of R 3.175 mm (a
/// 1/4 in end mill's corners, as FreeCAD's profile with cutter compensation writes them).
/// The curvature steps where a line meets an arc (0 to 1/R) bound the speed there, at the
/// junction only: the line's one sub-interval was capped by its end samples and ran at the
/// junctions' 8.9 mm/s from end to end (the program took 1.7 × LinuxCNC's time). Between
/// the arcs, the 100 mm lines run at the programmed feed (16.93 mm/s: F40 in/min), which
/// takes less than a millimetre to reach from the junction's speed (hand-checked: from 8.9
/// to 16.9 mm/s at 1000 mm/s² with a 50 000 mm/s³ jerk is under 0.3 mm).
#[test]
fn lines_between_tangent_arcs_run_at_their_feed() {
    let (r, f) = (3.175, 40.0 * 25.4 / 60.0);
    let mode = blend(0.01);
    // Counter-clockwise around a 100 x 40 mm rectangle from (r, 0).
    let corners = [
        ([100.0 + r, r], [100.0 + 2.0 * r, r], [100.0 + r, 0.0]),
        (
            [100.0 + r, 40.0 + r],
            [100.0 + r, 40.0 + 2.0 * r],
            [100.0 + 2.0 * r, 40.0 + r],
        ),
        ([r, 40.0 + r], [0.0, 40.0 + r], [r, 40.0 + 2.0 * r]),
        ([r, r], [r, 0.0], [0.0, r]),
    ];
    let mut moves = Vec::new();
    let mut n = 0;
    for (centre, end, line_end) in corners {
        n += 1;
        moves.push(Move::line(p3(line_end[0], line_end[1], 0.0), f, mode, n));
        n += 1;
        moves.push(Move::arc(
            p3(end[0], end[1], 0.0),
            [centre[0], centre[1], 0.0],
            [0.0, 0.0, 1.0],
            0,
            f,
            mode,
            n,
        ));
    }
    let lim = limits(V, A, J);
    let mut pl = planner(&lim, p3(r, 0.0, 0.0), 256);
    let tr = run(&mut pl, &moves, 100_000);
    assert_limits(&tr, V, A, J);
    assert!(dist(tr.pts.last().unwrap(), &p3(r, 0.0, 0.0)) <= 1e-9);
    // On the long lines (y = 0 and y = 40 + 2r, away from the corners by more than 1 mm)
    // the speed is the feed.
    let on_long_lines: Vec<f64> = tr
        .pts
        .windows(2)
        .zip(&tr.speed)
        .filter(|(w, _)| {
            let p = w[1];
            (p[1].abs() < 1e-9 || (p[1] - 40.0 - 2.0 * r).abs() < 1e-9)
                && p[0] > r + 1.0
                && p[0] < 100.0 + r - 1.0
        })
        .map(|(_, v)| *v)
        .collect();
    assert!(on_long_lines.len() > 10_000, "{}", on_long_lines.len());
    let slowest = on_long_lines.iter().cloned().fold(f64::INFINITY, f64::min);
    assert!(
        (slowest - f).abs() <= 1e-4 * f,
        "{slowest} mm/s on the lines, F {f}"
    );
}

/// A raster row of a 3-D surface as CAM writes it: 0.24 mm steps whose direction changes
/// by under 1e-4 rad at some vertices (tangent: passed as they are) and by a few 1e-3 rad
/// at the others (smoothed). After a tangent vertex the next smoothed span used to start
/// curved, as after a stop, turned by half its vertex's angle from the line it continued:
/// a step of the tangent that forced a stop there (a plain-G64 raster took 2.2 × LinuxCNC's
/// time). The row runs without a stop, within P of the polyline.
#[test]
fn a_raster_row_with_tangent_vertices_does_not_stop() {
    // z = 2 sin(0.1 x), rounded to 1 µm as a post-processor prints it: consecutive steps
    // differ by a few µm in z, some not at all (tangent: within 1e-4 rad).
    let verts: Vec<_> = (0..=200)
        .map(|k| {
            let x = 0.24 * k as f64;
            let z = (2.0 * (0.1 * x).sin() * 1000.0).round() / 1000.0;
            p3(x, 0.0, z)
        })
        .collect();
    let p = 0.05;
    let tr = check_run(&lines(&verts, 33.0, blend(p)), Some(&verts), p, 20_000);
    assert!(never_stops(&tr));
}

/// G64 Q merges consecutive lines whose inner vertices lie within Q of one line. On a run
/// that follows a curve, the vertices' smoothing must still stay within P of the merged
/// chord, which cuts the curve by the vertices' distance from it: a curved run merges only
/// where that distance is at most 0.85 P. Circles in chords of c: two merged chords cut the
/// circle by the sagitta (2c)²/(8R) (hand-checked): 0.54²/(8·3.76) = 0.0097 mm > 0.0085 mm
/// (no merge), 0.40²/(8·3.06) = 0.0065 mm (merged). Merging the first made an adaptive-like
/// clearing 2.6 × slower than not merging.
#[test]
fn curved_runs_merge_only_where_the_smoothing_keeps_p() {
    for (r, chord, merges) in [(3.76, 0.27, false), (3.06, 0.20, true)] {
        let n = (std::f64::consts::TAU * r / chord).round() as usize;
        let verts: Vec<_> = (0..=n / 4)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / n as f64;
                p3(r * a.cos(), r * a.sin(), 0.0)
            })
            .collect();
        let mode = PathMode::Blend {
            tolerance: 0.01,
            merge_tolerance: 0.01,
        };
        let lim = limits(V, A, J);
        let mut pl = planner(&lim, verts[0], 256);
        let tr = run(&mut pl, &lines(&verts, 50.0, mode), 20_000);
        assert_limits(&tr, V, A, J);
        let merged = pl.geometry_stats().merged;
        assert_eq!(merged > 0, merges, "R {r}, chords {chord}: {merged} merged");
        // Within P + Q of the programmed polyline.
        assert!(max_deviation(&tr, &verts) <= 0.02 + 1e-9);
    }
}

/// A circle polyline whose chords bulge from the circle by more than P (sagitta 1.6 P) runs
/// as a curve, not corner by corner: the smoothing moves its vertices towards the centre so
/// that the curve stays within P of the chords. Closed form: a curve within P of the
/// chords of a circle of radius R has a radius of at least R − P where it is circular, so
/// its per-axis acceleration and jerk limits allow v = min(V, √(A·(R − P)), (J·(R − P)²)^⅓)
/// (uniform circular motion: |a_x| ≤ v²/R, |j_x| ≤ v³/R²). Corner by corner within P each
/// 0.16 rad vertex passes at most (6·P·√J)^⅔ / θ = 35 mm/s (a jerk-limited turn within P),
/// half of that bound.
#[test]
fn a_circle_polyline_beyond_p_runs_at_the_circles_speed() {
    let (r, p) = (5.0, 0.01);
    let verts = circle_polyline(r, 1.6 * p, 1.0);
    let tr = check_run(&lines(&verts, V, blend(p)), Some(&verts), p, 20_000);
    let v_circle = V
        .min((A * (r - p)).sqrt())
        .min((J * (r - p) * (r - p)).cbrt());
    // The middle third of the turn, away from the start and the stop.
    let skip = tr.pts.len() - tr.speed.len();
    let lowest = tr.pts[skip..]
        .iter()
        .zip(&tr.speed)
        .filter(|(q, _)| {
            let a = q[1].atan2(q[0]).rem_euclid(std::f64::consts::TAU);
            (std::f64::consts::TAU / 3.0..2.0 * std::f64::consts::TAU / 3.0).contains(&a)
        })
        .fold(f64::INFINITY, |m, (_, v)| m.min(*v));
    assert!(
        lowest >= 0.9 * v_circle,
        "lowest speed on the middle third {lowest} mm/s, the circle's {v_circle}"
    );
}

/// A CAM polyline of an arc (R 5 mm, 0.5 mm chords) ending tangent into a 20 mm straight,
/// which leaves into the mirror arc, at G64 P0.02 and F 30 mm/s: the joins turn by half a
/// chord's angle (0.05 rad) between a chord and a line 40 times longer. A curvature ramp
/// from 1/R to zero within one chord c bounds the speed at (0.8·J·c·R)^(1/3) = 46 mm/s,
/// above the feed; a corner blend within half the last chord, after a span that
/// straightened before it, passed the joins at 10-12 mm/s (0.35 F).
#[test]
fn a_curved_run_joins_a_straight_without_a_corner() {
    let (r, p, f) = (5.0, 0.02, 30.0);
    let n = ((std::f64::consts::FRAC_PI_3) / (0.5 / r)) as usize;
    let dphi = std::f64::consts::FRAC_PI_3 / n as f64;
    let mut verts: Vec<_> = (0..=n)
        .map(|k| {
            let a = k as f64 * dphi;
            p3(r * a.cos(), r * a.sin(), 0.0)
        })
        .collect();
    let a = n as f64 * dphi;
    let (ex, ey) = (r * a.cos(), r * a.sin());
    let (sx, sy) = (ex - 20.0 * a.sin(), ey + 20.0 * a.cos());
    verts.push(p3(sx, sy, 0.0));
    let (cx, cy) = (sx - r * a.cos(), sy - r * a.sin());
    for k in 1..=n {
        let b = a + k as f64 * dphi;
        verts.push(p3(cx + r * b.cos(), cy + r * b.sin(), 0.0));
    }
    let moves = lines(&verts, f, blend(p));
    let tr = check_run(&moves, Some(&verts), p, 5000);
    // From the fourth vertex to the fourth from the end (away from the start and the
    // stop, 1.5 mm of path or more from either).
    let (from, to) = (verts[4], verts[verts.len() - 5]);
    let skip = tr.pts.len() - tr.speed.len();
    let pts = &tr.pts[skip..];
    let i0 = pts.iter().position(|q| dist(q, &from) < 0.05).unwrap();
    let i1 = pts.iter().rposition(|q| dist(q, &to) < 0.05).unwrap();
    let lowest = tr.speed[i0..i1]
        .iter()
        .fold(f64::INFINITY, |m, v| m.min(*v));
    assert!(lowest >= 0.6 * f, "lowest speed {lowest} mm/s at F {f}");
}
