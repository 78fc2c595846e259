//! The CiA 402 (IEC 61800-7-201) drive state machine, in the words of the standard: the
//! controlword (object 0x6040) the master writes, the statusword (0x6041) the drive answers
//! with, the states they encode and the transitions between them.
//!
//! ```text
//!            (0) power on
//!                 v
//!       Not ready to switch on --(1)--> Switch on disabled <-----------(15: fault reset)-- Fault
//!                                        |  ^  ^  ^                                          ^
//!                            (2 Shutdown)|  |7 |10|9, 12                                      |(14)
//!                                        v  |  |  |                                  Fault reaction active
//!                                Ready to switch on                                           ^
//!                                  (3)|  ^(6)   ^(8)                                          |(13: any fault)
//!                                     v  |      |
//!                                   Switched on |
//!                                  (4)|  ^(5)   |
//!                                     v  |      |
//!                               Operation enabled --(11 Quick stop)--> Quick stop active
//!                                                 <-(16 Enable operation)--
//! ```

/// CiA 402 error codes (object 0x603F) this crate reports.
pub mod error_code {
    /// No error.
    pub const NONE: u16 = 0x0000;
    /// Incremental position sensor fault (encoder lost).
    pub const POSITION_SENSOR: u16 = 0x7305;
    /// Communication: life guard / process-data watchdog expired.
    pub const COMMUNICATION: u16 = 0x8130;
    /// Generic error, the default of an injected drive fault.
    pub const GENERIC: u16 = 0x1000;
    /// Following error beyond the following error window (0x6065).
    pub const FOLLOWING_ERROR: u16 = 0x8611;

    /// What an error code means, after the emergency error codes of CiA 301 and the drive
    /// codes of CiA 402 (IEC 61800-7-201 Annex D): the exact code where the standard names
    /// it, else its group. Manufacturer-specific codes (0xFF00-0xFFFF) say so.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub const fn describe(code: u16) -> &'static str {
        match code {
            0x0000 => "no error",
            0x1000 => "generic error",
            0x2310 => "continuous over-current",
            0x2311 => "continuous over-current (device internal)",
            0x2320 => "short circuit or earth leakage at the output",
            0x2330 => "earth leakage",
            0x3110 => "mains over-voltage",
            0x3120 => "mains under-voltage",
            0x3130 => "mains phase failure",
            0x3210 => "DC link over-voltage",
            0x3220 => "DC link under-voltage",
            0x4210 => "excess temperature of the device",
            0x4310 => "excess temperature of the drive",
            0x4410 => "excess temperature of the supply",
            0x5112 => "supply voltage of the electronics low",
            0x5530 => "data storage (non-volatile memory) failure",
            0x6010 => "software reset (watchdog)",
            0x6320 => "parameter error",
            0x7121 => "motor blocked",
            0x7305 => "incremental position sensor 1 fault",
            0x7310 => "speed sensor fault",
            0x7320 => "position sensor fault",
            0x7500 => "communication error",
            0x8110 => "process data overrun",
            0x8130 => "life guard or process data watchdog expired",
            0x8400 => "velocity speed control error",
            0x8611 => "following error",
            0x8612 => "reference limit",
            0x9000 => "external error",
            0xFF00..=0xFFFF => "manufacturer-specific error",
            _ => match code >> 12 {
                0x1 => "generic error",
                0x2 => "current",
                0x3 => "voltage",
                0x4 => "temperature",
                0x5 => "device hardware",
                0x6 => "device software",
                0x7 => "additional modules (sensors, brake)",
                0x8 => "monitoring (communication, control)",
                0x9 => "external error",
                0xF => "additional functions",
                _ => "unknown error code",
            },
        }
    }
}

/// The controlword (object 0x6040).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ControlWord(pub u16);

impl ControlWord {
    /// Bit 0: switch on.
    pub const SWITCH_ON: u16 = 1 << 0;
    /// Bit 1: enable voltage.
    pub const ENABLE_VOLTAGE: u16 = 1 << 1;
    /// Bit 2: quick stop, active low (0 requests a quick stop).
    pub const QUICK_STOP: u16 = 1 << 2;
    /// Bit 3: enable operation.
    pub const ENABLE_OPERATION: u16 = 1 << 3;
    /// Bit 7: fault reset, acts on its rising edge.
    pub const FAULT_RESET: u16 = 1 << 7;

    /// "Shutdown" (0b0110): transitions 2, 6, 8.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub const fn shutdown() -> Self {
        Self(Self::QUICK_STOP | Self::ENABLE_VOLTAGE)
    }
    /// "Switch on" (0b0111): transition 3. Same bits as "disable operation".
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub const fn switch_on() -> Self {
        Self(Self::QUICK_STOP | Self::ENABLE_VOLTAGE | Self::SWITCH_ON)
    }
    /// "Disable operation" (0b0111): transition 5.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub const fn disable_operation() -> Self {
        Self::switch_on()
    }
    /// "Enable operation" (0b1111): transitions 4 and 16 (and 3 from ready to switch on).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub const fn enable_operation() -> Self {
        Self(Self::ENABLE_OPERATION | Self::QUICK_STOP | Self::ENABLE_VOLTAGE | Self::SWITCH_ON)
    }
    /// "Disable voltage" (0b0000): transitions 7, 9, 10, 12.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub const fn disable_voltage() -> Self {
        Self(0)
    }
    /// "Quick stop" (0b0010): transitions 7, 10, 11.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub const fn quick_stop() -> Self {
        Self(Self::ENABLE_VOLTAGE)
    }
    /// "Fault reset" (bit 7): transition 15 on its rising edge.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub const fn fault_reset() -> Self {
        Self(Self::FAULT_RESET)
    }

    /// Whether bit 7 (fault reset) is set.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub const fn fault_reset_requested(self) -> bool {
        self.0 & Self::FAULT_RESET != 0
    }

    /// The device-control command that bits 0 to 3 encode (bit 7 is edge-triggered and
    /// read separately).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub const fn command(self) -> DeviceCommand {
        let bits = self.0;
        if bits & Self::ENABLE_VOLTAGE == 0 {
            DeviceCommand::DisableVoltage
        } else if bits & Self::QUICK_STOP == 0 {
            DeviceCommand::QuickStop
        } else if bits & Self::SWITCH_ON == 0 {
            DeviceCommand::Shutdown
        } else if bits & Self::ENABLE_OPERATION == 0 {
            DeviceCommand::SwitchOn
        } else {
            DeviceCommand::EnableOperation
        }
    }
}

/// The device-control commands of the controlword (bits 0 to 3).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DeviceCommand {
    /// 0bx110.
    Shutdown,
    /// 0b0111: "switch on", and "disable operation" from operation enabled.
    SwitchOn,
    /// 0b1111: "switch on + enable operation".
    EnableOperation,
    /// 0bxx0x.
    DisableVoltage,
    /// 0bx01x.
    QuickStop,
}

/// The states of the drive (statusword bits 0-3, 5, 6).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Cia402State {
    /// Power-up, self test; no command accepted.
    NotReadyToSwitchOn,
    /// Initialised; the power stage may not be switched on.
    SwitchOnDisabled,
    /// High voltage may be applied; power stage off.
    ReadyToSwitchOn,
    /// Power stage on; no torque.
    SwitchedOn,
    /// The drive follows its set-points.
    OperationEnabled,
    /// Stopping on the quick-stop ramp.
    QuickStopActive,
    /// A fault was detected; the drive runs its fault reaction.
    FaultReactionActive,
    /// Faulted; torque off; waits for a fault reset.
    Fault,
}

impl Cia402State {
    /// The state after a device-control command, for the transitions the master commands
    /// (2 to 12 and 16). Commands a state does not react to leave it unchanged. Automatic
    /// transitions (0, 1, 13, 14) and the fault reset (15) belong to the drive; see
    /// [`after_fault_reset`](Self::after_fault_reset).
    ///
    /// "Switch on + enable operation" from ready to switch on is transition 3 here; a
    /// simulated drive makes one transition per cycle, so transition 4 follows next cycle.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub const fn after_command(self, command: DeviceCommand) -> Self {
        use Cia402State as S;
        use DeviceCommand as C;
        match (self, command) {
            (S::SwitchOnDisabled, C::Shutdown) => S::ReadyToSwitchOn, // 2
            (S::ReadyToSwitchOn, C::SwitchOn | C::EnableOperation) => S::SwitchedOn, // 3
            (S::SwitchedOn, C::EnableOperation) => S::OperationEnabled, // 4
            (S::OperationEnabled, C::SwitchOn) => S::SwitchedOn,      // 5
            (S::SwitchedOn, C::Shutdown) => S::ReadyToSwitchOn,       // 6
            (S::ReadyToSwitchOn, C::DisableVoltage | C::QuickStop) => S::SwitchOnDisabled, // 7
            (S::OperationEnabled, C::Shutdown) => S::ReadyToSwitchOn, // 8
            (S::OperationEnabled, C::DisableVoltage) => S::SwitchOnDisabled, // 9
            (S::SwitchedOn, C::DisableVoltage | C::QuickStop) => S::SwitchOnDisabled, // 10
            (S::OperationEnabled, C::QuickStop) => S::QuickStopActive, // 11
            (S::QuickStopActive, C::DisableVoltage) => S::SwitchOnDisabled, // 12
            (S::QuickStopActive, C::EnableOperation) => S::OperationEnabled, // 16
            (state, _) => state,
        }
    }

    /// The state after a fault reset (rising edge of controlword bit 7): transition 15
    /// from fault; other states do not react.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub const fn after_fault_reset(self) -> Self {
        match self {
            Self::Fault => Self::SwitchOnDisabled,
            state => state,
        }
    }

    /// Whether the motor is under control (torque applied) in this state.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub const fn is_torque_on(self) -> bool {
        matches!(self, Self::OperationEnabled | Self::QuickStopActive)
    }

    /// Whether the drive is faulted (fault reaction active or fault).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub const fn is_fault(self) -> bool {
        matches!(self, Self::FaultReactionActive | Self::Fault)
    }

    /// The controlword that walks a drive in this state one transition towards operation
    /// enabled (`enable`) or towards switch on disabled (`!enable`). A faulted drive gets
    /// "disable voltage": resetting a fault is the master's explicit decision
    /// ([`ControlWord::fault_reset`]).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub const fn controlword_towards(self, enable: bool) -> ControlWord {
        if !enable {
            return ControlWord::disable_voltage();
        }
        match self {
            Self::SwitchOnDisabled => ControlWord::shutdown(),
            Self::ReadyToSwitchOn => ControlWord::switch_on(),
            Self::SwitchedOn | Self::OperationEnabled => ControlWord::enable_operation(),
            Self::NotReadyToSwitchOn
            | Self::QuickStopActive
            | Self::FaultReactionActive
            | Self::Fault => ControlWord::disable_voltage(),
        }
    }
}

/// The statusword (object 0x6041).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct StatusWord(pub u16);

impl StatusWord {
    /// Bit 0: ready to switch on.
    pub const READY_TO_SWITCH_ON: u16 = 1 << 0;
    /// Bit 1: switched on.
    pub const SWITCHED_ON: u16 = 1 << 1;
    /// Bit 2: operation enabled.
    pub const OPERATION_ENABLED: u16 = 1 << 2;
    /// Bit 3: fault.
    pub const FAULT: u16 = 1 << 3;
    /// Bit 4: voltage enabled (high voltage applied).
    pub const VOLTAGE_ENABLED: u16 = 1 << 4;
    /// Bit 5: quick stop, active low.
    pub const QUICK_STOP: u16 = 1 << 5;
    /// Bit 6: switch on disabled.
    pub const SWITCH_ON_DISABLED: u16 = 1 << 6;
    /// Bit 7: warning.
    pub const WARNING: u16 = 1 << 7;
    /// Bit 9: remote (the controlword is in charge).
    pub const REMOTE: u16 = 1 << 9;
    /// Bit 10: target reached; in quick stop active, the drive stands at the end of its
    /// quick-stop ramp.
    pub const TARGET_REACHED: u16 = 1 << 10;
    /// Bit 11: internal limit active (here: the torque limit).
    pub const INTERNAL_LIMIT: u16 = 1 << 11;

    /// Bit 10, target reached.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub const fn target_reached(self) -> bool {
        self.0 & Self::TARGET_REACHED != 0
    }

    /// The state bits of `state` (bits 0-3, 5, 6) as the standard's table gives them.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub const fn state_bits(state: Cia402State) -> u16 {
        match state {
            Cia402State::NotReadyToSwitchOn => 0x0000,
            Cia402State::SwitchOnDisabled => 0x0040,
            Cia402State::ReadyToSwitchOn => 0x0021,
            Cia402State::SwitchedOn => 0x0023,
            Cia402State::OperationEnabled => 0x0027,
            Cia402State::QuickStopActive => 0x0007,
            Cia402State::FaultReactionActive => 0x000F,
            Cia402State::Fault => 0x0008,
        }
    }

    /// The state the statusword encodes (masks 0x4F / 0x6F of the standard). Patterns the
    /// standard does not define read as not ready to switch on.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub const fn state(self) -> Cia402State {
        let bits = self.0;
        match bits & 0x4F {
            0x00 => return Cia402State::NotReadyToSwitchOn,
            0x40 => return Cia402State::SwitchOnDisabled,
            0x0F => return Cia402State::FaultReactionActive,
            0x08 => return Cia402State::Fault,
            _ => {}
        }
        match bits & 0x6F {
            0x21 => Cia402State::ReadyToSwitchOn,
            0x23 => Cia402State::SwitchedOn,
            0x27 => Cia402State::OperationEnabled,
            0x07 => Cia402State::QuickStopActive,
            _ => Cia402State::NotReadyToSwitchOn,
        }
    }

    /// Whether `flag` (one of the bit constants) is set.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub const fn has(self, flag: u16) -> bool {
        self.0 & flag != 0
    }
}
