//! Positions and tolerances for any path length and any place on the machine: programs of
//! 10^5 and 10^6 mm of path run to their end, and isolated lines far from the origin keep
//! the limits on the time-optimal S-curve.
//!
//! The long programs run on a machine 1000 times faster than the benchmark machine (every
//! limit × 1000): their set-points have the benchmark machine's shape, scaled, in 1000
//! times fewer periods, so that 10^6 mm of path are affordable in a debug build. What used
//! to fail does not scale: the planner's absolute tolerances (1e-12 mm at the end of a
//! piece) against the rounding of positions counted from the program start, whose spacing
//! passes 1e-12 mm beyond 8 192 mm of path (the machine came to rest at a stop and never
//! moved again). `examples/long_paths.rs` runs the same at the benchmark machine's limits.

use crate::common::*;
use crate::long_path_program::long_path_program;
use rtcnc_motion::{
    Axis, AxisLimits, AxisVec, MachineLimits, Move, PathMode, Planner, TrivialKinematics,
};

fn machine(scale: f64, travel: f64) -> MachineLimits {
    MachineLimits::uniform(
        &[Axis::X, Axis::Y, Axis::Z],
        AxisLimits::new(
            100.0 * scale,
            1000.0 * scale,
            50_000.0 * scale,
            -travel,
            travel,
        ),
    )
}

fn planner_on(lim: &MachineLimits, start: AxisVec) -> Planner<TrivialKinematics> {
    Planner::new(
        lim,
        TrivialKinematics::identity(&[Axis::X, Axis::Y, Axis::Z]),
        T,
        256,
        start,
    )
    .unwrap()
}

fn runs_to_its_end(length: f64) {
    let scale = 1000.0;
    let lim = machine(scale, 1000.0);
    let (moves, end) = long_path_program(length, scale);
    let mut pl = planner_on(&lim, p3(0.0, 0.0, 0.0));
    let tr = run(&mut pl, &moves, 2_000_000);
    assert_limits(&tr, 100.0 * scale, 1000.0 * scale, 50_000.0 * scale);
    assert_eq!(pl.stats().limit_violations, 0);
    let last = *tr.pts.last().unwrap();
    assert!(dist(&last, &end) <= 1e-9, "ended {last:?}");
    // The zigzags end at rest exactly on their end points.
    let step = 50_000.0 * scale * T * T * T;
    for x in [960.0, -960.0] {
        assert!(rests_at(&tr, &p3(x, 0.0, 0.0), step), "no stop at X{x}");
    }
}

#[test]
fn a_program_of_1e5_mm_of_path_runs_to_its_end() {
    runs_to_its_end(1e5);
}

#[test]
fn a_program_of_1e6_mm_of_path_runs_to_its_end() {
    runs_to_its_end(1e6);
}

/// An isolated line follows the OTG's rest-to-rest S-curve; its set-points used to be
/// checked against a box shrunk by the rounding of positions (about 16 ulp of the
/// coordinates) that the S-curve's margin under the jerk limit (1e-7 relative, 5e-12 mm
/// per period at 50 000 mm/s³ and 1 ms) did not cover beyond about 400 mm from the
/// origin: the S-curve was left while braking at the full limits, and the speed policy
/// could not follow (22 set-points over the jerk limit on a 500 mm rapid, up to 8 ×).
#[test]
fn isolated_lines_far_from_the_origin_keep_the_s_curve_and_the_limits() {
    let travel = 20_000.0;
    let lim = machine(1.0, travel);
    // (start, end): long rapids and short lines at up to 10^4 mm from the origin.
    let cases = [
        (0.0, 900.0, true),
        (900.0, -900.0, true),
        (-1800.0, 1800.0, true),
        (9990.0, 10_000.0, false),
        (-10_000.0, -9000.0, false),
    ];
    for (a, b, rapid) in cases {
        let mut pl = planner_on(&lim, p3(a, 0.0, 0.0));
        let mv = if rapid {
            Move::rapid(p3(b, 0.0, 0.0), PathMode::ExactStop, 1)
        } else {
            Move::line(p3(b, 0.0, 0.0), 100.0, PathMode::ExactStop, 1)
        };
        let tr = run(&mut pl, &[mv], 100_000);
        assert_limits(&tr, 100.0, 1000.0, 50_000.0);
        let s = pl.stats();
        assert_eq!(
            (s.limit_violations, s.rollbacks, s.emergency_brakes),
            (0, 0, 0),
            "{a} -> {b}: {s:?}"
        );
        // The S-curve reaching 100 mm/s: L/v + v/A + A/J (closed form), ending on a
        // period: one more period than the whole periods within it.
        let len = (b - a).abs();
        let optimum = len / 100.0 + 100.0 / 1000.0 + 1000.0 / 50_000.0;
        let periods = (optimum / T).ceil();
        let taken = cycle_time(&tr) / T;
        assert!(
            (taken - periods).abs() <= 1.0,
            "{a} -> {b}: {taken} periods, S-curve {periods}"
        );
        let last = *tr.pts.last().unwrap();
        assert_eq!(last[0], b);
    }
}
