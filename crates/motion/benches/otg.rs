//! Cost of the trajectory generator: computing profiles (single axis, three synchronised
//! axes, the 1000 ruckig rest-to-rest cases) and evaluating them every servo period.
//!
//! `cargo bench -p rtcnc-motion --bench otg`; `bench/otg-vs-ruckig.sh` puts ruckig's figures
//! next to these.

// criterion_group! and criterion_main! make public functions without docs.
#![allow(missing_docs)]

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use rtcnc_motion::otg::{
    Limits, OnlineAxis, State, position_profile, synchronize, synchronize_straight,
    synchronize_velocity, velocity_profile,
};
use serde::Deserialize;

#[derive(Deserialize)]
struct CaseFile {
    cases: Vec<Case>,
}

#[derive(Deserialize)]
struct Case {
    pf: f64,
    vmax: f64,
    amax: f64,
    jmax: f64,
}

fn ruckig_cases() -> Vec<(State, Limits)> {
    let file: CaseFile = serde_json::from_str(include_str!("../tests/data/ruckig_cases.json"))
        .expect("ruckig_cases.json parses");
    file.cases
        .iter()
        .map(|c| {
            (
                State::at_rest(c.pf),
                Limits::symmetric(c.vmax, c.amax, c.jmax),
            )
        })
        .collect()
}

fn compute(c: &mut Criterion) {
    let mut group = c.benchmark_group("otg/compute");
    let limits = Limits::symmetric(50.0, 1.0, 0.01);
    group.bench_function("seed rest-to-rest 6000 pulse", |b| {
        b.iter(|| {
            position_profile(
                State::at_rest(0.0),
                black_box(State::at_rest(6000.0)),
                &limits,
            )
        })
    });
    let limits = Limits::symmetric(100.0, 1000.0, 50_000.0);
    let start = State::new(1.0, 40.0, -300.0);
    let target = State::new(12.0, -20.0, 150.0);
    group.bench_function("state-to-state single axis", |b| {
        b.iter(|| position_profile(black_box(start), black_box(target), &limits))
    });
    group.bench_function("velocity interface (quick stop)", |b| {
        b.iter(|| velocity_profile(black_box(start), 0.0, 0.0, &limits))
    });
    let starts = [
        State::new(0.0, 10.0, 0.0),
        State::new(5.0, -20.0, 100.0),
        State::at_rest(-3.0),
    ];
    let targets = [
        State::at_rest(20.0),
        State::at_rest(-4.0),
        State::new(1.0, 5.0, 0.0),
    ];
    let all = [
        limits,
        Limits::symmetric(80.0, 800.0, 40_000.0),
        Limits::symmetric(50.0, 500.0, 20_000.0),
    ];
    group.bench_function("three axes synchronised", |b| {
        b.iter(|| synchronize(black_box(&starts), black_box(&targets), &all))
    });
    let rest = [State::at_rest(0.0); 3];
    let ends = [
        State::at_rest(20.0),
        State::at_rest(-4.0),
        State::at_rest(1.0),
    ];
    group.bench_function("three axes straight line", |b| {
        b.iter(|| synchronize_straight(black_box(&rest), black_box(&ends), &all))
    });
    let speeds = [30.0, -10.0, 0.0];
    group.bench_function("three axes velocity synchronised", |b| {
        b.iter(|| synchronize_velocity(black_box(&starts), black_box(&speeds), &[0.0; 3], &all))
    });
    let cases = ruckig_cases();
    group.bench_function("1000 ruckig rest-to-rest cases (whole set)", |b| {
        b.iter(|| {
            for (target, limits) in &cases {
                let _ = black_box(position_profile(State::at_rest(0.0), *target, limits));
            }
        })
    });
    group.finish();
}

fn evaluate(c: &mut Criterion) {
    let mut group = c.benchmark_group("otg/evaluate");
    let limits = Limits::symmetric(100.0, 1000.0, 50_000.0);
    let profile = position_profile(
        State::new(1.0, 40.0, -300.0),
        State::new(12.0, -20.0, 150.0),
        &limits,
    )
    .expect("profile");
    let period = profile.duration() / 1000.0;
    // One call per servo period per axis, walking through the whole profile.
    group.bench_function("Profile::at, one servo period of one axis", |b| {
        let mut k = 0u32;
        b.iter(|| {
            k = (k + 1) % 1000;
            black_box(profile.at(black_box(f64::from(k) * period)))
        })
    });
    group.bench_function("OnlineAxis::step, one servo period of one axis", |b| {
        let mut axis = OnlineAxis::new(State::at_rest(0.0), limits).expect("axis");
        axis.set_target(State::at_rest(1e9)).expect("target");
        b.iter(|| black_box(axis.step(black_box(1e-3))))
    });
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().measurement_time(Duration::from_secs(2)).warm_up_time(Duration::from_millis(500));
    targets = compute, evaluate
}
criterion_main!(benches);
