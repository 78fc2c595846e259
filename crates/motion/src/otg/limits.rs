//! Kinematic limits and states of one axis, and their validation.

use super::OtgError;

/// Velocity, acceleration and jerk limits of one axis (or of one path coordinate).
///
/// All values are finite; `max_*` are positive and `min_*` negative. The jerk limit is
/// symmetric. Units are consistent arbitrary units (e.g. mm, s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// Upper velocity limit (> 0).
    pub max_velocity: f64,
    /// Lower velocity limit (< 0); usually `-max_velocity`.
    pub min_velocity: f64,
    /// Upper acceleration limit (> 0).
    pub max_acceleration: f64,
    /// Lower acceleration limit (< 0); usually `-max_acceleration`.
    pub min_acceleration: f64,
    /// Jerk limit (> 0), used in both directions.
    pub max_jerk: f64,
}

impl Limits {
    /// Symmetric limits: `|v| <= velocity`, `|a| <= acceleration`, `|j| <= jerk`.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn symmetric(velocity: f64, acceleration: f64, jerk: f64) -> Self {
        Self {
            max_velocity: velocity,
            min_velocity: -velocity,
            max_acceleration: acceleration,
            min_acceleration: -acceleration,
            max_jerk: jerk,
        }
    }

    /// Checks that every limit is finite and of the right sign.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn validate(&self) -> Result<(), OtgError> {
        let positive = [
            ("max_velocity", self.max_velocity),
            ("max_acceleration", self.max_acceleration),
            ("max_jerk", self.max_jerk),
        ];
        for (name, value) in positive {
            if !(value.is_finite() && value > 0.0) {
                return Err(OtgError::InvalidLimit {
                    name,
                    requirement: "greater than zero",
                    value,
                });
            }
        }
        let negative = [
            ("min_velocity", self.min_velocity),
            ("min_acceleration", self.min_acceleration),
        ];
        for (name, value) in negative {
            if !(value.is_finite() && value < 0.0) {
                return Err(OtgError::InvalidLimit {
                    name,
                    requirement: "less than zero",
                    value,
                });
            }
        }
        Ok(())
    }
}

/// Kinematic state of one axis: position, velocity and acceleration.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct State {
    /// Position.
    pub p: f64,
    /// Velocity.
    pub v: f64,
    /// Acceleration.
    pub a: f64,
}

impl State {
    /// A state with the given position, velocity and acceleration.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub const fn new(p: f64, v: f64, a: f64) -> Self {
        Self { p, v, a }
    }

    /// At rest at position `p`.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub const fn at_rest(p: f64) -> Self {
        Self { p, v: 0.0, a: 0.0 }
    }

    pub(crate) fn check_finite(&self, what: Which) -> Result<(), OtgError> {
        let names = match what {
            Which::Start => ["start position", "start velocity", "start acceleration"],
            Which::Target => ["target position", "target velocity", "target acceleration"],
        };
        for (name, value) in names.into_iter().zip([self.p, self.v, self.a]) {
            if !value.is_finite() {
                return Err(OtgError::NonFiniteInput { name, value });
            }
        }
        Ok(())
    }
}

#[derive(Clone, Copy)]
pub(crate) enum Which {
    Start,
    Target,
}

/// Checks that a target velocity and acceleration lie inside the limits and can be arrived
/// at: arriving with acceleration `af < 0` means the velocity was `vf + af²/2j` where the
/// acceleration was zero, which must not exceed the velocity limit (and mirrored).
pub(crate) fn check_target(vf: f64, af: f64, limits: &Limits) -> Result<(), OtgError> {
    let (vmax, vmin) = (limits.max_velocity, limits.min_velocity);
    let (amax, amin) = (limits.max_acceleration, limits.min_acceleration);
    let j = limits.max_jerk;
    if !(vmin..=vmax).contains(&vf) {
        return Err(OtgError::TargetVelocityOutOfLimits {
            velocity: vf,
            min: vmin,
            max: vmax,
        });
    }
    if !(amin..=amax).contains(&af) {
        return Err(OtgError::TargetAccelerationOutOfLimits {
            acceleration: af,
            min: amin,
            max: amax,
        });
    }
    let before = if af < 0.0 {
        vf + af * af / (2.0 * j)
    } else {
        vf - af * af / (2.0 * j)
    };
    let slack = 1e-12 * (vmax - vmin);
    if before > vmax + slack || before < vmin - slack {
        return Err(OtgError::TargetStateUnreachable {
            velocity: vf,
            acceleration: af,
            jerk: j,
            before,
        });
    }
    Ok(())
}
