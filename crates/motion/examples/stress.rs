//! Runs random move lists (lines in three modes, random feeds and blend tolerances) and
//! counts those whose set-points exceed a limit. Prints failing programs in the format of
//! the `debug_line spec` example. Usage: stress [N] [SEED].
#![allow(clippy::needless_range_loop)]
use rtcnc_motion::*;

struct Lcg(u64);
impl Lcg {
    fn f(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

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
        let k = 1 + (rng.f() * 8.0) as usize;
        let mut spec = String::new();
        let mut moves = Vec::new();
        let mut pos = [0.0; AXES];
        for i in 0..k {
            let mut e = [0.0; AXES];
            for a in 0..3 {
                e[a] = rng.f() * 40.0 - 20.0;
            }
            if rng.f() < 0.3 {
                e[2] = pos[2];
            }
            let feed = 5.0 + rng.f() * 145.0;
            let r = rng.f();
            let (mode, ms) = if r < 0.2 {
                (PathMode::ExactStop, "S".to_string())
            } else if r < 0.4 {
                (PathMode::ExactPath, "E".to_string())
            } else {
                let p = [0.001, 0.01, 0.1][(rng.f() * 3.0) as usize % 3];
                (
                    PathMode::Blend {
                        tolerance: p,
                        merge_tolerance: 0.0,
                    },
                    format!("B {p}"),
                )
            };
            spec += &format!("{} {} {} {} {}; ", e[0], e[1], e[2], feed, ms);
            moves.push(Move::line(e, feed, mode, i as u32 + 1));
            pos = e;
        }
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
        let (mut p_ovr, mut ovr, mut p_hold, mut p_quick) =
            (usize::MAX, 1.0, usize::MAX, usize::MAX);
        if online {
            (p_ovr, ovr) = (30 + (rng.f() * 600.0) as usize, 0.2 + rng.f() * 1.5);
            p_hold = 30 + (rng.f() * 900.0) as usize;
            if rng.f() < 0.1 {
                p_quick = 30 + (rng.f() * 1500.0) as usize;
            }
        }
        // STRESS_ONLY=<case>: run only that program (for a trace with RTCNC_MOTION_TRACE).
        let only = std::env::var("STRESS_ONLY")
            .ok()
            .and_then(|x| x.parse::<usize>().ok());
        let periods_max = if only.is_some_and(|o| o != case) {
            0
        } else {
            2_000_000
        };
        for n in 0..periods_max {
            if online {
                if n == p_ovr && kind('o') {
                    if only.is_some() {
                        eprintln!("OVERRIDE {ovr} at {n}");
                    }
                    pl.set_feed_override(ovr);
                }
                if n == p_hold && kind('h') {
                    if only.is_some() {
                        eprintln!("HOLD at {n}");
                    }
                    pl.hold();
                }
                if n == p_hold.saturating_add(300) && kind('h') {
                    if only.is_some() {
                        eprintln!("RESUME at {n}");
                    }
                    pl.resume();
                }
                if n == p_quick && kind('q') {
                    if only.is_some() {
                        eprintln!("QUICK at {n}");
                    }
                    pl.quick_stop();
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
