//! A debugging tool: prints the planner's look-ahead window (piece lengths, speed bounds)
//! for a program.
#![allow(clippy::needless_range_loop)]
use rtcnc_motion::*;
fn main() {
    let lim = AxisLimits::new(100.0, 1000.0, 50_000.0, -1000.0, 1000.0);
    let machine = MachineLimits::uniform(&[Axis::X, Axis::Y, Axis::Z], lim);
    let kin = TrivialKinematics::identity(&[Axis::X, Axis::Y, Axis::Z]);
    let mut start = [0.0; AXES];
    if let Some(l) = std::fs::read_to_string(std::env::args().nth(1).unwrap())
        .unwrap()
        .lines()
        .find(|l| l.starts_with("G0 "))
    {
        for w in l.split_whitespace() {
            let v: f64 = w[1..].parse().unwrap_or(0.0);
            match &w[..1] {
                "X" => start[0] = v,
                "Y" => start[1] = v,
                "Z" => start[2] = v,
                _ => {}
            }
        }
    }
    let mut pl = Planner::new(&machine, kin, 1e-3, 4096, start).unwrap();
    let text = std::fs::read_to_string(std::env::args().nth(1).unwrap()).unwrap();
    let mut n = 0;
    for l in text.lines().filter(|l| l.starts_with("G1 ")) {
        let mut e = [0.0; AXES];
        for w in l.split_whitespace() {
            let v: f64 = w[1..].parse().unwrap_or(0.0);
            match &w[..1] {
                "X" => e[0] = v,
                "Y" => e[1] = v,
                "Z" => e[2] = v,
                _ => {}
            }
        }
        pl.push(&Move::line(
            e,
            100.0,
            PathMode::Blend {
                tolerance: 0.001,
                merge_tolerance: 0.001,
            },
            n,
        ))
        .unwrap();
        n += 1;
        if n > 40 && std::env::args().nth(2).is_none() {
            break;
        }
    }
    if std::env::args().nth(2).as_deref() != Some("run") {
        let from: usize = std::env::args()
            .nth(3)
            .and_then(|x| x.parse().ok())
            .unwrap_or(0);
        for (i, (len, w, va, vc, kk)) in pl.debug_window().iter().enumerate().skip(from).take(30) {
            println!("{i} len={len:.4} w={w:.1?} vaxis={va:.1?} vcurve={vc:.1?} k={kk:.4?}");
        }
        return;
    }
    pl.flush();
    let mut j = [0.0; 3];
    let mut h = vec![[0.0; AXES]; 3];
    let t = 1e-3;
    for k in 0..20000 {
        let st = pl.next(&mut j);
        h.push(st.axes);
        let n = h.len();
        let w = &h[n - 4..];
        let mut s = String::new();
        for i in 0..2 {
            let v = (w[3][i] - w[2][i]) / t;
            let a = (w[3][i] - 2.0 * w[2][i] + w[1][i]) / (t * t);
            let jj = (w[3][i] - 3.0 * w[2][i] + 3.0 * w[1][i] - w[0][i]) / (t * t * t);
            s += &format!(" v={v:.2} a={a:.1} j={jj:.0}");
        }
        if k % 10 == 0 || std::env::var("ALL").is_ok() {
            println!(
                "{k} {:?} ps={:.3} line={} {s}",
                st.state, st.path_speed, st.line
            );
        }
        if st.state == MotionState::Idle {
            break;
        }
    }
    println!("{:?}", pl.stats());
}
#[allow(dead_code)]
fn unused() {}
