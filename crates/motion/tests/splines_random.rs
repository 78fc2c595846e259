//! Seeded random spline programs (G5/G5.1 chains, tangent or not, quadratic and cubic,
//! G61 and G64, feeds 10-150 mm/s; alone and with lines between them): every one is either
//! refused as a (near) cusp or ends exactly at its end point within the period budget, and
//! the limits hold in every one. 40 programs of each kind in debug builds, 150 and 300 in
//! release
//! (`cargo test --release -p rtcnc-motion --test suite -- splines_random:: --nocapture`).

use crate::common::*;
use crate::spline_programs::{Rng, program};

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
