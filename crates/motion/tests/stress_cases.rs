//! Move lists the randomised stress run (`examples/stress.rs`) found exceeding a limit,
//! shrunk to a few moves (`examples/shrink.rs`). Each must keep every axis's v, a, j limit
//! in every period, end exactly and count no violation. They failed with the controller
//! before set-points were generated ahead with verification and rollback (the spline case:
//! with the rollback before it restarted from states that fit the stricter model).

use crate::common::*;
use rtcnc_motion::{Bezier, Move, PathMode};

const V: f64 = 100.0;
const A: f64 = 1000.0;
const J: f64 = 50_000.0;

fn check(moves: &[Move], window: usize) {
    let lim = limits(V, A, J);
    let mut pl = planner(&lim, p3(0.0, 0.0, 0.0), window);
    let tr = run(&mut pl, moves, 20_000);
    assert_limits(&tr, V, A, J);
    assert_eq!(pl.stats().limit_violations, 0, "{:?}", pl.stats());
    let end = match moves.last().unwrap().kind {
        rtcnc_motion::MoveKind::Line { end, .. } | rtcnc_motion::MoveKind::Spline { end, .. } => {
            end
        }
        _ => unreachable!(),
    };
    let last = *tr.pts.last().unwrap();
    assert!(
        dist(&last, &end) <= 1e-9,
        "end off by {}",
        dist(&last, &end)
    );
}

/// Seed 1, program 428 of `stress 500 1`: a fast 3-D line into a blended corner, then an
/// exact stop. The controller used to notice the corner's slow-down too late and the
/// set-point jumped (acceleration 21 ×, jerk 400 × the limit).
#[test]
fn fast_line_into_a_blend_then_a_stop_keeps_the_limits() {
    let moves = [
        Move::line(p3(8.0, 13.0, 18.0), 145.0, blend(0.01), 1),
        Move::line(p3(-14.0, -3.0, 18.0), 123.0, blend(0.1), 2),
        Move::line(p3(-20.0, -6.0, 18.0), 110.0, PathMode::ExactStop, 3),
    ];
    for window in [64, 256, 2048] {
        check(&moves, window);
    }
}

/// Seed 2, program 221 of `stress 500 2`: a short blended zig-zag with feeds from 39 to
/// 118 mm/s (jerk 5.6 × the limit before the fix).
#[test]
fn short_zig_zag_with_mixed_feeds_keeps_the_limits() {
    let moves = [
        Move::line(p3(6.0, 20.0, -1.0), 118.0, PathMode::ExactPath, 1),
        Move::line(p3(6.0, 17.8, -1.0), 112.0, blend(0.01), 2),
        Move::line(p3(11.0, 11.85, -1.0), 39.0, blend(0.1), 3),
        Move::line(p3(-7.0, 6.0, 1.0), 84.0, blend(0.1), 4),
    ];
    for window in [64, 256, 2048] {
        check(&moves, window);
    }
}

/// Seed 6, program 400 of `stress 500 6` (once isolated lines follow the OTG profile): a
/// line to an exact-path stop, then two blended lines; the per-sample check moves points
/// on the second blend (acceleration and jerk up to 1.23 × the limit).
#[test]
fn line_to_a_stop_then_two_blends_keeps_the_limits() {
    let moves = [
        Move::line(p3(5.0, 2.8, -12.863), 63.0, PathMode::ExactPath, 1),
        Move::line(p3(-3.162995, 0.4, -17.1), 42.0, blend(0.1), 2),
        Move::line(p3(-11.85, -6.47, -15.574), 68.0, blend(0.001), 3),
    ];
    check(&moves, 256);
}

/// A random program of the kind `tests/splines_random.rs` makes (from another seed of
/// its generator, shrunk): a quadratic into a cubic, G61. Along the tightening curve the
/// path's deceleration bound falls (from −1000 to −115 mm/s²) faster than the speed can
/// follow, the set-points rise above the braking curve and meet dead ends. The rollbacks
/// made the whole region's model stricter, its stop model too, until the state they
/// restarted from (accelerating out of the start) could no longer stop under it and was a
/// dead end itself: they reached the emitted set-point (window 64: 132 violations,
/// acceleration 3.6 ×, jerk 118 × the limit). Now a rollback restarts from a state that
/// fits the stricter model.
#[test]
fn rollbacks_on_a_tightening_spline_do_not_cascade_into_a_violation() {
    let moves = [
        Move::spline(
            p3(-3.974, -0.454, 0.0),
            Bezier::Quadratic(p3(-3.65, 1.895, 0.0)),
            90.0,
            PathMode::ExactPath,
            1,
        ),
        Move::spline(
            p3(-7.0, -3.0, 0.0),
            Bezier::Cubic([p3(-4.331, -3.043, 0.0), p3(-4.0, -4.0, 0.0)]),
            90.0,
            PathMode::ExactPath,
            2,
        ),
    ];
    for window in [64, 256, 2048] {
        check(&moves, window);
    }
}

/// Seed 18, program 122 of the spline-and-line programs of `examples/splines_seeds.rs`,
/// shrunk: a quadratic from rest into an exact stop, then a line. The stop model of the
/// spline's last piece took the deceleration where that piece starts (a tight bend, about
/// 240 mm/s²) for the whole stop, where the piece before had taken its own (about
/// 530 mm/s²): the state entered the last piece at 52 mm/s, still accelerating, under the
/// braking curve but unable to stop under the new model. The generator followed that
/// model's stop profile until the set-point check failed some 200 periods later, when
/// every buffered state was too fast (23 counted violations, acceleration 5.5 ×, jerk
/// 105 × the limit). After them, the rollback's stricter model stayed in force at the
/// stop, where the line starts at a braking-curve speed of zero, and kept the machine at
/// rest for ever: the program never ended. Now the stop model never falls on the way into
/// a stop, and a stricter model ends at the stop it braked for.
#[test]
fn a_spline_into_a_stop_keeps_the_limits_and_the_next_line_starts() {
    let moves = [
        Move::spline(
            p3(-9.7, -5.0, 0.0),
            Bezier::Quadratic(p3(3.3, -6.0, 0.0)),
            105.0,
            PathMode::ExactPath,
            1,
        ),
        Move::line(p3(-20.0, -11.0, 0.0), 105.0, PathMode::ExactPath, 2),
    ];
    for window in [64, 256, 2048] {
        check(&moves, window);
    }
}
