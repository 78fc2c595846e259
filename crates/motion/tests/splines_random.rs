//! Seeded random spline programs (G5/G5.1 chains, tangent or not, quadratic and cubic,
//! G61 and G64, feeds 10-150 mm/s; alone and with lines between them): every one is either
//! refused as a (near) cusp or ends exactly at its end point within the period budget, and
//! the limits hold in every one. 40 programs of each kind in debug builds, 150 and 300 in
//! release
//! (`cargo test --release -p rtcnc-motion --test splines_random -- --nocapture`).

mod common;
use common::*;
use rtcnc_motion::{Bezier, Move, PathMode};

/// xorshift64: the programs are the same on every run.
struct Rng(u64);

impl Rng {
    fn f(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A program of one to four splines; with `lines`, each followed by a line along its end
/// tangent (60 %) or at a random angle.
fn program(rng: &mut Rng, lines: bool) -> (Vec<Move>, rtcnc_motion::AxisVec) {
    let n = 1 + (rng.f() * 4.0) as usize;
    let feed = 10.0 + rng.f() * 140.0;
    let mode = if rng.f() < 0.5 {
        PathMode::ExactPath
    } else {
        blend(0.01)
    };
    let mut moves = Vec::new();
    let mut p = p3(0.0, 0.0, 0.0);
    let mut prev_dir: Option<[f64; 2]> = None;
    for k in 0..n {
        let sc = 1.0 + rng.f() * 20.0;
        let mut c1 = p3(
            p[0] + (rng.f() - 0.5) * sc,
            p[1] + (rng.f() - 0.5) * sc,
            0.0,
        );
        if let Some(d) = prev_dir {
            // Mostly tangent to the move before (as G5 chains are).
            if rng.f() < 0.7 {
                let l = rng.f() * sc * 0.5 + 0.1;
                c1 = p3(p[0] + d[0] * l, p[1] + d[1] * l, 0.0);
            }
        }
        let end = p3(
            p[0] + (rng.f() - 0.5) * sc,
            p[1] + (rng.f() - 0.5) * sc,
            0.0,
        );
        let (control, last) = if rng.f() < 0.3 {
            (Bezier::Quadratic(c1), c1)
        } else {
            let c2 = p3(
                end[0] + (rng.f() - 0.5) * sc,
                end[1] + (rng.f() - 0.5) * sc,
                0.0,
            );
            (Bezier::Cubic([c1, c2]), c2)
        };
        let d = [end[0] - last[0], end[1] - last[1]];
        let l = d[0].hypot(d[1]);
        prev_dir = Some([d[0] / l, d[1] / l]);
        moves.push(Move::spline(end, control, feed, mode, k as u32 + 1));
        p = end;
        if lines {
            let l = rng.f() * sc;
            let ang = if rng.f() < 0.6 {
                0.0
            } else {
                (rng.f() - 0.5) * 3.0
            };
            let (c, s) = (ang.cos(), ang.sin());
            let d = prev_dir.unwrap();
            let dir = [c * d[0] - s * d[1], s * d[0] + c * d[1]];
            let e = p3(p[0] + l * dir[0], p[1] + l * dir[1], 0.0);
            moves.push(Move::line(e, feed, mode, k as u32 + 100));
            prev_dir = Some(dir);
            p = e;
        }
    }
    (moves, p)
}

/// Runs `count` programs from `seed`: none may exceed a limit or count a violation.
fn check(count: usize, seed: u64, lines: bool) {
    let mut rng = Rng(seed);
    let lim = limits(100.0, 1000.0, 50_000.0);
    let (mut run_count, mut excess, mut refused) = (0, Vec::new(), 0);
    for case in 0..count {
        let (moves, end) = program(&mut rng, lines);
        // Refused only as a (near) cusp: a curve that stops and turns back.
        let mut pl = planner(&lim, p3(0.0, 0.0, 0.0), 64);
        if let Some(e) = moves.iter().find_map(|m| pl.push(m).err()) {
            assert!(e.to_string().contains("turns back"), "case {case}: {e}");
            refused += 1;
            continue;
        }
        let mut pl = planner(&lim, p3(0.0, 0.0, 0.0), 64);
        let tr = run(&mut pl, &moves, 60_000);
        assert!(
            dist(tr.pts.last().unwrap(), &end) <= 1e-12,
            "case {case}: end"
        );
        let (rv, ra, rj) = ratios(&tr, 100.0, 1000.0, 50_000.0);
        if pl.stats().limit_violations > 0 || rv.max(ra).max(rj) > 1.0 + 1e-9 {
            excess.push((case, rv, ra, rj));
        }
        run_count += 1;
    }
    println!("{run_count} run, {refused} refused as (near) cusps, exceeding: {excess:?}");
    assert!(run_count >= count * 9 / 10, "{refused} refused");
    assert!(excess.is_empty(), "{excess:?}");
}

#[test]
fn random_spline_programs_end_exactly_within_the_limits() {
    let count = if cfg!(debug_assertions) { 40 } else { 150 };
    check(count, 0x1234_5678_9abc_def1, false);
}

#[test]
fn random_spline_and_line_programs_end_exactly_within_the_limits() {
    let count = if cfg!(debug_assertions) { 40 } else { 300 };
    check(count, 0x9876_5432_1fed_cba1, true);
}
