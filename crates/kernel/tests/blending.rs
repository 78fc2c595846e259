//! G64 P Q through the whole kernel: the interpreter's Q reaches the planner as its
//! collinear-merge tolerance (in millimetres, whatever the program's units).

use crate::common;
use crate::common::*;
use rtcnc_kernel::{Command, MachineState, Sample};

/// A CAM-style polyline along X: 40 segments of 0.5 mm whose odd vertices stand `rise`
/// off the line (a triangle wave), from (0, 0) to (20, 0), then a corner up to (20, 5).
fn polyline(rise: f64) -> Vec<[f64; 2]> {
    let mut points: Vec<[f64; 2]> = (0..=40)
        .map(|i| [0.5 * f64::from(i), if i % 2 == 1 { rise } else { 0.0 }])
        .collect();
    points.push([20.0, 5.0]);
    points
}

fn program(units: &str, scale: f64, p: f64, q: f64, points: &[[f64; 2]]) -> String {
    let mut text = format!(
        "{units} G90 G17\nG0 X0 Y0 Z0\nG64 P{p} Q{q}\nF{}\n",
        600.0 * scale
    );
    for pt in &points[1..] {
        text += &format!("G1 X{:.6} Y{:.6}\n", pt[0] * scale, pt[1] * scale);
    }
    text + "M2\n"
}

/// Distance from `p` to the polyline.
fn distance(points: &[[f64; 2]], p: [f64; 2]) -> f64 {
    points
        .windows(2)
        .map(|w| {
            let (a, b) = (w[0], w[1]);
            let d = [b[0] - a[0], b[1] - a[1]];
            let len2 = d[0] * d[0] + d[1] * d[1];
            let t = (((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1]) / len2).clamp(0.0, 1.0);
            (p[0] - a[0] - t * d[0]).hypot(p[1] - a[1] - t * d[1])
        })
        .fold(f64::MAX, f64::min)
}

/// Runs the program on the benchmark machine; the samples and the planner's merge count.
fn run(text: &str, name: &str) -> (Vec<Sample>, u64) {
    let cfg = config("bench-xyz.toml");
    let mut m = Machine::new(&cfg, Some(common::program(text, name)));
    m.power_on();
    let before = m.status().geometry.merged;
    m.command(Command::Start { from_line: 0 });
    assert!(m.until(20.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    let merged = m.status().geometry.merged - before;
    (m.samples, merged)
}

const RISE: f64 = 0.004;
const P: f64 = 0.005;
const Q: f64 = 0.01;

#[test]
fn g64_q_merges_a_nearly_collinear_polyline_into_one_line() {
    let points = polyline(RISE);
    let (samples, merged) = run(&program("G21", 1.0, P, Q, &points), "merge.ngc");
    // Every inner vertex of the 40 segments lies within 2·RISE = 0.008 < Q of the chord
    // from (0, 0) to the current end, so each segment after the first joins the run: 39
    // merges, and the tool goes straight from (0, 0) to (20, 0).
    assert_eq!(merged, 39);
    let on_line = samples
        .iter()
        .filter(|s| s.axes[0] > 0.0 && s.axes[0] < 19.5);
    assert!(on_line.clone().count() > 1000);
    for s in on_line {
        assert!(s.axes[1].abs() < 1e-12, "{s:?}");
    }
    // Everywhere within Q + P of the programmed polyline.
    let worst = samples
        .iter()
        .map(|s| distance(&points, [s.axes[0], s.axes[1]]))
        .fold(0.0, f64::max);
    assert!(worst <= Q + P + 1e-9, "{worst}");
}

#[test]
fn without_q_nothing_merges_and_the_path_follows_the_vertices() {
    let points = polyline(RISE);
    let (samples, merged) = run(&program("G21", 1.0, P, 0.0, &points), "no-merge.ngc");
    assert_eq!(merged, 0);
    // The path goes through the raised vertices (smoothed within P, never merged).
    let top = samples
        .iter()
        .map(|s| s.axes[1])
        .filter(|y| *y < 0.1)
        .fold(0.0, f64::max);
    assert!(top > 0.9 * RISE, "{top}");
    let worst = samples
        .iter()
        .map(|s| distance(&points, [s.axes[0], s.axes[1]]))
        .fold(0.0, f64::max);
    assert!(worst <= P + 1e-9, "{worst}");
}

#[test]
fn g64_p_and_q_in_an_inch_program_are_inches() {
    // The same polyline in inches: Q 0.0004 in = 0.01016 mm merges it, as Q0.01 mm does;
    // read as millimetres it would merge nothing (0.0004 mm < RISE).
    let points = polyline(RISE);
    let text = program("G20", 1.0 / 25.4, 0.0002, 0.0004, &points);
    let (_, merged) = run(&text, "merge-inch.ngc");
    assert_eq!(merged, 39);
}

/// Runs `text` on the benchmark machine with `[motion] default_blend_tolerance` set.
fn run_with_default_tolerance(text: &str, name: &str, tolerance: f64) -> Vec<Sample> {
    let toml = std::fs::read_to_string(repo().join("configs/bench-xyz.toml")).unwrap()
        + &format!("\n[motion]\ndefault_blend_tolerance = {tolerance}\n");
    let cfg = rtcnc_kernel::MachineConfig::parse(&toml, "bench-xyz+motion").unwrap();
    let mut m = Machine::new(&cfg, Some(common::program(text, name)));
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    assert!(m.until(30.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    m.samples
}

/// Plain G64 (LinuxCNC: "best speed", no bound) blends within the machine file's
/// `default_blend_tolerance`: the same path, set-point for set-point, as `G64 P` with that
/// value (it used to be P0: a stop at every corner). A zigzag of 2 mm lines with 30°
/// corners at F1800.
#[test]
fn plain_g64_blends_within_the_machine_files_tolerance() {
    let zigzag = |mode: &str| {
        let mut text = format!("G21 G90 G17\nG0 X0 Y0 Z0\n{mode}\nF1800\n");
        for k in 1..=20 {
            let a = if k % 2 == 0 { 15f64 } else { -15f64 }.to_radians();
            text += &format!("G91 G1 X{:.6} Y{:.6}\n", 2.0 * a.cos(), 2.0 * a.sin());
        }
        text + "G90\nM2\n"
    };
    for tolerance in [0.01, 0.05] {
        let plain = run_with_default_tolerance(&zigzag("G64"), "plain.ngc", tolerance);
        let with_p = run_with_default_tolerance(
            &zigzag(&format!("G64 P{tolerance}")),
            "with-p.ngc",
            tolerance,
        );
        assert_eq!(plain.len(), with_p.len());
        for (a, b) in plain.iter().zip(&with_p) {
            assert_eq!(a.axes, b.axes);
        }
        // At 0.05 mm the corners are blended: the path never comes to rest between its
        // start and its end (at 0.01 mm a stop is faster than the blend it allows).
        let moving: Vec<&Sample> = plain.iter().filter(|s| s.path_speed > 0.0).collect();
        let (first, last) = (moving[0].cycle, moving[moving.len() - 1].cycle);
        let stopped = last - first + 1 - moving.len() as u64;
        assert_eq!(
            stopped > 0,
            tolerance < 0.05,
            "P {tolerance}: {stopped} periods at rest"
        );
    }
}

#[test]
fn the_default_blend_tolerance_must_be_positive() {
    let base = std::fs::read_to_string(repo().join("configs/bench-xyz.toml")).unwrap();
    for bad in ["0.0", "-0.01", "nan"] {
        let toml = base.clone() + &format!("\n[motion]\ndefault_blend_tolerance = {bad}\n");
        let err = rtcnc_kernel::MachineConfig::parse(&toml, "bad").unwrap_err();
        assert!(
            err.to_string().contains("motion.default_blend_tolerance"),
            "{err}"
        );
    }
}
