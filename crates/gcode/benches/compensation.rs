//! Throughput of the cutter compensation stage on a long zig-zag contour (every corner
//! alternately convex and concave: an arc added, or an intersection computed).
//! `cargo bench -p rtcnc-gcode --bench compensation`; bench/compensation.sh puts the figure
//! next to LinuxCNC rs274's on the same path.

// criterion_group! and criterion_main! make public functions without docs.
#![allow(missing_docs)]

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use rtcnc_gcode::canon::{Canon, CanonCommand, CompensationSide, Pose, Source};
use rtcnc_gcode::compensation::Compensator;

const MOVES: usize = 100_000;

fn zigzag() -> Vec<Canon> {
    let mut v = Vec::with_capacity(MOVES + 2);
    let at = |line: usize, command| Canon {
        source: Source {
            file: 0,
            line: line as u32,
            n: None,
        },
        command,
    };
    v.push(at(
        0,
        CanonCommand::StartCutterRadiusCompensation {
            side: CompensationSide::Left,
            radius: 0.5,
            orientation: 0,
        },
    ));
    for i in 0..MOVES {
        let t = i as f64 * std::f64::consts::TAU / 50.0;
        let r = if i % 2 == 0 { 50.0 } else { 47.0 };
        let pose = Pose {
            x: r * t.cos(),
            y: r * t.sin(),
            ..Pose::ZERO
        };
        v.push(at(i + 1, CanonCommand::StraightFeed(pose)));
    }
    v.push(at(MOVES + 1, CanonCommand::StopCutterRadiusCompensation));
    v
}

fn bench(c: &mut Criterion) {
    let input = zigzag();
    let mut group = c.benchmark_group("compensation");
    group.throughput(Throughput::Elements(MOVES as u64));
    group.sample_size(20);
    group.bench_function("zigzag_100k_moves", |b| {
        b.iter_batched(
            || input.clone(),
            |input| {
                let mut stage = Compensator::new();
                let mut n = 0usize;
                for c in input {
                    stage.push(c).expect("compensable path");
                    while stage.pop().is_some() {
                        n += 1;
                    }
                }
                stage.finish();
                while stage.pop().is_some() {
                    n += 1;
                }
                n
            },
            criterion::BatchSize::LargeInput,
        )
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
