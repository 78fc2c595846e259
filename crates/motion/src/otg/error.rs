//! Error values of the trajectory generator: a stable code and a plain message, never a panic.

/// Why a profile could not be computed.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum OtgError {
    /// A limit is zero, of the wrong sign, NaN or infinite.
    #[error("limit {name} must be a finite number {requirement}, got {value}")]
    InvalidLimit {
        /// Which limit (`max_velocity`, `min_acceleration`, ...).
        name: &'static str,
        /// What it must be, in words.
        requirement: &'static str,
        /// The value given.
        value: f64,
    },
    /// A state or target value is NaN or infinite.
    #[error("{name} must be a finite number, got {value}")]
    NonFiniteInput {
        /// Which input (`start position`, `target velocity`, ...).
        name: &'static str,
        /// The value given.
        value: f64,
    },
    /// The target velocity lies outside the velocity limits.
    #[error("target velocity {velocity} is outside the velocity limits [{min}, {max}]")]
    TargetVelocityOutOfLimits {
        /// Requested target velocity.
        velocity: f64,
        /// Lower velocity limit.
        min: f64,
        /// Upper velocity limit.
        max: f64,
    },
    /// The target acceleration lies outside the acceleration limits.
    #[error("target acceleration {acceleration} is outside the acceleration limits [{min}, {max}]")]
    TargetAccelerationOutOfLimits {
        /// Requested target acceleration.
        acceleration: f64,
        /// Lower acceleration limit.
        min: f64,
        /// Upper acceleration limit.
        max: f64,
    },
    /// The target velocity and acceleration cannot be arrived at without breaking a velocity
    /// limit just before the end (e.g. a large deceleration demanded right at the top speed).
    #[error(
        "target state (velocity {velocity}, acceleration {acceleration}) cannot be reached \
         without exceeding a velocity limit: with jerk {jerk} the velocity before it was {before}"
    )]
    TargetStateUnreachable {
        /// Requested target velocity.
        velocity: f64,
        /// Requested target acceleration.
        acceleration: f64,
        /// Jerk limit.
        jerk: f64,
        /// Velocity the motion must have had where the acceleration was zero.
        before: f64,
    },
    /// No valid profile was found. This is a numerical failure of the solver for an input
    /// that should be solvable; it is reported instead of returning a wrong profile.
    #[error("no valid time-optimal profile found (numerical failure) for a move of {distance}")]
    NoProfileFound {
        /// Position difference of the move.
        distance: f64,
    },
    /// A profile of an exact duration was requested that is shorter than the minimum.
    #[error("requested duration {requested} is shorter than the minimum duration {minimum}")]
    DurationTooShort {
        /// Requested duration.
        requested: f64,
        /// Minimum duration of this axis.
        minimum: f64,
    },
    /// A straight-line (phase-synchronised) move was asked for, but the start or target
    /// velocity or acceleration of some axis is not along the line between the positions.
    #[error(
        "axis {axis}: its start or target velocity/acceleration is not along the straight line \
         of the move, so no straight-line profile exists (use time synchronisation)"
    )]
    NotCollinear {
        /// Index of the first axis off the line.
        axis: usize,
    },
    /// No common duration was found for a multi-axis move.
    #[error("axis {axis}: no profile of the synchronised duration {duration} was found")]
    SynchronizationFailed {
        /// Index of the axis that could not be synchronised.
        axis: usize,
        /// Duration that was tried last.
        duration: f64,
    },
}

impl OtgError {
    /// A stable, machine-readable code for this error kind.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn code(&self) -> &'static str {
        match self {
            Self::InvalidLimit { .. } => "otg-invalid-limit",
            Self::NonFiniteInput { .. } => "otg-non-finite-input",
            Self::TargetVelocityOutOfLimits { .. } => "otg-target-velocity-out-of-limits",
            Self::TargetAccelerationOutOfLimits { .. } => "otg-target-acceleration-out-of-limits",
            Self::TargetStateUnreachable { .. } => "otg-target-state-unreachable",
            Self::NoProfileFound { .. } => "otg-no-profile-found",
            Self::DurationTooShort { .. } => "otg-duration-too-short",
            Self::SynchronizationFailed { .. } => "otg-synchronization-failed",
            Self::NotCollinear { .. } => "otg-not-collinear",
        }
    }
}
