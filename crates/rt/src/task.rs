//! The task set: threads, tasks and their bodies, declared once at start-up, validated, then
//! handed to one of the two runners.

use std::collections::HashSet;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use crate::error::ConfigError;
use crate::ipc::{EventSemaphore, Trigger};
use crate::monitor::{Fault, FaultCode, MissReaction, Monitor, TaskKind, TaskMonitor, TaskState};
use crate::sys::monotonic_ns;
use crate::time::{Time, duration_ns};
use crate::trace::{EventKind, Lane, Trace, TraceEvent};

/// Lowest and highest task priority (the RTX64 range).
pub const PRIORITY_RANGE: std::ops::RangeInclusive<i32> = 0..=127;

/// Why a body is running.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wake {
    /// A periodic release.
    Period,
    /// The trigger the task waited for fired.
    Triggered,
    /// The timeout of a `Next::WaitFor` or `Next::Sleep` passed.
    TimedOut,
    /// A background task's turn, or the run after `Next::Continue`.
    Scheduled,
}

/// What an event or background task does after its body returns.
#[derive(Debug, Clone)]
pub enum Next {
    /// Finished: an event task waits for its trigger again; a background task is done
    /// (stopped) for the rest of the run.
    Done,
    /// Run the body again as soon as the scheduler gets to it (it yields to every task of
    /// higher or equal priority first).
    Continue,
    /// Suspend until `trigger` fires or `timeout` passes (`None`: no timeout); then the body
    /// runs again with [`Wake::Triggered`] or [`Wake::TimedOut`].
    WaitFor {
        /// What to wait for.
        trigger: Trigger,
        /// Longest wait.
        timeout: Option<Duration>,
    },
    /// Suspend for this long, then run again with [`Wake::TimedOut`].
    Sleep(Duration),
}

pub(crate) type PeriodicBody = Box<dyn FnMut(&mut Context<'_>) + Send>;
pub(crate) type ReactiveBody = Box<dyn FnMut(&mut Context<'_>) -> Next + Send>;

pub(crate) enum Body {
    Periodic(PeriodicBody),
    Reactive(ReactiveBody),
}

#[derive(Clone, Copy)]
pub(crate) enum ClockSource {
    Virtual,
    Real { epoch_mono: u64 },
}

/// What a task body sees of the executive: time, its activation, tracing and faults. The
/// same under both schedulers; tasks read time only from here, never from the OS clock.
pub struct Context<'a> {
    pub(crate) task: usize,
    pub(crate) name: &'a str,
    pub(crate) clock: ClockSource,
    pub(crate) start: u64,
    pub(crate) release: u64,
    pub(crate) activation: u64,
    pub(crate) run: u32,
    pub(crate) wake: Wake,
    pub(crate) consumed: u64,
    /// The body said the activation's remaining runs have nothing to do.
    pub(crate) runs_finished: bool,
    /// What the body asked its periodic thread's next release to move by (ns).
    pub(crate) release_shift: i64,
    pub(crate) lane: &'a Lane,
    pub(crate) monitor: &'a Monitor,
}

impl Context<'_> {
    /// Executive time now.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn now(&self) -> Time {
        match self.clock {
            ClockSource::Virtual => Time::from_nanos(self.start + self.consumed),
            ClockSource::Real { epoch_mono } => {
                Time::from_nanos(monotonic_ns().saturating_sub(epoch_mono))
            }
        }
    }

    /// When this body run started.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn start_time(&self) -> Time {
        Time::from_nanos(self.start)
    }

    /// The release time of this cycle (periodic), or when the task was woken (event and
    /// background tasks).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn release_time(&self) -> Time {
        Time::from_nanos(self.release)
    }

    /// Start time minus release time. For the first task of a periodic thread this is the
    /// thread's wake-up latency.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn lateness(&self) -> Duration {
        Duration::from_nanos(self.start.saturating_sub(self.release))
    }

    /// For a periodic task, the period index (release time / period); for other tasks, the
    /// number of earlier wake-ups.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn activation(&self) -> u64 {
        self.activation
    }

    /// Which of the runs of this activation this is (0-based; see `runs` of a periodic task).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn run(&self) -> u32 {
        self.run
    }

    /// Declares that the remaining runs of this periodic activation would find nothing to
    /// do (a task declared with several `runs` that has drained its work): the executive
    /// goes on with the thread's next task at once, and the runs not made are neither timed
    /// nor traced. Both schedulers; no effect on event and background tasks.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn finish_runs(&mut self) {
        self.runs_finished = true;
    }

    /// Moves the next release of this task's periodic thread, and every release after it,
    /// by `ns` (negative: earlier), so that a thread can follow a clock outside the
    /// executive (a fieldbus's distributed clock) by nudging its phase. The shifts asked
    /// during one cycle add up; the executive moves a cycle by at most a quarter of the
    /// period, so a nudge never skips a cycle or runs two back to back. Activations go on
    /// counting one per cycle. Both schedulers; no effect on event and background tasks.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn shift_next_release(&mut self, ns: i64) {
        self.release_shift = self.release_shift.saturating_add(ns);
    }

    /// Why the body runs.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn wake(&self) -> Wake {
        self.wake
    }

    /// The task's name.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn task_name(&self) -> &str {
        self.name
    }

    /// Declares that the body uses `d` of processor time here. Under virtual time the
    /// simulated processor is busy for `d` (tasks of higher priority preempt it); under real
    /// time the call spins for `d`. Used to model work in simulation and to load a system.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn consume(&mut self, d: Duration) {
        let ns = duration_ns(d);
        match self.clock {
            ClockSource::Virtual => self.consumed = self.consumed.saturating_add(ns),
            ClockSource::Real { .. } => {
                let until = monotonic_ns().saturating_add(ns);
                while monotonic_ns() < until {
                    std::hint::spin_loop();
                }
            }
        }
    }

    /// Puts a named instant with a value into the trace.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn mark(&mut self, label: &'static str, value: u64) {
        let time = self.now().as_nanos();
        self.lane.push(TraceEvent {
            time,
            kind: EventKind::Mark,
            task: self.task as u32,
            label,
            arg: value,
        });
    }

    /// Records a fault raised by this task (into the fault log and the trace).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn raise_fault(&mut self, code: u32, message: &'static str, value: u64) {
        let time = self.now();
        self.monitor.push_fault(Fault {
            time,
            task: self.task,
            code: FaultCode::User(code),
            detail: value,
            message,
        });
        self.lane.push(TraceEvent {
            time: time.as_nanos(),
            kind: EventKind::Fault,
            task: self.task as u32,
            label: message,
            arg: value,
        });
    }
}

/// A periodic thread declared in a [`TaskSetBuilder`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ThreadId(usize);

/// A task declared in a [`TaskSetBuilder`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TaskId(usize);

impl TaskId {
    /// Position of the task in declaration order: its index in [`Monitor::tasks`] and in
    /// [`crate::Fault::task`].
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn index(self) -> usize {
        self.0
    }
}

struct ThreadDecl {
    name: String,
    period: Duration,
    priority: i32,
}

pub(crate) enum DeclKind {
    Periodic { thread: usize, runs: u32 },
    Event { trigger: Trigger },
    Background,
}

struct TaskDecl {
    name: String,
    priority: i32,
    kind: DeclKind,
    body: Body,
    reaction: MissReaction,
    start_stopped: bool,
    deadline: Option<Duration>,
}

/// Declares threads and tasks; [`build`](Self::build) validates everything at once.
pub struct TaskSetBuilder {
    threads: Vec<ThreadDecl>,
    tasks: Vec<TaskDecl>,
    trace_capacity: usize,
    fault_capacity: usize,
}

impl Default for TaskSetBuilder {
    fn default() -> Self {
        Self::new()
    }
}

impl TaskSetBuilder {
    /// An empty task set; traces keep 16 384 events per thread, the fault log 1 024 faults.
    ///
    /// Real-time: no (set-up: allocates).
    pub fn new() -> Self {
        TaskSetBuilder {
            threads: Vec::new(),
            tasks: Vec::new(),
            trace_capacity: 16_384,
            fault_capacity: 1_024,
        }
    }

    /// A periodic thread: released at `0, period, 2·period, ...` with `priority` (0..=127,
    /// higher runs first). Its tasks run in the order they are added.
    ///
    /// Real-time: no (set-up: allocates).
    pub fn periodic_thread(&mut self, name: &str, period: Duration, priority: i32) -> ThreadId {
        self.threads.push(ThreadDecl {
            name: name.to_string(),
            period,
            priority,
        });
        ThreadId(self.threads.len() - 1)
    }

    /// Adds a task function to `thread`, run `runs` times per activation.
    ///
    /// Real-time: no (set-up: allocates).
    pub fn periodic(
        &mut self,
        thread: ThreadId,
        name: &str,
        runs: u32,
        body: impl FnMut(&mut Context<'_>) + Send + 'static,
    ) -> TaskId {
        let priority = self.threads.get(thread.0).map_or(0, |t| t.priority);
        self.push(
            name,
            priority,
            DeclKind::Periodic {
                thread: thread.0,
                runs,
            },
            Body::Periodic(Box::new(body)),
        )
    }

    /// An event-triggered task: runs at `priority` each time `trigger` fires.
    ///
    /// Real-time: no (set-up: allocates).
    pub fn event(
        &mut self,
        name: &str,
        priority: i32,
        trigger: Trigger,
        body: impl FnMut(&mut Context<'_>) -> Next + Send + 'static,
    ) -> TaskId {
        self.push(
            name,
            priority,
            DeclKind::Event { trigger },
            Body::Reactive(Box::new(body)),
        )
    }

    /// A background task: runs below every other task, in what time is left.
    ///
    /// Real-time: no (set-up: allocates).
    pub fn background(
        &mut self,
        name: &str,
        body: impl FnMut(&mut Context<'_>) -> Next + Send + 'static,
    ) -> TaskId {
        self.push(
            name,
            0,
            DeclKind::Background,
            Body::Reactive(Box::new(body)),
        )
    }

    fn push(&mut self, name: &str, priority: i32, kind: DeclKind, body: Body) -> TaskId {
        self.tasks.push(TaskDecl {
            name: name.to_string(),
            priority,
            kind,
            body,
            reaction: MissReaction::Count,
            start_stopped: false,
            deadline: None,
        });
        TaskId(self.tasks.len() - 1)
    }

    /// What a deadline miss of `task` triggers besides being recorded (default: count).
    ///
    /// Real-time: no (set-up).
    pub fn on_deadline_miss(&mut self, task: TaskId, reaction: MissReaction) -> &mut Self {
        if let Some(t) = self.tasks.get_mut(task.0) {
            t.reaction = reaction;
        }
        self
    }

    /// A relative deadline for `task`: for a periodic task, each run must end within
    /// `deadline` of its cycle's release (without one, the cycle must end by the next
    /// release); for an event task, each run must end within `deadline` of its wake-up.
    /// A late run is a deadline-miss fault. Background tasks have no deadline.
    ///
    /// Real-time: no (set-up).
    pub fn deadline(&mut self, task: TaskId, deadline: Duration) -> &mut Self {
        if let Some(t) = self.tasks.get_mut(task.0) {
            t.deadline = Some(deadline);
        }
        self
    }

    /// `task` begins stopped; it runs once started through its [`TaskControl`].
    ///
    /// Real-time: no (set-up).
    pub fn start_stopped(&mut self, task: TaskId) -> &mut Self {
        if let Some(t) = self.tasks.get_mut(task.0) {
            t.start_stopped = true;
        }
        self
    }

    /// Trace events kept per thread (0: no trace).
    ///
    /// Real-time: no (set-up).
    pub fn trace_capacity(&mut self, events_per_thread: usize) -> &mut Self {
        self.trace_capacity = events_per_thread;
        self
    }

    /// Faults kept in the fault log (later ones are counted, not kept).
    ///
    /// Real-time: no (set-up).
    pub fn fault_capacity(&mut self, faults: usize) -> &mut Self {
        self.fault_capacity = faults;
        self
    }

    /// Checks the declaration and builds the task set; the first problem found, in
    /// declaration order, is returned.
    ///
    /// Real-time: no (set-up: allocates).
    pub fn build(self) -> Result<TaskSet, ConfigError> {
        let mut names = HashSet::new();
        for t in &self.threads {
            if t.name.is_empty() {
                return Err(ConfigError::EmptyName { kind: "thread" });
            }
            if !names.insert(t.name.as_str()) {
                return Err(ConfigError::DuplicateName {
                    kind: "thread",
                    name: t.name.clone(),
                });
            }
            if t.period.is_zero() {
                return Err(ConfigError::ZeroPeriod {
                    thread: t.name.clone(),
                });
            }
            if !PRIORITY_RANGE.contains(&t.priority) {
                return Err(ConfigError::PriorityOutOfRange {
                    kind: "thread",
                    name: t.name.clone(),
                    priority: t.priority,
                });
            }
        }
        let mut names = HashSet::new();
        for t in &self.tasks {
            if t.name.is_empty() {
                return Err(ConfigError::EmptyName { kind: "task" });
            }
            if !names.insert(t.name.as_str()) {
                return Err(ConfigError::DuplicateName {
                    kind: "task",
                    name: t.name.clone(),
                });
            }
            match &t.kind {
                DeclKind::Periodic { thread, runs } => {
                    if *thread >= self.threads.len() {
                        return Err(ConfigError::UnknownThread {
                            task: t.name.clone(),
                        });
                    }
                    if *runs == 0 {
                        return Err(ConfigError::ZeroRuns {
                            task: t.name.clone(),
                        });
                    }
                }
                DeclKind::Event { .. } => {
                    if !PRIORITY_RANGE.contains(&t.priority) {
                        return Err(ConfigError::PriorityOutOfRange {
                            kind: "task",
                            name: t.name.clone(),
                            priority: t.priority,
                        });
                    }
                }
                DeclKind::Background => {
                    if t.deadline.is_some() {
                        return Err(ConfigError::DeadlineOnBackground {
                            task: t.name.clone(),
                        });
                    }
                }
            }
            if t.deadline.is_some_and(|d| d.is_zero()) {
                return Err(ConfigError::ZeroDeadline {
                    task: t.name.clone(),
                });
            }
        }
        for (i, th) in self.threads.iter().enumerate() {
            let has_task = self
                .tasks
                .iter()
                .any(|t| matches!(t.kind, DeclKind::Periodic { thread, .. } if thread == i));
            if !has_task {
                return Err(ConfigError::EmptyThread {
                    thread: th.name.clone(),
                });
            }
        }

        // Lanes: one per periodic thread, one per event task, one shared by background tasks.
        let mut lane_names: Vec<String> = self.threads.iter().map(|t| t.name.clone()).collect();
        let mut threads: Vec<ThreadSpec> = self
            .threads
            .iter()
            .map(|t| ThreadSpec {
                name: t.name.clone(),
                period_ns: duration_ns(t.period),
                priority: t.priority,
                tasks: Vec::new(),
            })
            .collect();
        let mut monitors = Vec::with_capacity(self.tasks.len());
        let mut tasks = Vec::with_capacity(self.tasks.len());
        let mut background_lane = None;
        for (index, decl) in self.tasks.into_iter().enumerate() {
            let (kind, lane, initial) = match &decl.kind {
                DeclKind::Periodic { thread, runs } => {
                    let th = &self.threads[*thread];
                    if let Some(spec) = threads.get_mut(*thread) {
                        spec.tasks.push(index);
                    }
                    (
                        TaskKind::Periodic {
                            thread: th.name.clone(),
                            period: th.period,
                            runs: *runs,
                        },
                        *thread,
                        TaskState::Waiting,
                    )
                }
                DeclKind::Event { trigger } => {
                    lane_names.push(decl.name.clone());
                    (
                        TaskKind::Event {
                            trigger: trigger.name().to_string(),
                        },
                        lane_names.len() - 1,
                        TaskState::Stopped,
                    )
                }
                DeclKind::Background => {
                    let lane = *background_lane.get_or_insert_with(|| {
                        lane_names.push("background".to_string());
                        lane_names.len() - 1
                    });
                    (TaskKind::Background, lane, TaskState::Ready)
                }
            };
            let initial = if decl.start_stopped {
                TaskState::Stopped
            } else {
                initial
            };
            let priority = match decl.kind {
                DeclKind::Background => -1,
                _ => decl.priority,
            };
            monitors.push(TaskMonitor::new(
                decl.name.clone(),
                kind,
                priority.max(0),
                initial,
            ));
            tasks.push(TaskSpec {
                name: decl.name,
                priority,
                kind: decl.kind,
                body: decl.body,
                reaction: decl.reaction,
                deadline_ns: decl.deadline.map(duration_ns),
                control: RunFlag::new(!decl.start_stopped),
                lane,
            });
        }
        let lanes = lane_names
            .into_iter()
            .map(|n| Arc::new(Lane::new(n, self.trace_capacity)))
            .collect();
        let monitor = Arc::new(Monitor::new(monitors, self.fault_capacity));
        let names = tasks.iter().map(|t| t.name.clone()).collect();
        Ok(TaskSet {
            threads,
            tasks,
            recording: Recording {
                lanes,
                names,
                monitor,
            },
        })
    }
}

pub(crate) struct ThreadSpec {
    pub name: String,
    pub period_ns: u64,
    pub priority: i32,
    pub tasks: Vec<usize>,
}

pub(crate) struct TaskSpec {
    pub name: String,
    /// -1 for background tasks.
    pub priority: i32,
    pub kind: DeclKind,
    pub body: Body,
    pub reaction: MissReaction,
    /// Relative deadline of each run (see `TaskSetBuilder::deadline`).
    pub deadline_ns: Option<u64>,
    pub control: RunFlag,
    pub lane: usize,
}

/// What a run leaves behind: the monitor and the trace lanes.
pub struct Recording {
    pub(crate) lanes: Vec<Arc<Lane>>,
    pub(crate) names: Vec<String>,
    pub(crate) monitor: Arc<Monitor>,
}

impl Recording {
    /// The timing monitor (live during a run).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn monitor(&self) -> &Arc<Monitor> {
        &self.monitor
    }

    /// The trace, for export.
    ///
    /// Real-time: no (allocates).
    pub fn trace(&self) -> Trace<'_> {
        Trace {
            lanes: &self.lanes,
            task_names: self.names.iter().map(String::as_str).collect(),
        }
    }
}

/// A validated set of threads and tasks, ready for a runner.
pub struct TaskSet {
    pub(crate) threads: Vec<ThreadSpec>,
    pub(crate) tasks: Vec<TaskSpec>,
    pub(crate) recording: Recording,
}

impl TaskSet {
    /// A builder.
    ///
    /// Real-time: no (set-up).
    pub fn builder() -> TaskSetBuilder {
        TaskSetBuilder::new()
    }

    /// The timing monitor (shared; stays readable during and after the run).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn monitor(&self) -> Arc<Monitor> {
        Arc::clone(&self.recording.monitor)
    }

    /// The start/stop control of the task called `name`.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn control(&self, name: &str) -> Option<TaskControl> {
        let index = self.tasks.iter().position(|t| t.name == name)?;
        self.control_of(TaskId(index))
    }

    /// The start/stop control of `task`.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn control_of(&self, task: TaskId) -> Option<TaskControl> {
        let t = self.tasks.get(task.0)?;
        Some(TaskControl {
            run: t.control.clone(),
            task: task.0,
            monitor: Arc::clone(&self.recording.monitor),
        })
    }
}

/// A task's start event, with an atomic copy of its state so that the per-cycle check
/// takes no lock.
#[derive(Clone)]
pub(crate) struct RunFlag {
    started: Arc<AtomicBool>,
    event: EventSemaphore,
}

impl RunFlag {
    fn new(started: bool) -> Self {
        RunFlag {
            started: Arc::new(AtomicBool::new(started)),
            event: EventSemaphore::with_state("task start", started),
        }
    }

    pub(crate) fn is_set(&self) -> bool {
        self.started.load(Ordering::Acquire)
    }

    fn set(&self) {
        self.started.store(true, Ordering::Release);
        self.event.set();
    }

    fn reset(&self) {
        self.started.store(false, Ordering::Release);
        self.event.reset();
    }

    /// Blocks until started or `stop` (real-time runner, outside any task body).
    pub(crate) fn wait_set_or_stop(&self, stop: &AtomicBool) -> bool {
        self.event.wait_set_or_stop(stop)
    }
}

/// Starts and stops one task through its start event: a task asked to stop finishes its
/// current cycle and stops itself at the start of the next one; it is never suspended from
/// outside.
#[derive(Clone)]
pub struct TaskControl {
    run: RunFlag,
    task: usize,
    monitor: Arc<Monitor>,
}

impl TaskControl {
    pub(crate) fn new(run: RunFlag, task: usize, monitor: Arc<Monitor>) -> Self {
        TaskControl { run, task, monitor }
    }

    /// Lets the task run from its next cycle (or trigger) on.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn start(&self) {
        self.run.set();
    }

    /// Asks the task to stop at the start of its next cycle.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn stop(&self) {
        self.run.reset();
    }

    /// True when the task is allowed to run.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn is_started(&self) -> bool {
        self.run.is_set()
    }

    /// The task's state now.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn state(&self) -> TaskState {
        self.monitor
            .task_at(self.task)
            .map_or(TaskState::Stopped, |t| t.state())
    }
}
