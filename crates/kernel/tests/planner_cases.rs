//! Programs that showed planner defects when run as a user would (the cases of the
//! project's defect list, copied into `data/cases/`): each runs to its end within every
//! axis's limits.

use crate::common::*;
use rtcnc_kernel::{Command, MachineState, Sample};

/// Largest |v|, |a|, |j| of the axis set-points over their limits (finite differences at
/// the servo period, as the planner checks them).
fn worst_ratio(samples: &[Sample], period: f64, limits: &[(f64, f64, f64)]) -> f64 {
    let mut worst: f64 = 0.0;
    for w in samples.windows(4) {
        for (i, &(v, a, j)) in limits.iter().enumerate() {
            let x: Vec<f64> = w.iter().map(|s| s.axes[i]).collect();
            let d1 = (x[3] - x[2]) / period;
            let d2 = (x[3] - 2.0 * x[2] + x[1]) / (period * period);
            let d3 = (x[3] - 3.0 * x[2] + 3.0 * x[1] - x[0]) / (period * period * period);
            worst = worst.max(d1.abs() / v).max(d2.abs() / a).max(d3.abs() / j);
        }
    }
    worst
}

/// Runs a case on a machine of `configs/` until the program ends (at most `limit_s` of
/// machine time); the samples.
fn run_case(config_name: &str, case: &str, limit_s: f64) -> Vec<Sample> {
    let cfg = config(config_name);
    let text = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/cases")
            .join(case),
    )
    .unwrap();
    let mut m = Machine::new(&cfg, Some(program(&text, case)));
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    let ended = m.until(limit_s, |s| {
        s.program_ended && s.state == MachineState::Idle
    });
    assert!(m.faults.is_empty(), "{case}: {:?}", m.faults);
    assert!(ended, "{case}: did not end within {limit_s} s");
    m.samples
}

/// Twelve 1800 mm rapids (10.8 km of path), then a polyline: the machine came to rest at
/// the end of the last rapid and never moved again (the end of a stop piece was missed by
/// the rounding of path positions counted from the program start), and each rapid beyond
/// about 400 mm from the origin exceeded the jerk limit 8 × while braking.
#[test]
fn long_path_stall_runs_to_its_end_within_the_limits() {
    let samples = run_case("bench-xyz.toml", "long-path-stall.ngc", 400.0);
    let worst = worst_ratio(&samples, 1e-3, &[(100.0, 1000.0, 50_000.0); 3]);
    assert!(worst <= 1.0 + 1e-9, "{worst}");
    let last = samples.last().unwrap().axes;
    // The program's last point.
    assert!(
        (last[0] + 8.6521).abs() < 1e-9 && (last[1] + 5.0141).abs() < 1e-9,
        "{last:?}"
    );
}

/// A G2 whose end radius is 0.5 µm longer than its start radius (CAM output rounded to four
/// decimals): the interpreter accepted it and the planner refused it ("arc radius
/// mismatch"). It runs as LinuxCNC runs it: a spiral whose radius grows linearly with the
/// angle from 10 to 10.0005 mm over the quarter turn.
#[test]
fn an_arc_with_a_half_micron_radius_difference_runs_as_a_spiral() {
    let samples = run_case("sim-mill.toml", "arc-radius-0.5um.ngc", 10.0);
    let limits = [
        (100.0, 1000.0, 50_000.0),
        (100.0, 1000.0, 50_000.0),
        (50.0, 800.0, 40_000.0),
    ];
    let worst = worst_ratio(&samples, 1e-3, &limits);
    assert!(worst <= 1.0 + 1e-9, "{worst}");
    // G2 X10 Y10.0005 I10 J0 from the origin: centre (10, 0), clockwise from the angle π
    // to π/2. Its end meets the line tangentially with a curvature step, which G64 P0.01
    // blends: up to half a radian from the arc's end (the longest trim of an arc end,
    // docs/motion.md) the path is within P of the spiral or the line; before, on it.
    let on_arc: Vec<_> = samples.iter().filter(|s| s.line == 3).collect();
    let mut exact = 0;
    for s in on_arc {
        let (x, y) = (s.axes[0] - 10.0, s.axes[1]);
        let swept = std::f64::consts::PI - y.atan2(x);
        let expected = 10.0 + 0.0005 * swept / std::f64::consts::FRAC_PI_2;
        let off_spiral = (x.hypot(y) - expected).abs();
        if swept <= std::f64::consts::FRAC_PI_2 - 0.5 {
            assert!(off_spiral <= 1e-9, "{:?}", s.axes);
            exact += 1;
        } else {
            let off_line = if x >= 0.0 {
                (y - 10.0005).abs()
            } else {
                f64::INFINITY
            };
            assert!(off_spiral.min(off_line) <= 0.01, "{:?}", s.axes);
        }
    }
    assert!(exact > 100, "{exact}");
    let last = samples.last().unwrap().axes;
    assert!((last[0] - 20.0).abs() < 1e-9 && (last[1] - 10.0005).abs() < 1e-9);
}

/// In an inch program the interpreter's tolerance is LinuxCNC's inch one (2·0.001·√2 in):
/// an arc whose radius grows by 0.0028 in (0.071 mm, more than the millimetre tolerance)
/// runs to its end, a spiral ending exactly at its end point.
#[test]
fn an_inch_arc_within_the_inch_tolerance_runs() {
    let cfg = config("sim-mill.toml");
    let text = "G20 G90 G17 G64 P0.0004\nF40\nG0 X0 Y0 Z0\nG2 X2.0028 Y0 I1 J0\nM2\n";
    let mut m = Machine::new(&cfg, Some(program(text, "inch-spiral.ngc")));
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    let ended = m.until(20.0, |s| s.program_ended && s.state == MachineState::Idle);
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    assert!(ended);
    let last = m.samples.last().unwrap().axes;
    assert!(
        (last[0] - 2.0028 * 25.4).abs() < 1e-9 && last[1].abs() < 1e-9,
        "{last:?}"
    );
}

/// RS274/NGC executes F before G20/G21, and LinuxCNC's canonical layer converts a feed rate
/// with the units in force when it is set: rs274 prints `SET_FEED_RATE(60)` before
/// `USE_LENGTH_UNITS(CANON_UNITS_INCHES)` for `G20 F60`
/// (`rtcnc-gcode/tests/corpus/221_units_and_feed_in_one_block.canon`), so F60 there is 60
/// mm/min, and F120 on `G21 F120` is 120 in/min. The kernel applied the units of the move
/// instead (25.4 × too fast, and too slow).
#[test]
fn a_feed_on_the_block_that_changes_the_units_is_in_the_units_before() {
    let text = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../gcode/tests/corpus/221_units_and_feed_in_one_block.ngc"),
    )
    .unwrap();
    let cfg = config("bench-xyz.toml");
    let mut m = Machine::new(&cfg, Some(program(&text, "feed-units.ngc")));
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    assert!(m.until(60.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    // (program line, feed in mm/s): F600 mm/min; F60 set in mm; F120 set in inches; F10 in
    // inches.
    for (line, feed) in [
        (5, 10.0),
        (7, 1.0),
        (9, 120.0 * 25.4 / 60.0),
        (11, 10.0 * 25.4 / 60.0),
    ] {
        // The cruise speed: the middle sample of the line.
        let on_line: Vec<f64> = m
            .samples
            .iter()
            .filter(|s| s.line == line)
            .map(|s| s.path_speed)
            .collect();
        let top = on_line[on_line.len() / 2];
        assert!(
            (top - feed).abs() <= 1e-3 * feed,
            "line {line}: {top} mm/s, F {feed}"
        );
    }
}

/// An adaptive-clearing-like program: rows of trochoidal loops (circles of R 2.87 mm in
/// 85 chords of 0.21 mm, advancing 0.56 mm per loop, F3000, G64 P0.02), each row ending at
/// a corner into a rapid retract. At the end of the first row the path arrived at the
/// corner braking harder than the curve allowed (a dead end); its rollback's stricter model
/// was dropped at every push of the moves that kept arriving behind it (the look-ahead re-ran
/// the braking curve back to that stop), so the same dead end was met again and again with
/// fewer set-points left to roll back each time, until none were left: set-points 124 ×
/// over the jerk limit and 7 × over the acceleration limit were emitted. Through the
/// kernel, since the moves must arrive while the machine runs.
#[test]
fn trochoidal_rows_ending_in_corners_keep_the_limits() {
    let (r, advance, chord, rows, loops) = (2.87f64, 0.56f64, 0.21f64, 3, 10);
    let n = (std::f64::consts::TAU * r / chord) as usize;
    let mut text = String::from("G21 G90 G17 G40 G49 G80\nG64 P0.02\nG0 Z5.000\n");
    let (x, mut y) = (10.0, 30.0);
    text += &format!("G0 X{:.3} Y{y:.3}\nG1 Z-3.000 F300.0\n", x + r);
    for _ in 0..rows {
        for k in 0..loops {
            let cx = x + k as f64 * advance;
            for j in 1..=n {
                let a = std::f64::consts::TAU * j as f64 / n as f64;
                let px = cx + r * a.cos() + advance * j as f64 / n as f64;
                text += &format!("G1 X{px:.3} Y{:.3} F3000.0\n", y + r * a.sin());
            }
        }
        y += 2.0 * r;
        text += &format!("G0 Z1.000\nG0 X{:.3} Y{y:.3}\nG1 Z-3.000 F300.0\n", x + r);
    }
    text += "G0 Z5.000\nM2\n";
    let cfg = config("bench-xyz.toml");
    let mut m = Machine::new(&cfg, Some(program(&text, "trochoid.ngc")));
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    assert!(m.until(60.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    let worst = worst_ratio(&m.samples, 1e-3, &[(100.0, 1000.0, 50_000.0); 3]);
    assert!(worst <= 1.0 + 1e-9, "{worst}");
}

/// Cutter compensation keeps an arc's radius difference while it changes its radii: an arc
/// of R 30 whose end radius is 0.029 mm longer (accepted: under 0.1 % of 30.029 mm) is
/// 0.029 mm off at R 27 inside a 6 mm cutter, which the rule alone would refuse at R 27
/// (0.0283 mm); the planner took the rule for the compensated radii and refused it.
#[test]
fn a_compensated_arc_keeps_the_radius_difference_the_interpreter_accepted() {
    let dir = std::env::temp_dir().join(format!("rtcnc-planner-cases-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let tools = dir.join("tools.tbl");
    std::fs::write(&tools, "T1 P1 D6.0 Z+40.0 ;6 mm flat end mill\n").unwrap();
    let toml = std::fs::read_to_string(repo().join("configs/bench-xyz.toml")).unwrap()
        + &format!(
            "\n[files]\ntool_table = {:?}\n",
            tools.display().to_string()
        );
    let cfg = rtcnc_kernel::MachineConfig::parse(&toml, "bench-xyz+tools").unwrap();
    let text = "G21 G90 G17 G64 P0.01\nT1 M6\nG0 X0 Y-10 Z0\nG41 D1\nG1 X0 Y0 F600\n\
                G3 X60.029 Y0 I30 J0\nG1 X60.029 Y-10\nG40\nG0 X0 Y-20\nM2\n";
    let mut m = Machine::new(&cfg, Some(program(text, "crc-spiral.ngc")));
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    let ended = m.until(30.0, |s| s.program_ended && s.state == MachineState::Idle);
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    assert!(ended);
    let last = m.samples.last().unwrap().axes;
    assert!(
        last[0].abs() < 1e-9 && (last[1] + 20.0).abs() < 1e-9,
        "{last:?}"
    );
}

/// The cubic Bézier through `c` at parameter t (Bernstein form), XY.
fn cubic_at(c: &[[f64; 2]; 4], t: f64) -> [f64; 2] {
    let s = 1.0 - t;
    let w = [s * s * s, 3.0 * s * s * t, 3.0 * s * t * t, t * t * t];
    [0, 1].map(|i| (0..4).map(|k| w[k] * c[k][i]).sum())
}

/// Distance of `p` from the curve: the grid's nearest point refined by ternary search on
/// the cells next to every local minimum.
fn distance_to_cubic(c: &[[f64; 2]; 4], p: [f64; 2]) -> f64 {
    let d2 = |t: f64| {
        let q = cubic_at(c, t);
        (q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)
    };
    let n = 400;
    let h = 1.0 / n as f64;
    let grid: Vec<f64> = (0..=n).map(|k| d2(k as f64 * h)).collect();
    let mut best = f64::INFINITY;
    for k in 0..=n {
        if (k > 0 && grid[k] > grid[k - 1]) || (k < n && grid[k] > grid[k + 1]) {
            continue;
        }
        let (mut lo, mut hi) = ((k as f64 * h - h).max(0.0), (k as f64 * h + h).min(1.0));
        for _ in 0..100 {
            let (a, b) = (lo + (hi - lo) / 3.0, hi - (hi - lo) / 3.0);
            if d2(a) < d2(b) {
                hi = b;
            } else {
                lo = a;
            }
        }
        best = best.min(d2(0.5 * (lo + hi))).min(grid[k]);
    }
    best.sqrt()
}

/// A G5 whose curve stops and turns back (a cusp; LinuxCNC's rs274 takes it as
/// `NURBS_FEED`) runs: the machine comes to rest at the cusp and goes on, within the limits.
/// Hand-worked: from (0, 0) with I10 J10 (P1 = (10, 10)) and P-10 Q10 from the end (10, 0)
/// (P2 = (0, 10)), B'(1/2) = 0 and B(1/2) = (P0 + 3 P1 + 3 P2 + P3)/8 = (5, 7.5). In G61
/// it took 9 s as 1 µm chords, each stopped at.
#[test]
fn a_g5_with_a_cusp_comes_to_rest_there_and_goes_on() {
    for mode in ["G61", "G64 P0.01"] {
        let text =
            format!("G21 G90 G17 {mode}\nG0 X0 Y0 Z0\nG5 I10 J10 P-10 Q10 X10 Y0 F1200\nM2\n");
        let cfg = config("bench-xyz.toml");
        let mut m = Machine::new(&cfg, Some(program(&text, "cusp.ngc")));
        m.power_on();
        m.command(Command::Start { from_line: 0 });
        let ended = m.until(60.0, |s| s.program_ended && s.state == MachineState::Idle);
        assert!(m.faults.is_empty(), "{:?}", m.faults);
        assert!(ended);
        let worst = worst_ratio(&m.samples, 1e-3, &[(100.0, 1000.0, 50_000.0); 3]);
        assert!(worst <= 1.0 + 1e-9, "{worst}");
        // At rest at the cusp: a set-point on it whose steps to and from it are at most
        // one period of the jerk (J·T³), as a stop's are.
        let near = |p: &Sample, q: &Sample| {
            (p.axes[0] - q.axes[0]).hypot(p.axes[1] - q.axes[1]) <= 50_000.0 * 1e-9
        };
        let rests = m.samples.windows(3).any(|w| {
            (w[1].axes[0] - 5.0).hypot(w[1].axes[1] - 7.5) <= 1e-9
                && near(&w[0], &w[1])
                && near(&w[2], &w[1])
        });
        assert!(rests, "{mode}: does not come to rest at the cusp");
        let last = m.samples.last().unwrap().axes;
        assert!(last[0] == 10.0 && last[1] == 0.0, "{last:?}");
        // The curve's length at the feed, and a second for the stop at the cusp and
        // the speed changes.
        let bezier = |t: f64| {
            let s = 1.0 - t;
            [
                3.0 * s * s * t * 10.0 + t * t * t * 10.0,
                3.0 * s * t * 10.0,
            ]
        };
        let length: f64 = (0..1000)
            .map(|k| {
                let (p, q) = (bezier(k as f64 / 1000.0), bezier((k + 1) as f64 / 1000.0));
                (q[0] - p[0]).hypot(q[1] - p[1])
            })
            .sum();
        let moving = m.samples.iter().filter(|s| s.line == 3).count() as f64 * 1e-3;
        assert!(
            moving <= length / 20.0 + 1.0,
            "{mode}: {moving} s on the curve of {length} mm"
        );
    }
}

/// `stall-splines.ngc` (3000 random lines and G5 curves, G64 P0.05) stood still at line
/// 574 (the long-path defect), then stopped with MOTION-012 at line 712: a curve that turns
/// on a radius below 0.1 µm, which the planner cannot follow at any speed; so does the next
/// one. Such a curve now runs cut at its near cusp, with chords within 1 µm of it into and
/// out of it (LinuxCNC runs it too, as arcs). The whole case runs to its end in `rtcnc sim`
/// (too long for a debug test); here its lines 712-716, from the end point of line 711:
/// every set-point of the two curves within P + 1 µm of them, the limits kept, the end
/// exact.
#[test]
fn near_cusp_splines_run_within_the_tolerance() {
    let case = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/cases/stall-splines.ngc"),
    )
    .unwrap();
    let lines: Vec<&str> = case.lines().collect();
    assert_eq!(lines[710], "G1 X259.970670 Y-21.319841");
    let text = format!(
        "{}\nG0 X259.970670 Y-21.319841\n{}\nM2\n",
        lines[0],
        lines[711..716].join("\n")
    );
    // Lines 712 and 713 of the case, 3 and 4 here (G5: I J from the start, P Q from the end).
    assert_eq!(
        &lines[711..713],
        [
            "G5 I12.968389 J-11.520088 P0.991439 Q9.027087 X258.437133 Y-27.590159",
            "G5 I-5.606241 J11.766226 P0.284900 Q-0.324211 X264.849927 Y-30.396029"
        ]
    );
    let cubic = |a: [f64; 2], ij: [f64; 2], pq: [f64; 2], b: [f64; 2]| {
        [
            a,
            [a[0] + ij[0], a[1] + ij[1]],
            [b[0] + pq[0], b[1] + pq[1]],
            b,
        ]
    };
    let (a, b, c) = (
        [259.970670, -21.319841],
        [258.437133, -27.590159],
        [264.849927, -30.396029],
    );
    let curves = [
        (
            3,
            cubic(a, [12.968389, -11.520088], [0.991439, 9.027087], b),
        ),
        (
            4,
            cubic(b, [-5.606241, 11.766226], [0.284900, -0.324211], c),
        ),
    ];
    for (_, curve) in &curves {
        // Near cusps the planner refuses: the smallest radius of curvature (from the
        // Bernstein derivatives, on a fine grid) is below 0.1 µm.
        let radius = |t: f64| {
            let s = 1.0 - t;
            let d1 = [0, 1].map(|i| {
                3.0 * (s * s * (curve[1][i] - curve[0][i])
                    + 2.0 * s * t * (curve[2][i] - curve[1][i])
                    + t * t * (curve[3][i] - curve[2][i]))
            });
            let d2 = [0, 1].map(|i| {
                6.0 * (s * (curve[2][i] - 2.0 * curve[1][i] + curve[0][i])
                    + t * (curve[3][i] - 2.0 * curve[2][i] + curve[1][i]))
            });
            let speed = d1[0].hypot(d1[1]);
            speed.powi(3) / (d1[0] * d2[1] - d1[1] * d2[0]).abs()
        };
        let r_min = (0..=200_000)
            .map(|k| radius(k as f64 / 200_000.0))
            .fold(f64::INFINITY, f64::min);
        assert!(r_min < 1e-4, "{r_min}");
    }

    let cfg = config("bench-xyz.toml");
    let mut m = Machine::new(&cfg, Some(program(&text, "near-cusp.ngc")));
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    let ended = m.until(60.0, |s| s.program_ended && s.state == MachineState::Idle);
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    assert!(ended);
    let worst = worst_ratio(&m.samples, 1e-3, &[(100.0, 1000.0, 50_000.0); 3]);
    assert!(worst <= 1.0 + 1e-9, "{worst}");
    // The corners at the curves' ends are blended within P of the programmed path there:
    // the rapid before them and the line after them count too.
    let segment = |p: [f64; 2], q: [f64; 2], x: [f64; 2]| {
        let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
        let t = (((x[0] - p[0]) * dx + (x[1] - p[1]) * dy) / (dx * dx + dy * dy)).clamp(0.0, 1.0);
        (x[0] - p[0] - t * dx).hypot(x[1] - p[1] - t * dy)
    };
    for (line, _) in &curves {
        let on_curve: Vec<_> = m.samples.iter().filter(|s| s.line == *line).collect();
        assert!(on_curve.len() > 100, "{}", on_curve.len());
        for s in on_curve {
            let x = [s.axes[0], s.axes[1]];
            let d = curves
                .iter()
                .map(|(_, curve)| distance_to_cubic(curve, x))
                .fold(segment([0.0, 0.0], a, x), f64::min)
                .min(segment(c, [260.868909, -30.340011], x));
            assert!(d <= 0.05 + 0.001 + 1e-9, "{d} at {x:?}");
        }
    }
    let last = m.samples.last().unwrap().axes;
    assert!(
        (last[0] - 250.163492).abs() < 1e-9 && (last[1] + 41.008107).abs() < 1e-9,
        "{last:?}"
    );
}
