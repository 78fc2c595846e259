//! Property tests: sampled profiles keep the limits, reach the target exactly and never
//! produce NaN; synchronised axes finish together. Case counts are small in debug builds
//! (CI); `cargo test --release` runs more.

use proptest::prelude::*;
use rtcnc_motion::otg::{Limits, Profile, State, position_profile, synchronize, velocity_profile};

const SLACK: f64 = 1.0 + 1e-9;

fn cases() -> u32 {
    if cfg!(debug_assertions) { 200 } else { 20_000 }
}

/// Log-uniform limits over several decades, optionally asymmetric.
fn limits() -> impl Strategy<Value = Limits> {
    (
        -1.0f64..2.0,
        -1.0f64..3.0,
        0.0f64..5.0,
        0.3f64..3.0,
        0.3f64..3.0,
        any::<bool>(),
    )
        .prop_map(|(v, a, j, vr, ar, asym)| {
            let (v, a, j) = (10f64.powf(v), 10f64.powf(a), 10f64.powf(j));
            let (vr, ar) = if asym { (vr, ar) } else { (1.0, 1.0) };
            Limits {
                max_velocity: v,
                min_velocity: -v * vr,
                max_acceleration: a,
                min_acceleration: -a * ar,
                max_jerk: j,
            }
        })
}

/// A state inside the limits that is not bound to break them (braking with the full jerk
/// keeps the velocity inside), from fractions in [-1, 1].
fn safe_state(l: &Limits, p: f64, fv: f64, fa: f64) -> State {
    let mut a = if fa >= 0.0 {
        fa * l.max_acceleration
    } else {
        -fa * l.min_acceleration
    };
    // Ramping the acceleration to zero changes the velocity by a|a|/2j: keep that inside.
    let span = l.max_velocity - l.min_velocity;
    let cap = (0.9 * span * 2.0 * l.max_jerk).sqrt();
    a = a.clamp(-cap, cap);
    let reach = a * a.abs() / (2.0 * l.max_jerk);
    let lo = l.min_velocity.max(l.min_velocity - reach);
    let hi = l.max_velocity.min(l.max_velocity - reach);
    State::new(p, lo + 0.5 * (fv + 1.0) * (hi - lo), a)
}

fn target_state(l: &Limits, p: f64, fv: f64, fa: f64) -> State {
    // Arriving with acceleration a means the velocity was v - a|a|/2j where a was zero.
    let s = safe_state(&Limits { ..*l }, p, fv, fa);
    let before = s.v - s.a * s.a.abs() / (2.0 * l.max_jerk);
    let shift = if before > l.max_velocity {
        l.max_velocity - before
    } else if before < l.min_velocity {
        l.min_velocity - before
    } else {
        0.0
    };
    State::new(p, (s.v + shift).clamp(l.min_velocity, l.max_velocity), s.a)
}

/// Samples the profile densely and at every phase boundary; checks limits and finiteness.
fn assert_within_limits(profile: &Profile, l: &Limits, from: f64) -> Result<(), TestCaseError> {
    let t_end = profile.duration();
    let mut boundaries = [0.0; 10];
    let mut t = 0.0;
    for (slot, phase) in boundaries.iter_mut().zip(profile.phases()) {
        t += phase.duration;
        *slot = t;
    }
    let grid = (0..=400).map(|k| t_end * k as f64 / 400.0);
    for t in grid.chain(boundaries.into_iter().take(profile.phase_count())) {
        if t < from {
            continue;
        }
        let s = profile.at(t);
        prop_assert!(s.p.is_finite() && s.v.is_finite() && s.a.is_finite() && s.j.is_finite());
        prop_assert!(
            s.v <= l.max_velocity * SLACK && s.v >= l.min_velocity * SLACK,
            "v {} at {t}",
            s.v
        );
        prop_assert!(
            s.a <= l.max_acceleration * SLACK && s.a >= l.min_acceleration * SLACK,
            "a {} at {t}",
            s.a
        );
        prop_assert!(s.j.abs() <= l.max_jerk * SLACK);
    }
    // Finite differences at a servo-like period agree: the set-points themselves, not only
    // the phase description, respect the acceleration and jerk limits.
    let dt = t_end / 400.0;
    let a_abs = l.max_acceleration.max(-l.min_acceleration);
    let mut previous = profile.at(from);
    for k in 1..=400 {
        let t = t_end * k as f64 / 400.0;
        if t <= from {
            continue;
        }
        let s = profile.at(t);
        let step = t - (t - dt).max(from);
        let tol = 1e-9 * (1.0 + previous.v.abs() + previous.a.abs());
        prop_assert!((s.a - previous.a).abs() <= l.max_jerk * step * SLACK + tol);
        prop_assert!((s.v - previous.v).abs() <= a_abs * step * SLACK + tol);
        previous = s;
    }
    Ok(())
}

fn assert_reaches(profile: &Profile, target: State, l: &Limits) -> Result<(), TestCaseError> {
    let t_end = profile.duration();
    let end = profile.at(t_end);
    prop_assert_eq!((end.p, end.v, end.a), (target.p, target.v, target.a));
    // The phases themselves arrive there, not only the stored end state.
    let dt = 1e-9 * t_end;
    let near = profile.at(t_end - dt);
    let v_scale = l.max_velocity.max(-l.min_velocity);
    let a_scale = l.max_acceleration.max(-l.min_acceleration);
    let scale = 1.0 + target.p.abs() + v_scale * t_end;
    prop_assert!(
        (near.p - target.p).abs() <= 1e-9 * scale + v_scale * dt,
        "p {} vs {}",
        near.p,
        target.p
    );
    prop_assert!(
        (near.v - target.v).abs() <= 1e-9 * (v_scale + a_scale * t_end) + a_scale * dt,
        "v {} vs {}",
        near.v,
        target.v
    );
    Ok(())
}

/// Limits over extreme scales: micrometre jogs to metre-per-second rapids, soft to very
/// stiff jerk limits.
fn wide_limits() -> impl Strategy<Value = Limits> {
    (-3.0f64..4.0, -2.0f64..6.0, -1.0f64..9.0)
        .prop_map(|(v, a, j)| Limits::symmetric(10f64.powf(v), 10f64.powf(a), 10f64.powf(j)))
}

fn wide_distance() -> impl Strategy<Value = f64> {
    (-7.0f64..4.0, any::<bool>()).prop_map(|(d, negative)| {
        if negative {
            -10f64.powf(d)
        } else {
            10f64.powf(d)
        }
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn position_profiles_keep_limits_and_reach_target(
        l in limits(),
        p0 in -100.0f64..100.0, fv0 in -1.0f64..1.0, fa0 in -1.0f64..1.0,
        pf in -100.0f64..100.0, fvf in -1.0f64..1.0, faf in -1.0f64..1.0,
        rest in any::<bool>(),
    ) {
        let start = safe_state(&l, p0, fv0, fa0);
        let target = if rest { State::at_rest(pf) } else { target_state(&l, pf, fvf, faf) };
        let profile = position_profile(start, target, &l).map_err(|e| TestCaseError::fail(e.to_string()))?;
        prop_assert_eq!(profile.brake_duration(), 0.0);
        assert_within_limits(&profile, &l, 0.0)?;
        let (v_peak, a_peak, j_peak) = profile.peaks();
        prop_assert!(v_peak <= l.max_velocity.max(-l.min_velocity) * SLACK);
        prop_assert!(a_peak <= l.max_acceleration.max(-l.min_acceleration) * SLACK);
        prop_assert!(j_peak <= l.max_jerk * SLACK);
        assert_reaches(&profile, target, &l)?;
    }

    #[test]
    fn start_outside_limits_comes_back_inside_and_stays(
        l in limits(),
        fv0 in -3.0f64..3.0, fa0 in -3.0f64..3.0,
        pf in -100.0f64..100.0,
    ) {
        // Inside the numeric envelope: the start acceleration cannot throw the velocity more
        // than a hundred times past its limit before the jerk limit brings it back.
        let a_cap = (200.0 * l.max_jerk * l.max_velocity).sqrt();
        let start = State::new(0.0, fv0 * l.max_velocity, (fa0 * l.max_acceleration).clamp(-a_cap, a_cap));
        let target = State::at_rest(pf);
        let profile = position_profile(start, target, &l).map_err(|e| TestCaseError::fail(e.to_string()))?;
        // First sample inside the limits and not bound to leave them (ramping the
        // acceleration to zero keeps the velocity inside): from then on everything stays in.
        let t_end = profile.duration();
        let inside = (0..=400).map(|k| t_end * k as f64 / 400.0).find(|&t| {
            let s = profile.at(t);
            let settled = s.v + s.a * s.a.abs() / (2.0 * l.max_jerk);
            s.v <= l.max_velocity && s.v >= l.min_velocity
                && s.a <= l.max_acceleration && s.a >= l.min_acceleration
                && settled <= l.max_velocity && settled >= l.min_velocity
        });
        if let Some(from) = inside {
            assert_within_limits(&profile, &l, from.max(profile.brake_duration()))?;
        }
        assert_reaches(&profile, target, &l)?;
    }

    #[test]
    fn velocity_profiles_keep_acceleration_and_jerk_limits(
        l in limits(),
        fv0 in -1.0f64..1.0, fa0 in -1.0f64..1.0, fvf in -1.0f64..1.0, faf in -1.0f64..1.0,
    ) {
        let start = safe_state(&l, 0.0, fv0, fa0);
        let target = target_state(&l, 0.0, fvf, faf);
        let profile = velocity_profile(start, target.v, target.a, &l).map_err(|e| TestCaseError::fail(e.to_string()))?;
        let t_end = profile.duration();
        for k in 0..=200 {
            let s = profile.at(t_end * k as f64 / 200.0);
            prop_assert!(s.a <= l.max_acceleration * SLACK && s.a >= l.min_acceleration * SLACK);
            prop_assert!(s.j.abs() <= l.max_jerk * SLACK);
        }
        let end = profile.at(t_end);
        prop_assert_eq!((end.v, end.a), (target.v, target.a));
    }

    #[test]
    fn synchronised_axes_finish_together(
        l in [limits(), limits(), limits()],
        p0 in [-50.0f64..50.0, -50.0f64..50.0, -50.0f64..50.0],
        pf in [-50.0f64..50.0, -50.0f64..50.0, -50.0f64..50.0],
        f in [(-1.0f64..1.0, -1.0f64..1.0), (-1.0f64..1.0, -1.0f64..1.0), (-1.0f64..1.0, -1.0f64..1.0)],
        moving in [any::<bool>(), any::<bool>(), any::<bool>()],
    ) {
        let start: [State; 3] = std::array::from_fn(|i| safe_state(&l[i], p0[i], f[i].0, f[i].1));
        // Half the targets are moving: their blocked duration intervals then matter.
        let target: [State; 3] = std::array::from_fn(|i| {
            if moving[i] { target_state(&l[i], pf[i], f[i].1, f[i].0) } else { State::at_rest(pf[i]) }
        });
        let sync = synchronize(&start, &target, &l).map_err(|e| TestCaseError::fail(e.to_string()))?;
        let t = sync.duration();
        let slowest = (0..3)
            .map(|i| position_profile(start[i], target[i], &l[i]).map(|p| p.duration()).unwrap_or(0.0))
            .fold(0.0, f64::max);
        prop_assert!(t >= slowest * (1.0 - 1e-12));
        for i in 0..3 {
            let profile = &sync.profiles[i];
            prop_assert!((profile.duration() - t).abs() <= 1e-9 * t);
            assert_within_limits(profile, &l[i], 0.0)?;
            assert_reaches(profile, target[i], &l[i])?;
        }
    }

    #[test]
    fn any_input_gives_a_profile_or_an_error_never_a_panic_or_nan(
        values in proptest::array::uniform11(prop_oneof![
            any::<f64>(),
            -10.0f64..10.0,
            Just(0.0), Just(f64::NAN), Just(f64::INFINITY), Just(-1.0),
        ]),
    ) {
        let [p0, v0, a0, pf, vf, af, vmax, vmin, amax, amin, j] = values;
        let l = Limits { max_velocity: vmax, min_velocity: vmin, max_acceleration: amax, min_acceleration: amin, max_jerk: j };
        if let Ok(profile) = position_profile(State::new(p0, v0, a0), State::new(pf, vf, af), &l) {
            for k in 0..=20 {
                let s = profile.at(profile.duration() * k as f64 / 20.0);
                prop_assert!(!(s.p.is_nan() || s.v.is_nan() || s.a.is_nan() || s.j.is_nan()));
            }
        }
        if let Ok(profile) = velocity_profile(State::new(p0, v0, a0), vf, af, &l) {
            let s = profile.at(profile.duration());
            prop_assert!(!(s.p.is_nan() || s.v.is_nan() || s.a.is_nan()));
        }
    }

    #[test]
    fn extreme_scales_solve_keep_limits_and_reach_target(
        l in [wide_limits(), wide_limits(), wide_limits()],
        d in [wide_distance(), wide_distance(), wide_distance()],
        f in [(-1.0f64..1.0, -1.0f64..1.0), (-1.0f64..1.0, -1.0f64..1.0), (-1.0f64..1.0, -1.0f64..1.0)],
        moving in [any::<bool>(), any::<bool>(), any::<bool>()],
    ) {
        let start: [State; 3] = std::array::from_fn(|i| safe_state(&l[i], 0.0, f[i].0, f[i].1));
        let target: [State; 3] = std::array::from_fn(|i| {
            if moving[i] { target_state(&l[i], d[i], f[i].1, f[i].0) } else { State::at_rest(d[i]) }
        });
        for i in 0..3 {
            let profile = position_profile(start[i], target[i], &l[i]).map_err(|e| TestCaseError::fail(e.to_string()))?;
            assert_within_limits(&profile, &l[i], 0.0)?;
            assert_reaches(&profile, target[i], &l[i])?;
        }
        let sync = synchronize(&start, &target, &l).map_err(|e| TestCaseError::fail(e.to_string()))?;
        for i in 0..3 {
            assert_within_limits(&sync.profiles[i], &l[i], 0.0)?;
            assert_reaches(&sync.profiles[i], target[i], &l[i])?;
        }
    }
}
