//! Runs random move lists (lines in three modes, random feeds and blend tolerances) and
//! counts those whose set-points exceed a limit. Prints failing programs in the format of
//! the `debug_line spec` example. Usage: stress [N] [SEED].
#![allow(clippy::needless_range_loop)]
use rtcnc_motion::*;

#[path = "../tests/support/line_programs.rs"]
mod line_programs;
use line_programs::{Change, Lcg, random_changes, random_lines};

fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|x| x.parse().ok())
        .unwrap_or(200);
    let seed: u64 = std::env::args()
        .nth(2)
        .and_then(|x| x.parse().ok())
        .unwrap_or(1);
    let mut rng = Lcg(seed);
    let (vm, am, jm, t) = (100.0, 1000.0, 50_000.0, 1e-3);
    let mut failures = 0;
    let (mut periods, mut rollbacks, mut violations, mut generated) = (0u64, 0u64, 0u64, 0u64);
    for case in 0..n {
        let (spec, moves) = random_lines(&mut rng);
        let lim = MachineLimits::uniform(
            &[Axis::X, Axis::Y, Axis::Z],
            AxisLimits::new(vm, am, jm, -1000.0, 1000.0),
        );
        let mut pl = Planner::new(
            &lim,
            TrivialKinematics::identity(&[Axis::X, Axis::Y, Axis::Z]),
            t,
            256,
            [0.0; AXES],
        )
        .unwrap();
        for m in &moves {
            pl.push(m).unwrap();
        }
        pl.flush();
        let mut h = vec![[0.0; AXES]; 3];
        let mut j = [0.0; 3];
        let mut worst = (0.0f64, 0.0f64, 0.0f64);
        // STRESS_ONLINE=1: on-line changes at random periods (an override, a hold and its
        // resume, and in one program of ten a quick stop).
        let online_kinds = std::env::var("STRESS_ONLINE").unwrap_or_default();
        let online = !online_kinds.is_empty();
        let kind = |c: char| online_kinds.contains(c) || online_kinds == "1";
        // (Drawn only then, so that the programs of a seed stay those of plain runs.)
        let changes = if online {
            random_changes(&mut rng)
        } else {
            Vec::new()
        };
        // STRESS_ONLY=<case>: run only that program (for a trace: `--features diagnostics` and RTCNC_MOTION_TRACE=1).
        let only = std::env::var("STRESS_ONLY")
            .ok()
            .and_then(|x| x.parse::<usize>().ok());
        let periods_max = if only.is_some_and(|o| o != case) {
            0
        } else {
            2_000_000
        };
        for n in 0..periods_max {
            for (at, c) in &changes {
                let letter = match c {
                    Change::Override(_) => 'o',
                    Change::Hold | Change::Resume => 'h',
                    Change::QuickStop => 'q',
                };
                if *at != n || !kind(letter) {
                    continue;
                }
                if only.is_some() {
                    eprintln!("{c:?} at {n}");
                }
                match *c {
                    Change::Override(f) => pl.set_feed_override(f),
                    Change::Hold => pl.hold(),
                    Change::Resume => pl.resume(),
                    Change::QuickStop => pl.quick_stop(),
                }
            }
            let st = pl.next(&mut j);
            h.push(st.axes);
            let w = &h[h.len() - 4..];
            for i in 0..3 {
                let v = ((w[3][i] - w[2][i]) / t).abs() / vm;
                let a = ((w[3][i] - 2.0 * w[2][i] + w[1][i]) / (t * t)).abs() / am;
                let jj =
                    ((w[3][i] - 3.0 * w[2][i] + 3.0 * w[1][i] - w[0][i]) / (t * t * t)).abs() / jm;
                worst = (worst.0.max(v), worst.1.max(a), worst.2.max(jj));
            }
            if st.state == MotionState::Idle {
                break;
            }
        }
        let st = pl.stats();
        periods += st.periods;
        rollbacks += st.rollbacks;
        violations += st.limit_violations;
        generated += st.generated;
        if worst.0 > 1.0 + 1e-9 || worst.1 > 1.0 + 1e-9 || worst.2 > 1.0 + 1e-9 {
            failures += 1;
            if failures <= 5 {
                println!(
                    "case {case}: v {:.3} a {:.3} j {:.3} stats {:?}\n  SPEC=\"{}\"",
                    worst.0,
                    worst.1,
                    worst.2,
                    pl.stats(),
                    spec
                );
            }
        }
    }
    println!(
        "{failures} of {n} programs exceeded a limit ({periods} periods, {generated} set-points generated, {rollbacks} rollbacks, {violations} counted violations)"
    );
}
