//! G64 P never makes a corner slower than a stop: a corner is blended only where the blend
//! is estimated to take no longer than stopping and restarting there.

use crate::common::*;
use rtcnc_motion::{AXES, AxisVec, Move, PathMode};

const V: f64 = 100.0;
const A: f64 = 1000.0;
const J: f64 = 50_000.0;

/// A zigzag of 2 mm lines and R 3 arcs over 0.8 rad, meeting at 0.4 rad (23°) corners,
/// F 30 mm/s (the program of the `arc_corners` bench), `n` moves.
fn zigzag(n: usize, mode: PathMode) -> Vec<Move> {
    let (r, sweep, turn) = (3.0, 0.8f64, 0.4f64);
    let mut at = [0.0f64; 2];
    let mut dir = 0.0f64;
    let p = |x: [f64; 2]| -> AxisVec {
        let mut v = [0.0; AXES];
        v[0] = x[0];
        v[1] = x[1];
        v
    };
    let mut moves = Vec::with_capacity(n);
    for k in 0..n {
        if k % 2 == 0 {
            at = [at[0] + 2.0 * dir.cos(), at[1] + 2.0 * dir.sin()];
            moves.push(Move::line(p(at), 30.0, mode, k as u32 + 1));
            dir += turn;
        } else {
            let s = if (k / 2) % 2 == 0 { 1.0 } else { -1.0 };
            let c = [at[0] - s * r * dir.sin(), at[1] + s * r * dir.cos()];
            let a0 = (at[1] - c[1]).atan2(at[0] - c[0]);
            let a1 = a0 + s * sweep;
            at = [c[0] + r * a1.cos(), c[1] + r * a1.sin()];
            moves.push(Move::arc(
                p(at),
                [c[0], c[1], 0.0],
                [0.0, 0.0, s],
                0,
                30.0,
                mode,
                k as u32 + 1,
            ));
            dir += s * sweep - turn;
        }
    }
    moves
}

/// Periods the zigzag takes in `mode`, with the limits checked.
fn periods(n: usize, mode: PathMode) -> usize {
    let lim = limits(V, A, J);
    let mut pl = planner(&lim, p3(0.0, 0.0, 0.0), 256);
    let tr = run(&mut pl, &zigzag(n, mode), 1_000_000);
    let (rv, ra, rj) = ratios(&tr, V, A, J);
    let tol = 1.0 + 1e-9;
    if std::env::var("ZIGZAG_MEASURE").is_ok() {
        eprintln!("{mode:?}: v {rv} a {ra} j {rj}, {} periods", tr.speed.len());
        return tr.speed.len();
    }
    assert!(
        rv <= tol && ra <= tol && rj <= tol,
        "{mode:?}: v {rv} a {ra} j {rj}"
    );
    assert_eq!(pl.stats().limit_violations, 0, "{mode:?}");
    tr.speed.len()
}

/// At P 0.01 and 0.001 the blends' speed limits (curvature change, about 10 and 2-3 mm/s)
/// make them slower than a stop at F 30: G64 must take no longer than G61. At P 0.1 the
/// blends pay and the path is faster than G61.
#[test]
fn zigzag_in_g64_takes_no_longer_than_exact_stops() {
    // The whole bench program (400 moves) with ZIGZAG_MEASURE set: figures, no checks.
    let n = if std::env::var("ZIGZAG_MEASURE").is_ok() {
        400
    } else {
        24
    };
    let g61 = periods(n, PathMode::ExactPath);
    for p in [0.01, 0.001] {
        let g64 = periods(n, blend(p));
        eprintln!("{n} moves: G64 P {p} {g64} periods, G61 {g61}");
        assert!(g64 <= g61, "P {p}: {g64} periods, G61 {g61}");
    }
    let g64 = periods(n, blend(0.1));
    eprintln!("{n} moves: G64 P 0.1 {g64} periods, G61 {g61}");
    assert!(g64 < g61, "P 0.1: {g64} periods, G61 {g61}");
}

/// Line corners follow the same choice: a square wave of 2 mm lines turning 90° either way
/// (too sharp for polyline smoothing). At F 30 every blend is slower than a stop (with the
/// former threshold P 0.1 blended them and took 3637 periods against 2809 in G61); at F 5
/// the P 0.1 blends pay.
#[test]
fn square_wave_of_lines_in_g64_takes_no_longer_than_exact_stops() {
    for feed in [30.0, 5.0] {
        square_wave(feed);
    }
}

fn square_wave(feed: f64) {
    let wave = |mode: PathMode| -> Vec<Move> {
        let dirs = [[1.0, 0.0], [0.0, 1.0], [1.0, 0.0], [0.0, -1.0]];
        let mut at = [0.0f64; 2];
        (0..24)
            .map(|k| {
                let d = dirs[k % 4];
                at = [at[0] + 2.0 * d[0], at[1] + 2.0 * d[1]];
                Move::line(p3(at[0], at[1], 0.0), feed, mode, k as u32 + 1)
            })
            .collect()
    };
    let periods = |mode: PathMode| {
        let lim = limits(V, A, J);
        let mut pl = planner(&lim, p3(0.0, 0.0, 0.0), 256);
        let tr = run(&mut pl, &wave(mode), 1_000_000);
        let (rv, ra, rj) = ratios(&tr, V, A, J);
        let tol = 1.0 + 1e-9;
        assert!(
            rv <= tol && ra <= tol && rj <= tol,
            "{mode:?}: v {rv} a {ra} j {rj}"
        );
        assert_eq!(pl.stats().limit_violations, 0, "{mode:?}");
        (tr.speed.len(), pl.geometry_stats())
    };
    let (g61, _) = periods(PathMode::ExactPath);
    for p in [0.001, 0.01, 0.1] {
        let (g64, gs) = periods(blend(p));
        eprintln!("square wave F {feed} P {p}: {g64} periods, G61 {g61}, {gs:?}");
        assert!(g64 <= g61, "F {feed} P {p}: {g64} periods, G61 {g61}");
        if feed < 10.0 && p == 0.1 {
            assert_eq!(gs.blends, 23);
            assert!(g64 < g61);
        }
    }
}
