//! The real-time runner: priority inheritance, start/stop, state, monitor. Tests assert the
//! order of events, never durations.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use rtcnc_rt::{
    BinarySemaphore, Next, PiMutex, RealTimeConfig, RealTimeRunner, RtStartError, SchedulingMode,
    TaskSet, TaskState,
};

type Log = Arc<Mutex<Vec<&'static str>>>;

/// Tests that pin SCHED_FIFO threads to CPU 0 run one at a time, so they do not disturb
/// each other's order of events.
static CPU0: Mutex<()> = Mutex::new(());

fn cpu0() -> std::sync::MutexGuard<'static, ()> {
    CPU0.lock().unwrap_or_else(|e| e.into_inner())
}

fn push(log: &Log, what: &'static str) {
    log.lock().unwrap().push(what);
}

/// Classic inversion: low (10) holds the mutex, high (100) wants it, medium (50) is CPU-bound.
/// All on one CPU. With priority inheritance low runs at high's priority until it unlocks,
/// so high gets the mutex before medium runs; without it, medium would run first.
#[test]
fn priority_inheritance_prevents_inversion() {
    let _cpu0 = cpu0();
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
    let _cpu0 = cpu0();
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

/// The RTX64 table of SEEDS.md (as in the virtual-time test) on the real-time runner, all
/// threads on one CPU: within every half millisecond the bodies start in the same order as
/// under virtual time. Only the order is compared, never the times. A machine too busy to
/// keep every release (skipped releases) makes the test skip with a message.
#[test]
fn rtx64_table_starts_in_the_same_order_as_in_virtual_time() {
    let _cpu0 = cpu0();
    // (name, period µs, runs, priority, cost µs)
    const RTX64: [(&str, u64, u32, i32, u64); 6] = [
        ("fieldbus", 500, 1, 126, 20),
        ("interpolation", 500, 2, 125, 10),
        ("look-ahead", 1000, 4, 120, 25),
        ("host commands", 1000, 3, 117, 15),
        ("status", 1000, 1, 110, 30),
        ("main", 1000, 1, 1, 300),
    ];
    type StartLog = Arc<Mutex<Vec<(u64, &'static str, u32)>>>;
    let build = |log: &StartLog| {
        let mut b = TaskSet::builder();
        for (name, period_us, runs, priority, cost_us) in RTX64 {
            let thread = b.periodic_thread(name, Duration::from_micros(period_us), priority);
            let log = Arc::clone(log);
            b.periodic(thread, name, runs, move |ctx| {
                // the half millisecond this start belongs to, from the release time
                let slot = ctx.release_time().as_nanos() / 500_000;
                log.lock().unwrap().push((slot, name, ctx.run()));
                ctx.consume(Duration::from_micros(cost_us));
            });
        }
        b.build().unwrap()
    };
    let slots = 40; // 20 ms

    let virtual_log: StartLog = Arc::default();
    let mut sim = rtcnc_rt::VirtualRunner::new(build(&virtual_log));
    sim.run_for(Duration::from_millis(20)).unwrap();

    let real_log: StartLog = Arc::default();
    let config = RealTimeConfig {
        scheduling: SchedulingMode::RequireFifo,
        lock_memory: true,
        cpus: Some(vec![0]),
        ..RealTimeConfig::default()
    };
    let handle = match RealTimeRunner::start(build(&real_log), config) {
        Ok(h) => h,
        Err(RtStartError::FifoNotPermitted) => {
            println!("skipped: SCHED_FIFO is not permitted here, real-time order cannot be shown");
            return;
        }
        Err(e) => panic!("{e}"),
    };
    // main has the lowest priority: once it has started past the window, every thread has
    // finished every cycle of the window (and any skipped release has been counted).
    wait_until(|| {
        real_log
            .lock()
            .unwrap()
            .iter()
            .any(|e| e.1 == "main" && e.0 >= slots)
    });
    let recording = handle.stop();

    // Starts grouped by release slot, in the order they happened within the slot (a stable
    // sort): a low-priority thread delayed into the next half millisecond by something else
    // on the machine still has to start after every higher-priority thread of its own slot.
    let in_window = |log: &StartLog| -> Vec<(u64, &'static str, u32)> {
        let mut starts: Vec<_> = log
            .lock()
            .unwrap()
            .iter()
            .copied()
            .filter(|e| e.0 < slots)
            .collect();
        starts.sort_by_key(|e| e.0);
        starts
    };
    let expected = in_window(&virtual_log);
    assert_eq!(expected.len(), 40 * 3 + 20 * 9);
    let skipped: u64 = recording
        .monitor()
        .stats()
        .iter()
        .map(|s| s.skipped_releases)
        .sum();
    if skipped > 0 {
        println!(
            "skipped: the machine delayed a cycle past its period ({skipped} releases skipped)"
        );
        return;
    }
    assert_eq!(in_window(&real_log), expected);
}

#[test]
fn a_task_that_finishes_its_runs_hands_the_cycle_to_the_next_task() {
    let log: Arc<Mutex<Vec<(&'static str, u32)>>> = Arc::default();
    let mut b = TaskSet::builder();
    let thread = b.periodic_thread("worker", Duration::from_millis(1), 50);
    let l = Arc::clone(&log);
    b.periodic(thread, "queue", 4, move |ctx| {
        l.lock().unwrap().push(("queue", ctx.run()));
        if ctx.run() == 1 {
            ctx.finish_runs();
        }
    });
    let l = Arc::clone(&log);
    b.periodic(thread, "after", 1, move |ctx| {
        l.lock().unwrap().push(("after", ctx.run()))
    });
    let config = RealTimeConfig {
        scheduling: SchedulingMode::BestEffort,
        lock_memory: false,
        ..RealTimeConfig::default()
    };
    let handle = RealTimeRunner::start(b.build().unwrap(), config).unwrap();
    wait_until(|| log.lock().unwrap().len() >= 9);
    let recording = handle.stop();
    let log = log.lock().unwrap();
    let cycles = log.len() / 3;
    let expected: Vec<_> = (0..cycles)
        .flat_map(|_| [("queue", 0), ("queue", 1), ("after", 0)])
        .collect();
    assert_eq!(log[..cycles * 3], expected[..]);
    let queue = recording
        .monitor()
        .task("queue")
        .unwrap()
        .stats()
        .activations;
    let after = recording
        .monitor()
        .task("after")
        .unwrap()
        .stats()
        .activations;
    // The stop may come between the runs of a cycle.
    assert!(
        (2 * after..=2 * after + 2).contains(&queue),
        "{queue} runs of queue, {after} of after"
    );
}

/// `Context::shift_next_release` under real time: the releases (the instants the thread is
/// woken for, as the runner computes them) move by the shifts asked, clamped to a quarter of
/// the period per cycle, and activations keep numbering the grid's periods.
#[test]
fn a_thread_nudges_its_phase_in_real_time_as_in_virtual_time() {
    let log: Arc<Mutex<Vec<(u64, u64, u64)>>> = Arc::default();
    let mut b = TaskSet::builder();
    let thread = b.periodic_thread("bus", Duration::from_millis(1), 50);
    let l = Arc::clone(&log);
    let mut cycles = 0u64;
    b.periodic(thread, "exchange", 1, move |ctx| {
        l.lock()
            .unwrap()
            .push((ctx.release_time().as_nanos(), ctx.activation(), cycles));
        // Counted in cycles run, not activations: a cycle skipped after an overrun on a
        // loaded machine must not lose a shift.
        match cycles {
            2 => ctx.shift_next_release(200_000),
            4 => ctx.shift_next_release(-1_000_000),
            _ => {}
        }
        cycles += 1;
    });
    let config = RealTimeConfig {
        scheduling: SchedulingMode::BestEffort,
        lock_memory: false,
        ..RealTimeConfig::default()
    };
    let handle = RealTimeRunner::start(b.build().unwrap(), config).unwrap();
    wait_until(|| log.lock().unwrap().len() >= 8);
    drop(handle.stop());
    let log = log.lock().unwrap();
    for &(release, activation, cycle) in log.iter() {
        // +200 µs after the third cycle, then −1 ms clamped to −250 µs: −50 µs in all.
        let offset: i64 = match cycle {
            0..=2 => 0,
            3..=4 => 200_000,
            _ => -50_000,
        };
        assert_eq!(
            release as i64,
            activation as i64 * 1_000_000 + offset,
            "cycle {cycle}"
        );
    }
    let activations: Vec<u64> = log.iter().map(|e| e.1).collect();
    assert!(
        activations.windows(2).all(|w| w[1] > w[0]),
        "{activations:?}"
    );
}
