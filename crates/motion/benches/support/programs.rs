//! The programs and the machine the planner's benchmarks and the `lookahead_cost` example
//! share (included with `#[path]`; each user takes what it needs).
#![allow(dead_code)]

use rtcnc_motion::{
    AXES, Axis, AxisLimits, AxisVec, Bezier, MachineLimits, Move, PathMode, Planner,
    TrivialKinematics,
};

/// A circle of R 10 in chords of 1 µm tolerance (0.28 mm), `turns` times round, G64 P0.001
/// Q0.001, F 100 mm/s: a CAM-like polyline. Returns the start and the moves.
pub fn polyline(turns: f64) -> (AxisVec, Vec<Move>) {
    let (r, tol): (f64, f64) = (10.0, 0.001);
    let phi = 2.0 * (1.0 - tol / r).acos();
    let total = 2.0 * std::f64::consts::PI * turns;
    let n = (total / phi).ceil() as usize;
    let mode = PathMode::Blend {
        tolerance: 0.001,
        merge_tolerance: 0.001,
    };
    let pt = |k: usize| {
        let th = total * k as f64 / n as f64;
        let mut p = [0.0; AXES];
        p[0] = r * th.cos();
        p[1] = r * th.sin();
        p
    };
    (
        pt(0),
        (1..=n)
            .map(|k| Move::line(pt(k), 100.0, mode, k as u32))
            .collect(),
    )
}

/// Tangent cubic arches of 2 mm along X from the origin, alternately up and down (each
/// leaves and arrives along +X), F 60 mm/s.
pub fn spline_chain(n: usize) -> Vec<Move> {
    let p = |x: f64, y: f64| {
        let mut v = [0.0; AXES];
        v[0] = x;
        v[1] = y;
        v
    };
    (0..n)
        .map(|k| {
            let x = 2.0 * k as f64;
            let h = if k % 2 == 0 { 1.0 } else { -1.0 };
            Move::spline(
                p(x + 2.0, 0.0),
                Bezier::Cubic([p(x + 0.5, h), p(x + 1.5, h)]),
                60.0,
                PathMode::ExactPath,
                k as u32 + 1,
            )
        })
        .collect()
}

/// The benchmark machine (XYZ, 100 mm/s, 1000 mm/s², 50 000 mm/s³, soft limits ±`extent`,
/// 1 ms), at rest at `start`, with a window of `window` pieces.
pub fn planner(start: AxisVec, window: usize, extent: f64) -> Planner<TrivialKinematics> {
    let lim = MachineLimits::uniform(
        &[Axis::X, Axis::Y, Axis::Z],
        AxisLimits::new(100.0, 1000.0, 50_000.0, -extent, extent),
    );
    Planner::new(
        &lim,
        TrivialKinematics::identity(&[Axis::X, Axis::Y, Axis::Z]),
        1e-3,
        window,
        start,
    )
    .expect("valid benchmark limits")
}

/// Pushes the whole program through the look-ahead (as much as the window takes per call)
/// and flushes it.
pub fn push_program(pl: &mut Planner<TrivialKinematics>, moves: &[Move]) {
    let mut k = 0;
    while k < moves.len() {
        k += pl.push_all(std::hint::black_box(&moves[k..])).unwrap();
    }
    pl.flush();
}
