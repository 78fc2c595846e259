//! The machine's side of the link, as three real-time task bodies and nothing that waits:
//! - [`UrgentPort`], the first function of the interpolation thread: the client's
//!   heartbeat, the loss reaction, and the urgent ring forwarded into the kernel's urgent
//!   channel, which interpolation reads right after in the same period;
//! - [`CommandPort`], inside command parsing: normal commands by serial, their
//!   acknowledgements (accepted, refused with the reason, done or failed), the continuous
//!   jog's keep-alive;
//! - [`Publisher`], after status feedback: the status snapshot, the events (faults,
//!   operator messages, state changes, acknowledgements), the trace samples.
//!
//! Neither allocates after start-up nor takes a lock other than the kernel's PI mutexes
//! (with `try_lock`): a client that stops reading only fills its rings, whose overflow is
//! counted.

use std::sync::Arc;
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};

use rtcnc_rt::{Context, RingConsumer, RingProducer, SeqlockReader};

use super::Refusal;
use super::layout::Segment;
use super::layout::{self, WireEvent, WireStatus, WireText, ack, command, event, flags, urgent};
use super::segment::{LinkError, Mapping, monotonic_ns};
use crate::config::{MAX_JOINTS, MachineConfig, OnLoss};
use crate::fault::Fault;
use crate::messages::{Command, FixedText, MachineState, Mode, Status, Urgent};
use crate::modal::ModalSnapshot;
use crate::servo::Sample;
use crate::shared::{Feedback, InterpreterRequest, LogicOutputs, LogicRequests, Shared, Snapshot};

/// How long the machine waits for the client's heartbeat before it declares it lost.
pub const LOSS_TIMEOUT: std::time::Duration = std::time::Duration::from_millis(250);
/// A continuous jog stops this long after its last keep-alive.
pub const JOG_KEEP_ALIVE: std::time::Duration = std::time::Duration::from_millis(200);

/// The machine's segment, created by the machine process and given to `Kernel::build`
/// (`KernelOptions::link`).
#[derive(Clone, Debug)]
pub struct MachineLink {
    map: Mapping,
    state: Arc<LinkState>,
}

/// What the three ports share (single writers each, plain atomics).
#[derive(Debug, Default)]
struct LinkState {
    feed_override: AtomicU64,
    rapid_override: AtomicU64,
    spindle_override: AtomicU64,
    /// [`flags`] bits the command port owns.
    flags: AtomicU32,
}

impl MachineLink {
    /// Creates the segment called `name` for this machine (replacing a dead machine's).
    pub fn create(name: &str, config: &MachineConfig) -> Result<MachineLink, LinkError> {
        let servo = config.servo_period();
        let status_period = rtcnc_rt::parse_duration(&config.tasks.status_feedback.period)
            .unwrap_or(servo)
            .max(servo);
        let map = Mapping::create(name, |h| {
            h.instance = monotonic_ns() ^ (u64::from(std::process::id()) << 48);
            h.joint_count = config.joints.len() as u32;
            h.servo_period_ns = servo.as_nanos() as u64;
            h.status_period_ns = status_period.as_nanos() as u64;
            h.axes_present = config
                .axis_plan()
                .iter()
                .fold(0, |m, p| m | 1 << (p.axis as u32));
            h.on_loss = match config.hmi.on_loss {
                OnLoss::Continue => 0,
                OnLoss::Hold => 1,
                OnLoss::Estop => 2,
            };
            h.loss_timeout_ns = LOSS_TIMEOUT.as_nanos() as u64;
            h.jog_keep_alive_ns = JOG_KEEP_ALIVE.as_nanos() as u64;
            h.machine_name = layout::name_field(&config.machine.name);
            for (j, joint) in config.joints.iter().enumerate().take(MAX_JOINTS) {
                h.joint_names[j] = layout::name_field(&joint.name);
            }
        })?;
        let state = LinkState::default();
        for o in [
            &state.feed_override,
            &state.rapid_override,
            &state.spindle_override,
        ] {
            o.store(1f64.to_bits(), Ordering::Relaxed);
        }
        Ok(MachineLink {
            map,
            state: Arc::new(state),
        })
    }

    /// The mapping.
    pub fn mapping(&self) -> &Mapping {
        &self.map
    }

    /// The three ports, for the kernel's task graph.
    pub(crate) fn ports(
        &self,
        shared: &Shared,
        modal: SeqlockReader<ModalSnapshot>,
        samples: Option<RingConsumer<Sample>>,
    ) -> Result<(UrgentPort, CommandPort, Publisher), rtcnc_rt::ConfigError> {
        let (urgent_events, from_urgent) = rtcnc_rt::ring::<WireEvent>("link urgent acks", 64)?;
        let (command_events, from_commands) =
            rtcnc_rt::ring::<WireEvent>("link command acks", 128)?;
        let header = &self.map.segment().header;
        let period = header.servo_period_ns.max(1);
        Ok((
            UrgentPort {
                map: self.map.clone(),
                state: self.state.clone(),
                status: Snapshot::new(shared.status.clone()),
                events: urgent_events,
                last_heartbeat: 0,
                last_seen_ns: 0,
                loss_timeout_ns: header.loss_timeout_ns,
                on_loss: header.on_loss,
                known_pid: 0,
                known_detaches: 0,
            },
            CommandPort {
                map: self.map.clone(),
                state: self.state.clone(),
                shared: shared.clone(),
                status: Snapshot::new(shared.status.clone()),
                feedback: Snapshot::new(shared.feedback.clone()),
                events: command_events,
                pending: [None; 8],
                jog_until: [None; layout::AXES],
                keep_alive_ns: header.jog_keep_alive_ns,
                axes_present: header.axes_present,
                _period: period,
            },
            Publisher {
                map: self.map.clone(),
                state: self.state.clone(),
                shared: shared.clone(),
                status: Snapshot::new(shared.status.clone()),
                feedback: Snapshot::new(shared.feedback.clone()),
                requests: Snapshot::new(shared.requests.clone()),
                outputs: Snapshot::new(shared.logic_outputs.clone()),
                modal: Snapshot::new(modal),
                samples,
                from_urgent,
                from_commands,
                seq: 0,
                following_error: [0.0; MAX_JOINTS],
                last_state: u32::MAX,
                ended: false,
                joints: header.joint_count as usize,
                out: WireStatus::default(),
            },
        ))
    }
}

/// The `MachineState` number of the link.
pub fn state_number(s: MachineState) -> u32 {
    match s {
        MachineState::Starting => 0,
        MachineState::EStop => 1,
        MachineState::Idle => 2,
        MachineState::Running => 3,
        MachineState::Held => 4,
        MachineState::Paused => 5,
        MachineState::WaitingForLogic => 6,
        MachineState::Fault => 7,
    }
}

fn mode_number(m: Mode) -> u32 {
    match m {
        Mode::Manual => 0,
        Mode::Auto => 1,
        Mode::Mdi => 2,
    }
}

fn ack_event(serial: u64, kind: u32, refusal: Option<Refusal>) -> WireEvent {
    let mut e = WireEvent {
        kind: event::ACK,
        code: kind,
        serial,
        joint: -1,
        ..WireEvent::default()
    };
    if let Some(r) = refusal {
        e.number = u64::from(r.number());
        e.text = WireText::new(r.message());
    }
    e
}

/// The first function of the interpolation thread.
pub(crate) struct UrgentPort {
    map: Mapping,
    state: Arc<LinkState>,
    status: Snapshot<Status>,
    events: RingProducer<WireEvent>,
    last_heartbeat: u64,
    last_seen_ns: u64,
    loss_timeout_ns: u64,
    on_loss: u32,
    /// The client seen last period (0: none).
    known_pid: u32,
    /// Its clean departures counted then.
    known_detaches: u64,
}

impl UrgentPort {
    /// Heartbeats, the loss reaction, then every urgent command into the kernel's urgent
    /// channel (interpolation, next in this thread, reads them in this same period).
    pub(crate) fn run(&mut self, ctx: &mut Context<'_>, shared: &Shared) {
        let seg = self.map.segment();
        let cycle = ctx.activation();
        seg.machine_heartbeat.store(cycle, Ordering::Release);
        let now = ctx.now().as_nanos();
        let beat = seg.client_heartbeat.load(Ordering::Acquire);
        if beat != self.last_heartbeat || self.last_seen_ns == 0 {
            self.last_heartbeat = beat;
            self.last_seen_ns = now;
        }
        // The client is lost when its heartbeat stops, or when another process took its
        // place without it having left (it was killed and a new one attached at once).
        let pid = seg.client_pid.load(Ordering::Acquire);
        let detaches = seg.client_detaches.load(Ordering::Acquire);
        let replaced =
            self.known_pid != 0 && pid != self.known_pid && detaches == self.known_detaches;
        let stale = pid != 0
            && now.saturating_sub(self.last_seen_ns) > self.loss_timeout_ns
            && seg
                .client_pid
                .compare_exchange(pid, 0, Ordering::AcqRel, Ordering::Relaxed)
                .is_ok();
        if replaced || stale {
            self.last_seen_ns = now;
            seg.client_losses.fetch_add(1, Ordering::Relaxed);
            let status = *self.status.get();
            // A jog (or homing) never goes on without its operator.
            if status.mode == Mode::Manual && status.state == MachineState::Running {
                let _ = shared.urgent.try_put(Urgent::Abort);
            }
            match self.on_loss {
                1 => {
                    let _ = shared.urgent.try_put(Urgent::FeedHold);
                }
                2 => {
                    let _ = shared.urgent.try_put(Urgent::EStop);
                }
                _ => {}
            }
            let lost = if replaced { self.known_pid } else { pid };
            let _ = self.events.push(WireEvent {
                kind: event::CLIENT_LOST,
                code: self.on_loss,
                number: u64::from(lost),
                joint: -1,
                ..WireEvent::default()
            });
        }
        self.known_pid = if stale { 0 } else { pid };
        self.known_detaches = detaches;
        // SAFETY: this task is the urgent ring's only consumer.
        while let Some(u) = unsafe { seg.urgent.pop() } {
            let acted_ns = monotonic_ns();
            let clamp = |v: f64, lo: f64, hi: f64, nan: f64| {
                if v.is_finite() { v.clamp(lo, hi) } else { nan }
            };
            let forwarded = match u.kind {
                urgent::ESTOP => Some(Urgent::EStop),
                urgent::FEED_HOLD => Some(Urgent::FeedHold),
                urgent::RESUME => Some(Urgent::Resume),
                urgent::ABORT => Some(Urgent::Abort),
                urgent::FEED_OVERRIDE => {
                    let v = clamp(u.value, 0.0, 2.0, 0.0);
                    self.state
                        .feed_override
                        .store(v.to_bits(), Ordering::Relaxed);
                    Some(Urgent::FeedOverride(v))
                }
                urgent::RAPID_OVERRIDE => {
                    let v = clamp(u.value, 0.0, 1.0, 0.0);
                    self.state
                        .rapid_override
                        .store(v.to_bits(), Ordering::Relaxed);
                    Some(Urgent::RapidOverride(v))
                }
                urgent::SPINDLE_OVERRIDE => {
                    let v = clamp(u.value, 0.5, 1.5, 1.0);
                    self.state
                        .spindle_override
                        .store(v.to_bits(), Ordering::Relaxed);
                    Some(Urgent::SpindleOverride(v))
                }
                _ => None,
            };
            let ok = match (u.kind, forwarded) {
                (_, Some(cmd)) => shared.urgent.try_put(cmd).is_ok(),
                // The kernel's jog stop is a normal command: put ahead of the others.
                (urgent::JOG_STOP, None) if u.axis < layout::AXES as u32 => shared
                    .normal
                    .put_front(Command::JogStop { axis: u.axis as u8 })
                    .is_ok(),
                _ => false,
            };
            let mut e = if ok {
                ack_event(u.serial, ack::DONE, None)
            } else if u.kind == urgent::JOG_STOP || forwarded.is_some() {
                ack_event(u.serial, ack::REFUSED, Some(Refusal::ChannelFull))
            } else {
                ack_event(u.serial, ack::REFUSED, Some(Refusal::Unknown))
            };
            e.cycle = cycle;
            e.written_ns = u.written_ns;
            e.written_cycle = u.written_cycle;
            e.acted_ns = acted_ns;
            e.number = if ok { 0 } else { e.number };
            let _ = self.events.push(e);
        }
    }
}

/// Commands whose acknowledgement waits for what they started to finish.
#[derive(Clone, Copy, Debug)]
struct Pending {
    serial: u64,
    kind: u32,
    /// The status cycle when it was accepted.
    since: u64,
    /// The machine was seen busy since.
    seen_busy: bool,
}

/// Normal commands from the client, inside the command-parsing task.
pub(crate) struct CommandPort {
    map: Mapping,
    state: Arc<LinkState>,
    shared: Shared,
    status: Snapshot<Status>,
    feedback: Snapshot<Feedback>,
    events: RingProducer<WireEvent>,
    pending: [Option<Pending>; 8],
    /// Continuous jogs and when they stop without a keep-alive (machine time, ns).
    jog_until: [Option<u64>; layout::AXES],
    keep_alive_ns: u64,
    axes_present: u32,
    _period: u64,
}

impl CommandPort {
    /// The next kernel command from the client (with its serial), or a jog stop of a
    /// continuous jog whose keep-alive lapsed (serial 0). Commands of the link itself
    /// (program load, keep-alive, tool table) are carried out here.
    pub(crate) fn next(&mut self, ctx: &mut Context<'_>) -> Option<(u64, Command)> {
        let now = ctx.now().as_nanos();
        self.settle_pending();
        for axis in 0..layout::AXES {
            if self.jog_until[axis].is_some_and(|t| now > t) {
                self.jog_until[axis] = None;
                return Some((0, Command::JogStop { axis: axis as u8 }));
            }
        }
        // A clone of the mapping's handle (no allocation) so `self` stays free to borrow.
        let map = self.map.clone();
        let seg = map.segment();
        loop {
            // SAFETY: this task is the command ring's only consumer.
            let c = unsafe { seg.commands.pop() }?;
            let axis = u8::try_from(c.axis).unwrap_or(u8::MAX);
            let on = c.number != 0;
            let cmd = match c.kind {
                command::RESET => Command::Reset,
                command::START => {
                    if self.state.flags.load(Ordering::Relaxed) & flags::PROGRAM_LOADED == 0 {
                        self.refuse(c.serial, Refusal::NoProgram);
                        continue;
                    }
                    Command::Start {
                        from_line: u32::try_from(c.number).unwrap_or(u32::MAX),
                    }
                }
                command::MDI => match FixedText::new(c.text.as_str()) {
                    Some(line) if !line.as_str().trim().is_empty() => Command::Mdi(line),
                    _ => {
                        self.refuse(c.serial, Refusal::BadValue);
                        continue;
                    }
                },
                command::JOG_CONTINUOUS => Command::JogContinuous {
                    axis,
                    velocity: c.value,
                },
                command::JOG_INCREMENT => Command::JogIncrement {
                    axis,
                    distance: c.value,
                },
                command::JOG_STOP => Command::JogStop { axis },
                command::HOME_ALL => Command::HomeAll,
                command::HOME_AXIS => Command::HomeAxis { axis },
                command::SET_MODE => match c.number {
                    0 => Command::SetMode(Mode::Manual),
                    1 => Command::SetMode(Mode::Auto),
                    2 => Command::SetMode(Mode::Mdi),
                    _ => {
                        self.refuse(c.serial, Refusal::BadValue);
                        continue;
                    }
                },
                command::HANDWHEEL => Command::Handwheel {
                    axis: (c.axis != u32::MAX).then_some(axis),
                    scale: c.value,
                },
                command::SINGLE_BLOCK => {
                    self.set_flag(flags::SINGLE_BLOCK, on);
                    Command::SingleBlock(on)
                }
                command::OPTIONAL_STOP => {
                    self.set_flag(flags::OPTIONAL_STOP, on);
                    Command::OptionalStop(on)
                }
                command::BLOCK_DELETE => {
                    self.set_flag(flags::BLOCK_DELETE, on);
                    Command::BlockDelete(on)
                }
                command::JOG_KEEP_ALIVE => {
                    if let Some(until) = self.jog_until.get_mut(usize::from(axis)) {
                        if until.is_some() {
                            *until = Some(now + self.keep_alive_ns);
                        }
                    }
                    continue;
                }
                command::LOAD_PROGRAM => {
                    let reply = self.load_program(&c.text);
                    self.answer(c.serial, reply);
                    continue;
                }
                command::RELOAD_TOOL_TABLE => {
                    let reply = if !self.idle() {
                        Err(Refusal::Busy)
                    } else {
                        self.shared
                            .interpreter_requests
                            .try_put(InterpreterRequest::ReloadToolTable)
                            .map_err(|_| Refusal::ChannelFull)
                            .map(|()| self.shared.interpreter_wake.signal())
                    };
                    self.answer(c.serial, reply);
                    continue;
                }
                _ => {
                    self.refuse(c.serial, Refusal::Unknown);
                    continue;
                }
            };
            return Some((c.serial, cmd));
        }
    }

    /// Whose keep-alive is watched: a client's continuous jog starts the watch of its axis;
    /// whatever else takes the axis ends it (a jog stop from either channel, an incremental
    /// jog, a jog of the kernel's own channel, the handwheel, homing), so that a lapse
    /// never stops a motion that needs no keep-alive. `from_client`: the command came
    /// through the link; the others are the kernel's own channel (urgent jog stops go
    /// there).
    pub(crate) fn watch_keep_alive(
        &mut self,
        ctx: &mut Context<'_>,
        from_client: bool,
        cmd: Command,
        ok: bool,
    ) {
        let (axis, watch) = match cmd {
            Command::JogContinuous { axis, .. } if ok => (axis, from_client),
            Command::JogStop { axis } => (axis, false),
            Command::JogIncrement { axis, .. } | Command::HomeAxis { axis } if ok => (axis, false),
            Command::Handwheel {
                axis: Some(axis), ..
            } if ok => (axis, false),
            Command::HomeAll if ok => {
                self.jog_until = [None; layout::AXES];
                return;
            }
            _ => return,
        };
        if let Some(until) = self.jog_until.get_mut(usize::from(axis)) {
            *until = watch.then(|| ctx.now().as_nanos() + self.keep_alive_ns);
        }
    }

    /// What the kernel made of a command [`next`](Self::next) gave.
    pub(crate) fn result(&mut self, ctx: &mut Context<'_>, serial: u64, cmd: Command, ok: bool) {
        self.watch_keep_alive(ctx, true, cmd, ok);
        if serial == 0 {
            return;
        }
        if !ok {
            let reason = self.why_refused(&cmd);
            self.refuse(serial, reason);
            return;
        }
        let waits = matches!(
            cmd,
            Command::Start { .. }
                | Command::Mdi(_)
                | Command::JogContinuous { .. }
                | Command::JogIncrement { .. }
                | Command::HomeAll
                | Command::HomeAxis { .. }
        );
        let kind = match cmd {
            Command::Start { .. } => command::START,
            Command::Mdi(_) => command::MDI,
            Command::JogContinuous { .. } => command::JOG_CONTINUOUS,
            Command::JogIncrement { .. } => command::JOG_INCREMENT,
            Command::HomeAxis { .. } => command::HOME_AXIS,
            _ => command::HOME_ALL,
        };
        let _ = self.events.push(ack_event(serial, ack::ACCEPTED, None));
        if !waits {
            let _ = self.events.push(ack_event(serial, ack::DONE, None));
            return;
        }
        let since = self.status.get().cycle;
        let entry = Pending {
            serial,
            kind,
            since,
            seen_busy: false,
        };
        match self.pending.iter_mut().find(|p| p.is_none()) {
            Some(slot) => *slot = Some(entry),
            // More than eight commands in flight: the oldest gives up its tracking.
            None => {
                self.pending.rotate_left(1);
                self.pending[7] = Some(entry);
            }
        }
    }

    fn set_flag(&self, flag: u32, on: bool) {
        if on {
            self.state.flags.fetch_or(flag, Ordering::Relaxed);
        } else {
            self.state.flags.fetch_and(!flag, Ordering::Relaxed);
        }
    }

    fn idle(&mut self) -> bool {
        matches!(
            self.status.get().state,
            MachineState::Idle | MachineState::EStop | MachineState::Fault
        )
    }

    fn load_program(&mut self, path: &WireText) -> Result<(), Refusal> {
        let status = *self.status.get();
        if status.mode == Mode::Auto
            && !matches!(
                status.state,
                MachineState::Idle | MachineState::EStop | MachineState::Fault
            )
        {
            return Err(Refusal::Busy);
        }
        let text = FixedText::new(path.as_str()).ok_or(Refusal::BadValue)?;
        if text.as_str().is_empty() {
            return Err(Refusal::BadValue);
        }
        self.shared
            .interpreter_requests
            .try_put(InterpreterRequest::Open(text))
            .map_err(|_| Refusal::ChannelFull)?;
        self.shared.interpreter_wake.signal();
        self.set_flag(flags::PROGRAM_LOADED, true);
        Ok(())
    }

    fn answer(&mut self, serial: u64, reply: Result<(), Refusal>) {
        match reply {
            Ok(()) => {
                let _ = self.events.push(ack_event(serial, ack::ACCEPTED, None));
                let _ = self.events.push(ack_event(serial, ack::DONE, None));
            }
            Err(r) => self.refuse(serial, r),
        }
    }

    fn refuse(&mut self, serial: u64, reason: Refusal) {
        let _ = self
            .events
            .push(ack_event(serial, ack::REFUSED, Some(reason)));
    }

    /// Why the kernel refused `cmd`, from the state it is in (the kernel decides; this only
    /// explains).
    fn why_refused(&mut self, cmd: &Command) -> Refusal {
        let status = *self.status.get();
        let feedback = *self.feedback.get();
        let axis_ok =
            |axis: u8| usize::from(axis) < layout::AXES && self.axes_present & (1 << axis) != 0;
        match *cmd {
            _ if status.state == MachineState::Starting => Refusal::NotReady,
            Command::Reset if feedback.estop => Refusal::EstopInput,
            Command::Reset if feedback.exchange_failed => Refusal::FieldbusDown,
            Command::Reset => Refusal::Busy,
            Command::JogStop { .. } => Refusal::NotJogging,
            Command::JogContinuous { axis, velocity } if !axis_ok(axis) || velocity == 0.0 => {
                if axis_ok(axis) {
                    Refusal::BadValue
                } else {
                    Refusal::BadAxis
                }
            }
            Command::JogIncrement { axis, .. } | Command::HomeAxis { axis } if !axis_ok(axis) => {
                Refusal::BadAxis
            }
            Command::Handwheel {
                axis: Some(axis), ..
            } if !axis_ok(axis) => Refusal::BadAxis,
            Command::Handwheel { scale, .. } if !(scale.is_finite() && scale > 0.0) => {
                Refusal::BadValue
            }
            Command::JogContinuous { velocity: v, .. }
            | Command::JogIncrement { distance: v, .. }
                if !v.is_finite() =>
            {
                Refusal::BadValue
            }
            _ if matches!(status.state, MachineState::EStop | MachineState::Fault) => {
                Refusal::NotReady
            }
            Command::BlockDelete(_) => Refusal::ChannelFull,
            _ => Refusal::Busy,
        }
    }

    /// Acknowledges as done (or failed) what accepted commands started, once the machine
    /// stands again.
    fn settle_pending(&mut self) {
        if self.pending.iter().all(Option::is_none) {
            return;
        }
        let status = *self.status.get();
        for slot in self.pending.iter_mut() {
            let Some(p) = slot.as_mut() else { continue };
            let busy = matches!(
                status.state,
                MachineState::Running
                    | MachineState::Held
                    | MachineState::Paused
                    | MachineState::WaitingForLogic
            );
            p.seen_busy |= busy;
            // The status must have been published at least twice since the command, so
            // that it shows what the command started.
            if busy || status.cycle < p.since + 3 {
                continue;
            }
            let e = match status.state {
                MachineState::EStop | MachineState::Fault => {
                    let mut e = ack_event(p.serial, ack::FAILED, Some(Refusal::Stopped));
                    e.code = ack::FAILED;
                    if let Some(f) = status.last_fault {
                        e.value = f64::from(f.code.number());
                        e.text = WireText::new(f.code.message());
                    }
                    e
                }
                _ if p.kind == command::START && !status.program_ended => {
                    ack_event(p.serial, ack::FAILED, Some(Refusal::Stopped))
                }
                _ => ack_event(p.serial, ack::DONE, None),
            };
            if self.events.push(e).is_ok() {
                *slot = None;
            }
        }
    }
}

/// The status, events and trace, published after status feedback.
pub(crate) struct Publisher {
    map: Mapping,
    state: Arc<LinkState>,
    shared: Shared,
    status: Snapshot<Status>,
    feedback: Snapshot<Feedback>,
    requests: Snapshot<LogicRequests>,
    outputs: Snapshot<LogicOutputs>,
    modal: Snapshot<ModalSnapshot>,
    samples: Option<RingConsumer<Sample>>,
    from_urgent: RingConsumer<WireEvent>,
    from_commands: RingConsumer<WireEvent>,
    seq: u64,
    following_error: [f64; MAX_JOINTS],
    last_state: u32,
    ended: bool,
    joints: usize,
    /// The snapshot being built (kept here: it is a few kilobytes).
    out: WireStatus,
}

impl Publisher {
    fn emit(&mut self, mut e: WireEvent, status: &Status) {
        let seg = self.map.segment();
        self.seq += 1;
        e.seq = self.seq;
        if e.time_ns == 0 {
            e.time_ns = status.time_ns;
        }
        if e.cycle == 0 {
            e.cycle = status.cycle;
        }
        // SAFETY: the publisher is the event ring's only producer.
        if unsafe { seg.events.push(e) }.is_err() {
            seg.events_dropped.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// One status period.
    pub(crate) fn run(&mut self, _ctx: &mut Context<'_>) {
        let status = *self.status.get();
        let map = self.map.clone();
        let seg = map.segment();
        self.publish_trace(seg);
        // The status first: a client that sees an event then reads a status at least as new
        // as what the event reports.
        let state = state_number(status.state);
        self.build_status(&status, state, seg);
        // SAFETY: the publisher is the status cell's only writer.
        unsafe { seg.status.publish(self.out) };
        self.publish_events(&status, state);
        self.ended = status.program_ended;
    }

    /// The servo samples to the trace ring; the following errors kept for the status.
    fn publish_trace(&mut self, seg: &Segment) {
        let joints = self.joints.min(MAX_JOINTS);
        if let Some(samples) = self.samples.as_mut() {
            let fe = &mut self.following_error;
            samples.drain_with(|s| {
                fe[..joints].copy_from_slice(&s.following_error[..joints]);
                let t = layout::TraceSample {
                    cycle: s.cycle,
                    time_ns: s.time_ns,
                    line: s.line,
                    joints: joints as u32,
                    path_speed: s.path_speed,
                    axes: s.axes,
                    setpoint: s.setpoint,
                    feedback: s.feedback,
                    following_error: s.following_error,
                };
                // SAFETY: the publisher is the trace ring's only producer.
                if unsafe { seg.trace.push(t) }.is_err() {
                    seg.trace_dropped.fetch_add(1, Ordering::Relaxed);
                }
            });
        }
    }

    /// The status snapshot in `self.out`.
    fn build_status(&mut self, status: &Status, state: u32, seg: &Segment) {
        let fb = *self.feedback.get();
        let req = *self.requests.get();
        let outputs = *self.outputs.get();
        let modal = *self.modal.get();
        let o = &mut self.out;
        o.cycle = status.cycle;
        o.time_ns = status.time_ns;
        o.state = state;
        o.mode = mode_number(status.mode);
        o.line = status.line;
        o.hold = super::hold_number(status.hold);
        let mut f = self.state.flags.load(Ordering::Relaxed);
        let mut set = |bit: u32, on: bool| {
            if on {
                f |= bit
            }
        };
        set(flags::PROGRAM_ENDED, status.program_ended);
        set(flags::READY, status.ready);
        set(flags::ESTOP_INPUT, fb.estop);
        set(flags::SPINDLE_ON, req.spindle_on);
        set(flags::SPINDLE_REVERSE, req.spindle_reverse);
        set(flags::MIST, req.mist);
        set(flags::FLOOD, req.flood);
        set(flags::LOGIC_HOLD, outputs.feed_hold_request);
        set(
            flags::CLIENT_ATTACHED,
            seg.client_pid.load(Ordering::Relaxed) != 0,
        );
        set(flags::MODAL_VALID, modal.valid);
        o.flags = f;
        o.homed = status.homed;
        o.fault_count = status.fault_count;
        o.tool = status.tool;
        o.last_fault = status.last_fault.map_or(0, |f| f.code.number());
        o.axes = status.axes;
        o.joint_setpoints = status.joint_setpoints;
        o.joint_feedback = status.joint_feedback;
        o.joint_velocity = fb.velocity;
        o.following_error = self.following_error;
        o.path_speed = status.path_speed;
        o.distance_to_go = status.distance_to_go;
        o.feed_override = status.feed_override;
        o.rapid_override = f64::from_bits(self.state.rapid_override.load(Ordering::Relaxed));
        o.spindle_override = f64::from_bits(self.state.spindle_override.load(Ordering::Relaxed));
        o.spindle_rpm = status.spindle_rpm;
        o.spindle_command_rpm = status.spindle_command_rpm;
        o.digital_inputs = fb.digital_inputs;
        o.digital_outputs = outputs.out_digital;
        o.analog_inputs = fb.analog_inputs;
        o.g_codes = modal.g_codes;
        o.m_codes = modal.m_codes;
        o.feed_rate = modal.feed_rate;
        o.speed = modal.speed;
        o.units_mm = modal.units_mm;
        o.work_system = u32::from(modal.work_system);
        o.work_offset = modal.work_offset;
        o.g92_offset = modal.g92_offset;
        o.tool_offset = modal.tool_offset;
        o.rotation = modal.rotation;
        o.client_losses = seg.client_losses.load(Ordering::Relaxed);
        o.events_dropped = seg.events_dropped.load(Ordering::Relaxed);
        o.trace_dropped = seg.trace_dropped.load(Ordering::Relaxed);
    }

    /// Events: acknowledgements first (they are the oldest), then faults and messages, then
    /// a change of state and the end of the program.
    fn publish_events(&mut self, status: &Status, state: u32) {
        while let Some(e) = self.from_urgent.pop() {
            self.emit(e, status);
        }
        while let Some(e) = self.from_commands.pop() {
            self.emit(e, status);
        }
        while let Some(f) = self.shared.faults.try_get() {
            let e = self.fault_event(&f);
            self.emit(e, status);
        }
        while let Some(m) = self.shared.operator_messages.try_get() {
            let e = WireEvent {
                kind: event::MESSAGE,
                time_ns: m.time_ns,
                cycle: m.cycle,
                line: m.line,
                joint: -1,
                text: WireText::new(m.text.as_str()),
                ..WireEvent::default()
            };
            self.emit(e, status);
        }
        if state != self.last_state {
            let e = WireEvent {
                kind: event::STATE,
                code: state,
                number: u64::from(self.last_state),
                value: f64::from(mode_number(status.mode)),
                line: status.line,
                joint: -1,
                ..WireEvent::default()
            };
            self.last_state = state;
            self.emit(e, status);
        }
        if status.program_ended && !self.ended {
            let e = WireEvent {
                kind: event::PROGRAM_END,
                line: status.line,
                joint: -1,
                ..WireEvent::default()
            };
            self.emit(e, status);
        }
    }

    /// A fault's event; the error text of a program, compensation or motion error with it.
    fn fault_event(&self, f: &Fault) -> WireEvent {
        let mut e = WireEvent {
            kind: event::FAULT,
            code: f.code.number(),
            time_ns: f.time_ns,
            line: f.line,
            joint: f.joint.map_or(-1, i32::from),
            value: f.value,
            ..WireEvent::default()
        };
        use crate::fault::FaultCode as F;
        if matches!(
            f.code,
            F::ProgramError | F::CompensationError | F::MotionError
        ) {
            if let Some(text) = self.shared.error_text.try_lock() {
                if let Some(t) = text.as_deref() {
                    e.text.push(t);
                }
            }
            if e.text.len == 0 {
                if let Some(m) = self.shared.motion_error.try_lock() {
                    if let Some(err) = m.as_ref() {
                        use std::fmt::Write as _;
                        let _ = write!(e.text, "planner: {err}");
                    }
                }
            }
        }
        e
    }
}
