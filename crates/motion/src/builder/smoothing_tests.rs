//! Smoothing of a dense polyline through an inflection between unequal chords: the crossing
//! of the benchmark lemniscate of Bernoulli (r² = a² cos 2φ, a = 20 mm, centred at
//! (−20, 0)), 1 µm chord tolerance, where the chords go 0.82 → 2.42 → 0.80 mm and the
//! curvature changes sign inside the long one. The curve's curvature is κ = 3r/a² and its
//! change |dκ/ds| = 3/a² · |dr/ds| ≤ 3/a², largest at the crossing.

use super::*;
use crate::geometry::arc_derivs;
use crate::input::{Move, PathMode};
use crate::limits::{AxisLimits, MachineLimits};

const A: f64 = 20.0;
const CENTRE: [f64; 2] = [-20.0, 0.0];
const P: f64 = 0.001;

/// Vertices 71-96 of the benchmark lemniscate (`bench/motion-paths.sh`), the crossing chord
/// from vertex 83 to 84.
const VERTICES: [[f64; 2]; 26] = [
    [-14.504410, 4.806154],
    [-14.823831, 4.589822],
    [-15.147772, 4.360706],
    [-15.477103, 4.117904],
    [-15.812937, 3.860274],
    [-16.156722, 3.586346],
    [-16.510386, 3.294172],
    [-16.876576, 2.981091],
    [-17.259085, 2.643297],
    [-17.663679, 2.275014],
    [-18.099953, 1.866641],
    [-18.586336, 1.399746],
    [-19.169849, 0.827306],
    [-20.883483, -0.880055],
    [-21.455573, -1.440393],
    [-21.936808, -1.901460],
    [-22.370013, -2.306085],
    [-22.772537, -2.671619],
    [-23.153548, -3.007237],
    [-23.518604, -3.318507],
    [-23.871384, -3.609119],
    [-24.214463, -3.881666],
    [-24.549723, -4.138049],
    [-24.878581, -4.379707],
    [-25.202127, -4.607760],
    [-25.521216, -4.823093],
];

fn p2(v: [f64; 2]) -> AxisVec {
    let mut p = [0.0; AXES];
    p[0] = v[0];
    p[1] = v[1];
    p
}

fn distance_to_segment(p: &AxisVec, a: &AxisVec, b: &AxisVec) -> f64 {
    let d = sub(b, a);
    let u = (dot(&sub(p, a), &d) / dot(&d, &d)).clamp(0.0, 1.0);
    norm(&sub(p, &add_scaled(a, &d, u)))
}

/// The builder's pieces for the polyline, run from a stop to a stop.
fn smoothed() -> (Vec<Piece>, GeometryStats) {
    let m = MachineLimits::uniform(
        &[Axis::X, Axis::Y, Axis::Z],
        AxisLimits::new(100.0, 1000.0, 50_000.0, -100.0, 100.0),
    );
    let lim = Lim::from(&m);
    let mode = PathMode::Blend {
        tolerance: P,
        merge_tolerance: P,
    };
    let mut b = Builder::new(p2(VERTICES[0]));
    let mut out = Vec::new();
    for (n, v) in VERTICES.iter().enumerate().skip(1) {
        b.push(&Move::line(p2(*v), 100.0, mode, n as u32), &lim, &mut out)
            .unwrap();
    }
    b.flush(&lim, &mut out);
    (out, b.stats)
}

#[test]
fn the_lemniscate_crossing_is_smoothed_through_without_a_corner_blend() {
    let (pieces, stats) = smoothed();
    assert_eq!(stats.smoothed, VERTICES.len() as u64 - 2, "{stats:?}");
    assert_eq!(stats.blends, 0, "{stats:?}");
    assert_eq!(stats.tolerance_exceeded, 0, "{stats:?}");
    assert_eq!(pieces.len(), VERTICES.len() - 1);
    let verts: Vec<AxisVec> = VERTICES.iter().map(|v| p2(*v)).collect();
    // Each span ends on its vertex, stays within P of its segment and joins the next one
    // with the same tangent and curvature (G2).
    let mut prev_end: Option<(AxisVec, AxisVec)> = None;
    for (i, pc) in pieces.iter().enumerate() {
        assert_eq!(pc.start, verts[i]);
        assert_eq!(pc.end, verts[i + 1]);
        for k in 0..=400 {
            let p = pc.shape.pos(k as f64 / 400.0);
            let dev = distance_to_segment(&p, &verts[i], &verts[i + 1]);
            assert!(dev <= P, "span {i}: {dev} mm from its segment");
        }
        let (t0, k0, _) = arc_derivs(&pc.shape.eval(0.0));
        if let Some((t1, k1)) = prev_end {
            assert!(norm(&sub(&t0, &t1)) < 1e-9, "tangent jump at vertex {i}");
            assert!(norm(&sub(&k0, &k1)) < 1e-9, "curvature jump at vertex {i}");
        }
        let (t1, k1, _) = arc_derivs(&pc.shape.eval(1.0));
        prev_end = Some((t1, k1));
    }
}

#[test]
fn curvature_and_its_change_follow_the_lemniscate_across_the_crossing() {
    let (pieces, _) = smoothed();
    // Spans 3-21, about 7 mm either side of the crossing. (The run starts from a stop in
    // the middle of the curve: its first vertex has no earlier one to take the curvature
    // change from, and the next two spans make up for the circle's tangent there.)
    let kp_curve = 3.0 / (A * A);
    let mut kp_max: f64 = 0.0;
    for (i, pc) in pieces.iter().enumerate().take(22).skip(3) {
        for k in 0..=200 {
            let d = pc.shape.eval(k as f64 / 200.0);
            let (_, kv, kp) = arc_derivs(&d);
            kp_max = kp_max.max(norm(&kp));
            // The curve's curvature at the nearest point (1 µm away at most): κ = 3r/a².
            let kappa = 3.0 * norm(&sub(&d.p, &p2(CENTRE))) / (A * A);
            assert!(
                (norm(&kv) - kappa).abs() <= 1e-4,
                "span {i} at {k}/200: curvature {} against {kappa}",
                norm(&kv)
            );
        }
    }
    // The smoothed curvature changes at most 10 % faster than the curve's at the crossing.
    assert!(
        kp_max <= 1.1 * kp_curve,
        "largest curvature change {kp_max} /mm² against {kp_curve}"
    );
}
