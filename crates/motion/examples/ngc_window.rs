//! Diagnosis: lines A..B of a G0/G1 program (absolute XYZ, F per minute, G20 scaled to mm)
//! through the planner alone on the benchmark machine (100 mm/s, 1000 mm/s², 50 000 mm/s³,
//! 1 ms, a window of 256 pieces as the kernel's), in G64 P Q (mm), fed as the window frees.
//! Prints the run's time, the largest v/a/j of the set-points over the limits and the
//! counters; a whole CAM program takes about a second (`rtcnc sim` takes a few).
//!
//!   ngc_window FILE A B P [Q]      (Q defaults to P; plain G64 in the kernel: Q = 0)
//!
//! Environment: PIECES=1 the window's pieces after the first push (kind, line, start,
//! length, braking curve and speed bounds at the samples, curvature); LINES=1 the time and
//! lowest speed per program line; TRACE=A-B every period on lines A..B; WINDOW=n pieces;
//! JERK=j the axes' jerk limit (mm/s³, default 50 000).
#![allow(clippy::needless_range_loop)]
use rtcnc_motion::*;
fn main() {
    let a: Vec<String> = std::env::args().collect();
    let text = std::fs::read_to_string(&a[1]).unwrap();
    let (from, to): (usize, usize) = (a[2].parse().unwrap(), a[3].parse().unwrap());
    let p: f64 = a[4].parse().unwrap();
    let q: f64 = a.get(5).map_or(p, |x| x.parse().unwrap());
    let jerk: f64 = std::env::var("JERK")
        .ok()
        .and_then(|j| j.parse().ok())
        .unwrap_or(50_000.0);
    let lim = AxisLimits::new(100.0, 1000.0, jerk, -1000.0, 1000.0);
    let machine = MachineLimits::uniform(&[Axis::X, Axis::Y, Axis::Z], lim);
    let kin = TrivialKinematics::identity(&[Axis::X, Axis::Y, Axis::Z]);
    let inch = text.contains("G20");
    let unit = if inch { 25.4 } else { 1.0 };
    let p = p * unit;
    let q = q * unit;
    let mut pos = [0.0; AXES];
    let mut feed = 10.0;
    let mut rapid = true;
    let mut moves = Vec::new();
    let mut start = None;
    for (i, l) in text.lines().enumerate() {
        let n = i + 1;
        let code = l.split('(').next().unwrap();
        let mut e = pos;
        let mut any = false;
        for w in code.split_whitespace() {
            let v: f64 = w[1..].parse().unwrap_or(0.0);
            let vu = v * unit;
            match &w[..1] {
                "X" => {
                    e[0] = vu;
                    any = true
                }
                "Y" => {
                    e[1] = vu;
                    any = true
                }
                "Z" => {
                    e[2] = vu;
                    any = true
                }
                "F" => feed = vu / 60.0,
                "G" if v == 0.0 => rapid = true,
                "G" if v == 1.0 => rapid = false,
                _ => {}
            }
        }
        if !any {
            continue;
        }
        if n >= from && n <= to {
            if start.is_none() {
                start = Some(pos);
            }
            let mode = PathMode::Blend {
                tolerance: p,
                merge_tolerance: q,
            };
            if e != pos {
                moves.push(if rapid {
                    Move::rapid(e, mode, n as u32)
                } else {
                    Move::line(e, feed, mode, n as u32)
                });
            }
        }
        pos = e;
    }
    let mut pl = Planner::new(
        &machine,
        kin,
        1e-3,
        std::env::var("WINDOW").map_or(256, |w| w.parse().unwrap()),
        start.unwrap(),
    )
    .unwrap();
    let mut next_move = pl.push_all(&moves).unwrap();
    if next_move == moves.len() {
        pl.flush();
    }
    if std::env::var("PIECES").is_ok() {
        for l in pl.debug_pieces() {
            println!("{l}");
        }
    }
    let mut j = [0.0; 3];
    let mut per = std::collections::BTreeMap::<u32, (u32, f64)>::new();
    let mut total = 0;
    let mut hist: Vec<[f64; 3]> = Vec::new();
    let mut worst = [0.0f64; 3];
    loop {
        if next_move < moves.len() {
            next_move += pl.push_all(&moves[next_move..]).unwrap();
            if next_move == moves.len() {
                pl.flush();
            }
        }
        let st = pl.next(&mut j);
        if st.state == MotionState::Idle {
            break;
        }
        total += 1;
        hist.push([j[0], j[1], j[2]]);
        let n = hist.len();
        if n >= 4 {
            let h = &hist[n - 4..];
            for ax in 0..3 {
                let v = (h[3][ax] - h[2][ax]) / 1e-3;
                let a = (h[3][ax] - 2.0 * h[2][ax] + h[1][ax]) / 1e-6;
                let jj = (h[3][ax] - 3.0 * h[2][ax] + 3.0 * h[1][ax] - h[0][ax]) / 1e-9;
                worst[0] = worst[0].max(v.abs() / 100.0);
                worst[1] = worst[1].max(a.abs() / 1000.0);
                worst[2] = worst[2].max(jj.abs() / 50000.0);
            }
        }
        if let Ok(r) = std::env::var("TRACE") {
            let mut it = r.split('-').map(|x| x.parse::<u32>().unwrap());
            let (a, b) = (it.next().unwrap(), it.next().unwrap());
            if st.line >= a && st.line <= b {
                println!(
                    "t={total} line={} v={:.2} x={:.4} y={:.4}",
                    st.line, st.path_speed, st.axes[0], st.axes[1]
                );
            }
        }
        let e = per.entry(st.line).or_insert((0, f64::INFINITY));
        e.0 += 1;
        e.1 = e.1.min(st.path_speed);
    }
    if std::env::var("LINES").is_ok() {
        for (l, (n, v)) in &per {
            println!("line {l}: {n} ms, vmin {v:.1}");
        }
    }
    println!(
        "total {total} ms; v/a/j ratios {:.4} {:.4} {:.4}; {:?} {:?}",
        worst[0],
        worst[1],
        worst[2],
        pl.stats(),
        pl.geometry_stats()
    );
}
