//! Position control and drive I/O: the two task functions of the fieldbus thread. Position
//! control takes the newest set-point, runs every joint's servo loop on the feedback of the
//! last exchange and writes the drive commands; drive I/O writes the machine interface's
//! outputs, exchanges the process image, checks limit switches, drive faults and the
//! e-stop input, and publishes the feedback image. Allocation-free per cycle.

use rtcnc_fieldbus::{
    Cia402State, ControlWord, Fieldbus, LatchSource, ProcessInputs, ProcessOutputs,
};
use rtcnc_motion::otg::{self, Limits, OnlineAxis};
use rtcnc_rt::{Context, LeadConsumer, RingProducer, SeqlockWriter};
use rtcnc_servo::{ServoCommand, ServoLoop, SetPointDifferentiator};

use crate::config::MAX_JOINTS;
use crate::fault::{FaultCode, TaskName};
use crate::motion::{DriveEnable, LatchRequest, ServoTarget};
use crate::shared::{Feedback, LogicOutputs, LogicRequests, Shared, Snapshot};

/// One recorded servo cycle (for the CSV files, plots and summaries of `rtcnc sim`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Servo cycle.
    pub cycle: u64,
    /// Time, ns.
    pub time_ns: u64,
    /// Joint set-points (machine coordinates).
    pub setpoint: [f64; MAX_JOINTS],
    /// Joint feedback (machine coordinates).
    pub feedback: [f64; MAX_JOINTS],
    /// Following error the servo loop saw.
    pub following_error: [f64; MAX_JOINTS],
    /// Axis set-point.
    pub axes: [f64; rtcnc_motion::AXES],
    /// Program line.
    pub line: u32,
    /// Path speed.
    pub path_speed: f64,
}

pub(crate) struct ServoStage<B: Fieldbus> {
    pub(crate) bus: B,
    outputs: ProcessOutputs,
    inputs: ProcessInputs,
    loops: Vec<ServoLoop>,
    differentiators: Vec<SetPointDifferentiator>,
    joint_count: usize,
    period_s: f64,
    target: Option<ServoTarget>,
    targets: LeadConsumer<ServoTarget>,
    recorder: Option<RingProducer<Sample>>,
    shared: Shared,
    feedback_out: SeqlockWriter<Feedback>,
    logic: Snapshot<LogicOutputs>,
    requests: Snapshot<LogicRequests>,
    was_enabled: u32,
    servo_fault: bool,
    reset_count: u32,
    limit_latched: u32,
    drive_fault_latched: u32,
    comm_fault: bool,
    /// The last exchange brought no fresh inputs (a lost frame the bus rode through).
    stale_inputs: bool,
    /// Per joint, the set-point of the last cycle that had fresh inputs.
    fresh_setpoint: [f64; MAX_JOINTS],
    estop_latched: bool,
    exchanges: u64,
    following_error: [f64; MAX_JOINTS],
    program_outputs: Vec<usize>,
    program_analog_outputs: Vec<usize>,
    previous_joints: [f64; MAX_JOINTS],
    underruns: u64,
    /// Per joint: the limits of its quick stop (for a stop of position control's own).
    stop_limits: Vec<Limits>,
    /// Interpolation let the set-points run dry: position control brings each joint to
    /// rest by itself along these generators, until the next reset.
    dry_stop: Option<[OnlineAxis; MAX_JOINTS]>,
    /// Bit n: joint n follows an auxiliary axis of the PLC, not interpolation.
    plc_joints: u32,
}

/// Cycles the fault-reset bit stays high, then low, while a faulted drive is to be enabled.
const FAULT_RESET_PULSE: u64 = 4;

/// The fieldbus thread corrects 1/this of the bus's phase error per cycle.
const PHASE_GAIN_DIVISOR: i64 = 10;

/// The kernel's fault for a failed exchange, and the value it carries (the AL status code
/// of a device that left OP, the working counter that came back).
fn fault_of(error: &rtcnc_fieldbus::FieldbusError) -> (FaultCode, f64) {
    use rtcnc_fieldbus::FieldbusError as E;
    match *error {
        E::WorkingCounter { received, .. } => (FaultCode::WorkingCounter, f64::from(received)),
        E::DeviceState { code, .. } => (FaultCode::DeviceState, f64::from(code)),
        E::LinkDown { .. } => (FaultCode::LinkDown, 0.0),
        E::CommunicationLost | E::ImageMismatch { .. } | E::InvalidPeriod { .. } => {
            (FaultCode::Communication, 0.0)
        }
    }
}

/// Periods without a set-point that position control bridges by going on along the last
/// two; the next one without is a fault (`kernel.setpoints_ran_dry`).
const BRIDGED_PERIODS: u64 = 4;

impl<B: Fieldbus> ServoStage<B> {
    // Every argument is one of the stage's own parts, handed over once at build time.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn new(
        bus: B,
        loops: Vec<ServoLoop>,
        period_s: f64,
        targets: LeadConsumer<ServoTarget>,
        recorder: Option<RingProducer<Sample>>,
        shared: Shared,
        feedback_out: SeqlockWriter<Feedback>,
        program_outputs: Vec<usize>,
    ) -> Self {
        let outputs = ProcessOutputs::new(bus.layout());
        let inputs = ProcessInputs::new(bus.layout());
        let joint_count = loops.len().min(MAX_JOINTS);
        ServoStage {
            bus,
            outputs,
            inputs,
            differentiators: vec![SetPointDifferentiator::new(); joint_count],
            loops,
            joint_count,
            period_s,
            target: None,
            targets,
            recorder,
            logic: Snapshot::new(shared.logic_outputs.clone()),
            requests: Snapshot::new(shared.requests.clone()),
            shared,
            feedback_out,
            was_enabled: 0,
            servo_fault: false,
            reset_count: 0,
            limit_latched: 0,
            drive_fault_latched: 0,
            comm_fault: false,
            stale_inputs: false,
            fresh_setpoint: [0.0; MAX_JOINTS],
            estop_latched: false,
            exchanges: 0,
            following_error: [0.0; MAX_JOINTS],
            program_outputs,
            program_analog_outputs: Vec::new(),
            previous_joints: [0.0; MAX_JOINTS],
            underruns: 0,
            stop_limits: Vec::new(),
            dry_stop: None,
            plc_joints: 0,
        }
    }

    /// Joints (bit n: joint n) whose set-points come from the PLC's auxiliary axes.
    pub(crate) fn with_plc_joints(mut self, mask: u32) -> Self {
        self.plc_joints = mask;
        self
    }

    /// The quick-stop limits of every joint, for the stop position control makes by itself
    /// when the set-points run dry.
    pub(crate) fn with_stop_limits(mut self, limits: Vec<Limits>) -> Self {
        self.stop_limits = limits;
        self
    }

    /// M67/M68 `E n` drive analogue output `points[n]`.
    pub(crate) fn with_program_analog_outputs(mut self, points: Vec<usize>) -> Self {
        self.program_analog_outputs = points;
        self
    }

    /// Position control: one servo cycle.
    pub(crate) fn position_control(&mut self, ctx: &mut Context<'_>) {
        self.take_setpoint();
        let Some(mut target) = self.target else {
            // Nothing planned yet: keep the drives where they are.
            for (command, feedback) in self.outputs.joints.iter_mut().zip(&self.inputs.joints) {
                command.controlword = feedback.state().controlword_towards(false);
            }
            return;
        };
        if target.reset_count != self.reset_count {
            self.clear_latched_faults(target.reset_count);
        }
        self.bridge_missing_setpoints(ctx, &mut target);
        let plc_unpowered = self.plc_axis_setpoints(ctx, &mut target);
        for j in 0..self.joint_count {
            self.control_joint(ctx, j, &target, plc_unpowered);
        }
        self.record(ctx, &target);
    }

    /// A reset (`reset_count` is the new count): the latched faults are cleared.
    #[inline]
    fn clear_latched_faults(&mut self, reset_count: u32) {
        self.reset_count = reset_count;
        self.servo_fault = false;
        // A switch still pressed stays latched, so the joint can be moved off it.
        self.limit_latched = 0;
        for (j, f) in self.inputs.joints.iter().enumerate().take(self.joint_count) {
            if f.negative_limit || f.positive_limit {
                self.limit_latched |= 1 << j;
            }
        }
        self.drive_fault_latched = 0;
        self.comm_fault = false;
        self.estop_latched = false;
        self.dry_stop = None;
    }

    /// Interpolation computes the set-points ahead (`tasks.setpoint_lead`); one is missing
    /// only when it stalled for longer than that. Then go on along the last two set-points
    /// for a few periods; beyond them it is a fault, and every joint is brought to rest
    /// here with its quick-stop limits, since interpolation cannot.
    #[inline]
    fn bridge_missing_setpoints(&mut self, ctx: &mut Context<'_>, target: &mut ServoTarget) {
        let missing = self.exchanges.saturating_sub(target.setpoints.cycle);
        if missing > 0 && target.enable != DriveEnable::Off {
            self.underruns += 1;
        }
        if missing > 0 && target.enable != DriveEnable::Off && self.dry_stop.is_none() {
            let k = missing.min(BRIDGED_PERIODS) as f64;
            let mut step = [0.0; MAX_JOINTS];
            for j in 0..self.joint_count {
                step[j] = target.setpoints.joints[j] - self.previous_joints[j];
                target.setpoints.joints[j] += step[j] * k;
            }
            if missing > BRIDGED_PERIODS {
                self.start_dry_stop(ctx, target, &step);
            }
        }
        if let Some(stops) = self.dry_stop.as_mut() {
            for (j, stop) in stops.iter_mut().enumerate().take(self.joint_count) {
                target.setpoints.joints[j] = stop.step(self.period_s).p;
            }
        }
    }

    /// The PLC's auxiliary axes: their joints' set-points (carried on from the logic task's
    /// last values to this period). Returns the joints (bits) whose drives MC_Power does
    /// not ask for.
    #[inline]
    fn plc_axis_setpoints(&mut self, ctx: &mut Context<'_>, target: &mut ServoTarget) -> u32 {
        let mut plc_unpowered = 0u32;
        if self.plc_joints != 0 {
            let plc = self.logic.get().plc_axes;
            // The logic's values are at least a period old (it runs after this thread):
            // the set-point is the PLC's profile one period ago, exact where the logic
            // runs every servo period and carried on by extrapolation where it runs less
            // often.
            let now = ctx
                .release_time()
                .as_nanos()
                .saturating_sub((self.period_s * 1e9) as u64);
            plc_unpowered = self.plc_joints;
            for i in 0..usize::from(plc.count).min(crate::config::MAX_PLC_AXES) {
                let j = usize::from(plc.joint[i]);
                if j < self.joint_count {
                    target.setpoints.joints[j] = plc.at(i, now) + target.offsets[j];
                    if plc.power & (1 << i) != 0 {
                        plc_unpowered &= !(1 << j);
                    }
                }
            }
        }
        plc_unpowered
    }

    /// Joint `j`'s drive command: its control word, its latch and, under control, its
    /// servo loop's output.
    #[inline]
    fn control_joint(
        &mut self,
        ctx: &mut Context<'_>,
        j: usize,
        target: &ServoTarget,
        plc_unpowered: u32,
    ) {
        let period = self.period_s;
        let (Some(command), Some(feedback), Some(servo), Some(diff)) = (
            self.outputs.joints.get_mut(j),
            self.inputs.joints.get(j),
            self.loops.get_mut(j),
            self.differentiators.get_mut(j),
        ) else {
            return;
        };
        let bit = 1u32 << j;
        let state = feedback.state();
        // During a quick stop only a drive still enabled stays so: one that lost its power
        // or faulted meanwhile is not brought up again before the operator's reset.
        let enable = match target.enable {
            DriveEnable::Off => false,
            DriveEnable::Keep => state == Cia402State::OperationEnabled,
            DriveEnable::On => true,
        };
        if state.is_fault() && enable {
            command.controlword =
                fault_reset_controlword(self.exchanges, self.was_enabled & bit != 0);
            self.was_enabled &= !bit;
            return;
        }
        command.controlword = if self.servo_fault {
            stop_category_1(state, feedback.statusword.target_reached())
        } else {
            state.controlword_towards(enable && plc_unpowered & bit == 0)
        };
        command.latch = latch_source(&target.latch, bit);
        let raw_target = target.setpoints.joints[j] - target.offsets[j];
        if state != Cia402State::OperationEnabled || self.servo_fault {
            // Not under control: hold the command at the actual position so that
            // enabling does not jump.
            self.was_enabled &= !bit;
            command.target_velocity = 0.0;
            command.target_position = feedback.position;
            command.velocity_offset = 0.0;
            command.torque_offset = 0.0;
            return;
        }
        if self.was_enabled & bit == 0 {
            self.was_enabled |= bit;
            servo.reset();
            diff.reset();
        }
        let setpoint = diff.next(raw_target, period);
        // Inputs left over from the last good cycle are compared as they were then: as
        // if the load had followed the set-points since.
        let measured = if self.stale_inputs {
            feedback.position + (setpoint.position - self.fresh_setpoint[j])
        } else {
            self.fresh_setpoint[j] = setpoint.position;
            feedback.position
        };
        match servo.update(setpoint, measured, period) {
            Ok(ServoCommand::Velocity(v)) => command.target_velocity = v,
            Ok(ServoCommand::Position(c)) => {
                command.target_position = c.position;
                command.velocity_offset = c.velocity_offset;
                command.torque_offset = c.torque_offset;
            }
            // With the e-stop input pressed the drives lose power (or are about to): a
            // following error then is its consequence, not a new fault.
            Err(_) if self.estop_latched => command.target_velocity = 0.0,
            Err(fault) => {
                if !self.servo_fault {
                    self.servo_fault = true;
                    let value = match fault {
                        rtcnc_servo::ServoFault::FollowingError { error, .. } => error,
                        _ => f64::NAN,
                    };
                    self.shared.raise(
                        ctx,
                        FaultCode::FollowingError,
                        TaskName::PositionControl,
                        Some(fault.joint() as u8),
                        target.setpoints.line,
                        value,
                    );
                }
                command.target_velocity = 0.0;
            }
        }
        self.following_error[j] = servo.following_error().last_error();
    }

    /// The period's sample for `rtcnc sim`'s recording, if there is one.
    #[inline]
    fn record(&mut self, ctx: &mut Context<'_>, target: &ServoTarget) {
        if let Some(recorder) = self.recorder.as_mut() {
            let mut feedback = [0.0; MAX_JOINTS];
            for j in 0..self.joint_count {
                if let Some(f) = self.inputs.joints.get(j) {
                    feedback[j] = f.position + target.offsets[j];
                }
            }
            let _ = recorder.push(Sample {
                cycle: target.setpoints.cycle,
                time_ns: ctx.release_time().as_nanos(),
                setpoint: target.setpoints.joints,
                feedback,
                following_error: self.following_error,
                axes: target.setpoints.axes,
                line: target.setpoints.line,
                path_speed: target.setpoints.path_speed,
            });
        }
    }

    /// The set-point intake: takes this period's set-point from the lead queue (the one
    /// for this exchange, however far ahead interpolation has computed), keeping the one
    /// before for extrapolation.
    fn take_setpoint(&mut self) {
        if let Ok(t) = self.targets.take(self.exchanges) {
            if let Some(previous) = &self.target {
                self.previous_joints = previous.setpoints.joints;
            }
            self.target = Some(t);
        }
    }

    /// The set-points ran dry: a fault, and from the extrapolated set-point of every joint
    /// (its velocity that of the last two set-points) a quick stop of position control's
    /// own, until the reset after it.
    fn start_dry_stop(&mut self, ctx: &mut Context<'_>, target: &ServoTarget, step: &[f64]) {
        let rest = OnlineAxis::new(otg::State::at_rest(0.0), Limits::symmetric(1.0, 1.0, 1.0));
        let Ok(rest) = rest else {
            return;
        };
        let mut stops = [rest; MAX_JOINTS];
        for (j, stop) in stops.iter_mut().enumerate().take(self.joint_count) {
            // The last bridged set-point (the extrapolation stops growing past the bridged
            // periods), moving on at the velocity of the last two.
            let p = target.setpoints.joints[j];
            let v = step[j] / self.period_s;
            let limits = self
                .stop_limits
                .get(j)
                .copied()
                .unwrap_or_else(|| Limits::symmetric(v.abs().max(1.0), 1e3, 1e5));
            let limits = Limits::symmetric(
                limits.max_velocity.max(v.abs()),
                limits.max_acceleration,
                limits.max_jerk,
            );
            *stop = OnlineAxis::new(otg::State::new(p, v, 0.0), limits)
                .or_else(|_| OnlineAxis::new(otg::State::at_rest(p), limits))
                .unwrap_or(rest);
        }
        self.dry_stop = Some(stops);
        self.shared.raise(
            ctx,
            FaultCode::SetpointsRanDry,
            TaskName::PositionControl,
            None,
            target.setpoints.line,
            (self.exchanges - target.setpoints.cycle) as f64,
        );
    }

    /// Drive I/O: one exchange.
    pub(crate) fn drive_io(&mut self, ctx: &mut Context<'_>) {
        {
            let mi = *self.logic.get();
            let req = self.requests.get();
            // The program's outputs as the set-point of this exchange carries them (M62,
            // M63 and M67 change with the move they precede).
            let outputs = self.target.map(|t| t.outputs).unwrap_or_default();
            let program_outputs = outputs.digital;
            let program_analog_outputs = outputs.analog;
            self.outputs.spindle.enable = mi.out_spindle_enable;
            self.outputs.spindle.speed_rpm = mi.out_spindle_rpm;
            self.outputs.spindle.orient = req.spindle_orient;
            self.outputs.spindle.orient_angle_deg = req.spindle_orient_angle;
            self.outputs.spindle.orient_mode = req.spindle_orient_mode;
            self.outputs.coolant.mist = mi.out_mist;
            self.outputs.coolant.flood = mi.out_flood;
            self.outputs.tool_changer.start = mi.out_tool_start;
            self.outputs.tool_changer.tool = mi.out_tool_number;
            // Each point is the logic's output, or'ed with the program output mapped to it
            // (M62..M65), written afresh every cycle so that an output the logic drops goes
            // off.
            for (i, o) in self.outputs.digital.iter_mut().enumerate().take(64) {
                *o = mi.out_digital & (1 << i) != 0;
            }
            for (n, &point) in self.program_outputs.iter().enumerate().take(64) {
                if let Some(o) = self.outputs.digital.get_mut(point) {
                    *o |= program_outputs & (1 << n) != 0;
                }
            }
            for (&point, &value) in self
                .program_analog_outputs
                .iter()
                .zip(&program_analog_outputs)
            {
                if let Some(o) = self.outputs.analog.get_mut(point) {
                    *o = value;
                }
            }
        }
        self.bus.set_time_ns(ctx.now().as_nanos());
        let result = self
            .bus
            .exchange(self.period_s, &self.outputs, &mut self.inputs);
        self.exchanges += 1;
        self.stale_inputs = !self.bus.inputs_fresh();
        if let Some(error) = self.bus.cycle_phase_error_ns() {
            // Follow the bus's clock (EtherCAT distributed clocks): move the next wake-up
            // by a tenth of how late this exchange came, a first-order loop that settles
            // within a few tens of cycles and filters the exchange's own jitter.
            ctx.shift_next_release(-(error / PHASE_GAIN_DIVISOR));
        }
        if let Err(error) = result
            && !self.comm_fault
        {
            self.comm_fault = true;
            if let Some(mut slot) = self.shared.fieldbus_error.try_lock() {
                *slot = Some(error);
            }
            let (code, value) = fault_of(&error);
            self.shared
                .raise(ctx, code, TaskName::DriveIo, None, 0, value);
        }
        let mut fb = Feedback {
            cycle: self.exchanges,
            exchange_failed: result.is_err(),
            ..Feedback::default()
        };
        for (j, f) in self.inputs.joints.iter().enumerate().take(self.joint_count) {
            let bit = 1u32 << j;
            fb.position[j] = f.position;
            fb.velocity[j] = f.velocity;
            if f.negative_limit {
                fb.negative_limit |= bit;
            }
            if f.positive_limit {
                fb.positive_limit |= bit;
            }
            if f.home_switch {
                fb.home_switch |= bit;
            }
            if f.latch.latched {
                fb.latched |= bit;
                fb.latch_position[j] = f.latch.position;
            }
            let state = f.state();
            if state == Cia402State::OperationEnabled {
                fb.enabled |= bit;
            }
            if state.is_fault() {
                fb.faulted |= bit;
            }
            if (f.negative_limit || f.positive_limit) && self.limit_latched & bit == 0 {
                self.limit_latched |= bit;
                self.shared.raise(
                    ctx,
                    FaultCode::HardLimit,
                    TaskName::DriveIo,
                    Some(j as u8),
                    0,
                    f.position,
                );
            }
            if state.is_fault()
                && self.drive_fault_latched & bit == 0
                && self.was_enabled & bit != 0
            {
                self.drive_fault_latched |= bit;
                self.shared.raise(
                    ctx,
                    FaultCode::DriveFault,
                    TaskName::DriveIo,
                    Some(j as u8),
                    0,
                    f64::from(f.error_code),
                );
            }
        }
        fb.estop = self.inputs.estop_active;
        if fb.estop && !self.estop_latched {
            self.estop_latched = true;
            self.shared
                .raise(ctx, FaultCode::EStop, TaskName::DriveIo, None, 0, 0.0);
        }
        fb.handwheel_counts = self.inputs.handwheel_counts;
        fb.spindle_rpm = self.inputs.spindle.speed_rpm;
        fb.spindle_at_speed = self.inputs.spindle.at_speed;
        fb.spindle_angle_deg = self.inputs.spindle.position_deg;
        fb.spindle_oriented = self.inputs.spindle.oriented;
        fb.tool = self.inputs.tool_changer.current_tool;
        fb.tool_change_done = self.inputs.tool_changer.done;
        // Branch-free: the inputs' levels change rarely but are packed every period.
        fb.digital_inputs = self
            .inputs
            .digital
            .iter()
            .take(64)
            .enumerate()
            .fold(0, |bits, (i, &d)| bits | (u64::from(d) << i));
        for (slot, &a) in fb.analog_inputs.iter_mut().zip(&self.inputs.analog) {
            *slot = a;
        }
        self.feedback_out.publish(fb);
    }

    /// Periods in which position control had to go on without a fresh set-point.
    pub(crate) fn underruns(&self) -> u64 {
        self.underruns
    }
}

/// The control word for a faulty drive while the machine is enabled. A drive fault is reset
/// by the master's explicit decision: a reset command. CiA 402 resets on the rising edge of
/// the fault-reset bit: pulsed, so a drive whose cause was still there at the first edge
/// resets at a later one once it is gone.
#[inline]
fn fault_reset_controlword(exchanges: u64, was_enabled: bool) -> ControlWord {
    let pulse_high = (exchanges / FAULT_RESET_PULSE) % 2 == 1;
    if !was_enabled && pulse_high {
        ControlWord::fault_reset()
    } else {
        ControlWord::disable_voltage()
    }
}

/// After a servo fault: the drive's own quick stop, then off (stop category 1): from quick
/// stop active, "disable voltage" once the drive reports it stands (`standing`).
#[inline]
fn stop_category_1(state: Cia402State, standing: bool) -> ControlWord {
    if state == Cia402State::QuickStopActive && standing {
        ControlWord::disable_voltage()
    } else if state == Cia402State::OperationEnabled || state == Cia402State::QuickStopActive {
        ControlWord::quick_stop()
    } else {
        state.controlword_towards(false)
    }
}

/// The latch armed for the joint of `bit`: the index pulse before the home switch before the
/// touch probe.
#[inline]
fn latch_source(latch: &LatchRequest, bit: u32) -> Option<LatchSource> {
    if latch.index & bit != 0 {
        Some(LatchSource::IndexPulse)
    } else if latch.switch & bit != 0 {
        Some(LatchSource::HomeSwitch)
    } else if latch.probe & bit != 0 {
        Some(LatchSource::TouchProbe {
            rising: latch.probe_rising,
        })
    } else {
        None
    }
}
