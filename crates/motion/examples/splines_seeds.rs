//! Runs the random spline programs of `tests/splines_random.rs` from other seeds and
//! reports those that exceed a limit, count a violation, miss their end point or do not
//! end. Usage: `splines_seeds [COUNT] [FIRST_SEED] [LAST_SEED]` (defaults 150 1 20): for
//! every seed N, COUNT programs of splines alone and COUNT with lines between them, the
//! test's xorshift generator seeded with N (spline-only) and N + 1000 (with lines).
//! `SPLINES_ONLY=<lines|splines>:<seed>:<case>` runs one program and prints its moves
//! (built with `--features diagnostics` and run with `RTCNC_MOTION_TRACE=1` for a trace).
#![allow(clippy::needless_range_loop)]

#[path = "../tests/support/spline_programs.rs"]
mod spline_programs;

use rtcnc_motion::*;
use spline_programs::{Rng, program};

const V: f64 = 100.0;
const A: f64 = 1000.0;
const J: f64 = 50_000.0;
const T: f64 = 1e-3;
/// A program that has not ended after this many periods counts as stalled (the longest
/// programs of the generator take some 10 000).
const BUDGET: usize = 200_000;

struct Outcome {
    worst: (f64, f64, f64),
    end_error: f64,
    ended: bool,
    stats: RunStats,
}

fn run(moves: &[Move], end: &AxisVec) -> Option<Outcome> {
    let lim = MachineLimits::uniform(
        &[Axis::X, Axis::Y, Axis::Z],
        AxisLimits::new(V, A, J, -1000.0, 1000.0),
    );
    let mut pl = Planner::new(
        &lim,
        TrivialKinematics::identity(&[Axis::X, Axis::Y, Axis::Z]),
        T,
        64,
        [0.0; AXES],
    )
    .ok()?;
    let mut k = 0;
    let mut flushed = false;
    let mut joints = [0.0; 3];
    let mut h = vec![[0.0; AXES]; 3];
    let mut worst = (0.0f64, 0.0f64, 0.0f64);
    let mut ended = false;
    for _ in 0..BUDGET {
        while k < moves.len() && pl.free() > 0 {
            // Refused (a near cusp): not run.
            pl.push(&moves[k]).ok()?;
            k += 1;
        }
        if k == moves.len() && !flushed {
            pl.flush();
            flushed = true;
        }
        let st = pl.next(&mut joints);
        h.push(st.axes);
        let w = &h[h.len() - 4..];
        for i in 0..3 {
            let v = ((w[3][i] - w[2][i]) / T).abs() / V;
            let a = ((w[3][i] - 2.0 * w[2][i] + w[1][i]) / (T * T)).abs() / A;
            let j = ((w[3][i] - 3.0 * w[2][i] + 3.0 * w[1][i] - w[0][i]) / (T * T * T)).abs() / J;
            worst = (worst.0.max(v), worst.1.max(a), worst.2.max(j));
        }
        if flushed && st.state == MotionState::Idle {
            ended = true;
            break;
        }
    }
    let last = h.last().copied().unwrap_or([0.0; AXES]);
    let end_error = (0..AXES)
        .map(|i| (last[i] - end[i]).powi(2))
        .sum::<f64>()
        .sqrt();
    Some(Outcome {
        worst,
        end_error,
        ended,
        stats: pl.stats(),
    })
}

fn seed_of(seed: u64, lines: bool) -> u64 {
    if lines { seed + 1000 } else { seed }
}

fn main() {
    let arg = |n: usize, d: u64| {
        std::env::args()
            .nth(n)
            .and_then(|x| x.parse().ok())
            .unwrap_or(d)
    };
    let (count, first, last) = (arg(1, 150) as usize, arg(2, 1), arg(3, 20));
    if let Ok(only) = std::env::var("SPLINES_ONLY") {
        let f: Vec<&str> = only.split(':').collect();
        let lines = f.first() == Some(&"lines");
        let seed: u64 = f.get(1).and_then(|x| x.parse().ok()).unwrap_or(1);
        let case: usize = f.get(2).and_then(|x| x.parse().ok()).unwrap_or(0);
        let mut rng = Rng(seed_of(seed, lines));
        let mut prog = program(&mut rng, lines);
        for _ in 0..case {
            prog = program(&mut rng, lines);
        }
        for m in &prog.0 {
            println!("{m:?}");
        }
        match run(&prog.0, &prog.1) {
            Some(o) => println!(
                "v {:.4} a {:.4} j {:.4} end error {:.3e} ended {} stats {:?}",
                o.worst.0, o.worst.1, o.worst.2, o.end_error, o.ended, o.stats
            ),
            None => println!("refused"),
        }
        return;
    }
    let (mut total, mut refused, mut failed) = (0, 0, 0);
    let (mut periods, mut rollbacks, mut violations) = (0u64, 0u64, 0u64);
    for seed in first..=last {
        for lines in [false, true] {
            let mut rng = Rng(seed_of(seed, lines));
            for case in 0..count {
                let (moves, end) = program(&mut rng, lines);
                total += 1;
                let Some(o) = run(&moves, &end) else {
                    refused += 1;
                    continue;
                };
                periods += o.stats.periods;
                rollbacks += o.stats.rollbacks;
                violations += o.stats.limit_violations;
                let tol = 1.0 + 1e-9;
                if !o.ended
                    || o.end_error > 1e-9
                    || o.stats.limit_violations > 0
                    || o.worst.0 > tol
                    || o.worst.1 > tol
                    || o.worst.2 > tol
                {
                    failed += 1;
                    let kind = if lines { "lines" } else { "splines" };
                    println!(
                        "SPLINES_ONLY={kind}:{seed}:{case}: v {:.3} a {:.3} j {:.3} end error {:.3e} ended {} stats {:?}",
                        o.worst.0, o.worst.1, o.worst.2, o.end_error, o.ended, o.stats
                    );
                }
            }
        }
    }
    println!(
        "{failed} of {total} programs failed ({refused} refused as (near) cusps; {periods} periods, {rollbacks} rollbacks, {violations} counted violations)"
    );
}
