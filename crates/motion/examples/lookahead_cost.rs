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

use rtcnc_motion::{AXES, MotionState};

#[path = "../benches/support/programs.rs"]
mod programs;
use programs::{planner, polyline, push_program, spline_chain};

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
    let mut planners: Vec<_> = (0..reps)
        .map(|_| planner(start, 4 * moves.len() + 16, 1000.0))
        .collect();
    if setup_only {
        println!("{} planners created", planners.len());
        return;
    }
    let mut pushed = 0usize;
    let t0 = Instant::now();
    for pl in &mut planners {
        push_program(pl, &moves);
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
