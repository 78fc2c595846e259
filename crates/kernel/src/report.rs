//! Figures of a run from its recorded servo cycles: per axis the largest |velocity|,
//! |acceleration| and |jerk| of the set-points (finite differences at the servo period, as
//! the motion library's own limit checks take them), per joint the largest following error.

use rtcnc_motion::AXES;

use crate::config::MAX_JOINTS;
use crate::servo::Sample;

/// Running maxima over a stream of samples.
#[derive(Debug, Clone, Default)]
pub struct RunStats {
    /// The last four axis set-points, oldest first (`kept` of them valid).
    history: [[f64; AXES]; 4],
    kept: usize,
    /// Samples seen.
    pub samples: u64,
    /// Largest |v| per axis.
    pub max_velocity: [f64; AXES],
    /// Largest |a| per axis.
    pub max_acceleration: [f64; AXES],
    /// Largest |j| per axis.
    pub max_jerk: [f64; AXES],
    /// Largest |following error| per joint.
    pub max_following_error: [f64; MAX_JOINTS],
    /// Largest |set-point − feedback| per joint (after the loop's own delay).
    pub max_tracking_error: [f64; MAX_JOINTS],
}

impl RunStats {
    /// Empty.
    pub fn new() -> RunStats {
        RunStats::default()
    }

    /// Adds one servo cycle; `period_s` is the servo period. `moving_only`: skip cycles
    /// before the first motion (no effect on maxima, which start at zero).
    pub fn add(&mut self, s: &Sample, period_s: f64) {
        self.samples += 1;
        if self.kept == 4 {
            self.history.copy_within(1.., 0);
            self.kept = 3;
        }
        self.history[self.kept] = s.axes;
        self.kept += 1;
        let h = &self.history;
        let n = self.kept;
        for i in 0..AXES {
            if n >= 2 {
                let v = (h[n - 1][i] - h[n - 2][i]) / period_s;
                self.max_velocity[i] = self.max_velocity[i].max(v.abs());
            }
            if n >= 3 {
                let a = (h[n - 1][i] - 2.0 * h[n - 2][i] + h[n - 3][i]) / (period_s * period_s);
                self.max_acceleration[i] = self.max_acceleration[i].max(a.abs());
            }
            if n >= 4 {
                let j = (h[n - 1][i] - 3.0 * h[n - 2][i] + 3.0 * h[n - 3][i] - h[n - 4][i])
                    / (period_s * period_s * period_s);
                self.max_jerk[i] = self.max_jerk[i].max(j.abs());
            }
        }
        for j in 0..MAX_JOINTS {
            self.max_following_error[j] =
                self.max_following_error[j].max(s.following_error[j].abs());
            self.max_tracking_error[j] =
                self.max_tracking_error[j].max((s.setpoint[j] - s.feedback[j]).abs());
        }
    }
}
