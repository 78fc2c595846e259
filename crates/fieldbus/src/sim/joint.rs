//! One simulated joint: a CiA 402 drive (state machine, velocity/position loops), the motor
//! and load, the encoder, limit and home switches, and the position latch.

use std::f64::consts::PI;

use crate::cia402::{Cia402State, StatusWord, error_code};
use crate::image::{DriveMode, JointCommand, JointFeedback, LatchFeedback, LatchSource};
use crate::sim::composed::{ComposedCycle, LinearDrive};
use crate::sim::config::{SimulatedJointConfig, SwitchRange};
use crate::sim::motor::MotorModel;

/// Below this speed (units/s) the drive reports a quick stop done (CiA 402's velocity
/// window, 0x606D).
const STANDSTILL_WINDOW: f64 = 0.01;

/// What the machine tells every drive about one cycle.
#[derive(Debug, Clone, Copy)]
pub(crate) struct CycleConditions {
    pub period_s: f64,
    pub substeps: usize,
    /// `period_s / substeps`.
    pub step_s: f64,
    /// Drive power is present (the e-stop chain is closed, or does not cut power).
    pub power: bool,
    /// The process-data watchdog expired.
    pub watchdog_expired: bool,
    /// The sub-steps that start before the command delay (the time from the sample to a
    /// new velocity or torque command acting): the previous command acts in them.
    pub delayed_substeps: usize,
}

#[derive(Debug, Clone)]
pub(crate) struct SimulatedJoint {
    mode: DriveMode,
    motor: MotorModel,
    units_per_revolution: f64,
    counts_per_revolution: f64,
    units_per_radian: f64,
    torque_limit: f64,
    velocity_gain: f64,
    velocity_integral_gain: f64,
    position_gain: f64,
    quick_stop_deceleration: f64,
    negative_limit: Option<f64>,
    positive_limit: Option<f64>,
    home_switch: Option<SwitchRange>,
    index_offset: Option<f64>,

    state: Cia402State,
    error_code: u16,
    fault_reset_was_high: bool,
    injected_fault: Option<u16>,
    encoder_lost: bool,
    counts: i64,
    counts_at_last_exchange: i64,
    velocity_integral: f64,
    previous_target: f64,
    quick_stop_velocity: f64,
    torque: f64,
    torque_limited: bool,
    latch_request: Option<LatchSource>,
    latch: LatchFeedback,
    /// A touch-probe latch caught and not yet reported: the position, and the exchanges
    /// until the drive reports it.
    probe_report: Option<(f64, u32)>,
    previous_command: JointCommand,
    /// A velocity drive's cycle in one step while it is linear (see `composed`).
    composed: Box<ComposedCycle>,
}

impl SimulatedJoint {
    pub(crate) fn new(config: &SimulatedJointConfig) -> Self {
        let bandwidth = 2.0 * PI * config.velocity_loop_bandwidth_hz;
        let inertia = config.motor.inertia;
        let units_per_radian = config.units_per_revolution / (2.0 * PI);
        let mut joint = Self {
            mode: config.drive,
            motor: MotorModel::new(
                &config.motor,
                config.units_per_revolution,
                config.initial_position,
            ),
            units_per_revolution: config.units_per_revolution,
            counts_per_revolution: f64::from(config.encoder_counts_per_revolution),
            units_per_radian,
            torque_limit: config.motor.torque_limit,
            // PI velocity loop tuned on the configured inertia: crossover at `bandwidth`,
            // integral corner a quarter of it (a critically damped double pole at bw/2).
            velocity_gain: inertia * bandwidth,
            velocity_integral_gain: inertia * bandwidth * bandwidth / 4.0,
            position_gain: config.position_loop_gain,
            quick_stop_deceleration: config.quick_stop_deceleration,
            negative_limit: config.negative_limit_switch,
            positive_limit: config.positive_limit_switch,
            home_switch: config.home_switch,
            index_offset: config.index_offset,
            state: Cia402State::NotReadyToSwitchOn,
            error_code: error_code::NONE,
            fault_reset_was_high: false,
            injected_fault: None,
            encoder_lost: false,
            counts: 0,
            counts_at_last_exchange: 0,
            velocity_integral: 0.0,
            previous_target: config.initial_position,
            quick_stop_velocity: 0.0,
            torque: 0.0,
            torque_limited: false,
            latch_request: None,
            latch: LatchFeedback::default(),
            probe_report: None,
            previous_command: JointCommand::default(),
            composed: Box::new(ComposedCycle::new()),
        };
        joint.counts = joint.encoder_counts(config.initial_position);
        joint.counts_at_last_exchange = joint.counts;
        joint
    }

    /// The drive's CiA 402 state.
    pub(crate) fn drive_state(&self) -> Cia402State {
        self.state
    }

    pub(crate) fn true_position(&self) -> f64 {
        self.motor.position()
    }

    pub(crate) fn true_velocity(&self) -> f64 {
        self.motor.velocity()
    }

    pub(crate) fn set_injected_fault(&mut self, code: Option<u16>) {
        self.injected_fault = code;
    }

    pub(crate) fn set_encoder_lost(&mut self, lost: bool) {
        self.encoder_lost = lost;
    }

    fn encoder_counts(&self, position: f64) -> i64 {
        floor_to_i64(position / self.units_per_revolution * self.counts_per_revolution)
    }

    fn counts_to_position(&self, counts: i64) -> f64 {
        counts as f64 / self.counts_per_revolution * self.units_per_revolution
    }

    /// The fault the drive detects this cycle, as a CiA 402 error code.
    fn fault_cause(&self, conditions: &CycleConditions) -> Option<u16> {
        if let Some(code) = self.injected_fault {
            return Some(code);
        }
        // A drive that closes the position loop itself sees its encoder go.
        if self.encoder_lost && self.mode.takes_position() {
            return Some(error_code::POSITION_SENSOR);
        }
        if conditions.watchdog_expired {
            return Some(error_code::COMMUNICATION);
        }
        None
    }

    /// One transition of the state machine per cycle, from the controlword and events.
    fn step_state_machine(&mut self, command: &JointCommand, conditions: &CycleConditions) {
        let fault_reset_high = command.controlword.fault_reset_requested();
        let fault_reset_edge = fault_reset_high && !self.fault_reset_was_high;
        self.fault_reset_was_high = fault_reset_high;
        let previous = self.state;
        let cause = self.fault_cause(conditions);
        self.state = match self.state {
            Cia402State::NotReadyToSwitchOn => Cia402State::SwitchOnDisabled, // 1
            Cia402State::FaultReactionActive => Cia402State::Fault,           // 14
            Cia402State::Fault => {
                if fault_reset_edge && cause.is_none() {
                    self.error_code = error_code::NONE;
                    Cia402State::SwitchOnDisabled // 15
                } else {
                    Cia402State::Fault
                }
            }
            state => match cause {
                Some(code) => {
                    self.error_code = code;
                    Cia402State::FaultReactionActive // 13
                }
                None if !conditions.power => Cia402State::SwitchOnDisabled,
                None => state.after_command(command.controlword.command()),
            },
        };
        if self.state == Cia402State::OperationEnabled && previous != Cia402State::OperationEnabled
        {
            self.velocity_integral = 0.0;
            self.previous_target = if command.target_position.is_finite() {
                command.target_position
            } else {
                self.motor.position()
            };
        }
        if self.state == Cia402State::QuickStopActive && previous != Cia402State::QuickStopActive {
            self.quick_stop_velocity = self.motor.velocity();
        }
    }

    fn step_latch_request(&mut self, request: Option<LatchSource>) {
        if request != self.latch_request {
            self.latch = LatchFeedback {
                armed: request.is_some(),
                ..LatchFeedback::default()
            };
            self.latch_request = request;
            self.probe_report = None;
        }
    }

    /// The touch probe's edge passed at `position` (the load's true position at the
    /// edge's instant): an armed touch-probe latch of that edge catches it (in whole
    /// counts) and reports it after `report_after` exchanges (0: in this one's feedback).
    pub(crate) fn touch_probe_edge(
        &mut self,
        rising: bool,
        position: f64,
        report_after: u32,
        feedback: &mut JointFeedback,
    ) {
        if self.latch_request != Some(LatchSource::TouchProbe { rising })
            || !self.latch.armed
            || self.latch.latched
            || self.probe_report.is_some()
            || self.encoder_lost
        {
            return;
        }
        // An ideal drive reports exact positions (its feedback too), any other whole counts.
        let caught = if self.mode == DriveMode::Ideal {
            position
        } else {
            self.counts_to_position(self.encoder_counts(position))
        };
        if report_after == 0 {
            self.latch.latched = true;
            self.latch.position = caught;
            feedback.latch = self.latch;
        } else {
            self.probe_report = Some((caught, report_after));
        }
    }

    /// One exchange nearer the touch-probe latch's report; reports it when due.
    fn report_probe_latch(&mut self) {
        match self.probe_report {
            Some((position, n)) if n <= 1 => {
                self.latch.latched = true;
                self.latch.position = position;
                self.probe_report = None;
            }
            Some((position, n)) => self.probe_report = Some((position, n - 1)),
            None => {}
        }
    }

    /// The torque of the PI velocity loop for `velocity_command` (units/s), integrating
    /// over `step_s` unless the torque limit holds it (anti-windup).
    fn velocity_loop(&mut self, velocity_command: f64, extra_torque: f64, step_s: f64) -> f64 {
        let error = (velocity_command - self.motor.velocity()) / self.units_per_radian;
        let torque = self.velocity_gain * error + self.velocity_integral + extra_torque;
        let saturated = torque.abs() >= self.torque_limit && torque * error > 0.0;
        if !saturated {
            self.velocity_integral += self.velocity_integral_gain * error * step_s;
        }
        torque
    }

    /// Advances the joint by one cycle under `command` and writes its feedback.
    pub(crate) fn cycle(
        &mut self,
        command: &JointCommand,
        conditions: &CycleConditions,
        feedback: &mut JointFeedback,
    ) {
        if self.begin_cycle(command, conditions) {
            let substeps = conditions.substeps.max(1);
            for substep in 1..=substeps {
                self.substep(command, conditions, substep);
            }
        }
        self.end_cycle(command, conditions, feedback);
    }

    /// The start of an exchange cycle: state machine, latch request, and for an ideal drive
    /// the whole move. Returns whether the cycle has sub-steps to run
    /// ([`substep`](Self::substep) for 1..=substeps, then [`end_cycle`](Self::end_cycle)).
    /// The machine runs the sub-steps of all joints interleaved, which changes no joint's
    /// arithmetic but lets the processor overlap the joints' independent chains.
    pub(crate) fn begin_cycle(
        &mut self,
        command: &JointCommand,
        conditions: &CycleConditions,
    ) -> bool {
        self.step_state_machine(command, conditions);
        self.step_latch_request(command.latch);
        self.torque_limited = false;
        if self.mode == DriveMode::Ideal {
            self.torque = 0.0;
            let before = self.motor.position();
            // A non-finite target (impossible on a real bus, which carries integers) holds.
            if self.state == Cia402State::OperationEnabled && command.target_position.is_finite() {
                let velocity = (command.target_position - before) / conditions.period_s;
                self.motor.place(command.target_position, velocity);
            } else {
                self.motor.place(before, 0.0);
            }
            self.update_latch(before, self.motor.position());
            return false;
        }
        !self.composed_cycle(command, conditions)
    }

    /// A velocity drive's cycle in one composed step, when the drive is in control, no
    /// latch is waiting for an edge and every sub-step stays linear (no torque clamp, no
    /// stop); returns whether it ran.
    fn composed_cycle(&mut self, command: &JointCommand, conditions: &CycleConditions) -> bool {
        if self.mode != DriveMode::Velocity
            || self.state != Cia402State::OperationEnabled
            || (self.latch.armed && !self.latch.latched && !self.encoder_lost)
        {
            return false;
        }
        let substeps = conditions.substeps.max(1);
        let step_s = conditions.step_s;
        let delayed = conditions.delayed_substeps;
        let (acceleration_per_torque, decay_rate, coulomb) = self.motor.linear_parts();
        let drive = LinearDrive {
            units_per_radian: self.units_per_radian,
            velocity_gain: self.velocity_gain,
            velocity_integral_gain: self.velocity_integral_gain,
            acceleration_per_torque,
            decay_rate,
        };
        if self.motor.velocity() == 0.0 {
            return self.stuck_cycle(command, conditions, delayed, coulomb);
        }
        if !self.composed.prepare(&drive, step_s, substeps, delayed) {
            return false;
        }
        let Some(result) = self.composed.run(
            self.motor.velocity(),
            self.velocity_integral,
            self.previous_command.target_velocity,
            command.target_velocity,
            coulomb,
            self.torque_limit,
        ) else {
            return false;
        };
        self.motor
            .place(self.motor.position() + result.displacement, result.velocity);
        self.velocity_integral = result.velocity_integral;
        self.torque = result.torque;
        true
    }

    /// A velocity drive's cycle at rest when stiction holds the load through every
    /// sub-step: only the velocity loop's integral moves. The same arithmetic as the
    /// sub-steps (bit for bit); returns false, with nothing changed, when the load would
    /// break loose or the torque would clamp in some sub-step.
    fn stuck_cycle(
        &mut self,
        command: &JointCommand,
        conditions: &CycleConditions,
        delayed: usize,
        coulomb: f64,
    ) -> bool {
        let previous = self.previous_command.target_velocity;
        let current = command.target_velocity;
        if !(previous.is_finite() && current.is_finite() && self.velocity_integral.is_finite()) {
            return false;
        }
        let (acceleration_per_torque, _, _) = self.motor.linear_parts();
        let stays_stuck = |torque: f64| {
            torque.abs() < self.torque_limit && (torque * acceleration_per_torque).abs() <= coulomb
        };
        let substeps = conditions.substeps.max(1);
        let delayed = delayed.min(substeps);
        let mut integral = self.velocity_integral;
        let mut torque = self.torque;
        // v = 0: the error is the command over the units per radian. Within the sub-steps
        // under one command the error is fixed, so the integral takes the same increment
        // every time and moves one way (rounding keeps a sum on the side it moves to), and
        // so does the torque: its extremes are those of the first and the last sub-step, and
        // checking those two checks every one.
        for (command, steps) in [(previous, delayed), (current, substeps - delayed)] {
            if steps == 0 {
                continue;
            }
            let error = (command - 0.0) / self.units_per_radian;
            let proportional = self.velocity_gain * error;
            let increment = self.velocity_integral_gain * error * conditions.step_s;
            let first = proportional + integral + 0.0;
            for _ in 1..steps {
                let next = integral + increment;
                // Once an increment changes nothing, none of the rest does either.
                if next.to_bits() == integral.to_bits() {
                    break;
                }
                integral = next;
            }
            torque = proportional + integral + 0.0;
            integral += increment;
            if !(stays_stuck(first) && stays_stuck(torque)) {
                return false;
            }
        }
        self.velocity_integral = integral;
        self.torque = torque;
        true
    }

    /// Sub-step `substep` (1-based) of the cycle: the drive's loops once, the torque held.
    #[inline]
    pub(crate) fn substep(
        &mut self,
        command: &JointCommand,
        conditions: &CycleConditions,
        substep: usize,
    ) {
        let substeps = conditions.substeps.max(1);
        let step_s = conditions.step_s;
        let started = (substep - 1) as f64;
        // Velocity and torque commands reach the motor `command_delay_s` after the sample
        // (the controller's computation and the DAC): until then the previous command acts.
        // A CSP drive's timing is its interpolation.
        let delayed = substep <= conditions.delayed_substeps && self.mode != DriveMode::Csp;
        let previous = self.previous_command;
        let active = if delayed { &previous } else { command };
        let mut demand = self.torque_demand(active, started, substeps, step_s);
        if !demand.is_finite() {
            // A non-finite command gives no torque rather than poisoning the model.
            demand = 0.0;
            self.velocity_integral = 0.0;
        }
        let torque = demand.clamp(-self.torque_limit, self.torque_limit);
        self.torque_limited |= torque != demand;
        self.torque = torque;
        let before = self.motor.position();
        self.motor.advance(torque, step_s);
        self.update_latch(before, self.motor.position());
    }

    /// The end of the cycle: the encoder and the feedback.
    pub(crate) fn end_cycle(
        &mut self,
        command: &JointCommand,
        conditions: &CycleConditions,
        feedback: &mut JointFeedback,
    ) {
        if self.state == Cia402State::OperationEnabled && command.target_position.is_finite() {
            self.previous_target = command.target_position;
        }
        self.previous_command = *command;
        self.report_probe_latch();
        if !self.encoder_lost {
            self.counts = self.encoder_counts(self.motor.position());
        }
        self.write_feedback(conditions.period_s, feedback);
    }

    /// The torque the drive asks for in the sub-step that starts `started` sub-steps into
    /// the cycle's `substeps`.
    fn torque_demand(
        &mut self,
        command: &JointCommand,
        started: f64,
        substeps: usize,
        step_s: f64,
    ) -> f64 {
        match self.state {
            Cia402State::OperationEnabled => match self.mode {
                DriveMode::Velocity => self.velocity_loop(command.target_velocity, 0.0, step_s),
                DriveMode::Csp => {
                    // Linear interpolation from the previous target to this one over the
                    // cycle: the reference reaches each target one period after it
                    // arrives, which is the lag of a CSP drive.
                    let fraction = started / substeps as f64;
                    let target = self.previous_target
                        + (command.target_position - self.previous_target) * fraction;
                    let velocity = self.position_gain * (target - self.motor.position())
                        + command.velocity_offset;
                    self.velocity_loop(velocity, command.torque_offset, step_s)
                }
                DriveMode::Torque => command.target_torque + command.torque_offset,
                DriveMode::Ideal => 0.0,
            },
            Cia402State::QuickStopActive => {
                let change = self.quick_stop_deceleration * step_s;
                let v = self.quick_stop_velocity;
                self.quick_stop_velocity = if v > change {
                    v - change
                } else if v < -change {
                    v + change
                } else {
                    0.0
                };
                self.velocity_loop(self.quick_stop_velocity, 0.0, step_s)
            }
            _ => {
                self.velocity_integral = 0.0;
                0.0
            }
        }
    }

    #[inline]
    fn update_latch(&mut self, before: f64, after: f64) {
        if !self.latch.armed || self.latch.latched || self.encoder_lost || before == after {
            return;
        }
        self.catch_latch(before, after);
    }

    fn catch_latch(&mut self, before: f64, after: f64) {
        let event = match self.latch_request {
            Some(LatchSource::IndexPulse) => self.index_between(before, after),
            Some(LatchSource::HomeSwitch) => self.home_edge_between(before, after),
            // The machine finds the probe's edge (it knows the probe): `touch_probe_edge`.
            Some(LatchSource::TouchProbe { .. }) | None => None,
        };
        if let Some(position) = event {
            self.latch.latched = true;
            self.latch.position = self.counts_to_position(self.encoder_counts(position));
        }
    }

    /// The first index position passed moving from `before` to `after`.
    fn index_between(&self, before: f64, after: f64) -> Option<f64> {
        let offset = self.index_offset?;
        let pitch = self.units_per_revolution;
        let n_before = ((before - offset) / pitch).floor();
        let n_after = ((after - offset) / pitch).floor();
        if n_before == n_after {
            return None;
        }
        // Index n sits at offset + n·pitch; moving up the first crossed is n_before + 1,
        // moving down it is n_before.
        let n = if after > before {
            n_before + 1.0
        } else {
            n_before
        };
        Some(offset + n * pitch)
    }

    /// The first home-switch edge passed moving from `before` to `after`.
    fn home_edge_between(&self, before: f64, after: f64) -> Option<f64> {
        let range = self.home_switch?;
        // The switch is on for from <= x <= to; the latch holds the edge it passed.
        let crossed = |edge: f64| (before < edge) != (after < edge);
        let upper = range.to;
        let edges = if after > before {
            [range.from, upper]
        } else {
            [upper, range.from]
        };
        edges.into_iter().find(|&edge| crossed(edge))
    }

    fn write_feedback(&mut self, period_s: f64, feedback: &mut JointFeedback) {
        let position = if self.mode == DriveMode::Ideal && !self.encoder_lost {
            self.motor.position()
        } else {
            self.counts_to_position(self.counts)
        };
        let moved = self.counts.wrapping_sub(self.counts_at_last_exchange);
        self.counts_at_last_exchange = self.counts;
        let mut status = StatusWord::state_bits(self.state) | StatusWord::REMOTE;
        if matches!(
            self.state,
            Cia402State::ReadyToSwitchOn
                | Cia402State::SwitchedOn
                | Cia402State::OperationEnabled
                | Cia402State::QuickStopActive
        ) {
            status |= StatusWord::VOLTAGE_ENABLED;
        }
        if self.torque_limited {
            status |= StatusWord::INTERNAL_LIMIT;
        }
        // A quick stop is done once its ramp has reached zero and the load stands within
        // the velocity window (0x606D's role).
        if self.state == Cia402State::QuickStopActive
            && self.quick_stop_velocity == 0.0
            && self.motor.velocity().abs() <= STANDSTILL_WINDOW
        {
            status |= StatusWord::TARGET_REACHED;
        }
        let true_position = self.motor.position();
        *feedback = JointFeedback {
            statusword: StatusWord(status),
            error_code: self.error_code,
            position,
            position_counts: self.counts,
            velocity: self.counts_to_position(moved) / period_s,
            torque: self.torque,
            negative_limit: self
                .negative_limit
                .is_some_and(|limit| true_position <= limit),
            positive_limit: self
                .positive_limit
                .is_some_and(|limit| true_position >= limit),
            home_switch: self
                .home_switch
                .is_some_and(|range| range.from <= true_position && true_position <= range.to),
            latch: self.latch,
        };
    }
}

/// `x.floor() as i64`: saturating at the i64 range, NaN to 0 (no panic on any state), with
/// no call to `floor`, which a target without SSE4.1 makes for every encoder reading. The
/// conversion truncates towards zero, one too high for a negative number with a fraction,
/// and converting back shows it exactly (every double from 2^52 on is whole).
fn floor_to_i64(x: f64) -> i64 {
    let truncated = x as i64;
    if truncated as f64 > x {
        truncated.saturating_sub(1)
    } else {
        truncated
    }
}

#[cfg(test)]
mod tests {
    use super::floor_to_i64;

    #[test]
    fn floor_to_i64_is_floor_as_i64() {
        let mut values = vec![
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            -1e-300,
            1e-300,
            4503599627370495.5,
            -4503599627370495.5,
            9007199254740993.0,
            -9007199254740993.0,
            i64::MAX as f64,
            i64::MIN as f64,
            -9.223372036854777e18,
            1e19,
            -1e19,
            f64::MAX,
            f64::MIN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ];
        let mut seed = 0x9e37_79b9_7f4a_7c15_u64;
        for _ in 0..100_000 {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            let unit = (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            values.extend([unit, unit * 1e3, unit * 2.6e7, f64::from_bits(seed)]);
        }
        for x in values {
            assert_eq!(floor_to_i64(x), x.floor() as i64, "{x:e}");
        }
    }
}
