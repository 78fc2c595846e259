//! Shrinks a failing move list (SPEC as in `stress`) to a smaller one that still exceeds a
//! limit: drops moves, then rounds coordinates and feeds. Usage: SPEC="..." shrink.
#![allow(clippy::needless_range_loop)]
use rtcnc_motion::*;

#[derive(Clone, Debug)]
struct M {
    e: [f64; 3],
    f: f64,
    mode: String,
    p: f64,
}

fn parse(spec: &str) -> Vec<M> {
    spec.split(';')
        .filter_map(|item| {
            let f: Vec<&str> = item.split_whitespace().collect();
            if f.len() < 5 {
                return None;
            }
            Some(M {
                e: [f[0].parse().ok()?, f[1].parse().ok()?, f[2].parse().ok()?],
                f: f[3].parse().ok()?,
                mode: f[4].to_string(),
                p: f.get(5).and_then(|x| x.parse().ok()).unwrap_or(0.0),
            })
        })
        .collect()
}

fn show(ms: &[M]) -> String {
    ms.iter()
        .map(|m| {
            let p = if m.mode == "B" {
                format!(" {}", m.p)
            } else {
                String::new()
            };
            format!("{} {} {} {} {}{}; ", m.e[0], m.e[1], m.e[2], m.f, m.mode, p)
        })
        .collect()
}

/// Worst ratio of |v|, |a|, |j| finite differences to the limits.
fn worst(ms: &[M]) -> f64 {
    let (vm, am, jm, t) = (100.0, 1000.0, 50_000.0, 1e-3);
    let lim = MachineLimits::uniform(
        &[Axis::X, Axis::Y, Axis::Z],
        AxisLimits::new(vm, am, jm, -1000.0, 1000.0),
    );
    let Ok(mut pl) = Planner::new(
        &lim,
        TrivialKinematics::identity(&[Axis::X, Axis::Y, Axis::Z]),
        t,
        256,
        [0.0; AXES],
    ) else {
        return 0.0;
    };
    for (n, m) in ms.iter().enumerate() {
        let mut e = [0.0; AXES];
        e[..3].copy_from_slice(&m.e);
        let mode = match m.mode.as_str() {
            "S" => PathMode::ExactStop,
            "E" => PathMode::ExactPath,
            _ => PathMode::Blend {
                tolerance: m.p,
                merge_tolerance: 0.0,
            },
        };
        if pl.push(&Move::line(e, m.f, mode, n as u32 + 1)).is_err() {
            return 0.0;
        }
    }
    pl.flush();
    let mut h = vec![[0.0; AXES]; 3];
    let mut j = [0.0; 3];
    let mut w = 0.0f64;
    for _ in 0..2_000_000 {
        let st = pl.next(&mut j);
        h.push(st.axes);
        let x = &h[h.len() - 4..];
        for i in 0..3 {
            let v = ((x[3][i] - x[2][i]) / t).abs() / vm;
            let a = ((x[3][i] - 2.0 * x[2][i] + x[1][i]) / (t * t)).abs() / am;
            let jj = ((x[3][i] - 3.0 * x[2][i] + 3.0 * x[1][i] - x[0][i]) / (t * t * t)).abs() / jm;
            w = w.max(v).max(a).max(jj);
        }
        if st.state == MotionState::Idle {
            break;
        }
    }
    w
}

fn main() {
    let mut ms = parse(&std::env::var("SPEC").expect("SPEC"));
    let mut best = worst(&ms);
    println!("start: {best:.3}");
    let ok = |w: f64| w > 1.0 + 1e-9;
    // Drop moves (keep the first move's start as the origin: dropping move 0 moves the start).
    let mut changed = true;
    while changed {
        changed = false;
        for i in (0..ms.len()).rev() {
            if ms.len() == 1 {
                break;
            }
            let mut c = ms.clone();
            c.remove(i);
            let w = worst(&c);
            if ok(w) {
                ms = c;
                best = w;
                changed = true;
            }
        }
    }
    // Round numbers to fewer digits.
    for digits in [0i32, 1, 2, 3, 4, 6] {
        let r = |x: f64| (x * 10f64.powi(digits)).round() / 10f64.powi(digits);
        for i in 0..ms.len() {
            for k in 0..4 {
                let mut c = ms.clone();
                if k < 3 {
                    if c[i].e[k] == r(c[i].e[k]) {
                        continue;
                    }
                    c[i].e[k] = r(c[i].e[k]);
                } else {
                    if c[i].f == r(c[i].f) {
                        continue;
                    }
                    c[i].f = r(c[i].f);
                }
                let w = worst(&c);
                if ok(w) {
                    ms = c;
                    best = w;
                }
            }
        }
    }
    println!("worst {best:.3}\nSPEC=\"{}\"", show(&ms));
}
