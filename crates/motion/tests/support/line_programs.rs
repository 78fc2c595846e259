//! The random line programs of the `stress` example (one to eight lines in three path modes,
//! feeds 5-150 mm/s, blend tolerances 0.001-0.1 mm) and their random on-line changes, and
//! the `x y z feed mode [P];` form they are printed in. Shared with `tests/online_changes.rs`
//! (included with `#[path]`), so that a seed names the same programs everywhere.
#![allow(dead_code)]

use rtcnc_motion::{AXES, Move, PathMode};

/// Linear congruential generator: uniform in [0, 1).
pub struct Lcg(pub u64);

impl Lcg {
    pub fn f(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn blend(tolerance: f64) -> PathMode {
    PathMode::Blend {
        tolerance,
        merge_tolerance: 0.0,
    }
}

/// One random program from the origin, with its `x y z feed mode [P];` form.
pub fn random_lines(rng: &mut Lcg) -> (String, Vec<Move>) {
    let k = 1 + (rng.f() * 8.0) as usize;
    let mut spec = String::new();
    let mut moves = Vec::new();
    let mut pos = [0.0; AXES];
    for i in 0..k {
        let mut e = [0.0; AXES];
        for c in e.iter_mut().take(3) {
            *c = rng.f() * 40.0 - 20.0;
        }
        if rng.f() < 0.3 {
            e[2] = pos[2];
        }
        let feed = 5.0 + rng.f() * 145.0;
        let r = rng.f();
        let (mode, ms) = if r < 0.2 {
            (PathMode::ExactStop, "S".to_string())
        } else if r < 0.4 {
            (PathMode::ExactPath, "E".to_string())
        } else {
            let p = [0.001, 0.01, 0.1][(rng.f() * 3.0) as usize % 3];
            (blend(p), format!("B {p}"))
        };
        spec += &format!("{} {} {} {} {}; ", e[0], e[1], e[2], feed, ms);
        moves.push(Move::line(e, feed, mode, i as u32 + 1));
        pos = e;
    }
    (spec, moves)
}

/// An on-line change, applied before the servo period it is listed with.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Change {
    Override(f64),
    Hold,
    Resume,
    QuickStop,
}

/// The changes the `stress` example makes with `STRESS_ONLINE`, drawn after the program: a
/// feed override (20-170 %), a hold and its resume 300 periods later, and in one program of
/// ten a quick stop.
pub fn random_changes(rng: &mut Lcg) -> Vec<(usize, Change)> {
    let p_ovr = 30 + (rng.f() * 600.0) as usize;
    let ovr = 0.2 + rng.f() * 1.5;
    let p_hold = 30 + (rng.f() * 900.0) as usize;
    let mut changes = vec![
        (p_ovr, Change::Override(ovr)),
        (p_hold, Change::Hold),
        (p_hold + 300, Change::Resume),
    ];
    if rng.f() < 0.1 {
        changes.push((30 + (rng.f() * 1500.0) as usize, Change::QuickStop));
    }
    changes
}

/// Lines from the origin written as `x y z feed mode [P];` (mode `S` exact stop, `E` exact
/// path, `B P` blend with tolerance P).
pub fn parse_spec(spec: &str) -> Vec<Move> {
    spec.split(';')
        .filter(|m| !m.trim().is_empty())
        .enumerate()
        .map(|(i, m)| {
            let w: Vec<&str> = m.split_whitespace().collect();
            let x: Vec<f64> = w[..4].iter().map(|v| v.parse().unwrap()).collect();
            let mode = match w[4] {
                "S" => PathMode::ExactStop,
                "E" => PathMode::ExactPath,
                _ => blend(w[5].parse().unwrap()),
            };
            let mut e = [0.0; AXES];
            e[..3].copy_from_slice(&x[..3]);
            Move::line(e, x[3], mode, i as u32 + 1)
        })
        .collect()
}
