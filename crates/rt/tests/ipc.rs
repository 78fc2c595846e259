//! Mailbox, semaphore and ring semantics, used from task bodies under both schedulers and
//! from threads outside the task set.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use rtcnc_rt::{
    BinarySemaphore, CountingSemaphore, EventSemaphore, IpcError, Mailbox, Next, RealTimeConfig,
    RealTimeRunner, Recording, SchedulingMode, TaskSet, VirtualRunner, Wake, ring,
};

#[derive(Clone, Copy, Debug)]
enum Sched {
    Virtual,
    Real,
}

/// Runs `set` for `ms` milliseconds of simulated time, or, under the real-time runner, until
/// `done` holds (at most 10 s of wall time): only the order of events is asserted, never time.
fn run(set: TaskSet, sched: Sched, ms: u64, done: impl Fn() -> bool) -> Recording {
    match sched {
        Sched::Virtual => {
            let mut sim = VirtualRunner::new(set);
            sim.run_for(Duration::from_millis(ms)).unwrap();
            sim.into_recording()
        }
        Sched::Real => {
            let config = RealTimeConfig {
                scheduling: SchedulingMode::BestEffort,
                lock_memory: false,
                ..RealTimeConfig::default()
            };
            let handle = RealTimeRunner::start(set, config).unwrap();
            for _ in 0..10_000 {
                if done() {
                    break;
                }
                std::thread::sleep(Duration::from_millis(1));
            }
            handle.stop()
        }
    }
}

type Log = Arc<Mutex<Vec<String>>>;

fn mailbox_ops_in_a_task(sched: Sched) {
    let mb: Mailbox<u32> = Mailbox::new("cmd", 3).unwrap();
    let log: Log = Arc::default();
    let mut b = TaskSet::builder();
    let t = b.periodic_thread("t", Duration::from_millis(1), 50);
    let (m, l) = (mb.clone(), Arc::clone(&log));
    b.periodic(t, "ops", 1, move |ctx| {
        if ctx.activation() != 0 {
            return;
        }
        let mut out = l.lock().unwrap();
        out.push(format!("empty get {:?}", m.try_get()));
        for v in [1, 2, 3] {
            m.try_put(v).unwrap();
        }
        let full = m.try_put(4).unwrap_err();
        out.push(format!("full put {:?} {}", full.reason, full.value));
        out.push(format!(
            "full front {:?}",
            m.put_front(9).unwrap_err().reason
        ));
        out.push(format!("peek {:?} len {}", m.peek(), m.len()));
        out.push(format!("get {:?}", m.try_get()));
        m.put_front(0).unwrap();
        out.push(format!("after urgent {:?}", m.peek()));
        out.push(format!("blocking get {:?}", m.get().unwrap_err()));
        out.push(format!(
            "timed put {:?}",
            m.put_timeout(5, Duration::from_millis(1))
                .unwrap_err()
                .reason
        ));
        out.push(format!("cleared {}", m.clear()));
        out.push(format!("empty {}", m.is_empty()));
    });
    run(b.build().unwrap(), sched, 3, || {
        log.lock().unwrap().len() == 10
    });
    assert_eq!(
        *log.lock().unwrap(),
        vec![
            "empty get None",
            "full put Full 4",
            "full front Full",
            "peek Some(1) len 3",
            "get Some(1)",
            "after urgent Some(0)",
            "blocking get BlockingInTask",
            "timed put BlockingInTask",
            "cleared 3",
            "empty true",
        ],
        "{sched:?}"
    );
}

#[test]
fn mailbox_full_empty_put_front_peek_clear_in_virtual_time() {
    mailbox_ops_in_a_task(Sched::Virtual);
}

#[test]
fn mailbox_full_empty_put_front_peek_clear_in_real_time() {
    mailbox_ops_in_a_task(Sched::Real);
}

/// An event task waits on a semaphore with a timeout twice: the first wait times out, the
/// second is satisfied by a periodic task's signal in its 61st run (60 ms).
fn timed_wait(sched: Sched) {
    let go = BinarySemaphore::new("go");
    let data = BinarySemaphore::new("data");
    let log: Log = Arc::default();
    let mut b = TaskSet::builder();
    let t = b.periodic_thread("clock", Duration::from_millis(1), 60);
    let (g, d) = (go.clone(), data.clone());
    let mut runs = 0u32;
    b.periodic(t, "signaller", 1, move |_| {
        runs += 1;
        match runs {
            1 => g.signal(),
            61 => d.signal(),
            _ => {}
        }
    });
    let (l, d) = (Arc::clone(&log), data.clone());
    b.event("waiter", 70, go.trigger(), move |ctx| {
        let mut out = l.lock().unwrap();
        out.push(format!("{:?}", ctx.wake()));
        match out.len() {
            1 => Next::WaitFor {
                trigger: d.trigger(),
                timeout: Some(Duration::from_millis(5)),
            },
            2 => Next::WaitFor {
                trigger: d.trigger(),
                timeout: None,
            },
            _ => Next::Done,
        }
    });
    let rec = run(b.build().unwrap(), sched, 80, || {
        log.lock().unwrap().len() == 3
    });
    assert_eq!(
        *log.lock().unwrap(),
        vec!["Triggered", "TimedOut", "Triggered"],
        "{sched:?}"
    );
    assert!(
        !data.is_signalled(),
        "the wake-up took the binary semaphore"
    );
    assert_eq!(rec.monitor().task("waiter").unwrap().stats().activations, 3);
}

#[test]
fn timed_wait_in_virtual_time() {
    timed_wait(Sched::Virtual);
}

#[test]
fn timed_wait_in_real_time() {
    timed_wait(Sched::Real);
}

/// Pulse releases every waiter once and leaves the event reset; a counting semaphore wakes
/// its task once per unit; the ring passes every item in order.
fn pulse_counting_and_ring(sched: Sched) {
    let event = EventSemaphore::new("cycle start");
    let units = CountingSemaphore::new("parts", 0, 3).unwrap();
    let (mut tx, mut rx) = ring::<u64>("samples", 4).unwrap();
    let log: Log = Arc::default();
    let sum = Arc::new(Mutex::new((0u64, 0u64)));
    let mut b = TaskSet::builder();
    let t = b.periodic_thread("driver", Duration::from_millis(1), 90);
    let (e, u, l) = (event.clone(), units.clone(), Arc::clone(&log));
    let mut runs = 0u64;
    b.periodic(t, "drive", 1, move |_| {
        // counted runs, not period indices: under load a real-time release may be skipped
        let a = runs;
        runs += 1;
        if a == 1 {
            e.pulse();
        }
        if a == 2 {
            for _ in 0..3 {
                u.signal().unwrap();
            }
            // No task takes from this one, so its maximum is reached whatever runs in parallel.
            let spare = CountingSemaphore::new("spare", 0, 2).unwrap();
            spare.signal().unwrap();
            spare.signal().unwrap();
            l.lock()
                .unwrap()
                .push(format!("over max {:?}", spare.signal().unwrap_err()));
        }
        if a < 20 {
            let _ = tx.push(a);
        }
    });
    let s = Arc::clone(&sum);
    b.periodic(t, "drain", 1, move |_| {
        while let Some(v) = rx.pop() {
            let mut s = s.lock().unwrap();
            s.0 += v;
            s.1 += 1;
        }
    });
    for name in ["waiter a", "waiter b"] {
        let l = Arc::clone(&log);
        b.event(name, 80, event.trigger(), move |ctx| {
            assert_eq!(ctx.wake(), Wake::Triggered);
            l.lock().unwrap().push(format!("{name} released"));
            Next::Done
        });
    }
    let l = Arc::clone(&log);
    b.event("counter", 10, units.trigger(), move |_| {
        l.lock().unwrap().push("unit".to_string());
        Next::Done
    });
    let rec = run(b.build().unwrap(), sched, 30, || {
        log.lock().unwrap().len() == 6 && sum.lock().unwrap().1 == 20
    });
    let mut got = log.lock().unwrap().clone();
    got.sort();
    assert_eq!(
        got,
        vec![
            "over max AtMaximum",
            "unit",
            "unit",
            "unit",
            "waiter a released",
            "waiter b released"
        ],
        "{sched:?}"
    );
    assert!(!event.is_set());
    assert_eq!(units.count(), 0);
    assert_eq!(*sum.lock().unwrap(), ((0..20).sum::<u64>(), 20));
    assert_eq!(
        rec.monitor().task("waiter a").unwrap().stats().activations,
        1
    );
}

#[test]
fn pulse_counting_semaphore_and_ring_in_virtual_time() {
    pulse_counting_and_ring(Sched::Virtual);
}

#[test]
fn pulse_counting_semaphore_and_ring_in_real_time() {
    pulse_counting_and_ring(Sched::Real);
}

#[test]
fn event_semaphore_set_stays_set_and_wakes_each_edge_once() {
    let ev = EventSemaphore::new("door");
    let log: Log = Arc::default();
    let mut b = TaskSet::builder();
    let t = b.periodic_thread("t", Duration::from_millis(1), 50);
    let e = ev.clone();
    b.periodic(t, "switch", 1, move |ctx| match ctx.activation() {
        1 => e.set(),
        2 => e.set(), // already set: no new edge
        3 => e.reset(),
        4 => e.set(),
        _ => {}
    });
    let l = Arc::clone(&log);
    b.event("watch", 40, ev.trigger(), move |ctx| {
        l.lock().unwrap().push(format!("{}", ctx.start_time()));
        Next::Done
    });
    let mut sim = VirtualRunner::new(b.build().unwrap());
    sim.run_for(Duration::from_millis(6)).unwrap();
    assert_eq!(*log.lock().unwrap(), vec!["0.001000000 s", "0.004000000 s"]);
    assert!(ev.is_set());
    assert_eq!(
        ev.wait_timeout(Duration::from_millis(1)),
        Ok(()),
        "a set event does not block"
    );
}

#[test]
fn outside_threads_block_on_the_os_clock_while_virtual_time_runs() {
    let replies: Mailbox<u64> = Mailbox::new("replies", 2).unwrap();
    // A thread outside the task set (an HMI) waits for a reply with a generous timeout.
    let r = replies.clone();
    let hmi = std::thread::spawn(move || r.get_timeout(Duration::from_secs(30)));
    let mut b = TaskSet::builder();
    let t = b.periodic_thread("t", Duration::from_millis(1), 50);
    let r = replies.clone();
    b.periodic(t, "reply", 1, move |ctx| {
        if ctx.activation() == 5 {
            r.try_put(42).unwrap();
        }
    });
    let mut sim = VirtualRunner::new(b.build().unwrap());
    sim.run_for(Duration::from_millis(10)).unwrap();
    assert_eq!(hmi.join().unwrap(), Ok(42));
    // Nothing more comes: a timed get from outside times out; a blocking put to a full box too.
    assert_eq!(
        replies.get_timeout(Duration::from_millis(2)),
        Err(IpcError::Timeout)
    );
    replies.try_put(1).unwrap();
    replies.try_put(2).unwrap();
    let rejected = replies
        .put_timeout(3, Duration::from_millis(2))
        .unwrap_err();
    assert_eq!((rejected.reason, rejected.value), (IpcError::Timeout, 3));
    assert_eq!(replies.get(), Ok(1));
    assert_eq!(replies.put(3).map_err(|e| e.reason), Ok(()));
    assert_eq!(
        BinarySemaphore::new("s").wait_timeout(Duration::from_millis(1)),
        Err(IpcError::Timeout)
    );
}
