//! Smooth curves as 1 µm polylines (G64 P0.001), as bench/motion_curves.py writes them:
//! the speed where the curvature is tight, and the limits when the whole curve is in the
//! window.

use crate::common::*;
use rtcnc_motion::AxisVec;
use std::f64::consts::PI;

/// Vertices of `f` on [0, t_end], each chord the longest within `tol` of the curve
/// (greedy, as bench/motion_curves.py and CAM systems place them), the coordinates rounded
/// to 6 decimals as that program prints them: most chords bulge by `tol`.
fn polyline(
    f: impl Fn(f64) -> AxisVec,
    derivs: impl Fn(f64) -> (AxisVec, AxisVec),
    t_end: f64,
    tol: f64,
) -> Vec<AxisVec> {
    let deviation = |t0: f64, t1: f64| {
        (1..16)
            .map(|m| seg_dist(&f(t0 + (t1 - t0) * m as f64 / 16.0), &f(t0), &f(t1)))
            .fold(0.0, f64::max)
    };
    // First step from the curvature: a chord of a circle bulges by L²κ/8.
    let step_guess = |t: f64| {
        let (d1, d2) = derivs(t);
        let sp = d1.iter().map(|x| x * x).sum::<f64>().sqrt();
        let cr = [
            d1[1] * d2[2] - d1[2] * d2[1],
            d1[2] * d2[0] - d1[0] * d2[2],
            d1[0] * d2[1] - d1[1] * d2[0],
        ];
        let kappa = cr.iter().map(|x| x * x).sum::<f64>().sqrt() / sp.powi(3);
        (8.0 * tol / kappa.max(1e-9)).sqrt() / sp
    };
    let mut ts = vec![0.0];
    let mut t = 0.0;
    while t < t_end {
        if deviation(t, t_end) <= tol {
            ts.push(t_end);
            break;
        }
        let mut hi = t_end.min(t + 1.5 * step_guess(t));
        let mut lo = t;
        while deviation(t, hi) <= tol && hi < t_end {
            lo = hi;
            hi = t_end.min(t + 2.0 * (hi - t));
        }
        for _ in 0..14 {
            let mid = 0.5 * (lo + hi);
            if deviation(t, mid) <= tol {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        t = if lo > t { lo } else { 0.5 * (t + hi) };
        ts.push(t);
    }
    let round = |x: f64| (x * 1e6).round() / 1e6;
    ts.iter()
        .map(|&t| {
            let p = f(t);
            p3(round(p[0]), round(p[1]), round(p[2]))
        })
        .collect()
}

/// Rhodonea r = R cos(kθ), θ in [0, π] for an odd k (the whole rose): as a sum of
/// rotations, x = R/2 (cos (k+1)θ + cos (k-1)θ), y = R/2 (sin (k+1)θ - sin (k-1)θ).
fn rose(k: f64, r: f64) -> (impl Fn(f64) -> AxisVec, impl Fn(f64) -> (AxisVec, AxisVec)) {
    let h = r / 2.0;
    let (a, b) = (k + 1.0, k - 1.0);
    let f = move |t: f64| {
        p3(
            h * ((a * t).cos() + (b * t).cos()),
            h * ((a * t).sin() - (b * t).sin()),
            0.0,
        )
    };
    let d = move |t: f64| {
        (
            p3(
                -h * (a * (a * t).sin() + b * (b * t).sin()),
                h * (a * (a * t).cos() - b * (b * t).cos()),
                0.0,
            ),
            p3(
                -h * (a * a * (a * t).cos() + b * b * (b * t).cos()),
                -h * (a * a * (a * t).sin() - b * b * (b * t).sin()),
                0.0,
            ),
        )
    };
    (f, d)
}

/// A rose's petal tips sampled at exactly P: its chords there bulge as far as the
/// tolerance, so the path through the vertices cannot keep the circle's curvature within
/// P. The vertices moved towards the centre (a concentric circle) keep it: the tip is
/// passed near its curvature's speed. At the middle petal's tip (θ = π/3, r = -R) the
/// tangent is perpendicular to the radius, the curvature (1 + k²)/R and the centripetal
/// acceleration on the radius: along X and Y, for per-axis limits A the speed
/// √(A·R/(1 + k²)/max(|cos 60°|, |sin 60°|)). Chords whose curvature swung between
/// the vertices' circles passed it at about half of that.
#[test]
fn a_rose_sampled_at_p_passes_its_tips_near_the_curvature_speed() {
    let (k, r, tol) = (3.0, 20.0, 0.001);
    let (f, d) = rose(k, r);
    let verts = polyline(&f, d, PI, tol);
    let lim = limits(100.0, 1000.0, 50_000.0);
    let mut pl = planner(&lim, verts[0], 1024);
    let tr = run(&mut pl, &lines(&verts, 100.0, blend(tol)), 20_000);
    assert_limits(&tr, 100.0, 1000.0, 50_000.0);
    assert_eq!(pl.stats().limit_violations, 0);
    assert!(max_deviation(&tr, &verts) <= tol * (1.0 + 1e-6));
    let tip = f(PI / 3.0);
    let v_tip = (1000.0 * r / (1.0 + k * k) / (PI / 3.0).sin()).sqrt();
    let lowest = tr.pts[3..]
        .iter()
        .zip(&tr.speed)
        .filter(|(p, _)| dist(p, &tip) < 0.5)
        .map(|(_, v)| *v)
        .fold(f64::INFINITY, f64::min);
    assert!(lowest.is_finite(), "the path passes the tip");
    assert!(
        lowest >= 0.85 * v_tip,
        "tip passed at {lowest:.1} mm/s, its curvature allows {v_tip:.1}"
    );
}

/// An epitrochoid with loops (R 10, r 2, d 3) whose start and end lie inside a tight loop,
/// the whole curve in the window (1024 pieces): the generator's stop model far from the
/// stop once took a piece's own deceleration at the braking curve, nearly 0 on a loop at
/// its centripetal limit, under which no state could stop at the curve's end 120 mm
/// away; it braked in vain, met dead ends it could not undo and emitted 961 set-points
/// beyond the limits (the jerk up to 9000 × its limit). With 256 pieces it kept them.
#[test]
fn an_epitrochoid_whole_in_the_window_keeps_the_limits() {
    let f = |t: f64| {
        p3(
            12.0 * t.cos() - 3.0 * (6.0 * t).cos(),
            12.0 * t.sin() - 3.0 * (6.0 * t).sin(),
            0.0,
        )
    };
    let d = |t: f64| {
        (
            p3(
                -12.0 * t.sin() + 18.0 * (6.0 * t).sin(),
                12.0 * t.cos() - 18.0 * (6.0 * t).cos(),
                0.0,
            ),
            p3(
                -12.0 * t.cos() + 108.0 * (6.0 * t).cos(),
                -12.0 * t.sin() + 108.0 * (6.0 * t).sin(),
                0.0,
            ),
        )
    };
    let tol = 0.00095;
    let verts = polyline(f, d, 2.0 * PI, tol);
    let lim = limits(100.0, 1000.0, 50_000.0);
    let mut pl = planner(&lim, verts[0], 1024);
    let tr = run(&mut pl, &lines(&verts, 100.0, blend(0.001)), 20_000);
    assert_limits(&tr, 100.0, 1000.0, 50_000.0);
    assert_eq!(pl.stats().limit_violations, 0);
    assert!(dist(tr.pts.last().unwrap(), verts.last().unwrap()) <= 1e-9);
}
