use rtcnc_motion::otg::*;
use std::time::Instant;
fn main() {
    let text = std::fs::read_to_string("crates/motion/tests/data/ruckig_cases.json").unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let cases: Vec<(f64, Limits)> = v["cases"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            (
                c["pf"].as_f64().unwrap(),
                Limits::symmetric(
                    c["vmax"].as_f64().unwrap(),
                    c["amax"].as_f64().unwrap(),
                    c["jmax"].as_f64().unwrap(),
                ),
            )
        })
        .collect();
    let mut best = f64::INFINITY;
    for _ in 0..60 {
        let t0 = Instant::now();
        for (pf, l) in &cases {
            std::hint::black_box(
                position_profile(State::at_rest(0.0), State::at_rest(*pf), l).unwrap(),
            );
        }
        best = best.min(t0.elapsed().as_secs_f64() / cases.len() as f64);
    }
    let l = Limits::symmetric(50.0, 1.0, 0.01);
    let mut seed = f64::INFINITY;
    for _ in 0..60 {
        let t0 = Instant::now();
        for _ in 0..1000 {
            std::hint::black_box(
                position_profile(
                    State::at_rest(0.0),
                    std::hint::black_box(State::at_rest(6000.0)),
                    &l,
                )
                .unwrap(),
            );
        }
        seed = seed.min(t0.elapsed().as_secs_f64() / 1000.0);
    }
    let l = Limits::symmetric(100.0, 1000.0, 50_000.0);
    let mut s2s = f64::INFINITY;
    for _ in 0..60 {
        let t0 = Instant::now();
        for _ in 0..1000 {
            std::hint::black_box(
                position_profile(
                    std::hint::black_box(State::new(1.0, 40.0, -300.0)),
                    State::new(12.0, -20.0, 150.0),
                    &l,
                )
                .unwrap(),
            );
        }
        s2s = s2s.min(t0.elapsed().as_secs_f64() / 1000.0);
    }
    println!(
        "min-pass: ruckig set {:.3} us/case, seed {:.3} us, state-to-state {:.3} us",
        best * 1e6,
        seed * 1e6,
        s2s * 1e6
    );
}
