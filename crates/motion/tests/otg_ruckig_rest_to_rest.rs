//! Rest-to-rest durations against ruckig 0.19.4 (`tests/data/ruckig_cases.json`, 1000 seeded
//! cases written by the peer script `ruckig_profile.py random --seed 20240601`), and the
//! seeds' 6000-pulse S-curve experiment.

use rtcnc_motion::otg::{Limits, State, position_profile, synchronize_on_period};
use serde::Deserialize;

#[derive(Deserialize)]
struct CaseFile {
    cases: Vec<Case>,
}

#[derive(Deserialize)]
struct Case {
    id: u32,
    pf: f64,
    vmax: f64,
    amax: f64,
    jmax: f64,
    duration: f64,
    peak_abs_velocity: f64,
    peak_abs_acceleration: f64,
}

fn cases() -> Vec<Case> {
    let text = include_str!("data/ruckig_cases.json");
    serde_json::from_str::<CaseFile>(text)
        .expect("ruckig_cases.json parses")
        .cases
}

#[test]
fn all_1000_rest_to_rest_durations_equal_ruckig() {
    let cases = cases();
    assert_eq!(cases.len(), 1000);
    let mut failures = Vec::new();
    for c in &cases {
        let limits = Limits::symmetric(c.vmax, c.amax, c.jmax);
        match position_profile(State::at_rest(0.0), State::at_rest(c.pf), &limits) {
            Ok(profile) => {
                let rel = (profile.duration() - c.duration).abs() / c.duration;
                if rel > 1e-6 {
                    failures.push(format!(
                        "case {}: {} vs ruckig {}",
                        c.id,
                        profile.duration(),
                        c.duration
                    ));
                }
            }
            Err(e) => failures.push(format!("case {}: {e}", c.id)),
        }
    }
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

#[test]
fn rest_to_rest_peaks_equal_ruckig() {
    for c in cases() {
        let limits = Limits::symmetric(c.vmax, c.amax, c.jmax);
        let profile = position_profile(State::at_rest(0.0), State::at_rest(c.pf), &limits).unwrap();
        let (v, a, _) = profile.peaks();
        assert!(
            (v - c.peak_abs_velocity).abs() <= 1e-6 * c.peak_abs_velocity,
            "case {}",
            c.id
        );
        assert!(
            (a - c.peak_abs_acceleration).abs() <= 1e-6 * c.peak_abs_acceleration,
            "case {}",
            c.id
        );
    }
}

/// The seeds' single-axis experiment in pulse and millisecond units. ruckig: 267.773 ms,
/// peak 44.814 pulse/ms and 0.669 pulse/ms², neither limit reached, four jerk phases of
/// 66.94 ms (the values are printed by `ruckig_profile.py paper`).
#[test]
fn seeds_6000_pulse_experiment_matches_ruckig() {
    let limits = Limits::symmetric(50.0, 1.0, 0.01);
    let profile = position_profile(State::at_rest(0.0), State::at_rest(6000.0), &limits).unwrap();
    assert_eq!(format!("{:.3}", profile.duration()), "267.773");
    let (v, a, j) = profile.peaks();
    assert_eq!(format!("{v:.3}"), "44.814");
    assert_eq!(format!("{a:.3}"), "0.669");
    assert_eq!(j, 0.01);
    let phases: Vec<_> = profile.phases().collect();
    assert_eq!(phases.len(), 4);
    for phase in &phases {
        assert_eq!(format!("{:.2}", phase.duration), "66.94");
        assert_eq!(phase.jerk.abs(), 0.01);
    }
    let end = profile.at(profile.duration());
    assert_eq!((end.p, end.v, end.a), (6000.0, 0.0, 0.0));
}

/// The same move rounded up to whole 1 ms servo periods (ruckig's discrete duration, printed
/// by `ruckig_profile.py paper` as `discrete_1ms_cycle`): 268 ms, peak 44.66309969706033.
#[test]
fn seeds_experiment_on_a_1_ms_period_matches_ruckig() {
    let limits = [Limits::symmetric(50.0, 1.0, 0.01)];
    let sync = synchronize_on_period(
        &[State::at_rest(0.0)],
        &[State::at_rest(6000.0)],
        &limits,
        1.0,
    )
    .unwrap();
    assert!((sync.duration() - 268.0).abs() < 1e-9);
    let (v, a, _) = sync.profiles[0].peaks();
    assert!(
        (v - 44.66309969706033).abs() < 1e-9 * 44.66309969706033,
        "{v}"
    );
    assert!(a <= 1.0);
    let end = sync.at(268.0)[0];
    assert_eq!((end.p, end.v, end.a), (6000.0, 0.0, 0.0));
    let near = sync.profiles[0].at(268.0 - 1e-9);
    assert!((near.p - 6000.0).abs() < 1e-9);
}
