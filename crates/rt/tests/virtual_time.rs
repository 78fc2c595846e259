//! The task model under the virtual-time runner: exact schedules worked out from the rules.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use rtcnc_rt::{
    ConfigError, FaultCode, Mailbox, MissReaction, Next, TaskSet, TaskSetBuilder, TaskState, Time,
    VirtualRunner, Wake,
};

type Log = Arc<Mutex<Vec<(u64, &'static str, u32)>>>;
type ValueLog = Arc<Mutex<Vec<(u64, &'static str, u64)>>>;

const US: u64 = 1_000;
const MS: u64 = 1_000_000;

/// The RTX64 soft motion controller's threads (SEEDS.md), with execution costs under 10 % of
/// the period except `main`, which is long enough to be preempted at each half millisecond.
/// (name, period µs, runs, priority, cost per run µs)
const RTX64: [(&str, u64, u32, i32, u64); 6] = [
    ("fieldbus", 500, 1, 126, 20),
    ("interpolation", 500, 2, 125, 10),
    ("look-ahead", 1000, 4, 120, 25),
    ("host commands", 1000, 3, 117, 15), // three slaves
    ("status", 1000, 1, 110, 30),
    ("main", 1000, 1, 1, 300),
];

fn rtx64_set(log: &Log) -> TaskSet {
    let mut b = TaskSet::builder();
    for (name, period_us, runs, priority, cost_us) in RTX64 {
        let thread = b.periodic_thread(name, Duration::from_micros(period_us), priority);
        let log = Arc::clone(log);
        b.periodic(thread, name, runs, move |ctx| {
            log.lock()
                .unwrap()
                .push((ctx.start_time().as_nanos(), name, ctx.run()));
            ctx.consume(Duration::from_micros(cost_us));
        });
    }
    b.build().unwrap()
}

#[test]
fn rtx64_table_runs_in_priority_order_at_the_expected_times() {
    let log: Log = Arc::default();
    let mut sim = VirtualRunner::new(rtx64_set(&log));
    sim.run_for(Duration::from_millis(100)).unwrap();

    // Worked out from the rules: every 0.5 ms the two fast threads run back to back (fieldbus
    // 20 µs, then interpolation twice 10 µs); on each whole millisecond the 1 ms threads follow
    // in priority order: look-ahead 4 × 25 µs from 40 µs, host commands 3 × 15 µs from 140 µs,
    // status at 185 µs, main at 215 µs (it is preempted at 500 µs by the fast threads and ends
    // at 555 µs). No start time depends on main, since it has the lowest priority.
    let mut expected = Vec::new();
    for slot in 0..200u64 {
        let t = slot * 500 * US;
        expected.push((t, "fieldbus", 0));
        expected.push((t + 20 * US, "interpolation", 0));
        expected.push((t + 30 * US, "interpolation", 1));
        if slot % 2 == 0 {
            for run in 0..4 {
                expected.push((t + (40 + 25 * run as u64) * US, "look-ahead", run));
            }
            for run in 0..3 {
                expected.push((t + (140 + 15 * run as u64) * US, "host commands", run));
            }
            expected.push((t + 185 * US, "status", 0));
            expected.push((t + 215 * US, "main", 0));
        }
    }
    let got = log.lock().unwrap().clone();
    assert_eq!(got.len(), 200 * 3 + 100 * 9);
    assert_eq!(got, expected);

    let monitor = sim.recording().monitor();
    let main = monitor.task("main").unwrap().stats();
    assert_eq!(main.activations, 100);
    // 215 µs late, 300 µs of work plus 40 µs of preemption by the fast threads
    assert_eq!(main.lateness.max, 215 * US);
    assert_eq!(main.execution.min, 340 * US);
    assert_eq!(main.execution.max, 340 * US);
    let interp = monitor.task("interpolation").unwrap().stats();
    assert_eq!(interp.activations, 400);
    assert_eq!(interp.lateness.max, 30 * US);
    assert_eq!(interp.execution.max, 10 * US);
    // The jitter histogram: runs start 20 µs and 30 µs after release, 200 times each. Above
    // 64 ns a bucket is 1/32 of its octave: 20 000 ns falls in 19 968..=20 479 and 30 000 ns
    // in 29 696..=30 207 (octave 2^14, width 512).
    assert_eq!(
        monitor
            .task("interpolation")
            .unwrap()
            .lateness_histogram()
            .buckets(),
        vec![(20_479, 200), (30_207, 200)]
    );
    assert_eq!(monitor.fault_count(), 0);
    assert_eq!(monitor.task("status").unwrap().state(), TaskState::Waiting);
}

#[test]
fn event_tasks_are_woken_by_a_mailbox_in_priority_order() {
    let frames: Mailbox<u64> = Mailbox::new("frames", 4).unwrap();
    let log: ValueLog = Arc::default();
    let mut b = TaskSet::builder();
    let producer = b.periodic_thread("producer", Duration::from_millis(1), 100);
    let out = frames.clone();
    b.periodic(producer, "produce", 1, move |ctx| {
        out.try_put(ctx.activation()).unwrap();
        ctx.consume(Duration::from_micros(100));
    });
    // A watcher above the producer only peeks; a consumer below it takes the frame.
    let mut watchers = Vec::new();
    for (name, priority, takes) in [("urgent watcher", 127, false), ("consumer", 50, true)] {
        let inbox = frames.clone();
        let log = Arc::clone(&log);
        let trigger = if takes {
            frames.data_trigger()
        } else {
            // fires on each pulse from the producer side below
            let ev = rtcnc_rt::EventSemaphore::new("frame ready");
            watchers.push(ev.clone());
            ev.trigger()
        };
        b.event(name, priority, trigger, move |ctx| {
            assert_eq!(ctx.wake(), Wake::Triggered);
            let value = if takes { inbox.try_get() } else { inbox.peek() };
            log.lock()
                .unwrap()
                .push((ctx.start_time().as_nanos(), name, value.unwrap_or(999)));
            Next::Done
        });
    }
    let pulse = watchers.pop().unwrap();
    let thread = b.periodic_thread("pulser", Duration::from_millis(1), 90);
    b.periodic(thread, "pulse", 1, move |_| pulse.pulse());
    let mut sim = VirtualRunner::new(b.build().unwrap());
    sim.run_for(Duration::from_millis(3)).unwrap();

    // At each millisecond k the producer (100) puts k and works 100 µs; the pulser (90) runs
    // after it, at k + 100 µs, and wakes the urgent watcher (127) at once; the consumer (50)
    // runs last. The mailbox never holds more than one frame.
    let mut expected = Vec::new();
    for k in 0..3u64 {
        expected.push((k * MS + 100 * US, "urgent watcher", k));
        expected.push((k * MS + 100 * US, "consumer", k));
    }
    assert_eq!(*log.lock().unwrap(), expected);
    assert!(frames.is_empty());
    let monitor = sim.recording().monitor();
    assert_eq!(monitor.task("consumer").unwrap().stats().activations, 3);
    assert_eq!(
        monitor.task("consumer").unwrap().state(),
        TaskState::Stopped
    );
}

#[test]
fn an_overrunning_task_gives_exactly_the_expected_deadline_misses() {
    let hook_calls = Arc::new(AtomicU64::new(0));
    let mut b = TaskSet::builder();
    let thread = b.periodic_thread("servo", Duration::from_millis(1), 100);
    let task = b.periodic(thread, "position control", 1, |ctx| {
        // normally 200 µs; activation 3 takes 1.5 ms, activation 7 takes 2.2 ms
        let cost = match ctx.activation() {
            3 => 1_500,
            7 => 2_200,
            _ => 200,
        };
        ctx.consume(Duration::from_micros(cost));
    });
    let calls = Arc::clone(&hook_calls);
    b.on_deadline_miss(
        task,
        MissReaction::Hook(Arc::new(move |fault| {
            assert_eq!(fault.code, FaultCode::DeadlineMiss);
            calls.fetch_add(1, Ordering::Relaxed);
        })),
    );
    let mut sim = VirtualRunner::new(b.build().unwrap());
    sim.run_for(Duration::from_millis(12)).unwrap();

    // Activation 3 (release 3 ms) ends at 4.5 ms: 0.5 ms late; release 4 ms is skipped and the
    // next cycle starts at 5 ms. Activation 7 ends at 9.2 ms: 1.2 ms late; releases 8 and 9
    // are skipped, the next cycle starts at 10 ms.
    let monitor = sim.recording().monitor();
    let faults = monitor.raw_faults();
    let got: Vec<(Time, FaultCode, u64)> =
        faults.iter().map(|f| (f.time, f.code, f.detail)).collect();
    assert_eq!(
        got,
        vec![
            (Time::from_micros(4_500), FaultCode::DeadlineMiss, 500 * US),
            (
                Time::from_micros(9_200),
                FaultCode::DeadlineMiss,
                1_200 * US
            ),
        ]
    );
    assert_eq!(hook_calls.load(Ordering::Relaxed), 2);
    let stats = monitor.task("position control").unwrap().stats();
    assert_eq!(stats.deadline_misses, 2);
    assert_eq!(stats.skipped_releases, 3);
    // releases run: 0 1 2 3 5 6 7 10 11
    assert_eq!(stats.activations, 9);
    assert_eq!(monitor.faults()[0].task, "position control");
}

fn traced_set() -> TaskSet {
    let log: Log = Arc::default();
    let mut b: TaskSetBuilder = TaskSet::builder();
    for (name, period_us, runs, priority, cost_us) in RTX64 {
        let thread = b.periodic_thread(name, Duration::from_micros(period_us), priority);
        let log = Arc::clone(&log);
        b.periodic(thread, name, runs, move |ctx| {
            log.lock().unwrap().push((0, name, 0));
            if ctx.activation() % 10 == 0 {
                ctx.mark("tenth", ctx.activation());
            }
            ctx.consume(Duration::from_micros(cost_us));
        });
    }
    b.build().unwrap()
}

#[test]
fn two_virtual_runs_give_byte_identical_traces() {
    let run = || {
        let mut sim = VirtualRunner::new(traced_set());
        sim.run_for(Duration::from_millis(20)).unwrap();
        sim.recording().trace().to_chrome_json()
    };
    let first = run();
    let second = run();
    assert_eq!(first, second);

    let json: serde_json::Value = serde_json::from_str(&first).unwrap();
    let events = json["traceEvents"].as_array().unwrap();
    let spans = events.iter().filter(|e| e["ph"] == "X").count();
    // 40 half-ms slots × 3 runs + 20 ms × 9 runs
    assert_eq!(spans, 40 * 3 + 20 * 9);
    let main_span = events
        .iter()
        .find(|e| e["ph"] == "X" && e["name"] == "main")
        .unwrap();
    assert_eq!(main_span["ts"].as_f64(), Some(215.0));
    assert_eq!(main_span["dur"].as_f64(), Some(340.0));
}

#[test]
fn a_host_time_profile_changes_nothing_in_the_run_and_counts_every_body_run() {
    let mut plain = VirtualRunner::new(traced_set());
    plain.run_for(Duration::from_millis(20)).unwrap();
    let mut profiled = VirtualRunner::new(traced_set()).with_host_profile();
    profiled.run_for(Duration::from_millis(20)).unwrap();
    assert_eq!(
        plain.recording().trace().to_chrome_json(),
        profiled.recording().trace().to_chrome_json()
    );
    assert!(plain.host_profile().is_none());
    let profile = profiled.host_profile().unwrap();
    let monitor = profiled.recording().monitor();
    assert_eq!(profile.tasks.len(), monitor.tasks().len());
    for (name, runs, _ns) in &profile.tasks {
        assert_eq!(
            *runs,
            monitor.task(name).unwrap().stats().activations,
            "{name}"
        );
    }
}

#[test]
fn a_task_asked_to_stop_stops_at_its_next_cycle_and_restarts() {
    let count = Arc::new(AtomicU64::new(0));
    let mut b = TaskSet::builder();
    let thread = b.periodic_thread("plc", Duration::from_millis(1), 80);
    let c = Arc::clone(&count);
    b.periodic(thread, "scan", 1, move |_| {
        c.fetch_add(1, Ordering::Relaxed);
    });
    let set = b.build().unwrap();
    let control = set.control("scan").unwrap();
    let mut sim = VirtualRunner::new(set);
    sim.run_for(Duration::from_micros(2_500)).unwrap(); // runs at 0, 1, 2 ms
    control.stop();
    sim.run_for(Duration::from_millis(3)).unwrap(); // 3, 4, 5 ms skipped
    assert_eq!(control.state(), TaskState::Stopped);
    control.start();
    sim.run_for(Duration::from_micros(1_500)).unwrap(); // runs at 6 ms
    assert_eq!(count.load(Ordering::Relaxed), 4);
}

#[test]
fn bad_declarations_are_refused_with_the_name_at_fault() {
    let empty = |_: &mut rtcnc_rt::Context<'_>| {};
    let mut b = TaskSet::builder();
    let t = b.periodic_thread("servo", Duration::ZERO, 10);
    b.periodic(t, "pid", 1, empty);
    let e = b.build().err().unwrap();
    assert_eq!(
        e,
        ConfigError::ZeroPeriod {
            thread: "servo".into()
        }
    );
    assert_eq!(
        e.to_string(),
        "thread 'servo': period must be greater than zero"
    );

    let mut b = TaskSet::builder();
    let t = b.periodic_thread("servo", Duration::from_millis(1), 128);
    b.periodic(t, "pid", 1, empty);
    assert_eq!(
        b.build().err().unwrap().to_string(),
        "thread 'servo': priority 128 is outside 0..=127"
    );

    let mut b = TaskSet::builder();
    let t = b.periodic_thread("servo", Duration::from_millis(1), 10);
    b.periodic(t, "pid", 1, empty);
    b.periodic(t, "pid", 1, empty);
    let e = b.build().err().unwrap();
    assert_eq!(e.code(), "duplicate_name");
    assert_eq!(e.to_string(), "task name 'pid' is used twice");

    let mut b = TaskSet::builder();
    let t = b.periodic_thread("servo", Duration::from_millis(1), 10);
    b.periodic(t, "pid", 0, empty);
    assert_eq!(
        b.build().err().unwrap(),
        ConfigError::ZeroRuns { task: "pid".into() }
    );

    let mut b = TaskSet::builder();
    let mb: Mailbox<u8> = Mailbox::new("cmd", 1).unwrap();
    b.event("hmi", -1, mb.data_trigger(), |_| Next::Done);
    assert_eq!(
        b.build().err().unwrap().to_string(),
        "task 'hmi': priority -1 is outside 0..=127"
    );

    let mut b = TaskSet::builder();
    b.periodic_thread("idle", Duration::from_millis(1), 10);
    assert_eq!(
        b.build().err().unwrap().to_string(),
        "thread 'idle' has no tasks"
    );

    let e = Mailbox::<u8>::new("frames", 0).err().unwrap();
    assert_eq!(
        e.to_string(),
        "channel 'frames': capacity must be at least 1"
    );
    assert_eq!(e.code(), "zero_capacity");
}

#[test]
fn a_task_that_never_lets_time_pass_is_reported_as_a_livelock() {
    let mb: Mailbox<u8> = Mailbox::new("never taken", 1).unwrap();
    mb.try_put(1).unwrap();
    let mut b = TaskSet::builder();
    b.event("stuck", 10, mb.data_trigger(), |_| Next::Done);
    let mut sim = VirtualRunner::new(b.build().unwrap());
    let e = sim.run_for(Duration::from_millis(1)).err().unwrap();
    assert_eq!(e.code(), "livelock");
    assert!(e.to_string().contains("'stuck'"), "{e}");
}

#[test]
fn background_tasks_run_in_what_is_left() {
    let starts: Arc<Mutex<Vec<u64>>> = Arc::default();
    let continued = Arc::new(AtomicU64::new(0));
    let mut b = TaskSet::builder();
    let thread = b.periodic_thread("servo", Duration::from_millis(1), 10);
    b.periodic(thread, "control", 1, |ctx| {
        ctx.consume(Duration::from_micros(100))
    });
    let s = Arc::clone(&starts);
    b.background("self test", move |ctx| {
        s.lock().unwrap().push(ctx.start_time().as_nanos());
        Next::Sleep(Duration::from_millis(1))
    });
    let c = Arc::clone(&continued);
    b.background("housekeeping", move |_| {
        c.fetch_add(1, Ordering::Relaxed);
        Next::Continue
    });
    let set = b.build().unwrap();
    let control = set.control("housekeeping").unwrap();
    let mut sim = VirtualRunner::new(set);
    sim.run_for(Duration::from_millis(1)).unwrap();
    // Each background run takes at least 10 µs. In the first millisecond the servo thread
    // takes 0..100 µs; the self test runs at 100 µs (to 110 µs), housekeeping fills
    // 110..1000 µs with 89 runs of 10 µs.
    assert_eq!(continued.load(Ordering::Relaxed), 89);
    control.stop();
    sim.run_for(Duration::from_millis(4)).unwrap();
    // The self test sleeps 1 ms after each 10 µs run: 100, 1110, 2120, 3130, 4140 µs (never
    // inside the servo thread's first 100 µs of a millisecond).
    assert_eq!(
        *starts.lock().unwrap(),
        vec![100 * US, 1_110 * US, 2_120 * US, 3_130 * US, 4_140 * US]
    );
    let monitor = sim.recording().monitor();
    assert_eq!(
        monitor.task("self test").unwrap().state(),
        TaskState::Suspended
    );
    assert_eq!(
        monitor.task("housekeeping").unwrap().state(),
        TaskState::Stopped
    );
    // housekeeping saw its stop at its next run (at 1 ms, after the servo's 100 µs, the self
    // test's turn is at 1110 µs): 89 runs in the first millisecond and none after.
    assert_eq!(continued.load(Ordering::Relaxed), 89);
}

#[test]
fn faults_raised_by_tasks_are_logged_and_traced_and_the_log_is_bounded() {
    let mut b = TaskSet::builder();
    b.fault_capacity(2).trace_capacity(8);
    let thread = b.periodic_thread("plc", Duration::from_millis(1), 50);
    b.periodic(thread, "scan", 1, |ctx| {
        if ctx.activation() % 4 == 3 {
            ctx.raise_fault(7, "limit switch X+", ctx.activation());
        }
    });
    let mut sim = VirtualRunner::new(b.build().unwrap());
    sim.run_for(Duration::from_millis(12)).unwrap();
    let monitor = sim.recording().monitor();
    // faults at 3, 7 and 11 ms; the log keeps two and counts three
    assert_eq!(monitor.fault_count(), 3);
    let faults = monitor.faults();
    assert_eq!(faults.len(), 2);
    assert_eq!(faults[1].time, Time::from_millis(7));
    assert_eq!(faults[1].code, FaultCode::User(7));
    assert_eq!(faults[1].message, "limit switch X+ (code 7, value 7)");
    assert_eq!(faults[1].task, "scan");
    // 12 spans + 3 faults in a lane of 8: the last 8 are kept, 7 dropped
    let trace = sim.recording().trace();
    assert_eq!(trace.event_count(), 8);
    assert_eq!(trace.dropped(), 7);
    let json: serde_json::Value = serde_json::from_str(&trace.to_chrome_json()).unwrap();
    let last_fault = json["traceEvents"]
        .as_array()
        .unwrap()
        .iter()
        .rfind(|e| e["cat"] == "fault")
        .unwrap()
        .clone();
    assert_eq!(last_fault["name"], "limit switch X+");
    assert_eq!(last_fault["ts"].as_f64(), Some(11_000.0));
    assert_eq!(last_fault["args"]["value"], 11);
}

#[test]
fn own_deadlines_of_periodic_and_event_tasks_give_exactly_the_expected_misses() {
    let setpoints: Mailbox<u64> = Mailbox::new("setpoints", 4).unwrap();
    let mut b = TaskSet::builder();
    let servo = b.periodic_thread("servo", Duration::from_millis(1), 100);
    let read = b.periodic(servo, "read inputs", 1, |ctx| {
        let cost = if ctx.activation() == 2 { 150 } else { 20 };
        ctx.consume(Duration::from_micros(cost));
    });
    b.deadline(read, Duration::from_micros(100));
    let out = setpoints.clone();
    b.periodic(servo, "pid", 1, move |ctx| {
        out.try_put(ctx.activation()).unwrap();
        let cost = if ctx.activation() == 5 { 1_200 } else { 50 };
        ctx.consume(Duration::from_micros(cost));
    });
    let inbox = setpoints.clone();
    let interp = b.event("interp", 50, setpoints.data_trigger(), move |ctx| {
        let mut cost = 100;
        while let Some(v) = inbox.try_get() {
            if v == 8 {
                cost = 400;
            }
        }
        ctx.consume(Duration::from_micros(cost));
        Next::Done
    });
    b.deadline(interp, Duration::from_micros(300));
    let mut sim = VirtualRunner::new(b.build().unwrap());
    sim.run_for(Duration::from_millis(10)).unwrap();

    // Worked out by hand (µs): activation 2: read inputs runs 2000..2150, its deadline is
    // 2100. Activation 5: pid runs 5020..6220 past the period (6000) and release 6000 is
    // skipped; interp, woken by pid's put at 5020, can only run 6220..6320 (deadline 5320).
    // Activation 8: interp runs 8070..8470 (deadline 8020 + 300 = 8320).
    let monitor = sim.recording().monitor();
    let got: Vec<(u64, String, u64)> = monitor
        .raw_faults()
        .iter()
        .map(|f| {
            let name = monitor.tasks()[f.task].name().to_string();
            (f.time.as_nanos() / US, name, f.detail / US)
        })
        .collect();
    assert_eq!(
        got,
        vec![
            (2_150, "read inputs".to_string(), 50),
            (6_220, "pid".to_string(), 220),
            (6_320, "interp".to_string(), 1_000),
            (8_470, "interp".to_string(), 150),
        ]
    );
    assert_eq!(monitor.task("pid").unwrap().stats().skipped_releases, 1);
    assert_eq!(monitor.task("interp").unwrap().stats().deadline_misses, 2);

    let mut b = TaskSet::builder();
    let t = b.periodic_thread("servo", Duration::from_millis(1), 100);
    let task = b.periodic(t, "pid", 1, |_| {});
    b.deadline(task, Duration::ZERO);
    assert_eq!(
        b.build().err().unwrap().to_string(),
        "task 'pid': deadline must be greater than zero"
    );
    let mut b = TaskSet::builder();
    let task = b.background("self test", |_| Next::Done);
    b.deadline(task, Duration::from_millis(1));
    assert_eq!(b.build().err().unwrap().code(), "deadline_on_background");
}

/// A thread's cycle: "queue" (4 runs of 10 µs) declares its remaining runs empty in run 1,
/// then "after" (5 µs). Worked out: queue runs 0 and 1 at 0 and 10 µs, after at 20 µs, in
/// every millisecond; the runs not made are not counted.
fn drained_queue_set(log: &Log) -> TaskSet {
    let mut b = TaskSet::builder();
    let thread = b.periodic_thread("worker", Duration::from_millis(1), 50);
    let l = Arc::clone(log);
    b.periodic(thread, "queue", 4, move |ctx| {
        l.lock()
            .unwrap()
            .push((ctx.start_time().as_nanos(), "queue", ctx.run()));
        ctx.consume(Duration::from_micros(10));
        if ctx.run() == 1 {
            ctx.finish_runs();
        }
    });
    let l = Arc::clone(log);
    b.periodic(thread, "after", 1, move |ctx| {
        l.lock()
            .unwrap()
            .push((ctx.start_time().as_nanos(), "after", ctx.run()));
        ctx.consume(Duration::from_micros(5));
    });
    b.build().unwrap()
}

#[test]
fn a_task_that_finishes_its_runs_hands_the_cycle_to_the_next_task() {
    let log: Log = Arc::default();
    let mut sim = VirtualRunner::new(drained_queue_set(&log));
    sim.run_for(Duration::from_millis(3)).unwrap();
    let mut expected = Vec::new();
    for ms in 0..3 {
        let t = ms * MS;
        expected.extend([
            (t, "queue", 0),
            (t + 10 * US, "queue", 1),
            (t + 20 * US, "after", 0),
        ]);
    }
    assert_eq!(*log.lock().unwrap(), expected);
    let monitor = sim.recording().monitor();
    assert_eq!(monitor.task("queue").unwrap().stats().activations, 6);
    assert_eq!(monitor.task("after").unwrap().stats().activations, 3);
}

/// A thread that nudges its own phase (`Context::shift_next_release`), as the fieldbus thread
/// follows a bus's distributed clock: every release after a shift moves by it, the shifts of
/// one cycle add up and are clamped to a quarter of the period, activations count on by one
/// per cycle, and a thread that asks nothing keeps the period grid.
#[test]
fn a_thread_nudges_its_phase_and_the_other_threads_keep_the_grid() {
    let log: ValueLog = Arc::default();
    let mut b = TaskSet::builder();
    let bus = b.periodic_thread("bus", Duration::from_millis(1), 100);
    let l = Arc::clone(&log);
    b.periodic(bus, "exchange", 1, move |ctx| {
        l.lock()
            .unwrap()
            .push((ctx.release_time().as_nanos(), "exchange", ctx.activation()));
        match ctx.activation() {
            // +30 µs, then +100 µs asked in two calls of one cycle.
            2 => ctx.shift_next_release(30_000),
            4 => {
                ctx.shift_next_release(60_000);
                ctx.shift_next_release(40_000);
            }
            // Far more than a quarter period earlier: moved by 250 µs only.
            6 => ctx.shift_next_release(-900_000),
            _ => {}
        }
    });
    let second = Arc::clone(&log);
    b.periodic(bus, "after", 1, move |ctx| {
        // The thread's second function sees the same release and may nudge it too.
        if ctx.activation() == 8 {
            ctx.shift_next_release(-5_000);
        }
        second
            .lock()
            .unwrap()
            .push((ctx.start_time().as_nanos(), "after", ctx.activation()));
    });
    let other = b.periodic_thread("other", Duration::from_millis(1), 50);
    let l = Arc::clone(&log);
    b.periodic(other, "other", 1, move |ctx| {
        l.lock()
            .unwrap()
            .push((ctx.release_time().as_nanos(), "other", ctx.activation()));
    });
    let mut sim = VirtualRunner::new(b.build().unwrap());
    sim.run_for(Duration::from_micros(10_500)).unwrap();
    let log = log.lock().unwrap();
    // Worked out from the rules: offset 0 up to activation 2, 30 µs from 3, 130 µs from 5,
    // 130 − 250 = −120 µs from 7, −125 µs from 9.
    let offset = |k: i64| match k {
        0..=2 => 0,
        3..=4 => 30_000,
        5..=6 => 130_000,
        7..=8 => -120_000,
        _ => -125_000,
    };
    let exchanges: Vec<(u64, u64)> = log
        .iter()
        .filter(|e| e.1 == "exchange")
        .map(|e| (e.0, e.2))
        .collect();
    let expected: Vec<(u64, u64)> = (0..11i64)
        .map(|k| ((k * 1_000_000 + offset(k)) as u64, k as u64))
        .collect();
    assert_eq!(exchanges, expected);
    // The second function runs right after the first, in the same shifted cycle.
    let after: Vec<(u64, u64)> = log
        .iter()
        .filter(|e| e.1 == "after")
        .map(|e| (e.0, e.2))
        .collect();
    assert_eq!(after, expected);
    let others: Vec<(u64, u64)> = log
        .iter()
        .filter(|e| e.1 == "other")
        .map(|e| (e.0, e.2))
        .collect();
    let grid: Vec<(u64, u64)> = (0..11u64).map(|k| (k * MS, k)).collect();
    assert_eq!(others, grid);
    // No release was late: a nudge is not a wake-up latency.
    let monitor = sim.recording().monitor();
    let stats = monitor.task("exchange").unwrap().stats();
    assert_eq!(stats.deadline_misses, 0);
}

#[test]
fn only_periodic_bodies_are_marked_as_periodic() {
    // (task, what `in_periodic_body` said inside it)
    let seen: Arc<Mutex<Vec<(&'static str, bool)>>> = Arc::default();
    let frames: Mailbox<u64> = Mailbox::new("frames", 4).unwrap();
    let mut b = TaskSet::builder();
    let thread = b.periodic_thread("servo", Duration::from_millis(1), 10);
    let (s, out) = (Arc::clone(&seen), frames.clone());
    b.periodic(thread, "control", 1, move |ctx| {
        s.lock()
            .unwrap()
            .push(("control", rtcnc_rt::in_periodic_body()));
        out.try_put(ctx.activation()).unwrap();
    });
    let (s, inbox) = (Arc::clone(&seen), frames.clone());
    b.event("consumer", 5, frames.data_trigger(), move |_| {
        inbox.try_get();
        s.lock()
            .unwrap()
            .push(("consumer", rtcnc_rt::in_periodic_body()));
        Next::Done
    });
    let s = Arc::clone(&seen);
    b.background("self test", move |_| {
        s.lock()
            .unwrap()
            .push(("self test", rtcnc_rt::in_periodic_body()));
        Next::Sleep(Duration::from_millis(1))
    });
    let mut sim = VirtualRunner::new(b.build().unwrap());
    sim.run_for(Duration::from_micros(500)).unwrap();
    assert!(!rtcnc_rt::in_periodic_body());
    assert_eq!(
        *seen.lock().unwrap(),
        [("control", true), ("consumer", false), ("self test", false)]
    );
}
