use crate::{FollowingErrorLimits, ServoFault};

/// Watches one joint's following error (set-point minus feedback) against its limits and
/// keeps the largest magnitude seen, for the run summary.
#[derive(Debug, Clone, Copy)]
pub struct FollowingErrorMonitor {
    joint: usize,
    limits: FollowingErrorLimits,
    last_error: f64,
    max_abs_error: f64,
}

impl FollowingErrorMonitor {
    /// A monitor for joint `joint` (limits validated by the caller's config).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn new(joint: usize, limits: FollowingErrorLimits) -> Self {
        Self {
            joint,
            limits,
            last_error: 0.0,
            max_abs_error: 0.0,
        }
    }

    /// Checks `error` (units) at `commanded_velocity` (units/s): a fault when its magnitude
    /// is strictly greater than the limit in force.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn check(&mut self, error: f64, commanded_velocity: f64) -> Result<(), ServoFault> {
        self.last_error = error;
        if error.abs() > self.max_abs_error {
            self.max_abs_error = error.abs();
        }
        let limit = self.limits.limit_at(commanded_velocity);
        if error.abs() > limit {
            return Err(ServoFault::FollowingError {
                joint: self.joint,
                error,
                limit,
            });
        }
        Ok(())
    }

    /// The joint index this monitor names in its faults.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn joint(&self) -> usize {
        self.joint
    }

    /// The error of the last checked cycle.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn last_error(&self) -> f64 {
        self.last_error
    }

    /// The largest error magnitude since construction or [`reset_max`](Self::reset_max).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn max_abs_error(&self) -> f64 {
        self.max_abs_error
    }

    /// Starts a new maximum (e.g. at program start).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn reset_max(&mut self) {
        self.max_abs_error = 0.0;
    }

    /// The limits in force.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn limits(&self) -> &FollowingErrorLimits {
        &self.limits
    }
}
