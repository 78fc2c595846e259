//! What the kernel's tasks share: the channels between stages and the plain-data images
//! written by one task each and read by others (feedback image, the two halves of the
//! machine interface, status), which are single-writer snapshots: no task waits for
//! another to read or write them.

use rtcnc_rt::{BinarySemaphore, Context, Mailbox, PiMutex, SeqlockReader, SeqlockWriter, seqlock};

use crate::config::MAX_JOINTS;
use crate::fault::{Fault, FaultCode, TaskName};
use crate::messages::{
    Command, FixedText, MachineBlock, MachineResult, OperatorMessage, ProgramBlock, Status, Urgent,
};

/// A pipeline message tagged with the program run it belongs to, so that an abort can drop
/// whatever of an old run is still in the channels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tagged<T> {
    /// Program run.
    pub epoch: u32,
    /// The message.
    pub block: T,
}

/// What the command parser asks of the interpreter.
// Plain data with a fixed size (no Box): the MDI line is carried inline.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum InterpreterRequest {
    /// Run the loaded program.
    Run {
        /// Program run.
        epoch: u32,
    },
    /// Interpret one MDI line.
    Mdi {
        /// Program run.
        epoch: u32,
        /// The line.
        line: FixedText,
    },
    /// Stop reading.
    Stop,
    /// Block delete setting for the next run.
    BlockDelete(bool),
    /// Load the program at this path (the next `Run` reads it).
    Open(FixedText),
    /// Read the tool table file again.
    ReloadToolTable,
}

/// The feedback image, published by drive I/O after every exchange (raw joint positions,
/// before homing offsets).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Feedback {
    /// Exchanges done.
    pub cycle: u64,
    /// Raw joint positions.
    pub position: [f64; MAX_JOINTS],
    /// Joint velocities.
    pub velocity: [f64; MAX_JOINTS],
    /// Bit n: negative limit switch of joint n.
    pub negative_limit: u32,
    /// Bit n: positive limit switch of joint n.
    pub positive_limit: u32,
    /// Bit n: home switch of joint n.
    pub home_switch: u32,
    /// Bit n: the latch of joint n has caught its edge.
    pub latched: u32,
    /// Latched raw positions.
    pub latch_position: [f64; MAX_JOINTS],
    /// Bit n: drive n is in operation enabled.
    pub enabled: u32,
    /// Bit n: drive n is faulted.
    pub faulted: u32,
    /// The e-stop input.
    pub estop: bool,
    /// The exchange failed (the bus lost, a device out of OP, frames lost beyond the
    /// bus's limit): every input here is the last one received, not what the devices
    /// report now.
    pub exchange_failed: bool,
    /// Handwheel counter.
    pub handwheel_counts: i64,
    /// Spindle speed, rpm.
    pub spindle_rpm: f64,
    /// Spindle at speed.
    pub spindle_at_speed: bool,
    /// Spindle angle from its index, degrees.
    pub spindle_angle_deg: f64,
    /// The spindle is oriented (M19).
    pub spindle_oriented: bool,
    /// Tool in the spindle.
    pub tool: u32,
    /// Tool change finished (held until the request drops).
    pub tool_change_done: bool,
    /// Digital inputs, bit n = input n (first 64).
    pub digital_inputs: u64,
    /// Analogue inputs (first 16).
    pub analog_inputs: [f64; crate::config::MAX_PROGRAM_IO],
}

/// The kernel's half of the machine interface (the PLC's signals): what the motion core asks
/// of the machine logic. Written by the motion core's tasks (one at a time, under the core's
/// lock), read by the logic and drive I/O.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LogicRequests {
    /// Spindle commanded on.
    pub spindle_on: bool,
    /// Counter-clockwise.
    pub spindle_reverse: bool,
    /// Commanded speed after the override, rpm.
    pub spindle_rpm: f64,
    /// M7.
    pub mist: bool,
    /// M8.
    pub flood: bool,
    /// M6 requested.
    pub tool_change_request: bool,
    /// Tool to load.
    pub tool_number: u32,
    /// M100..M199 requested.
    pub m_code_request: bool,
    /// The code.
    pub m_code: u16,
    /// P.
    pub m_p: f64,
    /// Q.
    pub m_q: f64,
    /// A program runs.
    pub program_running: bool,
    /// Every joint homed.
    pub homed: bool,
    /// Operator resets so far: the logic gives its `estop_reset` signal for a while after
    /// each change.
    pub reset_count: u32,
    /// The operator asked for the machine to be on (from a reset until an e-stop or fault).
    pub machine_on_request: bool,
    /// M19: orient the spindle (to the machine directly; the logic does not see it).
    pub spindle_orient: bool,
    /// Its angle, degrees.
    pub spindle_orient_angle: f64,
    /// Its mode: 0 shorter way, 1 clockwise, 2 counter-clockwise.
    pub spindle_orient_mode: u8,
}

/// The machine logic's half of the machine interface: its answers to the kernel and its
/// outputs to the machine. Written by the logic task only.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LogicOutputs {
    /// Spindle at speed.
    pub spindle_at_speed: bool,
    /// Tool change done.
    pub tool_change_done: bool,
    /// User M code done.
    pub m_code_done: bool,
    /// The logic asks for a feed hold.
    pub feed_hold_request: bool,
    /// The logic reports a machine fault.
    pub machine_fault: bool,
    /// The logic's e-stop chain is closed (motion allowed).
    pub estop_chain_ok: bool,
    /// Its code.
    pub machine_fault_code: i64,
    /// Spindle drive enabled.
    pub out_spindle_enable: bool,
    /// Signed spindle speed set-point.
    pub out_spindle_rpm: f64,
    /// Mist valve.
    pub out_mist: bool,
    /// Flood pump.
    pub out_flood: bool,
    /// Tool changer start.
    pub out_tool_start: bool,
    /// Tool changer target.
    pub out_tool_number: u32,
    /// Digital outputs, bit n = output n.
    pub out_digital: u64,
    /// The set-points of the PLC's auxiliary axes for their joints.
    pub plc_axes: PlcAxisSetpoints,
}

/// The PLC's auxiliary axes as the machine-logic task left them: for each, its joint's
/// set-point in the drive's units, with the velocity and acceleration to carry it on
/// until the next update.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PlcAxisSetpoints {
    /// Time of the values, ns (the logic task's release).
    pub time_ns: u64,
    /// Entries in use.
    pub count: u8,
    /// The joint of each entry.
    pub joint: [u8; crate::config::MAX_PLC_AXES],
    /// MC_Power asks for the drive (bit n: entry n).
    pub power: u8,
    /// Set-point positions.
    pub position: [f64; crate::config::MAX_PLC_AXES],
    /// Set-point velocities.
    pub velocity: [f64; crate::config::MAX_PLC_AXES],
    /// Set-point accelerations.
    pub acceleration: [f64; crate::config::MAX_PLC_AXES],
}

impl PlcAxisSetpoints {
    /// The set-point of entry `i` at time `now_ns`, carried on from the values at
    /// `time_ns` (at most 100 ms, and no further than a braking axis comes to rest).
    ///
    /// Real-time: yes (arithmetic only).
    pub fn at(&self, i: usize, now_ns: u64) -> f64 {
        let (p, v, a) = (self.position[i], self.velocity[i], self.acceleration[i]);
        let mut dt = (now_ns.saturating_sub(self.time_ns) as f64 * 1e-9).min(0.1);
        if a * v < 0.0 {
            dt = dt.min(-v / a);
        }
        p + v * dt + 0.5 * a * dt * dt
    }
}

/// The newest value of a snapshot channel as one real-time reader last got it, copied only
/// when there is a newer one: when the writer is in the middle of a write on another
/// processor, the reader goes on with the value it has rather than waiting.
pub(crate) type Snapshot<T> = rtcnc_rt::SeqlockCopy<T>;

/// The writing ends of the shared state images, each handed to its one writer.
pub(crate) struct Writers {
    pub(crate) feedback: SeqlockWriter<Feedback>,
    pub(crate) requests: SeqlockWriter<LogicRequests>,
    pub(crate) logic_outputs: SeqlockWriter<LogicOutputs>,
    pub(crate) status: SeqlockWriter<Status>,
}

/// Everything the tasks share. Built once; cloned handles go into the task closures.
#[derive(Clone)]
pub struct Shared {
    /// Operator: urgent commands.
    pub urgent: Mailbox<Urgent>,
    /// Operator: normal commands.
    pub normal: Mailbox<Command>,
    /// Command parser -> interpreter.
    pub interpreter_requests: Mailbox<InterpreterRequest>,
    /// Wakes the interpreter.
    pub interpreter_wake: BinarySemaphore,
    /// Interpreter -> tool compensation.
    pub program_blocks: Mailbox<Tagged<ProgramBlock>>,
    /// Tool compensation -> look-ahead.
    pub machine_blocks: Mailbox<Tagged<MachineBlock>>,
    /// Interpreter -> look-ahead: the texts of operator messages, by sequence number, in
    /// the order of their `Aux::Message` blocks.
    pub message_texts: Mailbox<(u32, FixedText)>,
    /// Operator messages as the machine reached them, for the operator.
    pub operator_messages: Mailbox<OperatorMessage>,
    /// Look-ahead -> interpreter: what the machine measured for a block the interpreter
    /// waits on (M66's input value for #5399), tagged with the run.
    pub machine_results: Mailbox<Tagged<MachineResult>>,
    /// Faults for the operator and the log.
    pub faults: Mailbox<Fault>,
    /// Faults that must stop motion, for the interpolation task (read first every cycle).
    pub stop_requests: Mailbox<Fault>,
    /// The feedback image (written by drive I/O every exchange).
    pub feedback: SeqlockReader<Feedback>,
    /// The kernel's requests to the machine logic.
    pub requests: SeqlockReader<LogicRequests>,
    /// The machine logic's answers and outputs.
    pub logic_outputs: SeqlockReader<LogicOutputs>,
    /// The status snapshot (written by the status task every period).
    pub status: SeqlockReader<Status>,
    /// The last interpreter error in words (non-real-time side only).
    pub error_text: std::sync::Arc<PiMutex<Option<String>>>,
    /// Faults raised so far (for the status snapshot).
    pub fault_count: std::sync::Arc<std::sync::atomic::AtomicU32>,
    /// The most exchanges with the drives between two runs of interpolation since
    /// start-up (1 when it never stalled): the longest stall the set-point lead had to
    /// ride through, in servo periods.
    pub interpolation_gap: std::sync::Arc<std::sync::atomic::AtomicU64>,
    /// The last move the planner refused (moved in, not formatted, by the look-ahead).
    pub motion_error: std::sync::Arc<PiMutex<Option<rtcnc_motion::MotionError>>>,
    /// The PLC's last run-time fault (its code, POU and line), for the operator; put here
    /// by the machine-logic task (a clone of the PLC's record: no allocation).
    pub plc_fault: std::sync::Arc<PiMutex<Option<rtcnc_plc::Fault>>>,
    /// The fieldbus's reason for its last communication fault (a device's name, state and
    /// AL status code, the working counter), for the operator; put here by drive I/O.
    pub fieldbus_error: std::sync::Arc<PiMutex<Option<rtcnc_fieldbus::FieldbusError>>>,
}

impl Shared {
    pub(crate) fn new() -> (Shared, Writers) {
        let (feedback_w, feedback) = seqlock("feedback image", Feedback::default());
        let (requests_w, requests) = seqlock("logic requests", LogicRequests::default());
        let (outputs_w, logic_outputs) = seqlock("logic outputs", LogicOutputs::default());
        let (status_w, status) = seqlock("status", Status::default());
        let writers = Writers {
            feedback: feedback_w,
            requests: requests_w,
            logic_outputs: outputs_w,
            status: status_w,
        };
        let shared = Shared {
            urgent: Mailbox::new("urgent commands", 32).expect("capacity > 0"),
            normal: Mailbox::new("normal commands", 64).expect("capacity > 0"),
            interpreter_requests: Mailbox::new("interpreter requests", 8).expect("capacity > 0"),
            interpreter_wake: BinarySemaphore::new("interpreter wake"),
            program_blocks: Mailbox::new("program blocks", 128).expect("capacity > 0"),
            machine_blocks: Mailbox::new("machine blocks", 128).expect("capacity > 0"),
            message_texts: Mailbox::new("message texts", 32).expect("capacity > 0"),
            operator_messages: Mailbox::new("operator messages", 1024).expect("capacity > 0"),
            machine_results: Mailbox::new("machine results", 8).expect("capacity > 0"),
            faults: Mailbox::new("faults", 1024).expect("capacity > 0"),
            stop_requests: Mailbox::new("stop requests", 64).expect("capacity > 0"),
            feedback,
            requests,
            logic_outputs,
            status,
            error_text: std::sync::Arc::new(PiMutex::new(None)),
            motion_error: std::sync::Arc::new(PiMutex::new(None)),
            plc_fault: std::sync::Arc::new(PiMutex::new(None)),
            fieldbus_error: std::sync::Arc::new(PiMutex::new(None)),
            fault_count: std::sync::Arc::new(std::sync::atomic::AtomicU32::new(0)),
            interpolation_gap: std::sync::Arc::new(std::sync::atomic::AtomicU64::new(0)),
        };
        (shared, writers)
    }

    /// Records a fault: the fault channel, the executive's fault log and trace, and (when it
    /// stops the machine) the interpolation's stop channel. Real-time safe.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn raise(
        &self,
        ctx: &mut Context<'_>,
        code: FaultCode,
        task: TaskName,
        joint: Option<u8>,
        line: u32,
        value: f64,
    ) -> Fault {
        let fault = Fault {
            code,
            time_ns: ctx.now().as_nanos(),
            task,
            joint,
            line,
            value,
        };
        ctx.raise_fault(
            code.number(),
            code.message(),
            joint.map_or(u64::from(line), u64::from),
        );
        self.fault_count
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let _ = self.faults.try_put(fault);
        if code.stops_machine() {
            let _ = self.stop_requests.try_put(fault);
        }
        fault
    }
}
