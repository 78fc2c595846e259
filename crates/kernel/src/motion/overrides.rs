//! The operator's overrides (feed, rapid, spindle) and the program's say over them
//! (M48-M53: overrides and the feed stop switch in force or not, adaptive feed). Every
//! program start, end, abort or fault puts them back in force and adaptive feed off.
//!
//! Adaptive feed (M52 P1, as LinuxCNC's `motion.adaptive-feed`): the machine's analogue
//! input, clamped to 0..=1, multiplies the feed of feed moves (not rapids) with the feed
//! override. It is read every servo period and taken into the planner when it has moved by
//! `ADAPTIVE_STEP` from the value in force, or reached 0 or 1: each change takes back the
//! set-points computed ahead, so a noisy input does not cost that every period.
//!
//! Feed per revolution under constant surface speed (G95 under G96): such a move is
//! planned at its feed per revolution times a nominal spindle speed above any the spindle
//! reaches (the G96 D cap), and while it runs the feed is scaled by the spindle's measured
//! speed over that nominal one, the same way, so the tool advances its feed per actual
//! revolution as the speed follows the diameter (LinuxCNC's velocity-synchronised feed).

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
    /// G95 under G96: the measured spindle speed over the move's nominal one, in force.
    pub(super) spindle_feed: f64,
    /// Where the moves' nominal spindle speed changes: (first piece, rev/s; 0 for a move
    /// whose feed does not follow the spindle), oldest first.
    per_revolution: [(u64, f64); PER_REVOLUTION_MARKS],
    per_revolution_count: usize,
}

/// Changes of the nominal spindle speed kept for the moves in the planner's window.
const PER_REVOLUTION_MARKS: usize = 32;

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
            spindle_feed: 1.0,
            per_revolution: [(0, 0.0); PER_REVOLUTION_MARKS],
            per_revolution_count: 0,
        }
    }

    /// M48-M53 as after a reset.
    pub(super) fn enable_all(&mut self) {
        self.feed_enabled = true;
        self.spindle_enabled = true;
        self.feed_stop_enabled = true;
        self.adaptive = None;
        self.spindle_feed = 1.0;
        self.per_revolution_count = 0;
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
        let adaptive = self.overrides.adaptive.unwrap_or(1.0) * self.overrides.spindle_feed;
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

    /// A move went into the planner: whether its feed follows the spindle's measured speed
    /// (G95 under G96, planned at `nominal_rps`), from its first piece on. A move that
    /// starts the path from rest takes the measured speed at once.
    pub(super) fn mark_feed_per_revolution(&mut self, nominal_rps: Option<f64>) {
        let value = nominal_rps
            .filter(|n| *n > 0.0 && n.is_finite())
            .unwrap_or(0.0);
        let o = &mut self.overrides;
        let last = o.per_revolution[..o.per_revolution_count]
            .last()
            .map_or(0.0, |m| m.1);
        if last == value {
            return;
        }
        if o.per_revolution_count == PER_REVOLUTION_MARKS {
            o.per_revolution.copy_within(1.., 0);
            o.per_revolution_count -= 1;
        }
        let first_piece = self.path.planner.next_piece_id();
        o.per_revolution[o.per_revolution_count] = (first_piece, value);
        o.per_revolution_count += 1;
        if !self.moving() {
            self.spindle_feed_step(true);
        }
    }

    /// Every servo period (interpolation): the feed of a G95 move under G96 follows the
    /// spindle's measured speed (taken into the planner when it has moved by
    /// `ADAPTIVE_STEP` of itself, as adaptive feed is). `now`: take it whatever the step.
    pub(super) fn spindle_feed_step(&mut self, now: bool) {
        let o = &mut self.overrides;
        if o.per_revolution_count == 0 {
            return;
        }
        // The mark in force: the last one at or before the piece being run (the first
        // one while none of them has started).
        let piece = self.path.planner.emitted_piece();
        let marks = &o.per_revolution[..o.per_revolution_count];
        let k = piece.map_or(0, |p| marks.iter().rposition(|m| m.0 <= p).unwrap_or(0));
        if k > 0 {
            o.per_revolution.copy_within(k..o.per_revolution_count, 0);
            o.per_revolution_count -= k;
        }
        let nominal = o.per_revolution[0].1;
        let factor = if nominal > 0.0 {
            let rps = self.interface.feedback.get().spindle_rpm.abs() / 60.0;
            clamped(rps / nominal, 0.0, 1.0, 0.0)
        } else {
            1.0
        };
        let in_force = o.spindle_feed;
        let reached_end = (factor == 0.0 || factor == 1.0) && factor != in_force;
        let moved = (factor - in_force).abs() >= ADAPTIVE_STEP * in_force;
        if factor != in_force && (now || reached_end || moved) {
            o.spindle_feed = factor;
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
