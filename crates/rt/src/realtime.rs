//! The real-time runner: each periodic thread and each event task on its own OS thread with
//! a SCHED_FIFO priority, memory locked, optional CPU affinity, periodic wake-ups at absolute
//! times on `CLOCK_MONOTONIC` (`clock_nanosleep` with `TIMER_ABSTIME`). Background tasks share
//! one normal-priority thread.
//!
//! Nothing in a cycle allocates: bodies, monitors, histograms and trace lanes are all set up
//! before the first release.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, mpsc};
use std::thread::JoinHandle;
use std::time::Duration;

use thiserror::Error;

use crate::ipc::{EventSemaphore, Trigger, WaitResult};
use crate::monitor::{FaultCode, MissReaction, Monitor, TaskState};
use crate::sys::{
    SchedOutcome, hold_cpu_dma_latency, lock_all_memory, may_lock_all_memory, monotonic_ns,
    os_priority, prefault_stack, set_current_thread_affinity, set_current_thread_fifo,
    set_in_periodic_body, set_in_task_body, sleep_until_monotonic, warn_once,
};
use crate::task::{
    Body, ClockSource, Context, DeclKind, Next, Recording, TaskControl, TaskSet, TaskSpec, Wake,
};
use crate::time::{Time, duration_ns};
use crate::trace::{EventKind, Lane, TraceEvent};
use crate::virtual_time::{
    clamp_release_shift, next_shifted_release, periodic_miss, reactive_miss, record_miss, shifted,
};

static WARNED_NO_FIFO: AtomicBool = AtomicBool::new(false);
static WARNED_NO_MLOCK: AtomicBool = AtomicBool::new(false);

/// How the runner asks the OS for real-time scheduling.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SchedulingMode {
    /// SCHED_FIFO when permitted, otherwise normal threads and one warning.
    #[default]
    BestEffort,
    /// SCHED_FIFO or refuse to start.
    RequireFifo,
    /// Normal threads, never SCHED_FIFO (tests on shared machines).
    Normal,
}

/// Options of a real-time run.
#[derive(Debug, Clone)]
pub struct RealTimeConfig {
    /// Real-time scheduling policy.
    pub scheduling: SchedulingMode,
    /// Lock all memory (mlockall) so no page fault reaches a cycle.
    pub lock_memory: bool,
    /// CPUs the executive's threads may run on (`None`: any).
    pub cpus: Option<Vec<usize>>,
    /// CPUs for single threads, by name (a periodic thread, an event task, or
    /// "background"); these override `cpus` for that thread.
    pub thread_cpus: Vec<(String, Vec<usize>)>,
    /// Keep CPUs out of idle states whose exit latency exceeds this many microseconds while
    /// the executive runs (PM QoS via /dev/cpu_dma_latency, as cyclictest does; skipped
    /// silently without permission). `None` leaves power management alone.
    pub cpu_dma_latency_us: Option<u32>,
    /// Time between the moment every thread is set up and the first release.
    pub start_delay: Duration,
    /// Print a warning on stderr for each deadline miss of a task whose reaction is
    /// `Warn`. A caller that draws its own display (a live status line) turns this off and
    /// reads the misses from [`RealTimeHandle::monitor`] instead.
    pub print_warnings: bool,
}

impl Default for RealTimeConfig {
    fn default() -> Self {
        RealTimeConfig {
            scheduling: SchedulingMode::BestEffort,
            lock_memory: true,
            cpus: None,
            thread_cpus: Vec::new(),
            cpu_dma_latency_us: Some(0),
            start_delay: Duration::from_millis(5),
            print_warnings: true,
        }
    }
}

/// The real-time runner could not start.
#[derive(Debug, Error)]
pub enum RtStartError {
    /// SCHED_FIFO was required and the OS refused it.
    #[error(
        "SCHED_FIFO is not permitted for this process (run as root, or grant CAP_SYS_NICE or an rtprio limit)"
    )]
    FifoNotPermitted,
    /// An OS thread could not be created.
    #[error("cannot create thread '{name}': {source}")]
    Spawn {
        /// The thread.
        name: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// A thread was to be pinned to a CPU this process may not run on.
    #[error("CPU {cpu} is not available to this process (available: {available:?})")]
    CpuUnavailable {
        /// The CPU asked for.
        cpu: usize,
        /// The CPUs of the process's affinity mask.
        available: Vec<usize>,
    },
}

impl RtStartError {
    /// Stable error code.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn code(&self) -> &'static str {
        match self {
            RtStartError::FifoNotPermitted => "fifo_not_permitted",
            RtStartError::Spawn { .. } => "spawn_failed",
            RtStartError::CpuUnavailable { .. } => "cpu_unavailable",
        }
    }
}

/// Starts task sets on OS threads.
pub struct RealTimeRunner;

/// What every executive thread shares.
#[derive(Clone)]
struct Shared {
    stop: Arc<AtomicBool>,
    /// Monotonic time of release zero; known once every thread is set up (see `await_start`).
    epoch: u64,
    epoch_cell: Arc<AtomicU64>,
    go: EventSemaphore,
    monitor: Arc<Monitor>,
    lanes: Vec<Arc<Lane>>,
    warn_pending: Arc<AtomicU64>,
}

impl Shared {
    fn now(&self) -> u64 {
        monotonic_ns().saturating_sub(self.epoch)
    }

    fn state(&self, task: usize, s: TaskState) {
        if let Some(m) = self.monitor.task_at(task) {
            m.set_state(s);
        }
    }

    fn lane(&self, index: usize) -> &Lane {
        &self.lanes[index]
    }

    fn span(&self, spec: &TaskSpec, task: usize, start: u64, end: u64) {
        self.lane(spec.lane).push(TraceEvent {
            time: start,
            kind: EventKind::Span,
            task: task as u32,
            label: "",
            arg: end.saturating_sub(start),
        });
    }
}

/// Reports the thread ready, then waits until every thread is: the epoch is fixed only then,
/// so a slow thread start cannot make another thread miss the first releases. False when
/// the runner is being stopped instead.
fn await_start(shared: &mut Shared, ready: mpsc::Sender<bool>, fifo: bool) -> bool {
    let _ = ready.send(fifo);
    drop(ready);
    if !shared.go.wait_set_or_stop(&shared.stop) || shared.stop.load(Ordering::Acquire) {
        return false;
    }
    shared.epoch = shared.epoch_cell.load(Ordering::Acquire);
    true
}

/// Per-thread set-up: scheduling, affinity, pre-faulted stack. Reports whether SCHED_FIFO
/// was granted.
fn setup_thread(name: &str, priority: Option<i32>, config: &RealTimeConfig) -> bool {
    let own = config
        .thread_cpus
        .iter()
        .find(|(n, _)| n == name)
        .map(|(_, cpus)| cpus);
    if let Some(cpus) = own.or(config.cpus.as_ref()) {
        set_current_thread_affinity(cpus);
    }
    prefault_stack(64 * 1024);
    match (priority, config.scheduling) {
        (Some(p), SchedulingMode::BestEffort | SchedulingMode::RequireFifo) => {
            set_current_thread_fifo(os_priority(p)) == SchedOutcome::Fifo
        }
        _ => true,
    }
}

/// What a body run leaves for its runner: what a reactive task waits for next, whether a
/// periodic task's remaining runs are empty, and the shift of its thread's next release.
struct Ran {
    next: Next,
    runs_finished: bool,
    release_shift: i64,
}

/// Runs one body with a context of real time.
#[allow(clippy::too_many_arguments)]
fn run_body(
    shared: &Shared,
    spec: &mut TaskSpec,
    task: usize,
    start: u64,
    release: u64,
    activation: u64,
    run: u32,
    wake: Wake,
) -> Ran {
    let TaskSpec {
        name, body, lane, ..
    } = spec;
    let mut ctx = Context {
        task,
        name,
        clock: ClockSource::Real {
            epoch_mono: shared.epoch,
        },
        start,
        release,
        activation,
        run,
        wake,
        consumed: 0,
        runs_finished: false,
        release_shift: 0,
        lane: shared.lane(*lane),
        monitor: &shared.monitor,
    };
    set_in_task_body(true);
    let next = match body {
        Body::Periodic(body) => {
            set_in_periodic_body(true);
            body(&mut ctx);
            set_in_periodic_body(false);
            Next::Done
        }
        Body::Reactive(body) => body(&mut ctx),
    };
    set_in_task_body(false);
    Ran {
        next,
        runs_finished: ctx.runs_finished,
        release_shift: ctx.release_shift,
    }
}

#[allow(clippy::too_many_arguments)]
fn periodic_thread(
    mut shared: Shared,
    name: String,
    mut tasks: Vec<(usize, TaskSpec)>,
    period: u64,
    ready: mpsc::Sender<bool>,
    priority: i32,
    config: RealTimeConfig,
) {
    let fifo = setup_thread(&name, Some(priority), &config);
    if !await_start(&mut shared, ready, fifo) {
        return;
    }
    // The release on the period grid, and how far the thread's phase is moved from it.
    let mut base = 0u64;
    let mut offset = 0i64;
    let mut release = 0u64;
    loop {
        sleep_until_monotonic(shared.epoch.saturating_add(release));
        let wake = shared.now();
        if shared.stop.load(Ordering::Acquire) {
            break;
        }
        let activation = base / period.max(1);
        let mut shift = 0i64;
        let mut missed: Option<usize> = None;
        let mut first = true;
        for (task, spec) in tasks.iter_mut() {
            let task = *task;
            if !spec.control.is_set() {
                shared.state(task, TaskState::Stopped);
                continue;
            }
            let runs = match spec.kind {
                DeclKind::Periodic { runs, .. } => runs,
                _ => 1,
            };
            let mut task_missed = false;
            for run in 0..runs {
                let start = if first { wake } else { shared.now() };
                first = false;
                shared.state(task, TaskState::Running);
                let ran = run_body(
                    &shared,
                    spec,
                    task,
                    start,
                    release,
                    activation,
                    run,
                    Wake::Period,
                );
                shift = shift.saturating_add(ran.release_shift);
                let end = shared.now();
                if let Some(m) = shared.monitor.task_at(task) {
                    m.record_run(
                        Some(start.saturating_sub(release)),
                        end.saturating_sub(start),
                    );
                }
                shared.span(spec, task, start, end);
                if let Some(late) = periodic_miss(
                    release,
                    period,
                    spec.deadline_ns,
                    end,
                    task,
                    &mut task_missed,
                    &mut missed,
                ) {
                    raise_miss(&shared, spec, task, end, late);
                }
                if ran.runs_finished {
                    break;
                }
            }
            shared.state(task, TaskState::Waiting);
        }
        offset = offset.saturating_add(clamp_release_shift(shift, period));
        let (next, skipped) = next_shifted_release(base, period, offset, shared.now());
        if skipped > 0 {
            if let Some(m) = missed.and_then(|t| shared.monitor.task_at(t)) {
                m.record_skipped(skipped);
            }
        }
        base = next;
        release = shifted(base, offset);
    }
}

fn raise_miss(shared: &Shared, spec: &TaskSpec, task: usize, now: u64, late: u64) {
    record_miss(
        &shared.monitor,
        shared.lane(spec.lane),
        spec,
        task,
        now,
        late,
        false,
    );
    if matches!(spec.reaction, MissReaction::Warn) {
        shared.warn_pending.fetch_add(1, Ordering::Release);
    }
}

/// What a reactive (event or background) task waits for next.
enum Waiting {
    OwnTrigger,
    Trigger {
        trigger: Trigger,
        token: u64,
        deadline: Option<u64>,
    },
    Until(u64),
    Ready(Wake),
    Finished,
}

fn after_body(next: Next, now: u64, has_trigger: bool) -> Waiting {
    match next {
        Next::Done if has_trigger => Waiting::OwnTrigger,
        Next::Done => Waiting::Finished,
        Next::Continue => Waiting::Ready(Wake::Scheduled),
        Next::WaitFor { trigger, timeout } => {
            let token = trigger.source.arm();
            Waiting::Trigger {
                trigger,
                token,
                deadline: timeout.map(|d| now.saturating_add(duration_ns(d))),
            }
        }
        Next::Sleep(d) => Waiting::Until(now.saturating_add(duration_ns(d))),
    }
}

/// Sleeps until executive time `t` or a stop request, in slices.
fn sleep_until_or_stop(shared: &Shared, t: u64) -> bool {
    loop {
        if shared.stop.load(Ordering::Acquire) {
            return false;
        }
        let now = shared.now();
        if now >= t {
            return true;
        }
        let slice_end = t.min(now + 20_000_000);
        sleep_until_monotonic(shared.epoch.saturating_add(slice_end));
    }
}

fn event_thread(
    mut shared: Shared,
    task: usize,
    mut spec: TaskSpec,
    ready: mpsc::Sender<bool>,
    config: RealTimeConfig,
) {
    let fifo = setup_thread(&spec.name, Some(spec.priority), &config);
    let trigger = match &spec.kind {
        DeclKind::Event { trigger } => trigger.clone(),
        _ => return,
    };
    // Armed before the first release, so edges from the first cycles are seen.
    let mut own_token = trigger.source.arm();
    if !await_start(&mut shared, ready, fifo) {
        return;
    }
    sleep_until_monotonic(shared.epoch);
    let mut waiting = Waiting::OwnTrigger;
    let mut activation = 0u64;
    while !shared.stop.load(Ordering::Acquire) {
        let wake = match &waiting {
            Waiting::OwnTrigger => {
                if !spec.control.is_set() {
                    shared.state(task, TaskState::Stopped);
                    spec.control.wait_set_or_stop(&shared.stop);
                    own_token = trigger.source.arm();
                    continue;
                }
                shared.state(task, TaskState::Stopped);
                match trigger.source.wait_ready(own_token, None, &shared.stop) {
                    WaitResult::Ready => {
                        if !spec.control.is_set() || !trigger.source.try_take(own_token) {
                            continue;
                        }
                        Wake::Triggered
                    }
                    WaitResult::TimedOut => continue,
                    WaitResult::Stopped => break,
                }
            }
            Waiting::Trigger {
                trigger: t,
                token,
                deadline,
            } => {
                shared.state(task, TaskState::Suspended);
                let mono = deadline.map(|d| shared.epoch.saturating_add(d));
                match t.source.wait_ready(*token, mono, &shared.stop) {
                    WaitResult::Ready => {
                        if !t.source.try_take(*token) {
                            continue;
                        }
                        Wake::Triggered
                    }
                    WaitResult::TimedOut => Wake::TimedOut,
                    WaitResult::Stopped => break,
                }
            }
            Waiting::Until(t) => {
                shared.state(task, TaskState::Suspended);
                if !sleep_until_or_stop(&shared, *t) {
                    break;
                }
                Wake::TimedOut
            }
            Waiting::Ready(w) => {
                // yield to threads of equal priority, as a continued body does in virtual time
                // SAFETY: plain syscall.
                unsafe { libc::sched_yield() };
                *w
            }
            Waiting::Finished => break,
        };
        own_token = trigger.source.arm();
        let start = shared.now();
        shared.state(task, TaskState::Running);
        let next = run_body(&shared, &mut spec, task, start, start, activation, 0, wake).next;
        activation += 1;
        let end = shared.now();
        if let Some(m) = shared.monitor.task_at(task) {
            m.record_run(None, end.saturating_sub(start));
        }
        shared.span(&spec, task, start, end);
        // The thread's wake-up is the start of the run here (the moment the trigger fired is
        // not known without a time stamp in every IPC call).
        if let Some(late) = reactive_miss(start, spec.deadline_ns, end) {
            raise_miss(&shared, &spec, task, end, late);
        }
        waiting = after_body(next, end, true);
    }
}

fn background_thread(
    mut shared: Shared,
    mut tasks: Vec<(usize, TaskSpec)>,
    ready: mpsc::Sender<bool>,
    config: RealTimeConfig,
) {
    setup_thread("background", None, &config);
    if !await_start(&mut shared, ready, true) {
        return;
    }
    sleep_until_monotonic(shared.epoch);
    let mut states: Vec<Waiting> = tasks
        .iter()
        .map(|_| Waiting::Ready(Wake::Scheduled))
        .collect();
    let mut activations = vec![0u64; tasks.len()];
    while !shared.stop.load(Ordering::Acquire) {
        let mut ran = false;
        let mut earliest = u64::MAX;
        for (i, (task, spec)) in tasks.iter_mut().enumerate() {
            let task = *task;
            let now = shared.now();
            let wake = match &states[i] {
                _ if !spec.control.is_set() => {
                    shared.state(task, TaskState::Stopped);
                    None
                }
                Waiting::Ready(w) => Some(*w),
                Waiting::Until(t) if *t <= now => Some(Wake::TimedOut),
                Waiting::Until(t) => {
                    earliest = earliest.min(*t);
                    None
                }
                Waiting::Trigger {
                    trigger,
                    token,
                    deadline,
                } => {
                    if trigger.source.is_ready(*token) && trigger.source.try_take(*token) {
                        Some(Wake::Triggered)
                    } else if deadline.is_some_and(|d| d <= now) {
                        Some(Wake::TimedOut)
                    } else {
                        if let Some(d) = deadline {
                            earliest = earliest.min(*d);
                        }
                        None
                    }
                }
                Waiting::OwnTrigger | Waiting::Finished => None,
            };
            let Some(wake) = wake else { continue };
            ran = true;
            let start = shared.now();
            shared.state(task, TaskState::Running);
            let next = run_body(&shared, spec, task, start, start, activations[i], 0, wake).next;
            activations[i] += 1;
            let end = shared.now();
            if let Some(m) = shared.monitor.task_at(task) {
                m.record_run(None, end.saturating_sub(start));
            }
            shared.span(spec, task, start, end);
            states[i] = after_body(next, end, false);
            shared.state(
                task,
                match states[i] {
                    Waiting::Ready(_) => TaskState::Ready,
                    Waiting::Finished | Waiting::OwnTrigger => TaskState::Stopped,
                    _ => TaskState::Suspended,
                },
            );
        }
        if !ran {
            // Idle: poll triggers and stop requests every millisecond at most.
            let until = earliest.min(shared.now() + 1_000_000);
            sleep_until_monotonic(shared.epoch.saturating_add(until));
        }
    }
}

/// A running real-time executive.
pub struct RealTimeHandle {
    shared: Shared,
    threads: Vec<JoinHandle<()>>,
    supervisor: Option<JoinHandle<()>>,
    recording: Option<Recording>,
    controls: Vec<(String, TaskControl)>,
    fifo: bool,
    /// Open while the run lasts: the PM QoS latency request.
    _pm_qos: Option<std::fs::File>,
}

impl RealTimeRunner {
    /// Starts every thread of `set`; the first release is `config.start_delay` from now.
    ///
    /// Real-time: no (set-up: allocates, starts threads).
    pub fn start(set: TaskSet, config: RealTimeConfig) -> Result<RealTimeHandle, RtStartError> {
        // A CPU outside the affinity mask would leave a thread unpinned without a word.
        let available = crate::sys::allowed_cpus();
        let asked = config
            .cpus
            .iter()
            .flatten()
            .chain(config.thread_cpus.iter().flat_map(|(_, cpus)| cpus));
        for &cpu in asked {
            if !available.contains(&cpu) {
                return Err(RtStartError::CpuUnavailable { cpu, available });
            }
        }
        if config.lock_memory {
            // With a finite RLIMIT_MEMLOCK, MCL_FUTURE would make later allocations (thread
            // stacks, buffers) fail once the limit is reached: lock only without a limit.
            if !may_lock_all_memory() || !lock_all_memory() {
                warn_once(
                    &WARNED_NO_MLOCK,
                    "memory is not locked (needs CAP_IPC_LOCK or an unlimited memlock limit); page faults may delay cycles",
                );
            }
        }
        let TaskSet {
            threads,
            tasks,
            recording,
        } = set;
        let controls: Vec<(String, TaskControl)> = tasks
            .iter()
            .enumerate()
            .map(|(i, t)| {
                (
                    t.name.clone(),
                    TaskControl::new(t.control.clone(), i, Arc::clone(&recording.monitor)),
                )
            })
            .collect();
        let warn_tasks: Vec<bool> = tasks
            .iter()
            .map(|t| matches!(t.reaction, MissReaction::Warn))
            .collect();
        let shared = Shared {
            stop: Arc::new(AtomicBool::new(false)),
            epoch: 0,
            epoch_cell: Arc::new(AtomicU64::new(0)),
            go: EventSemaphore::new("executive start"),
            monitor: Arc::clone(&recording.monitor),
            lanes: recording.lanes.clone(),
            warn_pending: Arc::new(AtomicU64::new(0)),
        };
        let mut specs: Vec<Option<TaskSpec>> = tasks.into_iter().map(Some).collect();
        let (tx, rx) = mpsc::channel::<bool>();
        let mut handles = Vec::new();
        let mut spawn = |name: String, f: Box<dyn FnOnce() + Send>| -> Result<(), RtStartError> {
            let h = std::thread::Builder::new()
                .name(name.chars().take(15).collect())
                .spawn(f)
                .map_err(|source| RtStartError::Spawn { name, source })?;
            handles.push(h);
            Ok(())
        };
        let mut spawned = 0usize;
        let mut result = Ok(());
        for th in threads {
            let group: Vec<(usize, TaskSpec)> = th
                .tasks
                .iter()
                .filter_map(|&i| specs.get_mut(i).and_then(Option::take).map(|s| (i, s)))
                .collect();
            let (sh, tx, cfg, period, prio) = (
                shared.clone(),
                tx.clone(),
                config.clone(),
                th.period_ns,
                th.priority,
            );
            let thread_name = th.name.clone();
            result = spawn(
                th.name.clone(),
                Box::new(move || periodic_thread(sh, thread_name, group, period, tx, prio, cfg)),
            );
            if result.is_err() {
                break;
            }
            spawned += 1;
        }
        let mut background = Vec::new();
        if result.is_ok() {
            for (i, slot) in specs.iter_mut().enumerate() {
                let Some(spec) = slot.take() else { continue };
                match spec.kind {
                    DeclKind::Event { .. } => {
                        let (sh, tx, cfg) = (shared.clone(), tx.clone(), config.clone());
                        result = spawn(
                            spec.name.clone(),
                            Box::new(move || event_thread(sh, i, spec, tx, cfg)),
                        );
                        if result.is_err() {
                            break;
                        }
                        spawned += 1;
                    }
                    _ => background.push((i, spec)),
                }
            }
        }
        if result.is_ok() && !background.is_empty() {
            let (sh, tx, cfg) = (shared.clone(), tx.clone(), config.clone());
            result = spawn(
                "background".to_string(),
                Box::new(move || background_thread(sh, background, tx, cfg)),
            );
            if result.is_ok() {
                spawned += 1;
            }
        }
        drop(tx);
        // Hear from every thread (no short cut: a thread not yet heard from is not ready).
        let answers: Vec<bool> = (0..spawned).map(|_| rx.recv().unwrap_or(false)).collect();
        let granted = answers.iter().all(|&a| a);
        let fifo = granted && config.scheduling != SchedulingMode::Normal;
        // Every thread is set up and waiting: fix the epoch and let them go.
        let mut shared = shared;
        shared.epoch = monotonic_ns() + duration_ns(config.start_delay);
        shared.epoch_cell.store(shared.epoch, Ordering::Release);
        let print_warnings = config.print_warnings && warn_tasks.iter().any(|&w| w);
        let supervisor = print_warnings.then(|| {
            let sh = shared.clone();
            std::thread::spawn(move || supervise(sh, warn_tasks))
        });
        let handle = RealTimeHandle {
            shared,
            threads: handles,
            supervisor,
            recording: Some(recording),
            controls,
            fifo,
            _pm_qos: config.cpu_dma_latency_us.and_then(hold_cpu_dma_latency),
        };
        if let Err(e) = result {
            handle.stop();
            return Err(e);
        }
        if !fifo {
            match config.scheduling {
                SchedulingMode::RequireFifo => {
                    handle.stop();
                    return Err(RtStartError::FifoNotPermitted);
                }
                SchedulingMode::BestEffort => warn_once(
                    &WARNED_NO_FIFO,
                    "SCHED_FIFO is not permitted for this process (run as root, or grant CAP_SYS_NICE or an rtprio limit); the executive runs on normal threads and its timing is not real-time",
                ),
                SchedulingMode::Normal => {}
            }
        }
        handle.shared.go.set();
        Ok(handle)
    }
}

/// Prints warnings for deadline misses of tasks whose reaction is `Warn`, outside the
/// real-time threads.
fn supervise(shared: Shared, warn_tasks: Vec<bool>) {
    let mut printed = 0usize;
    let mut seen = 0u64;
    loop {
        let stopping = shared.stop.load(Ordering::Acquire);
        let pending = shared.warn_pending.load(Ordering::Acquire);
        if pending != seen {
            seen = pending;
            let faults = shared.monitor.raw_faults();
            for f in faults.iter().skip(printed) {
                if f.code == FaultCode::DeadlineMiss && warn_tasks.get(f.task) == Some(&true) {
                    eprintln!("rtcnc-rt: warning: {}", shared.monitor.describe(f));
                }
            }
            printed = faults.len();
        }
        if stopping {
            break;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

impl RealTimeHandle {
    /// The timing monitor, live.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn monitor(&self) -> &Arc<Monitor> {
        &self.shared.monitor
    }

    /// The start/stop control of the task called `name`.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn control(&self, name: &str) -> Option<TaskControl> {
        self.controls
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, c)| c.clone())
    }

    /// True when every executive thread got SCHED_FIFO.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn is_fifo(&self) -> bool {
        self.fifo
    }

    /// Executive time now (zero at the first release; it counts up from before it).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn now(&self) -> Time {
        Time::from_nanos(self.shared.now())
    }

    fn shut_down(&mut self) {
        self.shared.stop.store(true, Ordering::Release);
        for h in self.threads.drain(..) {
            let _ = h.join();
        }
        if let Some(h) = self.supervisor.take() {
            let _ = h.join();
        }
    }

    /// Stops every thread (each at its next wake-up) and returns the monitor and trace.
    ///
    /// Real-time: no (joins the threads).
    pub fn stop(mut self) -> Recording {
        self.shut_down();
        match self.recording.take() {
            Some(r) => r,
            None => unreachable!("the recording is only taken here"),
        }
    }
}

impl Drop for RealTimeHandle {
    fn drop(&mut self) {
        self.shut_down();
    }
}
