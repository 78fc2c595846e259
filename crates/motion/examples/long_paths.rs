//! The long-path program of `tests/long_paths.rs` at the benchmark machine's limits (100
//! mm/s, 1000 mm/s², 50 000 mm/s³ per axis, 1 ms), where the test runs it 1000 × faster:
//! rapids back and forth between X −1000 and X 1000 with blended zigzags that end in exact
//! stops, then a circle polyline and a G61 square. Prints whether it ended, the end-point
//! error, the largest |v|, |a|, |j| against the limits and the planner's counters.
//!
//! Usage: `cargo run --release -p rtcnc-motion --example long_paths -- [LENGTH_MM [SCALE]]`
//! (defaults 1e6 mm, scale 1: 10^7 periods, some 10-20 s).

#![allow(clippy::needless_range_loop)]

#[path = "../tests/support/long_path_program.rs"]
mod long_path_program;

use rtcnc_motion::*;

fn main() {
    let mut args = std::env::args().skip(1);
    let length: f64 = args.next().and_then(|s| s.parse().ok()).unwrap_or(1e6);
    let scale: f64 = args.next().and_then(|s| s.parse().ok()).unwrap_or(1.0);
    let (v, a, j, t) = (100.0 * scale, 1000.0 * scale, 50_000.0 * scale, 1e-3);
    let machine = MachineLimits::uniform(
        &[Axis::X, Axis::Y, Axis::Z],
        AxisLimits::new(v, a, j, -1000.0, 1000.0),
    );
    let kin = TrivialKinematics::identity(&[Axis::X, Axis::Y, Axis::Z]);
    let mut pl = Planner::new(&machine, kin, t, 256, [0.0; AXES]).expect("planner");
    let (moves, end) = long_path_program::long_path_program(length, scale);
    let mut joints = [0.0; 3];
    let mut hist = [[0.0f64; 3]; 4];
    let mut worst = [0.0f64; 3];
    let (mut k, mut flushed, mut ended) = (0, false, false);
    let budget = (4.0 * length / (30.0 * scale) / t) as u64 + 1_000_000;
    let mut periods = 0u64;
    while periods < budget {
        while k < moves.len() && pl.free() > 0 {
            pl.push(&moves[k]).expect("push");
            k += 1;
        }
        if k == moves.len() && !flushed {
            pl.flush();
            flushed = true;
        }
        let st = pl.next(&mut joints);
        periods += 1;
        hist.copy_within(1.., 0);
        hist[3] = [st.axes[0], st.axes[1], st.axes[2]];
        if periods >= 4 {
            for i in 0..3 {
                let d1 = hist[3][i] - hist[2][i];
                let d2 = d1 - (hist[2][i] - hist[1][i]);
                let d3 = d2 - (hist[2][i] - 2.0 * hist[1][i] + hist[0][i]);
                worst[0] = worst[0].max(d1.abs() / (v * t));
                worst[1] = worst[1].max(d2.abs() / (a * t * t));
                worst[2] = worst[2].max(d3.abs() / (j * t * t * t));
            }
        }
        if flushed && st.state == MotionState::Idle {
            ended = true;
            break;
        }
    }
    let err = (0..3)
        .map(|i| (hist[3][i] - end[i]).abs())
        .fold(0.0, f64::max);
    println!(
        "{length} mm of path, {} moves, scale {scale}: {} after {periods} periods; end error {err:.1e} mm; largest |v|, |a|, |j| / limit {:.9}, {:.9}, {:.9}",
        moves.len(),
        if ended { "ended" } else { "DID NOT END" },
        worst[0],
        worst[1],
        worst[2]
    );
    println!("{:?}", pl.stats());
}
