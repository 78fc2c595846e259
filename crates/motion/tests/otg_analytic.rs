//! Closed-form cases worked out by hand, and the behaviour on bad input.

use rtcnc_motion::otg::{
    Limits, OnlineAxis, OnlineGroup, State, along_path, position_profile,
    position_profile_with_duration, velocity_profile,
};

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * b.abs().max(1e-300)
}

/// Neither the velocity nor the acceleration limit is reached: four jerk phases of equal
/// length T1 with L = 2 j T1³, so T = 4 (L / 2j)^(1/3).
#[test]
fn pure_jerk_rest_to_rest() {
    let (l, j) = (2.0, 1.0);
    let limits = Limits::symmetric(100.0, 100.0, j);
    let profile = position_profile(State::at_rest(0.0), State::at_rest(l), &limits).unwrap();
    assert!(close(
        profile.duration(),
        4.0 * (l / (2.0 * j)).cbrt(),
        1e-12
    ));
    assert!(close(profile.duration(), 4.0, 1e-12));
    // Peak acceleration j T1 = 1, peak velocity j T1² = 1 at the middle.
    let mid = profile.at(2.0);
    assert!(close(mid.v, 1.0, 1e-12));
    assert!(mid.a.abs() < 1e-12);
    assert!(close(profile.at(1.0).a, 1.0, 1e-12));
}

/// The acceleration limit is reached, the velocity limit is not: peak velocity
/// v = a/2 (-a/j + sqrt((a/j)² + 4L/a)), T = 2 (v/a + a/j).
#[test]
fn acceleration_limited_rest_to_rest() {
    let (l, v_max, a, j) = (10.0, 100.0, 2.0, 4.0);
    let limits = Limits::symmetric(v_max, a, j);
    let profile = position_profile(State::at_rest(0.0), State::at_rest(l), &limits).unwrap();
    let v = 0.5 * a * (-a / j + ((a / j).powi(2) + 4.0 * l / a).sqrt());
    assert!(close(profile.duration(), 2.0 * (v / a + a / j), 1e-12));
    let (v_peak, a_peak, j_peak) = profile.peaks();
    assert!(close(v_peak, v, 1e-12));
    assert!(close(a_peak, a, 1e-12));
    assert_eq!(j_peak, j);
}

/// Both limits are reached: T = v/a + a/j + L/v, seven phases (the full S-curve).
#[test]
fn full_s_curve_rest_to_rest() {
    let (l, v, a, j) = (100.0, 5.0, 2.0, 4.0);
    let limits = Limits::symmetric(v, a, j);
    let profile = position_profile(State::at_rest(0.0), State::at_rest(-l), &limits).unwrap();
    assert!(close(profile.duration(), v / a + a / j + l / v, 1e-12));
    assert_eq!(profile.phase_count(), 7);
    let jerks: Vec<f64> = profile.phases().map(|p| p.jerk).collect();
    assert_eq!(jerks, [-j, 0.0, j, 0.0, j, 0.0, -j]);
}

/// Velocity interface from rest: with the acceleration limit reached T = v/a + a/j, without
/// it T = 2 sqrt(v/j).
#[test]
fn velocity_interface_from_rest() {
    let limits = Limits::symmetric(10.0, 2.0, 4.0);
    let profile = velocity_profile(State::at_rest(0.0), 5.0, 0.0, &limits).unwrap();
    assert!(close(profile.duration(), 5.0 / 2.0 + 2.0 / 4.0, 1e-12));
    let profile = velocity_profile(State::at_rest(0.0), 0.5, 0.0, &limits).unwrap();
    assert!(close(
        profile.duration(),
        2.0 * (0.5f64 / 4.0).sqrt(),
        1e-12
    ));
    // The position travelled to reach v from rest symmetrically is v T / 2.
    assert!(close(
        profile.end().p,
        0.5 * profile.duration() / 2.0,
        1e-12
    ));
}

/// A quick stop from cruise speed with a start acceleration above the limit: first the
/// acceleration is brought back to the limit with the full jerk, then the stop.
#[test]
fn quick_stop_brings_acceleration_back_first() {
    let limits = Limits::symmetric(10.0, 2.0, 4.0);
    let profile = velocity_profile(State::new(0.0, 3.0, 3.0), 0.0, 0.0, &limits).unwrap();
    assert!(close(profile.brake_duration(), (3.0 - 2.0) / 4.0, 1e-12));
    let end = profile.at(profile.duration());
    assert_eq!((end.v, end.a), (0.0, 0.0));
    let (_, a_peak, _) = profile.peaks();
    assert!(a_peak <= 3.0);
}

#[test]
fn moving_back_takes_as_long_as_moving_forward() {
    let limits = Limits::symmetric(3.0, 7.0, 50.0);
    let forward = position_profile(State::at_rest(1.0), State::at_rest(4.5), &limits).unwrap();
    let back = position_profile(State::at_rest(4.5), State::at_rest(1.0), &limits).unwrap();
    assert!(close(forward.duration(), back.duration(), 1e-14));
}

#[test]
fn already_at_target_is_a_zero_duration_profile() {
    let limits = Limits::symmetric(3.0, 7.0, 50.0);
    let profile = position_profile(State::at_rest(2.0), State::at_rest(2.0), &limits).unwrap();
    assert_eq!(profile.duration(), 0.0);
    assert_eq!(profile.at(1.0).p, 2.0);
}

/// A profile of a longer prescribed duration from rest to rest: the cruise velocity v solves
/// L = v (T - v/a - a/j) when the acceleration limit is reached on the way.
#[test]
fn prescribed_duration_rest_to_rest() {
    let (l, a, j, t) = (100.0, 2.0, 4.0, 80.0);
    let limits = Limits::symmetric(100.0, a, j);
    let profile =
        position_profile_with_duration(State::at_rest(0.0), State::at_rest(l), &limits, t).unwrap();
    assert!(close(profile.duration(), t, 1e-12));
    // v² / a - v (T - a/j) + L = 0, smaller root (v = 1.27 > a²/j: the limit is reached).
    let b = t - a / j;
    let v = (b - (b * b - 4.0 * l / a).sqrt()) / (2.0 / a);
    let (v_peak, _, _) = profile.peaks();
    assert!(close(v_peak, v, 1e-9), "{v_peak} vs {v}");
    assert!(close(profile.at(t).p, l, 1e-12));
}

#[test]
fn along_path_reaches_length_and_speed() {
    let limits = Limits::symmetric(100.0, 1000.0, 50_000.0);
    let profile = along_path(5.0, 20.0, 0.0, 60.0, &limits).unwrap();
    let end = profile.at(profile.duration());
    assert_eq!((end.p, end.v, end.a), (5.0, 60.0, 0.0));
    let (lo, hi) = profile.position_extrema();
    assert!(lo >= 0.0 && hi <= 5.0 + 1e-12);
}

/// The seeds' experiment driven on line at a 1 ms servo period, with the target moved back
/// to 3000 pulses mid-move: the motion turns round within the limits and stops exactly there.
#[test]
fn online_target_change_mid_move() {
    let limits = Limits::symmetric(50.0, 1.0, 0.01);
    let mut axis = OnlineAxis::new(State::at_rest(0.0), limits).unwrap();
    axis.set_target(State::at_rest(6000.0)).unwrap();
    let mut last = axis.sample();
    for k in 1..=400_000 {
        if k == 150 {
            axis.set_target(State::at_rest(3000.0)).unwrap();
        }
        let s = axis.step(1.0);
        assert!(s.v.abs() <= 50.0 * (1.0 + 1e-9) && s.a.abs() <= 1.0 * (1.0 + 1e-9));
        assert!(s.j.abs() <= 0.01 * (1.0 + 1e-9));
        // Finite differences agree with the jerk limit too.
        assert!((s.a - last.a).abs() <= 0.01 * (1.0 + 1e-9));
        last = s;
        if axis.is_finished() {
            break;
        }
    }
    assert!(axis.is_finished());
    let end = axis.sample();
    assert_eq!((end.p, end.v, end.a), (3000.0, 0.0, 0.0));
}

/// Pure-jerk rest to rest over L = 2 (j = 1): T1 = 1, the middle at t = 2 is p = L/2. A
/// clock put back gives the same set-points again; a bad time leaves the clock.
#[test]
fn online_clock_put_back_replays_the_same_set_points() {
    let limits = Limits::symmetric(100.0, 100.0, 1.0);
    let mut axis = OnlineAxis::new(State::at_rest(0.0), limits).unwrap();
    axis.set_target(State::at_rest(2.0)).unwrap();
    let head: Vec<_> = (0..10).map(|_| axis.step(0.1)).collect();
    let mark = axis.time();
    let tail: Vec<_> = (0..20).map(|_| axis.step(0.1)).collect();
    assert!(close(tail[9].p, 1.0, 1e-12));
    assert!(close(head[9].v, 0.5, 1e-12));
    let at = axis.time();
    assert!(close(at, 3.0, 1e-12));
    axis.set_time(mark);
    let again: Vec<_> = (0..20).map(|_| axis.step(0.1)).collect();
    assert_eq!(again, tail);
    for bad in [f64::NAN, -1.0, f64::INFINITY] {
        axis.set_time(bad);
        assert_eq!(axis.time(), at);
    }
}

#[test]
fn bad_input_is_an_error_value_with_a_code() {
    let good = Limits::symmetric(1.0, 1.0, 1.0);
    let rest = State::at_rest(0.0);
    let cases: Vec<(Limits, State, State, &str)> = vec![
        (
            Limits {
                max_jerk: 0.0,
                ..good
            },
            rest,
            State::at_rest(1.0),
            "otg-invalid-limit",
        ),
        (
            Limits {
                max_velocity: -1.0,
                ..good
            },
            rest,
            State::at_rest(1.0),
            "otg-invalid-limit",
        ),
        (
            Limits {
                min_acceleration: 0.5,
                ..good
            },
            rest,
            State::at_rest(1.0),
            "otg-invalid-limit",
        ),
        (
            Limits {
                max_acceleration: f64::NAN,
                ..good
            },
            rest,
            State::at_rest(1.0),
            "otg-invalid-limit",
        ),
        (
            Limits {
                max_velocity: f64::INFINITY,
                ..good
            },
            rest,
            State::at_rest(1.0),
            "otg-invalid-limit",
        ),
        (
            good,
            State::new(f64::NAN, 0.0, 0.0),
            State::at_rest(1.0),
            "otg-non-finite-input",
        ),
        (
            good,
            rest,
            State::new(f64::INFINITY, 0.0, 0.0),
            "otg-non-finite-input",
        ),
        (
            good,
            rest,
            State::new(1.0, 2.0, 0.0),
            "otg-target-velocity-out-of-limits",
        ),
        (
            good,
            rest,
            State::new(1.0, 0.0, -2.0),
            "otg-target-acceleration-out-of-limits",
        ),
        // Arriving at full speed while decelerating at 1 means the speed was 1.5 before.
        (
            good,
            rest,
            State::new(1.0, 1.0, -1.0),
            "otg-target-state-unreachable",
        ),
    ];
    for (limits, start, target, code) in cases {
        let error = position_profile(start, target, &limits).unwrap_err();
        assert_eq!(error.code(), code, "{error}");
        assert!(!error.to_string().is_empty());
    }
    let error = velocity_profile(rest, f64::NAN, 0.0, &good).unwrap_err();
    assert_eq!(error.code(), "otg-non-finite-input");
    let error = position_profile_with_duration(rest, State::at_rest(1.0), &good, 0.5).unwrap_err();
    assert_eq!(error.code(), "otg-duration-too-short");
}

#[test]
fn evaluation_never_returns_nan() {
    let limits = Limits::symmetric(2.0, 3.0, 5.0);
    let profile =
        position_profile(State::new(0.0, 1.0, 0.5), State::at_rest(3.0), &limits).unwrap();
    for t in [
        f64::NAN,
        f64::NEG_INFINITY,
        -1.0,
        0.0,
        1.0,
        1e300,
        f64::INFINITY,
    ] {
        let s = profile.at(t);
        assert!(
            s.p.is_finite() && s.v.is_finite() && s.a.is_finite() && s.j.is_finite(),
            "t = {t}"
        );
    }
}

/// Three axes driven on line on a 1 ms servo period (mm, s): a target change mid-move, and
/// with period rounding the move ends exactly on a tick with every axis on its target.
#[test]
fn online_group_retargets_and_ends_on_a_tick() {
    let limits = [
        Limits::symmetric(100.0, 1000.0, 50_000.0),
        Limits::symmetric(80.0, 800.0, 40_000.0),
        Limits::symmetric(50.0, 500.0, 20_000.0),
    ];
    let mut group = OnlineGroup::new([State::at_rest(0.0); 3], limits).unwrap();
    group.set_period(Some(1e-3)).unwrap();
    group
        .set_targets(&[
            State::at_rest(10.0),
            State::at_rest(-5.0),
            State::at_rest(2.0),
        ])
        .unwrap();
    let targets = [
        State::at_rest(3.0),
        State::at_rest(4.0),
        State::at_rest(-1.0),
    ];
    let mut ticks_after_change = 0;
    for tick in 1..=10_000 {
        if tick == 40 {
            group.set_targets(&targets).unwrap();
            let ticks = group.duration() / 1e-3;
            assert!(
                (ticks - ticks.round()).abs() < 1e-6,
                "duration {} is not on a tick",
                group.duration()
            );
        }
        let samples = group.step(1e-3);
        for (s, l) in samples.iter().zip(&limits) {
            assert!(s.v.abs() <= l.max_velocity * (1.0 + 1e-9));
            assert!(s.a.abs() <= l.max_acceleration * (1.0 + 1e-9));
        }
        if tick >= 40 {
            ticks_after_change += 1;
        }
        if tick > 40 && group.is_finished() {
            break;
        }
    }
    assert!(group.is_finished());
    // Finished on the very tick the planned duration ends on.
    assert!((f64::from(ticks_after_change) * 1e-3 - group.duration()).abs() < 1e-9);
    for (s, t) in group.sample().iter().zip(&targets) {
        assert_eq!((s.p, s.v, s.a), (t.p, 0.0, 0.0));
    }
    assert_eq!(
        group.set_period(Some(0.0)).unwrap_err().code(),
        "otg-invalid-limit"
    );
}

/// An on-line axis created in motion does not keep accelerating on its own: it stops as
/// fast as its limits allow (from 3 with acceleration 0: T = 2 sqrt(v/j) with v j < a²).
#[test]
fn online_axis_created_in_motion_comes_to_rest() {
    let limits = Limits::symmetric(10.0, 20.0, 100.0);
    let mut axis = OnlineAxis::new(State::new(1.0, 3.0, 0.0), limits).unwrap();
    let (profile, _) = axis.profile();
    assert!((profile.duration() - 2.0 * (3.0f64 / 100.0).sqrt()).abs() < 1e-12);
    for _ in 0..1000 {
        axis.step(1e-3);
    }
    let s = axis.sample();
    assert_eq!((s.v, s.a), (0.0, 0.0));
    let group = OnlineGroup::new(
        [State::new(0.0, 3.0, 0.0), State::at_rest(2.0)],
        [limits; 2],
    )
    .unwrap();
    assert!((group.duration() - 2.0 * (3.0f64 / 100.0).sqrt()).abs() < 1e-12);
}
