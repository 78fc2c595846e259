//! G5.2/G5.3 NURBS curves through the whole kernel: the planner follows them as curves
//! (cubic Bézier pieces within 0.1 µm of the NURBS), within the machine's limits, without
//! stopping at the pieces' joints. The references are closed forms (a rational quadratic
//! quarter circle lies on its circle) and the NURBS evaluated here by the Cox-de Boor
//! recursion of its basis functions, written apart from the library's de Boor triangle.

use crate::common::*;
use rtcnc_kernel::{Command, MachineState, Sample};

fn run(text: &str, name: &str) -> Vec<Sample> {
    let mut m = Machine::new(&config("bench-xyz.toml"), Some(program(text, name)));
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    m.cycles(2);
    assert!(m.until(60.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert!(
        m.faults.is_empty(),
        "{:?} {:?}",
        m.faults,
        m.sim.handle().error_text()
    );
    m.samples
}

/// The largest velocity, acceleration and jerk of any axis, by finite differences of the
/// set-points (1 ms periods).
fn largest_derivatives(samples: &[Sample]) -> [f64; 3] {
    let t = 1e-3;
    let mut out = [0.0f64; 3];
    for w in samples.windows(4) {
        for i in 0..3 {
            let x: Vec<f64> = w.iter().map(|s| s.axes[i]).collect();
            let v = (x[3] - x[2]) / t;
            let a = (x[3] - 2.0 * x[2] + x[1]) / (t * t);
            let j = (x[3] - 3.0 * x[2] + 3.0 * x[1] - x[0]) / (t * t * t);
            out[0] = out[0].max(v.abs());
            out[1] = out[1].max(a.abs());
            out[2] = out[2].max(j.abs());
        }
    }
    out
}

#[test]
fn a_rational_quadratic_quarter_circle_is_followed_on_its_circle_without_stopping() {
    // The weight √2/2 on the corner point makes the conic a circle of radius 10 about the
    // origin. G61: the path keeps to the curve exactly (no blending at the pieces' joints).
    let text = "G21 G90 G61 F1200
G0 X10 Y0
G5.2 P1 L3
X10 Y10 P0.7071067811865476
X0 Y10 P1
G5.3
G1 X-5
M2
";
    let samples = run(text, "quarter.ngc");
    let on_curve: Vec<&Sample> = samples
        .iter()
        .filter(|s| s.line == 3 || s.line == 4 || s.line == 5 || s.line == 6)
        .collect();
    assert!(on_curve.len() > 500, "{}", on_curve.len());
    for s in &on_curve {
        let r = s.axes[0].hypot(s.axes[1]);
        assert!((r - 10.0).abs() <= 1.01e-4, "{:?} r {r}", &s.axes[..2]);
    }
    // It ends on (0, 10), tangent to the G1 after it, and goes on from there without a
    // stop.
    assert_eq!(samples.last().unwrap().axes[..2], [-5.0, 10.0]);
    // At the feed (20 mm/s) along the middle of the curve: no stop at the joints of its
    // cubic pieces (the path speed only ramps at the curve's ends, into the G1 it stops
    // before its corner at (0, 10)).
    let speeds: Vec<f64> = on_curve
        .iter()
        .filter(|s| s.axes[0] < 9.0 && s.axes[0] > 1.0)
        .map(|s| s.path_speed)
        .collect();
    let slowest = speeds.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(slowest > 19.9, "{slowest}");
    let [v, a, j] = largest_derivatives(&samples);
    assert!(
        v <= 100.0 + 1e-6 && a <= 1000.0 + 1e-3 && j <= 50_000.0 * 1.001,
        "{v} {a} {j}"
    );
}

/// The NURBS of order `k` with control points `(x, y, w)` on LinuxCNC's clamped uniform
/// knots, at parameter `u`, from its rational basis functions (Cox-de Boor).
fn cox_de_boor(points: &[(f64, f64, f64)], k: usize, u: f64) -> (f64, f64) {
    let n = points.len() - 1;
    let last = (n + 2 - k) as f64;
    let mut t = vec![0.0; k];
    t.extend((1..=n + 1 - k).map(|i| i as f64));
    t.extend(std::iter::repeat_n(last, k));
    let u = u.min(last * (1.0 - 1e-15));
    // Degree 0, then up to k - 1.
    let mut basis: Vec<f64> = (0..t.len() - 1)
        .map(|i| if t[i] <= u && u < t[i + 1] { 1.0 } else { 0.0 })
        .collect();
    for d in 1..k {
        let next: Vec<f64> = (0..t.len() - 1 - d)
            .map(|i| {
                let left = if t[i + d] > t[i] {
                    (u - t[i]) / (t[i + d] - t[i]) * basis[i]
                } else {
                    0.0
                };
                let right = if t[i + d + 1] > t[i + 1] {
                    (t[i + d + 1] - u) / (t[i + d + 1] - t[i + 1]) * basis[i + 1]
                } else {
                    0.0
                };
                left + right
            })
            .collect();
        basis = next;
    }
    let (mut x, mut y, mut w) = (0.0, 0.0, 0.0);
    for (b, &(px, py, pw)) in basis.iter().zip(points) {
        x += b * pw * px;
        y += b * pw * py;
        w += b * pw;
    }
    (x / w, y / w)
}

#[test]
fn an_order_four_weighted_nurbs_is_followed_within_its_tolerance_and_the_limits() {
    // examples/gcode/nurbs.ngc's curve, in G64 P0.01: every set-point on it lies within
    // P (corners the planner may round inside P) plus the 0.1 µm of the cubics of the
    // NURBS evaluated by Cox-de Boor; the path ends at the curve's end and goes on.
    let text = "G17 G21 G90 G64 P0.01
G0 X0 Y0 Z1
G1 Z0 F3000
G5.2 P1 L4
X10 Y20 P1
X30 Y25 P2
X40 Y5 P1
X60 Y10 P0.5
X70 Y0 P1
G5.3
G1 X80
M2
";
    let points = [
        (0.0, 0.0, 1.0),
        (10.0, 20.0, 1.0),
        (30.0, 25.0, 2.0),
        (40.0, 5.0, 1.0),
        (60.0, 10.0, 0.5),
        (70.0, 0.0, 1.0),
    ];
    let samples = run(text, "order4.ngc");
    // The curve as a dense polyline (parameter 0 to 3, 30 000 steps: 2.5 µm chords at
    // most over its ~100 mm, whose sag is far below the tolerance).
    let curve: Vec<(f64, f64)> = (0..=30_000)
        .map(|i| cox_de_boor(&points, 4, 3.0 * i as f64 / 30_000.0))
        .collect();
    let distance = |x: f64, y: f64| {
        curve
            .windows(2)
            .map(|w| {
                let (ax, ay) = w[0];
                let (bx, by) = w[1];
                let (dx, dy) = (bx - ax, by - ay);
                let l2 = dx * dx + dy * dy;
                let s = if l2 > 0.0 {
                    (((x - ax) * dx + (y - ay) * dy) / l2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                (x - ax - s * dx).hypot(y - ay - s * dy)
            })
            .fold(f64::INFINITY, f64::min)
    };
    let on_curve: Vec<&Sample> = samples
        .iter()
        .filter(|s| (4..=10).contains(&s.line))
        .step_by(7)
        .collect();
    assert!(on_curve.len() > 50, "{}", on_curve.len());
    let worst = on_curve
        .iter()
        .map(|s| distance(s.axes[0], s.axes[1]))
        .fold(0.0f64, f64::max);
    assert!(worst <= 0.01 + 1e-4, "{worst}");
    assert_eq!(samples.last().unwrap().axes[..2], [80.0, 0.0]);
    assert!(
        samples
            .iter()
            .any(|s| s.axes[0] == 70.0 && s.axes[1] == 0.0)
    );
    let [v, a, j] = largest_derivatives(&samples);
    assert!(
        v <= 100.0 + 1e-6 && a <= 1000.0 + 1e-3 && j <= 50_000.0 * 1.001,
        "{v} {a} {j}"
    );
}
