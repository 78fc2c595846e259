//! The shipped example programs run to their end on their machines, within every axis
//! limit, without faults.

use crate::common::*;
use rtcnc_kernel::report::RunStats;
use rtcnc_kernel::{Command, MachineState};

fn run_example(machine: &str, program: &str) -> (Machine, RunStats) {
    let cfg = config(machine);
    let mut m = Machine::new(&cfg, Some(repo().join("examples").join(program)));
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    let ended = m.until(120.0, |s| s.program_ended && s.state == MachineState::Idle);
    assert!(
        ended,
        "{program}: {:?} {:?}",
        m.faults,
        m.sim.handle().error_text()
    );
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    let mut stats = RunStats::new();
    let mut machine_stats = RunStats::for_machine(&cfg);
    for s in &m.samples {
        stats.add(s, cfg.servo_period().as_secs_f64());
        machine_stats.add(s, cfg.servo_period().as_secs_f64());
    }
    // Over the machine's own axes and joints the maxima are those over all, bit for bit.
    assert_eq!(machine_stats.max_velocity, stats.max_velocity);
    assert_eq!(machine_stats.max_acceleration, stats.max_acceleration);
    assert_eq!(machine_stats.max_jerk, stats.max_jerk);
    assert_eq!(machine_stats.max_following_error, stats.max_following_error);
    assert_eq!(machine_stats.max_tracking_error, stats.max_tracking_error);
    for p in cfg.axis_plan() {
        let a = cfg.axis(p.axis).unwrap();
        let i = p.axis as usize;
        let tol = 1.0 + 1e-6;
        assert!(
            stats.max_velocity[i] <= a.max_velocity * tol,
            "{:?} v",
            p.axis
        );
        assert!(
            stats.max_acceleration[i] <= a.max_acceleration * tol,
            "{:?} a",
            p.axis
        );
        assert!(
            stats.max_jerk[i] <= a.max_jerk * tol,
            "{:?} j {}",
            p.axis,
            stats.max_jerk[i]
        );
    }
    (m, stats)
}

#[test]
fn the_bracket_runs_on_the_mill_within_the_limits() {
    let (m, stats) = run_example("sim-mill.toml", "bracket.ngc");
    assert_eq!(&m.status().axes[..3], &[0.0, 0.0, 5.0]);
    assert_eq!(m.status().tool, 2);
    // The rapids reach the X limit; the servo loops follow within 20 µm.
    assert!(stats.max_velocity[0] > 99.9);
    assert!(stats.max_following_error[..3].iter().all(|&e| e < 0.02));
}

#[test]
fn the_shaft_runs_on_the_lathe_in_diameter_mode() {
    let (m, _) = run_example("sim-lathe.toml", "lathe-shaft.ngc");
    // Programmed X42 (a diameter) is 21 mm of cross-slide travel.
    let max_x = m.samples.iter().map(|s| s.axes[0]).fold(f64::MIN, f64::max);
    assert!((max_x - 21.0).abs() < 1e-9, "max X {max_x}");
    let min_z = m.samples.iter().map(|s| s.axes[2]).fold(f64::MAX, f64::min);
    assert!((min_z - -40.0).abs() < 1e-9, "min Z {min_z}");
}

#[test]
fn tool_length_and_cutter_radius_compensation_shape_the_path() {
    let dir = std::env::temp_dir().join(format!("rtcnc-tools-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let table = dir.join("tools.tbl");
    std::fs::write(&table, "T1 P1 Z+10.0 D6.0 ;6 mm cutter, 10 mm long\n").unwrap();
    let mut cfg = config("sim-mill.toml");
    cfg.files.tool_table = Some(table);
    // G43: Z-20 in the program is Z-10 on the machine with the 10 mm tool.
    // G41 on a 20 mm square traversed counter-clockwise: the cutter (radius 3) keeps to
    // the left, inside the square, so its centre never passes X17 or Y17.
    let text = "G21 G90 G61.1\nT1 M6\nG43 H1\nG0 X-4 Y-4 Z-20\nG41\nG1 X0 Y0 F600\nG1 X20\nG1 Y20\nG1 X0\nG1 Y0\nG40\nG1 X-4 Y-4\nM2\n";
    let mut m = Machine::started(&cfg, text, "comp.ngc");
    let ended = m.until(30.0, |s| s.program_ended && s.state == MachineState::Idle);
    assert!(
        ended,
        "{:?} {:?} {:?}",
        m.faults,
        m.sim.handle().error_text(),
        m.status()
    );
    assert!(
        m.faults.is_empty(),
        "{:?} {:?}",
        m.faults,
        m.sim.handle().error_text()
    );
    let max = |i: usize| m.samples.iter().map(|s| s.axes[i]).fold(f64::MIN, f64::max);
    let min_z = m.samples.iter().map(|s| s.axes[2]).fold(f64::MAX, f64::min);
    assert!((min_z - -10.0).abs() < 1e-12, "min Z {min_z}");
    assert!((max(0) - 17.0).abs() < 1e-9, "max X {}", max(0));
    assert!((max(1) - 17.0).abs() < 1e-9, "max Y {}", max(1));
}

#[test]
fn inch_programs_move_in_millimetres_on_the_machine() {
    let cfg = config("sim-mill.toml");
    let text = "G20 G90 G61.1\nG1 X1 Y0.5 F20\nM2\n";
    let mut m = Machine::started(&cfg, text, "inch.ngc");
    assert!(m.until(10.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert_eq!(&m.status().axes[..2], &[25.4, 12.7]);
    // F20 in/min along the diagonal: 20 × 25.4 / 60 mm/s.
    let top = m.samples.iter().map(|s| s.path_speed).fold(0.0, f64::max);
    assert!(
        (top - 20.0 * 25.4 / 60.0).abs() < 1e-3 * top,
        "path speed {top}"
    );
}

#[test]
fn the_thread_example_faces_at_constant_surface_speed_and_threads_on_the_lathe() {
    let (m, _) = run_example("sim-lathe.toml", "lathe-thread.ngc");
    // The facing cut reached the centre; the G76 passes went down to Z-22.
    let min = |i: usize| m.samples.iter().map(|s| s.axes[i]).fold(f64::MAX, f64::min);
    assert_eq!(min(0), 0.0);
    assert_eq!(min(2), -30.0);
    let thread_end = m
        .samples
        .iter()
        .filter(|s| s.line == 21)
        .map(|s| s.axes[2])
        .fold(f64::MAX, f64::min);
    assert_eq!(thread_end, -22.0);
}

/// Bernstein basis of degree `d` at t.
fn bernstein(d: usize, t: f64) -> Vec<f64> {
    let binom = |n: usize, k: usize| (0..k).fold(1.0, |b, i| b * (n - i) as f64 / (i + 1) as f64);
    (0..=d)
        .map(|k| binom(d, k) * t.powi(k as i32) * (1.0 - t).powi((d - k) as i32))
        .collect()
}

/// Control points of the Bézier curve of degree `d` through `pts` at parameters `ts`
/// (least squares: normal equations, Gaussian elimination with pivoting).
#[allow(clippy::needless_range_loop)] // matrix code reads best with indices
fn fit_bezier(d: usize, ts: &[f64], pts: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let n = d + 1;
    let mut m = vec![vec![0.0; n + 3]; n];
    for (t, p) in ts.iter().zip(pts) {
        let b = bernstein(d, *t);
        for r in 0..n {
            for c in 0..n {
                m[r][c] += b[r] * b[c];
            }
            for i in 0..3 {
                m[r][n + i] += b[r] * p[i];
            }
        }
    }
    for col in 0..n {
        let piv = (col..n)
            .max_by(|a, b| m[*a][col].abs().partial_cmp(&m[*b][col].abs()).unwrap())
            .unwrap();
        m.swap(col, piv);
        for r in 0..n {
            if r != col {
                let f = m[r][col] / m[col][col];
                for c in col..n + 3 {
                    m[r][c] -= f * m[col][c];
                }
            }
        }
    }
    (0..n)
        .map(|r| [0, 1, 2].map(|i| m[r][n + i] / m[r][r]))
        .collect()
}

/// The curve at t (de Casteljau).
#[allow(clippy::needless_range_loop)]
fn on_bezier(ctrl: &[[f64; 3]], t: f64) -> [f64; 3] {
    let mut q = [[0.0; 3]; 4];
    q[..ctrl.len()].copy_from_slice(ctrl);
    for level in (1..ctrl.len()).rev() {
        for k in 0..level {
            for i in 0..3 {
                q[k][i] = (1.0 - t) * q[k][i] + t * q[k + 1][i];
            }
        }
    }
    q[0]
}

/// Distance of `p` from the curve: nearest parameter on a grid, refined by bisection on
/// the derivative of the squared distance.
fn distance_to_bezier(ctrl: &[[f64; 3]], p: &[f64]) -> f64 {
    let d2 = |t: f64| {
        let q = on_bezier(ctrl, t);
        (0..3).map(|i| (q[i] - p[i]).powi(2)).sum::<f64>()
    };
    let n = 200;
    let k = (0..=n)
        .min_by(|a, b| {
            d2(*a as f64 / n as f64)
                .partial_cmp(&d2(*b as f64 / n as f64))
                .unwrap()
        })
        .unwrap();
    let (mut lo, mut hi) = (
        (k as f64 - 1.0).max(0.0) / n as f64,
        (k as f64 + 1.0).min(n as f64) / n as f64,
    );
    for _ in 0..80 {
        let (a, b) = (lo + (hi - lo) / 3.0, hi - (hi - lo) / 3.0);
        if d2(a) < d2(b) {
            hi = b;
        } else {
            lo = a;
        }
    }
    d2(0.5 * (lo + hi)).sqrt()
}

#[test]
fn splines_run_on_linuxcncs_curves_to_the_exact_end() {
    let (m, _) = run_example("sim-mill.toml", "gcode/splines.ngc");
    assert_eq!(&m.status().axes[..3], &[80.0, 10.0, 5.0]);
    // LinuxCNC's reference (tests/data, see linuxcnc_splines.py): its points per line, and
    // rs274's canonical stream for the order of each NURBS it builds (4 for G5, 3 for G5.1).
    let data = repo().join("crates/kernel/tests/data");
    let text = std::fs::read_to_string(data.join("splines.linuxcnc")).unwrap();
    let points: Vec<(u32, [f64; 3])> = text
        .lines()
        .map(|l| {
            let w: Vec<&str> = l.split_whitespace().collect();
            let f = |i: usize| w[i].parse::<f64>().unwrap();
            (w[0].parse().unwrap(), [f(1), f(2), f(3)])
        })
        .collect();
    let canon = std::fs::read_to_string(data.join("splines.rs274.canon")).unwrap();
    let orders: Vec<usize> = canon
        .lines()
        .filter_map(|l| l.strip_prefix("NURBS_FEED("))
        .map(|l| l.split(',').next().unwrap().parse().unwrap())
        .collect();
    assert_eq!(orders, [4, 4, 3, 3]);
    let mut curves = Vec::new();
    for (line, order) in (8..=11).zip(orders) {
        // The curve starts where the move before it ended; its points are at t = i/n.
        let first = points.iter().position(|(l, _)| *l == line).unwrap();
        let pts: Vec<[f64; 3]> = points[first - 1..]
            .iter()
            .take_while(|(l, _)| *l <= line)
            .map(|(_, p)| *p)
            .collect();
        let n = pts.len() - 1;
        let ts: Vec<f64> = (0..=n).map(|i| i as f64 / n as f64).collect();
        let ctrl = fit_bezier(order - 1, &ts, &pts);
        // The fit is exact: LinuxCNC's points lie on it to rounding.
        for (t, p) in ts.iter().zip(&pts) {
            let q = on_bezier(&ctrl, *t);
            assert!(
                (0..3).all(|i| (q[i] - p[i]).abs() < 1e-9),
                "line {line}: fit"
            );
        }
        curves.push((line, ctrl));
    }
    // Every set-point the machine was given on these lines lies on LinuxCNC's curve of its
    // line (or of the neighbouring one, for a set-point that crossed a junction in the
    // period its line was reported), but near the junctions: they are tangent and the
    // curvature steps there, which G64 P0.01 blends within P (docs/motion.md), trimming
    // each side by at most 45 % of the curve (under 5 mm here).
    let junctions = [
        [10.0, 0.0],
        [30.0, 10.0],
        [50.0, 0.0],
        [60.0, 5.0],
        [70.0, 10.0],
    ];
    let near_junction = |p: &[f64]| {
        junctions
            .iter()
            .any(|j| (p[0] - j[0]).hypot(p[1] - j[1]) < 5.0)
    };
    let mut checked = 0;
    for s in &m.samples {
        let Some(k) = curves.iter().position(|(l, _)| *l == s.line) else {
            continue;
        };
        let d = (k.saturating_sub(1)..(k + 2).min(curves.len()))
            .map(|j| distance_to_bezier(&curves[j].1, &s.axes[..3]))
            .fold(f64::INFINITY, f64::min);
        let d = if k == 0 {
            // The first spline follows a line along Y = 0 (set-points still on it).
            d.min(s.axes[1].abs() + (s.axes[2] + 1.0).abs())
        } else if k == curves.len() - 1 && s.axes[0] >= 70.0 {
            // The last one is followed by a line along Y = 10.
            d.min((s.axes[1] - 10.0).abs() + (s.axes[2] + 1.0).abs())
        } else {
            d
        };
        let allowed = if near_junction(&s.axes) { 0.01 } else { 1e-9 };
        assert!(
            d <= allowed,
            "line {}: set-point {:?} is {d} mm off",
            s.line,
            &s.axes[..3]
        );
        checked += usize::from(allowed < 0.01);
    }
    assert!(checked > 100, "{checked} set-points exactly on the splines");
}

#[test]
fn a_spline_in_inches_in_a_rotated_work_system_is_the_transformed_curve() {
    // G54 at X0.5 Y0.2 in, rotated 30°: machine = rotate(program) + offset, in mm. A Bézier
    // curve maps to the Bézier curve of the mapped control points.
    let text = "G20 G90 G17 G61\nG10 L2 P1 X0.5 Y0.2 R30\nG54 G0 X0 Y0\n\
                G1 X0.4 F20\nG5 I0.2 J0 P-0.2 Q0 X1.0 Y0.4\nM2\n";
    let cfg = config("sim-mill.toml");
    let mut m = Machine::started(&cfg, text, "inch-spline.ngc");
    assert!(
        m.until(60.0, |s| s.program_ended && s.state == MachineState::Idle),
        "{:?} {:?}",
        m.faults,
        m.sim.handle().error_text()
    );
    let (s30, c30) = 30f64.to_radians().sin_cos();
    let machine = |x: f64, y: f64| {
        [
            (c30 * x - s30 * y + 0.5) * 25.4,
            (s30 * x + c30 * y + 0.2) * 25.4,
            0.0,
        ]
    };
    let ctrl = [
        machine(0.4, 0.0),
        machine(0.6, 0.0),
        machine(0.8, 0.4),
        machine(1.0, 0.4),
    ];
    let mut on_spline = 0;
    for s in m.samples.iter().filter(|s| s.line == 5) {
        let d = distance_to_bezier(&ctrl, &s.axes[..3]);
        assert!(d <= 1e-9, "set-point {:?} is {d} mm off", &s.axes[..3]);
        on_spline += 1;
    }
    assert!(on_spline > 100, "{on_spline}");
    let end = m.status().axes;
    assert!(
        (0..2).all(|i| (end[i] - ctrl[3][i]).abs() <= 1e-9),
        "{end:?}"
    );
}
