use serde::Deserialize;

use crate::{
    ConfigError, CspCommand, CspConfig, CspLoop, FollowingErrorMonitor, PidConfig, PidController,
    ServoFault, SetPoint,
};

/// Which loop a joint runs, as the machine configuration names it:
/// `loop = "pid"` (the controller closes the position loop, velocity output) or
/// `loop = "csp"` (the drive closes it).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(tag = "loop", rename_all = "snake_case")]
pub enum ServoLoopConfig {
    /// [`PidController`].
    Pid(PidConfig),
    /// [`CspLoop`].
    Csp(CspConfig),
}

impl ServoLoopConfig {
    /// Checks the configuration; the error names the field.
    ///
    /// Real-time: no (set-up: a refusal allocates its message).
    pub fn validate(&self) -> Result<(), ConfigError> {
        match self {
            Self::Pid(config) => config.validate(),
            Self::Csp(config) => config.validate(),
        }
    }
}

/// What a joint's loop asks of its drive this cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ServoCommand {
    /// A velocity command (units/s), for a drive in velocity mode.
    Velocity(f64),
    /// A position set-point with offsets, for a drive in cyclic synchronous position mode.
    Position(CspCommand),
}

/// One joint's loop, either kind, behind one `update`.
#[derive(Debug, Clone)]
pub enum ServoLoop {
    /// The controller closes the position loop.
    Pid(PidController),
    /// The drive closes the position loop.
    Csp(CspLoop),
}

impl ServoLoop {
    /// The loop for joint `joint`, or the first refused configuration field.
    ///
    /// Real-time: no (set-up: a refusal allocates its message).
    pub fn new(joint: usize, config: &ServoLoopConfig) -> Result<Self, ConfigError> {
        Ok(match config {
            ServoLoopConfig::Pid(config) => Self::Pid(PidController::new(joint, config)?),
            ServoLoopConfig::Csp(config) => Self::Csp(CspLoop::new(joint, config)?),
        })
    }

    /// One servo cycle: the drive's command, or the fault that stops the joint.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn update(
        &mut self,
        setpoint: SetPoint,
        feedback: f64,
        period_s: f64,
    ) -> Result<ServoCommand, ServoFault> {
        match self {
            Self::Pid(pid) => pid
                .update(setpoint, feedback, period_s)
                .map(ServoCommand::Velocity),
            Self::Csp(csp) => csp
                .update(setpoint, feedback, period_s)
                .map(ServoCommand::Position),
        }
    }

    /// Clears the loop's history (integrator, derivative, set-points sent); call when the
    /// drive is enabled.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn reset(&mut self) {
        match self {
            Self::Pid(pid) => pid.reset(),
            Self::Csp(csp) => csp.reset(),
        }
    }

    /// The following-error monitor (last error, maximum, limits).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn following_error(&self) -> &FollowingErrorMonitor {
        match self {
            Self::Pid(pid) => pid.following_error(),
            Self::Csp(csp) => csp.following_error(),
        }
    }
}
