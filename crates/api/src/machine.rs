//! The API process's side of the machine: a thread that attaches to the machine's segment,
//! beats the heartbeat, drains events, trace samples and service replies, turns the status
//! into the API's document 100 times a second, notices when the machine is gone (its
//! heartbeat stands still or its process is dead) and attaches again when it is back.

use std::collections::{HashMap, VecDeque};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use rtcnc_kernel::FaultCode;
use rtcnc_kernel::link::layout::{
    self, ServiceReply, ServiceRequest, TraceSample, WireCommand, WireEvent, WireStatus, WireText,
    WireUrgent, ack, event, flags,
};
use rtcnc_kernel::link::{Client, Refusal, hold_cause, mode_name, state_name};
use tokio::sync::{broadcast, watch};

use crate::models::{self, Ack, AxisMap, Event};
use crate::problem::Problem;

/// The machine is taken for gone when its heartbeat stands still this long.
const MACHINE_TIMEOUT: Duration = Duration::from_millis(300);
/// Events the API keeps for `GET /api/events`.
const EVENT_HISTORY: usize = 10_000;
/// Trace samples kept (10 s at 1 kHz).
const TRACE_HISTORY: usize = 10_000;
/// Acknowledgements kept.
const ACK_HISTORY: usize = 4096;

/// Axis letters, X..W.
pub const AXIS_LETTERS: [&str; 9] = ["X", "Y", "Z", "A", "B", "C", "U", "V", "W"];

/// What the header says about the machine.
#[derive(Debug, Clone, Default)]
pub struct Meta {
    /// Name.
    pub name: String,
    /// Joint names.
    pub joints: Vec<String>,
    /// Bit n: axis n present.
    pub axes_present: u32,
    /// Servo period, s.
    pub servo_period_s: f64,
    /// Jog keep-alive, s.
    pub jog_keep_alive_s: f64,
}

impl Meta {
    /// The present axes' letters.
    pub fn axes(&self) -> Vec<String> {
        (0..9)
            .filter(|i| self.axes_present & (1 << i) != 0)
            .map(|i| AXIS_LETTERS[i].to_string())
            .collect()
    }

    /// The index of an axis letter present on the machine.
    pub fn axis_index(&self, letter: &str) -> Option<u32> {
        let i = AXIS_LETTERS
            .iter()
            .position(|l| l.eq_ignore_ascii_case(letter.trim()))?;
        (self.axes_present & (1 << i) != 0).then_some(i as u32)
    }
}

/// A fault kept for the history, with its acknowledgement.
#[derive(Debug, Clone)]
struct FaultEntry {
    record: models::FaultRecord,
}

/// The machine as the API sees it.
pub struct MachineConn {
    segment: String,
    client: Mutex<Option<Arc<Client>>>,
    meta: Mutex<Meta>,
    events: Mutex<VecDeque<Arc<Event>>>,
    next_seq: AtomicU64,
    event_tx: broadcast::Sender<Arc<Event>>,
    acks: Mutex<(HashMap<u64, Ack>, VecDeque<u64>)>,
    ack_tx: watch::Sender<u64>,
    replies: Mutex<HashMap<u64, ServiceReply>>,
    reply_tx: watch::Sender<u64>,
    trace: Mutex<VecDeque<TraceSample>>,
    trace_tx: broadcast::Sender<Arc<Vec<TraceSample>>>,
    status_tx: watch::Sender<Arc<models::Status>>,
    serial: AtomicU64,
    program: Mutex<Option<String>>,
    watch_paths: Mutex<Vec<String>>,
    faults: Mutex<Vec<FaultEntry>>,
    deadline_misses: AtomicU64,
    stop: AtomicBool,
}

fn text_of(t: &WireText) -> String {
    t.as_str().to_string()
}

impl MachineConn {
    /// For the segment called `segment`; call [`start`](Self::start) to run its thread.
    pub fn new(segment: &str, machine_name: &str) -> Arc<MachineConn> {
        let empty = models::Status {
            machine: machine_name.to_string(),
            connected: false,
            cycle: 0,
            time_s: 0.0,
            state: "unknown".into(),
            mode: "manual".into(),
            line: 0,
            program: None,
            program_ended: false,
            ready: false,
            estop_input: false,
            machine_position: AxisMap::new(),
            work_position: AxisMap::new(),
            distance_to_go: AxisMap::new(),
            joints: Vec::new(),
            path_speed: 0.0,
            overrides: models::Overrides {
                feed: 1.0,
                rapid: 1.0,
                spindle: 1.0,
            },
            spindle: models::Spindle {
                on: false,
                direction: "off".into(),
                rpm: 0.0,
                command_rpm: 0.0,
            },
            mist: false,
            flood: false,
            tool: 0,
            modal: None,
            digital_inputs: 0,
            digital_outputs: 0,
            analog_inputs: Vec::new(),
            plc_watch: Vec::new(),
            single_block: false,
            optional_stop: false,
            block_delete: false,
            logic_hold: false,
            hold: None,
            hold_message: None,
            fault_count: 0,
            last_fault: None,
            deadline_misses: 0,
            lease_holder: None,
            link: models::LinkCounters {
                client_losses: 0,
                events_dropped: 0,
                trace_dropped: 0,
            },
        };
        // Serials start from the clock (µs, well within the 2^53 a JSON number holds
        // exactly), so a restarted API never repeats one the machine may still acknowledge.
        let serial0 = rtcnc_kernel::link::monotonic_ns() / 1000;
        Arc::new(MachineConn {
            segment: segment.to_string(),
            client: Mutex::new(None),
            meta: Mutex::new(Meta {
                name: machine_name.to_string(),
                ..Meta::default()
            }),
            events: Mutex::new(VecDeque::with_capacity(EVENT_HISTORY)),
            next_seq: AtomicU64::new(1),
            event_tx: broadcast::channel(4096).0,
            acks: Mutex::new((HashMap::new(), VecDeque::new())),
            ack_tx: watch::channel(0).0,
            replies: Mutex::new(HashMap::new()),
            reply_tx: watch::channel(0).0,
            trace: Mutex::new(VecDeque::with_capacity(TRACE_HISTORY)),
            trace_tx: broadcast::channel(256).0,
            status_tx: watch::channel(Arc::new(empty)).0,
            serial: AtomicU64::new(serial0.max(1)),
            program: Mutex::new(None),
            watch_paths: Mutex::new(Vec::new()),
            faults: Mutex::new(Vec::new()),
            deadline_misses: AtomicU64::new(0),
            stop: AtomicBool::new(false),
        })
    }

    /// Runs the link thread.
    pub fn start(self: &Arc<Self>) -> std::thread::JoinHandle<()> {
        let me = Arc::clone(self);
        std::thread::Builder::new()
            .name("machine link".into())
            .spawn(move || me.run())
            .expect("thread")
    }

    /// Stops the link thread and leaves the machine.
    pub fn shutdown(&self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(c) = self.lock_client().take() {
            c.detach();
        }
    }

    fn lock_client(&self) -> std::sync::MutexGuard<'_, Option<Arc<Client>>> {
        self.client.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The attached, live machine, or 503.
    pub fn client(&self) -> Result<Arc<Client>, Problem> {
        self.lock_client().clone().ok_or_else(Problem::machine_gone)
    }

    /// Whether the machine answers.
    pub fn connected(&self) -> bool {
        self.lock_client().is_some()
    }

    /// The header's facts.
    pub fn meta(&self) -> Meta {
        self.meta.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }

    /// Status documents as they come (100 Hz).
    pub fn status_watch(&self) -> watch::Receiver<Arc<models::Status>> {
        self.status_tx.subscribe()
    }

    /// The newest status document.
    pub fn status(&self) -> Arc<models::Status> {
        self.status_tx.borrow().clone()
    }

    /// Events as they come.
    pub fn subscribe_events(&self) -> broadcast::Receiver<Arc<Event>> {
        self.event_tx.subscribe()
    }

    /// Trace samples as they come, in batches.
    pub fn subscribe_trace(&self) -> broadcast::Receiver<Arc<Vec<TraceSample>>> {
        self.trace_tx.subscribe()
    }

    /// The trace samples kept.
    pub fn trace(&self) -> Vec<TraceSample> {
        let t = self.trace.lock().unwrap_or_else(|e| e.into_inner());
        t.iter().copied().collect()
    }

    /// The newest event number.
    pub fn last_seq(&self) -> u64 {
        self.next_seq.load(Ordering::Relaxed) - 1
    }

    /// Events after `since` (at most `limit`), and how many of those the API no longer has.
    pub fn events_since(&self, since: u64, limit: usize) -> models::EventPage {
        let events = self.events.lock().unwrap_or_else(|e| e.into_inner());
        let first = events.front().map_or(self.last_seq() + 1, |e| e.seq);
        let missed = first.saturating_sub(since + 1);
        let out: Vec<Event> = events
            .iter()
            .filter(|e| e.seq > since)
            .take(limit)
            .map(|e| (**e).clone())
            .collect();
        models::EventPage {
            last_seq: out.last().map_or(self.last_seq().max(since), |e| e.seq),
            events: out,
            missed,
        }
    }

    /// The fault history.
    pub fn faults(&self) -> Vec<models::FaultRecord> {
        let f = self.faults.lock().unwrap_or_else(|e| e.into_inner());
        f.iter().map(|e| e.record.clone()).collect()
    }

    /// Acknowledges the faults up to `seq`; returns how many were newly acknowledged.
    pub fn acknowledge_faults(&self, seq: u64) -> usize {
        let mut f = self.faults.lock().unwrap_or_else(|e| e.into_inner());
        let mut n = 0;
        for e in f.iter_mut().filter(|e| e.record.seq <= seq) {
            if !e.record.acknowledged {
                e.record.acknowledged = true;
                n += 1;
            }
        }
        n
    }

    /// The loaded program's name (as the API loaded it).
    pub fn set_program(&self, name: Option<String>) {
        *self.program.lock().unwrap_or_else(|e| e.into_inner()) = name;
    }

    /// The PLC watch list (its values come with the status).
    pub fn set_watch_paths(&self, paths: Vec<String>) {
        *self.watch_paths.lock().unwrap_or_else(|e| e.into_inner()) = paths;
    }

    fn next_serial(&self) -> u64 {
        self.serial.fetch_add(1, Ordering::Relaxed)
    }

    fn register(&self, serial: u64) {
        let mut acks = self.acks.lock().unwrap_or_else(|e| e.into_inner());
        acks.0.insert(
            serial,
            Ack {
                serial,
                state: "pending".into(),
                code: None,
                message: None,
                latency_periods: None,
                latency_ns: None,
            },
        );
        acks.1.push_back(serial);
        while acks.1.len() > ACK_HISTORY {
            if let Some(old) = acks.1.pop_front() {
                acks.0.remove(&old);
            }
        }
    }

    /// Sends a normal command; returns its serial.
    pub fn send(&self, mut command: WireCommand) -> Result<u64, Problem> {
        let client = self.client()?;
        command.serial = self.next_serial();
        self.register(command.serial);
        client.send(command).map_err(|_| {
            Problem::new(
                axum::http::StatusCode::SERVICE_UNAVAILABLE,
                "link.full",
                "the machine's command ring is full: it does not take commands",
            )
            .retry_after(1)
        })?;
        Ok(command.serial)
    }

    /// Sends an urgent command; returns its serial.
    pub fn send_urgent(&self, kind: u32, axis: u32, value: f64) -> Result<u64, Problem> {
        let client = self.client()?;
        let serial = self.next_serial();
        self.register(serial);
        client
            .send_urgent(WireUrgent {
                serial,
                kind,
                axis,
                value,
                ..WireUrgent::default()
            })
            .map_err(|_| {
                Problem::new(
                    axum::http::StatusCode::SERVICE_UNAVAILABLE,
                    "link.full",
                    "the machine's urgent ring is full: it does not take commands",
                )
                .retry_after(1)
            })?;
        Ok(serial)
    }

    /// A command's acknowledgement now.
    pub fn ack(&self, serial: u64) -> Option<Ack> {
        let acks = self.acks.lock().unwrap_or_else(|e| e.into_inner());
        acks.0.get(&serial).cloned()
    }

    /// Waits until the command's acknowledgement is one of `states` or `timeout` passes;
    /// returns it as it is then.
    pub async fn wait_ack(&self, serial: u64, states: &[&str], timeout: Duration) -> Option<Ack> {
        let mut rx = self.ack_tx.subscribe();
        let deadline = tokio::time::Instant::now() + timeout;
        loop {
            let now = self.ack(serial)?;
            if states.contains(&now.state.as_str()) {
                return Some(now);
            }
            if tokio::time::timeout_at(deadline, rx.changed())
                .await
                .is_err()
            {
                return self.ack(serial);
            }
        }
    }

    /// Sends a service request and waits for its reply.
    pub async fn service(
        &self,
        kind: u32,
        text: &str,
        value: &str,
    ) -> Result<ServiceReply, Problem> {
        let client = self.client()?;
        let serial = self.next_serial();
        let mut rx = self.reply_tx.subscribe();
        let request = ServiceRequest {
            serial,
            kind,
            text: WireText::new(text),
            value_text: WireText::new(value),
            ..ServiceRequest::default()
        };
        client.request(request).map_err(|_| {
            Problem::new(
                axum::http::StatusCode::SERVICE_UNAVAILABLE,
                "link.full",
                "the machine's service ring is full",
            )
        })?;
        let deadline = tokio::time::Instant::now() + Duration::from_secs(2);
        loop {
            if let Some(r) = self
                .replies
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .remove(&serial)
            {
                return Ok(r);
            }
            if tokio::time::timeout_at(deadline, rx.changed())
                .await
                .is_err()
            {
                return Err(Problem::new(
                    axum::http::StatusCode::GATEWAY_TIMEOUT,
                    "link.timeout",
                    "the machine's service thread did not answer within 2 s",
                ));
            }
        }
    }

    fn push_event(&self, mut e: Event) {
        e.seq = self.next_seq.fetch_add(1, Ordering::Relaxed);
        let e = Arc::new(e);
        {
            let mut events = self.events.lock().unwrap_or_else(|e| e.into_inner());
            if events.len() >= EVENT_HISTORY {
                events.pop_front();
            }
            events.push_back(Arc::clone(&e));
        }
        if e.kind == "fault" {
            let mut f = self.faults.lock().unwrap_or_else(|e| e.into_inner());
            if f.len() >= EVENT_HISTORY {
                f.remove(0);
            }
            f.push(FaultEntry {
                record: models::FaultRecord {
                    seq: e.seq,
                    code: e.code.clone().unwrap_or_default(),
                    message: e.message.clone(),
                    time_s: e.time_s,
                    line: e.line,
                    joint: e.joint.clone(),
                    acknowledged: false,
                },
            });
        }
        let _ = self.event_tx.send(e);
    }

    fn local_event(&self, kind: &str, message: String) {
        self.push_event(Event {
            seq: 0,
            kind: kind.into(),
            time_s: 0.0,
            cycle: 0,
            code: None,
            message,
            line: None,
            joint: None,
            serial: None,
            ack: None,
            latency_periods: None,
            latency_ns: None,
            value: None,
        });
    }

    fn on_wire_event(&self, w: &WireEvent, meta: &Meta, last_machine_seq: &mut u64) {
        if *last_machine_seq != 0 && w.seq > *last_machine_seq + 1 {
            self.local_event(
                "events_lost",
                format!(
                    "the machine dropped {} events (its ring was full)",
                    w.seq - *last_machine_seq - 1
                ),
            );
        }
        *last_machine_seq = w.seq;
        let joint = usize::try_from(w.joint).ok().map(|j| {
            meta.joints
                .get(j)
                .cloned()
                .unwrap_or_else(|| format!("#{j}"))
        });
        let mut e = Event {
            seq: 0,
            kind: String::new(),
            time_s: w.time_ns as f64 * 1e-9,
            cycle: w.cycle,
            code: None,
            message: text_of(&w.text),
            line: (w.line > 0).then_some(w.line),
            joint: None,
            serial: None,
            ack: None,
            latency_periods: None,
            latency_ns: None,
            value: None,
        };
        match w.kind {
            event::ACK => {
                let state = match w.code {
                    ack::ACCEPTED => "accepted",
                    ack::DONE => "done",
                    ack::REFUSED => "refused",
                    _ => "failed",
                };
                e.kind = "ack".into();
                e.serial = Some(w.serial);
                e.ack = Some(state.into());
                let refusal = Refusal::from_number(w.number);
                let fault = FaultCode::from_number(w.value as u32).filter(|_| w.value > 0.0);
                e.code = match (fault, refusal) {
                    (Some(f), _) if w.code == ack::FAILED => Some(f.as_str().to_string()),
                    (_, Some(r)) => Some(r.code().to_string()),
                    _ => None,
                };
                if w.written_ns != 0 && w.acted_ns >= w.written_ns {
                    e.latency_ns = Some(w.acted_ns - w.written_ns);
                    e.latency_periods = Some(w.cycle.saturating_sub(w.written_cycle));
                }
                let mut acks = self.acks.lock().unwrap_or_else(|e| e.into_inner());
                if let Some(a) = acks.0.get_mut(&w.serial) {
                    // Done after accepted; a late "accepted" never undoes "done".
                    let rank = |s: &str| match s {
                        "pending" => 0,
                        "accepted" => 1,
                        _ => 2,
                    };
                    if rank(state) >= rank(&a.state) {
                        a.state = state.into();
                        a.code = e.code.clone();
                        a.message = (!e.message.is_empty()).then(|| e.message.clone());
                        if e.latency_ns.is_some() {
                            a.latency_ns = e.latency_ns;
                            a.latency_periods = e.latency_periods;
                        }
                    }
                }
                drop(acks);
                self.ack_tx.send_modify(|n| *n += 1);
            }
            event::FAULT => {
                e.kind = "fault".into();
                let code = FaultCode::from_number(w.code);
                e.code = Some(code.map_or("kernel.unknown", |c| c.as_str()).to_string());
                let base = code.map_or("fault", |c| c.message());
                e.message = if e.message.is_empty() {
                    base.to_string()
                } else {
                    format!("{base}: {}", e.message)
                };
                e.joint = joint;
                e.value = (w.value != 0.0 && w.value.is_finite()).then_some(w.value);
            }
            event::MESSAGE => e.kind = "message".into(),
            event::STATE => {
                e.kind = "state".into();
                e.code = Some(state_name(w.code).to_string());
                e.message = format!(
                    "{} -> {} ({})",
                    state_name(w.number as u32),
                    state_name(w.code),
                    mode_name(w.value as u32)
                );
            }
            event::CLIENT_LOST => {
                e.kind = "client_lost".into();
                e.message = format!(
                    "the machine lost its API process (pid {}): {}",
                    w.number,
                    match w.code {
                        1 => "feed hold",
                        2 => "e-stop",
                        _ => "the program goes on",
                    }
                );
            }
            event::PROGRAM_END => {
                e.kind = "program_end".into();
                e.message = "program ended".into();
            }
            _ => return,
        }
        self.push_event(e);
    }

    fn run(self: Arc<Self>) {
        let mut attached: Option<(Arc<Client>, u64, Instant, u64)> = None;
        let mut last_try = Instant::now() - Duration::from_secs(1);
        let mut last_status = Instant::now();
        let mut last_machine_seq = 0u64;
        let mut batch: Vec<TraceSample> = Vec::with_capacity(256);
        let mut wire_events: Vec<WireEvent> = Vec::with_capacity(256);
        let mut was_connected = false;
        while !self.stop.load(Ordering::Relaxed) {
            if attached.is_none() && last_try.elapsed() >= Duration::from_millis(100) {
                last_try = Instant::now();
                if let Ok(client) = Client::attach(&self.segment) {
                    let beat = client.machine_heartbeat();
                    attached = Some((Arc::new(client), beat, Instant::now(), 0));
                    last_machine_seq = 0;
                }
            }
            if let Some((client, beat, since, _)) = attached.as_mut() {
                if !client.heartbeat() {
                    // Another API process took the machine over.
                    attached = None;
                } else {
                    let now_beat = client.machine_heartbeat();
                    let pid = client.header().machine_pid;
                    // SAFETY: signal 0 only checks that the process exists.
                    let alive = unsafe { libc::kill(pid as i32, 0) } == 0;
                    if now_beat != *beat {
                        *beat = now_beat;
                        *since = Instant::now();
                        if !was_connected {
                            was_connected = true;
                            self.on_attached(client);
                        }
                    } else if since.elapsed() > MACHINE_TIMEOUT || !alive {
                        attached = None;
                    }
                }
                if attached.is_none() && was_connected {
                    was_connected = false;
                    *self.lock_client() = None;
                    self.local_event(
                        "machine_lost",
                        "the machine process does not answer; waiting for it".into(),
                    );
                    self.status_tx.send_modify(|s| {
                        let mut s2 = (**s).clone();
                        s2.connected = false;
                        *s = Arc::new(s2);
                    });
                }
            }
            if let (Some((client, ..)), true) = (attached.as_ref(), was_connected) {
                let client = Arc::clone(client);
                let meta = self.meta();
                wire_events.clear();
                client.drain_events(|w| wire_events.push(w));
                // The status first, then the events: whoever an event wakes reads a status at
                // least as new as the event (the machine publishes its status before its
                // events).
                if !wire_events.is_empty() {
                    last_status = Instant::now();
                    let doc = self.document(&client, &meta);
                    self.status_tx.send_replace(Arc::new(doc));
                }
                for w in &wire_events {
                    self.on_wire_event(w, &meta, &mut last_machine_seq);
                }
                batch.clear();
                client.drain_trace(|s| batch.push(*s));
                if !batch.is_empty() {
                    let mut t = self.trace.lock().unwrap_or_else(|e| e.into_inner());
                    for s in &batch {
                        if t.len() >= TRACE_HISTORY {
                            t.pop_front();
                        }
                        t.push_back(*s);
                    }
                    drop(t);
                    let _ = self.trace_tx.send(Arc::new(batch.clone()));
                }
                let mut got = false;
                client.drain_replies(|r| {
                    self.replies
                        .lock()
                        .unwrap_or_else(|e| e.into_inner())
                        .insert(r.serial, r);
                    got = true;
                });
                if got {
                    self.reply_tx.send_modify(|n| *n += 1);
                }
                if last_status.elapsed() >= Duration::from_millis(10) {
                    last_status = Instant::now();
                    let doc = self.document(&client, &meta);
                    self.status_tx.send_replace(Arc::new(doc));
                }
            }
            std::thread::sleep(Duration::from_millis(2));
        }
    }

    fn on_attached(&self, client: &Arc<Client>) {
        let h = client.header();
        let meta = Meta {
            name: client.machine_name().to_string(),
            joints: (0..h.joint_count as usize)
                .map(|j| client.joint_name(j).to_string())
                .collect(),
            axes_present: h.axes_present,
            servo_period_s: h.servo_period_ns as f64 * 1e-9,
            jog_keep_alive_s: h.jog_keep_alive_ns as f64 * 1e-9,
        };
        *self.meta.lock().unwrap_or_else(|e| e.into_inner()) = meta;
        // A restarted machine has no program loaded and no watch list.
        self.set_program(None);
        self.set_watch_paths(Vec::new());
        *self.lock_client() = Some(Arc::clone(client));
        self.local_event(
            "machine_attached",
            format!("attached to the machine (pid {})", h.machine_pid),
        );
    }

    fn document(&self, client: &Client, meta: &Meta) -> models::Status {
        let w: WireStatus = client.status();
        let timing = client.timing();
        let misses: u64 = timing.tasks[..(timing.count as usize).min(timing.tasks.len())]
            .iter()
            .map(|t| t.deadline_misses)
            .sum();
        self.deadline_misses.store(misses, Ordering::Relaxed);
        let watch = client.watch();
        let paths = self
            .watch_paths
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone();
        status_document(&w, meta, misses, &watch, &paths, self.program_name())
    }

    fn program_name(&self) -> Option<String> {
        self.program
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }
}

fn axis_map(meta: &Meta, values: &[f64; layout::AXES]) -> AxisMap {
    (0..layout::AXES)
        .filter(|i| meta.axes_present & (1 << i) != 0)
        .map(|i| (AXIS_LETTERS[i].to_string(), values[i]))
        .collect()
}

/// The G code name of a number in tenths (541 -> G54.1).
fn gcode_name(n: i32) -> String {
    if n % 10 == 0 {
        format!("G{}", n / 10)
    } else {
        format!("G{}.{}", n / 10, n % 10)
    }
}

/// The API's status document of a wire snapshot.
pub fn status_document(
    w: &WireStatus,
    meta: &Meta,
    deadline_misses: u64,
    watch: &layout::WireWatch,
    watch_paths: &[String],
    program: Option<String>,
) -> models::Status {
    let f = |bit: u32| w.flags & bit != 0;
    let modal_valid = f(flags::MODAL_VALID);
    let units = if w.units_mm > 0.0 { w.units_mm } else { 1.0 };
    // Work position: machine -> program units, minus work and tool offsets, rotated back,
    // minus G92 (LinuxCNC's order).
    let mut work = [0.0; layout::AXES];
    for i in 0..layout::AXES {
        let linear = !(3..6).contains(&i);
        let m = if linear { w.axes[i] / units } else { w.axes[i] };
        work[i] = m - w.work_offset[i] - w.tool_offset[i];
    }
    if w.rotation != 0.0 {
        let (s, c) = (-w.rotation.to_radians()).sin_cos();
        let (x, y) = (work[0], work[1]);
        work[0] = x * c - y * s;
        work[1] = x * s + y * c;
    }
    for i in 0..layout::AXES {
        work[i] -= w.g92_offset[i];
    }
    let joints = meta
        .joints
        .iter()
        .enumerate()
        .map(|(j, name)| models::Joint {
            name: name.clone(),
            setpoint: w.joint_setpoints[j],
            feedback: w.joint_feedback[j],
            velocity: w.joint_velocity[j],
            following_error: w.following_error[j],
            homed: w.homed & (1 << j) != 0,
        })
        .collect();
    let modal = modal_valid.then(|| models::Modal {
        g_codes: w
            .g_codes
            .iter()
            .filter(|&&g| g >= 0)
            .map(|&g| gcode_name(g))
            .collect(),
        m_codes: w
            .m_codes
            .iter()
            .filter(|&&m| m >= 0)
            .map(|m| format!("M{m}"))
            .collect(),
        feed_rate: w.feed_rate,
        speed: w.speed,
        units: if units > 1.0 { "inch" } else { "mm" }.into(),
        work_system: match w.work_system {
            n @ 1..=6 => format!("G{}", 53 + n),
            7 => "G59.1".into(),
            8 => "G59.2".into(),
            _ => "G59.3".into(),
        },
        work_offset: axis_map(meta, &w.work_offset),
        g92_offset: axis_map(meta, &w.g92_offset),
        tool_offset: axis_map(meta, &w.tool_offset),
        rotation: w.rotation,
    });
    let count = (watch.count as usize).min(watch_paths.len());
    models::Status {
        machine: meta.name.clone(),
        connected: true,
        cycle: w.cycle,
        time_s: w.time_ns as f64 * 1e-9,
        state: state_name(w.state).into(),
        mode: mode_name(w.mode).into(),
        line: w.line,
        program,
        program_ended: f(flags::PROGRAM_ENDED),
        ready: f(flags::READY),
        estop_input: f(flags::ESTOP_INPUT),
        machine_position: axis_map(meta, &w.axes),
        work_position: axis_map(meta, &work),
        distance_to_go: axis_map(meta, &w.distance_to_go),
        joints,
        path_speed: w.path_speed,
        overrides: models::Overrides {
            feed: w.feed_override,
            rapid: w.rapid_override,
            spindle: w.spindle_override,
        },
        spindle: models::Spindle {
            on: f(flags::SPINDLE_ON),
            direction: match (f(flags::SPINDLE_ON), f(flags::SPINDLE_REVERSE)) {
                (false, _) => "off",
                (true, false) => "cw",
                (true, true) => "ccw",
            }
            .into(),
            rpm: w.spindle_rpm,
            command_rpm: w.spindle_command_rpm,
        },
        mist: f(flags::MIST),
        flood: f(flags::FLOOD),
        tool: w.tool,
        modal,
        digital_inputs: w.digital_inputs,
        digital_outputs: w.digital_outputs,
        analog_inputs: w.analog_inputs.to_vec(),
        plc_watch: (0..count)
            .map(|i| models::WatchValue {
                path: watch_paths[i].clone(),
                value: watch.values[i],
                forced: watch.forced & (1 << i) != 0,
            })
            .collect(),
        single_block: f(flags::SINGLE_BLOCK),
        optional_stop: f(flags::OPTIONAL_STOP),
        block_delete: f(flags::BLOCK_DELETE),
        logic_hold: f(flags::LOGIC_HOLD),
        hold: hold_cause(w.hold).map(|c| c.as_str().to_string()),
        hold_message: hold_cause(w.hold).map(|c| c.message().to_string()),
        fault_count: w.fault_count,
        last_fault: FaultCode::from_number(w.last_fault).map(|c| c.as_str().to_string()),
        deadline_misses,
        lease_holder: None,
        link: models::LinkCounters {
            client_losses: w.client_losses,
            events_dropped: w.events_dropped,
            trace_dropped: w.trace_dropped,
        },
    }
}
