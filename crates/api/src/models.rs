//! The API's documents (JSON bodies), each with its OpenAPI schema.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// Values by axis letter (only the machine's axes), e.g. `{"X": 1.5, "Y": 0}`.
#[derive(Debug, Clone, Default, Serialize, Deserialize, ToSchema, PartialEq)]
#[serde(transparent)]
pub struct AxisMap(pub BTreeMap<String, f64>);

impl AxisMap {
    /// Empty.
    pub fn new() -> AxisMap {
        AxisMap::default()
    }
}

impl FromIterator<(String, f64)> for AxisMap {
    fn from_iter<I: IntoIterator<Item = (String, f64)>>(iter: I) -> Self {
        AxisMap(iter.into_iter().collect())
    }
}

/// The machine's status snapshot.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema, PartialEq)]
pub struct Status {
    /// The machine's name.
    pub machine: String,
    /// The machine process answers (false: every other field is the last known).
    pub connected: bool,
    /// Servo cycles run.
    pub cycle: u64,
    /// Machine time, s since its start.
    pub time_s: f64,
    /// `starting`, `estop`, `idle`, `running`, `held`, `paused`, `waiting_for_logic`, `fault`.
    pub state: String,
    /// `manual`, `auto`, `mdi`.
    pub mode: String,
    /// Program line executing.
    pub line: u32,
    /// The loaded program's name.
    pub program: Option<String>,
    /// The program reached its end.
    pub program_ended: bool,
    /// Drives enabled, ready for commands.
    pub ready: bool,
    /// The e-stop input is pressed.
    pub estop_input: bool,
    /// Machine position (set-point), mm or degrees.
    pub machine_position: AxisMap,
    /// Work position (program coordinates: work offset, G92, tool length offset and XY
    /// rotation taken off), program units.
    pub work_position: AxisMap,
    /// Distance to go: from the machine position to the end of the executing program or
    /// MDI line (its path as planned), per axis, mm or degrees; zero in manual motion and
    /// at rest.
    pub distance_to_go: AxisMap,
    /// Per joint.
    pub joints: Vec<Joint>,
    /// Path speed, units/s.
    pub path_speed: f64,
    /// Overrides.
    pub overrides: Overrides,
    /// Spindle.
    pub spindle: Spindle,
    /// Mist coolant on.
    pub mist: bool,
    /// Flood coolant on.
    pub flood: bool,
    /// Tool in the spindle.
    pub tool: u32,
    /// Active G and M codes, feed, speed, offsets (the interpreter's modal state, which in
    /// a program runs ahead of the motion by the look-ahead).
    pub modal: Option<Modal>,
    /// Digital inputs, bit n = input n.
    pub digital_inputs: u64,
    /// Digital outputs.
    pub digital_outputs: u64,
    /// Analogue inputs.
    pub analog_inputs: Vec<f64>,
    /// Watched PLC variables.
    pub plc_watch: Vec<WatchValue>,
    /// Single block on.
    pub single_block: bool,
    /// Optional stop (M1) on.
    pub optional_stop: bool,
    /// Block delete on.
    pub block_delete: bool,
    /// The machine logic holds the feed (door open, fault).
    pub logic_hold: bool,
    /// What holds the machine while `state` is `held`: `machine_logic` (it asks for a feed
    /// hold: the door open, a fault, the spindle not at speed; a resume is refused until it
    /// stops asking, and a program it held at its start goes on by itself then),
    /// `feed_stop_switch` (M53; goes on when released), `resume` (a feed hold waits for
    /// the operator's resume); none otherwise.
    pub hold: Option<String>,
    /// The operator's message of `hold`, e.g. `held: machine logic requests a feed hold
    /// (door open?)`.
    pub hold_message: Option<String>,
    /// Faults raised since the machine started.
    pub fault_count: u32,
    /// The last fault's code (`kernel.estop`, …).
    pub last_fault: Option<String>,
    /// Deadline misses of the real-time tasks so far.
    pub deadline_misses: u64,
    /// Who holds the control lease.
    pub lease_holder: Option<String>,
    /// Link counters.
    pub link: LinkCounters,
}

/// One joint.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema, PartialEq)]
pub struct Joint {
    /// Its name.
    pub name: String,
    /// Set-point.
    pub setpoint: f64,
    /// Feedback position.
    pub feedback: f64,
    /// Velocity (feedback), units/s.
    pub velocity: f64,
    /// Following error the servo loop saw in its last period.
    pub following_error: f64,
    /// Homed.
    pub homed: bool,
}

/// Overrides, as factors (1 = 100 %).
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema, PartialEq)]
pub struct Overrides {
    /// Feed, 0..2.
    pub feed: f64,
    /// Rapid, 0..1.
    pub rapid: f64,
    /// Spindle, 0.5..1.5.
    pub spindle: f64,
}

/// The spindle.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema, PartialEq)]
pub struct Spindle {
    /// Commanded on.
    pub on: bool,
    /// `cw`, `ccw` or `off`.
    pub direction: String,
    /// Measured speed, rpm.
    pub rpm: f64,
    /// Commanded speed (after the override and G96), rpm.
    pub command_rpm: f64,
}

/// The interpreter's modal state.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema, PartialEq)]
pub struct Modal {
    /// Active G codes (`G1`, `G17`, `G54`, `G64`, …).
    pub g_codes: Vec<String>,
    /// Active M codes.
    pub m_codes: Vec<String>,
    /// F, program units per minute.
    pub feed_rate: f64,
    /// S, rpm.
    pub speed: f64,
    /// `mm` or `inch`.
    pub units: String,
    /// `G54` .. `G59.3`.
    pub work_system: String,
    /// Work offset in force, program units.
    pub work_offset: AxisMap,
    /// G92 offset.
    pub g92_offset: AxisMap,
    /// Tool length offset.
    pub tool_offset: AxisMap,
    /// XY rotation, degrees.
    pub rotation: f64,
}

/// A watched PLC variable.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema, PartialEq)]
pub struct WatchValue {
    /// Its path.
    pub path: String,
    /// Value (BOOL as 0/1).
    pub value: f64,
    /// Forced.
    pub forced: bool,
}

/// Link counters.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema, PartialEq)]
pub struct LinkCounters {
    /// Times the machine lost its API process.
    pub client_losses: u64,
    /// Events the machine dropped (ring full).
    pub events_dropped: u64,
    /// Trace samples dropped.
    pub trace_dropped: u64,
}

/// One event.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema, PartialEq)]
pub struct Event {
    /// The API's sequence number (1, 2, …; kept across machine restarts).
    pub seq: u64,
    /// `ack`, `fault`, `message`, `state`, `program_end`, `client_lost`, `machine_lost`,
    /// `machine_attached`, `events_lost`.
    pub kind: String,
    /// Machine time, s.
    pub time_s: f64,
    /// Servo cycle.
    pub cycle: u64,
    /// Stable code: the acknowledgement's refusal, the fault's (`kernel.estop`), or the
    /// new state.
    pub code: Option<String>,
    /// Text for a person.
    pub message: String,
    /// Program line.
    pub line: Option<u32>,
    /// Joint name.
    pub joint: Option<String>,
    /// For `ack`: the command's serial.
    pub serial: Option<u64>,
    /// For `ack`: `accepted`, `done`, `refused`, `failed`.
    pub ack: Option<String>,
    /// For an urgent command's `ack`: servo periods from the client's write to the kernel
    /// acting (1 = the next period).
    pub latency_periods: Option<u64>,
    /// For an urgent command's `ack`: ns from the write to the kernel acting.
    pub latency_ns: Option<u64>,
    /// A value (following error, …).
    pub value: Option<f64>,
}

/// Events after a sequence number.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct EventPage {
    /// The events, oldest first.
    pub events: Vec<Event>,
    /// The newest sequence number (ask again with `since` = this).
    pub last_seq: u64,
    /// Events older than `since` that the API no longer keeps.
    pub missed: u64,
}

/// A command's acknowledgement.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema, PartialEq)]
pub struct Ack {
    /// The command's serial.
    pub serial: u64,
    /// `pending`, `accepted`, `done`, `refused`, `failed`.
    pub state: String,
    /// The refusal's or failure's code.
    pub code: Option<String>,
    /// Its message.
    pub message: Option<String>,
    /// For urgent commands: servo periods from the write to the kernel acting.
    pub latency_periods: Option<u64>,
    /// For urgent commands: ns from the write to the kernel acting.
    pub latency_ns: Option<u64>,
}

/// Log-in.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct Login {
    /// User name.
    pub user: String,
    /// Password.
    pub password: String,
}

/// A session.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct SessionInfo {
    /// Bearer token (only in the log-in answer).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub token: Option<String>,
    /// User.
    pub user: String,
    /// `viewer`, `operator`, `setter`, `admin`.
    pub role: String,
    /// Seconds until the session expires.
    pub expires_in_s: u64,
    /// The password is a one-time password: change it before anything else.
    pub password_change_required: bool,
    /// This session holds the control lease.
    pub holds_lease: bool,
}

/// A password change.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct PasswordChange {
    /// The password now.
    pub old: String,
    /// The new one (at least 8 characters).
    pub new: String,
}

/// The control lease.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct Lease {
    /// The holder's user name.
    pub holder: Option<String>,
    /// Held by the caller's session.
    pub mine: bool,
}

/// A program in the store.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct ProgramInfo {
    /// File name.
    pub name: String,
    /// Bytes.
    pub size: u64,
    /// Lines.
    pub lines: u64,
}

/// An interpreter error in an uploaded program.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct ProgramError {
    /// 1-based line.
    pub line: u32,
    /// 1-based column (0: the whole line).
    pub column: u32,
    /// Stable code (`gcode.…`).
    pub code: String,
    /// Message.
    pub message: String,
}

/// A tool-path preview: the canonical motion as polylines.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct Preview {
    /// Polylines, each rapid or feed, in program order.
    pub paths: Vec<Polyline>,
    /// Bounding box minimum (X, Y, Z), mm.
    pub min: [f64; 3],
    /// Maximum.
    pub max: [f64; 3],
    /// Interpreter errors (the preview ends at the first).
    pub errors: Vec<ProgramError>,
}

/// One polyline.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct Polyline {
    /// `rapid` or `feed`.
    pub kind: String,
    /// Program line of each point after the first.
    pub lines: Vec<u32>,
    /// Points (X, Y, Z), mm, in the canonical frame (work offsets applied).
    pub points: Vec<[f64; 3]>,
}

/// A cycle-time estimate from the planner in virtual time.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct Estimate {
    /// Seconds from cycle start to the end (what `rtcnc sim` prints).
    pub cycle_time_s: f64,
    /// The program reached its end.
    pub ended: bool,
    /// Faults, as codes.
    pub faults: Vec<String>,
    /// Host seconds the simulation took.
    pub computed_in_s: f64,
}

/// A tool (LinuxCNC `.tbl` meaning; lengths in machine units).
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema, PartialEq)]
pub struct Tool {
    /// T.
    pub number: i32,
    /// P: pocket.
    pub pocket: i32,
    /// Offsets (X, Y, Z, A, B, C, U, V, W; Z is the length on a mill).
    pub offset: AxisMap,
    /// D.
    pub diameter: f64,
    /// I: lathe front angle.
    #[serde(default)]
    pub front_angle: f64,
    /// J: lathe back angle.
    #[serde(default)]
    pub back_angle: f64,
    /// Q: lathe orientation.
    #[serde(default)]
    pub orientation: i32,
    /// Comment.
    #[serde(default)]
    pub comment: String,
}

/// A work offset (G54..G59.3), program units.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema, PartialEq)]
pub struct WorkOffset {
    /// `G54` .. `G59.3`.
    pub system: String,
    /// Offset per axis.
    pub offset: AxisMap,
    /// XY rotation, degrees.
    #[serde(default)]
    pub rotation: f64,
}

/// Start of a program.
#[derive(Debug, Clone, Default, Serialize, Deserialize, ToSchema)]
pub struct CycleStart {
    /// Run from this line (0: from the start).
    #[serde(default)]
    pub from_line: u32,
}

/// A program to load.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct LoadProgram {
    /// Name in the program store.
    pub name: String,
}

/// On or off.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct Switch {
    /// On.
    pub on: bool,
}

/// An MDI line.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct Mdi {
    /// The line (at most 256 bytes).
    pub line: String,
}

/// A jog.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct Jog {
    /// Axis letter.
    pub axis: String,
    /// Continuous: signed velocity, units/s (needs a keep-alive every 200 ms).
    #[serde(default)]
    pub velocity: Option<f64>,
    /// Incremental: signed distance, units.
    #[serde(default)]
    pub distance: Option<f64>,
}

/// An axis.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct AxisRef {
    /// Axis letter.
    pub axis: String,
}

/// The machine's mode.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, ToSchema, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum ModeName {
    /// Jog, handwheel, homing.
    Manual,
    /// Programs.
    Auto,
    /// MDI lines.
    Mdi,
}

/// A mode switch.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct ModeRequest {
    /// The mode.
    pub mode: ModeName,
}

/// Overrides to set (absent: unchanged).
#[derive(Debug, Clone, Default, Serialize, Deserialize, ToSchema)]
pub struct OverridesRequest {
    /// Feed, 0..2.
    #[serde(default)]
    pub feed: Option<f64>,
    /// Rapid, 0..1.
    #[serde(default)]
    pub rapid: Option<f64>,
    /// Spindle, 0.5..1.5.
    #[serde(default)]
    pub spindle: Option<f64>,
}

/// The spindle (an MDI M3/M4/M5 line: needs the machine idle).
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct SpindleRequest {
    /// `cw`, `ccw` or `off`.
    pub direction: String,
    /// rpm (for cw/ccw).
    #[serde(default)]
    pub rpm: Option<f64>,
}

/// Coolant (an MDI M7/M8/M9 line).
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct CoolantRequest {
    /// Mist.
    pub mist: bool,
    /// Flood.
    pub flood: bool,
}

/// A PLC variable.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct PlcVariable {
    /// Path (`GLOBAL`, `INSTANCE.VAR`, `timer.ET`, `word.3`).
    pub path: String,
    /// Value as IEC text (`TRUE`, `42`, `T#1s`).
    pub value: String,
}

/// A force.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct PlcForce {
    /// Path.
    pub path: String,
    /// Value as IEC text.
    pub value: String,
}

/// The watch list.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct PlcWatch {
    /// Paths (at most 16); their values come in the status (`plc_watch`).
    pub paths: Vec<String>,
}

/// A fault in the history.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct FaultRecord {
    /// The event's sequence number (acknowledge up to it).
    pub seq: u64,
    /// Stable code.
    pub code: String,
    /// Message.
    pub message: String,
    /// Machine time, s.
    pub time_s: f64,
    /// Program line.
    pub line: Option<u32>,
    /// Joint.
    pub joint: Option<String>,
    /// Acknowledged by an operator.
    pub acknowledged: bool,
}

/// Acknowledge faults.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct FaultAck {
    /// Every fault up to this sequence number.
    pub up_to_seq: u64,
}

/// Task timing.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct Timing {
    /// The real-time threads run SCHED_FIFO.
    pub fifo: bool,
    /// Servo periods without a fresh set-point so far.
    pub underruns: u64,
    /// Per task.
    pub tasks: Vec<TaskTiming>,
}

/// One task's timing (the executive's monitor).
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct TaskTiming {
    /// Name.
    pub name: String,
    /// Body runs.
    pub activations: u64,
    /// Execution time mean, µs.
    pub execution_mean_us: f64,
    /// p99, µs.
    pub execution_p99_us: f64,
    /// Largest, µs.
    pub execution_max_us: f64,
    /// Wake-up latency p99, µs.
    pub lateness_p99_us: f64,
    /// Largest, µs.
    pub lateness_max_us: f64,
    /// Deadline misses.
    pub deadline_misses: u64,
    /// Skipped releases.
    pub skipped_releases: u64,
}

/// Version and limits of this API.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct ApiInfo {
    /// rtcnc version.
    pub version: String,
    /// The machine's name.
    pub machine: String,
    /// Axis letters.
    pub axes: Vec<String>,
    /// Servo period, s.
    pub servo_period_s: f64,
    /// Largest upload, bytes.
    pub max_upload_bytes: u64,
    /// Largest WebSocket message from a client, bytes.
    pub max_ws_message_bytes: u64,
    /// Continuous jog keep-alive period, s.
    pub jog_keep_alive_s: f64,
}

/// The interpreter's verdict on a program text (nothing is stored).
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct ProgramCheck {
    /// Every error (up to 100), with line and column; empty: the program is good.
    pub errors: Vec<ProgramError>,
    /// Lines in the text.
    pub lines: u64,
}

/// The handwheel (manual pulse generator): which axis it moves and its scale.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct HandwheelRequest {
    /// Axis letter; absent or null releases the handwheel.
    #[serde(default)]
    pub axis: Option<String>,
    /// Multiplier of the machine's `handwheel.units_per_count` (×1, ×10, ×100).
    #[serde(default = "one")]
    pub scale: f64,
}

fn one() -> f64 {
    1.0
}

/// The machine file.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct MachineFile {
    /// Its path on the machine's computer.
    pub path: String,
    /// Its text (TOML).
    pub text: String,
    /// The file differs from the one the API process started with: the machine process
    /// takes the new one at its next start.
    pub changed_since_start: bool,
    /// Travel per handwheel count at ×1 (`[handwheel] units_per_count`), in the file the
    /// API process started with.
    pub handwheel_units_per_count: f64,
}

/// A machine file written.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct MachineFileSaved {
    /// Bytes written.
    pub size: u64,
    /// Always true: the machine process reads its file only when it starts.
    pub applies_at_next_start: bool,
}

/// A variable of the PLC program.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct PlcVariableInfo {
    /// Path (`GLOBAL`, `INSTANCE.VAR`, `A[3]`), as `GET /api/plc/variables/{path}` takes it.
    pub path: String,
    /// IEC type (`BOOL`, `INT`, `TIME`, …).
    pub type_name: String,
    /// Declared RETAIN.
    pub retain: bool,
    /// Direct address of a located variable (`%IX0.1`).
    pub location: Option<String>,
}
