/// Why a servo loop refused a cycle. Each value names the joint (its index in the machine
/// configuration) and has a stable [`code`](ServoFault::code).
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum ServoFault {
    /// The joint fell further behind (or ahead of) its set-point than the limit allows.
    #[error("joint {joint}: following error {error:.6} exceeds the limit {limit:.6}")]
    FollowingError {
        /// Joint index.
        joint: usize,
        /// Set-point minus feedback (units).
        error: f64,
        /// The limit in force at the commanded velocity (units).
        limit: f64,
    },
    /// A set-point or feedback value was NaN or infinite.
    #[error("joint {joint}: {input} is not a finite number")]
    NonFiniteInput {
        /// Joint index.
        joint: usize,
        /// Which input: "set-point" or "feedback".
        input: &'static str,
    },
    /// The period passed in was not a positive finite number of seconds.
    #[error("joint {joint}: servo period {period_s} s is not a positive finite number")]
    InvalidPeriod {
        /// Joint index.
        joint: usize,
        /// The period that was passed (seconds).
        period_s: f64,
    },
    /// The computed command overflowed (gains far too large for the inputs).
    #[error("joint {joint}: servo output is not a finite number")]
    NonFiniteOutput {
        /// Joint index.
        joint: usize,
    },
}

impl ServoFault {
    /// A stable machine-readable code for logs, the API and tests.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn code(&self) -> &'static str {
        match self {
            Self::FollowingError { .. } => "servo.following_error",
            Self::NonFiniteInput { .. } => "servo.non_finite_input",
            Self::InvalidPeriod { .. } => "servo.invalid_period",
            Self::NonFiniteOutput { .. } => "servo.non_finite_output",
        }
    }

    /// The joint the fault names.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn joint(&self) -> usize {
        match *self {
            Self::FollowingError { joint, .. }
            | Self::NonFiniteInput { joint, .. }
            | Self::InvalidPeriod { joint, .. }
            | Self::NonFiniteOutput { joint } => joint,
        }
    }
}
