//! Straight-line multi-axis moves (phase synchronisation) against ruckig 0.19.4
//! (`straight3` cases of `tests/data/otg_state_cases.json`, `Synchronization.Phase`, the
//! same limits on all axes, from rest or from a motion along the line): the durations equal
//! ruckig's and every sampled point lies on the straight line.

use rtcnc_motion::otg::{Limits, State, synchronize_straight};
use serde::Deserialize;

#[derive(Deserialize)]
struct CaseFile {
    straight3: Vec<Case>,
}

#[derive(Deserialize)]
struct AxisLimits {
    vmax: f64,
    amax: f64,
    jmax: f64,
}

#[derive(Deserialize)]
struct Case {
    p0: [f64; 3],
    v0: [f64; 3],
    a0: [f64; 3],
    pf: [f64; 3],
    limits: [AxisLimits; 3],
    duration: f64,
}

#[test]
fn straight_line_durations_equal_ruckig_phase_synchronisation() {
    let cases: CaseFile = serde_json::from_str(include_str!("data/otg_state_cases.json")).unwrap();
    assert!(cases.straight3.len() >= 20);
    for (k, c) in cases.straight3.iter().enumerate() {
        let start: [State; 3] = std::array::from_fn(|i| State::new(c.p0[i], c.v0[i], c.a0[i]));
        let target: [State; 3] = std::array::from_fn(|i| State::at_rest(c.pf[i]));
        let limits: [Limits; 3] = std::array::from_fn(|i| {
            Limits::symmetric(c.limits[i].vmax, c.limits[i].amax, c.limits[i].jmax)
        });
        let sync = synchronize_straight(&start, &target, &limits).unwrap();
        let t_end = sync.duration();
        assert!(
            (t_end - c.duration).abs() <= 1e-6 * c.duration,
            "case {k}: {t_end} vs ruckig {}",
            c.duration
        );
        let d: [f64; 3] = std::array::from_fn(|i| c.pf[i] - c.p0[i]);
        let length = d.iter().map(|x| x * x).sum::<f64>().sqrt();
        for n in 0..=100 {
            let samples = sync.at(t_end * f64::from(n) / 100.0);
            // Distance along the line, then the distance off it.
            let s: f64 = (0..3)
                .map(|i| (samples[i].p - c.p0[i]) * d[i] / length)
                .sum();
            for i in 0..3 {
                let off = samples[i].p - c.p0[i] - s * d[i] / length;
                assert!(
                    off.abs() <= 1e-9 * (1.0 + length),
                    "case {k}: {off} off the line"
                );
                assert!(samples[i].v.abs() <= limits[i].max_velocity * (1.0 + 1e-9));
                assert!(samples[i].a.abs() <= limits[i].max_acceleration * (1.0 + 1e-9));
                assert!(samples[i].j.abs() <= limits[i].max_jerk * (1.0 + 1e-9));
            }
        }
        for (i, s) in sync.at(t_end).iter().enumerate() {
            assert_eq!((s.p, s.v, s.a), (c.pf[i], 0.0, 0.0));
        }
    }
}

/// Different limits per axis: each axis is held to its own. A move of (3, 4) mm with axis
/// velocity limits (10, 2) mm/s: along the line s' ≤ min(10 / 0.6, 2 / 0.8) = 2.5 mm/s.
#[test]
fn each_axis_keeps_its_own_limits_on_the_line() {
    let limits = [
        Limits::symmetric(10.0, 100.0, 1000.0),
        Limits::symmetric(2.0, 100.0, 1000.0),
    ];
    let sync = synchronize_straight(
        &[State::at_rest(0.0); 2],
        &[State::at_rest(3.0), State::at_rest(4.0)],
        &limits,
    )
    .unwrap();
    let (vx, _, _) = sync.profiles[0].peaks();
    let (vy, _, _) = sync.profiles[1].peaks();
    assert!((vy - 2.0).abs() < 1e-12, "{vy}");
    assert!((vx - 1.5).abs() < 1e-12, "{vx}");
    // Cruise at 2.5 mm/s along a 5 mm line; along the line a <= min(100/0.6, 100/0.8) = 125
    // and j <= 1250, and v j = 3125 < a² so the acceleration limit is not reached: the speed
    // is reached in 2 sqrt(v/j) and T = 2 sqrt(v/j) + L/v.
    let t = 2.0 * (2.5f64 / 1250.0).sqrt() + 5.0 / 2.5;
    assert!(
        (sync.duration() - t).abs() < 1e-12,
        "{} vs {t}",
        sync.duration()
    );
}

#[test]
fn motion_off_the_line_is_refused() {
    let limits = [Limits::symmetric(10.0, 100.0, 1000.0); 2];
    let start = [State::new(0.0, 1.0, 0.0), State::at_rest(0.0)];
    let target = [State::at_rest(0.0), State::at_rest(5.0)];
    let error = synchronize_straight(&start, &target, &limits).unwrap_err();
    assert_eq!(error.code(), "otg-not-collinear");
    let standstill = synchronize_straight(
        &[State::at_rest(1.0); 2],
        &[State::at_rest(1.0); 2],
        &limits,
    );
    assert_eq!(standstill.unwrap().duration(), 0.0);
}
