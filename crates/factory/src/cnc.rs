//! The machine's status in the terms of OPC 40502 (OPC UA for CNC Systems): its
//! enumerations' values as the companion specification's NodeSet numbers them, and the
//! engineering units (UNECE codes) of its analogue variables.

use rtcnc_api::models::Status;

/// `CncChannelStatus`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ChannelStatus {
    /// A program or MDI line runs.
    Active = 0,
    /// Held, paused, or waiting for the machine logic.
    Interrupted = 1,
    /// At rest.
    Reset = 2,
}

/// `CncChannelProgramStatus`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ProgramStatus {
    /// No program runs.
    Stopped = 0,
    /// A program runs.
    Running = 1,
    /// It waits for the machine logic (M/S/T hand-shake).
    Waiting = 2,
    /// Held (feed hold) or paused (M0/M1, single block).
    Interrupted = 3,
    /// Stopped by an e-stop or a fault before its end.
    Canceled = 4,
}

/// `CncOperationMode`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OperationMode {
    /// Jog, handwheel, homing.
    Manual = 0,
    /// MDI ("MDA").
    Mda = 1,
    /// Programs.
    Automatic = 2,
}

/// `CncAxisStatus`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AxisStatus {
    /// Standing, drives on.
    InPosition = 0,
    /// Moving.
    Moving = 1,
    /// Drives off (e-stop, not ready).
    Parked = 2,
}

/// `CncSpindleStatus`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SpindleStatus {
    /// Off, or standing.
    Stopped = 0,
    /// At its commanded speed (within 2 %).
    InTargetArea = 1,
    /// Below it.
    Accelerating = 2,
    /// Above it.
    Decelerating = 3,
}

/// `CncSpindleTurnDirection`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TurnDirection {
    /// Off.
    None = 0,
    /// Clockwise (M3).
    Cw = 1,
    /// Counter-clockwise (M4).
    Ccw = 2,
}

/// The channel's status.
pub fn channel_status(s: &Status) -> ChannelStatus {
    match s.state.as_str() {
        "running" => ChannelStatus::Active,
        "held" | "paused" | "waiting_for_logic" => ChannelStatus::Interrupted,
        _ => ChannelStatus::Reset,
    }
}

/// The program's status. A program that an e-stop or a fault stopped before its end
/// reads `Canceled` until the next reset takes the machine back to idle.
pub fn program_status(s: &Status) -> ProgramStatus {
    match s.state.as_str() {
        "running" => ProgramStatus::Running,
        "held" | "paused" => ProgramStatus::Interrupted,
        "waiting_for_logic" => ProgramStatus::Waiting,
        "estop" | "fault" if s.mode == "auto" && s.line > 0 && !s.program_ended => {
            ProgramStatus::Canceled
        }
        _ => ProgramStatus::Stopped,
    }
}

/// The operation mode.
pub fn operation_mode(s: &Status) -> OperationMode {
    match s.mode.as_str() {
        "auto" => OperationMode::Automatic,
        "mdi" => OperationMode::Mda,
        _ => OperationMode::Manual,
    }
}

/// An axis's status from its speed (units/s) and whether the drives are on.
pub fn axis_status(ready: bool, speed: f64) -> AxisStatus {
    if !ready {
        AxisStatus::Parked
    } else if speed.abs() > 1e-6 {
        AxisStatus::Moving
    } else {
        AxisStatus::InPosition
    }
}

/// The spindle's status: measured against commanded speed.
pub fn spindle_status(s: &Status) -> SpindleStatus {
    let target = s.spindle.command_rpm.abs();
    let actual = s.spindle.rpm.abs();
    if !s.spindle.on || target == 0.0 {
        if actual > 0.5 {
            SpindleStatus::Decelerating
        } else {
            SpindleStatus::Stopped
        }
    } else if (actual - target).abs() <= 0.02 * target {
        SpindleStatus::InTargetArea
    } else if actual < target {
        SpindleStatus::Accelerating
    } else {
        SpindleStatus::Decelerating
    }
}

/// The spindle's direction.
pub fn turn_direction(s: &Status) -> TurnDirection {
    match s.spindle.direction.as_str() {
        "cw" => TurnDirection::Cw,
        "ccw" => TurnDirection::Ccw,
        _ => TurnDirection::None,
    }
}

/// G or M codes as numbers: `G1` → 1, `G64` → 64; a code with a decimal part (`G59.1`,
/// `G61.1`) as ten times its number (591, 611), since the companion model's arrays are
/// UInt32. Text that is not a code is left out.
pub fn code_numbers(codes: &[String], letter: char) -> Vec<u32> {
    codes
        .iter()
        .filter_map(|c| {
            let rest = c
                .trim()
                .strip_prefix([letter, letter.to_ascii_lowercase()])?;
            match rest.split_once('.') {
                None => rest.parse::<u32>().ok(),
                Some((whole, tenth)) if tenth.len() == 1 => {
                    let w = whole.parse::<u32>().ok()?;
                    let t = tenth.parse::<u32>().ok()?;
                    w.checked_mul(10)?.checked_add(t)
                }
                Some(_) => None,
            }
        })
        .collect()
}

/// `G54`..`G59.3` as 1..9 (0: unknown).
pub fn work_system_number(name: &str) -> u32 {
    rtcnc_api::work_system_number(name).unwrap_or(0)
}

/// An engineering unit (OPC UA's EUInformation with the UNECE common code).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Unit {
    /// UNECE common code (`MMT`).
    pub code: &'static str,
    /// Shown to people (`mm`).
    pub display: &'static str,
    /// What it is (`millimetre`).
    pub description: &'static str,
}

impl Unit {
    /// OPC UA's `UnitId` of a UNECE code: its characters' bytes, big-endian (OPC 10000-8,
    /// 5.6.3).
    pub fn unit_id(self) -> i32 {
        self.code
            .bytes()
            .fold(0i32, |acc, b| acc.wrapping_shl(8) | i32::from(b))
    }
}

/// mm.
pub const MILLIMETRE: Unit = Unit {
    code: "MMT",
    display: "mm",
    description: "millimetre",
};
/// Degrees.
pub const DEGREE: Unit = Unit {
    code: "DD",
    display: "°",
    description: "degree [unit of angle]",
};
/// mm/min.
pub const MILLIMETRE_PER_MINUTE: Unit = Unit {
    code: "H81",
    display: "mm/min",
    description: "millimetre per minute",
};
/// %.
pub const PERCENT: Unit = Unit {
    code: "P1",
    display: "%",
    description: "percent",
};
/// rpm.
pub const REVOLUTIONS_PER_MINUTE: Unit = Unit {
    code: "RPM",
    display: "r/min",
    description: "revolutions per minute",
};

#[cfg(test)]
mod tests {
    use super::*;

    /// The enumerations' values against the NodeSet's `Definition`s, read from the
    /// committed XML (the reference), not restated.
    #[test]
    fn enumerations_match_the_nodeset() {
        let xml = include_str!("../nodesets/Opc.Ua.CNC.NodeSet.xml");
        let fields = |name: &str| -> Vec<(String, i64)> {
            let start = xml
                .find(&format!("BrowseName=\"1:{name}\""))
                .unwrap_or_else(|| panic!("{name} in the NodeSet"));
            let def = &xml[start..];
            let def = &def[def.find("<Definition").unwrap()..def.find("</Definition>").unwrap()];
            def.split("<Field ")
                .skip(1)
                .map(|f| {
                    let attr = |a: &str| {
                        let i = f.find(&format!("{a}=\"")).unwrap() + a.len() + 2;
                        f[i..i + f[i..].find('"').unwrap()].to_string()
                    };
                    (attr("Name"), attr("Value").parse().unwrap())
                })
                .collect()
        };
        let check = |name: &str, ours: &[(&str, i64)]| {
            let theirs = fields(name);
            for (n, v) in ours {
                assert!(
                    theirs.iter().any(|(tn, tv)| tn == n && tv == v),
                    "{name}.{n} = {v} is not in the NodeSet: {theirs:?}"
                );
            }
        };
        check(
            "CncChannelStatus",
            &[
                ("Active", ChannelStatus::Active as i64),
                ("Interrupted", ChannelStatus::Interrupted as i64),
                ("Reset", ChannelStatus::Reset as i64),
            ],
        );
        check(
            "CncChannelProgramStatus",
            &[
                ("Stopped", ProgramStatus::Stopped as i64),
                ("Running", ProgramStatus::Running as i64),
                ("Waiting", ProgramStatus::Waiting as i64),
                ("Interrupted", ProgramStatus::Interrupted as i64),
                ("Canceled", ProgramStatus::Canceled as i64),
            ],
        );
        check(
            "CncOperationMode",
            &[
                ("Manual", OperationMode::Manual as i64),
                ("MDA", OperationMode::Mda as i64),
                ("Automatic", OperationMode::Automatic as i64),
            ],
        );
        check(
            "CncAxisStatus",
            &[
                ("InPosition", AxisStatus::InPosition as i64),
                ("Moving", AxisStatus::Moving as i64),
                ("Parked", AxisStatus::Parked as i64),
            ],
        );
        check(
            "CncSpindleStatus",
            &[
                ("Stopped", SpindleStatus::Stopped as i64),
                ("InTargetArea", SpindleStatus::InTargetArea as i64),
                ("Accelerating", SpindleStatus::Accelerating as i64),
                ("Decelerating", SpindleStatus::Decelerating as i64),
            ],
        );
        check(
            "CncSpindleTurnDirection",
            &[
                ("None", TurnDirection::None as i64),
                ("CW", TurnDirection::Cw as i64),
                ("CCW", TurnDirection::Ccw as i64),
            ],
        );
    }

    fn status(state: &str, mode: &str, line: u32, ended: bool) -> Status {
        let mut s: Status = serde_json::from_value(serde_json::json!({
            "machine": "m", "connected": true, "cycle": 0, "time_s": 0.0, "state": state,
            "mode": mode, "line": line, "program": "p.ngc", "program_ended": ended,
            "ready": true, "estop_input": false, "machine_position": {}, "work_position": {},
            "distance_to_go": {}, "joints": [], "path_speed": 0.0,
            "overrides": {"feed": 1.0, "rapid": 1.0, "spindle": 1.0},
            "spindle": {"on": false, "direction": "off", "rpm": 0.0, "command_rpm": 0.0},
            "mist": false, "flood": false, "tool": 0, "modal": null, "digital_inputs": 0,
            "digital_outputs": 0, "analog_inputs": [], "plc_watch": [], "single_block": false,
            "optional_stop": false, "block_delete": false, "logic_hold": false, "hold": null,
            "hold_message": null, "fault_count": 0, "last_fault": null, "deadline_misses": 0,
            "lease_holder": null,
            "link": {"client_losses": 0, "events_dropped": 0, "trace_dropped": 0}
        }))
        .unwrap();
        s.state = state.into();
        s
    }

    /// OPC 40502's meanings: a program stopped by an e-stop before its end is Canceled; one
    /// that ended, or an e-stop at rest, is Stopped; a feed hold interrupts the channel.
    #[test]
    fn program_and_channel_status() {
        let p = |st, mode, line, ended| program_status(&status(st, mode, line, ended));
        assert_eq!(p("estop", "auto", 12, false), ProgramStatus::Canceled);
        assert_eq!(p("estop", "auto", 12, true), ProgramStatus::Stopped);
        assert_eq!(p("estop", "manual", 0, false), ProgramStatus::Stopped);
        assert_eq!(p("held", "auto", 3, false), ProgramStatus::Interrupted);
        assert_eq!(
            p("waiting_for_logic", "auto", 3, false),
            ProgramStatus::Waiting
        );
        let c = |st| channel_status(&status(st, "auto", 1, false));
        assert_eq!(c("held"), ChannelStatus::Interrupted);
        assert_eq!(c("running"), ChannelStatus::Active);
        assert_eq!(c("idle"), ChannelStatus::Reset);
    }

    #[test]
    fn spindle_status_against_its_command() {
        let mut s = status("running", "auto", 1, false);
        s.spindle.on = true;
        s.spindle.command_rpm = 1000.0;
        for (rpm, want) in [
            (500.0, SpindleStatus::Accelerating),
            (985.0, SpindleStatus::InTargetArea),
            (1015.0, SpindleStatus::InTargetArea),
            (1100.0, SpindleStatus::Decelerating),
        ] {
            s.spindle.rpm = rpm;
            assert_eq!(spindle_status(&s), want, "{rpm} rpm");
        }
        s.spindle.on = false;
        s.spindle.command_rpm = 0.0;
        s.spindle.rpm = 300.0;
        assert_eq!(
            spindle_status(&s),
            SpindleStatus::Decelerating,
            "coasting down"
        );
        s.spindle.rpm = 0.0;
        assert_eq!(spindle_status(&s), SpindleStatus::Stopped);
    }

    #[test]
    fn unece_unit_ids() {
        // OPC 10000-8's own example: "MTR" (metre) is 5067858.
        let metre = Unit {
            code: "MTR",
            display: "m",
            description: "metre",
        };
        assert_eq!(metre.unit_id(), 5067858);
        // Two-character codes: 'P' 0x50, '1' 0x31.
        assert_eq!(PERCENT.unit_id(), 0x5031);
    }

    #[test]
    fn codes() {
        let g: Vec<String> = ["G1", "G17", "G59.1", "G61.1", "G64", "M3", "x", "G1.25"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        assert_eq!(code_numbers(&g, 'G'), vec![1, 17, 591, 611, 64]);
        assert_eq!(code_numbers(&g, 'M'), vec![3]);
        assert_eq!(work_system_number("G59.3"), 9);
        assert_eq!(work_system_number("G54"), 1);
    }
}
