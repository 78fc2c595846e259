//! Timing monitor: per-task state, activations, execution time, start lateness, deadline
//! misses, and the fault log.

use std::fmt;
use std::sync::Arc;
use std::sync::atomic::{AtomicU8, AtomicU64, Ordering::Relaxed};
use std::time::Duration;

use crate::histogram::{LogHistogram, Summary, bump};
use crate::sys::PiLock;
use crate::time::Time;

/// What a task is doing (the states of SEEDS.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum TaskState {
    /// Its body is executing.
    Running = 0,
    /// Released or triggered, waiting for the processor.
    Ready = 1,
    /// A periodic task waiting for its next period.
    Waiting = 2,
    /// An event task waiting for its trigger, or any task stopped by request (waiting to be
    /// started), or a background task that has finished.
    Stopped = 3,
    /// Waiting on a resource with a timeout (`Next::WaitFor` / `Next::Sleep`).
    Suspended = 4,
}

impl TaskState {
    fn from_u8(v: u8) -> TaskState {
        match v {
            0 => TaskState::Running,
            1 => TaskState::Ready,
            2 => TaskState::Waiting,
            4 => TaskState::Suspended,
            _ => TaskState::Stopped,
        }
    }

    /// Lower-case name.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn as_str(self) -> &'static str {
        match self {
            TaskState::Running => "running",
            TaskState::Ready => "ready",
            TaskState::Waiting => "waiting",
            TaskState::Stopped => "stopped",
            TaskState::Suspended => "suspended",
        }
    }
}

impl fmt::Display for TaskState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The kind of a fault.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FaultCode {
    /// A periodic thread's cycle finished after its deadline (the next release).
    DeadlineMiss,
    /// A fault raised by task code with its own code.
    User(u32),
}

impl FaultCode {
    /// Stable text code.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn as_str(self) -> &'static str {
        match self {
            FaultCode::DeadlineMiss => "deadline_miss",
            FaultCode::User(_) => "task_fault",
        }
    }
}

/// One recorded fault. Plain data: recording it never allocates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Fault {
    /// When it was detected.
    pub time: Time,
    /// The task that raised it (index into the task set).
    pub task: usize,
    /// What it is.
    pub code: FaultCode,
    /// For a deadline miss, how late the task finished, in ns; for a user fault, its value.
    pub detail: u64,
    /// A fixed message (user faults), empty for deadline misses.
    pub message: &'static str,
}

/// A fault with its task's name and a readable message (made when read, not when raised).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FaultRecord {
    /// When it was detected.
    pub time: Time,
    /// The task's name.
    pub task: String,
    /// What it is.
    pub code: FaultCode,
    /// Readable message.
    pub message: String,
}

impl fmt::Display for FaultRecord {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} {} [{}] {}",
            self.time,
            self.task,
            self.code.as_str(),
            self.message
        )
    }
}

/// What a deadline miss triggers besides being recorded and counted.
#[derive(Clone, Default)]
pub enum MissReaction {
    /// Record and count only.
    #[default]
    Count,
    /// Also print a warning (from a non-real-time context: at once in virtual time, from the
    /// supervisor thread under real time).
    Warn,
    /// Also call this hook, in the task's own thread, right when the miss is detected (the
    /// kernel uses it for feed hold or e-stop). It must be real-time safe: no allocation, no
    /// blocking.
    Hook(Arc<dyn Fn(&Fault) + Send + Sync>),
}

impl fmt::Debug for MissReaction {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MissReaction::Count => f.write_str("Count"),
            MissReaction::Warn => f.write_str("Warn"),
            MissReaction::Hook(_) => f.write_str("Hook"),
        }
    }
}

/// Static description of a task, as the monitor reports it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum TaskKind {
    /// A function of a periodic thread.
    Periodic {
        /// The thread.
        thread: String,
        /// Its period.
        period: Duration,
        /// Body runs per activation.
        runs: u32,
    },
    /// Woken by a trigger.
    Event {
        /// The trigger's channel name.
        trigger: String,
    },
    /// Runs in what is left.
    Background,
}

/// Live counters of one task. Written by the thread running the task, readable anywhere.
pub struct TaskMonitor {
    name: String,
    kind: TaskKind,
    priority: i32,
    state: AtomicU8,
    activations: AtomicU64,
    deadline_misses: AtomicU64,
    skipped_releases: AtomicU64,
    exec: LogHistogram,
    lateness: LogHistogram,
}

impl TaskMonitor {
    pub(crate) fn new(name: String, kind: TaskKind, priority: i32, state: TaskState) -> Self {
        TaskMonitor {
            name,
            kind,
            priority,
            state: AtomicU8::new(state as u8),
            activations: AtomicU64::new(0),
            deadline_misses: AtomicU64::new(0),
            skipped_releases: AtomicU64::new(0),
            exec: LogHistogram::new(),
            lateness: LogHistogram::new(),
        }
    }

    /// The task's name.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Its kind.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn kind(&self) -> &TaskKind {
        &self.kind
    }

    /// Its configured priority (0..=127).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn priority(&self) -> i32 {
        self.priority
    }

    /// Histogram of body execution times (ns).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn execution_histogram(&self) -> &LogHistogram {
        &self.exec
    }

    /// Histogram of periodic start lateness, i.e. jitter (ns).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn lateness_histogram(&self) -> &LogHistogram {
        &self.lateness
    }

    /// Its state now.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn state(&self) -> TaskState {
        TaskState::from_u8(self.state.load(Relaxed))
    }

    pub(crate) fn set_state(&self, s: TaskState) {
        self.state.store(s as u8, Relaxed);
    }

    pub(crate) fn record_run(&self, lateness_ns: Option<u64>, exec_ns: u64) {
        bump(&self.activations, 1);
        self.exec.record(exec_ns);
        if let Some(l) = lateness_ns {
            self.lateness.record(l);
        }
    }

    pub(crate) fn record_miss(&self, skipped: u64) {
        bump(&self.deadline_misses, 1);
        bump(&self.skipped_releases, skipped);
    }

    pub(crate) fn record_skipped(&self, skipped: u64) {
        bump(&self.skipped_releases, skipped);
    }

    /// A snapshot of the counters.
    ///
    /// Real-time: no (allocates).
    pub fn stats(&self) -> TaskStats {
        TaskStats {
            name: self.name.clone(),
            state: self.state(),
            activations: self.activations.load(Relaxed),
            execution: self.exec.summary(),
            lateness: self.lateness.summary(),
            deadline_misses: self.deadline_misses.load(Relaxed),
            skipped_releases: self.skipped_releases.load(Relaxed),
        }
    }
}

/// A snapshot of one task's timing.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TaskStats {
    /// The task's name.
    pub name: String,
    /// Its state when the snapshot was taken.
    pub state: TaskState,
    /// Body runs so far (a periodic task with `runs = 2` counts two per period).
    pub activations: u64,
    /// Execution time of a body run, start to end (including preemption), ns.
    pub execution: Summary,
    /// Start lateness of periodic runs: start minus the release time, ns.
    pub lateness: Summary,
    /// Cycles that finished after their deadline.
    pub deadline_misses: u64,
    /// Releases never run because an earlier cycle overran them.
    pub skipped_releases: u64,
}

struct FaultRing {
    slots: Vec<Fault>,
    total: u64,
}

/// Every task's monitor and the fault log of a task set.
pub struct Monitor {
    tasks: Vec<TaskMonitor>,
    faults: PiLock<FaultRing>,
    fault_capacity: usize,
}

impl Monitor {
    pub(crate) fn new(tasks: Vec<TaskMonitor>, fault_capacity: usize) -> Self {
        Monitor {
            tasks,
            faults: PiLock::new(FaultRing {
                slots: Vec::with_capacity(fault_capacity.max(1)),
                total: 0,
            }),
            fault_capacity: fault_capacity.max(1),
        }
    }

    /// Every task, in the order they were declared.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn tasks(&self) -> &[TaskMonitor] {
        &self.tasks
    }

    /// The task called `name`.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn task(&self, name: &str) -> Option<&TaskMonitor> {
        self.tasks.iter().find(|t| t.name == name)
    }

    pub(crate) fn task_at(&self, index: usize) -> Option<&TaskMonitor> {
        self.tasks.get(index)
    }

    /// Records a fault (PI lock, no allocation: the log keeps the first `fault_capacity`
    /// faults and counts the rest).
    pub(crate) fn push_fault(&self, fault: Fault) {
        let mut ring = self.faults.lock();
        ring.total += 1;
        if ring.slots.len() < self.fault_capacity {
            ring.slots.push(fault);
        }
    }

    /// Faults raised so far (including those beyond the log's capacity).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn fault_count(&self) -> u64 {
        self.faults.lock().total
    }

    /// The raw faults kept, in the order recorded.
    ///
    /// Real-time: no (allocates).
    pub fn raw_faults(&self) -> Vec<Fault> {
        self.faults.lock().slots.clone()
    }

    /// The faults kept, with task names and messages.
    ///
    /// Real-time: no (allocates).
    pub fn faults(&self) -> Vec<FaultRecord> {
        self.raw_faults().iter().map(|f| self.describe(f)).collect()
    }

    /// A fault with its task's name and a message.
    ///
    /// Real-time: no (allocates).
    pub fn describe(&self, f: &Fault) -> FaultRecord {
        let task = self
            .tasks
            .get(f.task)
            .map(|t| t.name.clone())
            .unwrap_or_else(|| format!("#{}", f.task));
        let message = match f.code {
            FaultCode::DeadlineMiss => {
                format!(
                    "cycle finished {} us after its deadline",
                    f.detail as f64 / 1000.0
                )
            }
            FaultCode::User(code) => format!("{} (code {code}, value {})", f.message, f.detail),
        };
        FaultRecord {
            time: f.time,
            task,
            code: f.code,
            message,
        }
    }

    /// A snapshot of every task.
    ///
    /// Real-time: no (allocates).
    pub fn stats(&self) -> Vec<TaskStats> {
        self.tasks.iter().map(TaskMonitor::stats).collect()
    }
}
