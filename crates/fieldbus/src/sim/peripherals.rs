//! The spindle and the tool changer of the simulated machine.

use crate::image::{SpindleCommand, SpindleFeedback, ToolChangeCommand, ToolChangerFeedback};
use crate::sim::config::{SpindleConfig, ToolChangerConfig};

/// A spindle drive that ramps its speed at a fixed acceleration.
#[derive(Debug, Clone)]
pub(crate) struct Spindle {
    config: SpindleConfig,
    speed_rpm: f64,
}

impl Spindle {
    pub(crate) fn new(config: SpindleConfig) -> Self {
        Self {
            config,
            speed_rpm: 0.0,
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
        let target = self.target(command, power);
        let change = self.config.acceleration_rpm_per_s * period_s;
        let difference = target - self.speed_rpm;
        self.speed_rpm = if difference.abs() <= change {
            target
        } else {
            self.speed_rpm + change.copysign(difference)
        };
        let at_speed =
            (self.speed_rpm - target).abs() <= self.config.at_speed_tolerance * target.abs();
        SpindleFeedback {
            speed_rpm: self.speed_rpm,
            at_speed,
        }
    }
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

/// Whole nanoseconds in `seconds` (validated finite and in range by the caller).
pub(crate) fn seconds_to_ns(seconds: f64) -> u64 {
    (seconds * 1e9).round() as u64
}
