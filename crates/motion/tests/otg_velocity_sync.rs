//! Velocity-interface time synchronisation against ruckig 0.19.4 (`vsync3` cases of
//! `tests/data/otg_state_cases.json`): three axes reach their target velocities and
//! accelerations together, at ruckig's duration; every axis keeps its acceleration and jerk
//! limits and ends exactly on its target.

use rtcnc_motion::otg::{Limits, State, synchronize_velocity};
use serde::Deserialize;

#[derive(Deserialize)]
struct CaseFile {
    vsync3: Vec<Case>,
}

#[derive(Deserialize)]
struct AxisLimits {
    vmax: f64,
    vmin: f64,
    amax: f64,
    amin: f64,
    jmax: f64,
}

#[derive(Deserialize)]
struct Case {
    v0: [f64; 3],
    a0: [f64; 3],
    vf: [f64; 3],
    af: [f64; 3],
    limits: [AxisLimits; 3],
    duration: f64,
}

#[test]
fn velocity_synchronisation_equals_ruckig() {
    let file: CaseFile = serde_json::from_str(include_str!("data/otg_state_cases.json")).unwrap();
    assert!(file.vsync3.len() >= 20);
    for (k, c) in file.vsync3.iter().enumerate() {
        let start: [State; 3] = std::array::from_fn(|i| State::new(0.0, c.v0[i], c.a0[i]));
        let limits: [Limits; 3] = std::array::from_fn(|i| Limits {
            max_velocity: c.limits[i].vmax,
            min_velocity: c.limits[i].vmin,
            max_acceleration: c.limits[i].amax,
            min_acceleration: c.limits[i].amin,
            max_jerk: c.limits[i].jmax,
        });
        let sync = synchronize_velocity(&start, &c.vf, &c.af, &limits).unwrap();
        let t = sync.duration();
        assert!(
            (t - c.duration).abs() <= 1e-6 * c.duration,
            "case {k}: {t} vs ruckig {}",
            c.duration
        );
        for (i, profile) in sync.profiles.iter().enumerate() {
            assert!(
                (profile.duration() - t).abs() <= 1e-9 * t,
                "case {k} axis {i}"
            );
            // Just before the end the phases themselves arrive there (the step back moves
            // the acceleration by at most j dt and the velocity by at most a dt).
            let dt = 1e-12 * t;
            let near = profile.at(t - dt);
            let l = &limits[i];
            let a_abs = l.max_acceleration.max(-l.min_acceleration);
            let v_tol = 1e-9 * (1.0 + c.vf[i].abs()) + a_abs * dt;
            let a_tol = 1e-9 * (1.0 + a_abs) + l.max_jerk * dt;
            assert!((near.v - c.vf[i]).abs() <= v_tol, "case {k} axis {i}");
            assert!((near.a - c.af[i]).abs() <= a_tol, "case {k} axis {i}");
            let from = profile.brake_duration();
            for n in 0..=100 {
                let s = profile.at(from + (t - from) * f64::from(n) / 100.0);
                assert!(
                    s.a <= limits[i].max_acceleration * (1.0 + 1e-9),
                    "case {k} axis {i}"
                );
                assert!(
                    s.a >= limits[i].min_acceleration * (1.0 + 1e-9),
                    "case {k} axis {i}"
                );
                assert!(s.j.abs() <= limits[i].max_jerk * (1.0 + 1e-9));
            }
        }
    }
}
