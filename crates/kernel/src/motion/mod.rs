//! The motion core: the machine's motion state, the planner (program and MDI motion), the
//! on-line trajectory generators (jog, handwheel, homing, independent joints) and the
//! program sequencer. Three tasks work on it under one priority-inheritance mutex, each
//! doing its own part: command parsing ([`MotionCore::command`]; urgent commands are read
//! by interpolation), look-ahead ([`MotionCore::look_ahead`]) and interpolation
//! ([`MotionCore::interpolate`]); the status task reads it ([`MotionCore::status`]).
//! Nothing here allocates after construction.
//!
//! One job per module:
//! - `state`: the machine's motion state and the table of its transitions;
//! - `commands`: the operator's commands, urgent and normal;
//! - `hold`: feed holds (operator, machine logic, feed stop switch) and resume;
//! - `safety`: e-stop and faults (quick stop, drives off), reset, the logic's e-stop chain;
//! - `sequencer`: the program sequencer (blocks into the planner, stops before what needs
//!   the machine standing), with `machine_functions` (M/S/T hand-shakes, program I/O);
//! - `homing`, `synced` (spindle-synchronised moves), `probing`, `manual` (jog,
//!   handwheel, independent joints): the motions other than the planner's path;
//! - `program_outputs`: M62-M68's outputs, immediate or at the start of the next move,
//!   carried to the drives with the set-points;
//! - `spindle` (speed, constant surface speed), `overrides` (feed, rapid, spindle, M48-M53);
//! - `interpolation`: one set-point per servo period, out to position control;
//! - `machine`: the axes and joints of the configuration.

mod commands;
mod hold;
mod homing;
mod interpolation;
mod machine;
mod machine_functions;
mod manual;
mod overrides;
mod probing;
mod program_outputs;
mod safety;
mod sequencer;
mod spindle;
mod stall;
mod state;
mod synced;

use rtcnc_motion::otg::{self, Limits, OnlineAxis};
use rtcnc_motion::{AXES, Kinematics, MotionState, Planner};
use rtcnc_rt::{LeadProducer, SeqlockWriter};

use crate::config::{MAX_JOINTS, MachineConfig};
use crate::error::KernelError;
use crate::kinematics::MachineKinematics;
use crate::messages::{HoldCause, JointSetpoints, MachineState, Mode, Status};
use crate::shared::{Feedback, LogicOutputs, LogicRequests, Shared, Snapshot};

use hold::Hold;
use interpolation::Output;
pub(crate) use machine::joint_quick_stop_limits;
use machine::{Machine, limits_of};
use machine_functions::ProgramIo;
use manual::Manual;
use overrides::Overrides;
use probing::Probe;
use program_outputs::OutputLog;
pub use program_outputs::ProgramOutputs;
use safety::Safety;
use sequencer::Program;
use spindle::Spindle;
use stall::StallWatch;
use state::{Event, State, Step, transition};
use synced::{SyncedChain, SyncedMove};

/// Latch requests carried with a set-point (bit n for joint n).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LatchRequest {
    /// Arm the index latch.
    pub index: u32,
    /// Arm the home-switch latch.
    pub switch: u32,
    /// Arm the touch-probe latch (0x60B8), on the edge `probe_rising` says.
    pub probe: u32,
    /// The touch-probe latch takes the rising edge (the probe closes), else the falling.
    pub probe_rising: bool,
}

/// What position control receives every servo period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ServoTarget {
    /// The set-points.
    pub setpoints: JointSetpoints,
    /// Homing offsets: raw joint position = machine position − offset.
    pub offsets: [f64; MAX_JOINTS],
    /// What the drives are to be.
    pub enable: DriveEnable,
    /// Incremented by every reset: position control clears its latched faults.
    pub reset_count: u32,
    /// Latches to arm.
    pub latch: LatchRequest,
    /// The program outputs (M62-M68) from this exchange on.
    pub outputs: ProgramOutputs,
}

/// What position control makes of the drives' power stage.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DriveEnable {
    /// Disabled.
    Off,
    /// An enabled drive stays enabled; one that is off stays off (a quick stop: it keeps
    /// braking drives under control, and one whose power came back meanwhile, the e-stop
    /// button released, or that faulted, waits for the operator's reset).
    Keep,
    /// Enabled: a drive that is off is brought up, a faulted one reset.
    On,
}

/// Which generator makes the axes' set-points.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Source {
    /// The planner (program, MDI), or a spindle-synchronised move in its place.
    Path,
    /// The on-line generators (jog, handwheel, homing).
    Manual,
}

/// The planner and the map from its joints to the machine's.
struct Path {
    planner: Planner<MachineKinematics>,
    /// The machine joint of each of the planner's joints.
    joints: [usize; MAX_JOINTS],
    joint_count: usize,
    /// The planner's joint set-points of this period.
    buf: [f64; MAX_JOINTS],
    /// The planner's state after its last set-point.
    state: MotionState,
}

/// The motion core's side of the machine interface: the feedback and the machine logic's
/// answers in, the requests to the logic out.
struct MachineInterface {
    /// The feedback image as drive I/O published it.
    feedback: Snapshot<Feedback>,
    /// The machine logic's answers.
    logic: Snapshot<LogicOutputs>,
    /// The requests to the machine logic (this core is their one writer) and whether they
    /// changed since they were last published.
    requests: LogicRequests,
    changed: bool,
    requests_out: SeqlockWriter<LogicRequests>,
}

/// The motion core. See the module documentation.
pub(crate) struct MotionCore {
    /// What the machine is doing (changed only by [`MotionCore::fire`]).
    state: State,
    machine: Machine,
    path: Path,
    manual: Manual,
    source: Source,
    /// The set-points produced ahead and what goes with them to position control.
    out: Output,
    mode: Mode,
    program: Program,
    safety: Safety,
    hold: Hold,
    /// Bit n: joint n is homed.
    homed: u32,
    spindle: Spindle,
    overrides: Overrides,
    io: ProgramIo,
    /// The program outputs' changes, immediate and synchronised with the path.
    outputs: OutputLog,
    /// The probing move in progress.
    probe: Option<Probe>,
    /// The spindle-synchronised move in progress.
    synced: Option<SyncedMove>,
    /// The lines of a chain of synchronised moves: collected until its last line comes,
    /// then the geometry of the chain in progress.
    synced_chain: SyncedChain,
    /// The tool in the spindle.
    tool: u32,
    interface: MachineInterface,
    stall: StallWatch,
}

impl MotionCore {
    /// The core for a validated configuration, at rest at the joints' initial positions.
    pub(crate) fn new(
        config: &MachineConfig,
        kinematics: MachineKinematics,
        shared: &Shared,
        requests_out: SeqlockWriter<LogicRequests>,
        setpoints_out: LeadProducer<ServoTarget>,
    ) -> Result<MotionCore, KernelError> {
        let (machine, start) = Machine::from_config(config);
        if kinematics.joint_count() != start.planner_joint_count {
            return Err(KernelError::Kinematics {
                expected: start.planner_joint_count,
                found: kinematics.joint_count(),
            });
        }
        let lead = config.tasks.setpoint_lead_periods(config.servo_period())?;
        let stall_limit = config.safety.stall_timeout_periods(config.servo_period())?;
        // The planner keeps the set-points of the lead (and a few more), so that it can go
        // back over those position control has not taken.
        let history = usize::try_from(lead)
            .unwrap_or(usize::MAX)
            .saturating_add(8);
        let planner = Planner::new(&start.limits, kinematics, machine.period_s, 256, start.axes)?
            .with_history(history);
        let at_rest = |p: f64, l: Limits| OnlineAxis::new(otg::State::at_rest(p), l);
        let mut axis_otg = [at_rest(0.0, limits_of(1.0, 1.0, 1.0))?; AXES];
        for i in 0..AXES {
            axis_otg[i] = at_rest(start.axes[i], machine.axis_limits[i])?;
        }
        let mut joint_otg = [axis_otg[0]; MAX_JOINTS];
        let mut joint_manual = 0u32;
        let joints = &machine.joints;
        for j in 0..machine.joint_count {
            joint_otg[j] = at_rest(start.joints[j], joints[j].limits)?;
            if joints[j].axis.is_none() {
                joint_manual |= 1 << j;
            }
        }
        let mut last = JointSetpoints {
            cycle: 0,
            joints: [0.0; MAX_JOINTS],
            axes: start.axes,
            line: 0,
            path_speed: 0.0,
            move_end: start.axes,
        };
        for j in 0..machine.joint_count {
            last.joints[j] = match joints[j].axis {
                Some(i) => start.axes[i],
                None => start.joints[j],
            };
        }
        for j in 0..machine.joint_count {
            if let Some(i) = joints[j].axis {
                joint_otg[j] = at_rest(start.axes[i], joints[j].limits)?;
            }
        }
        let independent_joints = joints
            .iter()
            .take(machine.joint_count)
            .any(|j| j.axis.is_none());
        Ok(MotionCore {
            state: State::Starting,
            path: Path {
                planner,
                joints: start.planner_joints,
                joint_count: start.planner_joint_count,
                buf: [0.0; MAX_JOINTS],
                state: MotionState::Idle,
            },
            manual: Manual::new(axis_otg, joint_otg, joint_manual),
            machine,
            source: Source::Path,
            out: Output::new(last, setpoints_out, lead, independent_joints, &joint_otg),
            mode: Mode::Manual,
            program: Program::new().with_five_axis_kinematics(
                config.kinematics.five_axis(),
                config.kinematics.tolerance,
            ),
            safety: Safety::new(),
            hold: Hold::default(),
            homed: 0,
            spindle: Spindle::new(config),
            overrides: Overrides::new(),
            io: ProgramIo::new(config),
            outputs: OutputLog::new(),
            probe: None,
            synced: None,
            synced_chain: SyncedChain::new(),
            tool: config.tool_changer.map_or(0, |t| t.initial_tool),
            stall: StallWatch::new(stall_limit),
            interface: MachineInterface {
                feedback: Snapshot::new(shared.feedback.clone()),
                logic: Snapshot::new(shared.logic_outputs.clone()),
                requests: requests_out.value(),
                changed: false,
                requests_out,
            },
        })
    }

    /// The requests to the machine logic, to change (published at the end of the task body).
    fn requests_mut(&mut self) -> &mut LogicRequests {
        self.interface.changed = true;
        &mut self.interface.requests
    }

    /// Publishes the requests to the machine logic if a task body changed them.
    fn publish_requests(&mut self) {
        if std::mem::take(&mut self.interface.changed) {
            self.interface
                .requests_out
                .publish_ref(&self.interface.requests);
        }
    }

    /// The self-test passed: the machine may be reset into operation.
    pub(crate) fn self_test_passed(&mut self) {
        self.fire(Event::SelfTestPassed);
    }

    /// The one place that changes the state: to where [`transition`] leads `event`.
    /// Returns false when the present state does not take the event (nothing changes).
    fn fire(&mut self, event: Event) -> bool {
        match transition(&self.state, event) {
            Some(next) => {
                self.state = next;
                true
            }
            None => false,
        }
    }

    /// The program's step, when a program or MDI line runs.
    fn step_of_program(&self) -> Option<Step> {
        match self.state {
            State::Program(step) => Some(step),
            _ => None,
        }
    }

    /// A program is loaded (auto mode can start).
    pub(crate) fn set_has_program(&mut self, has: bool) {
        self.program.loaded = has;
    }

    /// Whether anything of the path or the manual generators still moves: at the
    /// set-point position control applies next, or in those produced after it, or in the
    /// moves not started yet.
    fn moving(&self) -> bool {
        match self.source {
            Source::Path => {
                self.synced.is_some()
                    || self.out.now().state != MotionState::Idle
                    || self.path.state != MotionState::Idle
                    || self.path.planner.pieces_ahead() > 0
            }
            Source::Manual => self.manual_moving() || self.out.now().state != MotionState::Idle,
        }
    }

    /// The servo period the machine is in, by the set-point position control applies
    /// next (the clock of the sequencer's waits).
    fn now(&self) -> u64 {
        self.out.consumer_next()
    }

    /// The machine state as the status shows it.
    pub(crate) fn state(&self) -> MachineState {
        if self.state == State::Starting {
            return MachineState::Starting;
        }
        // Off and Stopping: the cause.
        if self.safety.estop {
            return MachineState::EStop;
        }
        if self.safety.fault {
            return MachineState::Fault;
        }
        // A hold outranks what the program waits for: whatever the wait ends in, nothing
        // moves on until the hold is released, and that is what the operator must see.
        if self.hold_cause().is_some() {
            return MachineState::Held;
        }
        match self.state {
            State::Program(Step::Logic { .. }) => MachineState::WaitingForLogic,
            State::Program(Step::Paused { .. }) => MachineState::Paused,
            State::Homing(_) | State::Program(_) => MachineState::Running,
            _ if self.moving() => MachineState::Running,
            _ => MachineState::Idle,
        }
    }

    /// What holds the machine, if anything does: the first thing the operator must clear.
    /// A program or MDI line that stands before its next block because the machine logic
    /// asks for a hold (it asked before the run's first block, so nothing latched) is held
    /// by it, though no resume is needed once the request falls.
    fn hold_cause(&self) -> Option<HoldCause> {
        let held_before_next_block = self.state == State::Program(Step::Feeding) && !self.moving();
        if self.hold.logic_request && (self.hold.latched() || held_before_next_block) {
            Some(HoldCause::MachineLogic)
        } else if self.hold.feed_stop {
            Some(HoldCause::FeedStopSwitch)
        } else if self.hold.latched() {
            Some(HoldCause::Resume)
        } else {
            None
        }
    }

    /// Fills the status snapshot (called by the status task).
    pub(crate) fn status(&self, feedback: &Feedback, time_ns: u64, status: &mut Status) {
        let last = &self.out.now().target.setpoints;
        status.cycle = last.cycle;
        status.time_ns = time_ns;
        status.state = self.state();
        status.hold = match status.state {
            MachineState::Held => self.hold_cause(),
            _ => None,
        };
        status.mode = self.mode;
        status.line = last.line;
        status.axes = last.axes;
        status.joint_setpoints = last.joints;
        for j in 0..self.machine.joint_count {
            status.joint_feedback[j] = feedback.position[j] + self.out.offsets[j];
        }
        status.path_speed = last.path_speed;
        for (d, (end, at)) in status
            .distance_to_go
            .iter_mut()
            .zip(last.move_end.iter().zip(&last.axes))
        {
            *d = end - at;
        }
        status.feed_override = self.overrides.feed;
        status.homed = self.homed;
        status.program_ended = self.program.ended;
        status.tool = self.tool;
        status.spindle_rpm = feedback.spindle_rpm;
        status.spindle_command_rpm = if self.spindle.on {
            self.spindle_command()
        } else {
            0.0
        };
        // Every drive, not some: a drive left in fault (its cause still there after the
        // reset's fault reset) keeps the machine from being ready.
        let all = u32::MAX >> (32 - self.machine.joint_count.clamp(1, 32));
        status.ready = self.drives_enabled() && feedback.enabled & all == all;
        status.geometry = self.path.planner.geometry_stats();
        if let Some(f) = self.safety.last_fault {
            status.last_fault = Some(f);
        }
    }
}
