/// What the interpolator asks of one joint for this cycle: position, and its first two time
/// derivatives for the feed-forward terms (joint units, seconds).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SetPoint {
    /// Commanded position (mm or degrees).
    pub position: f64,
    /// Commanded velocity (units/s); feeds the velocity feed-forward and scales the
    /// following-error limit.
    pub velocity: f64,
    /// Commanded acceleration (units/s²); feeds the acceleration feed-forward.
    pub acceleration: f64,
}

impl SetPoint {
    /// A set-point at rest at `position`.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn at_rest(position: f64) -> Self {
        Self {
            position,
            velocity: 0.0,
            acceleration: 0.0,
        }
    }

    pub(crate) fn is_finite(&self) -> bool {
        self.position.is_finite() && self.velocity.is_finite() && self.acceleration.is_finite()
    }
}

/// Builds [`SetPoint`]s from a stream of positions alone, by backward differences, for a
/// caller whose interpolator gives only positions. The first sample after [`reset`] has zero
/// velocity and acceleration.
///
/// [`reset`]: SetPointDifferentiator::reset
#[derive(Debug, Clone, Copy, Default)]
pub struct SetPointDifferentiator {
    previous_position: Option<f64>,
    previous_velocity: Option<f64>,
}

impl SetPointDifferentiator {
    /// A differentiator with no history.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn new() -> Self {
        Self::default()
    }

    /// Forgets the history (after a jump in the command, e.g. when the drive is enabled).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn reset(&mut self) {
        *self = Self::default();
    }

    /// The set-point for `position`, `period_s` after the previous one. A non-positive or
    /// non-finite period gives zero derivatives (the servo loop reports the bad period).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn next(&mut self, position: f64, period_s: f64) -> SetPoint {
        let period_ok = period_s.is_finite() && period_s > 0.0;
        let velocity = match self.previous_position {
            Some(previous) if period_ok => (position - previous) / period_s,
            _ => 0.0,
        };
        let acceleration = match self.previous_velocity {
            Some(previous) if period_ok => (velocity - previous) / period_s,
            _ => 0.0,
        };
        self.previous_velocity = self.previous_position.map(|_| velocity);
        self.previous_position = Some(position);
        SetPoint {
            position,
            velocity,
            acceleration,
        }
    }
}
