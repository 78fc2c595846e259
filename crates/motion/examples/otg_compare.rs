//! Stress comparison with ruckig on a large generated case file:
//!
//! ```sh
//! ~/.cache/rtcnc-peers/venv/bin/python crates/motion/tests/data/gen_otg_state_cases.py \
//!     --scale 30 --seed 7 --out /tmp/stress.json
//! cargo run --release -p rtcnc-motion --example otg_compare -- /tmp/stress.json
//! ```
//!
//! Prints, per family of cases, how many durations differ from ruckig's by more than 1e-6
//! (relative), and the worst cases.

use std::collections::BTreeMap;

use rtcnc_motion::otg::{
    Limits, State, position_profile, synchronize, synchronize_on_period, synchronize_straight,
    synchronize_velocity, velocity_profile,
};
use serde_json::Value;

fn f(v: &Value, key: &str) -> f64 {
    v[key].as_f64().unwrap_or(f64::NAN)
}

fn limits_of(v: &Value) -> Limits {
    Limits {
        max_velocity: f(v, "vmax"),
        min_velocity: f(v, "vmin"),
        max_acceleration: f(v, "amax"),
        min_acceleration: f(v, "amin"),
        max_jerk: f(v, "jmax"),
    }
}

fn main() {
    let path = std::env::args()
        .nth(1)
        .expect("usage: otg_compare CASES.json");
    let text = std::fs::read_to_string(&path).expect("readable case file");
    let doc: Value = serde_json::from_str(&text).expect("JSON case file");
    let mut stats: BTreeMap<String, (usize, usize, Vec<String>)> = BTreeMap::new();
    for (i, c) in doc["cases"].as_array().into_iter().flatten().enumerate() {
        let kind = c["kind"].as_str().unwrap_or("?").to_string();
        let start = State::new(f(c, "p0"), f(c, "v0"), f(c, "a0"));
        let limits = limits_of(c);
        let result = if c.get("pf").is_some() {
            position_profile(
                start,
                State::new(f(c, "pf"), f(c, "vf"), f(c, "af")),
                &limits,
            )
        } else {
            velocity_profile(start, f(c, "vf"), f(c, "af"), &limits)
        };
        let want = f(c, "duration");
        let entry = stats.entry(kind.clone()).or_default();
        entry.0 += 1;
        let bad = match result {
            Ok(p) => {
                let rel = (p.duration() - want) / want;
                (rel.abs() > 1e-6)
                    .then(|| format!("#{i}: {} vs {want} (rel {rel:+.2e})", p.duration()))
            }
            Err(e) => Some(format!("#{i}: {e}")),
        };
        if let Some(line) = bad {
            entry.1 += 1;
            entry.2.push(line);
        }
    }
    let sync_cases = doc["sync3"].as_array().into_iter().flatten();
    let straight_cases = doc["straight3"].as_array().into_iter().flatten();
    for (i, c) in sync_cases.chain(straight_cases).enumerate() {
        let arr = |key: &str| -> [f64; 3] {
            std::array::from_fn(|k| c[key][k].as_f64().unwrap_or(f64::NAN))
        };
        let (p0, v0, a0, pf, vf, af) = (
            arr("p0"),
            arr("v0"),
            arr("a0"),
            arr("pf"),
            arr("vf"),
            arr("af"),
        );
        let start: [State; 3] = std::array::from_fn(|k| State::new(p0[k], v0[k], a0[k]));
        let target: [State; 3] = std::array::from_fn(|k| State::new(pf[k], vf[k], af[k]));
        let limits: [Limits; 3] = std::array::from_fn(|k| limits_of(&c["limits"][k]));
        let want = f(c, "duration");
        let kind = c["kind"].as_str().unwrap_or("sync3").to_string();
        let entry = stats.entry(kind).or_default();
        entry.0 += 1;
        let result = match (c["period"].as_f64(), c["kind"].as_str()) {
            (_, Some("straight3")) => synchronize_straight(&start, &target, &limits),
            (Some(period), _) => synchronize_on_period(&start, &target, &limits, period),
            (None, _) => synchronize(&start, &target, &limits),
        };
        let bad = match result {
            Ok(s) => {
                let rel = (s.duration() - want) / want;
                (rel.abs() > 1e-6)
                    .then(|| format!("#{i}: {} vs {want} (rel {rel:+.2e})", s.duration()))
            }
            Err(e) => Some(format!("#{i}: {e}")),
        };
        if let Some(line) = bad {
            entry.1 += 1;
            entry.2.push(line);
        }
    }
    for (i, c) in doc["vsync3"].as_array().into_iter().flatten().enumerate() {
        let arr = |key: &str| -> [f64; 3] {
            std::array::from_fn(|k| c[key][k].as_f64().unwrap_or(f64::NAN))
        };
        let (v0, a0, vf, af) = (arr("v0"), arr("a0"), arr("vf"), arr("af"));
        let start: [State; 3] = std::array::from_fn(|k| State::new(0.0, v0[k], a0[k]));
        let limits: [Limits; 3] = std::array::from_fn(|k| limits_of(&c["limits"][k]));
        let want = f(c, "duration");
        let entry = stats.entry("vsync3".to_string()).or_default();
        entry.0 += 1;
        let bad = match synchronize_velocity(&start, &vf, &af, &limits) {
            Ok(s) => {
                let rel = (s.duration() - want) / want;
                (rel.abs() > 1e-6)
                    .then(|| format!("#{i}: {} vs {want} (rel {rel:+.2e})", s.duration()))
            }
            Err(e) => Some(format!("#{i}: {e}")),
        };
        if let Some(line) = bad {
            entry.1 += 1;
            entry.2.push(line);
        }
    }
    for (kind, (n, bad, lines)) in &stats {
        println!("{kind:12} {n:6} cases, {bad:4} differ from ruckig by more than 1e-6");
        for line in lines.iter().take(8) {
            println!("    {line}");
        }
    }
}
