//! The random spline programs of `tests/splines_random.rs` (G5/G5.1 chains, tangent or
//! not, quadratic and cubic, G61 and G64, feeds 10-150 mm/s; alone and with lines between
//! them), shared with the `splines_seeds` example (included with `#[path]`).
#![allow(dead_code)]

use rtcnc_motion::{AXES, AxisVec, Bezier, Move, PathMode};

fn p3(x: f64, y: f64, z: f64) -> AxisVec {
    let mut p = [0.0; AXES];
    p[0] = x;
    p[1] = y;
    p[2] = z;
    p
}

fn blend(tolerance: f64) -> PathMode {
    PathMode::Blend {
        tolerance,
        merge_tolerance: 0.0,
    }
}

/// xorshift64: the programs are the same on every run.
pub struct Rng(pub u64);

impl Rng {
    pub fn f(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A program of one to four splines; with `lines`, each followed by a line along its end
/// tangent (60 %) or at a random angle.
pub fn program(rng: &mut Rng, lines: bool) -> (Vec<Move>, AxisVec) {
    let n = 1 + (rng.f() * 4.0) as usize;
    let feed = 10.0 + rng.f() * 140.0;
    let mode = if rng.f() < 0.5 {
        PathMode::ExactPath
    } else {
        blend(0.01)
    };
    let mut moves = Vec::new();
    let mut p = p3(0.0, 0.0, 0.0);
    let mut prev_dir: Option<[f64; 2]> = None;
    for k in 0..n {
        let sc = 1.0 + rng.f() * 20.0;
        let mut c1 = p3(
            p[0] + (rng.f() - 0.5) * sc,
            p[1] + (rng.f() - 0.5) * sc,
            0.0,
        );
        if let Some(d) = prev_dir {
            // Mostly tangent to the move before (as G5 chains are).
            if rng.f() < 0.7 {
                let l = rng.f() * sc * 0.5 + 0.1;
                c1 = p3(p[0] + d[0] * l, p[1] + d[1] * l, 0.0);
            }
        }
        let end = p3(
            p[0] + (rng.f() - 0.5) * sc,
            p[1] + (rng.f() - 0.5) * sc,
            0.0,
        );
        let (control, last) = if rng.f() < 0.3 {
            (Bezier::Quadratic(c1), c1)
        } else {
            let c2 = p3(
                end[0] + (rng.f() - 0.5) * sc,
                end[1] + (rng.f() - 0.5) * sc,
                0.0,
            );
            (Bezier::Cubic([c1, c2]), c2)
        };
        let d = [end[0] - last[0], end[1] - last[1]];
        let l = d[0].hypot(d[1]);
        prev_dir = Some([d[0] / l, d[1] / l]);
        moves.push(Move::spline(end, control, feed, mode, k as u32 + 1));
        p = end;
        if lines {
            let l = rng.f() * sc;
            let ang = if rng.f() < 0.6 {
                0.0
            } else {
                (rng.f() - 0.5) * 3.0
            };
            let (c, s) = (ang.cos(), ang.sin());
            let d = prev_dir.unwrap();
            let dir = [c * d[0] - s * d[1], s * d[0] + c * d[1]];
            let e = p3(p[0] + l * dir[0], p[1] + l * dir[1], 0.0);
            moves.push(Move::line(e, feed, mode, k as u32 + 100));
            prev_dir = Some(dir);
            p = e;
        }
    }
    (moves, p)
}
