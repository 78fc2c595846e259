//! The process data of a CiA 402 drive: the objects the master can map (receive PDO:
//! outputs; transmit PDO: inputs), their place in the PDO, and the conversion between the
//! process image's joint units and the drive's increments.
//!
//! A position latch the controller asks for ([`JointCommand::latch`]) goes to the drive's
//! touch probe 1 when the PDOs carry it (0x60B8 out; 0x60B9, 0x60BA, 0x60BB in), with the
//! bits of CiA 402 (IEC 61800-7-201), as drives document them (Beckhoff EP7211 "Touch
//! Probe", AX8000 objects 0x60B8/0x60B9; Panasonic's in RSI's RapidCode "TouchProbe.cs"):
//! 0x60B8 bit 0 enable, bit 1 continuous, bits 2-3 trigger (00 probe input, 01 encoder
//! zero impulse), bit 4 sample the positive edge, bit 5 the negative; 0x60B9 bit 0
//! enabled, bit 1 positive-edge value stored (in 0x60BA), bit 2 negative (0x60BB).

use rtcnc_fieldbus::{
    ControlWord, JointCommand, JointFeedback, LatchFeedback, LatchSource, StatusWord,
};
use serde::Deserialize;

/// An object the master writes (receive PDO of the drive).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RxObject {
    /// 0x6040 controlword, 16 bits.
    Controlword,
    /// 0x607A target position (increments), 32 bits.
    TargetPosition,
    /// 0x60FF target velocity (increments/s), 32 bits.
    TargetVelocity,
    /// 0x6071 target torque (thousandths of rated), 16 bits.
    TargetTorque,
    /// 0x60B1 velocity offset (increments/s), 32 bits.
    VelocityOffset,
    /// 0x60B2 torque offset (thousandths of rated), 16 bits.
    TorqueOffset,
    /// 0x6060 modes of operation, 8 bits (always 8, CSP).
    ModesOfOperation,
    /// 0x60B8 touch probe function, 16 bits: arms touch probe 1 for a latch.
    TouchProbeFunction,
}

/// An object the master reads (transmit PDO of the drive).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TxObject {
    /// 0x6041 statusword, 16 bits.
    Statusword,
    /// 0x6064 position actual value (increments), 32 bits.
    PositionActual,
    /// 0x606C velocity actual value (increments/s), 32 bits.
    VelocityActual,
    /// 0x6077 torque actual value (thousandths of rated), 16 bits.
    TorqueActual,
    /// 0x60F4 following error actual value (increments), 32 bits.
    FollowingErrorActual,
    /// 0x60FD digital inputs (bit 0 negative limit, 1 positive limit, 2 home), 32 bits.
    DigitalInputs,
    /// 0x603F error code, 16 bits.
    ErrorCode,
    /// 0x6061 modes of operation display, 8 bits.
    ModesOfOperationDisplay,
    /// 0x60B9 touch probe status, 16 bits.
    TouchProbeStatus,
    /// 0x60BA touch probe 1 positive edge (increments), 32 bits.
    #[serde(rename = "touch_probe_1_positive_edge")]
    TouchProbe1PositiveEdge,
    /// 0x60BB touch probe 1 negative edge (increments), 32 bits.
    #[serde(rename = "touch_probe_1_negative_edge")]
    TouchProbe1NegativeEdge,
}

impl RxObject {
    /// The default CSP mapping: controlword, target position, velocity and torque offsets.
    pub const CSP_DEFAULT: [Self; 4] = [
        Self::Controlword,
        Self::TargetPosition,
        Self::VelocityOffset,
        Self::TorqueOffset,
    ];

    /// Object index.
    pub const fn index(self) -> u16 {
        match self {
            Self::Controlword => 0x6040,
            Self::TargetPosition => 0x607A,
            Self::TargetVelocity => 0x60FF,
            Self::TargetTorque => 0x6071,
            Self::VelocityOffset => 0x60B1,
            Self::TorqueOffset => 0x60B2,
            Self::ModesOfOperation => 0x6060,
            Self::TouchProbeFunction => 0x60B8,
        }
    }

    /// Length in bits.
    pub const fn bits(self) -> u8 {
        match self {
            Self::Controlword
            | Self::TargetTorque
            | Self::TorqueOffset
            | Self::TouchProbeFunction => 16,
            Self::ModesOfOperation => 8,
            _ => 32,
        }
    }
}

impl TxObject {
    /// The default CSP mapping: statusword, position actual, following error actual,
    /// digital inputs, error code.
    pub const CSP_DEFAULT: [Self; 5] = [
        Self::Statusword,
        Self::PositionActual,
        Self::FollowingErrorActual,
        Self::DigitalInputs,
        Self::ErrorCode,
    ];

    /// Object index.
    pub const fn index(self) -> u16 {
        match self {
            Self::Statusword => 0x6041,
            Self::PositionActual => 0x6064,
            Self::VelocityActual => 0x606C,
            Self::TorqueActual => 0x6077,
            Self::FollowingErrorActual => 0x60F4,
            Self::DigitalInputs => 0x60FD,
            Self::ErrorCode => 0x603F,
            Self::ModesOfOperationDisplay => 0x6061,
            Self::TouchProbeStatus => 0x60B9,
            Self::TouchProbe1PositiveEdge => 0x60BA,
            Self::TouchProbe1NegativeEdge => 0x60BB,
        }
    }

    /// Length in bits.
    pub const fn bits(self) -> u8 {
        match self {
            Self::Statusword | Self::TorqueActual | Self::ErrorCode | Self::TouchProbeStatus => 16,
            Self::ModesOfOperationDisplay => 8,
            _ => 32,
        }
    }
}

/// The 32-bit value of a PDO mapping entry: index, sub-index 0, bit length.
pub const fn mapping_value(index: u16, bits: u8) -> u32 {
    ((index as u32) << 16) | bits as u32
}

/// Largest PDO the master maps (bytes per direction per drive).
const MAX_PDO_BYTES: usize = 64;

fn check<T: Copy + PartialEq>(
    objects: &[T],
    required: &[(T, &str)],
    bits: impl Fn(T) -> u8,
) -> Result<(), String> {
    for (n, object) in objects.iter().enumerate() {
        if objects[..n].contains(object) {
            return Err(format!("entry {n} repeats an object"));
        }
    }
    for (object, name) in required {
        if !objects.contains(object) {
            return Err(format!("must contain {name}"));
        }
    }
    let bytes: usize = objects.iter().map(|o| usize::from(bits(*o)) / 8).sum();
    if bytes > MAX_PDO_BYTES || objects.len() > 8 {
        return Err(format!("at most 8 objects and {MAX_PDO_BYTES} bytes"));
    }
    Ok(())
}

/// Checks a receive PDO: controlword and target position present, no repeats, in size.
pub fn check_rx(objects: &[RxObject]) -> Result<(), String> {
    check(
        objects,
        &[
            (RxObject::Controlword, "controlword"),
            (RxObject::TargetPosition, "target_position"),
        ],
        RxObject::bits,
    )
}

/// Checks a transmit PDO: statusword and position actual present, no repeats, in size.
pub fn check_tx(objects: &[TxObject]) -> Result<(), String> {
    check(
        objects,
        &[
            (TxObject::Statusword, "statusword"),
            (TxObject::PositionActual, "position_actual"),
        ],
        TxObject::bits,
    )
}

/// Bits of 0x60B8 touch probe function.
pub mod touch_probe_function {
    /// Touch probe 1 enabled.
    pub const ENABLE: u16 = 1 << 0;
    /// Trigger on the position encoder's zero impulse (bits 2-3 = 01; 00 is the probe input).
    pub const TRIGGER_INDEX: u16 = 0b01 << 2;
    /// Sample the positive edge (into 0x60BA).
    pub const POSITIVE_EDGE: u16 = 1 << 4;
    /// Sample the negative edge (into 0x60BB).
    pub const NEGATIVE_EDGE: u16 = 1 << 5;
}

/// Bits of 0x60B9 touch probe status.
pub mod touch_probe_status {
    /// Touch probe 1 enabled.
    pub const ENABLED: u16 = 1 << 0;
    /// A positive-edge value is stored in 0x60BA.
    pub const POSITIVE_STORED: u16 = 1 << 1;
    /// A negative-edge value is stored in 0x60BB.
    pub const NEGATIVE_STORED: u16 = 1 << 2;
}

/// What a latch from the controller needs of the drive's touch probe.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LatchUse {
    /// On the encoder's index: 0x60B8, 0x60B9, 0x60BA.
    IndexPulse,
    /// On the probe input, either edge (G38.2-G38.5): 0x60B8, 0x60B9, 0x60BA, 0x60BB.
    ProbeInput,
}

/// The first touch probe object a latch of `what` needs that these PDOs lack, as
/// "0x60B8 (rx_pdo \"touch_probe_function\")"; `None` when every one is mapped.
pub fn missing_touch_probe_object(
    rx: &[RxObject],
    tx: &[TxObject],
    what: LatchUse,
) -> Option<&'static str> {
    if !rx.contains(&RxObject::TouchProbeFunction) {
        return Some("0x60B8 touch probe function (rx_pdo \"touch_probe_function\")");
    }
    let mut needed = vec![
        (
            TxObject::TouchProbeStatus,
            "0x60B9 touch probe status (tx_pdo \"touch_probe_status\")",
        ),
        (
            TxObject::TouchProbe1PositiveEdge,
            "0x60BA touch probe 1 positive edge (tx_pdo \"touch_probe_1_positive_edge\")",
        ),
    ];
    if what == LatchUse::ProbeInput {
        needed.push((
            TxObject::TouchProbe1NegativeEdge,
            "0x60BB touch probe 1 negative edge (tx_pdo \"touch_probe_1_negative_edge\")",
        ));
    }
    needed
        .into_iter()
        .find(|(object, _)| !tx.contains(object))
        .map(|(_, name)| name)
}

/// Where a touch-probe latch stands: the master first sees the probe off (0x60B9 bit 0
/// clear, so no stored bit is from an earlier arming), then writes the function and takes
/// the first stored bit that comes with the probe enabled.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ProbeArming {
    /// 0x60B8 = 0 until the status shows the probe off.
    Disarming,
    /// The function is written.
    Armed,
}

/// One drive's process data: where each object lies, the unit conversions, and what the
/// drive was last told (to hold it when a command is not a number).
#[derive(Debug, Clone, PartialEq)]
pub struct DriveCodec {
    rx: Vec<(RxObject, usize)>,
    tx: Vec<(TxObject, usize)>,
    rx_len: usize,
    tx_len: usize,
    counts_per_unit: f64,
    /// N·m per thousandth of rated torque.
    torque_unit: f64,
    last_target: i32,
    last_position: Option<i64>,
    /// The latch the controller asks for, and the home switch level when it was armed.
    latch_request: Option<LatchSource>,
    latch_reference: Option<bool>,
    latch: LatchFeedback,
    /// The PDOs carry the touch probe (0x60B8 out; 0x60B9 and 0x60BA in).
    touch_probe: bool,
    probe_arming: ProbeArming,
}

fn layout<T: Copy>(objects: &[T], bits: impl Fn(T) -> u8) -> (Vec<(T, usize)>, usize) {
    let mut offset = 0;
    let placed = objects
        .iter()
        .map(|&o| {
            let at = offset;
            offset += usize::from(bits(o)) / 8;
            (o, at)
        })
        .collect();
    (placed, offset)
}

fn put(buf: &mut [u8], at: usize, bytes: &[u8]) {
    if let Some(slot) = buf.get_mut(at..at + bytes.len()) {
        slot.copy_from_slice(bytes);
    }
}

fn get<const N: usize>(buf: &[u8], at: usize) -> [u8; N] {
    let mut out = [0u8; N];
    if let Some(slot) = buf.get(at..at + N) {
        out.copy_from_slice(slot);
    }
    out
}

/// A float to the nearest integer of type range, or `None` if it is not a number.
fn to_i32(value: f64) -> Option<i32> {
    value.is_finite().then(|| {
        value
            .round()
            .clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
    })
}

fn to_i16(value: f64) -> i16 {
    if value.is_finite() {
        value
            .round()
            .clamp(f64::from(i16::MIN), f64::from(i16::MAX)) as i16
    } else {
        0
    }
}

impl DriveCodec {
    /// A codec for these PDOs and units.
    pub fn new(
        rx: &[RxObject],
        tx: &[TxObject],
        counts_per_unit: f64,
        rated_torque_nm: f64,
    ) -> Self {
        let touch_probe =
            rx.contains(&RxObject::TouchProbeFunction) && tx.contains(&TxObject::TouchProbeStatus);
        let (rx, rx_len) = layout(rx, RxObject::bits);
        let (tx, tx_len) = layout(tx, TxObject::bits);
        Self {
            rx,
            tx,
            rx_len,
            tx_len,
            counts_per_unit,
            torque_unit: rated_torque_nm * 1e-3,
            last_target: 0,
            last_position: None,
            latch_request: None,
            latch_reference: None,
            latch: LatchFeedback::default(),
            touch_probe,
            probe_arming: ProbeArming::Disarming,
        }
    }

    /// The touch probe function (0x60B8) for the latch asked for, once armed.
    fn touch_probe_function(&self) -> u16 {
        use touch_probe_function::*;
        if self.probe_arming != ProbeArming::Armed {
            return 0;
        }
        match self.latch_request {
            Some(LatchSource::TouchProbe { rising: true }) => ENABLE | POSITIVE_EDGE,
            Some(LatchSource::TouchProbe { rising: false }) => ENABLE | NEGATIVE_EDGE,
            Some(LatchSource::IndexPulse) => ENABLE | TRIGGER_INDEX | POSITIVE_EDGE,
            Some(LatchSource::HomeSwitch) | None => 0,
        }
    }

    /// Bytes of outputs and inputs.
    pub fn lengths(&self) -> (usize, usize) {
        (self.rx_len, self.tx_len)
    }

    /// Joint units to increments.
    pub fn counts(&self, units: f64) -> Option<i32> {
        to_i32(units * self.counts_per_unit)
    }

    /// Writes `command` into the drive's outputs. A target that is not a number holds the
    /// last one sent.
    pub fn encode(&mut self, command: &JointCommand, outputs: &mut [u8]) {
        if command.latch != self.latch_request {
            // A new request (or none) re-arms the latch from the next inputs.
            self.latch_request = command.latch;
            self.latch_reference = None;
            self.latch = LatchFeedback::default();
            self.probe_arming = ProbeArming::Disarming;
        }
        if let Some(target) = self.counts(command.target_position) {
            self.last_target = target;
        }
        for &(object, at) in &self.rx {
            match object {
                RxObject::Controlword => put(outputs, at, &command.controlword.0.to_le_bytes()),
                RxObject::TargetPosition => put(outputs, at, &self.last_target.to_le_bytes()),
                RxObject::TargetVelocity => put(
                    outputs,
                    at,
                    &self
                        .counts(command.target_velocity)
                        .unwrap_or(0)
                        .to_le_bytes(),
                ),
                RxObject::VelocityOffset => put(
                    outputs,
                    at,
                    &self
                        .counts(command.velocity_offset)
                        .unwrap_or(0)
                        .to_le_bytes(),
                ),
                RxObject::TargetTorque => put(
                    outputs,
                    at,
                    &to_i16(command.target_torque / self.torque_unit).to_le_bytes(),
                ),
                RxObject::TorqueOffset => put(
                    outputs,
                    at,
                    &to_i16(command.torque_offset / self.torque_unit).to_le_bytes(),
                ),
                RxObject::ModesOfOperation => put(outputs, at, &[crate::MODE_CSP as u8]),
                RxObject::TouchProbeFunction => {
                    put(outputs, at, &self.touch_probe_function().to_le_bytes());
                }
            }
        }
    }

    /// Outputs that keep the drive where it stands, disabled: "disable voltage" and the
    /// actual position as target.
    pub fn encode_hold(&mut self, outputs: &mut [u8]) {
        let command = JointCommand {
            controlword: ControlWord::disable_voltage(),
            target_position: f64::NAN,
            ..JointCommand::default()
        };
        if let Some(position) = self.last_position {
            self.last_target = position.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32;
        }
        self.encode(&command, outputs);
    }

    /// Reads the drive's inputs into `feedback`; velocity comes from 0x606C when mapped,
    /// else from the position change over `period_s`.
    pub fn decode(&mut self, inputs: &[u8], period_s: f64, feedback: &mut JointFeedback) {
        let mut velocity = None;
        let mut digital = 0u32;
        let mut position = self.last_position.unwrap_or(0);
        let mut probe_status = 0u16;
        let mut probe_values = [0i32; 2];
        feedback.torque = 0.0;
        feedback.error_code = 0;
        for &(object, at) in &self.tx {
            match object {
                TxObject::Statusword => {
                    feedback.statusword = StatusWord(u16::from_le_bytes(get(inputs, at)));
                }
                TxObject::PositionActual => {
                    position = i64::from(i32::from_le_bytes(get(inputs, at)));
                }
                TxObject::VelocityActual => {
                    velocity = Some(f64::from(i32::from_le_bytes(get(inputs, at))));
                }
                TxObject::TorqueActual => {
                    feedback.torque =
                        f64::from(i16::from_le_bytes(get(inputs, at))) * self.torque_unit;
                }
                TxObject::DigitalInputs => digital = u32::from_le_bytes(get(inputs, at)),
                TxObject::ErrorCode => feedback.error_code = u16::from_le_bytes(get(inputs, at)),
                TxObject::TouchProbeStatus => probe_status = u16::from_le_bytes(get(inputs, at)),
                TxObject::TouchProbe1PositiveEdge => {
                    probe_values[0] = i32::from_le_bytes(get(inputs, at));
                }
                TxObject::TouchProbe1NegativeEdge => {
                    probe_values[1] = i32::from_le_bytes(get(inputs, at));
                }
                TxObject::FollowingErrorActual | TxObject::ModesOfOperationDisplay => {}
            }
        }
        let moved = self.last_position.map_or(0, |last| position - last);
        self.last_position = Some(position);
        feedback.position_counts = position;
        feedback.position = position as f64 / self.counts_per_unit;
        feedback.velocity = match velocity {
            Some(counts_per_s) => counts_per_s / self.counts_per_unit,
            None => moved as f64 / self.counts_per_unit / period_s,
        };
        feedback.negative_limit = digital & 0x1 != 0;
        feedback.positive_limit = digital & 0x2 != 0;
        feedback.home_switch = digital & 0x4 != 0;
        match self.latch_request {
            Some(LatchSource::HomeSwitch) | None => self.latch_home_switch(feedback),
            Some(_) => self.latch_touch_probe(probe_status, probe_values),
        }
        feedback.latch = self.latch;
    }

    /// An index or probe latch through the drive's touch probe 1 (unarmed when the PDOs do
    /// not carry it: the kernel then takes the position of the period, or refuses the
    /// machine file beforehand).
    fn latch_touch_probe(&mut self, status: u16, values: [i32; 2]) {
        use touch_probe_status::*;
        if !self.touch_probe {
            self.latch = LatchFeedback::default();
            return;
        }
        match self.probe_arming {
            ProbeArming::Disarming => {
                if status & ENABLED == 0 {
                    self.probe_arming = ProbeArming::Armed;
                }
                self.latch = LatchFeedback::default();
            }
            ProbeArming::Armed if self.latch.latched || status & ENABLED == 0 => {}
            ProbeArming::Armed => {
                let (stored, value) = match self.latch_request {
                    Some(LatchSource::TouchProbe { rising: false }) => {
                        (status & NEGATIVE_STORED, values[1])
                    }
                    _ => (status & POSITIVE_STORED, values[0]),
                };
                self.latch = if stored != 0 {
                    LatchFeedback {
                        armed: false,
                        latched: true,
                        position: f64::from(value) / self.counts_per_unit,
                    }
                } else {
                    LatchFeedback {
                        armed: true,
                        latched: false,
                        position: 0.0,
                    }
                };
            }
        }
    }

    /// The home switch's edge, latched by the master at the cycle it shows in the inputs
    /// (the position sampled with it, so within one period's travel of the edge).
    fn latch_home_switch(&mut self, feedback: &JointFeedback) {
        if self.latch_request != Some(LatchSource::HomeSwitch) {
            self.latch = LatchFeedback::default();
            return;
        }
        match self.latch_reference {
            None => {
                self.latch_reference = Some(feedback.home_switch);
                self.latch = LatchFeedback {
                    armed: true,
                    latched: false,
                    position: 0.0,
                };
            }
            Some(level) if !self.latch.latched && feedback.home_switch != level => {
                self.latch = LatchFeedback {
                    armed: false,
                    latched: true,
                    position: feedback.position,
                };
            }
            Some(_) => {}
        }
    }
}
