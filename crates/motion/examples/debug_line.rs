//! A debugging tool: runs one of a few hand-made programs (or `SPEC=...`) through the planner
//! and prints its statistics; `debug_window` dumps the window.
#![allow(clippy::needless_range_loop)]
use rtcnc_motion::*;

#[path = "../tests/support/line_programs.rs"]
mod line_programs;
use line_programs::parse_spec;

fn main() {
    let mut lim = AxisLimits::new(100.0, 1000.0, 50_000.0, -1000.0, 1000.0);
    if std::env::var("QUICK").is_ok() {
        lim.quick_stop_acceleration = 3000.0;
        lim.quick_stop_jerk = 200_000.0;
    }
    let machine = MachineLimits::uniform(&[Axis::X, Axis::Y, Axis::Z], lim);
    let kin = TrivialKinematics::identity(&[Axis::X, Axis::Y, Axis::Z]);
    let t = 1e-3;
    let mut pl = Planner::new(&machine, kin, t, 64, [0.0; AXES]).unwrap();
    #[allow(unused_assignments)]
    let which = std::env::args().nth(1).unwrap_or_default();
    let mode = PathMode::Blend {
        tolerance: std::env::var("P")
            .ok()
            .and_then(|p| p.parse().ok())
            .unwrap_or(0.01),
        merge_tolerance: 0.0,
    };
    let mut e = [0.0; AXES];
    if which == "spec" {
        // SPEC="x y z feed mode P; ..." with mode S (G61.1), E (G61) or B (G64 P).
        for m in parse_spec(&std::env::var("SPEC").unwrap()) {
            pl.push(&m).unwrap();
        }
    } else if which == "case3" {
        let pt = |x: f64, y: f64| {
            let mut e = [0.0; AXES];
            e[0] = x;
            e[1] = y;
            e
        };
        let p3: f64 = std::env::var("P3")
            .ok()
            .and_then(|x| x.parse().ok())
            .unwrap_or(0.001);
        let f3: f64 = std::env::var("F3")
            .ok()
            .and_then(|x| x.parse().ok())
            .unwrap_or(5.0);
        pl.push(&Move::line(
            pt(-12.169652098472351, 17.75586651294959),
            5.0,
            PathMode::ExactStop,
            1,
        ))
        .unwrap();
        pl.push(&Move::line(
            pt(0.0, 7.2583090811502835),
            141.60641655360988,
            PathMode::Blend {
                tolerance: p3,
                merge_tolerance: 0.0,
            },
            2,
        ))
        .unwrap();
        pl.push(&Move::line(
            pt(15.105943779691847, 6.863001365966919),
            f3,
            PathMode::ExactStop,
            3,
        ))
        .unwrap();
    } else if which == "arc2" {
        let envf = |k: &str, d: f64| {
            std::env::var(k)
                .ok()
                .and_then(|x| x.parse().ok())
                .unwrap_or(d)
        };
        let r: f64 = envf("R", 0.38337396818471536);
        let (cx, cy) = (0.0, envf("CY", r));
        let a0 = (0.0 - cy).atan2(0.0 - cx);
        let a1 = a0 + envf("SWEEP", 4.89908394343943);
        let mut end = [0.0; AXES];
        end[0] = cx + r * a1.cos();
        end[1] = cy + r * a1.sin();
        pl.push(&Move::arc(
            end,
            [cx, cy, 0.0],
            [0.0, 0.0, 1.0],
            0,
            68.29212730038314,
            PathMode::ExactStop,
            1,
        ))
        .unwrap();
    } else if which == "arc" {
        e[0] = 5.0;
        pl = Planner::new(
            &machine,
            TrivialKinematics::identity(&[Axis::X, Axis::Y, Axis::Z]),
            t,
            64,
            e,
        )
        .unwrap();
        pl.push(&Move::arc(
            e,
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 1.0],
            1,
            200.0,
            PathMode::ExactStop,
            1,
        ))
        .unwrap();
    } else if which == "square" {
        for (x, y) in [(10.0, 0.0), (10.0, 10.0), (0.0, 10.0), (0.0, 0.0)] {
            e[0] = x;
            e[1] = y;
            pl.push(&Move::line(e, 100.0, mode, 1)).unwrap();
        }
    } else {
        e[0] = std::env::var("L")
            .ok()
            .and_then(|x| x.parse().ok())
            .unwrap_or(20.0);
        pl.push(&Move::line(e, 100.0, mode, 1)).unwrap();
    }
    pl.flush();
    let mut j = [0.0; 3];
    let mut h = vec![[0.0; AXES]; 3];
    let hold_at: usize = std::env::var("HOLD")
        .ok()
        .and_then(|x| x.parse().ok())
        .unwrap_or(usize::MAX);
    for k in 0..20000 {
        if k == 150 && std::env::var("FO").is_ok() {
            pl.set_feed_override(0.5);
        }
        if k == 400 && std::env::var("FO").is_ok() {
            pl.set_feed_override(1.7);
        }
        if k == hold_at {
            if std::env::var("QUICK").is_ok() {
                pl.quick_stop()
            } else {
                pl.hold()
            }
        }
        let st = pl.next(&mut j);
        h.push(st.axes);
        let n = h.len();
        let w = &h[n - 4..];
        let v = (w[3][0] - w[2][0]) / t;
        let a = (w[3][0] - 2.0 * w[2][0] + w[1][0]) / (t * t);
        let jj = (w[3][0] - 3.0 * w[2][0] + 3.0 * w[1][0] - w[0][0]) / (t * t * t);
        let vy = (w[3][1] - w[2][1]) / t;
        println!(
            "{k} {:?} x={:.6} y={:.6} v={v:.3} vy={vy:.3} a={a:.1} j={jj:.0} ps={:.3} line={}",
            st.state, st.axes[0], st.axes[1], st.path_speed, st.line
        );
        if st.state == MotionState::Idle {
            break;
        }
    }
    println!("{:?} {:?}", pl.stats(), pl.geometry_stats());
}
