//! The messages between the kernel's stages and with the operator: plain data only (fixed
//! sizes, no pointers, no heap), so that a later step can move the channels into shared
//! memory between processes.

use rtcnc_motion::{AXES, Feed, Move};

use crate::config::MAX_JOINTS;

/// A short text (an MDI line, a program path) in a fixed buffer.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct FixedText {
    len: u16,
    bytes: [u8; FixedText::CAPACITY],
}

impl FixedText {
    /// Longest text, in bytes.
    pub const CAPACITY: usize = 256;

    /// The text, or `None` when it does not fit.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn new(text: &str) -> Option<FixedText> {
        if text.len() > Self::CAPACITY {
            return None;
        }
        let mut bytes = [0u8; Self::CAPACITY];
        bytes[..text.len()].copy_from_slice(text.as_bytes());
        Some(FixedText {
            len: text.len() as u16,
            bytes,
        })
    }

    /// The text, shortened at a character boundary to fit when it is longer.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn truncated(text: &str) -> FixedText {
        let mut end = text.len().min(Self::CAPACITY);
        while !text.is_char_boundary(end) {
            end -= 1;
        }
        FixedText::new(&text[..end]).unwrap_or(FixedText {
            len: 0,
            bytes: [0u8; Self::CAPACITY],
        })
    }

    /// The text.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn as_str(&self) -> &str {
        let len = usize::from(self.len).min(Self::CAPACITY);
        std::str::from_utf8(&self.bytes[..len]).unwrap_or("")
    }
}

impl std::fmt::Debug for FixedText {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:?}", self.as_str())
    }
}

/// Commands of the urgent channel: read first, every cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Urgent {
    /// Emergency stop: quick stop along the path, then the drives are disabled.
    EStop,
    /// Feed hold: decelerate along the path and wait.
    FeedHold,
    /// Resume after a feed hold (or continue after M0/M1/single block).
    Resume,
    /// Stop the program: decelerate along the path, drop what is queued.
    Abort,
    /// Feed override, 0..=2.
    FeedOverride(f64),
    /// Rapid override, 0..=1.
    RapidOverride(f64),
    /// Spindle override, 0.5..=1.5 of the programmed speed.
    SpindleOverride(f64),
}

/// Operating modes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Mode {
    /// Manual: jog, handwheel, homing.
    #[default]
    Manual,
    /// A program runs (or is paused).
    Auto,
    /// MDI lines.
    Mdi,
}

/// Commands of the normal channel.
// Plain data with a fixed size (no Box): the MDI line is carried inline.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Command {
    /// Leave e-stop or fault: reset the faults, enable the drives.
    Reset,
    /// Run the loaded program (auto mode), from its start or from a line (motion before the
    /// line is skipped; the machine goes to where that line starts at rapid).
    Start {
        /// First program line whose motion is executed (0 or 1: from the start).
        from_line: u32,
    },
    /// One MDI line.
    Mdi(FixedText),
    /// Continuous jog of an axis (index in X..W order) at `velocity` (signed, units/s).
    JogContinuous {
        /// Axis index.
        axis: u8,
        /// Signed velocity.
        velocity: f64,
    },
    /// Incremental jog by `distance`.
    JogIncrement {
        /// Axis index.
        axis: u8,
        /// Signed distance.
        distance: f64,
    },
    /// Stop a jog.
    JogStop {
        /// Axis index.
        axis: u8,
    },
    /// Handwheel on an axis (or off with `None`), `scale` units per count multiplier
    /// (×1, ×10, ×100).
    Handwheel {
        /// Axis index, or none to release the handwheel.
        axis: Option<u8>,
        /// Multiplier of `handwheel.units_per_count`.
        scale: f64,
    },
    /// Home every joint with a homing sequence (in sequence order).
    HomeAll,
    /// Switch the mode while the machine is idle, as an operator's mode key does; the
    /// commands that need a mode (cycle start, MDI, jog, homing) still switch to it.
    SetMode(Mode),
    /// Home the joints of one axis (together, whatever their sequence numbers).
    HomeAxis {
        /// Axis index.
        axis: u8,
    },
    /// Move an independent joint (one no axis drives) to `position`.
    JointMove {
        /// Joint index.
        joint: u8,
        /// Target position.
        position: f64,
    },
    /// Single block on/off.
    SingleBlock(bool),
    /// Optional stop (M1) on/off.
    OptionalStop(bool),
    /// Block delete (`/`) on/off; takes effect at the next program start.
    BlockDelete(bool),
}

/// Machine functions the machine logic acknowledges before motion continues past them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Aux {
    /// Spindle on at `rpm` (negative: counter-clockwise).
    SpindleOn {
        /// Signed speed.
        rpm: f64,
    },
    /// Spindle off.
    SpindleOff,
    /// Spindle speed change while on (or preset).
    SpindleSpeed {
        /// Speed, rpm.
        rpm: f64,
    },
    /// Mist coolant.
    Mist(bool),
    /// Flood coolant.
    Flood(bool),
    /// M6 with the prepared tool.
    ToolChange {
        /// Tool number.
        tool: u32,
    },
    /// M100..M199.
    UserM {
        /// Code.
        code: u16,
        /// P word (NaN when absent).
        p: f64,
        /// Q word (NaN when absent).
        q: f64,
    },
    /// M52: adaptive feed on (P1) or off (P0).
    AdaptiveFeed(bool),
    /// M62..M65 digital output.
    DigitalOutput {
        /// Program output number.
        index: u32,
        /// Value.
        on: bool,
        /// M62/M63: at the start of the next move, without stopping the path; M64/M65
        /// (false): once the motion before it is done.
        synchronized: bool,
    },
    /// M66 on a digital input: wait for a condition, at most `timeout` seconds.
    WaitInput {
        /// Program input number (P word), mapped by `io.program_inputs`.
        index: u32,
        /// The condition.
        condition: WaitCondition,
        /// Seconds; 0 reads the input and goes on.
        timeout: f64,
    },
    /// M66 E L0: read an analogue input (the interpreter waits for its value).
    ReadAnalogInput {
        /// Program input number (E word), mapped by `io.program_analog_inputs`.
        index: u32,
    },
    /// M67/M68: set an analogue output.
    AnalogOutput {
        /// Program output number (E word), mapped by `io.program_analog_outputs`.
        index: u32,
        /// Value (Q word).
        value: f64,
        /// M67: at the start of the next move, without stopping the path; M68 (false):
        /// once the motion before it is done.
        synchronized: bool,
    },
    /// G96 S D as the interpreter gives it: surface speed in the program's units per minute
    /// (m/min in G21, ft/min in G20), `max_rpm` the D word (1e30 without one). Tool
    /// compensation turns it into [`Aux::ConstantSurfaceSpeed`].
    SurfaceSpeed {
        /// S.
        surface: f64,
        /// D.
        max_rpm: f64,
    },
    /// G96 for the machine: the spindle turns at `factor / |X − x_centre|` rpm (capped at
    /// `max_rpm`), following the X set-point every servo period.
    ConstantSurfaceSpeed {
        /// Surface speed in mm/min over 2π (rpm·mm).
        factor: f64,
        /// Machine X of the spindle axis (the X offsets in force), mm.
        x_centre: f64,
        /// D word, rpm.
        max_rpm: f64,
    },
    /// G97: the spindle turns at the programmed rpm again.
    SurfaceSpeedOff,
    /// M19 R P: orient the spindle (stops its rotation).
    SpindleOrient {
        /// Angle, degrees.
        angle: f64,
        /// 0 the shorter way, 1 clockwise, 2 counter-clockwise.
        mode: u8,
    },
    /// M19 Q: wait for the orientation, at most `timeout` seconds, else stop the program.
    WaitOrient {
        /// Seconds.
        timeout: f64,
    },
    /// M48-M50: the operator's feed (and rapid) override in force or not.
    FeedOverrideEnable(bool),
    /// M48, M49, M51: the operator's spindle override in force or not.
    SpindleOverrideEnable(bool),
    /// M53: the feed stop switch heeded or not.
    FeedStopEnable(bool),
    /// M0.
    ProgramStop,
    /// M1.
    OptionalStop,
    /// `(MSG,...)` / `(DEBUG,...)`: shown once the motion before it is done. The text
    /// travels beside the blocks (see `Shared::message_texts`), so that every block stays
    /// small; `seq` finds it.
    Message {
        /// Sequence number of the text.
        seq: u32,
    },
}

/// An operator message (`(MSG,...)`, `(DEBUG,...)`) as the machine reached it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OperatorMessage {
    /// The servo cycle of the set-point at which the path stood at the message's block
    /// (everything before it done).
    pub cycle: u64,
    /// That set-point's time, ns since start (`cycle` servo periods).
    pub time_ns: u64,
    /// Program line.
    pub line: u32,
    /// The text (at most [`FixedText::CAPACITY`] bytes; longer texts are shortened).
    pub text: FixedText,
}

/// What the machine measured for a block the interpreter waits on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MachineResult {
    /// M66: the input's value (digital 0 or 1, or the analogue value), -1 on a time-out;
    /// the interpreter stores it in #5399.
    Input(f64),
    /// G38.x: where the probe changed (machine mm; where the move ended when it did not)
    /// and where the machine stands now (#5061-#5070 and the position the program goes on
    /// from).
    Probe {
        /// The probe changed.
        tripped: bool,
        /// Axis position at the change, machine mm (degrees for A B C).
        at: [f64; AXES],
        /// Axis position after the stop.
        stopped: [f64; AXES],
    },
}

/// What M66 waits for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WaitCondition {
    /// L0: no wait.
    Immediate,
    /// L1: a rising edge.
    Rise,
    /// L2: a falling edge.
    Fall,
    /// L3: the input high.
    High,
    /// L4: the input low.
    Low,
}

/// Most spindle-synchronised lines one chain may have (chained G33 blocks, a G76 pass
/// with tapers has four).
pub const MAX_SYNCED_CHAIN: usize = 16;

/// What the tool-compensation stage sends to look-ahead (machine coordinates, mm, s).
// Plain data in preallocated channels: a spline move is the largest, no boxing.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MachineBlock {
    /// A move for the planner.
    Motion(Move),
    /// A machine function (the look-ahead waits for the machine to stop first).
    Aux {
        /// Program line.
        line: u32,
        /// What.
        aux: Aux,
    },
    /// A spindle-synchronised line (G33, a G76 pass): from where the machine stands to
    /// `end`, `pitch` mm per spindle revolution, starting at the spindle's index.
    Synced {
        /// Program line.
        line: u32,
        /// End (machine coordinates).
        end: [f64; AXES],
        /// mm per revolution.
        pitch: f64,
        /// Rigid tapping (G33.1): back to the start with the spindle reversed, its speed
        /// times this factor on the way out (the I word, at least 1).
        tap: Option<f64>,
        /// Another synchronised line follows without a stop (chained G33, a G76 pass with
        /// tapers): they run as one, blended, on one spindle index.
        chained: bool,
    },
    /// A tool-tip move (a line or an arc) under tool-centre-point control (M428): the
    /// look-ahead cuts it into joint-space chords through the machine's table kinematics.
    TcpMove {
        /// Program line.
        line: u32,
        /// The tip's path (an arc's centre and normal in machine coordinates).
        path: rtcnc_motion::TipPath,
        /// End pose: the tool tip in the work's frame with the tool length in Z, machine
        /// coordinates (mm, degrees).
        end: [f64; AXES],
        /// G0.
        rapid: bool,
        /// The programmed feed: the tip's speed (or the rotary axes' where the tip
        /// stands).
        feed: Feed,
        /// Path mode at its end.
        mode: rtcnc_motion::PathMode,
        /// Tool length offset in Z (mm).
        tool_offset: f64,
    },
    /// A probing move (G38.x): it stops where the probe changes.
    Probe {
        /// The move (machine coordinates).
        mv: Move,
        /// Which G38.
        kind: rtcnc_gcode::canon::ProbeKind,
    },
    /// The program ended (M2/M30 or `%`).
    End {
        /// Program line.
        line: u32,
    },
    /// The interpreter or a stage found an error at `line`: stop before it.
    Error {
        /// Program line.
        line: u32,
        /// Stable code of the error (see [`crate::Fault`]).
        code: crate::FaultCode,
    },
    /// An MDI line is done (everything it queued is in the pipeline).
    MdiDone,
}

impl MachineBlock {
    /// The program line the block comes from (0 for the end of an MDI line).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn line(&self) -> u32 {
        match self {
            MachineBlock::Motion(mv) | MachineBlock::Probe { mv, .. } => mv.line,
            MachineBlock::Aux { line, .. }
            | MachineBlock::TcpMove { line, .. }
            | MachineBlock::Synced { line, .. }
            | MachineBlock::End { line }
            | MachineBlock::Error { line, .. } => *line,
            MachineBlock::MdiDone => 0,
        }
    }
}

/// What the interpreter sends to tool compensation: the program's own coordinates (current
/// work coordinate system, program units) with the offsets as they change.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ProgramBlock {
    /// Length units (mm per unit).
    Units(f64),
    /// Active G54.. offset (program units).
    WorkOffset([f64; AXES]),
    /// G92 offset.
    G92Offset([f64; AXES]),
    /// XY rotation of the work system, degrees.
    Rotation(f64),
    /// Tool length offset.
    ToolOffset([f64; AXES]),
    /// Feed for the following feed moves.
    FeedRate {
        /// Units per minute (per revolution in G95).
        rate: f64,
        /// G95.
        per_revolution: bool,
    },
    /// Path mode of the following moves.
    PathMode(rtcnc_motion::PathMode),
    /// M428 (true) / M429: the following lines are tool-tip moves of the machine's
    /// five-axis kinematics.
    ToolCentrePoint(bool),
    /// Straight move to `end` (program coordinates).
    Line {
        /// Line.
        line: u32,
        /// End.
        end: [f64; AXES],
        /// G0.
        rapid: bool,
    },
    /// Arc: end, centre and normal in program coordinates.
    Arc {
        /// Line.
        line: u32,
        /// End.
        end: [f64; AXES],
        /// Centre (X Y Z).
        centre: [f64; 3],
        /// Normal of the plane (right hand: counter-clockwise).
        normal: [f64; 3],
        /// Extra turns.
        turns: u32,
        /// Largest difference of the end radius from the start radius the interpreter
        /// accepts (program units).
        radius_tolerance: f64,
    },
    /// G33/G76: the following feed move advances `pitch` (program units) per spindle
    /// revolution, position-synchronised; `None` ends it.
    SpindleSync(Option<f64>),
    /// The next spindle-synchronised line chains into the one after it (no stop, no new
    /// index between them).
    SyncChained,
    /// G33.1 rigid tapping to `end` and back (program coordinates), at the pitch of the
    /// `SpindleSync` before it; the spindle's speed times `scale` on the way out.
    RigidTap {
        /// Line.
        line: u32,
        /// Bottom of the hole.
        end: [f64; AXES],
        /// I word.
        scale: f64,
    },
    /// G38.x straight probe to `end` (program coordinates).
    Probe {
        /// Line.
        line: u32,
        /// End.
        end: [f64; AXES],
        /// Which G38.
        kind: rtcnc_gcode::canon::ProbeKind,
    },
    /// Spline (G5, G5.1): end and Bézier control points in program coordinates.
    Spline {
        /// Line.
        line: u32,
        /// End.
        end: [f64; AXES],
        /// Inner control points (all nine axes).
        control: rtcnc_motion::Bezier,
    },
    /// Dwell, seconds.
    Dwell {
        /// Line.
        line: u32,
        /// Seconds.
        seconds: f64,
    },
    /// A machine function.
    Aux {
        /// Line.
        line: u32,
        /// What.
        aux: Aux,
    },
    /// End of program.
    End {
        /// Line.
        line: u32,
    },
    /// Error at a line.
    Error {
        /// Line.
        line: u32,
        /// Code.
        code: crate::FaultCode,
    },
    /// An MDI line has been interpreted.
    MdiDone,
}

/// One servo period's set-points of every joint, with the axis position they come from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointSetpoints {
    /// Servo cycle the set-point is for.
    pub cycle: u64,
    /// Joint positions.
    pub joints: [f64; MAX_JOINTS],
    /// Axis positions (X..W).
    pub axes: [f64; AXES],
    /// Program line being executed (0: none).
    pub line: u32,
    /// Path speed (units/s).
    pub path_speed: f64,
    /// Where the executing program or MDI line ends (axes, machine coordinates); equal to
    /// `axes` in manual motion.
    pub move_end: [f64; AXES],
}

/// What the status snapshot says the machine is doing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum MachineState {
    /// Power-up: self-test not finished.
    #[default]
    Starting,
    /// E-stop (or after power-up): drives disabled; needs a reset.
    EStop,
    /// Ready for a command.
    Idle,
    /// Moving (program, MDI, jog, homing).
    Running,
    /// Feed hold (decelerating or stopped on the path).
    Held,
    /// Program paused at M0/M1/single block; Resume continues.
    Paused,
    /// Waiting for the machine logic to acknowledge an M/S/T function.
    WaitingForLogic,
    /// A fault stopped the machine; needs a reset.
    Fault,
}

impl MachineState {
    /// Lower-case name.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn as_str(self) -> &'static str {
        match self {
            MachineState::Starting => "starting",
            MachineState::EStop => "estop",
            MachineState::Idle => "idle",
            MachineState::Running => "running",
            MachineState::Held => "held",
            MachineState::Paused => "paused",
            MachineState::WaitingForLogic => "waiting for logic",
            MachineState::Fault => "fault",
        }
    }
}

impl Status {
    /// The state as the operator is told it: the hold's message while held ("held: machine
    /// logic requests a feed hold (door open?)"), the state's name otherwise.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn state_text(&self) -> &'static str {
        match (self.state, self.hold) {
            (MachineState::Held, Some(cause)) => cause.message(),
            (state, _) => state.as_str(),
        }
    }
}

/// What holds the machine while its state is [`MachineState::Held`]: the first thing the
/// operator must clear for it to go on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HoldCause {
    /// The machine logic asks for a feed hold (the door open, a fault of the machine, the
    /// spindle not at speed); a resume is refused while it does. A program started while
    /// it asked goes on by itself when the request falls; a hold it latched on a moving
    /// path waits for a resume after.
    MachineLogic,
    /// The feed stop switch (M53) is on: the path goes on when it is released.
    FeedStopSwitch,
    /// A feed hold (the operator's, or one the machine logic or a deadline miss latched)
    /// waits for a resume.
    Resume,
}

impl HoldCause {
    /// Stable lower-case name.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn as_str(self) -> &'static str {
        match self {
            HoldCause::MachineLogic => "machine_logic",
            HoldCause::FeedStopSwitch => "feed_stop_switch",
            HoldCause::Resume => "resume",
        }
    }

    /// What the operator is told.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn message(self) -> &'static str {
        match self {
            HoldCause::MachineLogic => "held: machine logic requests a feed hold (door open?)",
            HoldCause::FeedStopSwitch => "held: the feed stop switch is on",
            HoldCause::Resume => "held: feed hold, resume to go on",
        }
    }
}

/// The feedback snapshot, published every servo cycle.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Status {
    /// Servo cycles run.
    pub cycle: u64,
    /// Time of the snapshot (ns since start).
    pub time_ns: u64,
    /// State.
    pub state: MachineState,
    /// What holds the machine while `state` is [`MachineState::Held`] (`None` otherwise).
    pub hold: Option<HoldCause>,
    /// Mode.
    pub mode: Mode,
    /// Program line being executed.
    pub line: u32,
    /// Axis set-point (X..W).
    pub axes: [f64; AXES],
    /// Joint set-points.
    pub joint_setpoints: [f64; MAX_JOINTS],
    /// Joint feedback positions.
    pub joint_feedback: [f64; MAX_JOINTS],
    /// Path speed, units/s.
    pub path_speed: f64,
    /// Distance to go per axis: from the set-point to the end of the executing line.
    pub distance_to_go: [f64; AXES],
    /// Feed override.
    pub feed_override: f64,
    /// Bit n: joint n is homed.
    pub homed: u32,
    /// Faults raised so far.
    pub fault_count: u32,
    /// The last fault.
    pub last_fault: Option<crate::Fault>,
    /// The program reached its end.
    pub program_ended: bool,
    /// Tool in the spindle.
    pub tool: u32,
    /// Spindle speed, rpm (measured).
    pub spindle_rpm: f64,
    /// Spindle speed commanded (after the override and G96), rpm; 0 while off.
    pub spindle_command_rpm: f64,
    /// The self-test passed and every drive is enabled.
    pub ready: bool,
    /// The planner's geometry counters since start-up (moves, G64 Q merges, blends,
    /// smoothed vertices, exact stops).
    pub geometry: rtcnc_motion::GeometryStats,
}
