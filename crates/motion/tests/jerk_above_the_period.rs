//! A jerk limit far above what set-points one servo period apart can resolve (a jerk phase,
//! acceleration over jerk, shorter than a period) is planned as a jerk phase of two periods
//! (`MIN_JERK_PHASE_PERIODS`): every limit kept, and a move as long as the closed form says.
//! Before, a 10^7 mm/s³ limit at 1 000 mm/s² and 1 ms let the stop model brake later than
//! whole periods allow: an engraving exceeded the acceleration 7 × and a 10^8 limit stalled.

use crate::common::*;
use rtcnc_motion::{MIN_JERK_PHASE_PERIODS, Move, PathMode};

const V: f64 = 100.0;
const A: f64 = 1000.0;

/// Periods of a rest-to-rest move of `d` along one axis that reaches `V` and `A`: the
/// S-curve's closed form d/v + v/a + a/j, rounded up to whole periods.
fn closed_form_periods(d: f64, j: f64) -> usize {
    ((d / V + V / A + A / j) / T - 1e-9).ceil() as usize
}

/// Periods the planner takes from the first set-point that moves to the first at the end.
fn moving_periods(tr: &Trace, end: f64) -> usize {
    let first = tr.pts.iter().position(|p| p[0] != 0.0).expect("it moves");
    let last = tr.pts.iter().position(|p| p[0] == end).expect("it arrives");
    last - first + 1
}

#[test]
fn a_jerk_phase_shorter_than_two_periods_is_planned_as_two() {
    let resolved = A / (MIN_JERK_PHASE_PERIODS * T);
    assert_eq!(resolved, 500_000.0);
    for jerk in [1e6, 1e7, 1e8, 1e12] {
        let mut pl = planner(&limits(V, A, jerk), p3(0.0, 0.0, 0.0), 64);
        let tr = run(
            &mut pl,
            &[Move::line(p3(50.0, 0.0, 0.0), V, PathMode::ExactStop, 1)],
            5000,
        );
        // The jerk the planner plans with, not only the machine's.
        assert_limits(&tr, V, A, resolved);
        assert_eq!(pl.stats().limit_violations, 0);
        let periods = moving_periods(&tr, 50.0);
        let expected = closed_form_periods(50.0, resolved);
        assert!(
            periods.abs_diff(expected) <= 1,
            "jerk {jerk}: {periods} periods, closed form {expected}"
        );
    }
}

#[test]
fn a_jerk_limit_the_period_resolves_is_kept_as_it_is() {
    // 50 000 mm/s³: a 20 ms jerk phase; the move takes the closed form's 0.62 s.
    let mut pl = planner(&limits(V, A, 50_000.0), p3(0.0, 0.0, 0.0), 64);
    let tr = run(
        &mut pl,
        &[Move::line(p3(50.0, 0.0, 0.0), V, PathMode::ExactStop, 1)],
        5000,
    );
    assert_limits(&tr, V, A, 50_000.0);
    let periods = moving_periods(&tr, 50.0);
    assert!(
        periods.abs_diff(closed_form_periods(50.0, 50_000.0)) <= 1,
        "{periods}"
    );
}

#[test]
fn short_segments_at_a_huge_jerk_limit_keep_the_acceleration() {
    // A zigzag of 0.3-1.2 mm chords turning 30-150°, blended within 0.05 mm, as an
    // engraving: at 10^8 mm/s³ the acceleration and the resolved jerk hold.
    let mut moves = Vec::new();
    let (mut x, mut y, mut heading) = (0.0f64, 0.0f64, 0.0f64);
    for k in 0..400u32 {
        let turn = (30.0 + 120.0 * f64::from(k * 37 % 11) / 10.0).to_radians();
        heading += if k % 2 == 0 { turn } else { -turn };
        let len = 0.3 + 0.9 * f64::from(k * 53 % 7) / 6.0;
        x += len * heading.cos();
        y += len * heading.sin();
        moves.push(Move::line(p3(x, y, 0.0), 60.0, blend(0.05), k + 1));
    }
    let mut pl = planner(&limits(V, A, 1e8), p3(0.0, 0.0, 0.0), 256);
    let tr = run(&mut pl, &moves, 200_000);
    assert_limits(&tr, V, A, A / (MIN_JERK_PHASE_PERIODS * T));
    assert_eq!(pl.stats().limit_violations, 0);
}
