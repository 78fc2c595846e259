//! A quick stop early in a rapid from rest on a machine whose weakest axis (here Z, which
//! does not move) has the lowest quick-stop limits: found by the kernel fuzz target
//! (fuzz/defects/kernel/estop-in-a-rapids-first-70ms). The stop's last periods could not
//! land on the stop point with the weakest axis's jerk; each dead end rolled the stop back
//! and the path went on for up to 0.4 s. Swept over every period of the rapid, after going
//! back over a set-point lead as the kernel does.

use crate::common::*;
use rtcnc_motion::{Axis, AxisLimits, MachineLimits, Move, PathMode};

const LEAD: usize = 50;

/// configs/sim-mill.toml's axes.
fn mill() -> MachineLimits {
    let mut xy = AxisLimits::new(100.0, 1000.0, 50_000.0, -1000.0, 1000.0);
    xy.quick_stop_acceleration = 2000.0;
    xy.quick_stop_jerk = 100_000.0;
    let mut lim = MachineLimits::uniform(&[Axis::X, Axis::Y, Axis::Z], xy);
    let mut z = AxisLimits::new(50.0, 800.0, 40_000.0, -100.0, 5.0);
    z.quick_stop_acceleration = 1600.0;
    z.quick_stop_jerk = 80_000.0;
    lim.axes[2] = Some(z);
    lim
}

#[test]
fn a_quick_stop_anywhere_in_a_rapid_stands_within_its_closed_form_time() {
    // The path brakes with the weakest axis's quick-stop limits (Z: 1600 mm/s², 80 000
    // mm/s³), less the stop model's margins (97 % and 90 %, and 99 % of a straight line's).
    let a = 0.97 * 0.99 * 1600.0;
    let j = 0.9 * 0.99 * 80_000.0;
    // Every period of the 14 mm rapid, which ends after about 0.2 s.
    for k in 5..260 {
        let mut pl = planner(&mill(), p3(0.0, 0.0, 0.0), 256).with_history(LEAD + 8);
        let mut joints = [0.0; 3];
        let mut pts = vec![p3(0.0, 0.0, 0.0); 3];
        pl.push(&Move::rapid(p3(10.0, 10.0, 0.0), PathMode::ExactStop, 1))
            .unwrap();
        pl.flush();
        for _ in 0..k + LEAD - 1 {
            pts.push(pl.next(&mut joints).axes);
        }
        pl.unemit(LEAD - 1).unwrap();
        pts.truncate(k + 3);
        // The path's speed and acceleration at the request, from the last set-points.
        let n = pts.len();
        let speed = |i: usize| {
            (0..2)
                .map(|ax| (pts[i][ax] - pts[i - 1][ax]).powi(2))
                .sum::<f64>()
                .sqrt()
                / T
        };
        let (v0, a0) = (speed(n - 1), (speed(n - 1) - speed(n - 2)) / T);
        pl.quick_stop();
        for _ in 0..2000 {
            pts.push(pl.next(&mut joints).axes);
        }
        // Closed form: release the acceleration (the speed grows meanwhile), then a
        // jerk-limited stop; plus the landing's few periods.
        let a0 = a0.max(0.0);
        let v1 = v0 + a0 * a0 / (2.0 * j);
        let bound = a0 / j + v1 / a + a / j + 8.0 * T;
        let last_move = pts.windows(2).rposition(|w| w[1] != w[0]).unwrap() + 1;
        let took = last_move.saturating_sub(k + 3) as f64 * T;
        assert!(
            took <= bound,
            "stop at {k} ms (v {v0:.1} mm/s, a {a0:.0} mm/s²) took {took:.3} s, bound {bound:.3} s"
        );
        let tr = Trace {
            pts,
            states: Vec::new(),
            speed: Vec::new(),
        };
        // Within X's and Y's quick-stop limits.
        assert_limits(&tr, 100.0, 2000.0, 100_000.0);
        assert_eq!(pl.stats().limit_violations, 0, "stop at {k} ms");
    }
}
