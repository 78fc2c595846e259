//! A hand-worked corner: a line along +X meets a circle of radius 5 at a right angle.
//! The trim points, tangents and curvatures come from the circle's equations, the blend is
//! rebuilt from the quintic Hermite basis written out by hand, and its distance from the
//! programmed path is measured by brute force.

use super::*;
use crate::axes::Axis;
use crate::input::{Move, PathMode};
use crate::limits::{AxisLimits, MachineLimits};

const R: f64 = 5.0;
const TOL: f64 = 0.05;

fn p2(x: f64, y: f64) -> AxisVec {
    let mut p = [0.0; AXES];
    p[0] = x;
    p[1] = y;
    p
}

/// Quintic Hermite basis: position, first and second derivative at both ends.
fn hermite(u: f64, e: [[f64; 2]; 6]) -> [f64; 2] {
    let (u2, u3, u4, u5) = (u * u, u * u * u, u.powi(4), u.powi(5));
    let h = [
        1.0 - 10.0 * u3 + 15.0 * u4 - 6.0 * u5,
        u - 6.0 * u3 + 8.0 * u4 - 3.0 * u5,
        0.5 * u2 - 1.5 * u3 + 1.5 * u4 - 0.5 * u5,
        0.5 * u3 - u4 + 0.5 * u5,
        -4.0 * u3 + 7.0 * u4 - 3.0 * u5,
        10.0 * u3 - 15.0 * u4 + 6.0 * u5,
    ];
    let mut p = [0.0; 2];
    for k in 0..6 {
        p[0] += h[k] * e[k][0];
        p[1] += h[k] * e[k][1];
    }
    p
}

/// The blend trimming the line and the circle by `d`, with parameter length `f`·chord,
/// from the circle's own equations: P0 = (-d, 0), T0 = (1, 0), K0 = 0; at φ = d/R on the
/// circle around (-R, 0): P1 = (-R + R cos φ, R sin φ), T1 = (-sin φ, cos φ),
/// K1 = -(cos φ, sin φ)/R.
fn by_hand(d: f64, f: f64) -> (impl Fn(f64) -> [f64; 2], f64) {
    let phi = d / R;
    let (s, c) = phi.sin_cos();
    let p1 = [-R + R * c, R * s];
    let l = f * ((p1[0] + d).powi(2) + p1[1].powi(2)).sqrt();
    let e = [
        [-d, 0.0],
        [l, 0.0],
        [0.0, 0.0],
        [-c / R * l * l, -s / R * l * l],
        [-s * l, c * l],
        p1,
    ];
    (move |u| hermite(u, e), l)
}

/// Distance from the programmed path: the segment (-10, 0)-(0, 0) and the quarter circle.
fn path_dist(p: [f64; 2]) -> f64 {
    let seg = if p[0] <= 0.0 {
        p[1].abs()
    } else {
        (p[0] * p[0] + p[1] * p[1]).sqrt()
    };
    let (x, y) = (p[0] + R, p[1]);
    let ang = y.atan2(x);
    let arc = if (0.0..=0.5 * std::f64::consts::PI).contains(&ang) {
        ((x * x + y * y).sqrt() - R).abs()
    } else {
        ((p[0]).powi(2) + p[1].powi(2)).sqrt()
    };
    seg.min(arc)
}

fn brute_deviation(f: impl Fn(f64) -> [f64; 2]) -> f64 {
    (0..=200_000)
        .map(|k| path_dist(f(k as f64 / 200_000.0)))
        .fold(0.0, f64::max)
}

#[test]
fn line_meeting_a_circle_at_a_right_angle() {
    let m = MachineLimits::uniform(
        &[Axis::X, Axis::Y, Axis::Z],
        AxisLimits::new(100.0, 1000.0, 50_000.0, -100.0, 100.0),
    );
    let lim = Lim::from(&m);
    let mode = PathMode::Blend {
        tolerance: TOL,
        merge_tolerance: 0.0,
    };
    let line = Builder::new(p2(-10.0, 0.0))
        .validate(&Move::line(p2(0.0, 0.0), 30.0, mode, 1), &lim)
        .unwrap()
        .unwrap();
    let arc = Builder::new(p2(0.0, 0.0))
        .validate(
            &Move::arc(p2(-R, R), [-R, 0.0, 0.0], [0.0, 0.0, 1.0], 0, 30.0, mode, 2),
            &lim,
        )
        .unwrap()
        .unwrap();
    let bl = solve(&line, None, &arc, TOL, 30.0, &L_FACTORS, &lim).unwrap();
    let d = bl.d;
    let phi = d / R;
    // Well inside the longest trim (2.5: half a radian of the circle).
    assert!(d > 0.05 && d < 1.0, "d {d}");

    // Trim points on the line and on the circle, at the same length d from the corner.
    assert_eq!(bl.from.st.p, p2(-d, 0.0));
    let q1 = p2(-R + R * phi.cos(), R * phi.sin());
    assert!(norm(&sub(&bl.to.st.p, &q1)) <= 1e-12);

    // Curvature-continuous: tangent and curvature vector of the neighbours at both ends.
    let (t0, k0, _) = arc_derivs(&bl.shape.eval(0.0));
    let (t1, k1, _) = arc_derivs(&bl.shape.eval(1.0));
    assert!(norm(&sub(&t0, &p2(1.0, 0.0))) <= 1e-12);
    assert!(norm(&k0) <= 1e-12);
    assert!(norm(&sub(&t1, &p2(-phi.sin(), phi.cos()))) <= 1e-12);
    assert!(norm(&sub(&k1, &p2(-phi.cos() / R, -phi.sin() / R))) <= 1e-9);

    // The same curve as the hand-built quintic, with the parameter length it chose.
    let chord = norm(&sub(&q1, &p2(-d, 0.0)));
    // Parameter length: the first derivative at the start is L·T0.
    let Shape::Poly { c } = bl.shape else {
        panic!("not a polynomial")
    };
    let bl_l = norm(&c[1]);
    let f = bl_l / chord;
    assert!(
        L_FACTORS.iter().any(|x| (x - f).abs() <= 1e-12),
        "factor {f}"
    );
    let (hand, l) = by_hand(d, f);
    assert!((l - bl_l).abs() <= 1e-12);
    for k in 0..=16 {
        let u = k as f64 / 16.0;
        let (a, b) = (hand(u), bl.shape.pos(u));
        assert!((a[0] - b[0]).abs() <= 1e-12 && (a[1] - b[1]).abs() <= 1e-12);
    }

    // Within P, using most of it (the search accepts 95 % of the target)...
    let dev = brute_deviation(&hand);
    assert!(dev <= TOL * (1.0 - 1e-3) + 1e-12, "deviation {dev}");
    assert!(dev >= 0.94 * TOL, "deviation {dev} leaves P unused");
    assert!(
        (dev - bl.deviation).abs() <= 2e-5 * TOL,
        "{dev} {} d {d} f {f}",
        bl.deviation
    );
    // ... and a reach 10 % longer (same factor) would leave it.
    let (longer, _) = by_hand(1.1 * d, f);
    assert!(brute_deviation(longer) > TOL);
}

/// The blend is sampled against the soft limits. Its neighbours were checked when pushed,
/// so here the envelope passed to the corner is narrowed after the fact (Y below the
/// blend's highest point) to reach the refusal: nothing is emitted and the corner stops.
/// At F 5 the blend beats a stop (at F 30 this right angle within 0.05 mm would not).
#[test]
fn a_blend_leaving_the_soft_limits_is_refused() {
    let m = MachineLimits::uniform(
        &[Axis::X, Axis::Y, Axis::Z],
        AxisLimits::new(100.0, 1000.0, 50_000.0, -100.0, 100.0),
    );
    let mut lim = Lim::from(&m);
    let mode = PathMode::Blend {
        tolerance: TOL,
        merge_tolerance: 0.0,
    };
    let line = Builder::new(p2(-10.0, 0.0))
        .validate(&Move::line(p2(0.0, 0.0), 5.0, mode, 1), &lim)
        .unwrap()
        .unwrap();
    let arc = Builder::new(p2(0.0, 0.0))
        .validate(
            &Move::arc(p2(-R, R), [-R, 0.0, 0.0], [0.0, 0.0, 1.0], 0, 5.0, mode, 2),
            &lim,
        )
        .unwrap()
        .unwrap();
    let mut b = Builder::new(p2(-10.0, 0.0));

    // Inside the envelope: the line up to the blend, the blend; the arc remains from the
    // blend's end.
    let mut out = Vec::new();
    let (next, _) = b
        .arc_corner(&line, None, &arc, TOL, &lim, &mut out)
        .unwrap();
    assert_eq!(out.len(), 2);
    assert!(out[1].corner_blend && !out[0].corner_blend);
    let Prim::Arc { a, u0, .. } = next else {
        panic!("the arc is not what remains")
    };
    assert_eq!(a, out[1].end);
    assert!(u0 > 0.0);

    let y_top = (0..=64)
        .map(|k| out[1].shape.pos(k as f64 / 64.0)[1])
        .fold(f64::NEG_INFINITY, f64::max);
    lim.max[1] = 0.5 * y_top;
    let mut out = Vec::new();
    assert!(
        b.arc_corner(&line, None, &arc, TOL, &lim, &mut out)
            .is_none()
    );
    assert!(out.is_empty());
}

/// A corner whose blend is slower than a stop, and one whose blend is faster, worked by
/// hand, for blends whose speed limit is the same all along. Both neighbours run along X at F 30 on axes of 100 mm/s, 1000 mm/s², 50 000 mm/s³
/// (path limits along X are the axis limits); the blend is 0.4 mm long and replaces 0.4 mm
/// of the programmed path; the neighbours (10 mm) are long enough to stop from F (0.75 mm).
///
/// A blend is chosen when estimated at least 10 % faster (`BLEND_TIME_MARGIN`).
/// A jerk-limited speed change Δv from zero acceleration takes t = 2·sqrt(Δv/J) when
/// Δv ≤ A²/J = 20 mm/s, covering s = Δv·t/2 beyond the lower speed.
/// - Stop: Δv = 30 > 20: t = 30/1000 + 1000/50 000 = 0.05 s, s = 0.75 mm; the stop and the
///   restart take 2·0.05 − 2·0.75/30 = 0.05 s more than cruising; with the replaced 0.4 mm
///   at F: 0.4/30 + 0.05 = 0.063 33 s.
/// - Blend at 10 mm/s: Δv = 20: t = 2·sqrt(20/50 000) = 0.04 s, s = 0.4 mm, distance of one
///   speed change 10·0.04 + 0.4 = 0.8 mm, so 0.04 − 0.8/30 = 0.013 33 s more than cruising,
///   twice; with 0.4 mm at 10 mm/s: 0.04 + 0.026 67 = 0.066 67 s > 0.063 33 s: stop.
/// - Blend at 20 mm/s: Δv = 10: t = 2·sqrt(10/50 000) = 0.028 284 s, s = 0.141 42 mm,
///   distance 20·0.028 284 + 0.141 42 = 0.707 11 mm, so 0.028 284 − 0.707 11/30 =
///   0.004 714 s, twice; with 0.4/20 = 0.02 s: 0.029 43 s < 0.9·0.063 33 s: blend.
#[test]
fn a_blend_is_chosen_only_where_it_is_faster_than_a_stop() {
    let m = MachineLimits::uniform(
        &[Axis::X, Axis::Y, Axis::Z],
        AxisLimits::new(100.0, 1000.0, 50_000.0, -100.0, 100.0),
    );
    let lim = Lim::from(&m);
    let x = p2(1.0, 0.0);
    let corner = |v_blend: f64| CornerChoice {
        feed: 30.0,
        feeds: [30.0; 2],
        v_blend,
        blend_len: 0.4,
        pass_time: 0.4 / v_blend,
        replaced_len: 0.4,
        reach: 10.0,
        t_in: x,
        t_out: x,
    };
    let (stop, slow) = corner(10.0).times(&lim);
    assert!((stop - (0.4 / 30.0 + 0.05)).abs() < 1e-12, "{stop}");
    assert!(
        (slow - (0.04 + 2.0 * (0.04 - 0.8 / 30.0))).abs() < 1e-12,
        "{slow}"
    );
    assert!(!corner(10.0).blend_pays(&lim));
    let (_, fast) = corner(20.0).times(&lim);
    let t = 2.0 * (10.0f64 / 50_000.0).sqrt();
    let fast_ref = 0.02 + 2.0 * (t - (20.0 * t + 5.0 * t) / 30.0);
    assert!((fast - fast_ref).abs() < 1e-12, "{fast} {fast_ref}");
    assert!((fast - 0.029_43).abs() < 1e-5);
    assert!(corner(20.0).blend_pays(&lim));
}

/// Neighbours too short to reach the feed: the speed compared is the one the path can stop
/// from within the shorter neighbour, which turns the choice. Same limits and blend
/// (0.4 mm, 0.4 mm replaced), the blend's limit 7 mm/s.
/// - Neighbours of 10 mm (F 30 reached): stop 0.063 33 s as above; blend: Δv = 23 > 20,
///   t = 0.023 + 0.02 = 0.043 s, s = 23·0.043/2 = 0.4945 mm, 0.043 − (7·0.043 + 0.4945)/30
///   = 0.016 48 s twice, with 0.4/7 = 0.057 14 s: 0.090 11 s: stop.
/// - Shorter neighbour of 0.1 mm: a pure-jerk stop covers v·sqrt(v/J), so the path reaches
///   at most v = (0.1²·J)^(1/3) = 7.937 mm/s there. Stop: t = 2·sqrt(7.937/J) = 0.025 20 s,
///   2·0.025 20 − 2·0.1/7.937 = 0.025 20 s, with 0.4/7.937 = 0.050 40 s: 0.075 60 s. Blend:
///   Δv = 0.937, t = 2·sqrt(0.937/J) = 0.008 658 s, s = 0.004 056 mm, 0.008 658 −
///   (7·0.008 658 + 0.004 056)/7.937 = 0.000 511 s twice, with 0.057 14 s: 0.058 17 s
///   < 0.9·0.075 60 s: blend.
#[test]
fn short_neighbours_limit_the_speed_a_stop_is_weighed_from() {
    let m = MachineLimits::uniform(
        &[Axis::X, Axis::Y, Axis::Z],
        AxisLimits::new(100.0, 1000.0, 50_000.0, -100.0, 100.0),
    );
    let lim = Lim::from(&m);
    let x = p2(1.0, 0.0);
    let c = CornerChoice {
        feed: 30.0,
        feeds: [30.0; 2],
        v_blend: 7.0,
        blend_len: 0.4,
        pass_time: 0.4 / 7.0,
        replaced_len: 0.4,
        reach: 0.1,
        t_in: x,
        t_out: x,
    };
    let j = 50_000.0f64;
    let f = (0.01 * j).cbrt();
    let t_f = 2.0 * (f / j).sqrt();
    let stop_ref = 0.4 / f + 2.0 * t_f - 2.0 * 0.1 / f;
    let dv = f - 7.0;
    let t_dv = 2.0 * (dv / j).sqrt();
    let blend_ref = 0.4 / 7.0 + 2.0 * (t_dv - (7.0 * t_dv + 0.5 * dv * t_dv) / f);
    let (stop, blend) = c.times(&lim);
    assert!((stop - stop_ref).abs() < 1e-9, "{stop} {stop_ref}");
    assert!((blend - blend_ref).abs() < 1e-9, "{blend} {blend_ref}");
    assert!((stop - 0.075_60).abs() < 1e-5 && (blend - 0.058_17).abs() < 1e-5);
    assert!(c.blend_pays(&lim));
    let long = CornerChoice { reach: 10.0, ..c };
    let (stop, blend) = long.times(&lim);
    assert!((stop - 0.063_33).abs() < 1e-5 && (blend - 0.090_11).abs() < 1e-5);
    assert!(!long.blend_pays(&lim));
}

/// Neighbours of different feeds: a rapid (100 mm/s on this machine) into a plunge at
/// 5 mm/s, 90°, each half of the replaced path 1 mm, the blend 1.8 mm at its limit 5 mm/s.
/// - Stop: the rapid's half at 100 mm/s and its stop, t(100) = 0.1 + 0.02 = 0.12 s over
///   s = 6 mm: 0.01 + 0.12 − 0.06 = 0.07 s; the plunge's half at 5 mm/s and its start,
///   t(5) = 2·sqrt(5/50 000) = 0.02 s over 0.05 mm: 0.2 + 0.02 − 0.01 = 0.21 s; 0.28 s.
/// - Blend: 1.8/5 = 0.36 s, and slowing from 100 to 5 before it: Δv = 95, t = 0.095 + 0.02
///   = 0.115 s over 5·0.115 + 95·0.115/2 = 6.0375 mm, 0.115 − 6.0375/100 = 0.054 625 s;
///   0.414 625 s: stop. (Weighed at the slower feed on both sides, as before: stop
///   2·0.21 = 0.42 s, blend 0.36 s, and the blend paid.)
#[test]
fn a_rapid_into_a_slow_feed_weighs_each_half_at_its_own_feed() {
    let m = MachineLimits::uniform(
        &[Axis::X, Axis::Y, Axis::Z],
        AxisLimits::new(100.0, 1000.0, 50_000.0, -100.0, 100.0),
    );
    let lim = Lim::from(&m);
    let c = CornerChoice {
        feed: 5.0,
        feeds: [f64::INFINITY, 5.0],
        v_blend: 5.0,
        blend_len: 1.8,
        pass_time: 1.8 / 5.0,
        replaced_len: 2.0,
        reach: 50.0,
        t_in: p2(1.0, 0.0),
        t_out: p2(0.0, 1.0),
    };
    let (stop, blend) = c.times(&lim);
    assert!((stop - 0.28).abs() < 1e-9, "{stop}");
    assert!((blend - 0.414_625).abs() < 1e-9, "{blend}");
    assert!(!c.blend_pays(&lim));
    let as_before = CornerChoice {
        feeds: [5.0; 2],
        ..c
    };
    assert!(as_before.blend_pays(&lim));
}

/// The speed whose jerk-limited stop (1000 mm/s², 50 000 mm/s³) takes a given distance,
/// worked by hand: 0.1 mm is below A³/J² = 0.4 mm, a pure-jerk stop, v·sqrt(v/J) = 0.1,
/// v = (0.01·J)^(1/3) = 7.937 005 mm/s; 10 mm is above: v²/(2A) + v·A/(2J) = 10,
/// v² + 20 v − 20 000 = 0, v = −10 + sqrt(20 100) = 131.774 468 mm/s.
#[test]
fn the_speed_whose_stop_takes_a_distance() {
    let (a, j) = (1000.0, 50_000.0);
    let v = stop_speed_for_distance(0.1, a, j);
    assert!((v - 7.937_005_259_840_998).abs() < 1e-12, "{v}");
    let v = stop_speed_for_distance(10.0, a, j);
    assert!((v - (-10.0 + 20_100f64.sqrt())).abs() < 1e-12, "{v}");
    assert!((v - 131.774_468).abs() < 1e-6, "{v}");
}

/// The bisection for the speed that stops within a neighbour skips the evaluations far
/// from the closed-form speed: its result is the one of evaluating the stop at every step
/// (the bisection as first written, below), bit for bit, over reaches from 1 µm to 1 m
/// (both sides of the pure-jerk regime) and several limits.
#[test]
fn the_shortened_bisection_gives_the_full_bisections_speed() {
    let full = |f: f64, reach: f64, a: f64, j: f64| {
        if scurve::stop(f, 0.0, a, j).0 > reach {
            let (mut lo, mut hi) = (0.0, f);
            for _ in 0..48 {
                let mid = 0.5 * (lo + hi);
                if scurve::stop(mid, 0.0, a, j).0 > reach {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            lo
        } else {
            f
        }
    };
    let mut n = 0;
    for (a, j) in [
        (1000.0, 50_000.0),
        (300.0, 1e6),
        (5000.0, 2e4),
        (1414.2, 70_710.7),
    ] {
        for f in [10.0, 100.0, 1000.0] {
            for k in 0..120 {
                let reach = 1e-3 * 10f64.powf(k as f64 / 20.0);
                let want = full(f, reach, a, j);
                assert_eq!(
                    speed_stopping_within(f, reach, a, j).to_bits(),
                    want.to_bits(),
                    "f {f} reach {reach} a {a} j {j}"
                );
                n += usize::from(want < f);
            }
        }
    }
    // Most cases bisect (a test that never bisects would prove nothing).
    assert!(n > 900, "{n}");
}
