//! Cost of rounding corners that involve arcs (G64 P): a zigzag of 2 mm lines and arcs of
//! R 3 mm over 0.8 rad, each junction a 0.4 rad corner, G64 P0.01, F 30 mm/s; 100 mm/s,
//! 1000 mm/s², 50 000 mm/s³ per axis. Throughput is in moves (one corner each) through
//! the look-ahead with `push_all`.
//!
//! `cargo bench -p rtcnc-motion --bench arc_corners`

// criterion_group! and criterion_main! make public functions without docs.
#![allow(missing_docs)]

use std::time::Duration;

use criterion::{BatchSize, Criterion, Throughput, criterion_group, criterion_main};
use rtcnc_motion::{AXES, AxisVec, Move, PathMode};

#[path = "support/programs.rs"]
mod programs;
use programs::{planner, push_program};

fn zigzag(n: usize) -> (AxisVec, Vec<Move>) {
    let mode = PathMode::Blend {
        tolerance: 0.01,
        merge_tolerance: 0.0,
    };
    let (r, sweep, turn) = (3.0, 0.8f64, 0.4f64);
    let mut at = [0.0f64; 2];
    let mut dir = 0.0f64;
    let mut moves = Vec::with_capacity(n);
    let p = |x: [f64; 2]| {
        let mut v = [0.0; AXES];
        v[0] = x[0];
        v[1] = x[1];
        v
    };
    for k in 0..n {
        if k % 2 == 0 {
            at = [at[0] + 2.0 * dir.cos(), at[1] + 2.0 * dir.sin()];
            moves.push(Move::line(p(at), 30.0, mode, k as u32 + 1));
            dir += turn;
        } else {
            // Counter-clockwise on odd pairs, clockwise on even ones.
            let s = if (k / 2) % 2 == 0 { 1.0 } else { -1.0 };
            let c = [at[0] - s * r * dir.sin(), at[1] + s * r * dir.cos()];
            let a0 = (at[1] - c[1]).atan2(at[0] - c[0]);
            let a1 = a0 + s * sweep;
            at = [c[0] + r * a1.cos(), c[1] + r * a1.sin()];
            moves.push(Move::arc(
                p(at),
                [c[0], c[1], 0.0],
                [0.0, 0.0, s],
                0,
                30.0,
                mode,
                k as u32 + 1,
            ));
            dir += s * sweep - turn;
        }
    }
    (p([0.0, 0.0]), moves)
}

fn bench(c: &mut Criterion) {
    let (start, moves) = zigzag(400);
    let blends = {
        let mut pl = planner(start, 4 * moves.len() + 16, 10_000.0);
        pl.push_all(&moves).unwrap();
        pl.flush();
        pl.geometry_stats().blends
    };
    println!("arc corners: {} moves, {blends} blended", moves.len());
    let mut g = c.benchmark_group("arc_corners");
    g.measurement_time(Duration::from_secs(3)).sample_size(20);
    g.throughput(Throughput::Elements(moves.len() as u64));
    g.bench_function("look-ahead: push line/arc corners", |b| {
        b.iter_batched(
            || planner(start, 4 * moves.len() + 16, 10_000.0),
            |mut pl| {
                push_program(&mut pl, &moves);
                pl
            },
            BatchSize::LargeInput,
        )
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
