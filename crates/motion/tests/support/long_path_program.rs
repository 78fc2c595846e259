//! The long-path program of `tests/long_paths.rs`, shared with the `long_paths` example
//! (included with `#[path]`): rapids back and forth between X −1000 and X 1000, each followed
//! by a zigzag of feed lines (blended at G64 P0.01) that ends in an exact stop, until the
//! path is `length` mm long; then a circle of R 10 in 0.5 mm chords at G64 P0.01 and a square
//! at G61 (its corners stop). Lengths and feeds are in the units of a machine `scale` times
//! the benchmark machine (100 mm/s, 1000 mm/s², 50 000 mm/s³ per axis × `scale`).
#![allow(dead_code)]

use rtcnc_motion::{AXES, AxisVec, Move, PathMode};

fn p3(x: f64, y: f64) -> AxisVec {
    let mut p = [0.0; AXES];
    p[0] = x;
    p[1] = y;
    p
}

fn dist(a: &AxisVec, b: &AxisVec) -> f64 {
    (0..AXES).map(|i| (a[i] - b[i]).powi(2)).sum::<f64>().sqrt()
}

/// The moves and the end point; the feed lines run at 30 % of the axis speed.
pub fn long_path_program(length: f64, scale: f64) -> (Vec<Move>, AxisVec) {
    let mode = PathMode::Blend {
        tolerance: 0.01,
        merge_tolerance: 0.0,
    };
    let feed = 30.0 * scale;
    // (end point, feed: None for a rapid, mode)
    let mut path: Vec<(AxisVec, Option<f64>, PathMode)> = Vec::new();
    let mut done = 0.0;
    let mut at = p3(0.0, 0.0);
    let mut side: f64 = 1.0;
    while done < length {
        let x = 1000.0 * side;
        path.push((p3(x, 0.0), None, mode));
        for k in 1..=4 {
            let v = p3(x - side * 10.0 * f64::from(k), f64::from(k % 2));
            let m = if k == 4 { PathMode::ExactStop } else { mode };
            path.push((v, Some(feed), m));
        }
        for (v, _, _) in &path[path.len() - 5..] {
            done += dist(&at, v);
            at = *v;
        }
        side = -side;
    }
    path.push((p3(10.0, 0.0), None, mode));
    // A circle of R 10 from (10, 0) in 128 equal chords (0.49 mm).
    for k in 1..=128 {
        let th = std::f64::consts::TAU * f64::from(k) / 128.0;
        path.push((p3(10.0 * th.cos(), 10.0 * th.sin()), Some(feed), mode));
    }
    for v in [p3(20.0, 0.0), p3(20.0, 10.0), p3(10.0, 10.0), p3(10.0, 0.0)] {
        path.push((v, Some(feed), PathMode::ExactPath));
    }
    let moves = path
        .iter()
        .enumerate()
        .map(|(i, (v, feed, m))| match feed {
            None => Move::rapid(*v, *m, i as u32 + 1),
            Some(f) => Move::line(*v, *f, *m, i as u32 + 1),
        })
        .collect();
    (moves, p3(10.0, 0.0))
}
