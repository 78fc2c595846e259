//! Scan time of the mill logic, of a 2000-rung generated program and of 50 object-oriented
//! stations called through an interface (examples/plc/stations.st), and compile time.
//! Goals: mill scan <= 5 us; 2000 rungs <= 200 us per scan (<= 100 ns per statement).

// criterion_group! and criterion_main! make public functions without docs.
#![allow(missing_docs)]

use std::sync::Arc;
use std::time::Duration;

use criterion::{Criterion, black_box, criterion_group, criterion_main};
use rtcnc_plc::{PlcConfig, Runtime, Signal, compile};

mod generated;

const MILL: &str = include_str!("../../../examples/plc/mill.st");
const MILL_TOML: &str = include_str!("../../../examples/plc/mill.toml");
const STATIONS: &str = include_str!("../../../examples/plc/stations.st");

fn mill_running() -> Runtime {
    let mut rt = Runtime::new(Arc::new(compile(MILL, "mill.st").unwrap()));
    let cfg: PlcConfig = toml::from_str(MILL_TOML).unwrap();
    rt.configure(&cfg).unwrap();
    rt.input_image_mut()[0] = 0b0000_1111; // e-stop ok, door closed, lube pressure, clamped
    rt.set_signal_bool(Signal::EstopReset, true);
    rt.set_signal_bool(Signal::MachineOnRequest, true);
    rt.set_signal_bool(Signal::SpindleOn, true);
    rt.set_signal(Signal::SpindleSpeedCommand, 1200.0);
    rt.set_signal(Signal::SpindleSpeedActual, 1199.0);
    rt.set_signal_bool(Signal::CoolantFlood, true);
    for k in 0..100 {
        rt.scan(Duration::from_millis(4 * k)).unwrap();
    }
    assert!(rt.signal_bool(Signal::SpindleAtSpeed));
    rt
}

/// CPU time of this thread: on a loaded machine (CI, shared development boxes) wall time
/// includes time the scheduler gave to other processes; CPU time does not.
fn thread_cpu_time() -> Duration {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes into the timespec we own; the clock id is valid.
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    Duration::new(ts.tv_sec as u64, ts.tv_nsec as u32)
}

fn bench_both(c: &mut Criterion, name: &str, rt: &mut Runtime, period_ms: u64) {
    let mut t = 1_000_000u64;
    c.bench_function(&format!("{name} (wall time)"), |b| {
        b.iter(|| {
            t += period_ms;
            rt.scan(black_box(Duration::from_millis(t))).unwrap();
        })
    });
    c.bench_function(&format!("{name} (thread CPU time)"), |b| {
        b.iter_custom(|iters| {
            let start = thread_cpu_time();
            for _ in 0..iters {
                t += period_ms;
                rt.scan(black_box(Duration::from_millis(t))).unwrap();
            }
            thread_cpu_time() - start
        })
    });
}

fn bench(c: &mut Criterion) {
    let mut mill = mill_running();
    bench_both(c, "mill.st scan", &mut mill, 4);

    let src = generated::ladder_program(2000);
    c.bench_function("compile 2000-rung program", |b| {
        b.iter(|| compile(black_box(&src), "ladder.st").unwrap())
    });

    let mut ladder = Runtime::new(Arc::new(compile(&src, "ladder.st").unwrap()));
    for (i, b) in ladder.input_image_mut().iter_mut().enumerate() {
        *b = (i as u8).wrapping_mul(37) | 1;
    }
    bench_both(c, "2000-rung scan", &mut ladder, 4);

    let mut stations = Runtime::new(Arc::new(compile(STATIONS, "stations.st").unwrap()));
    for k in 0..100 {
        stations.scan(Duration::from_millis(4 * k)).unwrap();
    }
    bench_both(c, "50-station method scan", &mut stations, 4);
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30).measurement_time(Duration::from_secs(3)).warm_up_time(Duration::from_secs(1));
    targets = bench
}
criterion_main!(benches);
