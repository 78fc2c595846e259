//! Virtual-time scheduler speed: simulated seconds per wall second for a 1 kHz thread with
//! four task functions (interpolate, servo, PLC, I/O), each declaring 50 µs of work and
//! passing data through a mailbox to an event task. Goal: at least 1000×.

// criterion_group! and criterion_main! make public functions without docs.
#![allow(missing_docs)]

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use rtcnc_rt::{Mailbox, Next, TaskSet, VirtualRunner};

/// The kernel's shape of work: six periodic threads at 1 kHz, 13 body runs per period
/// (two functions in the first thread, two threads with four runs), bodies that declare no
/// processor time, and an event task that is never woken: what the runner itself costs per
/// body run.
fn kernel_shaped_set() -> TaskSet {
    let idle: Mailbox<u64> = Mailbox::new("idle", 4).unwrap();
    let mut b = TaskSet::builder();
    let ms = Duration::from_millis(1);
    let threads = [
        ("fieldbus", 126, &["position control", "drive io"][..], 1),
        ("machine logic", 125, &["machine logic"][..], 1),
        ("interpolation", 124, &["interpolation"][..], 1),
        ("look-ahead", 120, &["look-ahead"][..], 4),
        ("command parsing", 117, &["command parsing"][..], 4),
        ("status feedback", 110, &["status feedback"][..], 1),
    ];
    for (thread, priority, tasks, runs) in threads {
        let th = b.periodic_thread(thread, ms, priority);
        for &name in tasks {
            let mut state = 0u64;
            b.periodic(th, name, runs, move |ctx| {
                state = state.wrapping_add(ctx.activation());
                black_box(state);
            });
        }
    }
    let inbox = idle.clone();
    b.event("tool compensation", 119, idle.data_trigger(), move |_| {
        black_box(inbox.try_get());
        Next::Done
    });
    b.build().unwrap()
}

fn task_set() -> TaskSet {
    let frames: Mailbox<u64> = Mailbox::new("frames", 16).unwrap();
    let mut b = TaskSet::builder();
    let servo = b.periodic_thread("servo", Duration::from_millis(1), 120);
    for name in ["interpolate", "servo", "plc", "io"] {
        let out = frames.clone();
        let mut state = 0u64;
        b.periodic(servo, name, 1, move |ctx| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(ctx.activation());
            if name == "io" {
                let _ = out.try_put(state);
            }
            ctx.consume(Duration::from_micros(50));
        });
    }
    let inbox = frames.clone();
    b.event("log", 10, frames.data_trigger(), move |_| {
        while let Some(v) = inbox.try_get() {
            black_box(v);
        }
        Next::Done
    });
    b.build().unwrap()
}

fn virtual_speed(c: &mut Criterion) {
    c.bench_function("virtual time: 1 s of a 1 kHz thread + 4 tasks", |b| {
        b.iter_batched(
            || VirtualRunner::new(task_set()),
            |mut sim| sim.run_for(Duration::from_secs(1)).unwrap(),
            BatchSize::LargeInput,
        )
    });
    let mut sim = VirtualRunner::new(task_set());
    let simulated = Duration::from_secs(100);
    let t0 = Instant::now();
    sim.run_for(simulated).unwrap();
    let wall = t0.elapsed();
    println!(
        "virtual-time speed: {:.0} simulated s per wall s ({} s simulated in {:.3} s; goal >= 1000x)",
        simulated.as_secs_f64() / wall.as_secs_f64(),
        simulated.as_secs(),
        wall.as_secs_f64()
    );
}

fn runner_overhead(c: &mut Criterion) {
    c.bench_function(
        "virtual time: 1 s of the kernel's six threads, zero-cost bodies",
        |b| {
            b.iter_batched(
                || VirtualRunner::new(kernel_shaped_set()),
                |mut sim| sim.run_for(Duration::from_secs(1)).unwrap(),
                BatchSize::LargeInput,
            )
        },
    );
    let mut sim = VirtualRunner::new(kernel_shaped_set());
    let simulated = Duration::from_secs(20);
    let t0 = Instant::now();
    sim.run_for(simulated).unwrap();
    let wall = t0.elapsed();
    let runs: u64 = sim
        .recording()
        .monitor()
        .tasks()
        .iter()
        .map(|t| t.stats().activations)
        .sum();
    println!(
        "virtual-time runner overhead: {:.1} ns per body run, {:.2} µs per simulated ms \
         ({runs} body runs in {:.3} s)",
        wall.as_nanos() as f64 / runs as f64,
        wall.as_secs_f64() * 1e6 / (simulated.as_secs_f64() * 1e3),
        wall.as_secs_f64()
    );
}

criterion_group!(benches, virtual_speed, runner_overhead);
criterion_main!(benches);
