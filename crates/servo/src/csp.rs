use crate::config::MAX_FEEDBACK_DELAY;
use crate::{ConfigError, CspConfig, FollowingErrorMonitor, ServoFault, SetPoint};

const HISTORY: usize = MAX_FEEDBACK_DELAY as usize + 1;

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
    /// The set-points sent in the last periods, newest at `newest` (a ring).
    sent: [f64; HISTORY],
    newest: usize,
    /// How many periods of `sent` are valid since construction or the last reset.
    sent_count: usize,
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
            sent: [0.0; HISTORY],
            newest: 0,
            sent_count: 0,
        })
    }

    /// Forgets the set-points sent before; call when the drive is enabled.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn reset(&mut self) {
        self.sent_count = 0;
    }

    /// Records `position` as sent this period and returns the set-point the feedback of
    /// this period shows: the one sent `feedback_delay_periods` before, or the oldest kept
    /// in the first periods after a reset.
    fn shown_by_feedback(&mut self, position: f64) -> f64 {
        self.newest = (self.newest + 1) % HISTORY;
        self.sent[self.newest] = position;
        self.sent_count = (self.sent_count + 1).min(HISTORY);
        let delay = usize::from(self.config.feedback_delay_periods).min(self.sent_count - 1);
        self.sent[(self.newest + HISTORY - delay) % HISTORY]
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
        let shown = self.shown_by_feedback(setpoint.position);
        self.monitor.check(shown - feedback, setpoint.velocity)?;
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
