//! Shared harness: runs move lists through the planner and measures the set-points.
#![allow(dead_code, clippy::needless_range_loop)]

use rtcnc_motion::{
    AXES, Axis, AxisLimits, AxisVec, MachineLimits, MotionState, Move, PathMode, Planner,
    TrivialKinematics,
};

pub const T: f64 = 1e-3;

pub fn limits(v: f64, a: f64, j: f64) -> MachineLimits {
    MachineLimits::uniform(
        &[Axis::X, Axis::Y, Axis::Z],
        AxisLimits::new(v, a, j, -1000.0, 1000.0),
    )
}

pub fn planner(lim: &MachineLimits, start: AxisVec, window: usize) -> Planner<TrivialKinematics> {
    Planner::new(
        lim,
        TrivialKinematics::identity(&[Axis::X, Axis::Y, Axis::Z]),
        T,
        window,
        start,
    )
    .unwrap()
}

pub fn p3(x: f64, y: f64, z: f64) -> AxisVec {
    let mut p = [0.0; AXES];
    p[0] = x;
    p[1] = y;
    p[2] = z;
    p
}

pub fn blend(p: f64) -> PathMode {
    PathMode::Blend {
        tolerance: p,
        merge_tolerance: 0.0,
    }
}

/// Set-points of one run, with the initial position repeated three times in front (the
/// machine was at rest before).
pub struct Trace {
    pub pts: Vec<AxisVec>,
    pub states: Vec<MotionState>,
    pub speed: Vec<f64>,
}

/// Pushes `moves` while there is room, flushes at the end, runs until idle. `hook` is called
/// before every period with the period index.
pub fn run_with(
    pl: &mut Planner<TrivialKinematics>,
    moves: &[Move],
    max_periods: usize,
    mut hook: impl FnMut(usize, &mut Planner<TrivialKinematics>),
) -> Trace {
    let start = pl.position();
    let mut tr = Trace {
        pts: vec![start; 3],
        states: Vec::new(),
        speed: Vec::new(),
    };
    let mut k = 0;
    let mut flushed = false;
    let mut joints = [0.0; 3];
    for n in 0..max_periods {
        while k < moves.len() && pl.free() > 0 {
            pl.push(&moves[k]).unwrap();
            k += 1;
        }
        if k == moves.len() && !flushed {
            pl.flush();
            flushed = true;
        }
        hook(n, pl);
        let st = pl.next(&mut joints);
        tr.pts.push(st.axes);
        tr.states.push(st.state);
        tr.speed.push(st.path_speed);
        if flushed && st.state == MotionState::Idle {
            // A few more periods at rest, so that the last differences are checked too.
            for _ in 0..3 {
                let st = pl.next(&mut joints);
                tr.pts.push(st.axes);
            }
            return tr;
        }
    }
    panic!("did not finish within {max_periods} periods");
}

pub fn run(pl: &mut Planner<TrivialKinematics>, moves: &[Move], max_periods: usize) -> Trace {
    run_with(pl, moves, max_periods, |_, _| {})
}

/// Largest |v|/vmax, |a|/amax, |j|/jmax over all axes, from finite differences at the servo
/// period of the set-points. A finite difference is an average of the continuous quantity
/// over one to three periods (with B-spline weights), so a trajectory whose continuous v, a,
/// j stay within the limits also has its differences within them: no tolerance is needed
/// beyond floating-point rounding of the differences themselves, which the test's 1e-9
/// relative margin covers for positions of up to about 100 mm.
pub fn ratios(tr: &Trace, v: f64, a: f64, j: f64) -> (f64, f64, f64) {
    let (mut rv, mut ra, mut rj) = (0.0f64, 0.0f64, 0.0f64);
    for w in tr.pts.windows(4) {
        for i in 0..3 {
            let dv = (w[3][i] - w[2][i]) / T;
            let da = (w[3][i] - 2.0 * w[2][i] + w[1][i]) / (T * T);
            let dj = (w[3][i] - 3.0 * w[2][i] + 3.0 * w[1][i] - w[0][i]) / (T * T * T);
            assert!(
                dv.is_finite() && da.is_finite() && dj.is_finite(),
                "NaN set-point"
            );
            rv = rv.max(dv.abs() / v);
            ra = ra.max(da.abs() / a);
            rj = rj.max(dj.abs() / j);
        }
    }
    (rv, ra, rj)
}

pub fn assert_limits(tr: &Trace, v: f64, a: f64, j: f64) {
    let (rv, ra, rj) = ratios(tr, v, a, j);
    let tol = 1.0 + 1e-9;
    if !(rv <= tol && ra <= tol && rj <= tol) {
        // Where: the first sample index exceeding a limit, with its neighbourhood.
        let mut at = 0;
        for (k, w) in tr.pts.windows(4).enumerate() {
            let bad = (0..3).any(|i| {
                let dv = (w[3][i] - w[2][i]) / T;
                let da = (w[3][i] - 2.0 * w[2][i] + w[1][i]) / (T * T);
                let dj = (w[3][i] - 3.0 * w[2][i] + 3.0 * w[1][i] - w[0][i]) / (T * T * T);
                dv.abs() > v * tol || da.abs() > a * tol || dj.abs() > j * tol
            });
            if bad {
                at = k + 3;
                break;
            }
        }
        let lo = at.saturating_sub(4);
        let hi = (at + 3).min(tr.pts.len());
        let around: Vec<_> = (lo..hi)
            .map(|k| {
                (
                    k,
                    tr.pts[k][0],
                    tr.pts[k][1],
                    tr.states.get(k.saturating_sub(3)),
                )
            })
            .collect();
        panic!(
            "limits exceeded: v {rv} a {ra} j {rj}; first at sample {at} of {}: {around:?}",
            tr.pts.len()
        );
    }
}

pub fn dist(a: &AxisVec, b: &AxisVec) -> f64 {
    (0..AXES).map(|i| (a[i] - b[i]).powi(2)).sum::<f64>().sqrt()
}

/// Distance of `p` from the segment a-b.
pub fn seg_dist(p: &AxisVec, a: &AxisVec, b: &AxisVec) -> f64 {
    let mut d = [0.0; AXES];
    let mut w = [0.0; AXES];
    for i in 0..AXES {
        d[i] = b[i] - a[i];
        w[i] = p[i] - a[i];
    }
    let l2: f64 = d.iter().map(|x| x * x).sum();
    let t = if l2 > 0.0 {
        (w.iter().zip(d.iter()).map(|(x, y)| x * y).sum::<f64>() / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (0..AXES)
        .map(|i| (w[i] - t * d[i]).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// How the segment nearest to a set-point is searched for.
#[derive(Clone, Copy)]
pub enum Nearest {
    /// Around the last nearest segment, moving with the run: for polylines that may come
    /// back near themselves, where the nearest of all segments could be a later pass.
    AlongTheRun,
    /// Every segment: for polylines that cross themselves, where following the run could
    /// jump to the crossing segment and miss the way back.
    AnySegment,
}

/// Largest distance of the set-points from the polyline `verts`, searched as `nearest` says.
pub fn deviation(tr: &Trace, verts: &[AxisVec], nearest: Nearest) -> f64 {
    match nearest {
        Nearest::AlongTheRun => max_deviation(tr, verts),
        Nearest::AnySegment => tr
            .pts
            .iter()
            .map(|q| {
                verts
                    .windows(2)
                    .map(|w| seg_dist(q, &w[0], &w[1]))
                    .fold(f64::INFINITY, f64::min)
            })
            .fold(0.0, f64::max),
    }
}

/// Runs `moves` from `start` under the limits `(v, a, j)` on every axis and checks what every
/// polyline run must keep: each limit on every set-point, no violation counted by the planner,
/// the end point of the last move (within 1 nm), and with `within = Some((verts, p))` every
/// set-point within `p` of the polyline `verts`.
pub fn check_polyline_run(
    (v, a, j): (f64, f64, f64),
    moves: &[Move],
    start: AxisVec,
    within: Option<(&[AxisVec], f64, Nearest)>,
    max_periods: usize,
) -> (Trace, rtcnc_motion::GeometryStats) {
    let mut pl = planner(&limits(v, a, j), start, 2048);
    let tr = run(&mut pl, moves, max_periods);
    assert_limits(&tr, v, a, j);
    assert_eq!(pl.stats().limit_violations, 0);
    let last = *tr.pts.last().unwrap();
    let end = match moves.last().unwrap().kind {
        rtcnc_motion::MoveKind::Line { end, .. } | rtcnc_motion::MoveKind::Arc { end, .. } => end,
        _ => last,
    };
    assert!(
        dist(&last, &end) <= 1e-9,
        "end point off by {}",
        dist(&last, &end)
    );
    if let Some((verts, p, nearest)) = within {
        let dev = deviation(&tr, verts, nearest);
        assert!(dev <= p * (1.0 + 1e-9) + 1e-12, "deviation {dev} > P {p}");
    }
    (tr, pl.geometry_stats())
}

/// Largest distance of the set-points from the programmed polyline `verts`, following the run.
pub fn max_deviation(tr: &Trace, verts: &[AxisVec]) -> f64 {
    let mut worst = 0.0f64;
    let mut seg: usize = 0;
    for p in &tr.pts {
        // Segments are visited in order; search a window around the last nearest one.
        let lo = seg.saturating_sub(4);
        let hi = (seg + 64).min(verts.len() - 1);
        let mut best = f64::INFINITY;
        for s in lo..hi {
            let d = seg_dist(p, &verts[s], &verts[s + 1]);
            if d < best {
                best = d;
                seg = s;
            }
        }
        worst = worst.max(best);
    }
    worst
}

/// Periods from the first set-point that leaves `start` to the last that differs from the
/// end point, times the period (the cycle time as the benchmarks measure it).
pub fn cycle_time(tr: &Trace) -> f64 {
    let start = tr.pts[0];
    let end = *tr.pts.last().unwrap();
    let first = tr.pts.iter().position(|p| *p != start).unwrap_or(0);
    let last = tr.pts.iter().rposition(|p| *p != end).map_or(0, |i| i + 1);
    (last + 1 - first) as f64 * T
}

/// Vertices on a circle of radius `r` around the origin starting at (r, 0), counter-clockwise,
/// with the chord count chosen so that every chord's sagitta r (1 - cos(φ/2)) is at most
/// `tol`, as make_polyline.py does for the benchmark programs (equal chords).
pub fn circle_polyline(r: f64, tol: f64, turns: f64) -> Vec<AxisVec> {
    let phi_max = 2.0 * (1.0 - tol / r).acos();
    let total = 2.0 * std::f64::consts::PI * turns;
    let n = (total / phi_max).ceil() as usize;
    (0..=n)
        .map(|k| {
            let th = total * k as f64 / n as f64;
            p3(r * th.cos(), r * th.sin(), 0.0)
        })
        .collect()
}

/// Ellipse with semi-axes a, b, vertices at equal parameter steps with at most `tol` sagitta
/// (checked numerically per chord by halving the step until it holds).
pub fn ellipse_polyline(a: f64, b: f64, tol: f64) -> Vec<AxisVec> {
    let f = |u: f64| p3(a * u.cos(), b * u.sin(), 0.0);
    let mut n = 16;
    loop {
        let ok = (0..n).all(|k| {
            let (u0, u1) = (
                2.0 * std::f64::consts::PI * k as f64 / n as f64,
                2.0 * std::f64::consts::PI * (k + 1) as f64 / n as f64,
            );
            (1..16).all(|m| {
                let u = u0 + (u1 - u0) * m as f64 / 16.0;
                seg_dist(&f(u), &f(u0), &f(u1)) <= tol
            })
        });
        if ok {
            break;
        }
        n = n * 5 / 4 + 1;
    }
    (0..=n)
        .map(|k| f(2.0 * std::f64::consts::PI * k as f64 / n as f64))
        .collect()
}

pub fn lines(verts: &[AxisVec], feed: f64, mode: PathMode) -> Vec<Move> {
    verts[1..]
        .iter()
        .enumerate()
        .map(|(i, v)| Move::line(*v, feed, mode, i as u32 + 1))
        .collect()
}

/// The path speed stays above zero from the first motion to the last.
pub fn never_stops(tr: &Trace) -> bool {
    let first = tr.speed.iter().position(|v| *v > 0.0).unwrap();
    let last = tr.speed.iter().rposition(|v| *v > 0.0).unwrap();
    tr.speed[first..=last].iter().all(|v| *v > 0.0)
}

/// Whether the trace comes to rest exactly at `c`: a set-point equals it and the steps
/// before and after are at most `step` (J·T³ for jerk J at period T; the first step from
/// rest is J·T³/6).
pub fn rests_at(tr: &Trace, c: &AxisVec, step: f64) -> bool {
    tr.pts
        .windows(3)
        .any(|w| w[1] == *c && dist(&w[0], &w[1]) <= step && dist(&w[2], &w[1]) <= step)
}
