//! The operator's overrides (feed, rapid, spindle) and the program's say over them
//! (M48-M53: overrides and the feed stop switch in force or not, adaptive feed). Every
//! program start, end, abort or fault puts them back in force and adaptive feed off.
//!
//! Adaptive feed (M52 P1, as LinuxCNC's `motion.adaptive-feed`): the machine's analogue
//! input, clamped to 0..=1, multiplies the feed of feed moves (not rapids) with the feed
//! override. It is read every servo period and taken into the planner when it has moved by
//! `ADAPTIVE_STEP` from the value in force, or reached 0 or 1: each change takes back the
//! set-points computed ahead, so a noisy input does not cost that every period.

use super::MotionCore;

/// The overrides and whether they are in force.
#[derive(Debug, Clone, Copy)]
pub(super) struct Overrides {
    /// Feed override, 0..=2.
    pub(super) feed: f64,
    /// Rapid override, 0..=1.
    pub(super) rapid: f64,
    /// Spindle override, 0.5..=1.5.
    pub(super) spindle: f64,
    /// M48-M50: the feed and rapid overrides in force (else 100 %).
    pub(super) feed_enabled: bool,
    /// M48, M49, M51: the spindle override in force.
    pub(super) spindle_enabled: bool,
    /// M53: the feed stop switch is heeded.
    pub(super) feed_stop_enabled: bool,
    /// M52 P1: adaptive feed on, with the factor in force.
    pub(super) adaptive: Option<f64>,
}

/// Change of the adaptive-feed input taken into the planner (1 % of the feed).
const ADAPTIVE_STEP: f64 = 0.01;

impl Overrides {
    pub(super) fn new() -> Overrides {
        Overrides {
            feed: 1.0,
            rapid: 1.0,
            spindle: 1.0,
            feed_enabled: true,
            spindle_enabled: true,
            feed_stop_enabled: true,
            adaptive: None,
        }
    }

    /// M48-M53 as after a reset.
    pub(super) fn enable_all(&mut self) {
        self.feed_enabled = true;
        self.spindle_enabled = true;
        self.feed_stop_enabled = true;
        self.adaptive = None;
    }

    /// The operator's spindle override, or 1 while M49/M51 P0 is in force.
    pub(super) fn spindle_factor(&self) -> f64 {
        if self.spindle_enabled {
            self.spindle
        } else {
            1.0
        }
    }
}

/// An override as the operator sent it, within `min..=max`; `otherwise` when not a number.
fn clamped(value: f64, min: f64, max: f64, otherwise: f64) -> f64 {
    if value.is_finite() {
        value.clamp(min, max)
    } else {
        otherwise
    }
}

impl MotionCore {
    pub(super) fn set_feed_override(&mut self, value: f64) {
        self.overrides.feed = clamped(value, 0.0, 2.0, 0.0);
        self.apply_feed_overrides();
    }

    pub(super) fn set_rapid_override(&mut self, value: f64) {
        self.overrides.rapid = clamped(value, 0.0, 1.0, 0.0);
        self.apply_feed_overrides();
    }

    pub(super) fn set_spindle_override(&mut self, value: f64) {
        self.overrides.spindle = clamped(value, 0.5, 1.5, 1.0);
        if self.interface.requests.spindle_on {
            let rpm = self.spindle_command();
            self.requests_mut().spindle_rpm = rpm;
        }
    }

    /// The feed and rapid overrides in force: the operator's, or 100 % while M49/M50 P0
    /// is in force.
    pub(super) fn effective_feed_overrides(&self) -> (f64, f64) {
        let adaptive = self.overrides.adaptive.unwrap_or(1.0);
        if self.overrides.feed_enabled {
            (self.overrides.feed * adaptive, self.overrides.rapid)
        } else {
            (adaptive, 1.0)
        }
    }

    /// M52: adaptive feed on (from the input's present value) or off. False when the
    /// machine has no adaptive-feed input (the program cannot turn it on).
    pub(super) fn set_adaptive_feed(&mut self, on: bool) -> bool {
        if !on {
            self.overrides.adaptive = None;
        } else if let Some(v) = self.adaptive_feed_input() {
            self.overrides.adaptive = Some(v);
        } else {
            return false;
        }
        self.apply_feed_overrides();
        true
    }

    /// Every servo period (interpolation): a moved adaptive-feed input into the planner.
    pub(super) fn adaptive_feed_step(&mut self) {
        let (Some(in_force), Some(v)) = (self.overrides.adaptive, self.adaptive_feed_input())
        else {
            return;
        };
        let reached_end = (v == 0.0 || v == 1.0) && v != in_force;
        if (v - in_force).abs() >= ADAPTIVE_STEP || reached_end {
            self.overrides.adaptive = Some(v);
            self.apply_feed_overrides();
        }
    }

    /// The adaptive-feed input's value, clamped to 0..=1 (0 when not a number).
    fn adaptive_feed_input(&mut self) -> Option<f64> {
        let point = self.io.adaptive_feed_point?;
        let v = *self.interface.feedback.get().analog_inputs.get(point)?;
        Some(clamped(v, 0.0, 1.0, 0.0))
    }

    /// The operator's feed and rapid overrides, or 100 % while M49/M50 P0 is in force.
    pub(super) fn apply_feed_overrides(&mut self) {
        let (feed, rapid) = self.effective_feed_overrides();
        self.take_back();
        self.path.planner.set_feed_override(feed);
        self.path.planner.set_rapid_override(rapid);
    }

    /// M48-M53 as after a reset: every override and the feed stop switch in force.
    pub(super) fn reset_enables(&mut self) {
        self.overrides.enable_all();
        self.apply_feed_overrides();
        if self.interface.requests.spindle_on {
            let rpm = self.spindle_command();
            self.requests_mut().spindle_rpm = rpm;
        }
    }
}
