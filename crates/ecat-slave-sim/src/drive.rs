//! A CiA 402 servo drive in cyclic synchronous position mode (mode 8), its motor and load
//! being the simulated joint of `rtcnc-fieldbus`: the drive's object dictionary (CiA 301
//! communication objects, CiA 402 objects, PDO mapping and assignment), the process data
//! in its current mapping, and the drive's behaviour on every cycle.
//!
//! Units on the wire are those of a real drive: positions in encoder increments, velocity
//! in increments per second, torque in thousandths of the rated torque (0x6076).

use std::any::Any;

use rtcnc_fieldbus::sim::{
    InjectedFault, SimulatedJointConfig, SimulatedMachine, SimulatedMachineConfig,
};
use rtcnc_fieldbus::{
    Cia402State, ControlWord, DeviceCommand, DriveMode, Fieldbus, JointCommand, LatchSource,
    ProcessInputs, ProcessOutputs,
};
use serde::Deserialize;

use crate::application::{Application, TransitionContext};
use crate::dictionary::{Access, Dictionary, Mapping, abort};
use crate::esc::{AlState, al_code};
use crate::sii::{
    FmmuUse, Identity, MailboxLayout, PROTOCOL_COE, Pdo, PdoEntry, SiiContents, SyncManagerDefault,
    SyncManagerUse,
};
use crate::touch_probe::{TouchProbe, Trigger};

/// Mode of operation "cyclic synchronous position" (0x6060).
pub const MODE_CSP: i8 = 8;
/// Error code of a following error beyond the window (0x603F).
pub const ERROR_FOLLOWING: u16 = 0x8611;
/// Largest number of entries in one mapping object.
const MAX_MAPPED: u8 = 8;
/// Largest process data in one direction (bytes).
const MAX_PDO_BYTES: usize = 64;

/// Physical addresses of the drive's sync managers.
const MAILBOX_OUT: u16 = 0x1000;
const MAILBOX_IN: u16 = 0x1080;
const MAILBOX_SIZE: u16 = 128;
const OUTPUTS: u16 = 0x1100;
const INPUTS: u16 = 0x1180;

/// CANopen data type codes (CiA 301 Table 44).
mod data_type {
    pub const INTEGER16: u8 = 0x03;
    pub const INTEGER32: u8 = 0x04;
    pub const UNSIGNED16: u8 = 0x06;
    pub const UNSIGNED32: u8 = 0x07;
}

/// One simulated drive's configuration.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriveConfig {
    /// Identity in the EEPROM and object 0x1018.
    #[serde(default = "default_drive_identity")]
    pub identity: Identity,
    /// Device name (EEPROM and object 0x1008).
    #[serde(default = "default_drive_name")]
    pub name: String,
    /// Rated torque of the motor (mN·m, object 0x6076): the unit of torque offsets.
    #[serde(default = "default_rated_torque")]
    pub rated_torque_mnm: u32,
    /// The motor, load, encoder and switches (`rtcnc-fieldbus`'s simulated joint; the
    /// drive mode is CSP whatever `drive` says). Its `index_offset` places the encoder's
    /// zero impulse for the touch probe.
    #[serde(default = "default_joint")]
    pub joint: SimulatedJointConfig,
    /// Time from a touch probe's edge to the drive reporting the value it latched (s),
    /// as a drive's latch-to-PDO delay; default 0.001.
    #[serde(default = "default_touch_probe_latency")]
    pub touch_probe_latency_s: f64,
}

impl Default for DriveConfig {
    fn default() -> Self {
        Self {
            identity: default_drive_identity(),
            name: default_drive_name(),
            rated_torque_mnm: default_rated_torque(),
            joint: default_joint(),
            touch_probe_latency_s: default_touch_probe_latency(),
        }
    }
}

/// The simulator's made-up vendor ID (not one the ETG assigned to a real vendor we know of).
pub const SIMULATOR_VENDOR_ID: u32 = 0x0000_0E5C;
/// Product code of the simulated CSP drive.
pub const DRIVE_PRODUCT_CODE: u32 = 0x0000_0402;

fn default_drive_identity() -> Identity {
    Identity {
        vendor_id: SIMULATOR_VENDOR_ID,
        product_code: DRIVE_PRODUCT_CODE,
        revision: 0x0001_0000,
        serial: 0,
    }
}

fn default_drive_name() -> String {
    "rtcnc sim CSP drive".into()
}

fn default_rated_torque() -> u32 {
    1270
}

fn default_touch_probe_latency() -> f64 {
    0.001
}

fn default_joint() -> SimulatedJointConfig {
    SimulatedJointConfig::with_drive(DriveMode::Csp)
}

/// Where one mapped object sits in the process data.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Mapped {
    index: u16,
    sub_index: u8,
    offset: usize,
    len: usize,
}

/// The load's true position over one cycle, from its start to its end (system time, ns).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CycleMotion {
    /// System time at the cycle's start.
    pub start_ns: u64,
    /// System time at its end.
    pub end_ns: u64,
    /// True position at the start (joint units).
    pub from: f64,
    /// True position at the end.
    pub to: f64,
}

/// Cycles of motion a drive keeps (to place an edge reported a few cycles late).
const MOTION_HISTORY: usize = 16;

/// The load's last cycles of motion, a ring: `count` of them filled, the newest before
/// `next`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct MotionHistory {
    cycles: [CycleMotion; MOTION_HISTORY],
    next: usize,
    count: usize,
}

impl MotionHistory {
    fn new() -> Self {
        Self {
            cycles: [CycleMotion::default(); MOTION_HISTORY],
            next: 0,
            count: 0,
        }
    }

    fn record(&mut self, motion: CycleMotion) {
        self.cycles[self.next] = motion;
        self.next = (self.next + 1) % MOTION_HISTORY;
        self.count = (self.count + 1).min(MOTION_HISTORY);
    }

    /// Oldest first.
    fn iter(&self) -> impl Iterator<Item = CycleMotion> + '_ {
        (0..self.count).map(move |age| {
            self.cycles[(self.next + MOTION_HISTORY - self.count + age) % MOTION_HISTORY]
        })
    }

    /// The load's position at system time `at_ns`, if a recorded cycle holds that instant
    /// (taken to move linearly within a cycle).
    fn position_at(&self, at_ns: u64) -> Option<f64> {
        let m = self
            .iter()
            .find(|m| m.start_ns <= at_ns && at_ns <= m.end_ns && m.end_ns > m.start_ns)?;
        let share = (at_ns - m.start_ns) as f64 / (m.end_ns - m.start_ns) as f64;
        Some(m.from + share * (m.to - m.from))
    }
}

/// The encoder increments of a load at `position` with the joint's quantisation.
fn encoder_counts(joint: &SimulatedJointConfig, position: f64) -> i32 {
    // `as` saturates and maps NaN to 0: no panic on any state.
    (position / joint.units_per_revolution * f64::from(joint.encoder_counts_per_revolution)).floor()
        as i32
}

/// A CiA 402 drive whose motor is a simulated joint.
pub struct CspDrive {
    config: DriveConfig,
    machine: SimulatedMachine,
    outputs: ProcessOutputs,
    feedback: ProcessInputs,
    dictionary: Dictionary,
    rx_layout: Vec<Mapped>,
    tx_layout: Vec<Mapped>,
    counts_per_unit: f64,
    injected_fault: Option<u16>,
    following_fault: bool,
    fault_reset_was_high: bool,
    touch_probe: TouchProbe,
    /// The system time at which the coming cycle starts.
    cycle_start_ns: u64,
    motion: MotionHistory,
    /// The index latch was caught last cycle: the joint's latch is re-armed (a cycle without
    /// the request) before a continuous probe takes the next pulse.
    index_rearm: bool,
}

impl std::fmt::Debug for CspDrive {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CspDrive")
            .field("name", &self.config.name)
            .finish_non_exhaustive()
    }
}

/// Why a drive could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("drive configuration: {0}")]
pub struct DriveConfigError(pub String);

impl CspDrive {
    /// A drive at power-up.
    pub fn new(config: &DriveConfig) -> Result<Self, DriveConfigError> {
        let mut joint = config.joint.clone();
        joint.drive = DriveMode::Csp;
        let mut machine_config: SimulatedMachineConfig = SimulatedMachineConfig {
            substep_s: 62.5e-6,
            communication_watchdog_s: 0.1,
            command_delay_s: 0.0,
            touch_probe_latency_s: 0.001,
            estop_removes_power: false,
            joints: vec![joint],
            spindle: Default::default(),
            tool_changer: Default::default(),
            io: Default::default(),
            devices: Vec::new(),
        };
        machine_config.io.digital_inputs = 0;
        machine_config.io.digital_outputs = 0;
        machine_config.io.analog_inputs = 0;
        machine_config.io.analog_outputs = 0;
        let machine = SimulatedMachine::new(&machine_config)
            .map_err(|error| DriveConfigError(error.within("joint").to_string()))?;
        let outputs = ProcessOutputs::new(machine.layout());
        let feedback = ProcessInputs::new(machine.layout());
        let counts_per_unit = f64::from(config.joint.encoder_counts_per_revolution)
            / config.joint.units_per_revolution;
        if !(config.touch_probe_latency_s.is_finite()
            && (0.0..=0.1).contains(&config.touch_probe_latency_s))
        {
            return Err(DriveConfigError(
                "touch_probe_latency_s: must be from 0 to 0.1 s".into(),
            ));
        }
        let mut drive = Self {
            config: config.clone(),
            machine,
            outputs,
            feedback,
            dictionary: Dictionary::new(),
            rx_layout: Vec::new(),
            tx_layout: Vec::new(),
            counts_per_unit,
            injected_fault: None,
            following_fault: false,
            fault_reset_was_high: false,
            touch_probe: TouchProbe::new((config.touch_probe_latency_s * 1e9).round() as u64),
            cycle_start_ns: 0,
            motion: MotionHistory::new(),
            index_rearm: false,
        };
        drive.build_dictionary();
        drive.rebuild_layouts();
        // The power-up transition (not ready to switch on -> switch on disabled) before the
        // first frame, as a drive boots before it answers.
        drive.step(1e-3, None);
        drive.publish();
        Ok(drive)
    }

    /// The load's true position (joint units) before the encoder.
    pub fn true_position(&self) -> f64 {
        self.true_state().0
    }

    /// The load's true position and velocity (joint units, per second).
    pub fn true_state(&self) -> (f64, f64) {
        self.machine.true_state(0).unwrap_or((0.0, 0.0))
    }

    /// The drive's CiA 402 state.
    pub fn state(&self) -> Cia402State {
        self.feedback.joints[0].state()
    }

    /// The object dictionary (for checks).
    pub fn objects(&self) -> &Dictionary {
        &self.dictionary
    }

    /// Encoder increments per joint unit.
    pub fn counts_per_unit(&self) -> f64 {
        self.counts_per_unit
    }

    /// An edge on the drive's touch probe 1 input at system time `at_ns` (`rising`: the
    /// input closes). A probe armed for it latches the encoder at that instant (from the
    /// load's motion in the cycle that holds it, once that cycle has run) and reports it
    /// `touch_probe_latency_s` later.
    pub fn touch_probe_input(&mut self, at_ns: u64, rising: bool) {
        self.touch_probe.input_edge(at_ns, rising);
        self.resolve_touch_probe_edges();
    }

    /// The cycles of motion that started at or after `since_ns`, oldest first (at most the
    /// last 16).
    pub fn motion_since(&self, since_ns: u64) -> impl Iterator<Item = CycleMotion> + '_ {
        self.motion.iter().filter(move |m| m.start_ns >= since_ns)
    }

    /// Latches the probe input's edges whose instant a recorded cycle holds.
    fn resolve_touch_probe_edges(&mut self) {
        let (motion, joint) = (&self.motion, &self.config.joint);
        self.touch_probe
            .resolve(|at| motion.position_at(at).map(|p| encoder_counts(joint, p)));
    }

    fn build_dictionary(&mut self) {
        use Access::{ReadOnly as Ro, ReadWrite as Rw, ReadWritePreOp as Pre};
        use Mapping::{None as No, Rx, Tx};
        let d = &mut self.dictionary;
        let id = self.config.identity;
        d.insert(0x1000, 0, &0x0002_0192u32.to_le_bytes(), Ro, No);
        d.insert_string(0x1008, 0, &self.config.name, 64, Ro);
        d.insert_string(0x1009, 0, "1", 16, Ro);
        d.insert_string(0x100A, 0, env!("CARGO_PKG_VERSION"), 16, Ro);
        d.insert(0x1018, 0, &[4], Ro, No);
        for (sub, value) in [
            (1, id.vendor_id),
            (2, id.product_code),
            (3, id.revision),
            (4, id.serial),
        ] {
            d.insert(0x1018, sub, &value.to_le_bytes(), Ro, No);
        }
        let rx: [PdoEntry; 4] = default_rx_entries();
        let tx: [PdoEntry; 5] = default_tx_entries();
        d.insert(0x1600, 0, &[rx.len() as u8], Pre, No);
        d.insert(0x1A00, 0, &[tx.len() as u8], Pre, No);
        for sub in 1..=MAX_MAPPED {
            let value = |entries: &[PdoEntry]| {
                entries
                    .get(usize::from(sub) - 1)
                    .map_or(0, PdoEntry::mapping_value)
            };
            d.insert(0x1600, sub, &value(&rx).to_le_bytes(), Pre, No);
            d.insert(0x1A00, sub, &value(&tx).to_le_bytes(), Pre, No);
        }
        d.insert(0x1C00, 0, &[4], Ro, No);
        for (sub, kind) in [(1u8, 1u8), (2, 2), (3, 3), (4, 4)] {
            d.insert(0x1C00, sub, &[kind], Ro, No);
        }
        d.insert(0x1C12, 0, &[1], Pre, No);
        d.insert(0x1C12, 1, &0x1600u16.to_le_bytes(), Pre, No);
        d.insert(0x1C13, 0, &[1], Pre, No);
        d.insert(0x1C13, 1, &0x1A00u16.to_le_bytes(), Pre, No);
        for index in [0x1C32u16, 0x1C33] {
            d.insert(index, 0, &[5], Ro, No);
            // Sync mode: 0 free run, 2 DC SYNC0.
            d.insert(index, 1, &0u16.to_le_bytes(), Pre, No);
            d.insert(index, 2, &0u32.to_le_bytes(), Pre, No);
            // Supported: free run, SM-synchronous, DC (bits 0, 1, 2-3 = 01).
            d.insert(index, 4, &0x0007u16.to_le_bytes(), Ro, No);
            d.insert(index, 5, &125_000u32.to_le_bytes(), Ro, No);
        }
        d.insert_string(0x2000, 0, "", 200, Rw);
        d.insert(0x603F, 0, &0u16.to_le_bytes(), Ro, Tx);
        d.insert(0x6040, 0, &0u16.to_le_bytes(), Rw, Rx);
        d.insert(0x6041, 0, &0u16.to_le_bytes(), Ro, Tx);
        d.insert(0x6060, 0, &0i8.to_le_bytes(), Rw, Rx);
        d.insert(0x6061, 0, &0i8.to_le_bytes(), Ro, Tx);
        d.insert(0x6064, 0, &0i32.to_le_bytes(), Ro, Tx);
        d.insert(0x6065, 0, &u32::MAX.to_le_bytes(), Rw, No);
        d.insert(0x606C, 0, &0i32.to_le_bytes(), Ro, Tx);
        d.insert(0x6071, 0, &0i16.to_le_bytes(), Rw, Rx);
        d.insert(0x6072, 0, &3000u16.to_le_bytes(), Rw, No);
        d.insert(
            0x6076,
            0,
            &self.config.rated_torque_mnm.to_le_bytes(),
            Ro,
            No,
        );
        d.insert(0x6077, 0, &0i16.to_le_bytes(), Ro, Tx);
        d.insert(0x607A, 0, &0i32.to_le_bytes(), Rw, Rx);
        d.insert(0x607D, 0, &[2], Ro, No);
        d.insert(0x607D, 1, &i32::MIN.to_le_bytes(), Rw, No);
        d.insert(0x607D, 2, &i32::MAX.to_le_bytes(), Rw, No);
        d.insert(0x6080, 0, &6000u32.to_le_bytes(), Rw, No);
        d.insert(0x608F, 0, &[2], Ro, No);
        d.insert(
            0x608F,
            1,
            &self
                .config
                .joint
                .encoder_counts_per_revolution
                .to_le_bytes(),
            Ro,
            No,
        );
        d.insert(0x608F, 2, &1u32.to_le_bytes(), Ro, No);
        d.insert(0x60B1, 0, &0i32.to_le_bytes(), Rw, Rx);
        d.insert(0x60B2, 0, &0i16.to_le_bytes(), Rw, Rx);
        d.insert(0x60B8, 0, &0u16.to_le_bytes(), Rw, Rx);
        d.insert(0x60B9, 0, &0u16.to_le_bytes(), Ro, Tx);
        d.insert(0x60BA, 0, &0i32.to_le_bytes(), Ro, Tx);
        d.insert(0x60BB, 0, &0i32.to_le_bytes(), Ro, Tx);
        d.insert(0x60C2, 0, &[2], Ro, No);
        d.insert(0x60C2, 1, &[0], Pre, No);
        d.insert(0x60C2, 2, &(-3i8).to_le_bytes(), Pre, No);
        d.insert(0x60F4, 0, &0i32.to_le_bytes(), Ro, Tx);
        d.insert(0x60FD, 0, &0u32.to_le_bytes(), Ro, Tx);
        d.insert(0x60FF, 0, &0i32.to_le_bytes(), Rw, Rx);
        d.insert(0x6502, 0, &0x0000_0080u32.to_le_bytes(), Ro, No);
    }

    /// The layout of the PDOs assigned to `assign` (0x1C12 or 0x1C13).
    fn layout_of(&self, assign: u16) -> Vec<Mapped> {
        let mut layout = Vec::new();
        let mut offset = 0;
        let count = self.dictionary.unsigned(assign, 0) as u8;
        for n in 1..=count {
            let pdo = self.dictionary.unsigned(assign, n) as u16;
            let entries = self.dictionary.unsigned(pdo, 0) as u8;
            for e in 1..=entries {
                let value = self.dictionary.unsigned(pdo, e) as u32;
                let len = usize::from((value & 0xFF) as u8) / 8;
                layout.push(Mapped {
                    index: (value >> 16) as u16,
                    sub_index: (value >> 8) as u8,
                    offset,
                    len,
                });
                offset += len;
            }
        }
        layout
    }

    fn rebuild_layouts(&mut self) {
        self.rx_layout = self.layout_of(0x1C12);
        self.tx_layout = self.layout_of(0x1C13);
    }

    fn read_i32(&self, index: u16) -> i32 {
        self.dictionary.unsigned(index, 0) as u32 as i32
    }

    fn read_i16(&self, index: u16) -> i16 {
        self.dictionary.unsigned(index, 0) as u16 as i16
    }

    /// The machine's joint command from the dictionary's output objects.
    fn joint_command(&self, outputs_valid: bool) -> JointCommand {
        let mut controlword = if outputs_valid {
            ControlWord(self.dictionary.unsigned(0x6040, 0) as u16)
        } else {
            ControlWord::disable_voltage()
        };
        let mode = self.dictionary.unsigned(0x6060, 0) as u8 as i8;
        if mode != MODE_CSP && controlword.command() == DeviceCommand::EnableOperation {
            // Without a supported mode of operation the drive does not enable operation.
            controlword = ControlWord(controlword.0 & !ControlWord::ENABLE_OPERATION);
        }
        let min = self.dictionary.unsigned(0x607D, 1) as u32 as i32;
        let max = self.dictionary.unsigned(0x607D, 2) as u32 as i32;
        let mut target = self.read_i32(0x607A);
        if min < max {
            target = target.clamp(min, max);
        }
        let max_speed_rpm = self.dictionary.unsigned(0x6080, 0) as f64;
        let max_velocity = max_speed_rpm / 60.0 * self.config.joint.units_per_revolution;
        let velocity = f64::from(self.read_i32(0x60B1)) / self.counts_per_unit;
        let rated = f64::from(self.config.rated_torque_mnm) * 1e-3;
        let max_torque = self.dictionary.unsigned(0x6072, 0) as f64 * 1e-3 * rated;
        let torque = f64::from(self.read_i16(0x60B2)) * 1e-3 * rated;
        JointCommand {
            controlword,
            target_position: f64::from(target) / self.counts_per_unit,
            target_velocity: 0.0,
            target_torque: 0.0,
            velocity_offset: velocity.clamp(-max_velocity, max_velocity),
            torque_offset: torque.clamp(-max_torque, max_torque),
            latch: None,
        }
    }

    /// Runs the drive and its motor over one cycle.
    fn step(&mut self, period_s: f64, outputs: Option<&[u8]>) {
        if let Some(bytes) = outputs {
            for mapped in &self.rx_layout {
                if let Some(value) = bytes.get(mapped.offset..mapped.offset + mapped.len) {
                    self.dictionary.set(mapped.index, mapped.sub_index, value);
                }
            }
        }
        let mut command = self.joint_command(outputs.is_some());
        let start_ns = self.cycle_start_ns;
        // Outside OP the outputs are not applied: the probe is off.
        let function = if outputs.is_some() {
            self.dictionary.unsigned(0x60B8, 0) as u16
        } else {
            0
        };
        self.touch_probe.command(function, start_ns);
        let index_wanted = self.touch_probe.trigger() == Some(Trigger::IndexPulse)
            && self.touch_probe.takes(true, start_ns)
            && !self.index_rearm;
        command.latch = index_wanted.then_some(LatchSource::IndexPulse);
        self.index_rearm = false;
        let from = self.true_position();
        let reset_high = command.controlword.fault_reset_requested();
        if reset_high && !self.fault_reset_was_high {
            self.following_fault = false;
        }
        self.fault_reset_was_high = reset_high;
        let cause = self
            .injected_fault
            .or(self.following_fault.then_some(ERROR_FOLLOWING));
        let fault = InjectedFault::DriveFault {
            joint: 0,
            error_code: cause.unwrap_or(0),
        };
        let _ = match cause {
            Some(_) => self.machine.inject(fault),
            None => self.machine.clear(fault),
        };
        self.outputs.joints[0] = command;
        if self
            .machine
            .exchange(period_s, &self.outputs, &mut self.feedback)
            .is_err()
        {
            return;
        }
        let end_ns = start_ns.saturating_add((period_s * 1e9).round() as u64);
        self.motion.record(CycleMotion {
            start_ns,
            end_ns,
            from,
            to: self.true_position(),
        });
        let latch = self.feedback.joints[0].latch;
        if index_wanted && latch.latched {
            // The joint latched the index in whole increments; its instant within the
            // cycle is not kept, so the latency counts from the cycle's start.
            let counts = (latch.position * self.counts_per_unit).round();
            let counts = counts.clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32;
            self.touch_probe.latch(true, start_ns, counts);
            self.index_rearm = true;
        }
        self.resolve_touch_probe_edges();
        self.touch_probe.report(end_ns);
        let window = self.dictionary.unsigned(0x6065, 0);
        if window != u64::from(u32::MAX) && self.state() == Cia402State::OperationEnabled {
            let error = self.following_error_counts();
            if error.unsigned_abs() > window {
                self.following_fault = true;
            }
        }
    }

    fn following_error_counts(&self) -> i64 {
        i64::from(self.read_i32(0x607A)) - self.feedback.joints[0].position_counts
    }

    /// Writes the drive's state into its input objects.
    fn publish(&mut self) {
        let joint = self.feedback.joints[0];
        let clamp32 = |v: i64| v.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32;
        let velocity = clamp32((joint.velocity * self.counts_per_unit).round() as i64);
        let rated = f64::from(self.config.rated_torque_mnm.max(1)) * 1e-3;
        let torque = (joint.torque / rated * 1000.0)
            .round()
            .clamp(f64::from(i16::MIN), f64::from(i16::MAX)) as i16;
        let inputs = u32::from(joint.negative_limit)
            | (u32::from(joint.positive_limit) << 1)
            | (u32::from(joint.home_switch) << 2);
        let mode = self.dictionary.unsigned(0x6060, 0) as u8;
        let ferror = clamp32(self.following_error_counts());
        let d = &mut self.dictionary;
        d.set(0x6041, 0, &joint.statusword.0.to_le_bytes());
        d.set(0x603F, 0, &joint.error_code.to_le_bytes());
        d.set(0x6064, 0, &clamp32(joint.position_counts).to_le_bytes());
        d.set(0x606C, 0, &velocity.to_le_bytes());
        d.set(0x6077, 0, &torque.to_le_bytes());
        d.set(0x60F4, 0, &ferror.to_le_bytes());
        d.set(0x60FD, 0, &inputs.to_le_bytes());
        d.set(0x6061, 0, &[mode]);
        d.set(0x60B9, 0, &self.touch_probe.status().to_le_bytes());
        d.set(0x60BA, 0, &self.touch_probe.positive_value().to_le_bytes());
        d.set(0x60BB, 0, &self.touch_probe.negative_value().to_le_bytes());
    }

    fn check_mapping_entry(&self, pdo: u16, value: u32) -> Result<(), u32> {
        if value == 0 {
            return Ok(());
        }
        let index = (value >> 16) as u16;
        let sub_index = (value >> 8) as u8;
        let bits = (value & 0xFF) as usize;
        let entry = self
            .dictionary
            .entry(index, sub_index)
            .ok_or(abort::NOT_MAPPABLE)?;
        let direction = if pdo >= 0x1A00 {
            Mapping::Tx
        } else {
            Mapping::Rx
        };
        if entry.mapping != direction || entry.fixed_len.map(|l| l * 8) != Some(bits) {
            return Err(abort::NOT_MAPPABLE);
        }
        Ok(())
    }
}

fn default_rx_entries() -> [PdoEntry; 4] {
    [
        PdoEntry {
            index: 0x6040,
            sub_index: 0,
            bits: 16,
            data_type: data_type::UNSIGNED16,
        },
        PdoEntry {
            index: 0x607A,
            sub_index: 0,
            bits: 32,
            data_type: data_type::INTEGER32,
        },
        PdoEntry {
            index: 0x60B1,
            sub_index: 0,
            bits: 32,
            data_type: data_type::INTEGER32,
        },
        PdoEntry {
            index: 0x60B2,
            sub_index: 0,
            bits: 16,
            data_type: data_type::INTEGER16,
        },
    ]
}

fn default_tx_entries() -> [PdoEntry; 5] {
    [
        PdoEntry {
            index: 0x6041,
            sub_index: 0,
            bits: 16,
            data_type: data_type::UNSIGNED16,
        },
        PdoEntry {
            index: 0x6064,
            sub_index: 0,
            bits: 32,
            data_type: data_type::INTEGER32,
        },
        PdoEntry {
            index: 0x60F4,
            sub_index: 0,
            bits: 32,
            data_type: data_type::INTEGER32,
        },
        PdoEntry {
            index: 0x60FD,
            sub_index: 0,
            bits: 32,
            data_type: data_type::UNSIGNED32,
        },
        PdoEntry {
            index: 0x603F,
            sub_index: 0,
            bits: 16,
            data_type: data_type::UNSIGNED16,
        },
    ]
}

impl Application for CspDrive {
    fn sii(&self) -> SiiContents {
        SiiContents {
            identity: self.config.identity,
            alias: 0,
            name: self.config.name.clone(),
            mailbox: Some(MailboxLayout {
                receive_offset: MAILBOX_OUT,
                receive_size: MAILBOX_SIZE,
                send_offset: MAILBOX_IN,
                send_size: MAILBOX_SIZE,
                protocols: PROTOCOL_COE,
            }),
            // SDO, PDO assignment and PDO configuration by SDO.
            coe_details: 0x01 | 0x04 | 0x08,
            fmmus: vec![
                FmmuUse::Outputs,
                FmmuUse::Inputs,
                FmmuUse::SyncManagerStatus,
            ],
            sync_managers: vec![
                SyncManagerDefault {
                    start: MAILBOX_OUT,
                    length: MAILBOX_SIZE,
                    control: 0x26,
                    enable: true,
                    usage: SyncManagerUse::MailboxOut,
                },
                SyncManagerDefault {
                    start: MAILBOX_IN,
                    length: MAILBOX_SIZE,
                    control: 0x22,
                    enable: true,
                    usage: SyncManagerUse::MailboxIn,
                },
                SyncManagerDefault {
                    start: OUTPUTS,
                    length: 0,
                    control: 0x64,
                    enable: true,
                    usage: SyncManagerUse::Outputs,
                },
                SyncManagerDefault {
                    start: INPUTS,
                    length: 0,
                    control: 0x20,
                    enable: true,
                    usage: SyncManagerUse::Inputs,
                },
            ],
            tx_pdos: vec![Pdo {
                index: 0x1A00,
                sync_manager: 3,
                entries: default_tx_entries().to_vec(),
            }],
            rx_pdos: vec![Pdo {
                index: 0x1600,
                sync_manager: 2,
                entries: default_rx_entries().to_vec(),
            }],
        }
    }

    fn dictionary(&self) -> Option<&Dictionary> {
        Some(&self.dictionary)
    }

    fn begin_cycle(&mut self, system_ns: u64) {
        self.cycle_start_ns = system_ns;
    }

    fn download(
        &mut self,
        index: u16,
        sub_index: u8,
        data: &[u8],
        state: AlState,
    ) -> Result<(), u32> {
        self.dictionary
            .check_download(index, sub_index, data, state)?;
        let value = {
            let mut bytes = [0u8; 8];
            for (b, v) in bytes.iter_mut().zip(data) {
                *b = *v;
            }
            u64::from_le_bytes(bytes)
        };
        match (index, sub_index) {
            (0x1600 | 0x1A00, 0) => {
                if value > u64::from(MAX_MAPPED) {
                    return Err(abort::VALUE_RANGE);
                }
                let mut bytes = 0;
                for sub in 1..=value as u8 {
                    let entry = self.dictionary.unsigned(index, sub) as u32;
                    if entry == 0 {
                        return Err(abort::VALUE_RANGE);
                    }
                    self.check_mapping_entry(index, entry)?;
                    bytes += (entry & 0xFF) as usize / 8;
                }
                if bytes > MAX_PDO_BYTES {
                    return Err(abort::PDO_TOO_LONG);
                }
            }
            (0x1600 | 0x1A00, _) => {
                if self.dictionary.unsigned(index, 0) != 0 {
                    return Err(abort::SUB_INDEX_0_NOT_ZERO);
                }
                self.check_mapping_entry(index, value as u32)?;
            }
            (0x1C12 | 0x1C13, 0)
                if value > 1 || (value == 1 && self.dictionary.unsigned(index, 1) == 0) =>
            {
                return Err(abort::VALUE_RANGE);
            }
            (0x1C12 | 0x1C13, 0) => {}
            (0x1C12 | 0x1C13, _) => {
                if self.dictionary.unsigned(index, 0) != 0 {
                    return Err(abort::SUB_INDEX_0_NOT_ZERO);
                }
                let expected = if index == 0x1C12 { 0x1600 } else { 0x1A00 };
                if value != expected {
                    return Err(abort::VALUE_RANGE);
                }
            }
            (0x6060, 0) => {
                let mode = data.first().copied().unwrap_or(0) as i8;
                if mode != 0 && mode != MODE_CSP {
                    return Err(abort::VALUE_RANGE);
                }
            }
            (0x60C2, 2) => {
                let exponent = data.first().copied().unwrap_or(0) as i8;
                if !(-6..=-3).contains(&exponent) {
                    return Err(abort::VALUE_RANGE);
                }
            }
            (0x1C32 | 0x1C33, 1) if !matches!(value, 0..=2) => {
                return Err(abort::VALUE_RANGE);
            }
            _ => {}
        }
        self.dictionary.set(index, sub_index, data);
        if matches!(index, 0x1600 | 0x1A00 | 0x1C12 | 0x1C13) {
            self.rebuild_layouts();
        }
        Ok(())
    }

    fn process_data_len(&self) -> (usize, usize) {
        let len = |layout: &[Mapped]| layout.iter().map(|m| m.len).sum();
        (len(&self.rx_layout), len(&self.tx_layout))
    }

    fn check_transition(&mut self, to: AlState, context: &TransitionContext) -> Result<(), u16> {
        if to == AlState::SafeOp {
            let value = self.dictionary.unsigned(0x60C2, 1);
            let exponent = self.dictionary.unsigned(0x60C2, 2) as u8 as i8;
            if let Some(cycle) = context.sync0_cycle_ns
                && value != 0
            {
                let period_ns = value as f64 * 10f64.powi(i32::from(exponent) + 9);
                if (period_ns - f64::from(cycle)).abs() > 0.5 {
                    return Err(al_code::INVALID_SYNC0_CYCLE);
                }
            }
        }
        Ok(())
    }

    fn cycle(&mut self, period_s: f64, outputs: Option<&[u8]>, inputs: &mut [u8]) {
        // The inputs are the state at this event; then the drive runs to the next one.
        for mapped in &self.tx_layout {
            if let (Some(value), Some(slot)) = (
                self.dictionary.value(mapped.index, mapped.sub_index),
                inputs.get_mut(mapped.offset..mapped.offset + mapped.len),
            ) && value.len() == slot.len()
            {
                slot.copy_from_slice(value);
            }
        }
        self.step(period_s, outputs);
        self.publish();
    }

    fn inject_fault(&mut self, error_code: Option<u16>) -> bool {
        self.injected_fault = error_code;
        true
    }

    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}
