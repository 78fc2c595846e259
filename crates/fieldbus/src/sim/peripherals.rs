//! The spindle and the tool changer of the simulated machine.

use crate::image::{SpindleCommand, SpindleFeedback, ToolChangeCommand, ToolChangerFeedback};
use crate::sim::config::{SpindleConfig, ToolChangerConfig};

/// A spindle drive that ramps its speed jerk-limited (an S-curve: acceleration and its rate
/// of change both bounded), with an encoder angle and an orientation mode (M19).
#[derive(Debug, Clone)]
pub(crate) struct Spindle {
    config: SpindleConfig,
    speed_rpm: f64,
    /// rev/min per second.
    acceleration_rpm_per_s: f64,
    /// Angle turned since power-up, degrees (clockwise positive, not wrapped).
    position_deg: f64,
    /// The orientation being done: its target (unwrapped) and the command it answers.
    orient: Option<(f64, f64, u8)>,
}

impl Spindle {
    pub(crate) fn new(config: SpindleConfig) -> Self {
        Self {
            config,
            speed_rpm: 0.0,
            acceleration_rpm_per_s: 0.0,
            position_deg: 0.0,
            orient: None,
        }
    }

    /// Angle from the index, degrees (0 ≤ angle < 360).
    pub(crate) fn angle_deg(&self) -> f64 {
        degrees_within_turn(self.position_deg)
    }

    /// The unwrapped target of an orientation to `angle` from where the spindle stands.
    fn orient_target(&self, angle: f64, mode: u8) -> f64 {
        let here = self.angle_deg();
        let angle = if angle.is_finite() {
            angle.rem_euclid(360.0)
        } else {
            0.0
        };
        let clockwise = (angle - here).rem_euclid(360.0);
        let counter = clockwise - 360.0;
        let delta = match mode {
            1 => clockwise,
            2 if clockwise == 0.0 => 0.0,
            2 => counter,
            _ if clockwise <= -counter => clockwise,
            _ => counter,
        };
        self.position_deg + delta
    }

    /// Orientation: stop at the acceleration, then turn at the orientation speed to the
    /// angle and hold it. Returns whether it stands within the tolerance.
    fn orient_cycle(&mut self, command: &SpindleCommand, power: bool, period_s: f64) -> bool {
        let key = (command.orient_angle_deg, command.orient_mode);
        if !power {
            self.ramp(0.0, period_s);
            self.orient = None;
            return false;
        }
        if self.speed_rpm != 0.0 {
            self.ramp(0.0, period_s);
            self.orient = None;
            return false;
        }
        let target = match self.orient {
            Some((target, angle, mode)) if (angle, mode) == key => target,
            _ => {
                let target = self.orient_target(key.0, key.1);
                self.orient = Some((target, key.0, key.1));
                target
            }
        };
        // Degrees per period at the orientation speed (rpm × 360 / 60).
        let step = self.config.orient_speed_rpm * 6.0 * period_s;
        let remaining = target - self.position_deg;
        if remaining.abs() <= step * (1.0 + 1e-9) {
            self.position_deg = target;
        } else {
            self.position_deg += step.copysign(remaining);
        }
        (target - self.position_deg).abs() <= self.config.orient_tolerance_deg
    }

    /// Ramps the speed towards `target` over one period and turns the angle with it. The
    /// time-optimal jerk-limited ramp from the present speed and acceleration is planned
    /// afresh every period (a plan's remainder is the plan from any state on it, so a
    /// steady target gives one S-curve, and a new target bends it without an acceleration
    /// step), and followed for one period.
    fn ramp(&mut self, target: f64, period_s: f64) {
        if self.speed_rpm == target && self.acceleration_rpm_per_s == 0.0 && period_s > 0.0 {
            // At the target and not accelerating (the spindle at speed, or standing): the
            // S-curve's pieces are all empty and the ramp below ends at once, at the target.
            self.speed_rpm = target;
            self.acceleration_rpm_per_s = 0.0;
            let turned_rpm_s = 0.0 + target * period_s;
            if turned_rpm_s.is_finite() {
                self.position_deg += turned_rpm_s * 6.0;
            }
            return;
        }
        let pieces = s_curve(
            self.speed_rpm,
            self.acceleration_rpm_per_s,
            target,
            self.config.acceleration_rpm_per_s,
            self.config.jerk_rpm_per_s2,
        );
        let mut speed = self.speed_rpm;
        let mut acceleration = self.acceleration_rpm_per_s;
        let mut turned_rpm_s = 0.0;
        let mut left = period_s;
        for (duration, jerk) in pieces {
            let t = duration.min(left);
            if t <= 0.0 {
                continue;
            }
            turned_rpm_s += speed * t + acceleration * t * t / 2.0 + jerk * t * t * t / 6.0;
            speed += acceleration * t + jerk * t * t / 2.0;
            acceleration += jerk * t;
            left -= t;
        }
        if left > 0.0 || !(speed.is_finite() && acceleration.is_finite()) {
            // The ramp ends within this period: exactly at the target, at rest.
            turned_rpm_s += target * left.max(0.0);
            speed = target;
            acceleration = 0.0;
        }
        self.speed_rpm = speed;
        self.acceleration_rpm_per_s = acceleration;
        // rev/min × s = 1/60 rev = 6°.
        if turned_rpm_s.is_finite() {
            self.position_deg += turned_rpm_s * 6.0;
        }
    }

    fn target(&self, command: &SpindleCommand, power: bool) -> f64 {
        if command.enable && power && command.speed_rpm.is_finite() {
            command
                .speed_rpm
                .clamp(-self.config.max_speed_rpm, self.config.max_speed_rpm)
        } else {
            0.0
        }
    }

    /// Ramps over `period_s` towards the command and reports speed and at-speed.
    pub(crate) fn cycle(
        &mut self,
        command: &SpindleCommand,
        power: bool,
        period_s: f64,
    ) -> SpindleFeedback {
        if command.orient {
            let oriented = self.orient_cycle(command, power, period_s);
            return SpindleFeedback {
                speed_rpm: self.speed_rpm,
                at_speed: false,
                position_deg: self.angle_deg(),
                oriented,
            };
        }
        self.orient = None;
        let target = self.target(command, power);
        self.ramp(target, period_s);
        let at_speed =
            (self.speed_rpm - target).abs() <= self.config.at_speed_tolerance * target.abs();
        SpindleFeedback {
            speed_rpm: self.speed_rpm,
            at_speed,
            position_deg: self.angle_deg(),
            oriented: false,
        }
    }
}

/// The time-optimal ramp of a speed from `speed` at `acceleration` to `target` at zero
/// acceleration with |acceleration| ≤ `max_acceleration` and |jerk| ≤ `max_jerk`, as three
/// (duration, jerk) pieces: jerk towards the target up to the peak acceleration, the peak
/// held, jerk back to zero. The direction is the side of the target on which the speed
/// would settle if the acceleration were brought to zero at once.
fn s_curve(
    speed: f64,
    acceleration: f64,
    target: f64,
    max_acceleration: f64,
    max_jerk: f64,
) -> [(f64, f64); 3] {
    let settles_at = speed + acceleration * acceleration.abs() / (2.0 * max_jerk);
    let direction = if target >= settles_at { 1.0 } else { -1.0 };
    // The speed change towards the target, and the acceleration along it.
    let change = direction * (target - speed);
    let along = direction * acceleration;
    // With no hold: the peak p from p² = J·change + a0²/2 (up from a0, down from p).
    let mut peak = (max_jerk * change + acceleration * acceleration / 2.0)
        .max(0.0)
        .sqrt();
    let mut hold = 0.0;
    if peak > max_acceleration {
        peak = max_acceleration;
        let ramps = (2.0 * peak * peak - acceleration * acceleration) / (2.0 * max_jerk);
        hold = ((change - ramps) / peak).max(0.0);
    }
    let peak = peak.max(along);
    [
        ((peak - along) / max_jerk, direction * max_jerk),
        (hold, 0.0),
        (peak / max_jerk, -direction * max_jerk),
    ]
}

/// A tool changer that completes a change a fixed time after the request.
#[derive(Debug, Clone)]
pub(crate) struct ToolChanger {
    change_time_ns: u64,
    current_tool: u32,
    pending_tool: u32,
    remaining_ns: u64,
    busy: bool,
    finished: bool,
    start_was_high: bool,
}

impl ToolChanger {
    pub(crate) fn new(config: ToolChangerConfig) -> Self {
        Self {
            change_time_ns: seconds_to_ns(config.change_time_s),
            current_tool: config.initial_tool,
            pending_tool: config.initial_tool,
            remaining_ns: 0,
            busy: false,
            finished: false,
            start_was_high: false,
        }
    }

    /// Advances by `period_ns` (whole nanoseconds, so the change time is exact).
    pub(crate) fn cycle(
        &mut self,
        command: &ToolChangeCommand,
        period_ns: u64,
    ) -> ToolChangerFeedback {
        if command.start && !self.start_was_high && !self.busy {
            self.busy = true;
            self.finished = false;
            self.pending_tool = command.tool;
            self.remaining_ns = self.change_time_ns;
        }
        self.start_was_high = command.start;
        if self.busy {
            self.remaining_ns = self.remaining_ns.saturating_sub(period_ns);
            if self.remaining_ns == 0 {
                self.busy = false;
                self.finished = true;
                self.current_tool = self.pending_tool;
            }
        }
        if !command.start {
            self.finished = false;
        }
        ToolChangerFeedback {
            current_tool: self.current_tool,
            busy: self.busy,
            done: self.finished,
        }
    }
}

/// `degrees.rem_euclid(360.0)`, bit for bit, without `fmod`: compiled as a loop over the
/// bits, it cost some 150 instructions of every exchange, which reports the angle. The
/// remainder of a division is exact, so taking the right number of whole turns away gives
/// it exactly; the quotient, rounded, can be one turn off, which the range check puts right.
pub(crate) fn degrees_within_turn(degrees: f64) -> f64 {
    const TURN: f64 = 360.0;
    // Below 2^50 degrees the rounded quotient is within one turn of the true one, and whole
    // turns are exact doubles.
    const EXACT_BELOW: f64 = (1u64 << 50) as f64;
    let magnitude = degrees.abs();
    if magnitude.is_nan() || magnitude >= EXACT_BELOW {
        return degrees.rem_euclid(TURN);
    }
    // Signed, which converts to and from a double in one instruction each.
    let after_turns = |turns: i64| magnitude - turns as f64 * TURN;
    let turns = (magnitude / TURN) as i64;
    let mut remainder = after_turns(turns);
    if remainder < 0.0 {
        remainder = after_turns(turns.saturating_sub(1));
    } else if remainder >= TURN {
        remainder = after_turns(turns.saturating_add(1));
    }
    // As `%`: the sign of the dividend, on a zero too; then `rem_euclid`'s step up.
    let truncated = remainder.copysign(degrees);
    if truncated < 0.0 {
        truncated + TURN
    } else {
        truncated
    }
}

/// Whole nanoseconds in `seconds` (validated finite and in range by the caller).
pub(crate) fn seconds_to_ns(seconds: f64) -> u64 {
    (seconds * 1e9).round() as u64
}

#[cfg(test)]
mod tests {
    use super::degrees_within_turn;

    fn same(a: f64, b: f64) -> bool {
        a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
    }

    #[test]
    fn degrees_within_turn_is_rem_euclid_bit_for_bit() {
        let mut values = vec![
            0.0,
            -0.0,
            f64::MIN_POSITIVE,
            -f64::MIN_POSITIVE,
            1e-300,
            -1e-300,
            f64::MAX,
            f64::MIN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            (1u64 << 50) as f64,
            -((1u64 << 50) as f64),
        ];
        // Whole turns and their neighbours, where a rounded quotient is one turn off.
        for turns in [1u64, 2, 3, 7, 1000, 123_456_789, (1 << 42) - 1, 1 << 42] {
            let edge = turns as f64 * 360.0;
            let above = f64::from_bits(edge.to_bits() + 1);
            let below = f64::from_bits(edge.to_bits() - 1);
            for x in [edge, above, below, edge + 359.999, edge - 1e-9] {
                values.extend([x, -x]);
            }
        }
        // A spindle's angle over a long run: many steps of irregular size.
        let mut x = 0.0_f64;
        let mut seed = 0x2545_f491_4f6c_dd1d_u64;
        for _ in 0..200_000 {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            let unit = (seed >> 11) as f64 / (1u64 << 53) as f64;
            x += (unit - 0.3) * 1e4;
            values.extend([x, x * 1e7, unit * 720.0 - 360.0]);
        }
        for x in values {
            assert!(
                same(degrees_within_turn(x), x.rem_euclid(360.0)),
                "{x:e}: {} != {}",
                degrees_within_turn(x),
                x.rem_euclid(360.0)
            );
        }
    }
}
