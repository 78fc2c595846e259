//! Look-ahead cost without criterion, for `perf stat` / `perf record`: pushes the planner
//! bench's polyline (a circle of R 10 in 1 µm-tolerance chords, G64 P0.001, four turns)
//! through `push_all` REPS times and prints segments per second.
//!
//! `cargo run --release -p rtcnc-motion --example lookahead_cost -- [REPS] [setup]`: with
//! `setup`, the planners are only created (subtract that run's instruction count to get the
//! pushing alone). `-- 1 run` runs the program to its end and prints the number of periods
//! and a hash of every set-point's bits (to show that a change leaves the path bit for bit);
//! `splines` in place of `run` does the same with the bench's chain of 400 G5 arches.

use std::time::Instant;

use rtcnc_motion::{
    AXES, Axis, AxisLimits, AxisVec, Bezier, MachineLimits, MotionState, Move, PathMode, Planner,
    TrivialKinematics,
};

fn polyline(turns: f64) -> (AxisVec, Vec<Move>) {
    let (r, tol): (f64, f64) = (10.0, 0.001);
    let phi = 2.0 * (1.0 - tol / r).acos();
    let total = 2.0 * std::f64::consts::PI * turns;
    let n = (total / phi).ceil() as usize;
    let mode = PathMode::Blend {
        tolerance: 0.001,
        merge_tolerance: 0.001,
    };
    let pt = |k: usize| {
        let th = total * k as f64 / n as f64;
        let mut p = [0.0; AXES];
        p[0] = r * th.cos();
        p[1] = r * th.sin();
        p
    };
    (
        pt(0),
        (1..=n)
            .map(|k| Move::line(pt(k), 100.0, mode, k as u32))
            .collect(),
    )
}

/// Tangent cubic arches along X, alternately up and down (as in the planner bench).
fn spline_chain(n: usize) -> Vec<Move> {
    let p = |x: f64, y: f64| {
        let mut v = [0.0; AXES];
        v[0] = x;
        v[1] = y;
        v
    };
    (0..n)
        .map(|k| {
            let x = 2.0 * k as f64;
            let h = if k % 2 == 0 { 1.0 } else { -1.0 };
            Move::spline(
                p(x + 2.0, 0.0),
                Bezier::Cubic([p(x + 0.5, h), p(x + 1.5, h)]),
                60.0,
                PathMode::ExactPath,
                k as u32 + 1,
            )
        })
        .collect()
}

fn main() {
    let reps: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(50);
    let mode = std::env::args().nth(2).unwrap_or_default();
    let setup_only = mode == "setup";
    let (start, moves) = if mode == "splines" {
        ([0.0; AXES], spline_chain(400))
    } else {
        polyline(4.0)
    };
    let lim = MachineLimits::uniform(
        &[Axis::X, Axis::Y, Axis::Z],
        AxisLimits::new(100.0, 1000.0, 50_000.0, -1000.0, 1000.0),
    );
    let mut planners: Vec<_> = (0..reps)
        .map(|_| {
            Planner::new(
                &lim,
                TrivialKinematics::identity(&[Axis::X, Axis::Y, Axis::Z]),
                1e-3,
                4 * moves.len() + 16,
                start,
            )
            .expect("valid limits")
        })
        .collect();
    if setup_only {
        println!("{} planners created", planners.len());
        return;
    }
    let mut pushed = 0usize;
    let t0 = Instant::now();
    for pl in &mut planners {
        let mut k = 0;
        while k < moves.len() {
            k += pl.push_all(&moves[k..]).expect("pushable program");
        }
        pl.flush();
        pushed += moves.len();
        if mode == "run" || mode == "splines" {
            let mut j = [0.0; 3];
            let (mut hash, mut periods) = (0xcbf2_9ce4_8422_2325u64, 0u64);
            loop {
                let st = pl.next(&mut j);
                periods += 1;
                for x in st.axes {
                    hash = (hash ^ x.to_bits()).wrapping_mul(0x0100_0000_01b3);
                }
                if st.state == MotionState::Idle || periods > 10_000_000 {
                    break;
                }
            }
            println!("{periods} periods, set-point hash {hash:016x}");
        }
    }
    let dt = t0.elapsed().as_secs_f64();
    println!(
        "{} segments in {:.3} s: {:.0} segments/s",
        pushed,
        dt,
        pushed as f64 / dt
    );
}
