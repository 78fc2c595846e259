//! The compressor (`builder/compressor.rs`): vertices of a dense G64 P polyline that turn too
//! far for the local smoothing (over 0.35 rad) take the state of a curve fitted over their
//! neighbours instead of a corner blend each; the path stays within P of the polyline, every
//! limit is kept, the program ends at its end point, and no curve is fitted across a run's
//! boundary (a sharper turn, a feed change, a rapid, an arc, a dwell, another tolerance).

use crate::common::*;
use proptest::prelude::*;
use rtcnc_motion::{AxisVec, Move, PathMode};

const V: f64 = 100.0;
const A: f64 = 1000.0;
const J: f64 = 50_000.0;

/// [`check_polyline_run`] under this file's limits, the deviation searched over every segment
/// (the test polylines cross themselves).
fn check_run(
    moves: &[Move],
    start: AxisVec,
    verts: Option<&[AxisVec]>,
    p: f64,
    max: usize,
) -> (Trace, rtcnc_motion::GeometryStats) {
    let within = verts.map(|v| (v, p, Nearest::AnySegment));
    check_polyline_run((V, A, J), moves, start, within, max)
}

/// `n` chords of length `c`, each turning by `phi` from the one before (a circle of radius
/// c / (2 sin(φ/2)) through the vertices), starting at `start` heading along `heading`.
fn turning_chords(start: AxisVec, heading: f64, c: f64, phi: f64, n: usize) -> Vec<AxisVec> {
    let mut v = vec![start];
    let (mut x, mut y, mut h) = (start[0], start[1], heading);
    for _ in 0..n {
        x += c * h.cos();
        y += c * h.sin();
        v.push(p3(x, y, start[2]));
        h += phi;
    }
    v
}

/// A circle polyline whose chords turn by 0.36 rad each (0.2 mm chords, R 0.5583 mm, chord
/// sagitta 0.0090 mm under P 0.01), two turns at F 50: each vertex turns past the local
/// smoothing's 0.35 rad, so without the compressor each is a corner blend within P, which a
/// jerk-limited path passes at most at (6·P·√J)^(2/3) / θ = 15.7 mm/s. The circle itself
/// allows √(A·R) = 23.6 mm/s (centripetal; its jerk, v³/R², allows (J·R²)^(1/3) = 25.0).
/// Over the middle third of the run the speed keeps 0.75 of the circle's, 17.7 mm/s, above
/// what corner blends could reach; the path stays within P of every vertex and chord.
#[test]
fn a_tight_circle_polyline_runs_near_the_circles_speed() {
    let (c, phi, p, f): (f64, f64, f64, f64) = (0.2, 0.36, 0.01, 50.0);
    let r = c / (2.0 * (0.5 * phi).sin());
    let n = (2.0 * std::f64::consts::TAU / phi).round() as usize;
    let verts = turning_chords(p3(0.0, 0.0, 0.0), 0.0, c, phi, n);
    let moves = lines(&verts, f, blend(p));
    let (tr, stats) = check_run(&moves, verts[0], Some(&verts), p, 20_000);
    let v_circle = (A * r).sqrt().min((J * r * r).cbrt());
    let corner_bound = (6.0 * p * J.sqrt()).powf(2.0 / 3.0) / phi;
    assert!(
        0.75 * v_circle > corner_bound * 1.1,
        "the case must tell the two apart"
    );
    let moving: Vec<f64> = tr.speed.iter().copied().filter(|v| *v > 0.0).collect();
    let third_m = moving.len() / 3;
    let lowest = moving[third_m..2 * third_m]
        .iter()
        .fold(f64::INFINITY, |m, v| m.min(*v));
    assert!(
        lowest >= 0.75 * v_circle,
        "lowest speed over the middle third {lowest} mm/s, the circle's {v_circle}, \
         corner by corner at most {corner_bound} ({} compressed, {} blends)",
        stats.compressed,
        stats.blends
    );
    // The time: the length at 0.75 of the circle's speed, plus a stop's worth at each end.
    let length = c * n as f64;
    let ramp = 2.0 * (v_circle / A + A / J);
    let time = cycle_time(&tr);
    assert!(
        time <= length / (0.75 * v_circle) + ramp,
        "{time} s for {length} mm; the circle at its speed takes {}",
        length / v_circle
    );
}

/// Two runs of tight chords (0.2 mm, turning 0.37 rad, past the local smoothing's 0.35, the
/// chords' sagitta 0.0093 mm under P 0.01) joined by something no curve is fitted across,
/// the second run at feed `f2` and tolerance `p2`. Each run of `k` lines has `k − 1` inner
/// vertices, every one compressed; the joint is an inner vertex of neither run.
fn two_runs(join: impl Fn(&mut Vec<Move>, AxisVec, f64) -> AxisVec, f2: f64, p2: f64) -> u64 {
    let (c, phi, p, f, k) = (0.2, 0.37, 0.01, 40.0, 6);
    let first = turning_chords(p3(0.0, 0.0, 0.0), 0.0, c, phi, k);
    let mut moves = lines(&first, f, blend(p));
    let heading = k as f64 * phi;
    let at = *first.last().unwrap();
    let from = join(&mut moves, at, heading);
    let second = turning_chords(from, heading, c, phi, k);
    let n0 = moves.len() as u32;
    for (i, v) in second[1..].iter().enumerate() {
        moves.push(Move::line(*v, f2, blend(p2), n0 + i as u32 + 1));
    }
    let (_, stats) = check_run(&moves, first[0], None, p, 20_000);
    stats.compressed
}

#[test]
fn one_run_compresses_every_inner_vertex() {
    // The same chords in one run (the joint a vertex like the others): all 11 inner
    // vertices.
    let n = two_runs(|_, at, _| at, 40.0, 0.01);
    assert_eq!(n, 11);
}

#[test]
fn no_curve_is_fitted_across_a_feed_change() {
    assert_eq!(two_runs(|_, at, _| at, 30.0, 0.01), 10);
}

#[test]
fn no_curve_is_fitted_across_another_tolerance() {
    assert_eq!(two_runs(|_, at, _| at, 40.0, 0.02), 10);
}

#[test]
fn no_curve_is_fitted_across_a_rapid() {
    let n = two_runs(
        |m, at, h| {
            let to = p3(at[0] + 0.2 * h.cos(), at[1] + 0.2 * h.sin(), 0.0);
            m.push(Move::rapid(to, blend(0.01), 100));
            to
        },
        40.0,
        0.01,
    );
    assert_eq!(n, 10);
}

#[test]
fn no_curve_is_fitted_across_a_dwell() {
    let n = two_runs(
        |m, at, _| {
            m.push(Move::dwell(0.01, 100));
            at
        },
        40.0,
        0.01,
    );
    assert_eq!(n, 10);
}

#[test]
fn no_curve_is_fitted_across_a_sharp_corner() {
    // The second run leaves at 1.2 rad from the first's last chord (beyond 0.8 rad).
    let (c, phi, p, f, k) = (0.2, 0.37, 0.01, 40.0, 6);
    let first = turning_chords(p3(0.0, 0.0, 0.0), 0.0, c, phi, k);
    let at = *first.last().unwrap();
    let second = turning_chords(at, (k - 1) as f64 * phi + 1.2, c, phi, k);
    let mut verts = first.clone();
    verts.extend_from_slice(&second[1..]);
    let moves = lines(&verts, f, blend(p));
    let (_, stats) = check_run(&moves, verts[0], Some(&verts), p, 20_000);
    assert_eq!(stats.compressed, 10);
}

#[test]
fn no_curve_is_fitted_across_an_arc() {
    // A quarter arc in the XZ plane (another plane) between the runs.
    let n = two_runs(
        |m, at, _| {
            let centre = [at[0] + 1.0, at[1], at[2]];
            let end = p3(at[0] + 1.0, at[1], at[2] + 1.0);
            m.push(Move::arc(
                end,
                centre,
                [0.0, 1.0, 0.0],
                0,
                40.0,
                blend(0.01),
                100,
            ));
            end
        },
        40.0,
        0.01,
    );
    assert_eq!(n, 10);
}

#[test]
fn exact_path_mode_is_not_compressed() {
    let verts = turning_chords(p3(0.0, 0.0, 0.0), 0.0, 0.2, 0.37, 12);
    let moves = lines(&verts, 40.0, PathMode::ExactPath);
    let (_, stats) = check_run(&moves, verts[0], Some(&verts), 0.0, 20_000);
    assert_eq!(stats.compressed, 0);
}

fn cases() -> u32 {
    if cfg!(debug_assertions) { 8 } else { 48 }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), failure_persistence: None, ..ProptestConfig::default() })]

    /// Random dense polylines (chords 0.03-1.2 mm, turns up to ±1 rad, some runs of equal
    /// turns), random P and feed: within P of every vertex and chord, every limit kept,
    /// the exact end point.
    #[test]
    fn random_dense_polylines_keep_p_the_limits_and_the_end_point(
        steps in proptest::collection::vec((0.03f64..1.2, -1.0f64..1.0, 0usize..4), 4..40),
        p in prop_oneof![Just(0.001f64), Just(0.005), Just(0.01), Just(0.02), Just(0.05)],
        f in 5.0f64..80.0,
    ) {
        let mut verts = vec![p3(0.0, 0.0, 0.0)];
        let (mut x, mut y, mut h) = (0.0f64, 0.0f64, 0.0f64);
        for (c, turn, repeat) in steps {
            for _ in 0..=repeat {
                h += turn;
                x += c * h.cos();
                y += c * h.sin();
                verts.push(p3(x, y, 0.0));
            }
        }
        let moves = lines(&verts, f, blend(p));
        check_run(&moves, verts[0], Some(&verts), p, 200_000);
    }
}
