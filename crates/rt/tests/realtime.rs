//! The real-time runner: priority inheritance, start/stop, state, monitor. Tests assert the
//! order of events, never durations.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use rtcnc_rt::{
    BinarySemaphore, Next, PiMutex, RealTimeConfig, RealTimeRunner, RtStartError, SchedulingMode,
    TaskSet, TaskState,
};

type Log = Arc<Mutex<Vec<&'static str>>>;

fn push(log: &Log, what: &'static str) {
    log.lock().unwrap().push(what);
}

/// Classic inversion: low (10) holds the mutex, high (100) wants it, medium (50) is CPU-bound.
/// All on one CPU. With priority inheritance low runs at high's priority until it unlocks,
/// so high gets the mutex before medium runs; without it, medium would run first.
#[test]
fn priority_inheritance_prevents_inversion() {
    let mutex = Arc::new(PiMutex::new(0u32));
    let (wake_low, wake_medium, wake_high) = (
        BinarySemaphore::new("low"),
        BinarySemaphore::new("medium"),
        BinarySemaphore::new("high"),
    );
    let done = BinarySemaphore::new("done");
    let log: Log = Arc::default();
    let mut b = TaskSet::builder();

    let (m, l, wh) = (Arc::clone(&mutex), Arc::clone(&log), wake_high.clone());
    b.event("low", 10, wake_low.trigger(), move |ctx| {
        let mut guard = m.lock();
        push(&l, "low locked");
        wh.signal(); // high preempts here
        ctx.consume(Duration::from_millis(5));
        *guard += 1;
        push(&l, "low unlocks");
        drop(guard);
        Next::Done
    });
    let (m, l, wm) = (Arc::clone(&mutex), Arc::clone(&log), wake_medium.clone());
    b.event("high", 100, wake_high.trigger(), move |_| {
        push(&l, "high wants");
        wm.signal(); // medium is ready from now on, below high
        let mut guard = m.lock();
        push(&l, "high locked");
        *guard += 1;
        Next::Done
    });
    let (l, d) = (Arc::clone(&log), done.clone());
    b.event("medium", 50, wake_medium.trigger(), move |ctx| {
        push(&l, "medium runs");
        ctx.consume(Duration::from_millis(5));
        push(&l, "medium done");
        d.signal();
        Next::Done
    });
    let config = RealTimeConfig {
        scheduling: SchedulingMode::RequireFifo,
        lock_memory: false,
        cpus: Some(vec![0]),
        ..RealTimeConfig::default()
    };
    let handle = match RealTimeRunner::start(b.build().unwrap(), config) {
        Ok(h) => h,
        Err(RtStartError::FifoNotPermitted) => {
            println!(
                "skipped: SCHED_FIFO is not permitted here, priority inheritance cannot be shown"
            );
            return;
        }
        Err(e) => panic!("{e}"),
    };
    std::thread::sleep(Duration::from_millis(30));
    wake_low.signal();
    done.wait_timeout(Duration::from_secs(10)).unwrap();
    let rec = handle.stop();
    assert_eq!(
        *log.lock().unwrap(),
        vec![
            "low locked",
            "high wants",
            "low unlocks",
            "high locked",
            "medium runs",
            "medium done"
        ]
    );
    assert_eq!(*mutex.lock(), 2);
    assert_eq!(rec.monitor().task("high").unwrap().stats().activations, 1);
}

#[test]
fn tasks_report_their_state_and_stop_at_their_next_cycle() {
    let counted = Arc::new(Mutex::new(0u32));
    let gate = BinarySemaphore::new("gate");
    let mut b = TaskSet::builder();
    let t = b.periodic_thread("plc", Duration::from_millis(1), 40);
    let c = Arc::clone(&counted);
    b.periodic(t, "scan", 1, move |_| *c.lock().unwrap() += 1);
    b.event("idle event", 30, gate.trigger(), |_| Next::Done);
    let bg = b.background("self test", |_| Next::Sleep(Duration::from_millis(1)));
    b.start_stopped(bg);
    let config = RealTimeConfig {
        scheduling: SchedulingMode::BestEffort,
        lock_memory: false,
        ..RealTimeConfig::default()
    };
    let handle = RealTimeRunner::start(b.build().unwrap(), config).unwrap();
    let scan = handle.control("scan").unwrap();
    wait_until(|| *counted.lock().unwrap() >= 5);
    scan.stop();
    // Stopped is set at the start of a cycle that saw the request: no body runs after it.
    wait_until(|| scan.state() == TaskState::Stopped);
    let frozen = *counted.lock().unwrap();
    std::thread::sleep(Duration::from_millis(20));
    assert_eq!(
        *counted.lock().unwrap(),
        frozen,
        "a stopped task does not run"
    );
    assert_eq!(scan.state(), TaskState::Stopped);
    assert_eq!(
        handle.control("idle event").unwrap().state(),
        TaskState::Stopped
    );
    assert_eq!(
        handle.control("self test").unwrap().state(),
        TaskState::Stopped
    );
    scan.start();
    wait_until(|| *counted.lock().unwrap() > frozen);
    let rec = handle.stop();
    let stats = rec.monitor().task("scan").unwrap().stats();
    assert_eq!(stats.activations, u64::from(*counted.lock().unwrap()));
    assert_eq!(
        rec.monitor().task("self test").unwrap().stats().activations,
        0
    );
}

/// Polls `condition` until it holds; gives up (failing) after 10 s.
fn wait_until(condition: impl Fn() -> bool) {
    for _ in 0..10_000 {
        if condition() {
            return;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    panic!("condition not reached in 10 s");
}

#[test]
fn threads_run_on_the_cpus_they_are_given() {
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    let wanted = cpus - 1; // the last CPU
    let seen: Arc<Mutex<Vec<i32>>> = Arc::default();
    let mut b = TaskSet::builder();
    let t = b.periodic_thread("pinned", Duration::from_millis(1), 20);
    let s = Arc::clone(&seen);
    b.periodic(t, "where", 1, move |_| {
        // SAFETY: plain query.
        s.lock().unwrap().push(unsafe { libc::sched_getcpu() });
    });
    let config = RealTimeConfig {
        scheduling: SchedulingMode::BestEffort,
        lock_memory: false,
        cpus: Some(vec![0]),
        thread_cpus: vec![("pinned".to_string(), vec![wanted])],
        ..RealTimeConfig::default()
    };
    let handle = RealTimeRunner::start(b.build().unwrap(), config).unwrap();
    wait_until(|| seen.lock().unwrap().len() >= 10);
    drop(handle.stop());
    let seen = seen.lock().unwrap();
    assert!(
        seen.iter().all(|&c| c == wanted as i32),
        "{seen:?} (wanted {wanted})"
    );
}
