//! Multi-axis time synchronisation against ruckig 0.19.4 (`sync3` cases of
//! `tests/data/otg_state_cases.json`): the common duration equals ruckig's, and every axis
//! reaches its own target at that instant. Twelve of the cases are ones where an axis's
//! blocked duration interval makes the common duration longer than every axis's minimum;
//! twelve round the duration up to a whole number of control periods (ruckig's discrete
//! duration).

use rtcnc_motion::otg::{Limits, State, position_block, synchronize, synchronize_on_period};
use serde::Deserialize;

#[derive(Deserialize)]
struct CaseFile {
    sync3: Vec<SyncCase>,
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
struct SyncCase {
    kind: String,
    period: Option<f64>,
    p0: [f64; 3],
    v0: [f64; 3],
    a0: [f64; 3],
    pf: [f64; 3],
    vf: [f64; 3],
    af: [f64; 3],
    limits: [AxisLimits; 3],
    duration: f64,
    independent_min_durations: [f64; 3],
}

fn cases() -> Vec<SyncCase> {
    serde_json::from_str::<CaseFile>(include_str!("data/otg_state_cases.json"))
        .expect("otg_state_cases.json parses")
        .sync3
}

fn inputs(c: &SyncCase) -> ([State; 3], [State; 3], [Limits; 3]) {
    let start = std::array::from_fn(|i| State::new(c.p0[i], c.v0[i], c.a0[i]));
    let target = std::array::from_fn(|i| State::new(c.pf[i], c.vf[i], c.af[i]));
    let limits = std::array::from_fn(|i| Limits {
        max_velocity: c.limits[i].vmax,
        min_velocity: c.limits[i].vmin,
        max_acceleration: c.limits[i].amax,
        min_acceleration: c.limits[i].amin,
        max_jerk: c.limits[i].jmax,
    });
    (start, target, limits)
}

#[test]
fn independent_minimum_durations_equal_ruckig() {
    for (k, c) in cases().iter().enumerate() {
        let (start, target, limits) = inputs(c);
        for i in 0..3 {
            let block = position_block(start[i], target[i], &limits[i]).unwrap();
            let want = c.independent_min_durations[i];
            assert!(
                (block.t_min - want).abs() <= 1e-6 * want,
                "case {k} axis {i}: {} vs {want}",
                block.t_min
            );
        }
    }
}

#[test]
fn synchronised_duration_equals_ruckig_and_all_axes_arrive_together() {
    let cases = cases();
    let blocked = cases.iter().filter(|c| c.kind == "sync3_blocked").count();
    assert!(
        blocked >= 10,
        "only {blocked} cases decided by a blocked interval"
    );
    let on_period = cases.iter().filter(|c| c.period.is_some()).count();
    assert!(
        on_period >= 10,
        "only {on_period} cases on a control period"
    );
    let mut failures = Vec::new();
    for (k, c) in cases.iter().enumerate() {
        let (start, target, limits) = inputs(c);
        let result = match c.period {
            Some(period) => synchronize_on_period(&start, &target, &limits, period),
            None => synchronize(&start, &target, &limits),
        };
        let sync = match result {
            Ok(sync) => sync,
            Err(e) => {
                failures.push(format!("case {k}: {e}"));
                continue;
            }
        };
        let t = sync.duration();
        if (t - c.duration).abs() > 1e-6 * c.duration {
            failures.push(format!("case {k}: {t} vs ruckig {}", c.duration));
        }
        for (i, profile) in sync.profiles.iter().enumerate() {
            assert!(
                (profile.duration() - t).abs() <= 1e-9 * t,
                "case {k} axis {i}"
            );
            let end = profile.at(t);
            assert!(
                (end.p - target[i].p).abs() <= 1e-9 * (1.0 + target[i].p.abs()),
                "case {k} axis {i}"
            );
            assert!(
                (end.v - target[i].v).abs() <= 1e-9 * (1.0 + target[i].v.abs()),
                "case {k} axis {i}"
            );
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} differ:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
}
