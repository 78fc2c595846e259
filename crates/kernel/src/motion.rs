//! The motion core: machine state and modes, the planner (program and MDI motion), the
//! on-line trajectory generators (jog, handwheel, homing, independent joints) and the
//! program sequencer. Three tasks work on it under one priority-inheritance mutex, each
//! doing its own part: command parsing ([`MotionCore::urgent`], [`MotionCore::command`]),
//! look-ahead ([`MotionCore::look_ahead`]) and interpolation ([`MotionCore::interpolate`]).
//! Nothing here allocates after construction.

use rtcnc_motion::otg::{Limits, OnlineAxis, State};
use rtcnc_motion::{AXES, Kinematics, MotionError, MotionState, Move, Planner};
use rtcnc_rt::{Context, RingProducer, SeqlockWriter};

use rtcnc_gcode::canon::ProbeKind;

use crate::config::{MAX_JOINTS, MachineConfig};
use crate::error::KernelError;
use crate::fault::{Fault, FaultCode, TaskName};
use crate::kinematics::MachineKinematics;
use crate::messages::{
    Aux, Command, JointSetpoints, MachineBlock, MachineResult, MachineState, Mode, OperatorMessage,
    Status, Urgent,
};
use crate::shared::{
    Feedback, InterpreterRequest, LogicOutputs, LogicRequests, Shared, Snapshot, Tagged,
};

/// Latch requests carried with a set-point (bit n for joint n).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LatchRequest {
    /// Arm the index latch.
    pub index: u32,
    /// Arm the home-switch latch.
    pub switch: u32,
}

/// What position control receives every servo period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ServoTarget {
    /// The set-points.
    pub setpoints: JointSetpoints,
    /// Homing offsets: raw joint position = machine position − offset.
    pub offsets: [f64; MAX_JOINTS],
    /// Drives enabled.
    pub enable: bool,
    /// Incremented by every reset: position control clears its latched faults.
    pub reset_count: u32,
    /// Latches to arm.
    pub latch: LatchRequest,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Source {
    Path,
    Manual,
}

#[derive(Debug, Clone, Copy, PartialEq)]
// Plain data held in place: boxing the larger variant would allocate on the real-time path.
#[allow(clippy::large_enum_variant)]
enum Then {
    Synced([f64; AXES], f64),
    Probe(Move, ProbeKind),
    Aux(Aux),
    Error(FaultCode),
    End,
    MdiDone,
    SingleBlockPause,
}

#[derive(Debug, Clone, Copy, PartialEq)]
// Plain data held in place: boxing the larger variant would allocate on the real-time path.
#[allow(clippy::large_enum_variant)]
enum Phase {
    /// No program or MDI.
    Idle,
    /// Moving blocks into the planner.
    Feeding,
    /// Waiting for the planner to stop, then doing `then` for `line`.
    Draining { then: Then, line: u32 },
    /// Waiting for the machine logic's acknowledgement of `aux`.
    Logic { aux: Aux, line: u32, released: bool },
    /// Paused at M0/M1/single block until resume.
    Paused { start_count: u32 },
    /// G33: the spindle-synchronised move runs.
    Synced,
    /// G38.x: the probing move runs (it stops where the probe changes).
    Probing { kind: ProbeKind, line: u32 },
    /// M19 Q: waiting for the spindle to report oriented until `deadline`.
    WaitOrient { deadline: u64, line: u32 },
    /// M66: waiting for a digital input until `deadline` (an interpolation cycle).
    WaitInput {
        bit: u64,
        condition: crate::messages::WaitCondition,
        deadline: u64,
        previous: bool,
    },
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum HomingStep {
    Search,
    SearchStop,
    BackOff,
    BackOffStop,
    Latch,
    LatchStop,
    MoveHome,
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Homing {
    sequence: u8,
    /// Joints of the current group with their step.
    step: [Option<HomingStep>; MAX_JOINTS],
}

/// G96: the spindle speed follows X.
#[derive(Debug, Clone, Copy, PartialEq)]
struct ConstantSurfaceSpeed {
    /// Surface speed (mm/min) over 2π.
    factor: f64,
    /// Machine X of the spindle axis.
    x_centre: f64,
    /// D word, at most the spindle's top speed.
    max_rpm: f64,
}

/// G33 / a G76 pass: a line whose progress follows the spindle's angle.
#[derive(Debug, Clone, Copy)]
struct SyncedMove {
    start: [f64; AXES],
    /// Unit direction.
    dir: [f64; AXES],
    length: f64,
    /// mm per revolution.
    pitch: f64,
    /// While tracking: the progress's offset from pitch × revolutions, jerk-limited from
    /// where it was at the index to 0 (planned in the frame that moves with the spindle,
    /// so it catches up time-optimally and then stays on it).
    offset: Option<OnlineAxis>,
    /// Progress along the line (mm): at rest before the index, to the end after tracking.
    otg: OnlineAxis,
    /// Path limits along the line (velocity, acceleration, jerk).
    limits: (f64, f64, f64),
    /// Unwrapped spindle angle (degrees) and the last reading (0..360).
    angle: f64,
    reading: f64,
    /// The unwrapped angle of the index the move started at; `None` while waiting for it.
    index: Option<f64>,
    /// Going to the end at rest (or stopping): no longer tracking.
    finishing: bool,
    line: u32,
}

/// One joint's data for the core, taken from the configuration.
#[derive(Debug, Clone, Copy)]
struct JointInfo {
    axis: Option<usize>,
    homing: Option<crate::config::HomingConfig>,
    limits: Limits,
    quick: Limits,
    min: f64,
    max: f64,
}

/// The motion core. See the module documentation.
pub(crate) struct MotionCore {
    planner: Planner<MachineKinematics>,
    planner_joints: [usize; MAX_JOINTS],
    planner_joint_count: usize,
    planner_buf: [f64; MAX_JOINTS],
    joints: [JointInfo; MAX_JOINTS],
    joint_count: usize,
    axis_present: [bool; AXES],
    axis_limits: [Limits; AXES],
    axis_quick: [Limits; AXES],
    axis_min: [f64; AXES],
    axis_max: [f64; AXES],
    jog_velocity: [f64; AXES],
    axis_otg: [OnlineAxis; AXES],
    joint_otg: [OnlineAxis; MAX_JOINTS],
    /// Bit n: joint n follows its own generator (homing, independent joint).
    joint_manual: u32,
    source: Source,
    period_s: f64,
    period_ns: u64,
    cycle: u64,
    offsets: [f64; MAX_JOINTS],
    last: JointSetpoints,
    last_state: MotionState,
    latch: LatchRequest,
    mode: Mode,
    phase: Phase,
    epoch: u32,
    pending: Option<MachineBlock>,
    start_count: u32,
    single_block: bool,
    optional_stop: bool,
    run_from_line: u32,
    skipped_to: Option<[f64; AXES]>,
    estop: bool,
    fault: bool,
    stopping: bool,
    enable: bool,
    reset_count: u32,
    ready: bool,
    held: bool,
    homed: u32,
    homing: Option<Homing>,
    handwheel: Option<(usize, f64)>,
    handwheel_counts: Option<i64>,
    handwheel_units_per_count: f64,
    feed_override: f64,
    rapid_override: f64,
    /// The programmed spindle speed (rpm, before the override).
    programmed_rpm: f64,
    /// The spindle is commanded on.
    spindle_on: bool,
    /// Interpolation cycle in which the last machine function started.
    aux_cycle: u64,
    /// Interpolation cycle of the last orientation command.
    orient_cycle: u64,
    /// Bit of the probe in the digital inputs (0: none).
    probe_bit: u64,
    /// The probing move in progress: its kind and where the probe changed.
    probe: Option<(ProbeKind, Option<[f64; AXES]>)>,
    /// Each axis' first joint (for positions from the feedback).
    axis_joint: [Option<usize>; AXES],
    /// The spindle-synchronised move in progress.
    synced: Option<SyncedMove>,
    /// A feed hold came during it: the program waits for a resume after it.
    hold_after_sync: bool,
    /// G96 in force.
    css: Option<ConstantSurfaceSpeed>,
    /// The spindle's top speed (rpm).
    spindle_max_rpm: f64,
    spindle_override: f64,
    /// M48-M51: the operator's overrides in force (else 100 %).
    feed_override_enabled: bool,
    spindle_override_enabled: bool,
    /// M53: the feed stop switch is heeded.
    feed_stop_enabled: bool,
    /// The feed stop switch holds the path now.
    feed_stop_active: bool,
    /// Bit of the feed stop switch in the digital inputs (0: none).
    feed_stop_bit: u64,
    program_ended: bool,
    tool: u32,
    last_fault: Option<Fault>,
    offsets_known: bool,
    has_program: bool,
    /// The machine logic asks for a feed hold (its level as interpolation last read it).
    /// Its rising edge holds a moving path as the operator's feed hold does; while it
    /// stands, a resume is refused and a standing path does not start.
    logic_hold: bool,
    /// The logic's hold rose while a program or MDI line stood between moves (not in its
    /// own spindle hand-shake): the next move waits for a resume, as a held path does.
    logic_paused: bool,
    program_inputs: [usize; 16],
    program_input_count: usize,
    program_analog_inputs: [usize; crate::config::MAX_PROGRAM_IO],
    program_analog_input_count: usize,
    program_analog_output_count: usize,
    /// The logic's e-stop chain has been seen closed since the last reset.
    chain_closed: bool,
    /// The feedback image as drive I/O published it.
    feedback: Snapshot<Feedback>,
    /// The machine logic's answers.
    logic: Snapshot<LogicOutputs>,
    /// The requests to the machine logic (this core is their one writer) and whether they
    /// changed since they were last published.
    requests: LogicRequests,
    requests_changed: bool,
    requests_out: SeqlockWriter<LogicRequests>,
}

/// Steps (blocks taken, phases passed) of one look-ahead run at most, so a run is bounded.
const LOOK_AHEAD_STEPS: usize = 64;

fn limits_of(v: f64, a: f64, j: f64) -> Limits {
    Limits::symmetric(v, a, j)
}

impl MotionCore {
    /// The core for a validated configuration, at rest at the joints' initial positions.
    pub(crate) fn new(
        config: &MachineConfig,
        kinematics: MachineKinematics,
        shared: &Shared,
        requests_out: SeqlockWriter<LogicRequests>,
    ) -> Result<MotionCore, KernelError> {
        let period_s = config.servo_period().as_secs_f64();
        let plan = config.axis_plan();
        let mut limits = rtcnc_motion::MachineLimits { axes: [None; AXES] };
        let mut axis_present = [false; AXES];
        let mut axis_limits = [limits_of(1.0, 1.0, 1.0); AXES];
        let mut axis_quick = axis_limits;
        let mut axis_min = [0.0; AXES];
        let mut axis_max = [0.0; AXES];
        let mut jog_velocity = [0.0; AXES];
        for p in &plan {
            let Some(a) = config.axis(p.axis) else {
                continue;
            };
            let i = p.axis as usize;
            let qa = a.quick_stop_acceleration.unwrap_or(a.max_acceleration);
            let qj = a.quick_stop_jerk.unwrap_or(a.max_jerk);
            limits.axes[i] = Some(rtcnc_motion::AxisLimits {
                max_velocity: a.max_velocity,
                max_acceleration: a.max_acceleration,
                max_jerk: a.max_jerk,
                min_position: a.min_position,
                max_position: a.max_position,
                quick_stop_acceleration: qa,
                quick_stop_jerk: qj,
            });
            axis_present[i] = true;
            axis_limits[i] = limits_of(a.max_velocity, a.max_acceleration, a.max_jerk);
            axis_quick[i] = limits_of(a.max_velocity, qa, qj);
            axis_min[i] = a.min_position;
            axis_max[i] = a.max_position;
            jog_velocity[i] = a.jog_velocity.unwrap_or(a.max_velocity / 10.0);
        }
        let joint_count = config.joints.len().min(MAX_JOINTS);
        let mut joints = [JointInfo {
            axis: None,
            homing: None,
            limits: limits_of(1.0, 1.0, 1.0),
            quick: limits_of(1.0, 1.0, 1.0),
            min: 0.0,
            max: 0.0,
        }; MAX_JOINTS];
        let mut planner_joint_count = 0;
        let mut axis_started = [false; AXES];
        let mut planner_joints = [0usize; MAX_JOINTS];
        let mut start = [0.0; AXES];
        let mut initial = [0.0; MAX_JOINTS];
        for (j, jc) in config.joints.iter().enumerate().take(joint_count) {
            initial[j] = jc.sim.initial_position;
            let axis = plan.iter().find(|p| p.joints.contains(&j)).map(|p| p.axis);
            let info = &mut joints[j];
            info.homing = jc.homing;
            match axis {
                Some(a) => {
                    let i = a as usize;
                    info.axis = Some(i);
                    info.limits = axis_limits[i];
                    info.quick = axis_quick[i];
                    info.min = axis_min[i];
                    info.max = axis_max[i];
                    // The axis starts where its first joint stands; the others are made to
                    // agree through their offsets until homing squares them.
                    if !std::mem::replace(&mut axis_started[i], true) {
                        start[i] = jc.sim.initial_position;
                    }
                    planner_joints[planner_joint_count] = j;
                    planner_joint_count += 1;
                }
                None => {
                    let l = jc.limits.unwrap_or(crate::config::JointLimitsConfig {
                        min_position: -1.0,
                        max_position: 1.0,
                        max_velocity: 1.0,
                        max_acceleration: 1.0,
                        max_jerk: 1.0,
                    });
                    info.limits = limits_of(l.max_velocity, l.max_acceleration, l.max_jerk);
                    info.quick = info.limits;
                    info.min = l.min_position;
                    info.max = l.max_position;
                }
            }
        }
        if kinematics.joint_count() != planner_joint_count {
            return Err(KernelError::Kinematics {
                expected: planner_joint_count,
                found: kinematics.joint_count(),
            });
        }
        let planner = Planner::new(&limits, kinematics, period_s, 256, start)?;
        let otg = |p: f64, l: Limits| OnlineAxis::new(State::at_rest(p), l);
        let mut axis_otg = [otg(0.0, limits_of(1.0, 1.0, 1.0))?; AXES];
        for i in 0..AXES {
            axis_otg[i] = otg(start[i], axis_limits[i])?;
        }
        let mut joint_otg = [axis_otg[0]; MAX_JOINTS];
        let mut joint_manual = 0u32;
        for j in 0..joint_count {
            joint_otg[j] = otg(initial[j], joints[j].limits)?;
            if joints[j].axis.is_none() {
                joint_manual |= 1 << j;
            }
        }
        let mut last = JointSetpoints {
            cycle: 0,
            joints: [0.0; MAX_JOINTS],
            axes: start,
            line: 0,
            path_speed: 0.0,
        };
        for j in 0..joint_count {
            last.joints[j] = match joints[j].axis {
                Some(i) => start[i],
                None => initial[j],
            };
        }
        for j in 0..joint_count {
            if let Some(i) = joints[j].axis {
                joint_otg[j] = otg(start[i], joints[j].limits)?;
            }
        }
        Ok(MotionCore {
            planner,
            planner_joints,
            planner_joint_count,
            planner_buf: [0.0; MAX_JOINTS],
            joints,
            joint_count,
            axis_present,
            axis_limits,
            axis_quick,
            axis_min,
            axis_max,
            jog_velocity,
            axis_otg,
            joint_otg,
            joint_manual,
            source: Source::Path,
            period_s,
            period_ns: config.servo_period().as_nanos() as u64,
            cycle: 0,
            offsets: [0.0; MAX_JOINTS],
            last,
            last_state: MotionState::Idle,
            latch: LatchRequest::default(),
            mode: Mode::Manual,
            phase: Phase::Idle,
            epoch: 0,
            pending: None,
            start_count: 0,
            single_block: false,
            optional_stop: false,
            run_from_line: 0,
            skipped_to: None,
            estop: true,
            fault: false,
            stopping: false,
            enable: false,
            reset_count: 0,
            ready: false,
            held: false,
            homed: 0,
            homing: None,
            handwheel: None,
            handwheel_counts: None,
            handwheel_units_per_count: config.handwheel.units_per_count,
            feed_override: 1.0,
            rapid_override: 1.0,
            programmed_rpm: 0.0,
            spindle_on: false,
            aux_cycle: 0,
            orient_cycle: 0,
            probe_bit: config.io.probe_input.map_or(0, |i| 1u64 << i.min(63)),
            probe: None,
            synced: None,
            hold_after_sync: false,
            axis_joint: {
                let mut a = [None; AXES];
                for j in (0..joint_count).rev() {
                    if let Some(i) = joints[j].axis {
                        a[i] = Some(j);
                    }
                }
                a
            },
            css: None,
            // A file without `[spindle]` gets the fieldbus's default spindle, as the
            // simulated machine does.
            spindle_max_rpm: config.spindle.map_or_else(
                || rtcnc_fieldbus::sim::SpindleConfig::default().max_speed_rpm,
                |s| s.max_speed_rpm,
            ),
            spindle_override: 1.0,
            feed_override_enabled: true,
            spindle_override_enabled: true,
            feed_stop_enabled: true,
            feed_stop_active: false,
            feed_stop_bit: config.io.feed_stop_input.map_or(0, |i| 1u64 << i.min(63)),
            program_ended: false,
            tool: config.tool_changer.map_or(0, |t| t.initial_tool),
            last_fault: None,
            offsets_known: false,
            has_program: false,
            logic_hold: false,
            logic_paused: false,
            program_inputs: {
                let mut p = [0usize; 16];
                for (slot, &i) in p.iter_mut().zip(&config.io.program_inputs) {
                    *slot = i;
                }
                p
            },
            program_input_count: config.io.program_inputs.len().min(16),
            program_analog_inputs: {
                let mut p = [0usize; crate::config::MAX_PROGRAM_IO];
                for (slot, &i) in p.iter_mut().zip(&config.io.program_analog_inputs) {
                    *slot = i;
                }
                p
            },
            program_analog_input_count: config
                .io
                .program_analog_inputs
                .len()
                .min(crate::config::MAX_PROGRAM_IO),
            program_analog_output_count: config
                .io
                .program_analog_outputs
                .len()
                .min(crate::config::MAX_PROGRAM_IO),
            chain_closed: false,
            feedback: Snapshot::new(shared.feedback.clone()),
            logic: Snapshot::new(shared.logic_outputs.clone()),
            requests: requests_out.value(),
            requests_changed: false,
            requests_out,
        })
    }

    /// The requests to the machine logic, to change (published at the end of the task body).
    fn requests_mut(&mut self) -> &mut LogicRequests {
        self.requests_changed = true;
        &mut self.requests
    }

    /// Publishes the requests to the machine logic if a task body changed them.
    fn publish_requests(&mut self) {
        if std::mem::take(&mut self.requests_changed) {
            self.requests_out.publish(self.requests);
        }
    }

    /// The self-test passed: the machine may be reset into operation.
    pub fn set_ready(&mut self, ready: bool) {
        self.ready = ready;
    }

    /// A program is loaded (auto mode can start).
    pub fn set_has_program(&mut self, has: bool) {
        self.has_program = has;
    }

    fn moving(&self) -> bool {
        match self.source {
            Source::Path => {
                self.synced.is_some()
                    || self.last_state != MotionState::Idle
                    || self.planner.window_len() > 0
            }
            Source::Manual => self.manual_moving(),
        }
    }

    fn manual_moving(&self) -> bool {
        (0..AXES).any(|i| self.axis_present[i] && !self.axis_otg[i].is_finished())
            || (0..self.joint_count).any(|j| !self.joint_otg[j].is_finished())
    }

    fn operational(&self) -> bool {
        self.ready && !self.estop && !self.fault && self.enable
    }

    /// The machine state as the status shows it.
    pub fn state(&self) -> MachineState {
        if !self.ready {
            return MachineState::Starting;
        }
        if self.estop {
            return MachineState::EStop;
        }
        if self.fault {
            return MachineState::Fault;
        }
        // A hold outranks what the program waits for: whatever the wait ends in, nothing
        // moves on until a resume, and that is what the operator must see.
        if self.held || self.logic_paused || self.feed_stop_active {
            return MachineState::Held;
        }
        match self.phase {
            Phase::Logic { .. } => return MachineState::WaitingForLogic,
            Phase::Paused { .. } => return MachineState::Paused,
            _ => {}
        }
        if self.moving() || self.homing.is_some() || self.phase != Phase::Idle {
            MachineState::Running
        } else {
            MachineState::Idle
        }
    }

    // ----- command parsing -------------------------------------------------------------

    /// An urgent command (e-stop, hold, resume, abort, overrides).
    pub fn urgent(&mut self, ctx: &mut Context<'_>, shared: &Shared, command: Urgent) {
        match command {
            Urgent::EStop => {
                shared.raise(ctx, FaultCode::EStop, TaskName::Interpolation, None, 0, 0.0);
            }
            Urgent::FeedHold => self.hold(),
            // The logic's hold (door open, fault, spindle not at speed) must clear first.
            Urgent::Resume if self.logic.get().feed_hold_request => {}
            Urgent::Resume => {
                if self.held || self.logic_paused {
                    self.held = false;
                    self.logic_paused = false;
                    // The feed stop switch keeps holding until it is released.
                    if !self.feed_stop_active {
                        self.planner.resume();
                    }
                }
                // One resume also continues a program paused at M0/M1 or a single block:
                // the operator's "go on" is the same key on every controller.
                if matches!(self.phase, Phase::Paused { .. }) {
                    self.start_count = self.start_count.wrapping_add(1);
                }
            }
            Urgent::Abort => self.abort(shared),
            Urgent::FeedOverride(f) => {
                self.feed_override = if f.is_finite() {
                    f.clamp(0.0, 2.0)
                } else {
                    0.0
                };
                self.apply_feed_overrides();
            }
            Urgent::RapidOverride(f) => {
                self.rapid_override = if f.is_finite() {
                    f.clamp(0.0, 1.0)
                } else {
                    0.0
                };
                self.apply_feed_overrides();
            }
            Urgent::SpindleOverride(f) => {
                self.spindle_override = if f.is_finite() {
                    f.clamp(0.5, 1.5)
                } else {
                    1.0
                };
                if self.requests.spindle_on {
                    let rpm = self.spindle_command();
                    self.requests_mut().spindle_rpm = rpm;
                }
            }
        }
    }

    /// The operator's feed and rapid overrides, or 100 % while M49/M50 P0 is in force.
    fn apply_feed_overrides(&mut self) {
        let (feed, rapid) = if self.feed_override_enabled {
            (self.feed_override, self.rapid_override)
        } else {
            (1.0, 1.0)
        };
        self.planner.set_feed_override(feed);
        self.planner.set_rapid_override(rapid);
    }

    /// The operator's spindle override, or 1 while M49/M51 P0 is in force.
    fn spindle_factor(&self) -> f64 {
        if self.spindle_override_enabled {
            self.spindle_override
        } else {
            1.0
        }
    }

    /// The spindle speed to command (rpm, unsigned): the programmed speed times the
    /// override; under G96 the surface speed over 2π·|X − centre| at the X set-point, times
    /// the override, capped at D (as LinuxCNC's motion controller does it every period).
    fn spindle_command(&self) -> f64 {
        match self.css {
            Some(c) => {
                let radius = (self.last.axes[0] - c.x_centre).abs();
                let rpm = if radius > 0.0 {
                    c.factor / radius
                } else {
                    c.max_rpm
                };
                (rpm * self.spindle_factor()).min(c.max_rpm)
            }
            None => self.programmed_rpm * self.spindle_factor(),
        }
    }

    /// M48-M53 as after a reset: every override and the feed stop switch in force.
    fn reset_enables(&mut self) {
        self.feed_override_enabled = true;
        self.spindle_override_enabled = true;
        self.feed_stop_enabled = true;
        self.apply_feed_overrides();
        if self.requests.spindle_on {
            let rpm = self.spindle_command();
            self.requests_mut().spindle_rpm = rpm;
        }
    }

    /// The operator's feed hold. It is latched in every state, moving or not, until a
    /// resume (or an abort, e-stop or fault): a moving path decelerates along itself, a
    /// jog or homing stops, and whatever the machine waits for (a machine function, a
    /// dwell, an input, a pause, the start of a program, the next MDI line) ends without
    /// the next block starting.
    fn hold(&mut self) {
        // An e-stop or fault has already stopped everything and ended the program; a hold
        // latched now would outlive the reset that follows.
        if self.estop || self.fault {
            return;
        }
        match self.source {
            // A thread pass cannot stop in the cut: the hold takes effect at its end (as in
            // LinuxCNC, which holds spindle-synchronised motion only after it).
            Source::Path if self.synced.is_some() => self.hold_after_sync = true,
            Source::Path => {
                self.held = true;
                if self.moving() {
                    self.planner.hold();
                }
            }
            Source::Manual => {
                self.held = true;
                // Homing cannot go on from where a hold stops it: it starts again.
                self.homing = None;
                self.handwheel = None;
                for i in 0..AXES {
                    if self.axis_present[i] {
                        let _ = self.axis_otg[i].stop();
                    }
                }
                // Joints of an axis that homing had taken over; independent joints move
                // beside the program and are not held (as PLCopen axes are not).
                for j in 0..self.joint_count {
                    if self.joints[j].axis.is_some() && self.joint_manual & (1 << j) != 0 {
                        let _ = self.joint_otg[j].stop();
                    }
                }
            }
        }
    }

    /// Axis joints that homing took over go back to their axis once they stand outside
    /// the group being homed (their group is done, or homing was stopped), so that the
    /// axis drives them again from there. Runs after the period's set-point `sp` is made,
    /// which it corrects for the axis, so the hand-over has no step.
    fn release_stopped_homing_joints(&mut self, sp: &mut JointSetpoints) {
        for j in 0..self.joint_count {
            let bit = 1u32 << j;
            let Some(i) = self.joints[j].axis else {
                continue;
            };
            let in_group = self.homing.is_some_and(|h| h.step[j].is_some());
            if self.joint_manual & bit == 0 || in_group || !self.joint_otg[j].is_finished() {
                continue;
            }
            let p = self.joint_otg[j].sample().p;
            if let Ok(o) = OnlineAxis::new(State::at_rest(p), self.axis_limits[i]) {
                self.axis_otg[i] = o;
            }
            self.joint_manual &= !bit;
            sp.axes[i] = p;
            sp.joints[j] = p;
        }
    }

    fn abort(&mut self, shared: &Shared) {
        self.probe = None;
        self.stop_synced(false);
        // A stopped program leaves no override disabled behind (M49, M50 P0, M53 P0).
        self.reset_enables();
        self.epoch = self.epoch.wrapping_add(1);
        let _ = shared
            .interpreter_requests
            .try_put(InterpreterRequest::Stop);
        shared.interpreter_wake.signal();
        self.pending = None;
        self.phase = Phase::Idle;
        self.held = false;
        self.logic_paused = false;
        self.homing = None;
        match self.source {
            Source::Path => self.planner.abort(),
            Source::Manual => self.stop_manual(false),
        }
        let mi = self.requests_mut();
        mi.tool_change_request = false;
        mi.m_code_request = false;
        mi.program_running = false;
    }

    fn stop_manual(&mut self, quick: bool) {
        for i in 0..AXES {
            if self.axis_present[i] {
                if quick {
                    let _ = self.axis_otg[i].set_limits(self.axis_quick[i]);
                }
                let _ = self.axis_otg[i].stop();
            }
        }
        for j in 0..self.joint_count {
            if quick {
                let _ = self.joint_otg[j].set_limits(self.joints[j].quick);
            }
            let _ = self.joint_otg[j].stop();
        }
    }

    /// A normal command. Returns false when it was refused in this state.
    pub fn command(&mut self, ctx: &mut Context<'_>, shared: &Shared, command: Command) -> bool {
        let ok = self.command_inner(ctx, shared, command);
        self.publish_requests();
        ok
    }

    fn command_inner(&mut self, ctx: &mut Context<'_>, shared: &Shared, command: Command) -> bool {
        // A latched feed hold refuses whatever would start motion (a program, an MDI
        // line, a jog, homing) until the operator resumes.
        let idle = self.operational()
            && !self.held
            && !self.moving()
            && self.phase == Phase::Idle
            && self.homing.is_none();
        let ok = match command {
            Command::Reset => {
                let feedback = *self.feedback.get();
                if !self.ready || feedback.estop || self.stopping {
                    false
                } else {
                    if !self.enable && self.offsets_known {
                        // The drives were off (the load may have coasted): the set-points
                        // start again from where the machine stands.
                        self.resync_to_feedback(&feedback);
                    }
                    self.estop = false;
                    self.fault = false;
                    self.enable = true;
                    self.apply_feed_overrides();
                    self.chain_closed = false;
                    self.reset_count = self.reset_count.wrapping_add(1);
                    let mi = self.requests_mut();
                    mi.reset_count = mi.reset_count.wrapping_add(1);
                    mi.machine_on_request = true;
                    true
                }
            }
            Command::Start { from_line } => {
                if idle && self.has_program {
                    self.begin(Mode::Auto, from_line);
                    let _ = shared
                        .interpreter_requests
                        .try_put(InterpreterRequest::Run { epoch: self.epoch });
                    shared.interpreter_wake.signal();
                    true
                } else if matches!(self.phase, Phase::Paused { .. }) {
                    self.start_count = self.start_count.wrapping_add(1);
                    true
                } else {
                    false
                }
            }
            Command::Mdi(line) => {
                if idle {
                    self.begin(Mode::Mdi, 0);
                    let _ = shared
                        .interpreter_requests
                        .try_put(InterpreterRequest::Mdi {
                            epoch: self.epoch,
                            line,
                        });
                    shared.interpreter_wake.signal();
                    true
                } else {
                    false
                }
            }
            Command::JogContinuous { axis, velocity } => {
                let i = usize::from(axis);
                if idle
                    && i < AXES
                    && self.axis_present[i]
                    && velocity.is_finite()
                    && velocity != 0.0
                {
                    self.enter_manual();
                    let speed = velocity.abs().min(self.axis_limits[i].max_velocity);
                    let target = if velocity > 0.0 {
                        self.axis_max[i]
                    } else {
                        self.axis_min[i]
                    };
                    let l = Limits::symmetric(
                        speed,
                        self.axis_limits[i].max_acceleration,
                        self.axis_limits[i].max_jerk,
                    );
                    self.axis_otg[i].set_limits(l).is_ok()
                        && self.axis_otg[i].set_target(State::at_rest(target)).is_ok()
                } else {
                    false
                }
            }
            Command::JogIncrement { axis, distance } => {
                let i = usize::from(axis);
                if idle && i < AXES && self.axis_present[i] && distance.is_finite() {
                    self.enter_manual();
                    let from = self.axis_otg[i].sample().p;
                    let target = (from + distance).clamp(self.axis_min[i], self.axis_max[i]);
                    let l = Limits::symmetric(
                        self.jog_velocity[i],
                        self.axis_limits[i].max_acceleration,
                        self.axis_limits[i].max_jerk,
                    );
                    self.axis_otg[i].set_limits(l).is_ok()
                        && self.axis_otg[i].set_target(State::at_rest(target)).is_ok()
                } else {
                    false
                }
            }
            Command::JogStop { axis } => {
                let i = usize::from(axis);
                if self.source == Source::Manual && i < AXES && self.axis_present[i] {
                    self.axis_otg[i].stop().is_ok()
                } else {
                    false
                }
            }
            Command::Handwheel { axis, scale } => match axis {
                None => {
                    self.handwheel = None;
                    true
                }
                Some(a) => {
                    let i = usize::from(a);
                    if idle && i < AXES && self.axis_present[i] && scale.is_finite() && scale > 0.0
                    {
                        self.enter_manual();
                        let _ = self.axis_otg[i].set_limits(self.axis_limits[i]);
                        self.handwheel = Some((i, scale * self.handwheel_units_per_count));
                        self.handwheel_counts = None;
                        true
                    } else {
                        false
                    }
                }
            },
            Command::HomeAll => {
                if idle {
                    self.enter_manual();
                    self.homed = 0;
                    self.homing = self.next_homing_group(None);
                    if self.homing.is_none() {
                        self.homed = (1u32 << self.joint_count) - 1;
                    }
                    true
                } else {
                    false
                }
            }
            Command::JointMove { joint, position } => {
                let j = usize::from(joint);
                // Independent joints move beside whatever the axes do (the seeds' 12-drive
                // test: independent moves during three-axis interpolation).
                if self.operational()
                    && self.homing.is_none()
                    && j < self.joint_count
                    && self.joints[j].axis.is_none()
                    && position.is_finite()
                {
                    let info = self.joints[j];
                    let target = position.clamp(info.min, info.max);
                    let _ = self.joint_otg[j].set_limits(info.limits);
                    self.joint_otg[j].set_target(State::at_rest(target)).is_ok()
                } else {
                    false
                }
            }
            Command::SingleBlock(on) => {
                self.single_block = on;
                true
            }
            Command::OptionalStop(on) => {
                self.optional_stop = on;
                true
            }
            Command::BlockDelete(on) => shared
                .interpreter_requests
                .try_put(InterpreterRequest::BlockDelete(on))
                .is_ok(),
        };
        if !ok {
            shared.raise(
                ctx,
                FaultCode::CommandRefused,
                TaskName::CommandParsing,
                None,
                0,
                0.0,
            );
        }
        ok
    }

    /// Puts every set-point generator at rest on the measured positions. Joints of a
    /// gantry axis that no longer agree lose their homed state (their offsets absorb the
    /// difference; homing squares them again).
    fn resync_to_feedback(&mut self, feedback: &Feedback) {
        let mut axes = self.last.axes;
        let mut axis_set = [false; AXES];
        for j in 0..self.joint_count {
            let machine = feedback.position[j] + self.offsets[j];
            match self.joints[j].axis {
                Some(i) if !axis_set[i] => {
                    axis_set[i] = true;
                    axes[i] = machine;
                    self.last.joints[j] = machine;
                }
                Some(i) => {
                    if (machine - axes[i]).abs() > 1e-3 {
                        self.homed &= !(1 << j);
                    }
                    self.offsets[j] = axes[i] - feedback.position[j];
                    self.last.joints[j] = axes[i];
                }
                None => {
                    self.last.joints[j] = machine;
                    if let Ok(o) = OnlineAxis::new(State::at_rest(machine), self.joints[j].limits) {
                        self.joint_otg[j] = o;
                    }
                }
            }
        }
        self.last.axes = axes;
        for i in 0..AXES {
            if self.axis_present[i] {
                if let Ok(o) = OnlineAxis::new(State::at_rest(axes[i]), self.axis_limits[i]) {
                    self.axis_otg[i] = o;
                }
            }
        }
        for j in 0..self.joint_count {
            if self.joints[j].axis.is_some() && self.joint_manual & (1 << j) != 0 {
                if let Ok(o) =
                    OnlineAxis::new(State::at_rest(self.last.joints[j]), self.joints[j].limits)
                {
                    self.joint_otg[j] = o;
                }
            }
        }
        let _ = self.planner.reset_at(axes);
    }

    fn begin(&mut self, mode: Mode, from_line: u32) {
        self.enter_path();
        if mode == Mode::Auto {
            self.reset_enables();
            self.css = None;
        }
        self.mode = mode;
        self.epoch = self.epoch.wrapping_add(1);
        self.phase = Phase::Feeding;
        self.logic_paused = false;
        self.pending = None;
        self.program_ended = false;
        self.run_from_line = from_line;
        self.skipped_to = None;
        self.requests_mut().program_running = mode == Mode::Auto;
    }

    /// Hands motion to the on-line generators, from where the path stands.
    fn enter_manual(&mut self) {
        self.mode = Mode::Manual;
        if self.source == Source::Manual {
            return;
        }
        let axes = self.last.axes;
        for i in 0..AXES {
            if self.axis_present[i] {
                if let Ok(o) = OnlineAxis::new(State::at_rest(axes[i]), self.axis_limits[i]) {
                    self.axis_otg[i] = o;
                }
            }
        }
        self.source = Source::Manual;
    }

    /// Hands motion to the planner, from where the generators stand.
    fn enter_path(&mut self) {
        if self.source == Source::Path {
            return;
        }
        let _ = self.planner.reset_at(self.last.axes);
        self.handwheel = None;
        self.source = Source::Path;
    }

    // ----- look-ahead --------------------------------------------------------------------

    /// One run of the look-ahead: moves blocks into the planner's window while it has room,
    /// stops the path before machine functions and errors, and sequences their hand-shakes.
    /// Returns whether another run in the same period may find more to do: only when this
    /// one stopped at its bound of steps. Otherwise it stopped on something only another
    /// task can change (no block, no room, the machine still moving, the logic's answer).
    pub fn look_ahead(&mut self, ctx: &mut Context<'_>, shared: &Shared) -> bool {
        let more = self.look_ahead_runs(ctx, shared);
        self.publish_requests();
        more
    }

    fn look_ahead_runs(&mut self, ctx: &mut Context<'_>, shared: &Shared) -> bool {
        if !self.operational() || self.stopping {
            return false;
        }
        for _ in 0..LOOK_AHEAD_STEPS {
            match self.phase {
                Phase::Idle => return false,
                Phase::Feeding => {
                    if self.held
                        || self.logic_paused
                        || ((self.logic_hold || self.feed_stop_active) && !self.moving())
                    {
                        return false;
                    }
                    let block = match self.pending.take() {
                        Some(b) => b,
                        None => match shared.machine_blocks.try_get() {
                            Some(Tagged { epoch, block }) if epoch == self.epoch => block,
                            Some(_) => continue,
                            None => return false,
                        },
                    };
                    if !self.feed(ctx, shared, block) {
                        return false;
                    }
                }
                Phase::Draining { then, line } => {
                    if self.moving() {
                        return false;
                    }
                    // Held: the next block (a machine function, a probing or threading
                    // move, the program's end) waits for the resume; an error stops the
                    // program at once.
                    if (self.held || self.logic_paused) && !matches!(then, Then::Error(_)) {
                        return false;
                    }
                    self.after_drain(ctx, shared, then, line);
                }
                Phase::Logic {
                    aux,
                    line,
                    released,
                } => {
                    if !self.logic_done(aux, line, released) {
                        return false;
                    }
                }
                Phase::Paused { start_count } => {
                    if self.start_count == start_count || self.held || self.logic_paused {
                        return false;
                    }
                    self.phase = Phase::Feeding;
                }
                Phase::Synced => {
                    if self.synced.is_some() {
                        return false;
                    }
                    self.phase = Phase::Feeding;
                }
                Phase::Probing { kind, line } => {
                    if self.moving() {
                        return false;
                    }
                    let tripped_at = self.probe.take().and_then(|p| p.1);
                    let must_change = matches!(kind, ProbeKind::TowardError | ProbeKind::AwayError);
                    if tripped_at.is_none() && must_change {
                        self.phase = Phase::Draining {
                            then: Then::Error(FaultCode::ProbeFailed),
                            line,
                        };
                        continue;
                    }
                    self.send_result(
                        shared,
                        MachineResult::Probe {
                            tripped: tripped_at.is_some(),
                            at: tripped_at.unwrap_or(self.last.axes),
                            stopped: self.last.axes,
                        },
                    );
                    self.phase = Phase::Feeding;
                }
                Phase::WaitOrient { deadline, line } => {
                    // The feedback answers the orientation only after the drive had it.
                    let oriented =
                        self.feedback.get().spindle_oriented && self.cycle >= self.orient_cycle + 2;
                    if oriented {
                        self.phase = Phase::Feeding;
                    } else if self.cycle >= deadline {
                        self.phase = Phase::Draining {
                            then: Then::Error(FaultCode::SpindleOrientTimeout),
                            line,
                        };
                    } else {
                        return false;
                    }
                }
                Phase::WaitInput {
                    bit,
                    condition,
                    deadline,
                    previous,
                } => {
                    use crate::messages::WaitCondition as W;
                    let now = self.feedback.get().digital_inputs & bit != 0;
                    let met = match condition {
                        W::Immediate => true,
                        W::Rise => now && !previous,
                        W::Fall => !now && previous,
                        W::High => now,
                        W::Low => !now,
                    };
                    if met || self.cycle >= deadline {
                        // #5399: the input's level, or -1 on a time-out (LinuxCNC).
                        let value = match (met, now) {
                            (false, _) => -1.0,
                            (true, true) => 1.0,
                            (true, false) => 0.0,
                        };
                        self.send_result(shared, MachineResult::Input(value));
                        self.phase = Phase::Feeding;
                    } else {
                        self.phase = Phase::WaitInput {
                            bit,
                            condition,
                            deadline,
                            previous: now,
                        };
                        return false;
                    }
                }
            }
        }
        true
    }

    /// Returns false when the block could not be taken now (kept for the next run).
    fn feed(&mut self, ctx: &mut Context<'_>, shared: &Shared, block: MachineBlock) -> bool {
        match block {
            MachineBlock::Motion(mv) => {
                if self.run_from_line > 1 && mv.line < self.run_from_line {
                    if let rtcnc_motion::MoveKind::Line { end, .. }
                    | rtcnc_motion::MoveKind::Arc { end, .. }
                    | rtcnc_motion::MoveKind::Spline { end, .. } = mv.kind
                    {
                        self.skipped_to = Some(end);
                    }
                    return true;
                }
                if let Some(end) = self.skipped_to.take() {
                    // Run from a line: go to where the first executed block starts, at rapid.
                    let approach = Move::rapid(end, rtcnc_motion::PathMode::ExactStop, mv.line);
                    if let Err(e) = self.planner.push(&approach) {
                        self.skipped_to = Some(end);
                        if matches!(e, MotionError::QueueFull) {
                            self.pending = Some(block);
                            return false;
                        }
                    }
                }
                match self.planner.push(&mv) {
                    Ok(()) => {
                        if self.single_block {
                            self.planner.flush();
                            self.phase = Phase::Draining {
                                then: Then::SingleBlockPause,
                                line: mv.line,
                            };
                        }
                        true
                    }
                    Err(MotionError::QueueFull) => {
                        self.pending = Some(block);
                        false
                    }
                    // A move to where the machine already is: nothing to do (LinuxCNC drops
                    // such moves too).
                    Err(MotionError::ZeroLength { .. }) => true,
                    Err(e) => {
                        let _ = ctx;
                        self.planner.flush();
                        self.phase = Phase::Draining {
                            then: Then::Error(FaultCode::MotionError),
                            line: e.line().unwrap_or(mv.line),
                        };
                        *shared.motion_error.lock() = Some(e);
                        true
                    }
                }
            }
            MachineBlock::Aux { line, aux } => {
                self.planner.flush();
                self.phase = Phase::Draining {
                    then: Then::Aux(aux),
                    line,
                };
                let _ = shared;
                true
            }
            MachineBlock::Synced { line, end, pitch } => {
                self.planner.flush();
                self.phase = Phase::Draining {
                    then: Then::Synced(end, pitch),
                    line,
                };
                true
            }
            MachineBlock::Probe { mv, kind } => {
                self.planner.flush();
                self.phase = Phase::Draining {
                    then: Then::Probe(mv, kind),
                    line: mv.line,
                };
                true
            }
            MachineBlock::End { line } => {
                self.planner.flush();
                self.phase = Phase::Draining {
                    then: Then::End,
                    line,
                };
                true
            }
            MachineBlock::Error { line, code } => {
                self.planner.flush();
                self.phase = Phase::Draining {
                    then: Then::Error(code),
                    line,
                };
                true
            }
            MachineBlock::MdiDone => {
                self.planner.flush();
                self.phase = Phase::Draining {
                    then: Then::MdiDone,
                    line: 0,
                };
                true
            }
        }
    }

    fn after_drain(&mut self, ctx: &mut Context<'_>, shared: &Shared, then: Then, line: u32) {
        match then {
            Then::SingleBlockPause => {
                self.phase = Phase::Paused {
                    start_count: self.start_count,
                }
            }
            Then::End => {
                self.reset_enables();
                self.phase = Phase::Idle;
                self.program_ended = true;
                self.requests_mut().program_running = false;
            }
            Then::MdiDone => self.phase = Phase::Idle,
            Then::Error(code) => {
                shared.raise(ctx, code, TaskName::LookAhead, None, line, 0.0);
                self.phase = Phase::Idle;
                self.epoch = self.epoch.wrapping_add(1);
                let _ = shared
                    .interpreter_requests
                    .try_put(InterpreterRequest::Stop);
                self.requests_mut().program_running = false;
            }
            Then::Aux(aux) => self.start_aux(shared, aux, line),
            Then::Probe(mv, kind) => self.start_probe(shared, mv, kind),
            Then::Synced(end, pitch) => self.start_synced(end, pitch, line),
        }
    }

    fn start_aux(&mut self, shared: &Shared, aux: Aux, line: u32) {
        self.aux_cycle = self.cycle;
        // A copy of the requests, published where the old lock was given back.
        let mut mi = self.requests;
        match aux {
            Aux::SpindleOn { rpm } => {
                mi.spindle_orient = false;
                mi.spindle_on = rpm != 0.0;
                self.spindle_on = mi.spindle_on;
                mi.spindle_reverse = rpm < 0.0;
                self.programmed_rpm = rpm.abs();
                mi.spindle_rpm = self.spindle_command();
            }
            Aux::SpindleOff => {
                mi.spindle_orient = false;
                mi.spindle_on = false;
                self.spindle_on = false;
            }
            // Orientation goes to the spindle drive at once; M19 Q waits for it.
            Aux::SpindleOrient { angle, mode } => {
                mi.spindle_on = false;
                self.spindle_on = false;
                mi.spindle_orient = true;
                mi.spindle_orient_angle = angle;
                mi.spindle_orient_mode = mode;
                *self.requests_mut() = mi;
                self.orient_cycle = self.cycle;
                self.phase = Phase::Feeding;
                return;
            }
            Aux::WaitOrient { timeout } => {
                *self.requests_mut() = mi;
                self.phase = Phase::WaitOrient {
                    deadline: self.deadline_after(timeout),
                    line,
                };
                return;
            }
            Aux::ConstantSurfaceSpeed {
                factor,
                x_centre,
                max_rpm,
            } => {
                self.css = Some(ConstantSurfaceSpeed {
                    factor,
                    x_centre,
                    max_rpm: max_rpm.min(self.spindle_max_rpm),
                });
                mi.spindle_rpm = self.spindle_command();
            }
            // Tool compensation turns it into the above.
            Aux::SurfaceSpeed { .. } => {}
            // The S number in force becomes the rpm; not waited for (an S word usually
            // follows at once, and that is waited for).
            Aux::SurfaceSpeedOff => {
                self.css = None;
                mi.spindle_rpm = self.spindle_command();
                *self.requests_mut() = mi;
                self.phase = Phase::Feeding;
                return;
            }
            Aux::SpindleSpeed { rpm } => {
                self.programmed_rpm = rpm.abs();
                mi.spindle_rpm = self.spindle_command();
            }
            Aux::Mist(on) => mi.mist = on,
            Aux::Flood(on) => mi.flood = on,
            Aux::ToolChange { tool } => {
                mi.tool_number = tool;
                mi.tool_change_request = true;
            }
            Aux::UserM { code, p, q } => {
                mi.m_code = code;
                mi.m_p = p;
                mi.m_q = q;
                mi.m_code_request = true;
            }
            Aux::DigitalOutput { index, on } => {
                if index < 64 {
                    if on {
                        mi.program_outputs |= 1 << index;
                    } else {
                        mi.program_outputs &= !(1 << index);
                    }
                }
            }
            Aux::WaitInput {
                index,
                condition,
                timeout,
            } => {
                let point = usize::try_from(index)
                    .ok()
                    .filter(|&i| i < self.program_input_count)
                    .map(|i| self.program_inputs[i]);
                let Some(point) = point.filter(|&p| p < 64) else {
                    // An input the machine does not map: the program cannot wait on it.
                    self.phase = Phase::Draining {
                        then: Then::Error(FaultCode::AuxRefused),
                        line,
                    };
                    return;
                };
                let deadline = self.deadline_after(timeout);
                let bit = 1u64 << point;
                let previous = self.feedback.get().digital_inputs & bit != 0;
                self.phase = Phase::WaitInput {
                    bit,
                    condition,
                    deadline,
                    previous,
                };
                return;
            }
            Aux::ReadAnalogInput { index } => {
                *self.requests_mut() = mi;
                let point = usize::try_from(index)
                    .ok()
                    .filter(|&i| i < self.program_analog_input_count)
                    .map(|i| self.program_analog_inputs[i]);
                let value = point.and_then(|p| self.feedback.get().analog_inputs.get(p).copied());
                match value {
                    Some(v) => {
                        self.send_result(shared, MachineResult::Input(v));
                        self.phase = Phase::Feeding;
                    }
                    None => {
                        self.phase = Phase::Draining {
                            then: Then::Error(FaultCode::AuxRefused),
                            line,
                        }
                    }
                }
                return;
            }
            Aux::AnalogOutput { index, value } => {
                let slot = usize::try_from(index)
                    .ok()
                    .filter(|&i| i < self.program_analog_output_count)
                    .and_then(|i| mi.program_analog_outputs.get_mut(i));
                let mapped = slot.is_some();
                if let Some(slot) = slot {
                    *slot = value;
                }
                *self.requests_mut() = mi;
                self.phase = if mapped {
                    Phase::Feeding
                } else {
                    Phase::Draining {
                        then: Then::Error(FaultCode::AuxRefused),
                        line,
                    }
                };
                return;
            }
            Aux::FeedOverrideEnable(on) => {
                *self.requests_mut() = mi;
                self.feed_override_enabled = on;
                self.apply_feed_overrides();
                self.phase = Phase::Feeding;
                return;
            }
            Aux::SpindleOverrideEnable(on) => {
                self.spindle_override_enabled = on;
                if mi.spindle_on {
                    mi.spindle_rpm = self.spindle_command();
                }
                *self.requests_mut() = mi;
                self.phase = Phase::Feeding;
                return;
            }
            Aux::FeedStopEnable(on) => {
                *self.requests_mut() = mi;
                self.feed_stop_enabled = on;
                self.phase = Phase::Feeding;
                return;
            }
            Aux::ProgramStop => {
                self.phase = Phase::Paused {
                    start_count: self.start_count,
                };
                return;
            }
            Aux::Message { seq } => {
                *self.requests_mut() = mi;
                self.show_message(shared, seq, line);
                self.phase = Phase::Feeding;
                return;
            }
            Aux::OptionalStop => {
                self.phase = if self.optional_stop {
                    Phase::Paused {
                        start_count: self.start_count,
                    }
                } else {
                    Phase::Feeding
                };
                return;
            }
        }
        *self.requests_mut() = mi;
        self.phase = Phase::Logic {
            aux,
            line,
            released: false,
        };
    }

    /// The interpolation cycle at which a wait of `seconds` ends: now for 0 (or a
    /// negative or NaN time, which the interpreter refuses before), never for an infinite
    /// one, and saturating for one longer than the machine will run.
    fn deadline_after(&self, seconds: f64) -> u64 {
        if seconds.is_nan() || seconds <= 0.0 {
            return self.cycle;
        }
        // `as` saturates: infinity and 1e30 s become u64::MAX periods.
        let periods = (seconds / self.period_s).ceil() as u64;
        self.cycle.saturating_add(periods)
    }

    /// Starts a probing move: refused without a probe input, or when the probe already is
    /// where the move looks for (LinuxCNC's "probe is already tripped" / "not tripped").
    fn start_probe(&mut self, shared: &Shared, mv: Move, kind: ProbeKind) {
        let contact = self.feedback.get().digital_inputs & self.probe_bit != 0;
        let toward = matches!(kind, ProbeKind::TowardError | ProbeKind::Toward);
        let fail = |line| Phase::Draining {
            then: Then::Error(FaultCode::ProbeFailed),
            line,
        };
        if self.probe_bit == 0 || contact == toward {
            self.phase = fail(mv.line);
            return;
        }
        match self.planner.push(&mv) {
            Ok(()) => {
                self.planner.flush();
                self.probe = Some((kind, None));
                self.phase = Phase::Probing {
                    kind,
                    line: mv.line,
                };
            }
            // Already there: the probe did not change.
            Err(MotionError::ZeroLength { .. }) => {
                self.probe = Some((kind, None));
                self.phase = Phase::Probing {
                    kind,
                    line: mv.line,
                };
            }
            Err(e) => {
                self.phase = Phase::Draining {
                    then: Then::Error(FaultCode::MotionError),
                    line: e.line().unwrap_or(mv.line),
                };
                *shared.motion_error.lock() = Some(e);
            }
        }
    }

    /// Starts a spindle-synchronised line (G33) from where the machine stands: it waits for
    /// the spindle's index, then its progress follows pitch × revolutions. Refused when the
    /// spindle stands, when the line leaves the soft limits, or when the spindle turns too
    /// fast for the pitch and the axes (the axes could not keep up).
    fn start_synced(&mut self, end: [f64; AXES], pitch: f64, line: u32) {
        let feedback = *self.feedback.get();
        let fail = |code| Phase::Draining {
            then: Then::Error(code),
            line,
        };
        let start = self.last.axes;
        let mut dir = [0.0; AXES];
        let mut length2 = 0.0;
        for i in 0..AXES {
            dir[i] = end[i] - start[i];
            length2 += dir[i] * dir[i];
        }
        let length = length2.sqrt();
        if !length.is_finite() {
            self.phase = fail(FaultCode::MotionError);
            return;
        }
        if length == 0.0 {
            self.phase = Phase::Feeding;
            return;
        }
        let (mut v, mut a, mut j) = (f64::INFINITY, f64::INFINITY, f64::INFINITY);
        for i in 0..AXES {
            dir[i] /= length;
            let share = dir[i].abs();
            if share < 1e-12 {
                continue;
            }
            if !self.axis_present[i] || end[i] < self.axis_min[i] || end[i] > self.axis_max[i] {
                self.phase = fail(FaultCode::MotionError);
                return;
            }
            let l = self.axis_limits[i];
            v = v.min(l.max_velocity / share);
            a = a.min(l.max_acceleration / share);
            j = j.min(l.max_jerk / share);
        }
        let speed = pitch * feedback.spindle_rpm.abs() / 60.0;
        let otg = OnlineAxis::new(State::at_rest(0.0), Limits::symmetric(v, a, j));
        match otg {
            Ok(otg) if self.spindle_on && speed > 0.0 && speed <= 0.9 * v && pitch > 0.0 => {
                self.synced = Some(SyncedMove {
                    start,
                    dir,
                    length,
                    pitch,
                    offset: None,
                    otg,
                    limits: (v, a, j),
                    angle: feedback.spindle_angle_deg,
                    reading: feedback.spindle_angle_deg,
                    index: None,
                    finishing: false,
                    line,
                });
                self.phase = Phase::Synced;
            }
            _ => self.phase = fail(FaultCode::SyncFailed),
        }
    }

    /// One period of the synchronised move: follows the spindle's angle (from the last
    /// exchange) and gives the axis position; finished moves hand the path back to the
    /// planner where they ended.
    fn synced_step(&mut self, feedback: &Feedback, sp: &mut JointSetpoints) {
        let Some(mut m) = self.synced else {
            return;
        };
        let dt = self.period_s;
        let mut delta = feedback.spindle_angle_deg - m.reading;
        if delta > 180.0 {
            delta -= 360.0;
        } else if delta <= -180.0 {
            delta += 360.0;
        }
        m.reading = feedback.spindle_angle_deg;
        m.angle += delta;
        if m.index.is_none() {
            // The index is at angle 0: the first crossing of a whole turn.
            let (now, before) = (
                (m.angle / 360.0).floor(),
                ((m.angle - delta) / 360.0).floor(),
            );
            if now != before {
                m.index = Some(360.0 * now.max(before));
            }
        }
        let mut progress = None;
        if let (Some(index), false) = (m.index, m.finishing) {
            let (vmax, a, j) = m.limits;
            let speed = m.pitch * (delta / 360.0 / dt).abs();
            let here = m.pitch * ((m.angle - index) / 360.0).abs();
            if m.offset.is_none() {
                // At the index: the offset from the spindle's progress now, to be closed.
                let relative = Limits {
                    max_velocity: vmax - speed,
                    min_velocity: -vmax - speed,
                    max_acceleration: a,
                    min_acceleration: -a,
                    max_jerk: j,
                };
                let at = m.otg.sample();
                let start = State::new(at.p - here, at.v - speed, at.a);
                m.offset = OnlineAxis::new(start, relative)
                    .and_then(|mut o| o.set_target(State::at_rest(0.0)).map(|()| o))
                    .ok();
                if m.offset.is_none() {
                    m.finishing = true;
                    let _ = m.otg.stop();
                }
            }
            if let Some(offset) = m.offset.as_mut() {
                // The set-point is applied in the next period: where the spindle will be.
                let e = offset.step(dt);
                let p = here + speed * dt + e.p;
                let v = speed + e.v;
                let stopping = 0.5 * v * (v / a + a / j) + v * dt;
                if p + stopping >= m.length {
                    // The end: at most this speed, then to rest on the end point.
                    // (From the last set-point, which `otg` holds.)
                    m.finishing = true;
                    let limits = Limits::symmetric(v.abs().max(speed).max(1e-6), a, j);
                    let _ = m.otg.set_limits(limits);
                    let _ = m.otg.set_target(State::at_rest(m.length));
                } else {
                    progress = Some((p, v));
                    // Where a stop would start from (abort, fault).
                    if let Ok(o) = OnlineAxis::new(
                        State::new(p, v, e.a),
                        Limits::symmetric(vmax.max(v.abs()), a, j),
                    ) {
                        m.otg = o;
                    }
                }
            }
        }
        let s = match progress {
            Some((p, v)) => rtcnc_motion::otg::Sample {
                p,
                v,
                a: 0.0,
                j: 0.0,
            },
            None if m.finishing || m.offset.is_none() => m.otg.step(dt),
            None => m.otg.sample(),
        };
        for i in 0..AXES {
            sp.axes[i] = m.start[i] + m.dir[i] * s.p;
        }
        for jn in 0..self.joint_count {
            if let Some(i) = self.joints[jn].axis {
                sp.joints[jn] = sp.axes[i];
            }
        }
        sp.line = m.line;
        sp.path_speed = s.v.abs();
        if m.finishing && m.otg.is_finished() {
            self.synced = None;
            let _ = self.planner.reset_at(sp.axes);
            if std::mem::take(&mut self.hold_after_sync) {
                // Standing between moves now: the next one waits for a resume.
                self.held = true;
            }
        } else {
            self.synced = Some(m);
        }
    }

    /// Stops a synchronised move along its line (abort, fault): it no longer tracks.
    fn stop_synced(&mut self, quick: bool) {
        if let Some(m) = self.synced.as_mut() {
            m.finishing = true;
            if quick {
                let (v, _, _) = m.limits;
                let (mut a, mut j) = (f64::INFINITY, f64::INFINITY);
                for i in 0..AXES {
                    let share = m.dir[i].abs();
                    if share > 1e-12 {
                        a = a.min(self.axis_quick[i].max_acceleration / share);
                        j = j.min(self.axis_quick[i].max_jerk / share);
                    }
                }
                let _ = m.otg.set_limits(Limits::symmetric(v, a, j));
            }
            let _ = m.otg.stop();
        }
    }

    /// During a probing move, every period: where the probe changes, remember the axis
    /// position (from the feedback, as LinuxCNC) and stop the move.
    fn probe_step(&mut self, feedback: &Feedback) {
        let Some((kind, None)) = self.probe else {
            return;
        };
        let contact = feedback.digital_inputs & self.probe_bit != 0;
        let toward = matches!(kind, ProbeKind::TowardError | ProbeKind::Toward);
        if contact != toward {
            return;
        }
        let mut at = self.last.axes;
        for i in 0..AXES {
            if let Some(j) = self.axis_joint[i] {
                at[i] = feedback.position[j] + self.offsets[j];
            }
        }
        self.probe = Some((kind, Some(at)));
        self.planner.abort();
    }

    /// Hands the interpreter the result it waits for (it reads on once it has it).
    fn send_result(&self, shared: &Shared, result: MachineResult) {
        let _ = shared.machine_results.try_put(Tagged {
            epoch: self.epoch,
            block: result,
        });
        shared.interpreter_wake.signal();
    }

    /// Hands the text of message `seq` to the operator, stamped with the set-point at which
    /// the path stands at its block. Texts of an aborted run still in the channel are
    /// older: they are dropped on the way.
    fn show_message(&self, shared: &Shared, seq: u32, line: u32) {
        for _ in 0..shared.message_texts.capacity() {
            let Some((s, text)) = shared.message_texts.try_get() else {
                return;
            };
            if s == seq {
                let _ = shared.operator_messages.try_put(OperatorMessage {
                    cycle: self.cycle,
                    time_ns: self.cycle.saturating_mul(self.period_ns),
                    line,
                    text,
                });
                return;
            }
        }
    }

    /// Whether the machine logic acknowledged `aux`; drops hand-shake requests once done.
    fn logic_done(&mut self, aux: Aux, line: u32, released: bool) -> bool {
        let answers = *self.logic.get();
        let done = match aux {
            Aux::SpindleOn { .. }
            | Aux::SpindleSpeed { .. }
            | Aux::ConstantSurfaceSpeed { .. }
            | Aux::SurfaceSpeed { .. }
            | Aux::SurfaceSpeedOff => {
                // The logic's at-speed answers the new command only after the drives have
                // had it (one exchange) and the logic has scanned again.
                !self.requests.spindle_on
                    || (answers.spindle_at_speed && self.cycle >= self.aux_cycle + 2)
            }
            Aux::SpindleOff => true,
            Aux::Mist(on) => answers.out_mist == on,
            Aux::Flood(on) => answers.out_flood == on,
            Aux::ToolChange { tool } => {
                if !released {
                    if answers.tool_change_done {
                        self.requests_mut().tool_change_request = false;
                        self.tool = tool;
                        self.phase = Phase::Logic {
                            aux,
                            line,
                            released: true,
                        };
                    }
                    false
                } else {
                    !answers.tool_change_done
                }
            }
            Aux::UserM { .. } => {
                if !released {
                    if answers.m_code_done {
                        self.requests_mut().m_code_request = false;
                        self.phase = Phase::Logic {
                            aux,
                            line,
                            released: true,
                        };
                    }
                    false
                } else {
                    !answers.m_code_done
                }
            }
            Aux::DigitalOutput { .. }
            | Aux::ProgramStop
            | Aux::OptionalStop
            | Aux::Message { .. }
            | Aux::SpindleOrient { .. }
            | Aux::WaitOrient { .. }
            | Aux::FeedOverrideEnable(_)
            | Aux::SpindleOverrideEnable(_)
            | Aux::FeedStopEnable(_)
            | Aux::ReadAnalogInput { .. }
            | Aux::AnalogOutput { .. }
            | Aux::WaitInput { .. } => true,
        };
        if done {
            self.phase = Phase::Feeding;
        }
        done
    }

    // ----- interpolation -----------------------------------------------------------------

    /// One servo period: reacts to stop requests first, then computes the set-point of
    /// every joint and sends it to position control.
    pub fn interpolate(
        &mut self,
        ctx: &mut Context<'_>,
        shared: &Shared,
        out: &mut RingProducer<ServoTarget>,
    ) {
        // The urgent channel first, all of it, every servo cycle: an e-stop read here stops
        // the set-points computed in this very cycle.
        while let Some(u) = shared.urgent.try_get() {
            self.urgent(ctx, shared, u);
        }
        while let Some(fault) = shared.stop_requests.try_get() {
            self.on_fault(shared, fault);
        }
        let feedback = *self.feedback.get();
        if !self.offsets_known && feedback.cycle > 0 {
            // Before homing, a joint's machine position is where the kernel believed it
            // was at power-up: the offsets make feedback and set-points agree.
            self.offsets_known = true;
            for j in 0..self.joint_count {
                self.offsets[j] = self.last.joints[j] - feedback.position[j];
            }
        }
        let chain_ok = {
            let mi = *self.logic.get();
            if mi.feed_hold_request && !self.logic_hold {
                let spindle_handshake = matches!(
                    self.phase,
                    Phase::Logic {
                        aux: Aux::SpindleOn { .. }
                            | Aux::SpindleSpeed { .. }
                            | Aux::ConstantSurfaceSpeed { .. }
                            | Aux::SurfaceSpeedOff,
                        ..
                    }
                );
                if self.moving() {
                    self.hold();
                } else if self.phase != Phase::Idle && !spindle_handshake {
                    self.logic_paused = true;
                }
            }
            self.logic_hold = mi.feed_hold_request;
            mi.estop_chain_ok
        };
        // The feed stop switch (M53): holds a moving path while it is on, and lets it go on
        // by itself when released (LinuxCNC's feed hold input); no new move starts meanwhile.
        let stop_now = self.feed_stop_enabled && feedback.digital_inputs & self.feed_stop_bit != 0;
        if stop_now != self.feed_stop_active {
            self.feed_stop_active = stop_now;
            if self.source == Source::Path {
                if stop_now {
                    if self.moving() {
                        self.planner.hold();
                    }
                } else if !self.held && !self.logic_paused {
                    self.planner.resume();
                }
            }
        }
        // The machine logic's e-stop chain: once closed after a reset, its opening is an
        // e-stop (the chain closes a scan or two after the reset).
        if self.enable && !self.estop {
            if chain_ok {
                self.chain_closed = true;
            } else if self.chain_closed {
                self.chain_closed = false;
                shared.raise(ctx, FaultCode::EStop, TaskName::MachineLogic, None, 0, 0.0);
            }
        }
        self.probe_step(&feedback);
        // One set-point per exchange with the drives, numbered by the exchange it is for:
        // the one made in period p is applied by position control in period p + 1, after
        // the exchanges of periods up to p, i.e. p + 1 less the periods the fieldbus thread
        // skipped. The number does not depend on whether drive I/O has already done this
        // period's exchange, which on several processors it may or may not have (reading
        // the feedback's exchange count instead made the set-points one period late about
        // every other period at 10 kHz). After a late activation (a real-time overrun) the
        // missed set-points are computed now, at most four; none when interpolation is
        // ahead. It never runs more than one exchange ahead of the feedback: while the
        // fieldbus thread stalls (it woke late on another processor) the machine does not
        // move on, so neither do its set-points.
        let skipped = shared
            .fieldbus_skipped
            .load(std::sync::atomic::Ordering::Relaxed);
        let target = (ctx.activation() + 1)
            .saturating_sub(skipped)
            .min(feedback.cycle + 1);
        let steps = target.saturating_sub(self.cycle).min(4);
        let line = self.last.line;
        for _ in 0..steps {
            self.step(&feedback);
        }
        if self.last.line != line {
            // The program line in the trace, so a timeline shows which block ran when.
            ctx.mark("line", u64::from(self.last.line));
        }
        // G96: the spindle speed follows the X set-point.
        if self.css.is_some() && self.spindle_on {
            let rpm = self.spindle_command();
            if self.requests.spindle_rpm != rpm {
                self.requests_mut().spindle_rpm = rpm;
            }
        }
        if self.stopping && !self.moving() {
            self.stopping = false;
            if self.estop || self.fault {
                self.enable = false;
            }
        }
        self.publish_requests();
        if steps == 0 {
            return;
        }
        let _ = out.push(ServoTarget {
            setpoints: self.last,
            offsets: self.offsets,
            enable: self.enable,
            reset_count: self.reset_count,
            latch: self.latch,
        });
    }

    /// One servo period of the set-point generators.
    fn step(&mut self, feedback: &Feedback) {
        self.cycle += 1;
        let mut sp = self.last;
        sp.cycle = self.cycle;
        match self.source {
            Source::Path if self.synced.is_some() => self.synced_step(feedback, &mut sp),
            Source::Path => {
                let n = self.planner_joint_count;
                let status = self.planner.next(&mut self.planner_buf[..n]);
                for k in 0..n {
                    sp.joints[self.planner_joints[k]] = self.planner_buf[k];
                }
                sp.axes = status.axes;
                sp.line = status.line;
                sp.path_speed = status.path_speed;
                self.last_state = status.state;
                if status.state == MotionState::Idle && self.phase == Phase::Idle {
                    sp.line = 0;
                }
            }
            Source::Manual => {
                self.handwheel_step(feedback);
                let mut speed2 = 0.0;
                for i in 0..AXES {
                    if self.axis_present[i] {
                        let s = self.axis_otg[i].step(self.period_s);
                        sp.axes[i] = s.p;
                        speed2 += s.v * s.v;
                    }
                }
                sp.path_speed = speed2.sqrt();
                for j in 0..self.joint_count {
                    if let Some(i) = self.joints[j].axis {
                        sp.joints[j] = sp.axes[i];
                    }
                }
                self.homing_step(feedback);
            }
        }
        // Joints on their own generator (homing, independent joints).
        for j in 0..self.joint_count {
            if self.joint_manual & (1 << j) != 0 {
                sp.joints[j] = self.joint_otg[j].step(self.period_s).p;
            }
        }
        if self.source == Source::Manual {
            self.release_stopped_homing_joints(&mut sp);
        }
        self.last = sp;
    }

    fn on_fault(&mut self, shared: &Shared, fault: Fault) {
        self.last_fault = Some(fault);
        self.requests_mut().machine_on_request = false;
        if fault.code == FaultCode::EStop {
            self.estop = true;
        } else {
            self.fault = true;
        }
        if !self.enable {
            return;
        }
        // Quick stop of whatever moves, with the configured deceleration and jerk; the
        // drives are disabled once it stands (see `interpolate`).
        self.stopping = true;
        self.probe = None;
        self.stop_synced(true);
        self.epoch = self.epoch.wrapping_add(1);
        let _ = shared
            .interpreter_requests
            .try_put(InterpreterRequest::Stop);
        self.pending = None;
        self.phase = Phase::Idle;
        self.held = false;
        self.logic_paused = false;
        self.homing = None;
        self.latch = LatchRequest::default();
        match self.source {
            Source::Path => self.planner.quick_stop(),
            Source::Manual => {
                self.handwheel = None;
                self.stop_manual(true);
            }
        }
        let mi = self.requests_mut();
        mi.tool_change_request = false;
        mi.m_code_request = false;
        mi.program_running = false;
        mi.spindle_on = false;
        mi.spindle_orient = false;
        self.spindle_on = false;
        // A stopped program leaves no override disabled behind; the planner takes them at
        // the reset.
        self.feed_override_enabled = true;
        self.spindle_override_enabled = true;
        self.feed_stop_enabled = true;
    }

    fn handwheel_step(&mut self, feedback: &Feedback) {
        let Some((i, per_count)) = self.handwheel else {
            self.handwheel_counts = None;
            return;
        };
        let counts = feedback.handwheel_counts;
        let previous = self.handwheel_counts.replace(counts).unwrap_or(counts);
        let delta = counts.wrapping_sub(previous);
        if delta != 0 {
            let target = self.handwheel_target(i) + delta as f64 * per_count;
            let target = target.clamp(self.axis_min[i], self.axis_max[i]);
            let _ = self.axis_otg[i].set_target(State::at_rest(target));
        }
    }

    /// Where the axis generator is heading (its profile's end).
    fn handwheel_target(&self, i: usize) -> f64 {
        let (profile, _) = self.axis_otg[i].profile();
        profile.at(profile.duration()).p
    }

    fn next_homing_group(&self, after: Option<u8>) -> Option<Homing> {
        let sequence = (0..self.joint_count)
            .filter_map(|j| self.joints[j].homing.map(|h| h.sequence))
            .filter(|s| after.is_none_or(|a| *s > a))
            .min()?;
        let mut step = [None; MAX_JOINTS];
        for (j, slot) in step.iter_mut().enumerate().take(self.joint_count) {
            if self.joints[j]
                .homing
                .is_some_and(|h| h.sequence == sequence)
            {
                *slot = Some(HomingStep::Search);
            }
        }
        Some(Homing { sequence, step })
    }

    /// One period of the homing sequence of the current group.
    fn homing_step(&mut self, feedback: &Feedback) {
        let Some(mut homing) = self.homing else {
            return;
        };
        let mut all_done = true;
        for j in 0..self.joint_count {
            let Some(step) = homing.step[j] else {
                continue;
            };
            let Some(h) = self.joints[j].homing else {
                continue;
            };
            let bit = 1u32 << j;
            let toward = h.search_velocity.signum();
            let on_switch = feedback.home_switch & bit != 0;
            let otg = &mut self.joint_otg[j];
            let next = match step {
                HomingStep::Search => {
                    if self.joint_manual & bit == 0 {
                        // Take the joint over from its axis, at rest where it stands.
                        let p = self.last.joints[j];
                        if let Ok(o) = OnlineAxis::new(State::at_rest(p), self.joints[j].limits) {
                            *otg = o;
                        }
                        self.joint_manual |= bit;
                        let _ = otg.set_velocity(h.search_velocity, 0.0);
                        Some(HomingStep::Search)
                    } else if on_switch {
                        let _ = otg.stop();
                        Some(HomingStep::SearchStop)
                    } else {
                        Some(HomingStep::Search)
                    }
                }
                HomingStep::SearchStop => {
                    if otg.is_finished() {
                        let _ = otg.set_velocity(-toward * h.latch_velocity, 0.0);
                        Some(HomingStep::BackOff)
                    } else {
                        Some(HomingStep::SearchStop)
                    }
                }
                HomingStep::BackOff => {
                    if !on_switch {
                        let _ = otg.stop();
                        Some(HomingStep::BackOffStop)
                    } else {
                        Some(HomingStep::BackOff)
                    }
                }
                HomingStep::BackOffStop => {
                    if otg.is_finished() {
                        if h.use_index {
                            self.latch.index |= bit;
                        } else {
                            self.latch.switch |= bit;
                        }
                        let _ = otg.set_velocity(toward * h.latch_velocity, 0.0);
                        Some(HomingStep::Latch)
                    } else {
                        Some(HomingStep::BackOffStop)
                    }
                }
                HomingStep::Latch => {
                    if feedback.latched & bit != 0
                        && (self.latch.index | self.latch.switch) & bit != 0
                    {
                        self.latch.index &= !bit;
                        self.latch.switch &= !bit;
                        // The latched raw position becomes `latch_position`.
                        let new_offset = h.latch_position - feedback.latch_position[j];
                        let shift = new_offset - self.offsets[j];
                        self.offsets[j] = new_offset;
                        let s = otg.sample();
                        if let Ok(o) = OnlineAxis::new(
                            State::new(s.p + shift, s.v, s.a),
                            self.joints[j].limits,
                        ) {
                            *otg = o;
                        }
                        let _ = otg.stop();
                        Some(HomingStep::LatchStop)
                    } else {
                        Some(HomingStep::Latch)
                    }
                }
                HomingStep::LatchStop => {
                    if otg.is_finished() {
                        let _ = otg.set_target(State::at_rest(h.home_position));
                        Some(HomingStep::MoveHome)
                    } else {
                        Some(HomingStep::LatchStop)
                    }
                }
                HomingStep::MoveHome => {
                    if otg.is_finished() {
                        self.homed |= bit;
                        None
                    } else {
                        Some(HomingStep::MoveHome)
                    }
                }
            };
            homing.step[j] = next;
            if next.is_some() {
                all_done = false;
            }
        }
        if all_done {
            // The group's axis joints, now squared, go back to their axes at the end of
            // this period (`release_stopped_homing_joints`).
            self.homing = self.next_homing_group(Some(homing.sequence));
            if self.homing.is_none() {
                // Joints without a sequence are homed where they stand.
                for j in 0..self.joint_count {
                    if self.joints[j].homing.is_none() {
                        self.homed |= 1 << j;
                    }
                }
                self.requests_mut().homed = true;
            }
        } else {
            self.homing = Some(homing);
        }
    }

    /// Fills the status snapshot (called by the status task).
    pub fn status(&self, feedback: &Feedback, time_ns: u64, status: &mut Status) {
        status.cycle = self.cycle;
        status.time_ns = time_ns;
        status.state = self.state();
        status.mode = self.mode;
        status.line = self.last.line;
        status.axes = self.last.axes;
        status.joint_setpoints = self.last.joints;
        for j in 0..self.joint_count {
            status.joint_feedback[j] = feedback.position[j] + self.offsets[j];
        }
        status.path_speed = self.last.path_speed;
        status.feed_override = self.feed_override;
        status.homed = self.homed;
        status.program_ended = self.program_ended;
        status.tool = self.tool;
        status.spindle_rpm = feedback.spindle_rpm;
        status.spindle_command_rpm = if self.spindle_on {
            self.spindle_command()
        } else {
            0.0
        };
        status.ready = self.ready && self.enable && feedback.enabled != 0;
        status.geometry = self.planner.geometry_stats();
        if let Some(f) = self.last_fault {
            status.last_fault = Some(f);
        }
    }
}
