//! Figures of a run from its recorded servo cycles: per axis the largest |velocity|,
//! |acceleration| and |jerk| of the set-points (finite differences at the servo period, as
//! the motion library's own limit checks take them), per joint the largest following error.

use rtcnc_motion::AXES;

use crate::config::{MAX_JOINTS, MachineConfig, axis_of};
use crate::servo::Sample;

/// Running maxima over a stream of samples.
#[derive(Debug, Clone)]
pub struct RunStats {
    /// The last four axis set-points, a ring: the newest at `next - 1` (modulo 4), `kept`
    /// of them valid.
    history: [[f64; AXES]; 4],
    next: usize,
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
    /// Per axis the largest |first, second, third difference| of the set-points: the
    /// maxima above are these over the period's powers, divided only when one grows
    /// (division by a positive number keeps the order, so the quotient of the largest is
    /// the largest quotient, bit for bit).
    max_differences: [[f64; AXES]; 3],
    /// The axes (by index) and the number of joints the maxima are taken over; the others
    /// never move, so their maxima stay zero either way.
    axes: [bool; AXES],
    joints: usize,
}

impl Default for RunStats {
    fn default() -> RunStats {
        RunStats {
            history: [[0.0; AXES]; 4],
            next: 0,
            kept: 0,
            samples: 0,
            max_velocity: [0.0; AXES],
            max_acceleration: [0.0; AXES],
            max_jerk: [0.0; AXES],
            max_following_error: [0.0; MAX_JOINTS],
            max_tracking_error: [0.0; MAX_JOINTS],
            max_differences: [[0.0; AXES]; 3],
            axes: [true; AXES],
            joints: MAX_JOINTS,
        }
    }
}

impl RunStats {
    /// Empty.
    pub fn new() -> RunStats {
        RunStats::default()
    }

    /// Empty, over the axes and joints `config` declares (the others never move): the
    /// same maxima as [`RunStats::new`] for a run of that machine, in less time per sample.
    pub fn for_machine(config: &MachineConfig) -> RunStats {
        let mut axes = [false; AXES];
        for letter in config.axes.keys() {
            if let Some(axis) = axis_of(letter) {
                axes[axis as usize] = true;
            }
        }
        RunStats {
            axes,
            joints: config.joints.len().min(MAX_JOINTS),
            ..RunStats::default()
        }
    }

    /// Adds one servo cycle; `period_s` is the servo period. `moving_only`: skip cycles
    /// before the first motion (no effect on maxima, which start at zero).
    pub fn add(&mut self, s: &Sample, period_s: f64) {
        self.samples += 1;
        self.history[self.next] = s.axes;
        self.next = (self.next + 1) % 4;
        self.kept = (self.kept + 1).min(4);
        // The set-points from the newest (h0) back; those not yet seen are never read.
        let at = |back: usize| &self.history[(self.next + 3 - back) % 4];
        let (h0, h1, h2, h3) = (at(0), at(1), at(2), at(3));
        let n = self.kept;
        for i in (0..AXES).filter(|&i| self.axes[i]) {
            if n >= 2 {
                let d = (h0[i] - h1[i]).abs();
                if d > self.max_differences[0][i] {
                    self.max_differences[0][i] = d;
                    self.max_velocity[i] = d / period_s;
                }
            }
            if n >= 3 {
                let d = (h0[i] - 2.0 * h1[i] + h2[i]).abs();
                if d > self.max_differences[1][i] {
                    self.max_differences[1][i] = d;
                    self.max_acceleration[i] = d / (period_s * period_s);
                }
            }
            if n >= 4 {
                let d = (h0[i] - 3.0 * h1[i] + 3.0 * h2[i] - h3[i]).abs();
                if d > self.max_differences[2][i] {
                    self.max_differences[2][i] = d;
                    self.max_jerk[i] = d / (period_s * period_s * period_s);
                }
            }
        }
        for j in 0..self.joints {
            self.max_following_error[j] =
                self.max_following_error[j].max(s.following_error[j].abs());
            self.max_tracking_error[j] =
                self.max_tracking_error[j].max((s.setpoint[j] - s.feedback[j]).abs());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The maxima are those of the finite differences divided at every sample, as their
    /// definition says, bit for bit.
    #[test]
    fn maxima_are_those_of_the_quotients_of_every_sample() {
        let period = 0.001;
        let mut stats = RunStats::new();
        let mut history: Vec<f64> = Vec::new();
        let (mut v, mut a, mut j) = (0.0f64, 0.0f64, 0.0f64);
        for k in 0..400 {
            let t = k as f64 * period;
            // Uneven steps, both signs: a cubic with a wobble.
            let x = 3.0 * t * t * t - 2.0 * t + 1e-3 * (37.0 * t).sin();
            let mut sample = Sample {
                cycle: k,
                time_ns: 0,
                setpoint: [0.0; MAX_JOINTS],
                feedback: [0.0; MAX_JOINTS],
                following_error: [0.0; MAX_JOINTS],
                axes: [0.0; AXES],
                line: 0,
                path_speed: 0.0,
            };
            sample.axes[1] = x;
            stats.add(&sample, period);
            history.push(x);
            let h = &history[history.len().saturating_sub(4)..];
            let n = h.len();
            if n >= 2 {
                v = v.max(((h[n - 1] - h[n - 2]) / period).abs());
            }
            if n >= 3 {
                a = a.max(((h[n - 1] - 2.0 * h[n - 2] + h[n - 3]) / (period * period)).abs());
            }
            if n >= 4 {
                let d = h[n - 1] - 3.0 * h[n - 2] + 3.0 * h[n - 3] - h[n - 4];
                j = j.max((d / (period * period * period)).abs());
            }
            assert_eq!(
                (
                    stats.max_velocity[1],
                    stats.max_acceleration[1],
                    stats.max_jerk[1]
                ),
                (v, a, j),
                "after sample {k}"
            );
        }
        assert!(v > 0.0 && a > 0.0 && j > 0.0);
        assert_eq!(stats.max_velocity[0], 0.0);
    }
}
