//! Runtime faults: a code, a message, a time and the task that raised them (plain data).

/// Which kernel task raised a fault.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TaskName {
    /// Power-up self-test.
    SelfTest,
    /// Operator command parsing.
    CommandParsing,
    /// The G-code interpreter.
    Interpreter,
    /// Tool compensation.
    ToolCompensation,
    /// Look-ahead.
    LookAhead,
    /// Interpolation.
    Interpolation,
    /// Position control.
    PositionControl,
    /// Drive I/O.
    DriveIo,
    /// Machine logic (PLC).
    MachineLogic,
    /// The executive's timing monitor.
    Monitor,
    /// Background checks while running.
    BackgroundCheck,
}

impl TaskName {
    /// The executive's name of the task.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn as_str(self) -> &'static str {
        match self {
            TaskName::SelfTest => "self test",
            TaskName::CommandParsing => "command parsing",
            TaskName::Interpreter => "interpreter",
            TaskName::ToolCompensation => "tool compensation",
            TaskName::LookAhead => "look-ahead",
            TaskName::Interpolation => "interpolation",
            TaskName::PositionControl => "position control",
            TaskName::DriveIo => "drive io",
            TaskName::MachineLogic => "machine logic",
            TaskName::Monitor => "monitor",
            TaskName::BackgroundCheck => "self test",
        }
    }
}

/// What went wrong.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FaultCode {
    /// The e-stop was pressed (urgent command or the e-stop input).
    EStop,
    /// A hard limit switch tripped on a joint.
    HardLimit,
    /// A joint's following error exceeded its limit.
    FollowingError,
    /// A drive reported a fault.
    DriveFault,
    /// The fieldbus exchange failed.
    Communication,
    /// A real-time task missed its deadline.
    DeadlineMiss,
    /// The interpreter refused a block ("error in program").
    ProgramError,
    /// Tool compensation refused a block.
    CompensationError,
    /// The planner refused a move (soft limit, bad geometry).
    MotionError,
    /// The PLC stopped with a runtime fault, or reported a machine fault.
    LogicFault,
    /// An M/S/T function was refused (no spindle, unknown output).
    AuxRefused,
    /// Homing could not find its switch or index.
    HomingFailed,
    /// A command was not allowed in the current state (logged, not stopping).
    CommandRefused,
    /// A background check found a persistent file's folder gone or read-only, or the
    /// drive exchange no longer advancing (logged, not stopping by itself).
    BackgroundCheck,
    /// M19 Q: the spindle did not report oriented within the time-out.
    SpindleOrientTimeout,
    /// G38.2-G38.5: the probe was already in the state the move looks for, or G38.2/G38.4
    /// ended without the probe changing, or the machine has no probe input.
    ProbeFailed,
    /// G33/G76: the spindle does not turn, or turns too fast for the pitch and the axes.
    SyncFailed,
    /// Position control found no set-point for five periods in a row: interpolation
    /// stalled for longer than the set-point lead (`tasks.setpoint_lead`). Position
    /// control brings every joint to rest by itself.
    SetpointsRanDry,
    /// Interpolation could not queue a set-point (position control stopped taking them).
    SetpointsLost,
    /// The stall watchdog: a program's path stood still while it should move for longer
    /// than `safety.stall_timeout`; the program is stopped at the line.
    MotionStalled,
    /// The fieldbus answered with a wrong working counter (a device did not take part in
    /// the process data) as many cycles in a row as the machine file allows.
    WorkingCounter,
    /// A fieldbus device left its operational state (EtherCAT: it dropped out of OP, with
    /// its AL status code).
    DeviceState,
    /// The fieldbus's network link (cable, port) is down.
    LinkDown,
}

impl FaultCode {
    /// Every code, in number order.
    pub const ALL: [FaultCode; 23] = [
        FaultCode::EStop,
        FaultCode::HardLimit,
        FaultCode::FollowingError,
        FaultCode::DriveFault,
        FaultCode::Communication,
        FaultCode::DeadlineMiss,
        FaultCode::ProgramError,
        FaultCode::CompensationError,
        FaultCode::MotionError,
        FaultCode::LogicFault,
        FaultCode::AuxRefused,
        FaultCode::HomingFailed,
        FaultCode::CommandRefused,
        FaultCode::BackgroundCheck,
        FaultCode::SpindleOrientTimeout,
        FaultCode::ProbeFailed,
        FaultCode::SyncFailed,
        FaultCode::SetpointsRanDry,
        FaultCode::SetpointsLost,
        FaultCode::MotionStalled,
        FaultCode::WorkingCounter,
        FaultCode::DeviceState,
        FaultCode::LinkDown,
    ];

    /// The code of a [`number`](Self::number).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn from_number(number: u32) -> Option<FaultCode> {
        Self::ALL.iter().copied().find(|c| c.number() == number)
    }

    /// Stable code.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn as_str(self) -> &'static str {
        match self {
            FaultCode::EStop => "kernel.estop",
            FaultCode::HardLimit => "kernel.hard_limit",
            FaultCode::FollowingError => "kernel.following_error",
            FaultCode::DriveFault => "kernel.drive_fault",
            FaultCode::Communication => "kernel.communication",
            FaultCode::DeadlineMiss => "kernel.deadline_miss",
            FaultCode::ProgramError => "kernel.program_error",
            FaultCode::CompensationError => "kernel.compensation_error",
            FaultCode::MotionError => "kernel.motion_error",
            FaultCode::LogicFault => "kernel.logic_fault",
            FaultCode::AuxRefused => "kernel.aux_refused",
            FaultCode::HomingFailed => "kernel.homing_failed",
            FaultCode::CommandRefused => "kernel.command_refused",
            FaultCode::BackgroundCheck => "kernel.background_check",
            FaultCode::SpindleOrientTimeout => "kernel.spindle_orient_timeout",
            FaultCode::ProbeFailed => "kernel.probe_failed",
            FaultCode::SyncFailed => "kernel.sync_failed",
            FaultCode::SetpointsRanDry => "kernel.setpoints_ran_dry",
            FaultCode::SetpointsLost => "kernel.setpoints_lost",
            FaultCode::MotionStalled => "kernel.motion_stalled",
            FaultCode::WorkingCounter => "kernel.working_counter",
            FaultCode::DeviceState => "kernel.device_state",
            FaultCode::LinkDown => "kernel.link_down",
        }
    }

    /// Number for the executive's fault log and trace.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn number(self) -> u32 {
        self as u32 + 100
    }

    /// Plain message.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn message(self) -> &'static str {
        match self {
            FaultCode::EStop => "emergency stop",
            FaultCode::HardLimit => "hard limit switch",
            FaultCode::FollowingError => "following error",
            FaultCode::DriveFault => "drive fault",
            FaultCode::Communication => "fieldbus communication lost",
            FaultCode::DeadlineMiss => "deadline miss",
            FaultCode::ProgramError => "error in program",
            FaultCode::CompensationError => "error in program (tool compensation)",
            FaultCode::MotionError => "error in program (motion)",
            FaultCode::LogicFault => "machine logic fault",
            FaultCode::AuxRefused => "machine function refused",
            FaultCode::HomingFailed => "homing failed",
            FaultCode::CommandRefused => "command refused",
            FaultCode::BackgroundCheck => "background check failed",
            FaultCode::SpindleOrientTimeout => "spindle orientation timed out",
            FaultCode::ProbeFailed => "probing move failed",
            FaultCode::SyncFailed => "spindle-synchronised move impossible",
            FaultCode::SetpointsRanDry => "set-points ran dry (interpolation stalled)",
            FaultCode::SetpointsLost => "set-point lost (position control stopped taking)",
            FaultCode::MotionStalled => "the path stood still while it should move",
            FaultCode::WorkingCounter => "fieldbus working counter wrong",
            FaultCode::DeviceState => "fieldbus device left its operational state",
            FaultCode::LinkDown => "fieldbus link down",
        }
    }

    /// Whether the fault stops the machine at once (quick stop, then the drives are
    /// disabled until a reset). Program errors stop the program instead: the look-ahead
    /// lets the machine finish the blocks before the bad one.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn stops_machine(self) -> bool {
        matches!(
            self,
            FaultCode::EStop
                | FaultCode::HardLimit
                | FaultCode::FollowingError
                | FaultCode::DriveFault
                | FaultCode::Communication
                | FaultCode::LogicFault
                | FaultCode::HomingFailed
                | FaultCode::SetpointsRanDry
                | FaultCode::SetpointsLost
                | FaultCode::WorkingCounter
                | FaultCode::DeviceState
                | FaultCode::LinkDown
        )
    }
}

/// Why a probing move failed: the `value` of a [`FaultCode::ProbeFailed`] fault, worded
/// as LinuxCNC 2.9's motion controller words it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ProbeFailure {
    /// The machine file names no probe input.
    NoProbeInput,
    /// G38.2/G38.3 started with the probe in contact.
    AlreadyTripped,
    /// G38.4/G38.5 started with the probe clear.
    AlreadyClear,
    /// G38.2 reached its end point without contact.
    NoContact,
    /// G38.4 reached its end point without losing contact.
    ContactNotBroken,
}

impl ProbeFailure {
    const ALL: [ProbeFailure; 5] = [
        ProbeFailure::NoProbeInput,
        ProbeFailure::AlreadyTripped,
        ProbeFailure::AlreadyClear,
        ProbeFailure::NoContact,
        ProbeFailure::ContactNotBroken,
    ];

    /// The fault's `value` for this failure (1 to 5).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn value(self) -> f64 {
        f64::from(self as u8 + 1)
    }

    /// The failure a fault's `value` names.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn from_value(value: f64) -> Option<ProbeFailure> {
        Self::ALL.into_iter().find(|f| f.value() == value)
    }

    /// The operator's text (LinuxCNC's, except for the missing input, which it does not have).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn message(self) -> &'static str {
        match self {
            ProbeFailure::NoProbeInput => "no probe input in the machine file",
            ProbeFailure::AlreadyTripped => {
                "Probe is already tripped when starting G38.2 or G38.3 move"
            }
            ProbeFailure::AlreadyClear => {
                "Probe is already clear when starting G38.4 or G38.5 move"
            }
            ProbeFailure::NoContact => "G38.2 move finished without making contact.",
            ProbeFailure::ContactNotBroken => "G38.4 move finished without breaking contact.",
        }
    }
}

/// One fault.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fault {
    /// What.
    pub code: FaultCode,
    /// When (ns since the start of the run, the executive's clock).
    pub time_ns: u64,
    /// Raised by.
    pub task: TaskName,
    /// Joint concerned, if any.
    pub joint: Option<u8>,
    /// Program line concerned (0: none).
    pub line: u32,
    /// A value (the following error, the drive's error code, ...).
    pub value: f64,
}

impl Fault {
    /// Text for the operator; `joint_name` gives a joint's configured name.
    ///
    /// Real-time: no (allocates).
    pub fn describe(&self, joint_name: impl Fn(usize) -> String) -> String {
        let probe_failure = match self.code {
            FaultCode::ProbeFailed => ProbeFailure::from_value(self.value),
            _ => None,
        };
        let mut s = format!(
            "{} [{}] at {:.6} s in {}",
            probe_failure.map_or(self.code.message(), ProbeFailure::message),
            self.code.as_str(),
            self.time_ns as f64 * 1e-9,
            self.task.as_str()
        );
        if let Some(j) = self.joint {
            s.push_str(&format!(", joint {}", joint_name(usize::from(j))));
        }
        if self.line > 0 {
            s.push_str(&format!(", line {}", self.line));
        }
        if self.code == FaultCode::DriveFault && self.value > 0.0 && self.value <= 65535.0 {
            // The drive's error code (0x603F), in hexadecimal as drive manuals list it.
            let code = self.value as u16;
            s.push_str(&format!(
                " (error code {code:#06x}: {})",
                rtcnc_fieldbus::cia402::error_code::describe(code)
            ));
        } else if self.code == FaultCode::DeviceState && self.value > 0.0 {
            s.push_str(&format!(" (AL status code {:#06x})", self.value as u16));
        } else if self.code == FaultCode::WorkingCounter {
            s.push_str(&format!(" (working counter {})", self.value));
        } else if self.value != 0.0 && self.value.is_finite() && probe_failure.is_none() {
            s.push_str(&format!(" ({})", self.value));
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::FaultCode;

    #[test]
    fn every_code_comes_back_from_its_number() {
        // The numbers are the variants' order from 100, so ALL lists each once, in order;
        // the last variant closes the list (a code missing from ALL reads as unknown on the
        // other side of the shared-memory link).
        for (i, code) in FaultCode::ALL.iter().enumerate() {
            assert_eq!(code.number(), 100 + i as u32);
            assert_eq!(FaultCode::from_number(code.number()), Some(*code));
        }
        assert_eq!(FaultCode::ALL.last().copied(), Some(FaultCode::LinkDown));
    }
}
