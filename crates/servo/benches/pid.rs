//! Cost of one servo cycle for one joint: PID update (velocity-output loop) and CSP loop.

// criterion_group! and criterion_main! make public functions without docs.
#![allow(missing_docs)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use rtcnc_servo::{
    CspConfig, CspLoop, FollowingErrorLimits, PidConfig, PidController, PidGains, SetPoint,
};

const LIMITS: FollowingErrorLimits = FollowingErrorLimits {
    min_ferror: 1.0,
    ferror: 10.0,
    max_velocity: 100.0,
};

fn pid_update(c: &mut Criterion) {
    let gains = PidGains {
        i: 10.0,
        d: 0.001,
        output_limit: Some(200.0),
        integrator_limit: Some(0.1),
        ..PidGains::default()
    };
    let mut pid = PidController::new(
        0,
        &PidConfig {
            gains,
            following_error: LIMITS,
        },
    )
    .unwrap();
    let mut k = 0u32;
    c.bench_function("pid_update_one_joint", |b| {
        b.iter(|| {
            k = k.wrapping_add(1);
            let t = f64::from(k % 1000) * 1e-3;
            let setpoint = SetPoint {
                position: 10.0 * t,
                velocity: 10.0,
                acceleration: 0.0,
            };
            black_box(pid.update(black_box(setpoint), black_box(10.0 * t - 1e-4), 1e-3))
        })
    });
    let config = CspConfig {
        velocity_ff: 1.0,
        torque_ff: 1e-4,
        following_error: LIMITS,
        feedback_delay_periods: 0,
    };
    let mut csp = CspLoop::new(0, &config).unwrap();
    c.bench_function("csp_update_one_joint", |b| {
        b.iter(|| {
            let setpoint = SetPoint {
                position: 1.0,
                velocity: 10.0,
                acceleration: 5.0,
            };
            black_box(csp.update(black_box(setpoint), black_box(0.9999), 1e-3))
        })
    });
}

criterion_group!(benches, pid_update);
criterion_main!(benches);
