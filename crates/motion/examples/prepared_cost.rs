//! What a push costs where the kernel holds its lock: the bracket's outline
//! (examples/bracket.ngc: lines into tangent arcs of R 5, G64 P0.01, F 20 mm/s; 20 laps)
//! pushed whole (`Planner::push`, all under the lock before moves were built apart) and
//! built apart (`PreparedMove::build` without the lock, then `prepare` and `push_prepared`
//! under it). Prints the median, the 90th percentile and the longest call, in µs, each call
//! the shortest of five repetitions.
//!
//!   cargo run [--release] -p rtcnc-motion --example prepared_cost

use std::time::Instant;

use rtcnc_motion::{
    AXES, Axis, AxisLimits, AxisVec, MachineLimits, Move, PathMode, Planner, PreparedMove,
    TrivialKinematics,
};

fn p2(x: f64, y: f64) -> AxisVec {
    let mut p = [0.0; AXES];
    p[0] = x;
    p[1] = y;
    p
}

fn outline(laps: usize) -> Vec<Move> {
    let mode = PathMode::Blend {
        tolerance: 0.01,
        merge_tolerance: 0.0,
    };
    let (f, z) = (20.0, [0.0, 0.0, 1.0]);
    let mut moves = Vec::new();
    for lap in 0..laps {
        let line = 10 * lap as u32;
        moves.extend([
            Move::line(p2(60.0, -5.0), f, mode, line + 1),
            Move::arc(p2(65.0, 0.0), [60.0, 0.0, 0.0], z, 0, f, mode, line + 2),
            Move::line(p2(65.0, 35.0), f, mode, line + 3),
            Move::arc(p2(60.0, 40.0), [60.0, 35.0, 0.0], z, 0, f, mode, line + 4),
            Move::line(p2(5.0, 40.0), f, mode, line + 5),
            Move::arc(p2(0.0, 35.0), [5.0, 35.0, 0.0], z, 0, f, mode, line + 6),
            Move::line(p2(0.0, 0.0), f, mode, line + 7),
            Move::arc(p2(5.0, -5.0), [5.0, 0.0, 0.0], z, 0, f, mode, line + 8),
        ]);
    }
    moves
}

fn planner() -> Planner<TrivialKinematics> {
    let lim = AxisLimits::new(100.0, 1000.0, 50_000.0, -100.0, 300.0);
    Planner::new(
        &MachineLimits::uniform(&[Axis::X, Axis::Y], lim),
        TrivialKinematics::identity(&[Axis::X, Axis::Y]),
        1e-3,
        1024,
        p2(5.0, -5.0),
    )
    .expect("the machine is valid")
}

/// Durations in µs per call, the shortest of the repetitions (a preemption on a loaded
/// machine lengthens one repetition's call, rarely all of them).
#[derive(Default)]
struct Times(Vec<f64>);

impl Times {
    fn add(&mut self, call: usize, t0: Instant) {
        let us = t0.elapsed().as_secs_f64() * 1e6;
        match self.0.get_mut(call) {
            Some(t) => *t = t.min(us),
            None => self.0.push(us),
        }
    }
    fn show(&self, what: &str) {
        let mut t = self.0.clone();
        t.sort_by(f64::total_cmp);
        let at = |q: f64| t[((t.len() - 1) as f64 * q) as usize];
        println!(
            "{what:<42} median {:8.1}  p90 {:8.1}  longest {:8.1} µs ({} calls)",
            at(0.5),
            at(0.9),
            at(1.0),
            t.len()
        );
    }
}

const REPETITIONS: usize = 5;

fn main() {
    let moves = outline(20);
    let (mut push, mut held, mut build) = (Times::default(), Times::default(), Times::default());
    let mut blends = 0;
    for _ in 0..REPETITIONS {
        let mut whole = planner();
        for (call, mv) in moves.iter().enumerate() {
            let t0 = Instant::now();
            whole.push(mv).expect("the outline fits the window");
            push.add(call, t0);
        }
        blends = whole.geometry_stats().blends;
        let mut apart = planner();
        let mut staging = PreparedMove::new();
        for (key, mv) in moves.iter().enumerate() {
            let t0 = Instant::now();
            apart.prepare(mv, key as u64, &mut staging);
            held.add(2 * key, t0);
            let t0 = Instant::now();
            staging.build();
            build.add(key, t0);
            let t0 = Instant::now();
            apart
                .push_prepared(&mut staging)
                .expect("the outline fits the window");
            // The copy and the append are two holds of the lock.
            held.add(2 * key + 1, t0);
        }
    }
    println!("blends: {blends}");
    push.show("push (all under the lock)");
    build.show("build (without the lock)");
    held.show("prepare or push_prepared (under the lock)");
}
