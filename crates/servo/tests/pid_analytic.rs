//! The position loop against closed-form discrete-time references: the plant is an ideal
//! integrator (the drive's velocity equals the command, held for one period), so
//! x[k+1] = x[k] + T·u[k] and every error sequence below has an exact formula.

use rtcnc_servo::{FollowingErrorLimits, PidConfig, PidController, PidGains, ServoFault, SetPoint};

const T: f64 = 0.001;

fn wide_limits() -> FollowingErrorLimits {
    FollowingErrorLimits {
        min_ferror: 1e3,
        ferror: 1e3,
        max_velocity: 100.0,
    }
}

fn controller(gains: PidGains, limits: FollowingErrorLimits) -> PidController {
    PidController::new(
        0,
        &PidConfig {
            gains,
            following_error: limits,
        },
    )
    .expect("valid config")
}

fn p_only(p: f64) -> PidGains {
    PidGains {
        p,
        velocity_ff: 0.0,
        acceleration_ff: 0.0,
        ..PidGains::default()
    }
}

#[test]
fn p_only_loop_on_integrator_decays_as_one_minus_kp_t_to_the_k() {
    let kp = 150.0;
    let mut pid = controller(p_only(kp), wide_limits());
    let target = 1.0;
    let mut x = 0.0;
    let r: f64 = 1.0 - kp * T;
    for k in 0..200 {
        let expected_error = target * r.powi(k);
        assert!(
            ((target - x) - expected_error).abs() < 1e-12,
            "cycle {k}: error {} expected {expected_error}",
            target - x
        );
        let u = pid.update(SetPoint::at_rest(target), x, T).unwrap();
        x += T * u;
    }
}

#[test]
fn velocity_feed_forward_gives_zero_following_error_on_a_ramp() {
    let v = 37.5;
    let mut pid = controller(
        PidGains {
            p: 80.0,
            ..PidGains::default()
        },
        wide_limits(),
    );
    let mut x = 0.0;
    for k in 0..500 {
        let t = k as f64 * T;
        let sp = SetPoint {
            position: v * t,
            velocity: v,
            acceleration: 0.0,
        };
        assert!(
            (sp.position - x).abs() < 1e-12,
            "cycle {k}: error {}",
            sp.position - x
        );
        let u = pid.update(sp, x, T).unwrap();
        x += T * u;
    }
}

#[test]
fn half_period_acceleration_feed_forward_makes_up_the_held_command_on_a_parabola() {
    // A held velocity v(kT) + a·T/2 covers exactly the parabola's distance over one period.
    let a = 400.0;
    let gains = PidGains {
        p: 80.0,
        velocity_ff: 1.0,
        acceleration_ff: T / 2.0,
        ..Default::default()
    };
    let mut pid = controller(gains, wide_limits());
    let mut x = 0.0;
    for k in 0..300 {
        let t = k as f64 * T;
        let sp = SetPoint {
            position: 0.5 * a * t * t,
            velocity: a * t,
            acceleration: a,
        };
        assert!(
            (sp.position - x).abs() < 1e-11,
            "cycle {k}: error {}",
            sp.position - x
        );
        let u = pid.update(sp, x, T).unwrap();
        x += T * u;
    }
}

#[test]
fn integrator_is_clamped_at_its_limit() {
    let limit = 0.0375;
    let gains = PidGains {
        p: 2.0,
        i: 10.0,
        velocity_ff: 0.0,
        acceleration_ff: 0.0,
        integrator_limit: Some(limit),
        ..Default::default()
    };
    let mut pid = controller(gains, wide_limits());
    let error = 0.5; // the plant does not move: constant error
    for k in 1..=200 {
        let out = pid.update(SetPoint::at_rest(error), 0.0, T).unwrap();
        let expected_integral = (k as f64 * error * T).min(limit);
        assert!(
            (pid.integral() - expected_integral).abs() < 1e-12,
            "cycle {k}"
        );
        assert!(
            (out - (2.0 * error + 10.0 * expected_integral)).abs() < 1e-12,
            "cycle {k}"
        );
    }
}

#[test]
fn integrator_stops_while_the_output_is_saturated_and_unwinds_at_once() {
    let gains = PidGains {
        p: 0.0,
        i: 1.0,
        velocity_ff: 0.0,
        acceleration_ff: 0.0,
        output_limit: Some(0.5),
        ..Default::default()
    };
    let mut pid = controller(gains, wide_limits());
    let t = 1.0 / 1024.0; // a binary fraction, so the integral sums without rounding
    // Error 1: the integral reaches 0.5 after 512 cycles, then the output saturates.
    for _ in 0..2000 {
        let out = pid.update(SetPoint::at_rest(1.0), 0.0, t).unwrap();
        assert!(out <= 0.5);
    }
    assert_eq!(pid.integral(), 0.5);
    // The error reverses: without anti-windup the output would stay at the limit for
    // another 1488 cycles; with it the output leaves the limit on the first cycle.
    let out = pid.update(SetPoint::at_rest(-1.0), 0.0, t).unwrap();
    assert_eq!(out, 0.5 - t);
}

#[test]
fn output_is_limited_both_ways() {
    let gains = PidGains {
        p: 1000.0,
        output_limit: Some(20.0),
        ..Default::default()
    };
    let mut pid = controller(gains, wide_limits());
    assert_eq!(pid.update(SetPoint::at_rest(1.0), 0.0, T).unwrap(), 20.0);
    assert_eq!(pid.update(SetPoint::at_rest(-1.0), 0.0, T).unwrap(), -20.0);
}

#[test]
fn deadband_zeroes_small_errors_and_shifts_large_ones() {
    let gains = PidGains {
        deadband: 0.001,
        ..p_only(100.0)
    };
    let mut pid = controller(gains, wide_limits());
    assert_eq!(pid.update(SetPoint::at_rest(0.0009), 0.0, T).unwrap(), 0.0);
    assert_eq!(pid.update(SetPoint::at_rest(-0.001), 0.0, T).unwrap(), 0.0);
    let out = pid.update(SetPoint::at_rest(0.004), 0.0, T).unwrap();
    assert!((out - 100.0 * 0.003).abs() < 1e-12);
    let out = pid.update(SetPoint::at_rest(-0.004), 0.0, T).unwrap();
    assert!((out + 100.0 * 0.003).abs() < 1e-12);
}

#[test]
fn p_loop_with_deadband_settles_towards_the_deadband_edge() {
    // e[k] - db = (e[0] - db)·(1 - Kp·T)^k while e stays above the deadband.
    let (kp, db, e0) = (100.0, 0.002, 0.05);
    let mut pid = controller(
        PidGains {
            deadband: db,
            ..p_only(kp)
        },
        wide_limits(),
    );
    let mut x = 0.0;
    let r: f64 = 1.0 - kp * T;
    for k in 0..300 {
        let expected = db + (e0 - db) * r.powi(k);
        assert!(((e0 - x) - expected).abs() < 1e-12, "cycle {k}");
        x += T * pid.update(SetPoint::at_rest(e0), x, T).unwrap();
    }
}

#[test]
fn derivative_acts_on_the_change_of_error() {
    let gains = PidGains {
        d: 0.01,
        ..p_only(0.0)
    };
    let mut pid = controller(gains, wide_limits());
    // First cycle: no history, no derivative.
    assert_eq!(pid.update(SetPoint::at_rest(0.1), 0.0, T).unwrap(), 0.0);
    let out = pid.update(SetPoint::at_rest(0.3), 0.0, T).unwrap();
    assert!((out - 0.01 * 0.2 / T).abs() < 1e-9);
}

#[test]
fn bias_is_added_to_the_output() {
    let mut pid = controller(
        PidGains {
            bias: 0.25,
            ..p_only(10.0)
        },
        wide_limits(),
    );
    let out = pid.update(SetPoint::at_rest(0.1), 0.0, T).unwrap();
    assert!((out - 1.25).abs() < 1e-12);
}

#[test]
fn following_error_faults_at_the_cycle_the_analytic_error_crosses_the_velocity_scaled_limit() {
    // P-only loop, ramp command, no feed-forward: e[k] = (v/Kp)·(1 - r^k), r = 1 - Kp·T.
    let (kp, v) = (20.0, 50.0);
    let limits = FollowingErrorLimits {
        min_ferror: 0.05,
        ferror: 2.0,
        max_velocity: 100.0,
    };
    let limit = 2.0 * v / 100.0; // 1.0: the velocity-scaled limit is in force
    let r: f64 = 1.0 - kp * T;
    let first_k = ((1.0 - limit * kp / v).ln() / r.ln()).floor() as i32 + 1;
    assert_eq!(
        first_k, 26,
        "hand check: 2.5·(1 - 0.98^k) > 1 first at k = 26"
    );
    let mut pid = controller(p_only(kp), limits);
    let mut x = 0.0;
    for k in 0..1000 {
        let sp = SetPoint {
            position: v * k as f64 * T,
            velocity: v,
            acceleration: 0.0,
        };
        match pid.update(sp, x, T) {
            Ok(u) => {
                assert!(k < first_k, "no fault at cycle {k}");
                x += T * u;
            }
            Err(fault) => {
                assert_eq!(k, first_k);
                let ServoFault::FollowingError {
                    joint,
                    error,
                    limit: in_force,
                } = fault
                else {
                    panic!("wrong fault {fault:?}");
                };
                assert_eq!(joint, 0);
                assert!((error - (v / kp) * (1.0 - r.powi(k))).abs() < 1e-9);
                assert_eq!(in_force, limit);
                assert_eq!(fault.code(), "servo.following_error");
                return;
            }
        }
    }
    panic!("no following-error fault");
}

#[test]
fn following_error_at_standstill_uses_the_static_limit() {
    let limits = FollowingErrorLimits {
        min_ferror: 0.01,
        ferror: 1.0,
        max_velocity: 100.0,
    };
    let mut pid = controller(p_only(10.0), limits);
    assert!(
        pid.update(SetPoint::at_rest(0.01), 0.0, T).is_ok(),
        "at the limit is allowed"
    );
    let fault = pid.update(SetPoint::at_rest(0.0), 0.0101, T).unwrap_err();
    assert_eq!(
        fault,
        ServoFault::FollowingError {
            joint: 0,
            error: -0.0101,
            limit: 0.01
        }
    );
    assert_eq!(
        fault.to_string(),
        "joint 0: following error -0.010100 exceeds the limit 0.010000"
    );
}

#[test]
fn following_error_limit_scales_linearly_above_the_static_floor() {
    let limits = FollowingErrorLimits {
        min_ferror: 0.01,
        ferror: 1.0,
        max_velocity: 100.0,
    };
    assert_eq!(limits.limit_at(0.0), 0.01);
    assert_eq!(limits.limit_at(0.5), 0.01);
    assert_eq!(limits.limit_at(-50.0), 0.5);
    assert_eq!(limits.limit_at(100.0), 1.0);
}

#[test]
fn non_finite_inputs_and_bad_periods_are_faults_that_leave_the_state_alone() {
    let mut pid = controller(
        PidGains {
            i: 5.0,
            ..p_only(10.0)
        },
        wide_limits(),
    );
    pid.update(SetPoint::at_rest(0.1), 0.0, T).unwrap();
    let integral = pid.integral();
    let nan_sp = SetPoint {
        position: 0.0,
        velocity: f64::NAN,
        acceleration: 0.0,
    };
    assert_eq!(
        pid.update(nan_sp, 0.0, T),
        Err(ServoFault::NonFiniteInput {
            joint: 0,
            input: "set-point"
        })
    );
    assert_eq!(
        pid.update(SetPoint::at_rest(0.1), f64::INFINITY, T),
        Err(ServoFault::NonFiniteInput {
            joint: 0,
            input: "feedback"
        })
    );
    for period in [0.0, -T, f64::NAN] {
        let fault = pid.update(SetPoint::at_rest(0.1), 0.0, period).unwrap_err();
        assert_eq!(fault.code(), "servo.invalid_period");
    }
    assert_eq!(pid.integral(), integral);
    let out = pid.update(SetPoint::at_rest(0.1), 0.0, T).unwrap();
    assert!(out.is_finite());
}

#[test]
fn overflowing_output_is_a_fault_not_an_infinity() {
    let mut pid = controller(p_only(1e307), wide_limits());
    let fault = pid.update(SetPoint::at_rest(100.0), 0.0, T).unwrap_err();
    assert_eq!(fault, ServoFault::NonFiniteOutput { joint: 0 });
}

#[test]
fn reset_clears_integral_and_derivative_history() {
    let mut pid = controller(
        PidGains {
            i: 5.0,
            d: 0.01,
            ..p_only(0.0)
        },
        wide_limits(),
    );
    pid.update(SetPoint::at_rest(0.1), 0.0, T).unwrap();
    pid.reset();
    assert_eq!(pid.integral(), 0.0);
    // No derivative kick from the old error after a reset.
    let out = pid.update(SetPoint::at_rest(0.0), 0.0, T).unwrap();
    assert_eq!(out, 0.0);
}
