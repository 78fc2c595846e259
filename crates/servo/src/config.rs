use serde::Deserialize;

/// A refused value names its field; the one type and checks of every machine-file crate.
pub use rtcnc_rt::FieldError as ConfigError;
use rtcnc_rt::check::{finite, non_negative, positive};

/// Gains of the velocity-output position loop. Units follow from the output being a
/// velocity command in joint units per second.
///
/// The defaults (p = 200/s, velocity_ff = 1, acceleration_ff = 0.5 ms) are tuned for a
/// velocity-commanded drive with integral action in its velocity loop (the simulated
/// analogue drive of `rtcnc-fieldbus`, 200 Hz) and a 1 ms servo period: such a drive has no
/// velocity lag under constant acceleration, so acceleration_ff only makes up the half
/// period a held command loses (T/2). With them the seeds' S-curve experiment stays within
/// 1 µm (test `experiment1` of `rtcnc-fieldbus`). For another period set
/// acceleration_ff = T/2.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PidGains {
    /// Proportional gain (1/s): velocity command per unit of position error.
    pub p: f64,
    /// Integral gain (1/s²).
    pub i: f64,
    /// Derivative gain (dimensionless): on the error's rate of change.
    pub d: f64,
    /// Velocity feed-forward (dimensionless, LinuxCNC FF1): 1 passes the commanded
    /// velocity through.
    pub velocity_ff: f64,
    /// Acceleration feed-forward (seconds, LinuxCNC FF2): makes up the drive's velocity lag
    /// and the half period that a held command loses while accelerating.
    pub acceleration_ff: f64,
    /// Constant added to the output (units/s), e.g. an analogue drive's offset.
    pub bias: f64,
    /// Errors smaller than this (units) count as zero; larger ones are reduced by it.
    pub deadband: f64,
    /// Largest output magnitude (units/s); absent means unlimited.
    pub output_limit: Option<f64>,
    /// Largest magnitude of the error integral (units·s); absent means unlimited.
    pub integrator_limit: Option<f64>,
}

impl Default for PidGains {
    fn default() -> Self {
        Self {
            p: 200.0,
            i: 0.0,
            d: 0.0,
            velocity_ff: 1.0,
            acceleration_ff: 0.0005,
            bias: 0.0,
            deadband: 0.0,
            output_limit: None,
            integrator_limit: None,
        }
    }
}

impl PidGains {
    /// Checks every gain; the error names the first refused field.
    ///
    /// Real-time: no (set-up: a refusal allocates its message).
    pub fn validate(&self) -> Result<(), ConfigError> {
        non_negative("p", self.p)?;
        non_negative("i", self.i)?;
        non_negative("d", self.d)?;
        finite("velocity_ff", self.velocity_ff)?;
        finite("acceleration_ff", self.acceleration_ff)?;
        finite("bias", self.bias)?;
        non_negative("deadband", self.deadband)?;
        if let Some(limit) = self.output_limit {
            positive("output_limit", limit)?;
        }
        if let Some(limit) = self.integrator_limit {
            non_negative("integrator_limit", limit)?;
        }
        Ok(())
    }
}

/// Following-error limits, as LinuxCNC's `FERROR` and `MIN_FERROR`: the limit in force is
/// `max(min_ferror, ferror · |commanded velocity| / max_velocity)`.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FollowingErrorLimits {
    /// The static limit (units): applies at standstill and low speed.
    pub min_ferror: f64,
    /// The limit at `max_velocity` (units), scaled linearly with the commanded speed.
    pub ferror: f64,
    /// The joint's maximum velocity (units/s), the scale of `ferror`.
    pub max_velocity: f64,
}

impl FollowingErrorLimits {
    /// Checks the limits; the error names the first refused field.
    ///
    /// Real-time: no (set-up: a refusal allocates its message).
    pub fn validate(&self) -> Result<(), ConfigError> {
        positive("min_ferror", self.min_ferror)?;
        positive("ferror", self.ferror)?;
        positive("max_velocity", self.max_velocity)?;
        if self.ferror < self.min_ferror {
            return Err(ConfigError::new(
                "ferror",
                "must not be smaller than min_ferror",
            ));
        }
        Ok(())
    }

    /// The limit in force at a commanded velocity (units/s).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn limit_at(&self, commanded_velocity: f64) -> f64 {
        let scaled = self.ferror * commanded_velocity.abs() / self.max_velocity;
        if scaled > self.min_ferror {
            scaled
        } else {
            self.min_ferror
        }
    }
}

/// Configuration of one [`PidController`](crate::PidController).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PidConfig {
    /// PID and feed-forward gains; every one has a default.
    #[serde(default)]
    pub gains: PidGains,
    /// Following-error limits.
    pub following_error: FollowingErrorLimits,
}

impl PidConfig {
    /// Checks the whole configuration; the error names the field (`gains.p`, ...).
    ///
    /// Real-time: no (set-up: a refusal allocates its message).
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.gains.validate().map_err(|e| e.within("gains"))?;
        self.following_error
            .validate()
            .map_err(|e| e.within("following_error"))
    }
}

/// Configuration of one [`CspLoop`](crate::CspLoop) (drive in cyclic synchronous position).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CspConfig {
    /// Fraction of the commanded velocity sent as the drive's velocity offset (0 to 1).
    #[serde(default = "one")]
    pub velocity_ff: f64,
    /// Torque offset per unit of commanded acceleration (N·m per unit/s²), i.e. the
    /// reflected inertia; 0 sends no torque offset.
    #[serde(default)]
    pub torque_ff: f64,
    /// Following-error limits.
    pub following_error: FollowingErrorLimits,
    /// Servo periods from a set-point sent to the drive to the feedback that shows it (the
    /// fieldbus cycle and the drive's own delay; 1 for a drive that reports next cycle the
    /// position it was sent). The following error compares the feedback with the set-point
    /// sent that many periods before, so that it measures tracking and not the transport
    /// delay, which at 100 mm/s and 4 ms periods alone is 0.4 mm per period. 0 (the
    /// default) compares with the latest set-point; at most [`MAX_FEEDBACK_DELAY`].
    #[serde(default)]
    pub feedback_delay_periods: u8,
}

/// The largest `feedback_delay_periods` a CSP loop keeps set-points for.
pub const MAX_FEEDBACK_DELAY: u8 = 8;

fn one() -> f64 {
    1.0
}

impl CspConfig {
    /// Checks the whole configuration; the error names the field.
    ///
    /// Real-time: no (set-up: a refusal allocates its message).
    pub fn validate(&self) -> Result<(), ConfigError> {
        finite("velocity_ff", self.velocity_ff)?;
        if !(0.0..=1.0).contains(&self.velocity_ff) {
            return Err(ConfigError::new("velocity_ff", "must be between 0 and 1"));
        }
        non_negative("torque_ff", self.torque_ff)?;
        if self.feedback_delay_periods > MAX_FEEDBACK_DELAY {
            return Err(ConfigError::new(
                "feedback_delay_periods",
                "must be at most 8 servo periods",
            ));
        }
        self.following_error
            .validate()
            .map_err(|e| e.within("following_error"))
    }
}
