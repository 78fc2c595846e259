//! Position loops in cyclic synchronous position mode, and the servo configuration's checks.

use rtcnc_servo::{
    CspCommand, CspConfig, CspLoop, FollowingErrorLimits, PidConfig, PidController, ServoFault,
    SetPoint, SetPointDifferentiator,
};

const LIMITS: FollowingErrorLimits = FollowingErrorLimits {
    min_ferror: 0.01,
    ferror: 0.1,
    max_velocity: 100.0,
};

#[test]
fn csp_loop_passes_the_set_point_with_feed_forward_offsets() {
    let config = CspConfig {
        velocity_ff: 0.5,
        torque_ff: 2e-4,
        following_error: LIMITS,
        feedback_delay_periods: 0,
    };
    let mut csp = CspLoop::new(3, &config).unwrap();
    let sp = SetPoint {
        position: 12.5,
        velocity: 40.0,
        acceleration: 500.0,
    };
    let command = csp.update(sp, 12.49, 0.001).unwrap();
    assert_eq!(
        command,
        CspCommand {
            position: 12.5,
            velocity_offset: 20.0,
            torque_offset: 0.1
        }
    );
}

#[test]
fn csp_loop_checks_following_error_and_names_its_joint() {
    let config = CspConfig {
        velocity_ff: 1.0,
        torque_ff: 0.0,
        following_error: LIMITS,
        feedback_delay_periods: 0,
    };
    let mut csp = CspLoop::new(7, &config).unwrap();
    // At 50 units/s the limit is 0.05.
    let sp = SetPoint {
        position: 1.0,
        velocity: 50.0,
        acceleration: 0.0,
    };
    assert!(csp.update(sp, 0.951, 0.001).is_ok());
    let fault = csp.update(sp, 0.9, 0.001).unwrap_err();
    assert_eq!(fault.joint(), 7);
    assert_eq!(fault.code(), "servo.following_error");
    assert!(
        fault
            .to_string()
            .starts_with("joint 7: following error 0.1")
    );
    assert_eq!(
        csp.update(SetPoint::at_rest(f64::NAN), 0.0, 0.001),
        Err(ServoFault::NonFiniteInput {
            joint: 7,
            input: "set-point"
        })
    );
}

#[test]
fn configuration_reads_from_toml_with_default_gains() {
    let config: PidConfig = toml::from_str(
        "[gains]\np = 120.0\noutput_limit = 150.0\n\
         [following_error]\nmin_ferror = 0.01\nferror = 0.1\nmax_velocity = 100.0\n",
    )
    .unwrap();
    assert_eq!(config.gains.p, 120.0);
    assert_eq!(config.gains.output_limit, Some(150.0));
    assert_eq!(config.gains.velocity_ff, 1.0);
    assert!(PidController::new(0, &config).is_ok());
}

#[test]
fn unknown_keys_are_refused() {
    let result: Result<PidConfig, _> = toml::from_str(
        "[gains]\nkp = 1.0\n[following_error]\nmin_ferror = 0.01\nferror = 0.1\nmax_velocity = 1.0\n",
    );
    assert!(
        result
            .unwrap_err()
            .to_string()
            .contains("unknown field `kp`")
    );
}

#[test]
fn validation_names_the_refused_field_and_the_reason() {
    let mut config: PidConfig = toml::from_str(
        "[following_error]\nmin_ferror = 0.01\nferror = 0.1\nmax_velocity = 100.0\n",
    )
    .unwrap();
    config.gains.p = -1.0;
    let error = PidController::new(0, &config).unwrap_err();
    assert_eq!(error.field, "gains.p");
    assert_eq!(error.to_string(), "gains.p: must not be negative");
    config.gains.p = 1.0;
    config.following_error.ferror = 0.001;
    let error = config.validate().unwrap_err().within("joints[2].servo");
    assert_eq!(error.field, "joints[2].servo.following_error.ferror");
    assert_eq!(error.reason, "must not be smaller than min_ferror");
    config.following_error.ferror = 0.1;
    config.gains.acceleration_ff = f64::NAN;
    assert_eq!(
        config.validate().unwrap_err().field,
        "gains.acceleration_ff"
    );
}

#[test]
fn csp_validation_refuses_feed_forward_outside_zero_to_one() {
    let config = CspConfig {
        velocity_ff: 1.5,
        torque_ff: 0.0,
        following_error: LIMITS,
        feedback_delay_periods: 0,
    };
    assert_eq!(CspLoop::new(0, &config).unwrap_err().field, "velocity_ff");
}

#[test]
fn differentiator_gives_backward_differences_of_a_parabola() {
    // x = a·t²/2 sampled at kT: v[k] = a·(k - 1/2)·T, acceleration a from the third sample on.
    let (a, t) = (300.0, 0.001);
    let mut diff = SetPointDifferentiator::new();
    let first = diff.next(0.0, t);
    assert_eq!((first.velocity, first.acceleration), (0.0, 0.0));
    for k in 1..50 {
        let time = k as f64 * t;
        let sp = diff.next(0.5 * a * time * time, t);
        assert!(
            (sp.velocity - a * (k as f64 - 0.5) * t).abs() < 1e-9,
            "k {k}"
        );
        if k >= 2 {
            assert!(
                (sp.acceleration - a).abs() < 1e-6,
                "k {k}: {}",
                sp.acceleration
            );
        }
    }
}

#[test]
fn servo_loop_is_chosen_by_the_configuration() {
    use rtcnc_servo::{ServoCommand, ServoLoop, ServoLoopConfig};
    let limits = "[following_error]\nmin_ferror = 0.01\nferror = 0.1\nmax_velocity = 100.0\n";
    let pid: ServoLoopConfig = toml::from_str(&format!("loop = \"pid\"\n{limits}")).unwrap();
    let csp: ServoLoopConfig =
        toml::from_str(&format!("loop = \"csp\"\ntorque_ff = 0.5\n{limits}")).unwrap();
    let sp = SetPoint {
        position: 1.0,
        velocity: 2.0,
        acceleration: 4.0,
    };
    let mut pid = ServoLoop::new(0, &pid).unwrap();
    // Default gains: p·e + velocity_ff·v + acceleration_ff·a = 200·0.001 + 2 + 0.0005·4.
    match pid.update(sp, 0.999, 0.001).unwrap() {
        ServoCommand::Velocity(v) => assert!((v - (0.2 + 2.0 + 0.002)).abs() < 1e-9, "{v}"),
        other => panic!("{other:?}"),
    }
    let mut csp = ServoLoop::new(1, &csp).unwrap();
    assert_eq!(
        csp.update(sp, 0.999, 0.001).unwrap(),
        ServoCommand::Position(CspCommand {
            position: 1.0,
            velocity_offset: 2.0,
            torque_offset: 2.0
        })
    );
    assert_eq!(csp.following_error().joint(), 1);
    let unknown = toml::from_str::<ServoLoopConfig>(&format!("loop = \"pid\"\nfoo = 1\n{limits}"));
    assert!(unknown.is_err());
    let bad = toml::from_str::<ServoLoopConfig>(&format!("loop = \"pd\"\n{limits}"));
    assert!(
        bad.unwrap_err()
            .to_string()
            .contains("unknown variant `pd`")
    );
}

/// A drive that reports one period later the position it was sent, as the simulated CSP
/// drives and most EtherCAT drives do, from standstill at 0 to 100 units/s in one step with
/// 4 ms periods: each period's set-point is 0.4 ahead of the feedback of that period.
fn one_period_lag_at_4_ms(delay: u8) -> Result<(), ServoFault> {
    let config = CspConfig {
        velocity_ff: 1.0,
        torque_ff: 0.0,
        following_error: FollowingErrorLimits {
            min_ferror: 0.05,
            ferror: 0.2,
            max_velocity: 100.0,
        },
        feedback_delay_periods: delay,
    };
    let mut csp = CspLoop::new(0, &config).unwrap();
    let (period, speed) = (0.004, 100.0);
    let mut at_the_drive = 0.0;
    for k in 0..=50 {
        let sp = SetPoint {
            position: speed * period * f64::from(k),
            velocity: speed,
            acceleration: 0.0,
        };
        csp.update(sp, at_the_drive, period)?;
        at_the_drive = sp.position;
    }
    Ok(())
}

#[test]
fn csp_following_error_compares_with_the_set_point_the_feedback_shows() {
    // Compared with the latest set-point, the transport delay alone is 0.4 against a limit
    // of 0.2 at 100 units/s.
    let fault = one_period_lag_at_4_ms(0).unwrap_err();
    assert_eq!(fault.code(), "servo.following_error");
    assert!(fault.to_string().contains("following error 0.4"), "{fault}");
    // Compared with the set-point sent one period before, a drive that follows exactly has
    // no following error.
    assert!(one_period_lag_at_4_ms(1).is_ok());
}

#[test]
fn csp_after_a_reset_compares_with_the_oldest_set_point_it_has() {
    let config = CspConfig {
        velocity_ff: 1.0,
        torque_ff: 0.0,
        following_error: LIMITS,
        feedback_delay_periods: 2,
    };
    let mut csp = CspLoop::new(0, &config).unwrap();
    let sp = |position: f64| SetPoint {
        position,
        velocity: 0.0,
        acceleration: 0.0,
    };
    csp.update(sp(1.0), 0.0, 0.001).unwrap_err();
    csp.reset();
    // First period after the reset: only this set-point is known (error 5 - 5 = 0).
    csp.update(sp(5.0), 5.0, 0.001).unwrap();
    csp.update(sp(5.005), 5.0, 0.001).unwrap();
    // From the third period on, two periods back: 5.0, then 5.005, which a feedback of
    // 5.025 is 0.02 past (limit 0.01).
    csp.update(sp(5.01), 5.0, 0.001).unwrap();
    let fault = csp.update(sp(5.015), 5.025, 0.001).unwrap_err();
    assert!(
        fault.to_string().contains("following error -0.02"),
        "{fault}"
    );
}

#[test]
fn csp_validation_refuses_a_feedback_delay_beyond_eight_periods() {
    let config = CspConfig {
        velocity_ff: 1.0,
        torque_ff: 0.0,
        following_error: LIMITS,
        feedback_delay_periods: 9,
    };
    assert_eq!(
        CspLoop::new(0, &config).unwrap_err().field,
        "feedback_delay_periods"
    );
}
