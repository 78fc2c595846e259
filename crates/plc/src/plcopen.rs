//! PLCopen Motion Control part 1 on auxiliary axes (a tool carousel, a conveyor, a pallet
//! changer): the axis state diagram and the blocks MC_Power, MC_Home, MC_Reset, MC_Stop,
//! MC_Halt, MC_MoveAbsolute, MC_MoveRelative, MC_MoveAdditive, MC_MoveVelocity,
//! MC_ReadActualPosition, MC_ReadStatus and MC_ReadAxisError.
//!
//! An axis is configured in [`crate::PlcConfig`] (`[axes.NAME]` with its limits) and bound
//! to an `AXIS_REF` variable of the program. Its set-point comes from the jerk-limited
//! on-line trajectory generator of `rtcnc-motion`, within the axis's limits and those the
//! block asks for. Every scan first advances each axis to the scan's time, then runs the
//! programs: a command given in a scan starts at that scan's time. Without a drive the
//! set-point is also the actual position ([`crate::Runtime::axis`] gives it to whoever
//! drives the axis); with one ([`crate::Runtime::set_axis_drive`], the kernel's auxiliary
//! joints) the drive's feedback is the actual position, MC_Power waits for the drive to be
//! enabled, and a drive that faults or drops out puts the axis into ErrorStop.
//! Only buffer mode Aborting is offered: a new motion command takes the axis over and the
//! block that had it reports CommandAborted.

use rtcnc_motion::otg::{Limits, OnlineAxis, State};
use serde::Deserialize;

use crate::stdfb::{Cells, StdFb};

/// Limits of an auxiliary axis, in its units (mm or degrees) and seconds.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisConfig {
    /// Largest velocity.
    pub velocity: f64,
    /// Largest acceleration (and deceleration).
    pub acceleration: f64,
    /// Largest jerk.
    pub jerk: f64,
    /// Software limits: a target outside them is refused, a velocity move stops at them
    /// with an axis error.
    #[serde(default)]
    pub min_position: Option<f64>,
    /// See `min_position`.
    #[serde(default)]
    pub max_position: Option<f64>,
    /// A modulo (rotary) axis: positions count from 0 up to this period (e.g. 360), and
    /// MC_MoveAbsolute's Direction picks the way round. No software limits then.
    #[serde(default)]
    pub modulo: Option<f64>,
}

/// The PLCopen state of an axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AxisState {
    /// Not powered.
    Disabled,
    /// Powered, at rest, no command.
    Standstill,
    /// MC_Home is running.
    Homing,
    /// Moving to a position (MC_Move*, MC_Halt).
    DiscreteMotion,
    /// Moving at a velocity (MC_MoveVelocity).
    ContinuousMotion,
    /// MC_Stop holds the axis.
    Stopping,
    /// An axis error stopped it; MC_Reset clears it.
    ErrorStop,
}

/// What the drive of an auxiliary axis reports each period, in the drive's own units
/// (before the home offset MC_Home sets).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DriveFeedback {
    /// Actual position.
    pub position: f64,
    /// The drive is in operation enabled (following its set-point).
    pub enabled: bool,
    /// The drive is faulted.
    pub faulted: bool,
}

/// What [`crate::Runtime::axis`] reports about an axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisStatus {
    /// PLCopen state.
    pub state: AxisState,
    /// Set-point position (also the actual position when no drive reports).
    pub position: f64,
    /// The set-point in the drive's units: `position` less the home offset.
    pub drive_position: f64,
    /// Actual position: the drive's, plus the home offset; the set-point without a drive.
    pub actual_position: f64,
    /// MC_Power asks for the drive to be enabled.
    pub power_requested: bool,
    /// Set-point velocity.
    pub velocity: f64,
    /// Set-point acceleration.
    pub acceleration: f64,
    /// Axis error (0 none): see [`error_id`].
    pub error_id: u16,
    /// MC_Home has completed since power-up.
    pub homed: bool,
}

/// ErrorID values the blocks give (PLCopen leaves them to the supplier).
pub mod error_id {
    /// The AXIS_REF names no configured axis.
    pub const NO_AXIS: u16 = 0x0001;
    /// The axis is not powered (Disabled).
    pub const DISABLED: u16 = 0x0002;
    /// The axis is in ErrorStop: MC_Reset first.
    pub const ERROR_STOP: u16 = 0x0003;
    /// MC_Stop holds the axis (Stopping).
    pub const STOPPING: u16 = 0x0004;
    /// A velocity, acceleration, deceleration or jerk is negative or not a number, or a
    /// position is not a number.
    pub const INVALID_PARAMETER: u16 = 0x0005;
    /// The target lies outside the axis's software limits.
    pub const OUTSIDE_LIMITS: u16 = 0x0006;
    /// Only BufferMode 0 (mcAborting) is offered.
    pub const BUFFER_MODE: u16 = 0x0007;
    /// Axis error: a velocity move reached a software limit.
    pub const LIMIT_REACHED: u16 = 0x0010;
    /// The trajectory generator refused the motion.
    pub const PROFILE: u16 = 0x0011;
    /// Axis error: the drive faulted, or left operation enabled while the axis was powered.
    pub const DRIVE: u16 = 0x0012;
    /// MC_Home needs the axis at Standstill.
    pub const NOT_STANDSTILL: u16 = 0x0008;
}

/// One configured axis at run time.
#[derive(Debug, Clone)]
pub(crate) struct Axis {
    pub name: String,
    config: AxisConfig,
    otg: OnlineAxis,
    state: AxisState,
    error_id: u16,
    homed: bool,
    /// Number of the command that controls the axis; a new one aborts the last.
    command: u64,
    /// The last command that reached its end (target, velocity, standstill).
    finished: u64,
    /// What the running command waits for.
    goal: Goal,
    /// The target of the running discrete move (for MC_MoveAdditive).
    target: f64,
    /// Time of the last step, ns.
    last: Option<i64>,
    /// Position less drive position (set by MC_Home).
    offset: f64,
    /// The drive's last report; `None`: no drive, the set-point is the position.
    drive: Option<DriveFeedback>,
    /// MC_Power's Enable.
    power_requested: bool,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Goal {
    None,
    Position,
    Velocity,
    Halt,
    Stop,
    Home(f64),
}

fn limits_of(c: &AxisConfig) -> Limits {
    Limits::symmetric(c.velocity, c.acceleration, c.jerk)
}

impl Axis {
    pub(crate) fn new(name: &str, config: AxisConfig) -> Result<Axis, String> {
        if let Some(m) = config.modulo {
            if !(m.is_finite() && m > 0.0) {
                return Err(format!("axis '{name}': modulo must be a positive number"));
            }
            if config.min_position.is_some() || config.max_position.is_some() {
                return Err(format!(
                    "axis '{name}': a modulo axis has no software limits (remove min_position and max_position)"
                ));
            }
        }
        let otg = OnlineAxis::new(State::at_rest(0.0), limits_of(&config))
            .map_err(|e| format!("axis '{name}': {e}"))?;
        Ok(Axis {
            name: name.to_string(),
            config,
            otg,
            state: AxisState::Disabled,
            error_id: 0,
            homed: false,
            command: 0,
            finished: 0,
            goal: Goal::None,
            target: 0.0,
            last: None,
            offset: 0.0,
            drive: None,
            power_requested: false,
        })
    }

    pub(crate) fn status(&self) -> AxisStatus {
        let s = self.otg.sample();
        AxisStatus {
            state: self.state,
            position: self.wrap(s.p),
            drive_position: s.p - self.offset,
            actual_position: self.actual(),
            power_requested: self.power_requested,
            velocity: s.v,
            acceleration: s.a,
            error_id: self.error_id,
            homed: self.homed,
        }
    }

    /// Back to power-up: Disabled at the current position, no command.
    pub(crate) fn reset(&mut self) {
        let p = self.otg.sample().p;
        self.hold(p);
        self.state = AxisState::Disabled;
        self.error_id = 0;
        self.homed = false;
        self.command += 1;
        self.goal = Goal::None;
        self.last = None;
        self.power_requested = false;
    }

    /// A position as the program sees it: on a modulo axis, within 0 up to the period.
    fn wrap(&self, p: f64) -> f64 {
        match self.config.modulo {
            Some(m) => p.rem_euclid(m),
            None => p,
        }
    }

    fn actual(&self) -> f64 {
        self.wrap(match self.drive {
            Some(d) => d.position + self.offset,
            None => self.otg.sample().p,
        })
    }

    /// The set-point (not wrapped) a modulo axis goes to for `position` in `direction`
    /// (1 positive, 2 or 0 the shortest way, 3 or -1 negative, 4 the way it moves now).
    fn modulo_target(&self, m: f64, position: f64, direction: i64) -> Option<f64> {
        let s = self.otg.sample();
        let d = (position.rem_euclid(m) - s.p.rem_euclid(m)).rem_euclid(m);
        let (up, down) = (d, d - m);
        let shortest = if up <= -down { up } else { down };
        let step = match direction {
            1 => up,
            3 | -1 => {
                if d == 0.0 {
                    0.0
                } else {
                    down
                }
            }
            2 | 0 => shortest,
            4 if s.v > 0.0 => up,
            4 if s.v < 0.0 && d != 0.0 => down,
            4 => shortest,
            _ => return None,
        };
        Some(s.p + step)
    }

    /// The drive's report of this period. A drive that is not enabled does not follow the
    /// set-point, so the set-point follows it (enabling then does not jump); one that
    /// faults, or drops out while the axis is powered, is an axis error.
    pub(crate) fn set_drive(&mut self, fb: DriveFeedback) {
        let was_enabled = self.drive.is_some_and(|d| d.enabled);
        self.drive = Some(fb);
        let powered = !matches!(self.state, AxisState::Disabled | AxisState::ErrorStop);
        if powered && (fb.faulted || (was_enabled && !fb.enabled)) {
            self.error_id = error_id::DRIVE;
            self.state = AxisState::ErrorStop;
            self.goal = Goal::None;
        }
        if !fb.enabled {
            let actual = self.actual();
            if actual.is_finite() {
                self.hold(actual);
            }
        }
    }

    fn hold(&mut self, p: f64) {
        if let Ok(o) = OnlineAxis::new(State::at_rest(p), limits_of(&self.config)) {
            self.otg = o;
        }
    }

    /// Advances the set-point to time `now` and moves the state diagram on.
    pub(crate) fn step(&mut self, now: i64) {
        let dt = match self.last {
            Some(t) => now.saturating_sub(t).max(0) as f64 * 1e-9,
            None => 0.0,
        };
        self.last = Some(now);
        let s = self.otg.step(dt);
        let outside = |c: &AxisConfig| {
            c.min_position.is_some_and(|m| s.p < m && s.v < 0.0)
                || c.max_position.is_some_and(|m| s.p > m && s.v > 0.0)
        };
        if self.state == AxisState::ContinuousMotion && outside(&self.config) {
            self.error_id = error_id::LIMIT_REACHED;
            self.state = AxisState::ErrorStop;
            self.goal = Goal::Stop;
            let _ = self.otg.stop();
            return;
        }
        match (self.goal, self.otg.is_finished()) {
            (Goal::Home(p), _) => {
                // The simulated reference search ends at once: the position becomes the
                // home position (the drive stays where it is: its offset changes).
                self.offset = p - (s.p - self.offset);
                self.hold(p);
                self.homed = true;
                self.state = AxisState::Standstill;
                self.finished = self.command;
                self.goal = Goal::None;
            }
            (Goal::Position | Goal::Halt, true) => {
                self.state = AxisState::Standstill;
                self.finished = self.command;
                self.goal = Goal::None;
            }
            (Goal::Velocity, true) => {
                // InVelocity; the command goes on.
                self.finished = self.command;
            }
            (Goal::Stop, true) => {
                // Standstill reached; Stopping (or ErrorStop) lasts until released.
                self.finished = self.command;
            }
            _ => {}
        }
    }
}

// ------------------------------------------------------------------- block layouts

use crate::stdfb::Dir::{In, Out};
use crate::types::Elem::{Bool, Int, LReal, UDInt, Word};

type Member = (&'static str, crate::types::Elem, crate::stdfb::Dir);

/// Outputs of the Execute-started blocks, after their inputs.
const EXEC_OUT: [Member; 6] = [
    ("DONE", Bool, Out),
    ("BUSY", Bool, Out),
    ("ACTIVE", Bool, Out),
    ("COMMANDABORTED", Bool, Out),
    ("ERROR", Bool, Out),
    ("ERRORID", Word, Out),
];

macro_rules! layout {
    ($name:ident, [$($m:expr),* $(,)?]) => {
        pub(crate) const $name: &[Member] = &[$($m),*];
    };
}

layout!(
    POWER,
    [
        ("AXIS", UDInt, In),
        ("ENABLE", Bool, In),
        ("ENABLE_POSITIVE", Bool, In),
        ("ENABLE_NEGATIVE", Bool, In),
        ("STATUS", Bool, Out),
        ("VALID", Bool, Out),
        ("ERROR", Bool, Out),
        ("ERRORID", Word, Out),
    ]
);
layout!(
    HOME,
    [
        ("AXIS", UDInt, In),
        ("EXECUTE", Bool, In),
        ("POSITION", LReal, In),
        ("BUFFERMODE", Int, In),
        EXEC_OUT[0],
        EXEC_OUT[1],
        EXEC_OUT[2],
        EXEC_OUT[3],
        EXEC_OUT[4],
        EXEC_OUT[5],
    ]
);
layout!(
    STOP,
    [
        ("AXIS", UDInt, In),
        ("EXECUTE", Bool, In),
        ("DECELERATION", LReal, In),
        ("JERK", LReal, In),
        EXEC_OUT[0],
        EXEC_OUT[1],
        EXEC_OUT[2],
        EXEC_OUT[3],
        EXEC_OUT[4],
        EXEC_OUT[5],
    ]
);
layout!(
    HALT,
    [
        ("AXIS", UDInt, In),
        ("EXECUTE", Bool, In),
        ("DECELERATION", LReal, In),
        ("JERK", LReal, In),
        ("BUFFERMODE", Int, In),
        EXEC_OUT[0],
        EXEC_OUT[1],
        EXEC_OUT[2],
        EXEC_OUT[3],
        EXEC_OUT[4],
        EXEC_OUT[5],
    ]
);
layout!(
    MOVE_ABSOLUTE,
    [
        ("AXIS", UDInt, In),
        ("EXECUTE", Bool, In),
        ("CONTINUOUSUPDATE", Bool, In),
        ("POSITION", LReal, In),
        ("VELOCITY", LReal, In),
        ("ACCELERATION", LReal, In),
        ("DECELERATION", LReal, In),
        ("JERK", LReal, In),
        ("DIRECTION", Int, In),
        ("BUFFERMODE", Int, In),
        EXEC_OUT[0],
        EXEC_OUT[1],
        EXEC_OUT[2],
        EXEC_OUT[3],
        EXEC_OUT[4],
        EXEC_OUT[5],
    ]
);
layout!(
    MOVE_DISTANCE,
    [
        ("AXIS", UDInt, In),
        ("EXECUTE", Bool, In),
        ("CONTINUOUSUPDATE", Bool, In),
        ("DISTANCE", LReal, In),
        ("VELOCITY", LReal, In),
        ("ACCELERATION", LReal, In),
        ("DECELERATION", LReal, In),
        ("JERK", LReal, In),
        ("BUFFERMODE", Int, In),
        EXEC_OUT[0],
        EXEC_OUT[1],
        EXEC_OUT[2],
        EXEC_OUT[3],
        EXEC_OUT[4],
        EXEC_OUT[5],
    ]
);
layout!(
    MOVE_VELOCITY,
    [
        ("AXIS", UDInt, In),
        ("EXECUTE", Bool, In),
        ("CONTINUOUSUPDATE", Bool, In),
        ("VELOCITY", LReal, In),
        ("ACCELERATION", LReal, In),
        ("DECELERATION", LReal, In),
        ("JERK", LReal, In),
        ("DIRECTION", Int, In),
        ("BUFFERMODE", Int, In),
        ("INVELOCITY", Bool, Out),
        EXEC_OUT[1],
        EXEC_OUT[2],
        EXEC_OUT[3],
        EXEC_OUT[4],
        EXEC_OUT[5],
    ]
);
layout!(
    RESET,
    [
        ("AXIS", UDInt, In),
        ("EXECUTE", Bool, In),
        ("DONE", Bool, Out),
        ("BUSY", Bool, Out),
        ("ERROR", Bool, Out),
        ("ERRORID", Word, Out),
    ]
);
layout!(
    READ_POSITION,
    [
        ("AXIS", UDInt, In),
        ("ENABLE", Bool, In),
        ("VALID", Bool, Out),
        ("BUSY", Bool, Out),
        ("ERROR", Bool, Out),
        ("ERRORID", Word, Out),
        ("POSITION", LReal, Out),
    ]
);
layout!(
    READ_STATUS,
    [
        ("AXIS", UDInt, In),
        ("ENABLE", Bool, In),
        ("VALID", Bool, Out),
        ("BUSY", Bool, Out),
        ("ERROR", Bool, Out),
        ("ERRORID", Word, Out),
        ("ERRORSTOP", Bool, Out),
        ("DISABLED", Bool, Out),
        ("STOPPING", Bool, Out),
        ("HOMING", Bool, Out),
        ("STANDSTILL", Bool, Out),
        ("DISCRETEMOTION", Bool, Out),
        ("CONTINUOUSMOTION", Bool, Out),
        ("SYNCHRONIZEDMOTION", Bool, Out),
    ]
);
layout!(
    READ_ERROR,
    [
        ("AXIS", UDInt, In),
        ("ENABLE", Bool, In),
        ("VALID", Bool, Out),
        ("BUSY", Bool, Out),
        ("ERROR", Bool, Out),
        ("ERRORID", Word, Out),
        ("AXISERRORID", Word, Out),
    ]
);

/// Hidden cells after the members: previous Execute, the command number, and whether
/// the outputs were shown with Execute already FALSE.
pub(crate) const HIDDEN: u32 = 3;

// ------------------------------------------------------------------- running the blocks

fn f(v: u64) -> f64 {
    f64::from_bits(v)
}

/// The cells of one block instance, by member index.
struct Slots<'a, 'b>(&'a mut Cells<'b>);

impl Slots<'_, '_> {
    fn get(&self, i: usize) -> u64 {
        self.0.get(i)
    }
    fn set(&mut self, i: usize, v: u64) {
        self.0.set(i, v)
    }
    fn flag(&self, i: usize) -> bool {
        self.get(i) & 1 != 0
    }
}

/// Runs a motion block on its instance cells; `axes` are the configured axes (an
/// AXIS_REF holds the axis number, 1-based).
pub(crate) fn run(fb: StdFb, s: &mut Cells, axes: &mut [Axis]) {
    let n = fb.members().len();
    let mut s = Slots(s);
    let axis = (s.get(0) as usize)
        .checked_sub(1)
        .and_then(|i| axes.get_mut(i));
    match fb {
        StdFb::McPower => power(&mut s, axis),
        StdFb::McReadActualPosition | StdFb::McReadStatus | StdFb::McReadAxisError => {
            read(fb, &mut s, axis)
        }
        _ => execute(fb, &mut s, n, axis),
    }
}

fn power(s: &mut Slots, axis: Option<&mut Axis>) {
    let enable = s.flag(1);
    let Some(ax) = axis else {
        s.set(4, 0);
        s.set(5, 0);
        s.set(6, enable as u64);
        s.set(7, if enable { error_id::NO_AXIS as u64 } else { 0 });
        return;
    };
    ax.power_requested = enable;
    // With a drive, the axis is powered once the drive is enabled.
    let drive_ready = ax.drive.is_none_or(|d| d.enabled && !d.faulted);
    if enable && ax.state == AxisState::Disabled && (drive_ready || ax.error_id != 0) {
        ax.state = if ax.error_id != 0 {
            AxisState::ErrorStop
        } else {
            AxisState::Standstill
        };
    } else if !enable && ax.state != AxisState::Disabled {
        // The drive is switched off where it is: every command ends.
        let p = ax.otg.sample().p;
        ax.hold(p);
        ax.state = AxisState::Disabled;
        ax.command += 1;
        ax.goal = Goal::None;
    }
    s.set(4, (ax.state != AxisState::Disabled) as u64);
    s.set(5, enable as u64);
    s.set(6, 0);
    s.set(7, 0);
}

fn read(fb: StdFb, s: &mut Slots, axis: Option<&mut Axis>) {
    let enable = s.flag(1);
    let clear = |s: &mut Slots, from: usize, to: usize| (from..to).for_each(|i| s.set(i, 0));
    let n = fb.members().len();
    if !enable {
        clear(s, 2, n);
        return;
    }
    let Some(ax) = axis else {
        clear(s, 2, n);
        s.set(4, 1);
        s.set(5, error_id::NO_AXIS as u64);
        return;
    };
    s.set(2, 1);
    s.set(3, 1);
    s.set(4, 0);
    s.set(5, 0);
    match fb {
        StdFb::McReadActualPosition => s.set(6, ax.actual().to_bits()),
        StdFb::McReadAxisError => s.set(6, ax.error_id as u64),
        _ => {
            let st = ax.state;
            let states = [
                AxisState::ErrorStop,
                AxisState::Disabled,
                AxisState::Stopping,
                AxisState::Homing,
                AxisState::Standstill,
                AxisState::DiscreteMotion,
                AxisState::ContinuousMotion,
            ];
            for (k, x) in states.iter().enumerate() {
                s.set(6 + k, (st == *x) as u64);
            }
            s.set(13, 0);
        }
    }
}

/// A request a block makes of its axis.
enum Request {
    Home(f64),
    Stop {
        dec: f64,
        jerk: f64,
    },
    Halt {
        dec: f64,
        jerk: f64,
    },
    Position {
        target: f64,
        v: f64,
        acc: f64,
        jerk: f64,
    },
    Velocity {
        v: f64,
        acc: f64,
        jerk: f64,
    },
    Reset,
}

/// A limit the block asks for, within the axis's: 0 means the axis's own.
fn within(asked: f64, axis: f64) -> Option<f64> {
    if asked.is_nan() || asked < 0.0 {
        None
    } else if asked == 0.0 {
        Some(axis)
    } else {
        Some(asked.min(axis))
    }
}

fn request(fb: StdFb, s: &Slots, ax: &Axis) -> Result<Request, u16> {
    let c = &ax.config;
    let bad = error_id::INVALID_PARAMETER;
    let buffer = |i: usize| {
        if s.get(i) as i64 == 0 {
            Ok(())
        } else {
            Err(error_id::BUFFER_MODE)
        }
    };
    let in_limits = |p: f64| {
        if !p.is_finite() {
            Err(bad)
        } else if c.min_position.is_some_and(|m| p < m) || c.max_position.is_some_and(|m| p > m) {
            Err(error_id::OUTSIDE_LIMITS)
        } else {
            Ok(p)
        }
    };
    let speed = |i: usize| -> Result<f64, u16> {
        let v = f(s.get(i));
        if !(v.is_finite() && v > 0.0) {
            return Err(bad);
        }
        Ok(v.min(c.velocity))
    };
    Ok(match fb {
        StdFb::McHome => {
            buffer(3)?;
            let p = in_limits(f(s.get(2)))?;
            Request::Home(c.modulo.map_or(p, |m| p.rem_euclid(m)))
        }
        StdFb::McStop => Request::Stop {
            dec: within(f(s.get(2)), c.acceleration).ok_or(bad)?,
            jerk: within(f(s.get(3)), c.jerk).ok_or(bad)?,
        },
        StdFb::McHalt => {
            buffer(4)?;
            Request::Halt {
                dec: within(f(s.get(2)), c.acceleration).ok_or(bad)?,
                jerk: within(f(s.get(3)), c.jerk).ok_or(bad)?,
            }
        }
        StdFb::McMoveAbsolute | StdFb::McMoveRelative | StdFb::McMoveAdditive => {
            let bm = if fb == StdFb::McMoveAbsolute { 9 } else { 8 };
            buffer(bm)?;
            let x = f(s.get(3));
            if !x.is_finite() {
                return Err(bad);
            }
            let here = ax.otg.sample().p;
            let target = match fb {
                StdFb::McMoveAbsolute => match c.modulo {
                    Some(m) => ax.modulo_target(m, x, s.get(8) as i64).ok_or(bad)?,
                    None => x,
                },
                StdFb::McMoveRelative => here + x,
                // Added to the running move's target, else to where the axis is.
                _ if ax.state == AxisState::DiscreteMotion => ax.target + x,
                _ => here + x,
            };
            Request::Position {
                target: in_limits(target)?,
                v: speed(4)?,
                acc: within(f(s.get(5)), c.acceleration).ok_or(bad)?,
                jerk: within(f(s.get(7)), c.jerk).ok_or(bad)?,
            }
        }
        StdFb::McMoveVelocity => {
            buffer(8)?;
            let v = f(s.get(3));
            if !v.is_finite() || v < 0.0 {
                return Err(bad);
            }
            // Direction: negative as CODESYS (-1) and PLCopen/TwinCAT (3) number it.
            let negative = matches!(s.get(7) as i64, -1 | 3);
            let v = v.min(c.velocity);
            Request::Velocity {
                v: if negative { -v } else { v },
                acc: within(f(s.get(4)), c.acceleration).ok_or(bad)?,
                jerk: within(f(s.get(6)), c.jerk).ok_or(bad)?,
            }
        }
        _ => Request::Reset,
    })
}

/// Starts a request on the axis; the command number on success.
fn start(ax: &mut Axis, r: Request) -> Result<u64, u16> {
    let c = ax.config;
    match (&r, ax.state) {
        (Request::Reset, _) => {}
        (_, AxisState::Disabled) => return Err(error_id::DISABLED),
        (_, AxisState::ErrorStop) => return Err(error_id::ERROR_STOP),
        (Request::Stop { .. }, _) => {}
        (_, AxisState::Stopping) => return Err(error_id::STOPPING),
        (Request::Home(_), s) if s != AxisState::Standstill => {
            return Err(error_id::NOT_STANDSTILL);
        }
        _ => {}
    }
    let limited = |v: f64, a: f64, j: f64| Limits::symmetric(v, a, j);
    let profile = |r: Result<(), rtcnc_motion::otg::OtgError>| r.map_err(|_| error_id::PROFILE);
    match r {
        Request::Reset => {
            ax.error_id = 0;
            if ax.state == AxisState::ErrorStop {
                ax.state = AxisState::Standstill;
                ax.goal = Goal::None;
            }
        }
        Request::Home(p) => {
            ax.state = AxisState::Homing;
            ax.goal = Goal::Home(p);
        }
        Request::Stop { dec, jerk } | Request::Halt { dec, jerk } => {
            let stop = matches!(r, Request::Stop { .. });
            profile(ax.otg.set_limits(limited(c.velocity, dec, jerk)))?;
            profile(ax.otg.stop())?;
            ax.state = if stop {
                AxisState::Stopping
            } else {
                AxisState::DiscreteMotion
            };
            ax.goal = if stop { Goal::Stop } else { Goal::Halt };
        }
        Request::Position {
            target,
            v,
            acc,
            jerk,
        } => {
            profile(ax.otg.set_limits(limited(v, acc, jerk)))?;
            profile(ax.otg.set_target(State::at_rest(target)))?;
            ax.state = AxisState::DiscreteMotion;
            ax.goal = Goal::Position;
            ax.target = target;
        }
        Request::Velocity { v, acc, jerk } => {
            profile(ax.otg.set_limits(limited(c.velocity, acc, jerk)))?;
            profile(ax.otg.set_velocity(v, 0.0))?;
            ax.state = AxisState::ContinuousMotion;
            ax.goal = Goal::Velocity;
        }
    }
    ax.command += 1;
    Ok(ax.command)
}

/// The Execute-started blocks. Outputs: `base` = DONE (or INVELOCITY), BUSY, ACTIVE,
/// COMMANDABORTED, ERROR, ERRORID (MC_Reset: DONE, BUSY, ERROR, ERRORID).
fn execute(fb: StdFb, s: &mut Slots, n: usize, axis: Option<&mut Axis>) {
    let reset_block = fb == StdFb::McReset;
    let base = if reset_block { 2 } else { n - 6 };
    let (done, busy) = (base, base + 1);
    let (active, aborted, error, error_code) = if reset_block {
        (None, None, base + 2, base + 3)
    } else {
        (Some(base + 2), Some(base + 3), base + 4, base + 5)
    };
    let (prev, seq) = (n, n + 1);
    let execute = s.flag(1);
    let rising = execute && !s.flag(prev);
    s.set(prev, execute as u64);
    // Done, Error and CommandAborted stay while Execute is TRUE, and for one call after
    // they were set with Execute already FALSE.
    if !execute && !s.flag(busy) {
        for i in [Some(done), aborted, Some(error)].into_iter().flatten() {
            s.set(i, 0);
        }
        s.set(error_code, 0);
    }
    let finish = |s: &mut Slots, out: usize| {
        if out != done {
            s.set(done, 0); // InVelocity of MC_MoveVelocity
        }
        s.set(out, 1);
        s.set(busy, 0);
        if let Some(a) = active {
            s.set(a, 0);
        }
    };
    let Some(ax) = axis else {
        if rising {
            finish(s, error);
            s.set(error_code, error_id::NO_AXIS as u64);
        }
        return;
    };
    if rising {
        for i in [Some(done), aborted, Some(error)].into_iter().flatten() {
            s.set(i, 0);
        }
        s.set(error_code, 0);
        match request(fb, s, ax).and_then(|r| start(ax, r)) {
            Ok(c) => {
                s.set(seq, c);
                s.set(busy, 1);
                if let Some(a) = active {
                    s.set(a, 1);
                }
                if reset_block {
                    finish(s, done);
                }
            }
            Err(code) => {
                finish(s, error);
                s.set(error_code, code as u64);
            }
        }
        // A command given in this scan is seen done at the earliest in the next one.
        return;
    }
    if !s.flag(busy) {
        // MC_Stop keeps the axis in Stopping until its Execute falls after Done.
        if fb == StdFb::McStop
            && !execute
            && s.get(seq) == ax.command
            && ax.state == AxisState::Stopping
            && ax.finished == ax.command
        {
            ax.state = AxisState::Standstill;
            ax.goal = Goal::None;
        }
        return;
    }
    let mine = s.get(seq);
    if ax.command != mine {
        match aborted {
            Some(a) => finish(s, a),
            None => finish(s, done),
        }
        return;
    }
    if ax.state == AxisState::ErrorStop {
        finish(s, error);
        s.set(error_code, ax.error_id as u64);
        return;
    }
    if ax.finished == mine {
        if fb == StdFb::McMoveVelocity {
            // InVelocity; the block keeps the axis until another command takes it.
            s.set(done, 1);
        } else {
            finish(s, done);
            if fb == StdFb::McStop && !execute && ax.state == AxisState::Stopping {
                ax.state = AxisState::Standstill;
                ax.goal = Goal::None;
            }
        }
    }
}
