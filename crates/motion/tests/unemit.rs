//! Going back over emitted set-points (`Planner::unemit`): a caller that computes set-points
//! ahead of the period they are applied in, and goes back over the ones not yet applied
//! before an on-line change, applies exactly the set-points of a planner that computed each
//! one just in time and got the change in the same period. The reference here is that
//! just-in-time planner, bit for bit.

use crate::common::*;

use crate::line_programs::{Lcg, random_lines};

use rtcnc_motion::{
    AXES, AxisVec, Bezier, Move, PathMode, Planner, RewindError, TrivialKinematics,
};

#[derive(Debug, Clone, Copy)]
enum Change {
    Hold,
    Resume,
    Override(f64),
    Abort,
    QuickStop,
}

fn apply(pl: &mut Planner<TrivialKinematics>, change: Change) {
    match change {
        Change::Hold => pl.hold(),
        Change::Resume => pl.resume(),
        Change::Override(f) => pl.set_feed_override(f),
        Change::Abort => pl.abort(),
        Change::QuickStop => pl.quick_stop(),
    }
}

fn loaded(moves: &[Move], history: usize) -> Planner<TrivialKinematics> {
    let lim = limits(100.0, 1000.0, 50_000.0);
    let mut pl = planner(&lim, p3(0.0, 0.0, 0.0), 256).with_history(history);
    for m in moves {
        pl.push(m).unwrap();
    }
    pl.flush();
    pl
}

/// The set-points applied in periods 0..periods by a just-in-time planner, with `changes`
/// made before the set-point of their period is computed.
fn just_in_time(moves: &[Move], changes: &[(usize, Change)], periods: usize) -> Vec<AxisVec> {
    let mut pl = loaded(moves, 0);
    let mut joints = [0.0; 3];
    (0..periods)
        .map(|n| {
            for &(_, c) in changes.iter().filter(|(at, _)| *at == n) {
                apply(&mut pl, c);
            }
            pl.next(&mut joints).axes
        })
        .collect()
}

/// The same with the set-points computed `lead` periods ahead: before a change, the ones
/// not yet applied are gone back over.
fn ahead(moves: &[Move], changes: &[(usize, Change)], periods: usize, lead: usize) -> Vec<AxisVec> {
    let mut pl = loaded(moves, lead);
    let mut joints = [0.0; 3];
    let mut queue: std::collections::VecDeque<AxisVec> = Default::default();
    let mut applied = Vec::new();
    for n in 0..periods {
        let at_n: Vec<Change> = changes
            .iter()
            .filter(|(at, _)| *at == n)
            .map(|&(_, c)| c)
            .collect();
        if !at_n.is_empty() {
            pl.unemit(queue.len()).unwrap();
            queue.clear();
            for c in at_n {
                apply(&mut pl, c);
            }
        }
        while queue.len() < lead {
            queue.push_back(pl.next(&mut joints).axes);
        }
        applied.push(queue.pop_front().unwrap());
    }
    applied
}

/// The first period in which two runs differ, with both set-points (none: equal).
fn first_difference(a: &[AxisVec], b: &[AxisVec]) -> Option<(usize, AxisVec, AxisVec)> {
    (0..a.len().max(b.len()))
        .find(|&i| a.get(i) != b.get(i))
        .map(|i| {
            let at = |v: &[AxisVec]| v.get(i).copied().unwrap_or([f64::NAN; AXES]);
            (i, at(a), at(b))
        })
}

fn program_with_arcs_and_a_spline() -> Vec<Move> {
    let b = |tolerance| PathMode::Blend {
        tolerance,
        merge_tolerance: 0.0,
    };
    vec![
        Move::line(p3(20.0, 0.0, 0.0), 90.0, b(0.05), 1),
        // A quarter circle about (20, 10), counter-clockwise (normal +Z), to (30, 10).
        Move::arc(
            p3(30.0, 10.0, 0.0),
            [20.0, 10.0, 0.0],
            [0.0, 0.0, 1.0],
            0,
            80.0,
            b(0.05),
            2,
        ),
        Move::spline(
            p3(5.0, 25.0, 0.0),
            Bezier::Cubic([p3(30.0, 20.0, 0.0), p3(10.0, 15.0, 0.0)]),
            70.0,
            b(0.01),
            3,
        ),
        Move::line(p3(5.0, 25.0, -3.0), 40.0, PathMode::ExactStop, 4),
        Move::line(p3(0.0, 0.0, -3.0), 100.0, b(0.1), 5),
    ]
}

#[test]
fn going_back_without_a_change_emits_the_same_set_points_again() {
    let moves = program_with_arcs_and_a_spline();
    let reference = just_in_time(&moves, &[], 3000);
    let mut pl = loaded(&moves, 32);
    let mut joints = [0.0; 3];
    let mut emitted: Vec<AxisVec> = Vec::new();
    let mut rng = Lcg(7);
    while emitted.len() < 3000 {
        emitted.push(pl.next(&mut joints).axes);
        if rng.f() < 0.1 {
            let n = ((rng.f() * 33.0) as usize).min(pl.unemittable());
            pl.unemit(n).unwrap();
            emitted.truncate(emitted.len() - n);
        }
    }
    assert_eq!(first_difference(&emitted, &reference), None);
}

#[test]
fn a_change_after_going_back_acts_as_if_it_came_just_in_time() {
    let moves = program_with_arcs_and_a_spline();
    for (name, changes) in [
        (
            "hold and resume",
            vec![(400, Change::Hold), (900, Change::Resume)],
        ),
        (
            "overrides",
            vec![(300, Change::Override(0.4)), (650, Change::Override(1.7))],
        ),
        ("abort", vec![(500, Change::Abort)]),
        ("quick stop", vec![(700, Change::QuickStop)]),
        (
            // A resume during the last periods of the hold's stop (the landing).
            "resume while landing",
            vec![(400, Change::Hold), (455, Change::Resume)],
        ),
    ] {
        let reference = just_in_time(&moves, &changes, 4000);
        for lead in [1, 2, 5, 20, 64] {
            assert_eq!(
                first_difference(&ahead(&moves, &changes, 4000, lead), &reference),
                None,
                "{name}, lead {lead}"
            );
        }
    }
}

#[test]
fn random_programs_with_random_changes_match_the_just_in_time_planner() {
    let mut rng = Lcg(20261126);
    for _ in 0..40 {
        let (_, moves) = random_lines(&mut rng);
        let mut changes = Vec::new();
        let mut at = 0usize;
        for _ in 0..4 {
            at += 50 + (rng.f() * 600.0) as usize;
            let c = match (rng.f() * 5.0) as usize {
                0 => Change::Hold,
                1 => Change::Resume,
                2 => Change::Override(0.2 + rng.f() * 1.5),
                3 => Change::Abort,
                _ => Change::Override(1.0),
            };
            changes.push((at, c));
        }
        let reference = just_in_time(&moves, &changes, 3000);
        let lead = 1 + (rng.f() * 40.0) as usize;
        assert_eq!(
            ahead(&moves, &changes, 3000, lead),
            reference,
            "{changes:?} lead {lead}"
        );
    }
}

#[test]
fn going_back_is_refused_beyond_the_history_and_across_a_finished_stop() {
    let moves = program_with_arcs_and_a_spline();
    let mut pl = loaded(&moves, 8);
    let mut joints = [0.0; AXES];
    for _ in 0..100 {
        pl.next(&mut joints[..3]);
    }
    assert_eq!(
        pl.unemit(9),
        Err(RewindError::NotKept { asked: 9, kept: 8 })
    );
    let here = pl.position();
    // Refused: nothing changed.
    assert_eq!(pl.next(&mut joints[..3]).axes, {
        let mut other = loaded(&moves, 0);
        for _ in 0..100 {
            other.next(&mut joints[..3]);
        }
        assert_eq!(other.position(), here);
        other.next(&mut joints[..3]).axes
    });
    pl.abort();
    // The abort's stop ends in the period the planner reports idle: the path is dropped
    // there, and nothing before it can be gone back to.
    let mut periods = 0;
    while pl.next(&mut joints[..3]).state != rtcnc_motion::MotionState::Idle {
        periods += 1;
        assert!(periods < 2000);
    }
    assert_eq!(pl.unemittable(), 0);
    assert!(matches!(pl.unemit(1), Err(RewindError::NotKept { .. })));
    pl.next(&mut joints[..3]);
    assert_eq!(pl.unemittable(), 1);
}

#[test]
fn a_planner_without_history_cannot_go_back() {
    let mut pl = loaded(&program_with_arcs_and_a_spline(), 0);
    let mut joints = [0.0; 3];
    pl.next(&mut joints);
    assert_eq!(pl.unemittable(), 0);
    assert_eq!(pl.unemit(0), Ok(()));
    assert_eq!(
        pl.unemit(1),
        Err(RewindError::NotKept { asked: 1, kept: 0 })
    );
}
