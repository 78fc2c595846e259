//! The layout of the machine's shared-memory segment: every type here is `#[repr(C)]`
//! plain data (integers, floats, byte arrays; no pointers, no Rust enums), so a process
//! that maps the segment at another address, or a process of another build with the same
//! layout version, reads the same bytes the same way. docs/shared-memory.md describes it.

use std::sync::atomic::{AtomicU32, AtomicU64};

use rtcnc_rt::{SeqlockCell, SpscCell};

use crate::config::{MAX_JOINTS, MAX_PROGRAM_IO};

/// "RTCNCSHM", little-endian: the first eight bytes of a segment.
pub const MAGIC: u64 = u64::from_le_bytes(*b"RTCNCSHM");
/// The layout version; a client of another layout is refused.
pub const LAYOUT_VERSION: u32 = 2;
/// Axes X Y Z A B C U V W.
pub const AXES: usize = rtcnc_motion::AXES;
/// Bytes of a text in a command, event or reply.
pub const TEXT: usize = 256;
/// Normal commands in flight.
pub const COMMAND_SLOTS: usize = 64;
/// Urgent commands in flight.
pub const URGENT_SLOTS: usize = 32;
/// Events waiting for the client.
pub const EVENT_SLOTS: usize = 1024;
/// Trace samples waiting for the client (4 s at 1 kHz).
pub const TRACE_SLOTS: usize = 4096;
/// Service requests (PLC variables) in flight.
pub const SERVICE_SLOTS: usize = 16;
/// PLC variables watched at once.
pub const WATCH_SLOTS: usize = 16;
/// Tasks in the timing table.
pub const TIMING_SLOTS: usize = 16;

/// A text in a fixed buffer (UTF-8, cut at a character boundary when too long).
#[repr(C)]
#[derive(Clone, Copy)]
pub struct WireText {
    /// Bytes used.
    pub len: u32,
    /// The bytes.
    pub bytes: [u8; TEXT],
}

impl Default for WireText {
    fn default() -> Self {
        WireText {
            len: 0,
            bytes: [0; TEXT],
        }
    }
}

impl std::fmt::Debug for WireText {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:?}", self.as_str())
    }
}

impl WireText {
    /// `text`, shortened at a character boundary to fit.
    pub fn new(text: &str) -> WireText {
        let mut t = WireText::default();
        t.push(text);
        t
    }

    /// Appends what fits of `text`.
    pub fn push(&mut self, text: &str) {
        let used = (self.len as usize).min(TEXT);
        let mut end = text.len().min(TEXT - used);
        while !text.is_char_boundary(end) {
            end -= 1;
        }
        self.bytes[used..used + end].copy_from_slice(&text.as_bytes()[..end]);
        self.len = (used + end) as u32;
    }

    /// The text (empty when the bytes are not UTF-8: they came from another process).
    pub fn as_str(&self) -> &str {
        let len = (self.len as usize).min(TEXT);
        std::str::from_utf8(&self.bytes[..len]).unwrap_or("")
    }
}

impl std::fmt::Write for WireText {
    fn write_str(&mut self, s: &str) -> std::fmt::Result {
        self.push(s);
        Ok(())
    }
}

/// Kinds of normal command (`WireCommand::kind`).
pub mod command {
    /// Leave e-stop or fault.
    pub const RESET: u32 = 1;
    /// Cycle start; `number` = first line (0: from the start).
    pub const START: u32 = 2;
    /// One MDI line in `text`.
    pub const MDI: u32 = 3;
    /// Continuous jog of `axis` at `value` units/s (signed); needs a keep-alive.
    pub const JOG_CONTINUOUS: u32 = 4;
    /// Incremental jog of `axis` by `value`.
    pub const JOG_INCREMENT: u32 = 5;
    /// Stop the jog of `axis`.
    pub const JOG_STOP: u32 = 6;
    /// Home every joint.
    pub const HOME_ALL: u32 = 7;
    /// Single block, `number` 0 or 1.
    pub const SINGLE_BLOCK: u32 = 8;
    /// Optional stop (M1), `number` 0 or 1.
    pub const OPTIONAL_STOP: u32 = 9;
    /// Block delete, `number` 0 or 1.
    pub const BLOCK_DELETE: u32 = 10;
    /// Load the program at the path in `text` (the next cycle start runs it).
    pub const LOAD_PROGRAM: u32 = 11;
    /// The continuous jog of `axis` goes on for another keep-alive period.
    pub const JOG_KEEP_ALIVE: u32 = 12;
    /// Read the tool table file again.
    pub const RELOAD_TOOL_TABLE: u32 = 13;
    /// The handwheel on `axis` with `value` times `handwheel.units_per_count` per count;
    /// `axis` = `u32::MAX` releases it.
    pub const HANDWHEEL: u32 = 14;
    /// Home the joints of `axis`.
    pub const HOME_AXIS: u32 = 15;
    /// Switch the mode: `number` 0 manual, 1 auto, 2 MDI.
    pub const SET_MODE: u32 = 16;
}

/// One normal command, acknowledged by its serial number.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct WireCommand {
    /// Serial number (not 0), chosen by the client.
    pub serial: u64,
    /// CLOCK_MONOTONIC when the client wrote it, ns.
    pub written_ns: u64,
    /// [`command`] kind.
    pub kind: u32,
    /// Axis index (X..W = 0..8).
    pub axis: u32,
    /// A number (line, flag).
    pub number: u64,
    /// A value (velocity, distance).
    pub value: f64,
    /// Text (MDI line, program path).
    pub text: WireText,
}

/// Kinds of urgent command (`WireUrgent::kind`).
pub mod urgent {
    /// Emergency stop.
    pub const ESTOP: u32 = 1;
    /// Feed hold.
    pub const FEED_HOLD: u32 = 2;
    /// Resume after a hold or a pause.
    pub const RESUME: u32 = 3;
    /// Stop the program (abort).
    pub const ABORT: u32 = 4;
    /// Feed override `value` (0..2).
    pub const FEED_OVERRIDE: u32 = 5;
    /// Rapid override `value` (0..1).
    pub const RAPID_OVERRIDE: u32 = 6;
    /// Spindle override `value` (0.5..1.5).
    pub const SPINDLE_OVERRIDE: u32 = 7;
    /// Stop the jog of `axis`.
    pub const JOG_STOP: u32 = 8;
}

/// One urgent command: read by the interpolation task's link before anything else in its
/// period.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct WireUrgent {
    /// Serial number (not 0).
    pub serial: u64,
    /// CLOCK_MONOTONIC when the client wrote it, ns.
    pub written_ns: u64,
    /// The machine's heartbeat (servo cycle) the client saw when it wrote it.
    pub written_cycle: u64,
    /// [`urgent`] kind.
    pub kind: u32,
    /// Axis index for a jog stop.
    pub axis: u32,
    /// Override value.
    pub value: f64,
}

/// Kinds of event (`WireEvent::kind`).
pub mod event {
    /// A command's acknowledgement: `code` is an [`super::ack`] kind, `serial` the
    /// command's, `number` its refusal reason ([`crate::link::Refusal`] number) or fault.
    pub const ACK: u32 = 1;
    /// A fault: `code` the kernel's fault number, `line`, `joint`, `value`; `text` the
    /// program error in words for program errors.
    pub const FAULT: u32 = 2;
    /// An operator message (`(MSG,...)`): `line`, `text`.
    pub const MESSAGE: u32 = 3;
    /// State change: `code` the new state, `number` the old one, `value` the mode.
    pub const STATE: u32 = 4;
    /// The client was lost (no heartbeat): `code` the reaction (`on_loss`).
    pub const CLIENT_LOST: u32 = 5;
    /// The program ended at `line`.
    pub const PROGRAM_END: u32 = 6;
}

/// Acknowledgement kinds (`WireEvent::code` of an [`event::ACK`]).
pub mod ack {
    /// The kernel took the command.
    pub const ACCEPTED: u32 = 1;
    /// What the command started has finished.
    pub const DONE: u32 = 2;
    /// Refused; `number` says why.
    pub const REFUSED: u32 = 3;
    /// Accepted, but what it started ended in a fault, e-stop or stop.
    pub const FAILED: u32 = 4;
}

/// One event, numbered by the machine.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct WireEvent {
    /// Sequence number (1, 2, …; gaps are events lost to a full ring).
    pub seq: u64,
    /// [`event`] kind.
    pub kind: u32,
    /// Kind-specific code.
    pub code: u32,
    /// The machine's time, ns since its start.
    pub time_ns: u64,
    /// Servo cycle.
    pub cycle: u64,
    /// Command serial (acknowledgements).
    pub serial: u64,
    /// Kind-specific number.
    pub number: u64,
    /// Program line.
    pub line: u32,
    /// Joint, -1 for none.
    pub joint: i32,
    /// Kind-specific value.
    pub value: f64,
    /// For an urgent command's acknowledgement: the client's write time (ns, CLOCK_MONOTONIC)
    /// and the machine's cycle then.
    pub written_ns: u64,
    /// The cycle the client saw when it wrote the command.
    pub written_cycle: u64,
    /// CLOCK_MONOTONIC when the kernel took the command, ns.
    pub acted_ns: u64,
    /// Text.
    pub text: WireText,
}

/// Status flags (`WireStatus::flags`).
pub mod flags {
    /// The program reached its end.
    pub const PROGRAM_ENDED: u32 = 1 << 0;
    /// Drives enabled, ready.
    pub const READY: u32 = 1 << 1;
    /// The e-stop input is pressed.
    pub const ESTOP_INPUT: u32 = 1 << 2;
    /// Spindle commanded on.
    pub const SPINDLE_ON: u32 = 1 << 3;
    /// Spindle counter-clockwise.
    pub const SPINDLE_REVERSE: u32 = 1 << 4;
    /// Mist coolant.
    pub const MIST: u32 = 1 << 5;
    /// Flood coolant.
    pub const FLOOD: u32 = 1 << 6;
    /// Single block on.
    pub const SINGLE_BLOCK: u32 = 1 << 7;
    /// Optional stop on.
    pub const OPTIONAL_STOP: u32 = 1 << 8;
    /// Block delete on.
    pub const BLOCK_DELETE: u32 = 1 << 9;
    /// A program is loaded.
    pub const PROGRAM_LOADED: u32 = 1 << 10;
    /// The machine logic asks for a feed hold (door, fault).
    pub const LOGIC_HOLD: u32 = 1 << 11;
    /// A client is attached.
    pub const CLIENT_ATTACHED: u32 = 1 << 12;
    /// The interpreter's modal state is known (`g_codes` and the offsets are valid).
    pub const MODAL_VALID: u32 = 1 << 13;
}

/// The status snapshot: published by the machine every status-feedback period under a
/// seqlock.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct WireStatus {
    /// Servo cycles run.
    pub cycle: u64,
    /// The machine's time, ns since its start.
    pub time_ns: u64,
    /// `MachineState` number (see `crate::link::state_name`).
    pub state: u32,
    /// `Mode` number: 0 manual, 1 auto, 2 MDI.
    pub mode: u32,
    /// Program line executing.
    pub line: u32,
    /// [`flags`].
    pub flags: u32,
    /// Bit n: joint n homed.
    pub homed: u32,
    /// Faults raised so far.
    pub fault_count: u32,
    /// Tool in the spindle.
    pub tool: u32,
    /// The last fault's number (0: none).
    pub last_fault: u32,
    /// Axis positions, machine coordinates (set-point), mm or degrees.
    pub axes: [f64; AXES],
    /// Joint set-points.
    pub joint_setpoints: [f64; MAX_JOINTS],
    /// Joint feedback positions.
    pub joint_feedback: [f64; MAX_JOINTS],
    /// Joint velocities (feedback), units/s.
    pub joint_velocity: [f64; MAX_JOINTS],
    /// Following error each servo loop saw in its last period.
    pub following_error: [f64; MAX_JOINTS],
    /// Path speed, units/s.
    pub path_speed: f64,
    /// Distance to go per axis, machine units: to the end of the executing line.
    pub distance_to_go: [f64; AXES],
    /// Feed override.
    pub feed_override: f64,
    /// Rapid override.
    pub rapid_override: f64,
    /// Spindle override.
    pub spindle_override: f64,
    /// Spindle speed measured, rpm.
    pub spindle_rpm: f64,
    /// Spindle speed commanded, rpm.
    pub spindle_command_rpm: f64,
    /// Digital inputs (bit n = input n).
    pub digital_inputs: u64,
    /// Digital outputs.
    pub digital_outputs: u64,
    /// Analogue inputs.
    pub analog_inputs: [f64; MAX_PROGRAM_IO],
    /// Active G codes ×10 (G64 = 640, G54.1 = 541), the interpreter's modal state; -1 unused.
    pub g_codes: [i32; 16],
    /// Active M codes; -1 unused.
    pub m_codes: [i32; 8],
    /// F in program units.
    pub feed_rate: f64,
    /// S.
    pub speed: f64,
    /// mm per program unit (1 or 25.4).
    pub units_mm: f64,
    /// Active work system, 1..9 = G54..G59.3.
    pub work_system: u32,
    /// What holds the machine while `state` is held: a `HoldCause` number (see
    /// `crate::link::hold_cause`), 0 for none. (It was padding: a client of an older
    /// segment reads 0.)
    pub hold: u32,
    /// Work offset in force (G54..), program units.
    pub work_offset: [f64; AXES],
    /// G92 offset, program units.
    pub g92_offset: [f64; AXES],
    /// Tool length offset, program units.
    pub tool_offset: [f64; AXES],
    /// XY rotation of the work system, degrees.
    pub rotation: f64,
    /// Times the client was lost so far.
    pub client_losses: u64,
    /// Events dropped because the ring was full.
    pub events_dropped: u64,
    /// Trace samples dropped because the ring was full.
    pub trace_dropped: u64,
}

impl Default for WireStatus {
    fn default() -> Self {
        // SAFETY: every field is an integer, a float or an array of them: all zeros is a
        // value.
        unsafe { std::mem::zeroed() }
    }
}

/// One period's set-points and feedback, for plots.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct TraceSample {
    /// Servo cycle.
    pub cycle: u64,
    /// Time, ns since the machine's start.
    pub time_ns: u64,
    /// Program line.
    pub line: u32,
    /// Joints in use.
    pub joints: u32,
    /// Path speed.
    pub path_speed: f64,
    /// Axis set-points.
    pub axes: [f64; AXES],
    /// Joint set-points.
    pub setpoint: [f64; MAX_JOINTS],
    /// Joint feedback.
    pub feedback: [f64; MAX_JOINTS],
    /// Following errors.
    pub following_error: [f64; MAX_JOINTS],
}

/// One task's timing (the executive's monitor).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct WireTaskTiming {
    /// Task name.
    pub name: [u8; 32],
    /// Body runs.
    pub activations: u64,
    /// Execution time, ns.
    pub execution_mean_ns: u64,
    /// p99.
    pub execution_p99_ns: u64,
    /// Largest.
    pub execution_max_ns: u64,
    /// Start lateness (wake-up latency), p99, ns.
    pub lateness_p99_ns: u64,
    /// Largest.
    pub lateness_max_ns: u64,
    /// Deadline misses.
    pub deadline_misses: u64,
    /// Skipped releases.
    pub skipped_releases: u64,
}

/// Task timing, published by the machine's service thread a few times a second.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct WireTiming {
    /// Entries used.
    pub count: u32,
    /// The threads run SCHED_FIFO.
    pub fifo: u32,
    /// Servo periods without a fresh set-point so far (position control extrapolated).
    pub underruns: u64,
    /// Entries.
    pub tasks: [WireTaskTiming; TIMING_SLOTS],
}

impl Default for WireTiming {
    fn default() -> Self {
        // SAFETY: plain integers and byte arrays: all zeros is a value.
        unsafe { std::mem::zeroed() }
    }
}

/// Kinds of service request (`ServiceRequest::kind`), handled by the machine's service
/// thread, off the real-time tasks.
pub mod service {
    /// Read the PLC variable at the path in `text`.
    pub const PLC_READ: u32 = 1;
    /// Force it to the value in `value_text`.
    pub const PLC_FORCE: u32 = 2;
    /// Release its force.
    pub const PLC_UNFORCE: u32 = 3;
    /// Watch the comma-separated paths in `text` (replaces the watch list).
    pub const PLC_WATCH: u32 = 4;
}

/// A request to the machine's service thread.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct ServiceRequest {
    /// Serial (not 0).
    pub serial: u64,
    /// [`service`] kind.
    pub kind: u32,
    /// Padding.
    pub _pad: u32,
    /// Path or paths.
    pub text: WireText,
    /// A value, as text.
    pub value_text: WireText,
}

/// The service thread's answer.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct ServiceReply {
    /// The request's serial.
    pub serial: u64,
    /// 1 done, 0 refused.
    pub ok: u32,
    /// Padding.
    pub _pad: u32,
    /// Stable code of a refusal (`plc.unknown_variable`, …).
    pub code: WireText,
    /// The value read, or the message.
    pub text: WireText,
}

/// Watched PLC variables' values, published by the service thread.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct WireWatch {
    /// Watch list version (changes with every new list).
    pub list: u64,
    /// Entries used.
    pub count: u32,
    /// Bit n: entry n is forced.
    pub forced: u32,
    /// Values (booleans as 0/1).
    pub values: [f64; WATCH_SLOTS],
}

impl Default for WireWatch {
    fn default() -> Self {
        // SAFETY: plain numbers.
        unsafe { std::mem::zeroed() }
    }
}

/// The header: written once by the machine before the segment gets its name.
#[repr(C)]
pub struct Header {
    /// [`MAGIC`], stored last.
    pub magic: AtomicU64,
    /// [`LAYOUT_VERSION`].
    pub layout_version: u32,
    /// Size of [`Header`].
    pub header_size: u32,
    /// Size of the whole [`Segment`].
    pub segment_size: u64,
    /// Distinguishes one start of the machine from the next (its start time, ns).
    pub instance: u64,
    /// The machine process.
    pub machine_pid: u32,
    /// Joints configured.
    pub joint_count: u32,
    /// Servo period, ns.
    pub servo_period_ns: u64,
    /// Status period, ns.
    pub status_period_ns: u64,
    /// Bit n: axis n (X..W) present.
    pub axes_present: u32,
    /// `[hmi] on_loss`: 0 continue, 1 hold, 2 e-stop.
    pub on_loss: u32,
    /// Loss of the client after this long without its heartbeat, ns.
    pub loss_timeout_ns: u64,
    /// A continuous jog stops this long after its last keep-alive, ns.
    pub jog_keep_alive_ns: u64,
    /// The machine's name (`[machine] name`).
    pub machine_name: [u8; 64],
    /// Joint names.
    pub joint_names: [[u8; 16]; MAX_JOINTS],
}

/// The whole segment.
#[repr(C)]
pub struct Segment {
    /// Header.
    pub header: Header,
    /// The machine's heartbeat: the servo cycle of its last status period.
    pub machine_heartbeat: AtomicU64,
    /// The client's heartbeat: a counter it increments every few milliseconds.
    pub client_heartbeat: AtomicU64,
    /// The attached client's process id (0: none).
    pub client_pid: AtomicU32,
    /// Padding.
    pub _pad: u32,
    /// Times the machine declared its client lost.
    pub client_losses: AtomicU64,
    /// Times a client left cleanly (a client that replaces another without this having
    /// changed means the other was lost).
    pub client_detaches: AtomicU64,
    /// Events dropped (ring full).
    pub events_dropped: AtomicU64,
    /// Trace samples dropped (ring full).
    pub trace_dropped: AtomicU64,
    /// Client -> machine: normal commands.
    pub commands: SpscCell<WireCommand, COMMAND_SLOTS>,
    /// Client -> machine: urgent commands.
    pub urgent: SpscCell<WireUrgent, URGENT_SLOTS>,
    /// Machine -> client: status snapshot.
    pub status: SeqlockCell<WireStatus>,
    /// Machine -> client: events.
    pub events: SpscCell<WireEvent, EVENT_SLOTS>,
    /// Machine -> client: trace samples.
    pub trace: SpscCell<TraceSample, TRACE_SLOTS>,
    /// Machine -> client: task timing.
    pub timing: SeqlockCell<WireTiming>,
    /// Machine -> client: watched PLC values.
    pub watch: SeqlockCell<WireWatch>,
    /// Client -> machine's service thread.
    pub requests: SpscCell<ServiceRequest, SERVICE_SLOTS>,
    /// Machine's service thread -> client.
    pub replies: SpscCell<ServiceReply, SERVICE_SLOTS>,
}

/// Copies `text` into a fixed, zero-padded name field.
pub fn name_field<const N: usize>(text: &str) -> [u8; N] {
    let mut out = [0u8; N];
    let mut end = text.len().min(N);
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    out[..end].copy_from_slice(&text.as_bytes()[..end]);
    out
}

/// The text of a zero-padded name field.
pub fn field_name(bytes: &[u8]) -> &str {
    let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
    std::str::from_utf8(&bytes[..end]).unwrap_or("")
}
