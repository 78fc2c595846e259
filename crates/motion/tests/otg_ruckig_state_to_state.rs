//! State-to-state durations against ruckig 0.19.4: seeded random cases with non-zero start
//! and target states, start states outside the limits, asymmetric limits and the velocity
//! interface (`tests/data/otg_state_cases.json`, written by `tests/data/gen_otg_state_cases.py`).

use rtcnc_motion::otg::{Limits, State, position_profile, velocity_profile};
use serde::Deserialize;

#[derive(Deserialize)]
struct CaseFile {
    cases: Vec<Case>,
}

#[derive(Deserialize)]
struct Case {
    kind: String,
    p0: f64,
    v0: f64,
    a0: f64,
    pf: Option<f64>,
    vf: f64,
    af: f64,
    vmax: f64,
    vmin: f64,
    amax: f64,
    amin: f64,
    jmax: f64,
    duration: f64,
}

impl Case {
    fn limits(&self) -> Limits {
        Limits {
            max_velocity: self.vmax,
            min_velocity: self.vmin,
            max_acceleration: self.amax,
            min_acceleration: self.amin,
            max_jerk: self.jmax,
        }
    }
}

fn cases() -> Vec<Case> {
    serde_json::from_str::<CaseFile>(include_str!("data/otg_state_cases.json"))
        .expect("otg_state_cases.json parses")
        .cases
}

fn failures_of(kind_filter: &dyn Fn(&str) -> bool) -> (usize, Vec<String>) {
    let mut failures = Vec::new();
    let mut n = 0;
    for (i, c) in cases()
        .iter()
        .enumerate()
        .filter(|(_, c)| kind_filter(&c.kind))
    {
        n += 1;
        let start = State::new(c.p0, c.v0, c.a0);
        let result = match c.pf {
            Some(pf) => position_profile(start, State::new(pf, c.vf, c.af), &c.limits()),
            None => velocity_profile(start, c.vf, c.af, &c.limits()),
        };
        match result {
            Ok(profile) => {
                let rel = (profile.duration() - c.duration).abs() / c.duration;
                if rel > 1e-6 {
                    failures.push(format!(
                        "#{i} {}: {} vs ruckig {} (rel {rel:.2e})",
                        c.kind,
                        profile.duration(),
                        c.duration
                    ));
                }
            }
            Err(e) => failures.push(format!("#{i} {}: error {e}", c.kind)),
        }
    }
    (n, failures)
}

fn assert_family(kind: &str) {
    let (n, failures) = failures_of(&|k| k == kind);
    assert!(n >= 50, "{kind}: only {n} cases");
    assert!(
        failures.is_empty(),
        "{kind}: {} of {n} differ:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

#[test]
fn start_inside_limits_to_rest() {
    assert_family("inside");
}

#[test]
fn non_zero_target_velocity() {
    assert_family("target_v");
}

#[test]
fn non_zero_target_velocity_and_acceleration() {
    assert_family("target_va");
}

#[test]
fn start_outside_limits_brakes_first() {
    assert_family("violating");
}

#[test]
fn asymmetric_limits() {
    assert_family("asymmetric");
}

#[test]
fn asymmetric_limits_and_start_outside_them() {
    assert_family("asym_violating");
}

#[test]
fn velocity_interface() {
    assert_family("velocity");
}
