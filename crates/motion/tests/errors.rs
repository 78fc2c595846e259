//! Bad input gives an error value with a code and the program line, never a panic.

use crate::common::*;
use rtcnc_motion::{
    AXES, Axis, AxisLimits, Feed, MachineLimits, MotionError, Move, MoveKind, PathMode, Planner,
    TrivialKinematics,
};

fn pl() -> Planner<TrivialKinematics> {
    let mut lim = limits(100.0, 1000.0, 50_000.0);
    for a in [Axis::X, Axis::Y, Axis::Z] {
        let l = lim.axes[a as usize].as_mut().unwrap();
        l.min_position = -50.0;
        l.max_position = 50.0;
    }
    planner(&lim, p3(0.0, 0.0, 0.0), 64)
}

#[test]
fn bad_machine_limits_are_refused_with_their_name() {
    for (v, a, j) in [
        (0.0, 1000.0, 1e4),
        (100.0, -1.0, 1e4),
        (100.0, 1000.0, f64::NAN),
        (f64::INFINITY, 1.0, 1.0),
    ] {
        let lim = MachineLimits::uniform(&[Axis::X], AxisLimits::new(v, a, j, -1.0, 1.0));
        let e = Planner::new(
            &lim,
            TrivialKinematics::identity(&[Axis::X]),
            1e-3,
            64,
            [0.0; AXES],
        )
        .err()
        .unwrap();
        assert_eq!(e.code(), "MOTION-001");
        assert!(e.to_string().contains("axis X"), "{e}");
    }
    let lim = limits(100.0, 1000.0, 5e4);
    for period in [0.0, -1e-3, f64::NAN] {
        assert!(
            Planner::new(
                &lim,
                TrivialKinematics::identity(&[Axis::X]),
                period,
                64,
                [0.0; AXES]
            )
            .is_err()
        );
    }
}

#[test]
fn nan_coordinates_and_feeds_are_refused() {
    let mut p = pl();
    let e = p
        .push(&Move::line(p3(f64::NAN, 0.0, 0.0), 10.0, blend(0.01), 7))
        .unwrap_err();
    assert_eq!((e.code(), e.line()), ("MOTION-002", Some(7)));
    let e = p
        .push(&Move::line(p3(1.0, 0.0, 0.0), f64::NAN, blend(0.01), 8))
        .unwrap_err();
    assert_eq!(e.line(), Some(8));
    let e = p
        .push(&Move::line(p3(1.0, 0.0, 0.0), 0.0, blend(0.01), 9))
        .unwrap_err();
    assert_eq!((e.code(), e.line()), ("MOTION-004", Some(9)));
    let e = p
        .push(&Move::line(p3(1.0, 0.0, 0.0), -5.0, blend(0.01), 10))
        .unwrap_err();
    assert_eq!(e.code(), "MOTION-004");
    let bad_tol = PathMode::Blend {
        tolerance: -0.1,
        merge_tolerance: 0.0,
    };
    assert_eq!(
        p.push(&Move::line(p3(1.0, 0.0, 0.0), 5.0, bad_tol, 11))
            .unwrap_err()
            .code(),
        "MOTION-007"
    );
}

#[test]
fn zero_length_move_is_refused() {
    let mut p = pl();
    let e = p
        .push(&Move::line(p3(0.0, 0.0, 0.0), 10.0, blend(0.01), 3))
        .unwrap_err();
    assert_eq!(e, MotionError::ZeroLength { line: 3 });
}

#[test]
fn arc_with_mismatched_radius_is_refused() {
    let mut p = pl();
    // Start (0,0) around (5,0): radius 5; end (10.01, 0): radius 5.01.
    let mv = Move::arc(
        p3(10.01, 0.0, 0.0),
        [5.0, 0.0, 0.0],
        [0.0, 0.0, 1.0],
        0,
        10.0,
        blend(0.01),
        12,
    );
    let e = p.push(&mv).unwrap_err();
    assert_eq!((e.code(), e.line()), ("MOTION-005", Some(12)));
    let zero_normal = Move::arc(
        p3(10.0, 0.0, 0.0),
        [5.0, 0.0, 0.0],
        [0.0, 0.0, 0.0],
        0,
        10.0,
        blend(0.01),
        13,
    );
    assert_eq!(p.push(&zero_normal).unwrap_err().code(), "MOTION-006");
}

#[test]
fn soft_limit_refuses_a_line_end_outside_the_envelope() {
    let mut p = pl();
    let e = p
        .push(&Move::line(p3(60.0, 0.0, 0.0), 10.0, blend(0.01), 21))
        .unwrap_err();
    match e {
        MotionError::SoftLimit { line, axis, .. } => assert_eq!((line, axis), (21, 'X')),
        other => panic!("{other:?}"),
    }
}

#[test]
fn soft_limit_refuses_an_arc_whose_extent_leaves_the_envelope() {
    // Both end points inside (x = 40 and x = 40) but the half circle through y = 0 bulges to
    // x = 40 + 15 = 55 > 50.
    let mut p = pl();
    p.push(&Move::line(
        p3(40.0, 15.0, 0.0),
        50.0,
        PathMode::ExactStop,
        1,
    ))
    .unwrap();
    let arc = Move::arc(
        p3(40.0, -15.0, 0.0),
        [40.0, 0.0, 0.0],
        [0.0, 0.0, -1.0],
        0,
        10.0,
        PathMode::ExactStop,
        2,
    );
    let e = p.push(&arc).unwrap_err();
    match e {
        MotionError::SoftLimit {
            line,
            axis,
            position,
            ..
        } => {
            assert_eq!((line, axis), (2, 'X'));
            assert!((position - 55.0).abs() < 1e-9);
        }
        other => panic!("{other:?}"),
    }
    // The same half circle the other way round stays inside.
    let arc_ok = Move::arc(
        p3(40.0, -15.0, 0.0),
        [40.0, 0.0, 0.0],
        [0.0, 0.0, 1.0],
        0,
        10.0,
        PathMode::ExactStop,
        3,
    );
    p.push(&arc_ok).unwrap();
}

#[test]
fn moving_an_axis_the_machine_lacks_is_refused() {
    let mut p = pl();
    let mut end = p3(1.0, 0.0, 0.0);
    end[Axis::B as usize] = 10.0;
    assert_eq!(
        p.push(&Move::line(end, 10.0, blend(0.01), 4))
            .unwrap_err()
            .code(),
        "MOTION-008"
    );
}

#[test]
fn inverse_time_and_per_revolution_feeds_resolve_to_path_speed() {
    let mut p = pl();
    // 10 mm in 0.5 s (G93) = 20 mm/s; 0.1 mm/rev at 5 rev/s (G95) = 0.5 mm/s.
    let m1 = Move {
        kind: MoveKind::Line {
            end: p3(10.0, 0.0, 0.0),
            rapid: false,
        },
        feed: Feed::InverseTime { seconds: 0.5 },
        mode: PathMode::ExactStop,
        line: 1,
    };
    let tr = run(&mut p, &[m1], 10_000);
    let peak = tr.speed.iter().cloned().fold(0.0, f64::max);
    assert!((peak - 20.0).abs() < 2e-3, "{peak}");
    let m2 = Move {
        kind: MoveKind::Line {
            end: p3(10.0, 1.0, 0.0),
            rapid: false,
        },
        feed: Feed::PerRevolution {
            mm_per_rev: 0.1,
            spindle_rev_per_s: 5.0,
        },
        mode: PathMode::ExactStop,
        line: 2,
    };
    let tr = run(&mut p, &[m2], 20_000);
    let peak = tr.speed.iter().cloned().fold(0.0, f64::max);
    assert!((peak - 0.5).abs() < 5e-5, "{peak}");
}

#[test]
fn queue_full_is_an_error_not_a_panic() {
    let mut p = pl();
    let mut n = 0;
    let err = loop {
        n += 1;
        let x = if n % 2 == 0 { 0.0 } else { 1.0 };
        match p.push(&Move::line(
            p3(x, n as f64 * 0.01, 0.0),
            10.0,
            blend(0.01),
            n,
        )) {
            Ok(()) => assert!(n < 10_000),
            Err(e) => break e,
        }
    };
    assert_eq!(err, MotionError::QueueFull);
}
