//! The machine's shared-memory link to the operator's surfaces (docs/shared-memory.md):
//! one named segment per machine under `/dev/shm`, with a versioned header, a ring of
//! normal commands acknowledged by serial number, an urgent ring read first every servo
//! period, a status snapshot under a seqlock, event and trace rings, task timing, service
//! requests (PLC variables), and a heartbeat each way.
//!
//! The machine process creates the segment ([`MachineLink::create`]) and gives it to
//! `Kernel::build`; one client (the API server) attaches ([`Client::attach`]).

mod client;
mod machine;
mod segment;
mod service;

pub mod layout;

pub use client::{Client, ClientError};
pub(crate) use machine::{CommandPort, Publisher, UrgentPort};
pub use machine::{JOG_KEEP_ALIVE, LOSS_TIMEOUT, MachineLink, state_number};
pub use segment::{LinkError, Mapping, monotonic_ns, segment_dir, segment_path};
pub use service::ServiceThread;

use crate::messages::HoldCause;

/// Why a command was refused: a stable code and a message for the operator.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refusal {
    /// Not after power-up, e-stop or a fault: reset first.
    NotReady,
    /// The machine is busy (a program, MDI, jog or homing runs).
    Busy,
    /// No program is loaded.
    NoProgram,
    /// The e-stop input is pressed.
    EstopInput,
    /// No such axis on this machine.
    BadAxis,
    /// A value out of range or not a number.
    BadValue,
    /// No jog to stop.
    NotJogging,
    /// The kernel's channel is full; try again.
    ChannelFull,
    /// Unknown command kind (a client of another build).
    Unknown,
    /// What the command started was stopped before its end (fault, e-stop, abort).
    Stopped,
    /// A reset while the fieldbus exchange fails (the bus lost, a device out of OP).
    FieldbusDown,
}

impl Refusal {
    /// Every reason, in number order.
    pub const ALL: [Refusal; 11] = [
        Refusal::NotReady,
        Refusal::Busy,
        Refusal::NoProgram,
        Refusal::EstopInput,
        Refusal::BadAxis,
        Refusal::BadValue,
        Refusal::NotJogging,
        Refusal::ChannelFull,
        Refusal::Unknown,
        Refusal::Stopped,
        Refusal::FieldbusDown,
    ];

    /// Number on the link.
    pub fn number(self) -> u32 {
        self as u32 + 1
    }

    /// The reason of a number.
    pub fn from_number(n: u64) -> Option<Refusal> {
        Self::ALL
            .iter()
            .copied()
            .find(|r| u64::from(r.number()) == n)
    }

    /// Stable code.
    pub fn code(self) -> &'static str {
        match self {
            Refusal::NotReady => "command.not_ready",
            Refusal::Busy => "command.busy",
            Refusal::NoProgram => "command.no_program",
            Refusal::EstopInput => "command.estop_input",
            Refusal::BadAxis => "command.bad_axis",
            Refusal::BadValue => "command.bad_value",
            Refusal::NotJogging => "command.not_jogging",
            Refusal::ChannelFull => "command.channel_full",
            Refusal::Unknown => "command.unknown",
            Refusal::Stopped => "command.stopped",
            Refusal::FieldbusDown => "command.fieldbus_down",
        }
    }

    /// Message.
    pub fn message(self) -> &'static str {
        match self {
            Refusal::NotReady => "the machine is not ready: reset it first",
            Refusal::Busy => "the machine is busy (a program, MDI, jog or homing runs)",
            Refusal::NoProgram => "no program is loaded",
            Refusal::EstopInput => "the e-stop input is pressed",
            Refusal::BadAxis => "no such axis on this machine",
            Refusal::BadValue => "a value is out of range or not a number",
            Refusal::NotJogging => "no jog to stop",
            Refusal::ChannelFull => "the kernel's command channel is full; try again",
            Refusal::Unknown => "unknown command",
            Refusal::Stopped => "stopped before its end (fault, e-stop or stop)",
            Refusal::FieldbusDown => {
                "the fieldbus exchange fails (the bus lost, a device out of OP): reset once it works"
            }
        }
    }
}

/// The link's number of what holds the machine (`WireStatus::hold`): 0 for none.
pub fn hold_number(cause: Option<HoldCause>) -> u32 {
    match cause {
        None => 0,
        Some(HoldCause::MachineLogic) => 1,
        Some(HoldCause::FeedStopSwitch) => 2,
        Some(HoldCause::Resume) => 3,
    }
}

/// What holds the machine, from the link's number (`WireStatus::hold`).
pub fn hold_cause(n: u32) -> Option<HoldCause> {
    match n {
        1 => Some(HoldCause::MachineLogic),
        2 => Some(HoldCause::FeedStopSwitch),
        3 => Some(HoldCause::Resume),
        _ => None,
    }
}

/// Names of the link's state numbers (`WireStatus::state`).
pub fn state_name(n: u32) -> &'static str {
    match n {
        0 => "starting",
        1 => "estop",
        2 => "idle",
        3 => "running",
        4 => "held",
        5 => "paused",
        6 => "waiting_for_logic",
        7 => "fault",
        _ => "unknown",
    }
}

/// Names of the link's mode numbers.
pub fn mode_name(n: u32) -> &'static str {
    match n {
        0 => "manual",
        1 => "auto",
        2 => "mdi",
        _ => "unknown",
    }
}
