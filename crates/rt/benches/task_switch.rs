//! Task switch time: two event tasks of the real-time runner, pinned to one CPU, wake each
//! other through binary semaphores (ping-pong). One round trip is two switches. The
//! RT-Linux CNC paper (SEEDS.md) reports a maximum task switch under 35 µs.

// criterion_group! and criterion_main! make public functions without docs.
#![allow(missing_docs)]

use std::sync::Arc;
use std::time::{Duration, Instant};

use criterion::{Criterion, criterion_group, criterion_main};
use rtcnc_rt::histogram::LinearHistogram;
use rtcnc_rt::{BinarySemaphore, Next, RealTimeConfig, RealTimeRunner, SchedulingMode, TaskSet};

struct PingPong {
    ping: BinarySemaphore,
    done: BinarySemaphore,
    handle: rtcnc_rt::RealTimeHandle,
    target: Arc<std::sync::atomic::AtomicU64>,
    round_trips: Arc<LinearHistogram>,
}

fn start() -> PingPong {
    let ping = BinarySemaphore::new("ping");
    let pong = BinarySemaphore::new("pong");
    let done = BinarySemaphore::new("done");
    let target = Arc::new(std::sync::atomic::AtomicU64::new(0));
    let round_trips = Arc::new(LinearHistogram::new(100, 10_000)); // 0.1 µs bins up to 1 ms
    let mut b = TaskSet::builder();
    let (po, d, t, h) = (
        pong.clone(),
        done.clone(),
        Arc::clone(&target),
        Arc::clone(&round_trips),
    );
    let mut count = 0u64;
    let mut last: Option<u64> = None;
    b.event("ping", 90, ping.trigger(), move |ctx| {
        let now = ctx.start_time().as_nanos();
        if let Some(prev) = last {
            h.record(now - prev);
        }
        count += 1;
        if count >= t.load(std::sync::atomic::Ordering::Acquire) {
            count = 0;
            last = None;
            d.signal();
        } else {
            last = Some(now);
            po.signal();
        }
        Next::Done
    });
    let pi = ping.clone();
    b.event("pong", 90, pong.trigger(), move |_| {
        pi.signal();
        Next::Done
    });
    let config = RealTimeConfig {
        scheduling: SchedulingMode::BestEffort,
        lock_memory: true,
        cpus: Some(vec![0]),
        ..RealTimeConfig::default()
    };
    let handle = RealTimeRunner::start(b.build().unwrap(), config).unwrap();
    std::thread::sleep(Duration::from_millis(40));
    PingPong {
        ping,
        done,
        handle,
        target,
        round_trips,
    }
}

fn task_switch(c: &mut Criterion) {
    let pp = start();
    println!(
        "task switch bench: {}",
        if pp.handle.is_fifo() {
            "SCHED_FIFO, both tasks on CPU 0"
        } else {
            "SCHED_FIFO not permitted: normal threads, figures are not real-time"
        }
    );
    c.bench_function("semaphore ping-pong round trip (2 task switches)", |b| {
        b.iter_custom(|iters| {
            pp.target
                .store(iters.max(1), std::sync::atomic::Ordering::Release);
            let t0 = Instant::now();
            pp.ping.signal();
            pp.done.wait().unwrap();
            let elapsed = t0.elapsed();
            // Idle as long as we ran: two SCHED_FIFO tasks ping-ponging without a break would
            // hit the kernel's real-time throttling (95 % per second) and measure that instead.
            std::thread::sleep(elapsed);
            elapsed
        })
    });
    let s = pp.round_trips.summary();
    println!(
        "task switch (half a round trip) over {} round trips: mean {:.2} us, p99 {:.2} us, max {:.2} us; RT-Linux paper: max < 35 us -> max ratio {:.3}",
        s.count,
        s.mean as f64 / 2000.0,
        s.p99 as f64 / 2000.0,
        s.max as f64 / 2000.0,
        s.max as f64 / 2000.0 / 35.0
    );
    drop(pp.handle.stop());
}

criterion_group!(benches, task_switch);
criterion_main!(benches);
