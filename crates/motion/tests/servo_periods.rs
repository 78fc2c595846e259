//! The same program at any servo period from 100 µs to 4 ms: the same path within P, the
//! same speed and a cycle time within a few periods, every set-point within the limits.
//!
//! The contour is the bracket's (examples/bracket.ngc) first corner: a line along the soft
//! limit y = -5 into a quarter arc of radius 5 (G3, tangent) and out of it along a tangent
//! line, at F 20 mm/s in G64 P0.01. Where a line meets the arc the curvature steps from 0 to
//! 1/5 mm⁻¹. Passed as it is, that step happens between two set-points, and its jerk
//! (v²·ΔK/T) allows a speed that falls with the period: 11 mm/s at 1 ms, 3.5 mm/s at
//! 100 µs. Blended within P, nothing in the path depends on the period.

use rtcnc_motion::{
    AXES, Axis, AxisLimits, AxisVec, MachineLimits, MotionState, Move, PathMode, Planner,
    TrivialKinematics,
};

const V: f64 = 100.0;
const A: f64 = 1000.0;
const J: f64 = 50_000.0;
const F: f64 = 20.0;
const R: f64 = 5.0;
const P: f64 = 0.01;
const Y_MIN: f64 = -5.0;

fn p3(x: f64, y: f64) -> AxisVec {
    let mut p = [0.0; AXES];
    p[0] = x;
    p[1] = y;
    p
}

fn machine() -> MachineLimits {
    let mut y = AxisLimits::new(V, A, J, Y_MIN, 200.0);
    y.min_position = Y_MIN;
    MachineLimits {
        axes: {
            let mut axes = [None; AXES];
            axes[Axis::X as usize] = Some(AxisLimits::new(V, A, J, -5.0, 300.0));
            axes[Axis::Y as usize] = Some(y);
            axes[Axis::Z as usize] = Some(AxisLimits::new(V, A, J, -100.0, 5.0));
            axes
        },
    }
}

/// From (40, -5): the line to (60, -5), the arc around (60, 0) to (65, 0), the line to
/// (65, 20).
fn contour() -> (AxisVec, [Move; 3]) {
    let mode = PathMode::Blend {
        tolerance: P,
        merge_tolerance: 0.0,
    };
    (
        p3(40.0, Y_MIN),
        [
            Move::line(p3(60.0, Y_MIN), F, mode, 1),
            Move::arc(
                p3(65.0, 0.0),
                [60.0, 0.0, 0.0],
                [0.0, 0.0, 1.0],
                0,
                F,
                mode,
                2,
            ),
            Move::line(p3(65.0, 20.0), F, mode, 3),
        ],
    )
}

/// Distance from `p` to the programmed contour.
fn off_path(p: &AxisVec) -> f64 {
    let (x, y) = (p[0], p[1]);
    let first = if x <= 60.0 {
        (y - Y_MIN).abs()
    } else {
        f64::INFINITY
    };
    let arc = if x >= 60.0 && y <= 0.0 {
        (((x - 60.0).powi(2) + y * y).sqrt() - R).abs()
    } else {
        f64::INFINITY
    };
    let last = if y >= 0.0 {
        (x - 65.0).abs()
    } else {
        f64::INFINITY
    };
    first.min(arc).min(last)
}

struct Run {
    points: Vec<AxisVec>,
    speeds: Vec<f64>,
}

fn run(period: f64) -> Run {
    let (start, moves) = contour();
    let mut pl = Planner::new(
        &machine(),
        TrivialKinematics::identity(&[Axis::X, Axis::Y, Axis::Z]),
        period,
        256,
        start,
    )
    .unwrap();
    for m in &moves {
        pl.push(m).unwrap();
    }
    pl.flush();
    let mut joints = [0.0; 3];
    let mut run = Run {
        points: vec![start; 3],
        speeds: Vec::new(),
    };
    let limit = (10.0 / period) as usize;
    for _ in 0..limit {
        let st = pl.next(&mut joints);
        run.points.push(st.axes);
        run.speeds.push(st.path_speed);
        if st.state == MotionState::Idle {
            for _ in 0..3 {
                run.points.push(pl.next(&mut joints).axes);
            }
            return run;
        }
    }
    panic!("not finished within 10 s at a {period} s period");
}

/// From the first set-point that leaves the start to the last that differs from the end.
fn cycle_time(run: &Run, period: f64) -> f64 {
    let (start, end) = (run.points[0], *run.points.last().unwrap());
    let first = run.points.iter().position(|p| *p != start).unwrap();
    let last = run.points.iter().rposition(|p| *p != end).unwrap() + 1;
    (last + 1 - first) as f64 * period
}

/// Largest |v|/V, |a|/A, |j|/J of any axis from the finite differences at `period`.
fn limit_ratio(run: &Run, period: f64) -> f64 {
    let mut worst = 0.0f64;
    for w in run.points.windows(4) {
        for axis in [Axis::X as usize, Axis::Y as usize] {
            let x = [w[0][axis], w[1][axis], w[2][axis], w[3][axis]];
            let v = (x[3] - x[2]) / period;
            let a = (x[3] - 2.0 * x[2] + x[1]) / period.powi(2);
            let j = (x[3] - 3.0 * x[2] + 3.0 * x[1] - x[0]) / period.powi(3);
            worst = worst.max(v.abs() / V).max(a.abs() / A).max(j.abs() / J);
        }
    }
    worst
}

const PERIODS: [f64; 6] = [100e-6, 250e-6, 500e-6, 1e-3, 2e-3, 4e-3];

#[test]
fn a_tangent_arc_contour_runs_alike_at_every_servo_period() {
    // The acceleration-limited optimum, by hand: the centripetal acceleration on the arc,
    // F²/R = 80 mm/s², is far below A, so the whole contour runs at F but for the start and
    // the stop. F equals A²/J, so each is a pure jerk ramp of 2·sqrt(F/J) = 40 ms that covers
    // F·20 ms: each costs 20 ms over the contour's length at F.
    let length = 20.0 + 0.5 * std::f64::consts::PI * R + 20.0;
    let ramp = 2.0 * (F / J).sqrt();
    let optimum = length / F + ramp;
    assert!((optimum - 2.432_699).abs() < 1e-6, "{optimum}");

    for period in PERIODS {
        let run = run(period);
        let ratio = limit_ratio(&run, period);
        assert!(ratio <= 1.0 + 1e-9, "{period} s: limits exceeded {ratio}×");
        for p in &run.points {
            assert!(
                off_path(p) <= P * (1.0 + 1e-9),
                "{period} s: {p:?} is off the path"
            );
            // The blend stays on the inside of the arc: never beyond the soft limit that
            // the first line runs along.
            assert!(p[1] >= Y_MIN, "{period} s: {p:?} beyond the soft limit");
        }
        // At F through both junctions: away from the start's and the stop's ramps (each
        // covers F·20 ms = 0.4 mm), nothing slower than F but for a dip of 2 % at most (the
        // curvature sampled on either side of the blend's ends differs slightly).
        let cruise = run.points[3..]
            .iter()
            .zip(&run.speeds)
            .filter(|(p, _)| p[0] >= 41.0 && p[1] <= 19.0)
            .map(|(_, v)| *v);
        let slowest = cruise.fold(f64::INFINITY, f64::min);
        assert!(
            slowest >= 0.98 * F,
            "{period} s: {slowest} mm/s at the slowest"
        );
        let t = cycle_time(&run, period);
        assert!(
            (t - optimum).abs() <= 3.0 * period + 0.002,
            "{period} s: {t} s, the optimum {optimum} s"
        );
    }
}
