//! The machine interface: named signals between the motion kernel and the PLC program,
//! and the configuration that maps them onto PLC variables.
//!
//! Hand-shakes (M-codes, tool change) follow one pattern: the kernel sets the data
//! (`m_code_number`, `m_code_p`, ...) and raises the request; the PLC does the work and
//! raises `..._done`; the kernel sees done, drops the request and continues motion; the PLC
//! drops done.

use std::collections::BTreeMap;

use serde::Deserialize;

/// Which way a signal flows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// Written by the kernel before a scan, read by the PLC program.
    ToPlc,
    /// Written by the PLC program, read by the kernel after a scan.
    FromPlc,
}

/// What a signal carries; decides which variable types it may be mapped to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SignalKind {
    /// BOOL.
    Bool,
    /// A number (REAL, LREAL or any integer variable).
    Number,
    /// An integer (any integer variable).
    Integer,
    /// A bit mask, bit n for joint n (any unsigned or bit-string variable).
    Mask,
}

macro_rules! signals {
    ($( $variant:ident = $name:literal, $dir:ident, $kind:ident, $safe:literal, $doc:literal; )*) => {
        /// A signal of the machine interface.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
        pub enum Signal {
            $( #[doc = $doc] $variant, )*
        }

        impl Signal {
            /// Every signal, in declaration order.
            pub const ALL: &'static [Signal] = &[ $( Signal::$variant, )* ];

            /// The name used in configurations.
            ///
            /// Real-time: yes (no allocation, no blocking).
            pub fn name(self) -> &'static str {
                match self { $( Signal::$variant => $name, )* }
            }
            /// Direction.
            ///
            /// Real-time: yes (no allocation, no blocking).
            pub fn direction(self) -> Direction {
                match self { $( Signal::$variant => Direction::$dir, )* }
            }
            /// Value kind.
            ///
            /// Real-time: yes (no allocation, no blocking).
            pub fn kind(self) -> SignalKind {
                match self { $( Signal::$variant => SignalKind::$kind, )* }
            }
            /// Value a FromPlc signal takes when the PLC faults (1.0 = TRUE).
            ///
            /// Real-time: yes (no allocation, no blocking).
            pub fn safe_value(self) -> f64 {
                match self { $( Signal::$variant => $safe as f64, )* }
            }
            /// What it means.
            ///
            /// Real-time: yes (no allocation, no blocking).
            pub fn description(self) -> &'static str {
                match self { $( Signal::$variant => $doc, )* }
            }
        }
    };
}

signals! {
    EstopChainIn = "estop_chain_in", ToPlc, Bool, 0, "External e-stop chain is closed (TRUE = healthy).";
    EstopReset = "estop_reset", ToPlc, Bool, 0, "Operator asks to reset the e-stop.";
    MachineOnRequest = "machine_on_request", ToPlc, Bool, 0, "Operator asks to switch the machine on.";
    ProgramRunning = "program_running", ToPlc, Bool, 0, "A part program is running.";
    AxesHomed = "axes_homed", ToPlc, Bool, 0, "Every axis is homed.";
    SpindleOn = "spindle_on", ToPlc, Bool, 0, "Spindle commanded on (M3/M4; M5 clears).";
    SpindleReverse = "spindle_reverse", ToPlc, Bool, 0, "Spindle commanded counter-clockwise (M4).";
    SpindleSpeedCommand = "spindle_speed_command", ToPlc, Number, 0, "Commanded spindle speed (S word, rpm).";
    SpindleSpeedActual = "spindle_speed_actual", ToPlc, Number, 0, "Measured spindle speed from the drive (rpm).";
    CoolantMist = "coolant_mist", ToPlc, Bool, 0, "Mist coolant commanded (M7; M9 clears).";
    CoolantFlood = "coolant_flood", ToPlc, Bool, 0, "Flood coolant commanded (M8; M9 clears).";
    ToolChangeRequest = "tool_change_request", ToPlc, Bool, 0, "Kernel requests a tool change (M6), waits for tool_change_done.";
    ToolNumber = "tool_number", ToPlc, Integer, 0, "Tool to load for the requested change (T word).";
    MCodeRequest = "m_code_request", ToPlc, Bool, 0, "Kernel requests a user M-code (M100..M199), waits for m_code_done.";
    MCodeNumber = "m_code_number", ToPlc, Integer, 0, "Number of the requested user M-code, 100..199.";
    MCodeP = "m_code_p", ToPlc, Number, 0, "P word of the requested user M-code.";
    MCodeQ = "m_code_q", ToPlc, Number, 0, "Q word of the requested user M-code.";
    LimitMin = "limit_min", ToPlc, Mask, 0, "Negative limit switches, bit n for joint n.";
    LimitMax = "limit_max", ToPlc, Mask, 0, "Positive limit switches, bit n for joint n.";
    EstopChainOut = "estop_chain_out", FromPlc, Bool, 0, "PLC closes the e-stop chain: motion allowed (FALSE stops the machine).";
    MachineOn = "machine_on", FromPlc, Bool, 0, "Machine is on (drives may be enabled).";
    SpindleEnable = "spindle_enable", FromPlc, Bool, 0, "Spindle drive enabled.";
    SpindleSpeedOut = "spindle_speed_out", FromPlc, Number, 0, "Spindle speed set-point to the drive (rpm, signed by direction).";
    SpindleAtSpeed = "spindle_at_speed", FromPlc, Bool, 0, "Spindle has reached its speed; the kernel waits for it before cutting.";
    CoolantMistOn = "coolant_mist_on", FromPlc, Bool, 0, "Mist coolant valve open.";
    CoolantFloodOn = "coolant_flood_on", FromPlc, Bool, 0, "Flood coolant pump on.";
    FeedHoldRequest = "feed_hold_request", FromPlc, Bool, 1, "PLC asks the kernel to hold feed (e.g. door open).";
    ToolChangeDone = "tool_change_done", FromPlc, Bool, 0, "Acknowledges tool_change_request.";
    MCodeDone = "m_code_done", FromPlc, Bool, 0, "Acknowledges m_code_request.";
    MachineFault = "machine_fault", FromPlc, Bool, 1, "The machine logic found a fault (e.g. tool change timeout); the kernel stops the program.";
    MachineFaultCode = "machine_fault_code", FromPlc, Integer, 0, "Code of the machine logic's fault (program-defined).";
    FeedOverride = "feed_override", FromPlc, Number, 0, "Feed override in percent, from the operator panel.";
    SpindleOverride = "spindle_override", FromPlc, Number, 0, "Spindle override in percent, from the operator panel.";
    RapidOverride = "rapid_override", FromPlc, Number, 0, "Rapid override in percent, from the operator panel.";
}

impl Signal {
    /// Look up by configuration name (case-insensitive).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn from_name(name: &str) -> Option<Signal> {
        Signal::ALL
            .iter()
            .copied()
            .find(|s| s.name().eq_ignore_ascii_case(name))
    }
}

/// The PLC part of a machine configuration: which variable each signal maps to, and the
/// safe values of outputs. Deserializes from a TOML table such as
///
/// ```toml
/// [signals]
/// spindle_on = "Mill.spindle_cmd"
/// spindle_at_speed = "Mill.at_speed"
/// [safe_values]
/// "Mill.door_lock" = "TRUE"
/// ```
#[derive(Debug, Clone, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PlcConfig {
    /// Signal name → PLC variable name.
    #[serde(default)]
    pub signals: BTreeMap<String, String>,
    /// Variable name (of a `%Q` located variable or a variable mapped to a signal from the
    /// PLC) → value it takes when the PLC faults, in IEC text (`TRUE`, `0`, `T#1s`).
    #[serde(default)]
    pub safe_values: BTreeMap<String, String>,
    /// AXIS_REF variable name → the auxiliary axis it refers to (PLCopen motion blocks).
    #[serde(default)]
    pub axes: BTreeMap<String, crate::plcopen::AxisConfig>,
}

/// Why a configuration cannot be applied.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ConfigError {
    /// No signal of that name.
    #[error("unknown signal '{0}'")]
    UnknownSignal(String),
    /// The variable does not exist.
    #[error("signal '{signal}': {error}")]
    Variable {
        /// Signal.
        signal: String,
        /// What went wrong with its variable.
        error: crate::runtime::MonitorError,
    },
    /// The variable's type does not suit the signal.
    #[error("signal '{signal}' carries a {kind:?} value, variable '{variable}' is {ty}")]
    Type {
        /// Signal.
        signal: String,
        /// Kind of the signal.
        kind: SignalKind,
        /// Variable.
        variable: String,
        /// Its type.
        ty: String,
    },
    /// A bad safe value entry.
    #[error("safe value for '{variable}': {message}")]
    SafeValue {
        /// Variable.
        variable: String,
        /// Reason.
        message: String,
    },
    /// A bad `[axes]` entry.
    #[error("axis '{variable}': {message}")]
    Axis {
        /// The AXIS_REF variable.
        variable: String,
        /// Reason.
        message: String,
    },
}

impl ConfigError {
    /// Stable code.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn code(&self) -> &'static str {
        match self {
            ConfigError::UnknownSignal(_) => "unknown-signal",
            ConfigError::Variable { .. } => "signal-variable",
            ConfigError::Type { .. } => "signal-type",
            ConfigError::SafeValue { .. } => "safe-value",
            ConfigError::Axis { .. } => "axis",
        }
    }
}
