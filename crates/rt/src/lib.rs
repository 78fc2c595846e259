//! `rtcnc-rt`: the real-time executive of rtcnc. It knows nothing about CNC.
//!
//! A [`TaskSet`] is declared once at start-up with a [`TaskSetBuilder`]: periodic threads
//! (period, priority 0..=127) each running an ordered list of task functions a given number
//! of times per activation; event tasks woken by a [`Trigger`] (a mailbox or a semaphore);
//! background tasks running in what time is left. The same task set then runs on either
//!
//! - [`VirtualRunner`]: one thread, a simulated clock, fixed-priority preemptive scheduling
//!   of one simulated processor; deterministic (same schedule, monitor and trace bytes on
//!   every run) and much faster than real time; or
//! - [`RealTimeRunner`]: one OS thread per periodic thread and per event task, SCHED_FIFO
//!   priorities, locked memory, absolute wake-ups on `CLOCK_MONOTONIC`.
//!
//! Task bodies run to completion and see the executive only through [`Context`] (time,
//! activation, trace marks, faults), so they cannot tell which runner runs them. A task
//! that has to wait returns [`Next::WaitFor`] instead of blocking.
//!
//! IPC ([`Mailbox`], [`BinarySemaphore`], [`CountingSemaphore`], [`EventSemaphore`],
//! [`PiMutex`], [`ring`]) works under both runners. The [`Monitor`] keeps each task's
//! activations, execution time, start lateness and deadline misses; the trace exports as
//! Chrome trace-event JSON.
//!
//! # Real-time use
//!
//! A periodic task's body may call the IPC objects' non-blocking operations (`try_put`,
//! `try_get`, `peek`, `try_wait`, `signal`, `set`, `pulse`, `reset`), [`PiMutex::lock`],
//! the producer and consumer sides of [`ring`], [`seqlock`], [`latest`] and [`lead_queue`],
//! and [`Context`]'s methods; [`in_periodic_body`] tells whether the caller is one. The
//! blocking calls (`put`, `get`, `wait` and their `_timeout` forms) refuse to run inside
//! any task body ([`IpcError::BlockingInTask`]) rather than block it. The constructors,
//! [`TaskSetBuilder`], the runners and the exports of the monitor and the trace are set-up
//! or reporting and may allocate. Each public function's doc says it in a line of its own,
//! `Real-time: yes (...)` or `Real-time: no (why)`; `crates/kernel/tests/real_time_docs.rs`
//! checks that every one has it.
//!
//! ```
//! use std::time::Duration;
//! use rtcnc_rt::{Mailbox, Next, TaskSet, VirtualRunner};
//!
//! let frames: Mailbox<u32> = Mailbox::new("frames", 8).unwrap();
//! let mut set = TaskSet::builder();
//! let servo = set.periodic_thread("servo", Duration::from_millis(1), 120);
//! let out = frames.clone();
//! set.periodic(servo, "interpolate", 1, move |ctx| {
//!     let _ = out.try_put(ctx.activation() as u32);
//! });
//! let inbox = frames.clone();
//! set.event("log", 10, frames.data_trigger(), move |_ctx| {
//!     while inbox.try_get().is_some() {}
//!     Next::Done
//! });
//! let mut sim = VirtualRunner::new(set.build().unwrap());
//! sim.run_for(Duration::from_millis(10)).unwrap();
//! assert_eq!(sim.recording().monitor().task("log").unwrap().stats().activations, 10);
//! ```

pub mod check;
mod error;
pub mod histogram;
pub mod ipc;
mod monitor;
mod realtime;
mod sys;
mod task;
mod time;
mod trace;
mod virtual_time;

pub use check::FieldError;
pub use error::ConfigError;
pub use ipc::{
    BinarySemaphore, CountingSemaphore, EventSemaphore, IpcError, LatestReader, LatestWriter,
    LeadConsumer, LeadProducer, Mailbox, Missing, PiMutex, PiMutexGuard, Rejected, RingConsumer,
    RingProducer, SeqlockCell, SeqlockCopy, SeqlockReader, SeqlockWriter, SpscCell, Trigger,
    latest, lead_queue, ring, seqlock,
};
pub use monitor::{
    Fault, FaultCode, FaultRecord, MissReaction, Monitor, TaskKind, TaskMonitor, TaskState,
    TaskStats,
};
pub use realtime::{RealTimeConfig, RealTimeHandle, RealTimeRunner, RtStartError, SchedulingMode};
pub use sys::{
    allowed_cpus, executive_priority_for_os, in_periodic_body, os_fifo_range, os_priority,
};
pub use task::{
    Context, Next, PRIORITY_RANGE, Recording, TaskControl, TaskId, TaskSet, TaskSetBuilder,
    ThreadId, Wake,
};
pub use time::{DurationError, Time, duration_from_secs, parse_duration};
pub use trace::Trace;
pub use virtual_time::{HostProfile, RunError, VirtualRunner};
