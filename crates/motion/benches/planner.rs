//! Cost of the path planner: look-ahead throughput (segments per second through geometry,
//! speed-limit sampling and the braking-curve passes) and interpolation cost per servo period
//! per axis, on a CAM-like polyline (a circle of R 10 in 0.28 mm chords, 1 µm chord
//! tolerance, G64 P0.001, F 100 mm/s, 100 mm/s, 1000 mm/s², 50 000 mm/s³ per axis).
//!
//! The same two figures on a chain of tangent G5 splines (cubic arches of 2 mm, F 60 mm/s).
//!
//! `cargo bench -p rtcnc-motion --bench planner`; goals: ≥ 500 000 segments/s, ≤ 50 ns per
//! axis per period.

// criterion_group! and criterion_main! make public functions without docs.
#![allow(missing_docs)]

use std::hint::black_box;
use std::time::Duration;

use criterion::{BatchSize, Criterion, Throughput, criterion_group, criterion_main};

#[path = "support/programs.rs"]
mod programs;
use programs::{planner, polyline, push_program, spline_chain};
use rtcnc_motion::AXES;

fn bench(c: &mut Criterion) {
    let (start, moves) = polyline(4.0);
    let mut g = c.benchmark_group("planner");
    g.measurement_time(Duration::from_secs(3)).sample_size(20);
    g.throughput(Throughput::Elements(moves.len() as u64));
    g.bench_function("look-ahead: push segments", |b| {
        b.iter_batched(
            || planner(start, 4 * moves.len() + 16, 1000.0),
            |mut pl| {
                push_program(&mut pl, &moves);
                pl
            },
            BatchSize::LargeInput,
        )
    });
    // Interpolation: 200 periods at speed in the middle of the program.
    const PERIODS: u64 = 200;
    g.throughput(Throughput::Elements(PERIODS));
    g.bench_function("interpolate: one servo period (3 axes)", |b| {
        b.iter_batched(
            || {
                let mut pl = planner(start, 4 * moves.len() + 16, 1000.0);
                for m in &moves {
                    pl.push(m).unwrap();
                }
                pl.flush();
                let mut j = [0.0; 3];
                for _ in 0..300 {
                    pl.next(&mut j);
                }
                pl
            },
            |mut pl| {
                let mut j = [0.0; 3];
                for _ in 0..PERIODS {
                    black_box(pl.next(&mut j));
                }
                pl
            },
            BatchSize::LargeInput,
        )
    });
    g.finish();
}

fn bench_splines(c: &mut Criterion) {
    let moves = spline_chain(400);
    let start = [0.0; AXES];
    let mut g = c.benchmark_group("planner, G5 splines");
    g.measurement_time(Duration::from_secs(3)).sample_size(20);
    g.throughput(Throughput::Elements(moves.len() as u64));
    g.bench_function("look-ahead: push splines", |b| {
        b.iter_batched(
            || planner(start, 4 * moves.len() + 16, 1000.0),
            |mut pl| {
                push_program(&mut pl, &moves);
                pl
            },
            BatchSize::LargeInput,
        )
    });
    const PERIODS: u64 = 200;
    g.throughput(Throughput::Elements(PERIODS));
    g.bench_function("interpolate: one servo period (3 axes)", |b| {
        b.iter_batched(
            || {
                let mut pl = planner(start, 4 * moves.len() + 16, 1000.0);
                pl.push_all(&moves).unwrap();
                pl.flush();
                let mut j = [0.0; 3];
                for _ in 0..300 {
                    pl.next(&mut j);
                }
                pl
            },
            |mut pl| {
                let mut j = [0.0; 3];
                for _ in 0..PERIODS {
                    black_box(pl.next(&mut j));
                }
                pl
            },
            BatchSize::LargeInput,
        )
    });
    g.finish();
}

criterion_group!(benches, bench, bench_splines);
criterion_main!(benches);
