//! The per-cycle path allocates nothing: a counting allocator watches the threads that run
//! task bodies once the task set is running.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use rtcnc_rt::{
    BinarySemaphore, EventSemaphore, Mailbox, Next, RealTimeConfig, RealTimeRunner, SchedulingMode,
    TaskSet, VirtualRunner, lead_queue, ring,
};

struct Counting;

/// Allocations by watched threads, per test (the tests run in parallel): [virtual, real time].
static WATCHED_ALLOCATIONS: [AtomicU64; 2] = [AtomicU64::new(0), AtomicU64::new(0)];
const VIRTUAL: usize = 0;
const REAL_TIME: usize = 1;

thread_local! {
    /// Which counter this thread's allocations go to, if any.
    static WATCHED: Cell<Option<usize>> = const { Cell::new(None) };
}

fn watch(counter: Option<usize>) {
    WATCHED.with(|w| w.set(counter));
}

fn allocations(counter: usize) -> u64 {
    WATCHED_ALLOCATIONS[counter].load(Ordering::Relaxed)
}

// SAFETY: forwards to the system allocator; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if let Some(counter) = WATCHED.with(|w| w.get()) {
            WATCHED_ALLOCATIONS[counter].fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: same contract as ours.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as ours.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// A servo-like set: two periodic threads passing data through a mailbox and a ring, an
/// event task on the mailbox, one on a semaphore, a deadline miss every 50 cycles, trace on.
fn task_set(watch_in_bodies: bool) -> TaskSet {
    let frames: Mailbox<[f64; 6]> = Mailbox::new("frames", 8).unwrap();
    let tick = BinarySemaphore::new("tick");
    let pulse = EventSemaphore::new("cycle");
    let (mut tx, mut rx) = ring::<[f64; 6]>("setpoints", 8).unwrap();
    let (mut lead_tx, mut lead_rx) = lead_queue::<[f64; 6]>("lead", 16, 0).unwrap();
    let mut b = TaskSet::builder();
    let fast = b.periodic_thread("servo", Duration::from_micros(500), 120);
    let slow = b.periodic_thread("plc", Duration::from_millis(1), 100);
    let (out, t, p) = (frames.clone(), tick.clone(), pulse.clone());
    b.periodic(fast, "interpolate", 2, move |ctx| {
        if watch_in_bodies {
            watch(Some(REAL_TIME));
        }
        let a = ctx.activation() as f64;
        let _ = tx.push([a; 6]);
        // Written ahead, replaced every tenth activation.
        lead_tx.catch_up();
        while lead_tx.lead() < 8 && lead_tx.push([a; 6]).is_ok() {}
        if ctx.activation() % 10 == 0 {
            let from = lead_tx.consumer_next();
            lead_tx.rewind(from);
        }
        let _ = out.try_put([a; 6]);
        t.signal();
        p.pulse();
        if ctx.activation() % 50 == 49 {
            ctx.consume(Duration::from_micros(700)); // overrun: a deadline-miss fault
        }
        ctx.mark("cycle", ctx.activation());
    });
    b.periodic(slow, "scan", 1, move |ctx| {
        if watch_in_bodies {
            watch(Some(REAL_TIME));
        }
        while let Some(v) = rx.pop() {
            std::hint::black_box(v);
        }
        let _ = std::hint::black_box(lead_rx.take(ctx.activation()));
        ctx.consume(Duration::from_micros(50));
    });
    let inbox = frames.clone();
    b.event("log", 20, frames.data_trigger(), move |_| {
        if watch_in_bodies {
            watch(Some(REAL_TIME));
        }
        while inbox.try_get().is_some() {}
        Next::Done
    });
    b.event("count", 30, tick.trigger(), move |_| {
        if watch_in_bodies {
            watch(Some(REAL_TIME));
        }
        Next::Done
    });
    b.event("wait", 40, pulse.trigger(), move |ctx| {
        if watch_in_bodies {
            watch(Some(REAL_TIME));
        }
        if ctx.activation() % 2 == 0 {
            Next::WaitFor {
                trigger: pulse.trigger(),
                timeout: Some(Duration::from_micros(100)),
            }
        } else {
            Next::Done
        }
    });
    b.trace_capacity(256);
    b.build().unwrap()
}

#[test]
fn virtual_time_cycles_do_not_allocate() {
    let mut sim = VirtualRunner::new(task_set(false));
    sim.run_for(Duration::from_millis(10)).unwrap(); // warm-up
    watch(Some(VIRTUAL));
    sim.run_for(Duration::from_millis(200)).unwrap();
    watch(None);
    assert_eq!(allocations(VIRTUAL), 0);
    // the run did work: 200 ms of two threads, and deadline misses were recorded
    let monitor = sim.recording().monitor();
    assert_eq!(monitor.task("scan").unwrap().stats().activations, 210);
    assert!(monitor.fault_count() > 0);
}

#[test]
fn real_time_cycles_do_not_allocate() {
    let config = RealTimeConfig {
        scheduling: SchedulingMode::BestEffort,
        lock_memory: false,
        ..RealTimeConfig::default()
    };
    // Bodies mark their thread as watched on their first run; from then on every allocation
    // on an executive thread is counted.
    let handle = RealTimeRunner::start(task_set(true), config).unwrap();
    let monitor = std::sync::Arc::clone(handle.monitor());
    for _ in 0..10_000 {
        if monitor.task("scan").unwrap().stats().activations >= 100 {
            break;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    let recording = handle.stop();
    assert!(
        recording
            .monitor()
            .task("scan")
            .unwrap()
            .stats()
            .activations
            >= 100
    );
    assert_eq!(allocations(REAL_TIME), 0);
}
