//! The virtual-time runner: the task set on one thread and a simulated clock.
//!
//! The model is one processor with fixed-priority preemptive scheduling. A body runs at the
//! instant its turn comes (its effects are visible from that instant); the processor time it
//! declares with [`Context::consume`] then keeps the simulated processor busy, and a task of
//! higher priority released meanwhile preempts it. A periodic thread's cycle runs its task
//! functions in order; the cycle's deadline is its next release. Ties between equal
//! priorities go to whoever became ready first, then to declaration order. Nothing depends
//! on the wall clock, so every run gives the same schedule, the same monitor figures and
//! the same trace bytes.

use std::time::Duration;

use thiserror::Error;

use crate::ipc::Trigger;
use crate::monitor::{Fault, FaultCode, MissReaction, TaskState};
use crate::sys::{set_in_periodic_body, set_in_task_body, take_ipc_touched};
use crate::task::{
    Body, ClockSource, Context, DeclKind, Next, Recording, TaskControl, TaskSet, TaskSpec,
    ThreadSpec, Wake,
};
use crate::time::{Time, duration_ns};
use crate::trace::{EventKind, TraceEvent};

/// Steps allowed at one simulated instant before the run is declared a livelock.
const MAX_STEPS_PER_INSTANT: u64 = 1_000_000;

/// A virtual-time run could not go on.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum RunError {
    /// Tasks kept running at one simulated instant without consuming time (for example an
    /// event task that never takes the message that wakes it).
    #[error(
        "livelock at {time}: task '{task}' ran {MAX_STEPS_PER_INSTANT} times without time passing"
    )]
    Livelock {
        /// The task seen last.
        task: String,
        /// The simulated instant.
        time: Time,
    },
}

impl RunError {
    /// Stable error code.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn code(&self) -> &'static str {
        match self {
            RunError::Livelock { .. } => "livelock",
        }
    }
}

/// When a periodic cycle that started at `release` ends at `end`, the next release: the
/// next period boundary, or, after an overrun, the first boundary not before `end` (the
/// boundaries in between are skipped, and counted).
pub(crate) fn next_release(release: u64, period: u64, end: u64) -> (u64, u64) {
    let nominal = release.saturating_add(period);
    if end <= nominal {
        return (nominal, 0);
    }
    let skipped = (end - nominal).div_ceil(period);
    (nominal + skipped * period, skipped)
}

/// The most a periodic thread's release moves in one cycle (see
/// [`Context::shift_next_release`]): a quarter of the period.
pub(crate) fn clamp_release_shift(shift: i64, period: u64) -> i64 {
    let most = i64::try_from(period / 4).unwrap_or(i64::MAX);
    shift.clamp(-most, most)
}

/// The release of a thread whose cycles are moved by `offset` from the period grid: a cycle
/// of grid time `base` is released at `base + offset` (never before 0).
pub(crate) fn shifted(base: u64, offset: i64) -> u64 {
    u64::try_from((i128::from(base) + i128::from(offset)).max(0)).unwrap_or(u64::MAX)
}

/// When a cycle of a thread moved by `offset` (grid time `base`) ends at `end`: the next
/// release on the grid, and the boundaries skipped ([`next_release`] in the thread's own
/// frame).
pub(crate) fn next_shifted_release(base: u64, period: u64, offset: i64, end: u64) -> (u64, u64) {
    let end_on_grid =
        u64::try_from((i128::from(end) - i128::from(offset)).max(0)).unwrap_or(u64::MAX);
    next_release(base, period, end_on_grid)
}

/// Decides whether a periodic run that ended at `end` is a deadline miss, with the same rule
/// under both runners: a task with its own deadline misses when it ends later than
/// `release + deadline`; otherwise the first run of the cycle that ends after the next
/// release (`release + period`) is charged. At most one miss per task per cycle. Returns how
/// late the run was; updates `task_missed` and `cycle_missed` (who overran the period).
pub(crate) fn periodic_miss(
    release: u64,
    period: u64,
    own_deadline: Option<u64>,
    end: u64,
    task: usize,
    task_missed: &mut bool,
    cycle_missed: &mut Option<usize>,
) -> Option<u64> {
    let period_deadline = release.saturating_add(period);
    let mut late = None;
    if let Some(d) = own_deadline {
        let deadline = release.saturating_add(d);
        if end > deadline && !*task_missed {
            late = Some(end - deadline);
        }
    } else if end > period_deadline && cycle_missed.is_none() && !*task_missed {
        late = Some(end - period_deadline);
    }
    if late.is_some() {
        *task_missed = true;
    }
    if end > period_deadline && cycle_missed.is_none() {
        *cycle_missed = Some(task);
    }
    late
}

/// Whether an event or background run woken at `woke` and ended at `end` missed its own
/// deadline, and by how much.
pub(crate) fn reactive_miss(woke: u64, own_deadline: Option<u64>, end: u64) -> Option<u64> {
    let deadline = woke.saturating_add(own_deadline?);
    (end > deadline).then(|| end - deadline)
}

/// Records a deadline miss of `task` detected at `now`, `late` ns late: fault log, monitor,
/// trace, then the task's reaction (`warn_now`: print a `Warn` at once).
pub(crate) fn record_miss(
    monitor: &crate::monitor::Monitor,
    lane: &crate::trace::Lane,
    spec: &TaskSpec,
    task: usize,
    now: u64,
    late: u64,
    warn_now: bool,
) -> Fault {
    let fault = Fault {
        time: Time::from_nanos(now),
        task,
        code: FaultCode::DeadlineMiss,
        detail: late,
        message: "",
    };
    monitor.push_fault(fault);
    if let Some(m) = monitor.task_at(task) {
        m.record_miss(0);
    }
    lane.push(TraceEvent {
        time: now,
        kind: EventKind::Fault,
        task: task as u32,
        label: FaultCode::DeadlineMiss.as_str(),
        arg: late,
    });
    react_to_miss(
        &spec.reaction,
        &fault,
        || monitor.describe(&fault).to_string(),
        warn_now,
    );
    fault
}

pub(crate) fn react_to_miss(
    reaction: &MissReaction,
    fault: &Fault,
    describe: impl FnOnce() -> String,
    warn_now: bool,
) {
    match reaction {
        MissReaction::Count => {}
        MissReaction::Warn => {
            if warn_now {
                eprintln!("rtcnc-rt: warning: {}", describe());
            }
        }
        MissReaction::Hook(hook) => hook(fault),
    }
}

struct Step {
    task: usize,
    start: u64,
    remaining: u64,
    lateness: Option<u64>,
    next: Option<Next>,
}

/// What booking the end of a step needs.
struct EndedStep {
    task: usize,
    start: u64,
    lateness: Option<u64>,
}

struct Cycle {
    release: u64,
    /// The release on the period grid (`release` minus the thread's offset).
    base: u64,
    /// Shifts of the thread's next release asked in this cycle (ns).
    shift: i64,
    activation: u64,
    pos: usize,
    run: u32,
    checked: bool,
    missed: Option<usize>,
    /// The task at `pos` has had its miss this cycle.
    task_missed: bool,
    /// The task at `pos` declared its remaining runs of this cycle empty.
    runs_finished: bool,
    seq: u64,
    step: Option<Step>,
}

struct VThread {
    spec: ThreadSpec,
    next_release: u64,
    /// `next_release` on the period grid.
    next_base: u64,
    /// How far the thread's releases are moved from the grid (ns).
    offset: i64,
    cycle: Option<Cycle>,
}

enum RState {
    /// Stopped by request; waits for its start event.
    Parked,
    WaitTrigger {
        token: u64,
    },
    Suspended {
        trigger: Option<Trigger>,
        token: u64,
        deadline: Option<u64>,
    },
    Ready(Wake),
    Running,
    /// A background task that returned `Next::Done`.
    Finished,
}

struct VReactive {
    task: usize,
    priority: i32,
    trigger: Option<Trigger>,
    state: RState,
    seq: u64,
    activation: u64,
    own_token: u64,
    /// When the task last became ready (its wake-up, for its deadline).
    ready_at: u64,
    step: Option<Step>,
}

#[derive(Clone, Copy)]
enum Pick {
    Thread(usize),
    Reactive(usize),
}

/// Runs a [`TaskSet`] in simulated time, deterministically and as fast as the CPU allows.
///
/// Use [`run_for`](Self::run_for) / [`run_until`](Self::run_until) in steps; between steps,
/// code outside the task set may feed mailboxes or read the monitor, and the next step sees
/// it at the simulated instant where the previous one stopped.
pub struct VirtualRunner {
    now: u64,
    threads: Vec<VThread>,
    reactive: Vec<VReactive>,
    tasks: Vec<TaskSpec>,
    recording: Recording,
    seq: u64,
    instant_steps: u64,
    instant: u64,
    background_step_ns: u64,
    /// Something may have fired a trigger or changed a start event since the last poll.
    dirty: bool,
    /// The earliest `next_release` of the threads between two cycles (`u64::MAX`: none),
    /// so that looking for releases due does not visit every thread at every step.
    earliest_release: u64,
    /// No event or background task's timeout falls before this (`u64::MAX`: none
    /// suspended with one), so that a poll with no IPC change visits no task until then.
    earliest_timeout: u64,
    /// Host processor time spent in each task's bodies, when asked for.
    host: Option<HostProfile>,
}

/// The host processor time of a virtual-time run, per task: what simulating each task
/// costs on the computer that runs the simulation (not simulated time).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct HostProfile {
    /// Per task, in declaration order: (name, body runs, host time in the bodies, ns).
    pub tasks: Vec<(String, u64, u64)>,
    /// The cost of one pair of clock readings, ns, already taken off each body run.
    pub clock_overhead_ns: u64,
}

impl HostProfile {
    fn new(tasks: &[TaskSpec]) -> Self {
        // What reading the clock twice costs, so that it is not charged to the bodies.
        let rounds = 2000u32;
        let t0 = std::time::Instant::now();
        for _ in 0..rounds {
            std::hint::black_box(std::time::Instant::now());
        }
        let per_read = t0.elapsed().as_nanos() as u64 / u64::from(rounds);
        HostProfile {
            tasks: tasks.iter().map(|t| (t.name.clone(), 0, 0)).collect(),
            clock_overhead_ns: per_read,
        }
    }

    fn charge(&mut self, task: usize, since: std::time::Instant) {
        let ns = (since.elapsed().as_nanos() as u64).saturating_sub(self.clock_overhead_ns);
        if let Some(t) = self.tasks.get_mut(task) {
            t.1 += 1;
            t.2 += ns;
        }
    }
}

impl VirtualRunner {
    /// Takes the task set; the simulated clock starts at zero.
    ///
    /// Real-time: no (set-up: allocates).
    pub fn new(set: TaskSet) -> Self {
        let TaskSet {
            threads,
            tasks,
            recording,
        } = set;
        let reactive = tasks
            .iter()
            .enumerate()
            .filter_map(|(i, t)| {
                let trigger = match &t.kind {
                    DeclKind::Periodic { .. } => return None,
                    DeclKind::Event { trigger } => Some(trigger.clone()),
                    DeclKind::Background => None,
                };
                Some(VReactive {
                    task: i,
                    priority: t.priority,
                    trigger,
                    state: RState::Parked,
                    seq: 0,
                    activation: 0,
                    own_token: 0,
                    ready_at: 0,
                    step: None,
                })
            })
            .collect();
        VirtualRunner {
            now: 0,
            threads: threads
                .into_iter()
                .map(|spec| VThread {
                    spec,
                    next_release: 0,
                    next_base: 0,
                    offset: 0,
                    cycle: None,
                })
                .collect(),
            reactive,
            tasks,
            recording,
            seq: 0,
            instant_steps: 0,
            instant: 0,
            background_step_ns: 10_000,
            dirty: true,
            earliest_release: 0,
            earliest_timeout: u64::MAX,
            host: None,
        }
    }

    /// Measures the host processor time of every body run (two clock readings each), for
    /// a profile of what each task costs the simulation; see [`host_profile`](Self::host_profile).
    /// It changes nothing in the simulated run.
    ///
    /// Real-time: no (set-up).
    pub fn with_host_profile(mut self) -> Self {
        self.host = Some(HostProfile::new(&self.tasks));
        self
    }

    /// The host time spent in each task's bodies so far (with [`with_host_profile`](Self::with_host_profile)).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn host_profile(&self) -> Option<&HostProfile> {
        self.host.as_ref()
    }

    /// The least simulated processor time one background body run takes (default 10 µs),
    /// so that a background task that always continues lets time pass.
    ///
    /// Real-time: no (set-up).
    pub fn with_background_step(mut self, step: Duration) -> Self {
        self.background_step_ns = duration_ns(step).max(1);
        self
    }

    /// Simulated time now.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn now(&self) -> Time {
        Time::from_nanos(self.now)
    }

    /// The monitor and trace of the run.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn recording(&self) -> &Recording {
        &self.recording
    }

    /// Ends the run and keeps its monitor and trace.
    ///
    /// Real-time: no (ends the runner).
    pub fn into_recording(self) -> Recording {
        self.recording
    }

    /// The start/stop control of the task called `name`.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn control(&self, name: &str) -> Option<TaskControl> {
        let index = self.tasks.iter().position(|t| t.name == name)?;
        let t = &self.tasks[index];
        Some(TaskControl::new(
            t.control.clone(),
            index,
            std::sync::Arc::clone(&self.recording.monitor),
        ))
    }

    /// Runs for `d` of simulated time.
    ///
    /// Real-time: no (the runner itself: it runs the task set).
    pub fn run_for(&mut self, d: Duration) -> Result<(), RunError> {
        let end = self.now.saturating_add(duration_ns(d));
        self.run_until(Time::from_nanos(end))
    }

    /// Runs until simulated time `end`: everything due before `end` happens; what is due at
    /// `end` happens in the next call.
    ///
    /// Real-time: no (the runner itself: it runs the task set).
    pub fn run_until(&mut self, end: Time) -> Result<(), RunError> {
        let end = end.as_nanos();
        // Code outside the task set may have fed mailboxes or started tasks since the last call.
        self.dirty = true;
        while self.now < end {
            self.refresh();
            match self.pick() {
                None => {
                    let t = self.next_event_time().unwrap_or(u64::MAX);
                    self.now = t.min(end).max(self.now);
                }
                Some(pick) => {
                    let remaining = match pick {
                        Pick::Thread(i) => self.threads[i]
                            .cycle
                            .as_ref()
                            .and_then(|c| c.step.as_ref())
                            .map(|s| s.remaining),
                        Pick::Reactive(i) => self.reactive[i].step.as_ref().map(|s| s.remaining),
                    };
                    match remaining {
                        Some(rem) => {
                            let horizon = self.next_event_time().unwrap_or(u64::MAX).min(end);
                            let slice = rem.min(horizon.saturating_sub(self.now));
                            self.now += slice;
                            let left = rem - slice;
                            match pick {
                                Pick::Thread(i) => {
                                    if let Some(s) =
                                        self.threads[i].cycle.as_mut().and_then(|c| c.step.as_mut())
                                    {
                                        s.remaining = left;
                                    }
                                    if left == 0 {
                                        self.finish_thread_step(i);
                                    }
                                }
                                Pick::Reactive(i) => {
                                    if let Some(s) = self.reactive[i].step.as_mut() {
                                        s.remaining = left;
                                    }
                                    if left == 0 {
                                        self.finish_reactive_step(i);
                                    }
                                }
                            }
                        }
                        None => {
                            if self.instant != self.now {
                                self.instant = self.now;
                                self.instant_steps = 0;
                            }
                            self.instant_steps += 1;
                            if self.instant_steps > MAX_STEPS_PER_INSTANT {
                                let task = match pick {
                                    Pick::Thread(i) => self.threads[i].spec.name.clone(),
                                    Pick::Reactive(i) => {
                                        self.tasks[self.reactive[i].task].name.clone()
                                    }
                                };
                                return Err(RunError::Livelock {
                                    task,
                                    time: Time::from_nanos(self.now),
                                });
                            }
                            match pick {
                                Pick::Thread(i) => self.start_thread_step(i),
                                Pick::Reactive(i) => self.start_reactive_step(i),
                            }
                        }
                    }
                }
            }
        }
        Ok(())
    }

    fn next_seq(&mut self) -> u64 {
        self.seq += 1;
        self.seq
    }

    fn set_state(&self, task: usize, state: TaskState) {
        if let Some(m) = self.recording.monitor.task_at(task) {
            m.set_state(state);
        }
    }

    /// Releases due threads, wakes tasks whose trigger fired or timeout passed.
    fn refresh(&mut self) {
        if self.earliest_release <= self.now {
            self.release_due_threads();
        }
        self.poll_reactive();
    }

    /// Starts the cycle of every thread whose release is due, and finds the next release.
    fn release_due_threads(&mut self) {
        let mut earliest = u64::MAX;
        for i in 0..self.threads.len() {
            let th = &self.threads[i];
            if th.cycle.is_none() && th.next_release <= self.now {
                let release = th.next_release;
                let base = th.next_base;
                let activation = base / th.spec.period_ns.max(1);
                let seq = self.next_seq();
                let th = &mut self.threads[i];
                th.cycle = Some(Cycle {
                    release,
                    base,
                    shift: 0,
                    activation,
                    pos: 0,
                    run: 0,
                    checked: false,
                    missed: None,
                    task_missed: false,
                    runs_finished: false,
                    seq,
                    step: None,
                });
                for &t in &th.spec.tasks {
                    if self.tasks[t].control.is_set() {
                        if let Some(m) = self.recording.monitor.task_at(t) {
                            m.set_state(TaskState::Ready);
                        }
                    }
                }
            } else if th.cycle.is_none() {
                earliest = earliest.min(th.next_release);
            }
        }
        self.earliest_release = earliest;
    }

    /// Wakes event and background tasks whose trigger fired or timeout passed.
    fn poll_reactive(&mut self) {
        // Triggers and start events only change under an IPC object's lock, taken by a body
        // (or a miss hook, or code outside the task set between two run calls), or when a
        // task's own waiting state changed; without that, only timeouts can wake a task.
        let poll = std::mem::take(&mut self.dirty) | take_ipc_touched();
        if !poll && self.earliest_timeout > self.now {
            return;
        }
        for i in 0..self.reactive.len() {
            if !poll {
                let due = matches!(
                    self.reactive[i].state,
                    RState::Suspended { deadline: Some(d), .. } if d <= self.now
                );
                if due {
                    let seq = self.next_seq();
                    let r = &mut self.reactive[i];
                    r.state = RState::Ready(Wake::TimedOut);
                    r.seq = seq;
                    r.ready_at = self.now;
                    let task = r.task;
                    self.set_state(task, TaskState::Ready);
                }
                continue;
            }
            let task = self.reactive[i].task;
            let started = self.tasks[task].control.is_set();
            // A started event task begins waiting for its trigger (and may find it ready now).
            if started && matches!(self.reactive[i].state, RState::Parked) {
                if let Some(trig) = &self.reactive[i].trigger {
                    let token = trig.source.arm();
                    self.reactive[i].state = RState::WaitTrigger { token };
                    self.set_state(task, TaskState::Stopped);
                }
            }
            let r = &self.reactive[i];
            let wake: Option<Wake> = match &r.state {
                RState::Parked => (started && r.trigger.is_none()).then_some(Wake::Scheduled),
                RState::WaitTrigger { token } => {
                    if !started {
                        self.reactive[i].state = RState::Parked;
                        None
                    } else {
                        match &r.trigger {
                            Some(trig)
                                if trig.source.is_ready(*token) && trig.source.try_take(*token) =>
                            {
                                Some(Wake::Triggered)
                            }
                            _ => None,
                        }
                    }
                }
                RState::Suspended {
                    trigger,
                    token,
                    deadline,
                } => {
                    let fired = trigger
                        .as_ref()
                        .is_some_and(|t| t.source.is_ready(*token) && t.source.try_take(*token));
                    if fired {
                        Some(Wake::Triggered)
                    } else if deadline.is_some_and(|d| d <= self.now) {
                        Some(Wake::TimedOut)
                    } else {
                        None
                    }
                }
                RState::Ready(_) | RState::Running | RState::Finished => None,
            };
            if let Some(w) = wake {
                let seq = self.next_seq();
                let now = self.now;
                let r = &mut self.reactive[i];
                r.state = RState::Ready(w);
                r.seq = seq;
                r.ready_at = now;
                self.set_state(task, TaskState::Ready);
            }
        }
        self.earliest_timeout = self
            .reactive
            .iter()
            .filter_map(|r| match r.state {
                RState::Suspended { deadline, .. } => deadline,
                _ => None,
            })
            .min()
            .unwrap_or(u64::MAX);
    }

    /// Whether an event or background task of a priority above `priority` is ready.
    fn reactive_above(&self, priority: i32) -> bool {
        self.reactive
            .iter()
            .any(|r| r.priority > priority && matches!(r.state, RState::Ready(_) | RState::Running))
    }

    fn pick(&self) -> Option<Pick> {
        let mut best: Option<(i32, u64, Pick)> = None;
        let mut consider = |prio: i32, seq: u64, p: Pick| {
            let better = match best {
                None => true,
                Some((bp, bs, _)) => prio > bp || (prio == bp && seq < bs),
            };
            if better {
                best = Some((prio, seq, p));
            }
        };
        for (i, th) in self.threads.iter().enumerate() {
            if let Some(c) = &th.cycle {
                consider(th.spec.priority, c.seq, Pick::Thread(i));
            }
        }
        for (i, r) in self.reactive.iter().enumerate() {
            if matches!(r.state, RState::Ready(_) | RState::Running) {
                consider(r.priority, r.seq, Pick::Reactive(i));
            }
        }
        best.map(|(_, _, p)| p)
    }

    fn next_event_time(&self) -> Option<u64> {
        // Called after `refresh`: every release due has been made, so the earliest is ahead.
        let releases = (self.earliest_release > self.now).then_some(self.earliest_release);
        let timeouts = self.reactive.iter().filter_map(|r| match r.state {
            RState::Suspended { deadline, .. } => deadline,
            _ => None,
        });
        releases
            .into_iter()
            .chain(timeouts)
            .filter(|&t| t > self.now)
            .min()
    }

    #[allow(clippy::too_many_arguments)]
    fn context<'a>(
        recording: &'a Recording,
        name: &'a str,
        lane: usize,
        task: usize,
        now: u64,
        release: u64,
        activation: u64,
        run: u32,
        wake: Wake,
    ) -> Context<'a> {
        Context {
            task,
            name,
            clock: ClockSource::Virtual,
            start: now,
            release,
            activation,
            run,
            wake,
            consumed: 0,
            runs_finished: false,
            release_shift: 0,
            lane: &recording.lanes[lane],
            monitor: &recording.monitor,
        }
    }

    /// Starts the next step of thread `i`'s cycle. Steps that declare no processor time end
    /// at once; the cycle then goes on with its next step here, without a round through
    /// the scheduler loop, as long as that loop would pick this thread again: no release
    /// can fall due at this instant, so only an event task of higher priority woken by the
    /// body can come first (equal priorities woken now queue behind this cycle).
    fn start_thread_step(&mut self, i: usize) {
        loop {
            if !self.start_one_thread_step(i) || self.threads[i].cycle.is_none() {
                return;
            }
            self.poll_reactive();
            if self.reactive_above(self.threads[i].spec.priority)
                || self.instant_steps >= MAX_STEPS_PER_INSTANT
            {
                return;
            }
            self.instant_steps += 1;
        }
    }

    /// One step of thread `i`'s cycle; true when it declared no time and is over.
    fn start_one_thread_step(&mut self, i: usize) -> bool {
        let now = self.now;
        let th = &mut self.threads[i];
        let Some(cycle) = th.cycle.as_mut() else {
            return false;
        };
        // Skip tasks asked to stop: they stop themselves at the start of their cycle.
        while let Some(&task) = th.spec.tasks.get(cycle.pos) {
            if cycle.checked || self.tasks[task].control.is_set() {
                cycle.checked = true;
                break;
            }
            if let Some(m) = self.recording.monitor.task_at(task) {
                m.set_state(TaskState::Stopped);
            }
            cycle.pos += 1;
        }
        let Some(&task) = th.spec.tasks.get(cycle.pos) else {
            self.finish_cycle(i);
            return false;
        };
        let TaskSpec {
            name, body, lane, ..
        } = &mut self.tasks[task];
        let mut ctx = Self::context(
            &self.recording,
            name,
            *lane,
            task,
            now,
            cycle.release,
            cycle.activation,
            cycle.run,
            Wake::Period,
        );
        if let Some(m) = self.recording.monitor.task_at(task) {
            m.set_state(TaskState::Running);
        }
        set_in_task_body(true);
        let host_start = self.host.is_some().then(std::time::Instant::now);
        if let Body::Periodic(body) = body {
            set_in_periodic_body(true);
            body(&mut ctx);
            set_in_periodic_body(false);
        }
        if let (Some(profile), Some(start)) = (self.host.as_mut(), host_start) {
            profile.charge(task, start);
        }
        set_in_task_body(false);
        let cost = ctx.consumed;
        cycle.runs_finished = ctx.runs_finished;
        cycle.shift = cycle.shift.saturating_add(ctx.release_shift);
        let lateness = Some(now - cycle.release);
        if cost == 0 {
            // Over at once: no step to keep for the scheduler loop.
            self.end_thread_step(i, task, now, lateness);
            return true;
        }
        cycle.step = Some(Step {
            task,
            start: now,
            remaining: cost,
            lateness,
            next: None,
        });
        false
    }

    fn finish_thread_step(&mut self, i: usize) {
        let Some(step) = self.threads[i].cycle.as_mut().and_then(|c| c.step.take()) else {
            return;
        };
        self.end_thread_step(i, step.task, step.start, step.lateness);
    }

    /// Books the end of a step of thread `i` (task `task`, started at `start`) now.
    fn end_thread_step(&mut self, i: usize, task: usize, start: u64, lateness: Option<u64>) {
        let step = EndedStep {
            task,
            start,
            lateness,
        };
        let now = self.now;
        let th = &mut self.threads[i];
        let Some(cycle) = th.cycle.as_mut() else {
            return;
        };
        let recording = &self.recording;
        let spec = &self.tasks[step.task];
        if let Some(m) = recording.monitor.task_at(step.task) {
            m.record_run(step.lateness, now - step.start);
        }
        recording.lanes[spec.lane].push(TraceEvent {
            time: step.start,
            kind: EventKind::Span,
            task: step.task as u32,
            label: "",
            arg: now - step.start,
        });
        if let Some(late) = periodic_miss(
            cycle.release,
            th.spec.period_ns,
            spec.deadline_ns,
            now,
            step.task,
            &mut cycle.task_missed,
            &mut cycle.missed,
        ) {
            record_miss(
                &recording.monitor,
                &recording.lanes[spec.lane],
                spec,
                step.task,
                now,
                late,
                true,
            );
        }
        let runs = match spec.kind {
            DeclKind::Periodic { runs, .. } => runs,
            _ => 1,
        };
        cycle.run += 1;
        if cycle.run >= runs || cycle.runs_finished {
            cycle.run = 0;
            cycle.runs_finished = false;
            cycle.pos += 1;
            cycle.checked = false;
            cycle.task_missed = false;
            if let Some(m) = recording.monitor.task_at(step.task) {
                m.set_state(TaskState::Waiting);
            }
        }
        if cycle.pos >= th.spec.tasks.len() {
            self.finish_cycle(i);
        }
    }

    fn finish_cycle(&mut self, i: usize) {
        let now = self.now;
        let th = &mut self.threads[i];
        let Some((base, shift, missed)) = th.cycle.as_ref().map(|c| (c.base, c.shift, c.missed))
        else {
            return;
        };
        th.cycle = None;
        let period = th.spec.period_ns;
        if shift != 0 {
            th.offset = th.offset.saturating_add(clamp_release_shift(shift, period));
        }
        // A thread on the grid (every thread but one following an outside clock) needs
        // none of the shifted arithmetic.
        let (next, skipped) = if th.offset == 0 {
            next_release(base, period, now)
        } else {
            next_shifted_release(base, period, th.offset, now)
        };
        th.next_base = next;
        th.next_release = if th.offset == 0 {
            next
        } else {
            shifted(next, th.offset)
        };
        self.earliest_release = self.earliest_release.min(th.next_release);
        if skipped > 0 {
            if let Some(m) = missed.and_then(|t| self.recording.monitor.task_at(t)) {
                m.record_skipped(skipped);
            }
        }
    }

    fn start_reactive_step(&mut self, i: usize) {
        let now = self.now;
        let r = &mut self.reactive[i];
        let task = r.task;
        let wake = match r.state {
            RState::Ready(w) => w,
            _ => return,
        };
        let spec = &mut self.tasks[task];
        if !spec.control.is_set() {
            r.state = RState::Parked;
            if let Some(m) = self.recording.monitor.task_at(task) {
                m.set_state(TaskState::Stopped);
            }
            return;
        }
        if let Some(t) = &r.trigger {
            r.own_token = t.source.arm();
        }
        let TaskSpec {
            name,
            body,
            lane,
            kind,
            ..
        } = spec;
        let mut ctx = Self::context(
            &self.recording,
            name,
            *lane,
            task,
            now,
            now,
            r.activation,
            0,
            wake,
        );
        r.activation += 1;
        r.state = RState::Running;
        if let Some(m) = self.recording.monitor.task_at(task) {
            m.set_state(TaskState::Running);
        }
        set_in_task_body(true);
        let host_start = self.host.is_some().then(std::time::Instant::now);
        let next = match body {
            Body::Reactive(body) => body(&mut ctx),
            Body::Periodic(_) => Next::Done,
        };
        if let (Some(profile), Some(start)) = (self.host.as_mut(), host_start) {
            profile.charge(task, start);
        }
        set_in_task_body(false);
        let mut cost = ctx.consumed;
        if matches!(kind, DeclKind::Background) {
            cost = cost.max(self.background_step_ns);
        }
        r.step = Some(Step {
            task,
            start: now,
            remaining: cost,
            lateness: None,
            next: Some(next),
        });
        if cost == 0 {
            self.finish_reactive_step(i);
        }
    }

    fn finish_reactive_step(&mut self, i: usize) {
        let now = self.now;
        let seq = self.next_seq();
        let r = &mut self.reactive[i];
        let Some(step) = r.step.take() else {
            return;
        };
        let spec = &self.tasks[step.task];
        if let Some(m) = self.recording.monitor.task_at(step.task) {
            m.record_run(None, now - step.start);
        }
        self.recording.lanes[spec.lane].push(TraceEvent {
            time: step.start,
            kind: EventKind::Span,
            task: step.task as u32,
            label: "",
            arg: now - step.start,
        });
        if let Some(late) = reactive_miss(r.ready_at, spec.deadline_ns, now) {
            record_miss(
                &self.recording.monitor,
                &self.recording.lanes[spec.lane],
                spec,
                step.task,
                now,
                late,
                true,
            );
        }
        let (state, shown) = match step.next.unwrap_or(Next::Done) {
            Next::Done => match &r.trigger {
                Some(_) => (
                    RState::WaitTrigger { token: r.own_token },
                    TaskState::Stopped,
                ),
                None => (RState::Finished, TaskState::Stopped),
            },
            Next::Continue => {
                r.seq = seq;
                r.ready_at = now;
                (RState::Ready(Wake::Scheduled), TaskState::Ready)
            }
            Next::WaitFor { trigger, timeout } => {
                let token = trigger.source.arm();
                (
                    RState::Suspended {
                        trigger: Some(trigger),
                        token,
                        deadline: timeout.map(|d| now.saturating_add(duration_ns(d))),
                    },
                    TaskState::Suspended,
                )
            }
            Next::Sleep(d) => (
                RState::Suspended {
                    trigger: None,
                    token: 0,
                    deadline: Some(now.saturating_add(duration_ns(d))),
                },
                TaskState::Suspended,
            ),
        };
        let timeout = match &state {
            RState::Suspended { deadline, .. } => *deadline,
            _ => None,
        };
        r.state = state;
        if let Some(d) = timeout {
            self.earliest_timeout = self.earliest_timeout.min(d);
        }
        if let Some(m) = self.recording.monitor.task_at(step.task) {
            m.set_state(shown);
        }
        self.dirty = true;
    }
}
