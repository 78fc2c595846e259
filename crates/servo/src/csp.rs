use crate::{ConfigError, CspConfig, FollowingErrorMonitor, ServoFault, SetPoint};

/// What a drive in cyclic synchronous position mode receives for one cycle (CiA 402
/// objects 0x607A target position, 0x60B1 velocity offset, 0x60B2 torque offset).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CspCommand {
    /// Target position (units).
    pub position: f64,
    /// Velocity feed-forward (units/s).
    pub velocity_offset: f64,
    /// Torque feed-forward (N·m).
    pub torque_offset: f64,
}

/// The controller's side of a joint whose drive closes the position loop itself: it passes
/// the set-point through with feed-forward offsets and checks the following error.
#[derive(Debug, Clone)]
pub struct CspLoop {
    config: CspConfig,
    monitor: FollowingErrorMonitor,
}

impl CspLoop {
    /// A loop for joint `joint`, or the first refused configuration field.
    ///
    /// Real-time: no (set-up: a refusal allocates its message).
    pub fn new(joint: usize, config: &CspConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(Self {
            config: *config,
            monitor: FollowingErrorMonitor::new(joint, config.following_error),
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
    ) -> Result<CspCommand, ServoFault> {
        let joint = self.monitor.joint();
        if !setpoint.is_finite() {
            return Err(ServoFault::NonFiniteInput {
                joint,
                input: "set-point",
            });
        }
        if !feedback.is_finite() {
            return Err(ServoFault::NonFiniteInput {
                joint,
                input: "feedback",
            });
        }
        if !(period_s.is_finite() && period_s > 0.0) {
            return Err(ServoFault::InvalidPeriod { joint, period_s });
        }
        self.monitor
            .check(setpoint.position - feedback, setpoint.velocity)?;
        let command = CspCommand {
            position: setpoint.position,
            velocity_offset: self.config.velocity_ff * setpoint.velocity,
            torque_offset: self.config.torque_ff * setpoint.acceleration,
        };
        if !(command.velocity_offset.is_finite() && command.torque_offset.is_finite()) {
            return Err(ServoFault::NonFiniteOutput { joint });
        }
        Ok(command)
    }

    /// The joint index this loop names in its faults.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn joint(&self) -> usize {
        self.monitor.joint()
    }

    /// The following-error monitor (last error, maximum, limits).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn following_error(&self) -> &FollowingErrorMonitor {
        &self.monitor
    }
}
