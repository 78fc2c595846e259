//! The path planner in a servo loop: a 20 mm square with its corners blended within
//! 0.05 mm (G64 P0.05), entered and left at rapid, on a 3-axis machine with a 1 ms servo
//! period, at two tolerances. Prints the cycle time and how the path passes the square's
//! first corner: on a blend inside the tolerance, or in an exact stop where a blend the jerk
//! limit allows would be slower than stopping. `cargo run -p rtcnc-motion --example 01_contour`

use rtcnc_motion::{
    AXES, Axis, AxisLimits, AxisVec, MachineLimits, MotionState, Move, PathMode, Planner,
    TrivialKinematics,
};

fn point(x: f64, y: f64, z: f64) -> AxisVec {
    let mut p = [0.0; AXES];
    p[0] = x;
    p[1] = y;
    p[2] = z;
    p
}

fn main() -> Result<(), rtcnc_motion::MotionError> {
    for tolerance in [0.05, 1.0] {
        run(tolerance)?;
    }
    Ok(())
}

fn run(tolerance: f64) -> Result<(), rtcnc_motion::MotionError> {
    // Every axis: 100 mm/s, 1000 mm/s², 50 000 mm/s³, travel ±500 mm.
    let axes = [Axis::X, Axis::Y, Axis::Z];
    let limits = MachineLimits::uniform(
        &axes,
        AxisLimits::new(100.0, 1000.0, 50_000.0, -500.0, 500.0),
    );
    let period = 0.001;
    let start = point(0.0, 0.0, 5.0);
    let mut planner = Planner::new(
        &limits,
        TrivialKinematics::identity(&axes),
        period,
        256,
        start,
    )?;

    // The program's moves, in mm and mm/s, each with its source line.
    let blend = PathMode::Blend {
        tolerance,
        merge_tolerance: 0.0,
    };
    let moves = [
        Move::rapid(point(0.0, 0.0, 1.0), PathMode::ExactPath, 1),
        Move::line(point(0.0, 0.0, -1.0), 10.0, PathMode::ExactPath, 2),
        Move::line(point(20.0, 0.0, -1.0), 50.0, blend, 3),
        Move::line(point(20.0, 20.0, -1.0), 50.0, blend, 4),
        Move::line(point(0.0, 20.0, -1.0), 50.0, blend, 5),
        Move::line(point(0.0, 0.0, -1.0), 50.0, PathMode::ExactPath, 6),
        Move::rapid(point(0.0, 0.0, 5.0), PathMode::ExactPath, 7),
    ];
    planner.push_all(&moves)?;
    // The program ends here: the path ends in a stop.
    planner.flush();

    // The servo loop: one set-point per period, for as long as the path moves. Near the
    // corner (20, 0): the closest point and the path speed there.
    let mut joints = [0.0; 3];
    let (mut periods, mut closest, mut speed_there) = (0u64, f64::INFINITY, 0.0);
    loop {
        let status = planner.next(&mut joints);
        periods += 1;
        let d = (joints[0] - 20.0).hypot(joints[1]);
        if d < closest {
            closest = d;
            speed_there = status.path_speed;
        }
        if status.state == MotionState::Idle {
            break;
        }
    }
    println!(
        "G64 P{tolerance}: cycle time {:.3} s",
        periods as f64 * period
    );
    println!(
        "  corner (20, 0): passed {closest:.3} mm from it (set-points 1 ms apart) at {speed_there:.1} mm/s{}",
        if speed_there < 1e-9 {
            " (an exact stop)"
        } else {
            ""
        }
    );
    println!(
        "  set-points over a limit: {}",
        planner.stats().limit_violations
    );
    Ok(())
}
