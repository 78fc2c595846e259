//! The process image: what the controller writes to the machine each cycle
//! ([`ProcessOutputs`]) and what it reads back ([`ProcessInputs`]). Both are sized once from
//! a [`ProcessLayout`] and then rewritten in place, so a cycle allocates nothing.

use serde::Deserialize;

use crate::cia402::{Cia402State, ControlWord, StatusWord};

/// How a joint's drive is commanded (CiA 402 modes of operation, object 0x6060, plus an
/// ideal drive for benchmark machines).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DriveMode {
    /// The drive follows [`JointCommand::target_velocity`] with its own velocity loop; the
    /// controller closes the position loop (an analogue drive behind a DAC, or cyclic
    /// synchronous velocity).
    Velocity,
    /// Cyclic synchronous position: the drive closes position and velocity loops on
    /// [`JointCommand::target_position`] plus the velocity and torque offsets.
    Csp,
    /// Cyclic synchronous torque: the drive applies [`JointCommand::target_torque`] plus the
    /// torque offset (an analogue torque amplifier).
    Torque,
    /// The position follows [`JointCommand::target_position`] exactly and at once.
    Ideal,
}

impl DriveMode {
    /// Whether the controller sends positions (CSP, ideal) rather than closing the loop.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub const fn takes_position(self) -> bool {
        matches!(self, Self::Csp | Self::Ideal)
    }
}

/// What a drive latches, like the touch-probe function of CiA 402 (object 0x60B8).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LatchSource {
    /// The encoder's index (zero) pulse.
    IndexPulse,
    /// Either edge of the home switch.
    HomeSwitch,
    /// The drive's touch-probe input (0x60B8 touch probe 1 on its external input), on the
    /// rising edge (the probe closes) or the falling edge (it opens). The position at the
    /// edge's instant comes back as the latch (0x60BA rising, 0x60BB falling), some time
    /// after the edge (the drive's own latency).
    TouchProbe {
        /// Latch on the rising edge, else on the falling one.
        rising: bool,
    },
}

/// One joint's part of the outputs (the drive's RxPDO).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct JointCommand {
    /// The controlword (0x6040): walks the drive's state machine.
    pub controlword: ControlWord,
    /// Target position (units), in [`DriveMode::Csp`] and [`DriveMode::Ideal`] (0x607A).
    pub target_position: f64,
    /// Target velocity (units/s), in [`DriveMode::Velocity`] (0x60FF).
    pub target_velocity: f64,
    /// Target torque (N·m), in [`DriveMode::Torque`] (0x6071).
    pub target_torque: f64,
    /// Velocity feed-forward added by a CSP drive (units/s, 0x60B1).
    pub velocity_offset: f64,
    /// Torque feed-forward added in CSP and torque modes (N·m, 0x60B2).
    pub torque_offset: f64,
    /// Arms the position latch while `Some`; a change from `None` re-arms it.
    pub latch: Option<LatchSource>,
}

/// The position latch of one joint.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LatchFeedback {
    /// The latch is armed and waiting.
    pub armed: bool,
    /// The event happened since arming; `position` holds where.
    pub latched: bool,
    /// The latched position (units), quantised to encoder counts.
    pub position: f64,
}

/// One joint's part of the inputs (the drive's TxPDO and the joint's switches).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct JointFeedback {
    /// The statusword (0x6041).
    pub statusword: StatusWord,
    /// The error code (0x603F); 0 when there is none.
    pub error_code: u16,
    /// Position (units): encoder counts times the scale.
    pub position: f64,
    /// Raw encoder counts.
    pub position_counts: i64,
    /// Velocity (units/s): counts moved in the last cycle over the period.
    pub velocity: f64,
    /// Torque the drive applies (N·m).
    pub torque: f64,
    /// Negative hard-limit switch.
    pub negative_limit: bool,
    /// Positive hard-limit switch.
    pub positive_limit: bool,
    /// Home switch.
    pub home_switch: bool,
    /// The position latch.
    pub latch: LatchFeedback,
}

impl JointFeedback {
    /// The drive's CiA 402 state, decoded from the statusword.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub const fn state(&self) -> Cia402State {
        self.statusword.state()
    }
}

/// Spindle outputs.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SpindleCommand {
    /// Run the spindle.
    pub enable: bool,
    /// Speed (rev/min); the sign gives the direction (positive: M3, clockwise).
    pub speed_rpm: f64,
    /// Orient (M19): stop, then turn to `orient_angle_deg` and hold there (overrides
    /// `enable` and `speed_rpm` while on).
    pub orient: bool,
    /// Orientation angle, degrees from the index (0 ≤ angle < 360).
    pub orient_angle_deg: f64,
    /// How to get there: 0 the shorter way, 1 always clockwise (the M3 direction), 2
    /// always counter-clockwise (LinuxCNC's `orient` modes).
    pub orient_mode: u8,
}

/// Spindle inputs.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SpindleFeedback {
    /// Measured speed (rev/min), signed.
    pub speed_rpm: f64,
    /// The speed is within the configured tolerance of the command.
    pub at_speed: bool,
    /// Angle from the index, degrees (0 ≤ angle < 360; clockwise positive).
    pub position_deg: f64,
    /// Orienting and standing within the orientation tolerance of the angle.
    pub oriented: bool,
}

/// Coolant outputs (M7, M8, M9), and the pumps' state as inputs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Coolant {
    /// Mist (M7).
    pub mist: bool,
    /// Flood (M8).
    pub flood: bool,
}

/// Tool-changer outputs: a change to `tool` starts on the rising edge of `start`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ToolChangeCommand {
    /// The tool to put in the spindle.
    pub tool: u32,
    /// Request; keep it high until `done`, then drop it.
    pub start: bool,
}

/// Tool-changer inputs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ToolChangerFeedback {
    /// The tool in the spindle (0: none).
    pub current_tool: u32,
    /// A change is under way.
    pub busy: bool,
    /// The requested change is complete (until `start` drops).
    pub done: bool,
}

/// The shape of a machine's process image.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct ProcessLayout {
    /// Drive mode of each joint, in joint order.
    pub joints: Vec<DriveMode>,
    /// Number of digital inputs.
    pub digital_inputs: usize,
    /// Number of digital outputs.
    pub digital_outputs: usize,
    /// Number of analogue inputs.
    pub analog_inputs: usize,
    /// Number of analogue outputs.
    pub analog_outputs: usize,
}

/// Everything the controller writes in one cycle.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ProcessOutputs {
    /// One command per joint.
    pub joints: Vec<JointCommand>,
    /// Digital outputs.
    pub digital: Vec<bool>,
    /// Analogue outputs (volts, or the unit the module uses).
    pub analog: Vec<f64>,
    /// Spindle.
    pub spindle: SpindleCommand,
    /// Coolant.
    pub coolant: Coolant,
    /// Tool changer.
    pub tool_changer: ToolChangeCommand,
}

impl ProcessOutputs {
    /// All-zero outputs (drives commanded to "disable voltage") shaped by `layout`.
    ///
    /// Real-time: no (set-up: allocates the image).
    pub fn new(layout: &ProcessLayout) -> Self {
        Self {
            joints: vec![JointCommand::default(); layout.joints.len()],
            digital: vec![false; layout.digital_outputs],
            analog: vec![0.0; layout.analog_outputs],
            ..Self::default()
        }
    }
}

/// Everything the controller reads in one cycle.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ProcessInputs {
    /// One feedback per joint.
    pub joints: Vec<JointFeedback>,
    /// Digital inputs.
    pub digital: Vec<bool>,
    /// Analogue inputs.
    pub analog: Vec<f64>,
    /// The emergency-stop chain is open (button pressed or chain broken).
    pub estop_active: bool,
    /// The handwheel (MPG) counter: detents turned since power-up, wrapping.
    pub handwheel_counts: i64,
    /// Spindle.
    pub spindle: SpindleFeedback,
    /// Coolant pumps running.
    pub coolant: Coolant,
    /// Tool changer.
    pub tool_changer: ToolChangerFeedback,
}

impl ProcessInputs {
    /// All-zero inputs shaped by `layout`.
    ///
    /// Real-time: no (set-up: allocates the image).
    pub fn new(layout: &ProcessLayout) -> Self {
        Self {
            joints: vec![JointFeedback::default(); layout.joints.len()],
            digital: vec![false; layout.digital_inputs],
            analog: vec![0.0; layout.analog_inputs],
            ..Self::default()
        }
    }
}
