//! The master's configuration: what the machine file's `[fieldbus]` section holds when
//! `kind = "ethercat"` (the kernel removes `kind` and passes the rest). Every key is
//! listed in docs/ethercat.md; refusals name the key.

use serde::Deserialize;

use crate::pdo::{RxObject, TxObject};

/// The EtherCAT master.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EthercatConfig {
    /// The network interface the bus is on (a raw socket: needs CAP_NET_RAW).
    pub interface: String,
    /// Wrong or missing working counters in a row that make a fieldbus fault (1 = the
    /// first one). Default 3.
    #[serde(default = "defaults::working_counter_limit")]
    pub working_counter_limit: u32,
    /// How long one exchange waits for its frame to come back (µs); default: half the
    /// cycle period. A frame later than this counts as lost for that cycle.
    #[serde(default)]
    pub reply_timeout_us: Option<u32>,
    /// Distributed clocks: SYNC0 at the cycle period on every device that has them.
    /// Default true.
    #[serde(default = "defaults::yes")]
    pub distributed_clocks: bool,
    /// Where in the cycle the master sends, after SYNC0, as a fraction of the period.
    /// Default 0.5 (half a period away from the devices' SYNC0 event).
    #[serde(default = "defaults::send_phase")]
    pub send_phase: f64,
    /// Frames sent at start-up to align the devices' clocks to the reference clock before
    /// SYNC0 starts (static drift compensation). Default 1000.
    #[serde(default = "defaults::dc_static_sync_iterations")]
    pub dc_static_sync_iterations: u32,
    /// Time a state change (INIT → PRE-OP → SAFE-OP → OP) may take (ms). Default 5000.
    #[serde(default = "defaults::state_timeout_ms")]
    pub state_timeout_ms: u32,
    /// Sync manager watchdog of every device (ms): how long a device in OP goes without
    /// new outputs before it drops to SAFE-OP (AL status code 0x001B). Absent: the
    /// devices' own (usually 100 ms).
    #[serde(default)]
    pub sm_watchdog_ms: Option<u16>,
    /// Digital input of the process image that carries the e-stop chain (a normally closed
    /// contact: the e-stop is active while the input is off). Absent: no e-stop input.
    #[serde(default)]
    pub estop_input: Option<usize>,
    /// The devices, in the order they sit on the bus.
    pub slaves: Vec<SlaveConfig>,
}

/// One device on the bus.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum SlaveConfig {
    /// A CiA 402 servo drive in cyclic synchronous position mode.
    Cia402 {
        /// A name for messages.
        name: String,
        /// Expected vendor ID (refused at start-up on mismatch, like the next two).
        vendor_id: u32,
        /// Expected product code.
        product_code: u32,
        /// Expected revision number.
        revision: u32,
        /// The joint of the process image this drive moves.
        joint: usize,
        /// Encoder increments per joint unit (mm or degree), e.g. 131072 / 5 for a 17-bit
        /// encoder on a 5 mm lead screw.
        counts_per_unit: f64,
        /// Rated torque (N·m, the drive's 0x6076): torque offsets go out in thousandths of
        /// it. Default 1.
        #[serde(default = "defaults::rated_torque")]
        rated_torque_nm: f64,
        /// Receive PDO (outputs) contents; default the CiA 402 CSP set.
        #[serde(default = "defaults::rx_pdo")]
        rx_pdo: Vec<RxObject>,
        /// Transmit PDO (inputs) contents; default the CiA 402 CSP set.
        #[serde(default = "defaults::tx_pdo")]
        tx_pdo: Vec<TxObject>,
        /// Following error window (joint units, 0x6065); absent: the drive's own.
        #[serde(default)]
        following_error_window: Option<f64>,
        /// Software position limits [min, max] (joint units, 0x607D); absent: the drive's.
        #[serde(default)]
        position_limits: Option<[f64; 2]>,
        /// Maximum motor speed (rpm, 0x6080); absent: the drive's.
        #[serde(default)]
        max_motor_speed_rpm: Option<u32>,
        /// Maximum torque (thousandths of rated, 0x6072); absent: the drive's.
        #[serde(default)]
        max_torque_permille: Option<u16>,
        /// Further SDO writes in PRE-OP, in order, after the ones above.
        #[serde(default)]
        sdo: Vec<SdoWrite>,
    },
    /// A digital I/O terminal: its input bits feed the digital inputs of the process image
    /// from `inputs` on, its outputs come from the digital outputs from `outputs` on.
    Dio {
        /// A name for messages.
        name: String,
        /// Expected vendor ID.
        vendor_id: u32,
        /// Expected product code.
        product_code: u32,
        /// Expected revision number.
        revision: u32,
        /// First digital input of the process image its inputs go to.
        #[serde(default)]
        inputs: usize,
        /// First digital output of the process image its outputs come from.
        #[serde(default)]
        outputs: usize,
        /// Input bits (default 8).
        #[serde(default = "defaults::eight")]
        input_bits: usize,
        /// Output bits (default 8).
        #[serde(default = "defaults::eight")]
        output_bits: usize,
    },
}

impl SlaveConfig {
    /// The name for messages.
    pub fn name(&self) -> &str {
        match self {
            Self::Cia402 { name, .. } | Self::Dio { name, .. } => name,
        }
    }

    /// The expected identity.
    pub fn identity(&self) -> ExpectedIdentity {
        match self {
            Self::Cia402 {
                vendor_id,
                product_code,
                revision,
                ..
            }
            | Self::Dio {
                vendor_id,
                product_code,
                revision,
                ..
            } => ExpectedIdentity {
                vendor_id: *vendor_id,
                product_code: *product_code,
                revision: *revision,
            },
        }
    }
}

/// The identity a device must show in its EEPROM.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ExpectedIdentity {
    /// Vendor ID.
    pub vendor_id: u32,
    /// Product code.
    pub product_code: u32,
    /// Revision number.
    pub revision: u32,
}

impl std::fmt::Display for ExpectedIdentity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "vendor {:#010x} product {:#010x} revision {:#010x}",
            self.vendor_id, self.product_code, self.revision
        )
    }
}

/// An SDO download done in PRE-OP.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SdoWrite {
    /// Object index.
    pub index: u16,
    /// Sub-index.
    #[serde(default)]
    pub sub_index: u8,
    /// Value (its low `bytes` bytes are written, little-endian).
    pub value: i64,
    /// Size: 1, 2 or 4 bytes.
    pub bytes: u8,
}

/// A refused configuration: the key and the reason.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("fieldbus.{key}: {reason}")]
pub struct ConfigError {
    /// The key (below `fieldbus`).
    pub key: String,
    /// Why.
    pub reason: String,
}

impl ConfigError {
    fn new(key: impl Into<String>, reason: impl Into<String>) -> Self {
        Self {
            key: key.into(),
            reason: reason.into(),
        }
    }

    /// Stable code.
    pub fn code(&self) -> &'static str {
        "ethercat.config"
    }
}

/// Largest number of devices.
pub const MAX_SLAVES: usize = 64;

impl EthercatConfig {
    /// Checks every key; the error names the first refused one.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if self.interface.is_empty() || self.interface.len() >= 16 {
            return Err(ConfigError::new(
                "interface",
                "must be a network interface name (1 to 15 characters)",
            ));
        }
        if self.working_counter_limit == 0 {
            return Err(ConfigError::new(
                "working_counter_limit",
                "must be at least 1",
            ));
        }
        if !(0.05..=0.95).contains(&self.send_phase) {
            return Err(ConfigError::new(
                "send_phase",
                "must be between 0.05 and 0.95",
            ));
        }
        if self.sm_watchdog_ms.is_some_and(|ms| ms == 0 || ms > 6500) {
            return Err(ConfigError::new("sm_watchdog_ms", "between 1 and 6500 ms"));
        }
        if self.state_timeout_ms == 0 {
            return Err(ConfigError::new("state_timeout_ms", "must be at least 1"));
        }
        if self.slaves.is_empty() || self.slaves.len() > MAX_SLAVES {
            return Err(ConfigError::new(
                "slaves",
                format!("between 1 and {MAX_SLAVES} devices"),
            ));
        }
        let mut joints = Vec::new();
        let mut inputs: Vec<(usize, usize)> = Vec::new();
        let mut outputs: Vec<(usize, usize)> = Vec::new();
        for (n, slave) in self.slaves.iter().enumerate() {
            let key = |k: &str| format!("slaves[{n}].{k}");
            match slave {
                SlaveConfig::Cia402 {
                    joint,
                    counts_per_unit,
                    rated_torque_nm,
                    rx_pdo,
                    tx_pdo,
                    following_error_window,
                    position_limits,
                    sdo,
                    ..
                } => {
                    if joints.contains(joint) {
                        return Err(ConfigError::new(key("joint"), "another drive has it"));
                    }
                    joints.push(*joint);
                    if !(counts_per_unit.is_finite() && *counts_per_unit > 0.0) {
                        return Err(ConfigError::new(key("counts_per_unit"), "must be > 0"));
                    }
                    if !(rated_torque_nm.is_finite() && *rated_torque_nm > 0.0) {
                        return Err(ConfigError::new(key("rated_torque_nm"), "must be > 0"));
                    }
                    crate::pdo::check_rx(rx_pdo).map_err(|r| ConfigError::new(key("rx_pdo"), r))?;
                    crate::pdo::check_tx(tx_pdo).map_err(|r| ConfigError::new(key("tx_pdo"), r))?;
                    if let Some(window) = following_error_window
                        && !(window.is_finite() && *window > 0.0)
                    {
                        return Err(ConfigError::new(
                            key("following_error_window"),
                            "must be > 0",
                        ));
                    }
                    if let Some([min, max]) = position_limits
                        && !(min.is_finite() && max.is_finite() && min < max)
                    {
                        return Err(ConfigError::new(
                            key("position_limits"),
                            "must be [min, max] with min < max",
                        ));
                    }
                    for (k, write) in sdo.iter().enumerate() {
                        if !matches!(write.bytes, 1 | 2 | 4) {
                            return Err(ConfigError::new(
                                key(&format!("sdo[{k}].bytes")),
                                "must be 1, 2 or 4",
                            ));
                        }
                    }
                }
                SlaveConfig::Dio {
                    inputs: i,
                    outputs: o,
                    input_bits,
                    output_bits,
                    ..
                } => {
                    if *input_bits > 64 || *output_bits > 64 {
                        return Err(ConfigError::new(key("input_bits"), "at most 64"));
                    }
                    for (ranges, start, bits, name) in [
                        (&mut inputs, *i, *input_bits, "inputs"),
                        (&mut outputs, *o, *output_bits, "outputs"),
                    ] {
                        if start > 4096 {
                            return Err(ConfigError::new(key(name), "at most 4096"));
                        }
                        let end = start + bits;
                        if ranges.iter().any(|(s, e)| start < *e && end > *s) {
                            return Err(ConfigError::new(key(name), "overlaps another terminal's"));
                        }
                        ranges.push((start, end));
                    }
                }
            }
        }
        joints.sort_unstable();
        if let Some(missing) = joints.iter().enumerate().find(|(n, j)| *n != **j) {
            return Err(ConfigError::new(
                "slaves",
                format!(
                    "joints must be numbered 0 to {} without a gap: no joint {}",
                    joints.len() - 1,
                    missing.0
                ),
            ));
        }
        Ok(())
    }
}

mod defaults {
    use crate::pdo::{RxObject, TxObject};

    pub fn working_counter_limit() -> u32 {
        3
    }
    pub fn yes() -> bool {
        true
    }
    pub fn send_phase() -> f64 {
        0.5
    }
    pub fn dc_static_sync_iterations() -> u32 {
        1000
    }
    pub fn state_timeout_ms() -> u32 {
        5000
    }
    pub fn rated_torque() -> f64 {
        1.0
    }
    pub fn eight() -> usize {
        8
    }
    pub fn rx_pdo() -> Vec<RxObject> {
        RxObject::CSP_DEFAULT.to_vec()
    }
    pub fn tx_pdo() -> Vec<TxObject> {
        TxObject::CSP_DEFAULT.to_vec()
    }
}
