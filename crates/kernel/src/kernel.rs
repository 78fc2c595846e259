//! Building the task graph from a machine configuration, a fieldbus and a kinematics; the
//! power-up self-test; and the handle through which the operator side (CLI, tests, a later
//! API server) talks to the kernel.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use rtcnc_fieldbus::Fieldbus;
use rtcnc_fieldbus::sim::SimulatedMachine;
use rtcnc_gcode::{Parameters, Settings, ToolTable};
use rtcnc_motion::PreparedMove;
use rtcnc_plc::RetainSnapshot;
use rtcnc_rt::{
    LeadConsumer, LeadProducer, MissReaction, PiMutex, RingConsumer, RingProducer, SeqlockWriter,
    TaskId, TaskSet, TaskSetBuilder, ThreadId,
};
use rtcnc_servo::ServoLoop;

use crate::compensation::CompensationStage;
use crate::config::{FieldbusKind, LengthUnits, MachineConfig, MissReactionConfig, ThreadConfig};
use crate::fault::{Fault, FaultCode, TaskName};
use crate::interpreter::InterpreterStage;
use crate::kinematics::MachineKinematics;
use crate::logic::{Logic, LogicStage};
use crate::messages::{Command, OperatorMessage, Status, Urgent};
use crate::motion::{MotionCore, ServoTarget};
use crate::servo::{Sample, ServoStage};
use crate::shared::{LogicRequests, Shared, Snapshot, Writers};
use crate::sim::{SimulatedEthercatHandle, SimulatedMachineHandle};

use crate::error::{KernelError, SelfTestFailure};

/// Options of one kernel instance.
#[derive(Debug, Clone, Default)]
pub struct KernelOptions {
    /// The part program auto mode runs.
    pub program: Option<PathBuf>,
    /// The machine file's PLC program already compiled (`rtcnc_plc::compile_file` of its
    /// `[plc] program`), for a host that builds many kernels of one machine; `None`
    /// compiles the file.
    pub plc_program: Option<Arc<rtcnc_plc::Program>>,
    /// Record every servo cycle (ring of this many samples; drain it often enough).
    pub record_capacity: usize,
    /// Trace events kept per executive thread.
    pub trace_capacity: Option<usize>,
    /// Processor time the interpolation task declares per run on top of its own work:
    /// virtual time charges it, real time spins for it. For load and deadline-miss tests.
    pub interpolation_load: Option<Duration>,
    /// One stall of interpolation: at its activation `.0` it declares `.1` of processor
    /// time on top of its work (virtual time charges it; real time spins), as a thread
    /// that its processor does not run for that long. For the set-point lead's tests.
    pub interpolation_stall: Option<(u64, Duration)>,
    /// Fault injection: from the set-point with this number on the planner makes no
    /// progress (its set-point stands while it says it moves), as a planner that stalls.
    /// For the stall watchdog's test.
    pub freeze_path_from: Option<u64>,
    /// Fault injection: the planner takes no move of a program (each is answered as if its
    /// window were full), as a sequencer that cannot hand its next block on. For the stall
    /// watchdog's test.
    pub refuse_moves: bool,
    /// The shared-memory link to an API process (`rtcnc machine`): its tasks run first in
    /// the interpolation thread, in command parsing and after status feedback.
    pub link: Option<crate::link::MachineLink>,
}

/// The result of the power-up self-test.
#[derive(Debug, Clone, Default)]
pub struct SelfTestReport {
    /// Each check and what it found.
    pub checks: Vec<(&'static str, String)>,
}

/// What the operator side may ask of the drive stage, whatever its fieldbus.
trait DriveStatus: Send + Sync {
    /// See [`KernelHandle::setpoint_underruns`].
    fn setpoint_underruns(&self) -> u64;
}

impl<B: Fieldbus + Send> DriveStatus for PiMutex<ServoStage<B>> {
    fn setpoint_underruns(&self) -> u64 {
        self.lock().underruns()
    }
}

/// What the operator side holds: channels in, snapshots and faults out.
#[derive(Clone)]
pub struct KernelHandle {
    shared: Shared,
    drives: Arc<dyn DriveStatus>,
    simulated: Option<SimulatedMachineHandle>,
    simulated_ethercat: Option<SimulatedEthercatHandle>,
    config: Arc<MachineConfig>,
    plc: Option<Arc<PiMutex<rtcnc_plc::Runtime>>>,
}

impl KernelHandle {
    /// Sends an urgent command; false when the channel is full.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn urgent(&self, command: Urgent) -> bool {
        self.shared.urgent.try_put(command).is_ok()
    }

    /// Sends a normal command; false when the channel is full.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn command(&self, command: Command) -> bool {
        self.shared.normal.try_put(command).is_ok()
    }

    /// The latest status snapshot.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn status(&self) -> Status {
        self.shared.status.read()
    }

    /// The status channel, for a reader that keeps its own copy.
    pub(crate) fn status_reader(&self) -> rtcnc_rt::SeqlockReader<Status> {
        self.shared.status.clone()
    }

    /// Operator messages (`(MSG,...)`, `(DEBUG,...)`) the machine reached since the last
    /// call, in program order.
    ///
    /// Real-time: no (allocates).
    pub fn take_messages(&self) -> Vec<OperatorMessage> {
        std::iter::from_fn(|| self.shared.operator_messages.try_get()).collect()
    }

    /// Faults raised since the last call.
    ///
    /// Real-time: no (allocates).
    pub fn take_faults(&self) -> Vec<Fault> {
        std::iter::from_fn(|| self.shared.faults.try_get()).collect()
    }

    /// The last program error in words: the interpreter's or tool compensation's, else the
    /// planner's (a soft limit, a bad arc).
    ///
    /// Real-time: no (allocates).
    pub fn error_text(&self) -> Option<String> {
        self.shared.error_text.lock().clone().or_else(|| {
            self.shared
                .motion_error
                .lock()
                .as_ref()
                .map(|e| format!("planner: {e}"))
        })
    }

    /// The simulated machine the kernel runs on (press the e-stop, turn the handwheel,
    /// inject faults); [`KernelError::NotSimulated`] on any other fieldbus.
    ///
    /// Real-time: yes (no allocation, no blocking); its refusal's message allocates when formatted.
    pub fn simulated_machine(&self) -> Result<&SimulatedMachineHandle, KernelError> {
        self.simulated.as_ref().ok_or(KernelError::NotSimulated)
    }

    /// The simulated EtherCAT devices the kernel's master runs on (`[fieldbus.simulation]`:
    /// inject frame loss, a device's fall to SAFE-OP, a drive fault, link down);
    /// [`KernelError::NotSimulated`] on any other fieldbus.
    ///
    /// Real-time: yes (no allocation, no blocking); its refusal's message allocates when formatted.
    pub fn simulated_ethercat(&self) -> Result<&SimulatedEthercatHandle, KernelError> {
        self.simulated_ethercat
            .as_ref()
            .ok_or(KernelError::NotSimulated)
    }

    /// Servo periods in which position control had no fresh set-point (real-time overruns
    /// of interpolation) and extrapolated.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn setpoint_underruns(&self) -> u64 {
        self.drives.setpoint_underruns()
    }

    /// The set-point lead in servo periods, and the most exchanges with the drives
    /// between two runs of interpolation since start-up (1 without a stall): a gap up to
    /// the lead is ridden through; beyond it the set-points run dry
    /// (`kernel.setpoints_ran_dry`).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn setpoint_lead(&self) -> (u64, u64) {
        let lead = self
            .config
            .tasks
            .setpoint_lead_periods(self.config.servo_period())
            .unwrap_or(1);
        let gap = self
            .shared
            .interpolation_gap
            .load(std::sync::atomic::Ordering::Relaxed);
        (lead, gap)
    }

    /// The PLC runtime, shared with the machine-logic task (hold it briefly).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn plc(&self) -> Option<&Arc<PiMutex<rtcnc_plc::Runtime>>> {
        self.plc.as_ref()
    }

    /// The configuration.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn config(&self) -> &MachineConfig {
        &self.config
    }

    /// A joint's configured name.
    ///
    /// Real-time: no (allocates).
    pub fn joint_name(&self, joint: usize) -> String {
        self.config
            .joints
            .get(joint)
            .map_or_else(|| format!("#{joint}"), |j| j.name.clone())
    }

    /// A fault in words, with the joint's name; a PLC fault with the PLC's code, POU and
    /// line.
    ///
    /// Real-time: no (allocates).
    pub fn describe(&self, fault: &Fault) -> String {
        let text = fault.describe(|j| self.joint_name(j));
        if matches!(
            fault.code,
            FaultCode::Communication
                | FaultCode::WorkingCounter
                | FaultCode::DeviceState
                | FaultCode::LinkDown
        ) && let Some(error) = &*self.shared.fieldbus_error.lock()
        {
            return format!("{text}: {error}");
        }
        match &*self.shared.plc_fault.lock() {
            Some(plc) if fault.code == FaultCode::LogicFault && fault.value == 0.0 => {
                format!("{text}: {plc}")
            }
            _ => text,
        }
    }
}

/// A kernel ready to be run by either runner.
pub struct Kernel {
    /// The task set (give it to `VirtualRunner::new` or `RealTimeRunner::start`).
    pub tasks: TaskSet,
    /// The operator side.
    pub handle: KernelHandle,
    /// Recorded servo cycles (when `record_capacity > 0`).
    pub samples: Option<RingConsumer<Sample>>,
    /// What the self-test found.
    pub self_test: SelfTestReport,
}

impl Kernel {
    /// Builds the kernel for a configuration on the fieldbus its `fieldbus.kind` names
    /// (`"sim"`: the simulated machine the file describes) with the file's kinematics; see
    /// [`Kernel::build_with`].
    ///
    /// Real-time: no (set-up: allocates).
    pub fn build(config: &MachineConfig, options: KernelOptions) -> Result<Kernel, KernelError> {
        config.validate()?;
        let kinematics = MachineKinematics::from_config(config)?;
        match config.fieldbus.kind {
            FieldbusKind::Sim => {
                let machine = SimulatedMachine::new(&config.simulated_machine()?)
                    .map_err(KernelError::SimulatedMachine)?;
                Kernel::assemble(config, options, machine, kinematics)
            }
            FieldbusKind::Ethercat => {
                let Some(section) = &config.fieldbus.ethercat else {
                    return Err(KernelError::Config(crate::ConfigError::Invalid {
                        key: "fieldbus".into(),
                        reason: "kind = \"ethercat\" without the master's keys".into(),
                    }));
                };
                let period = config.servo_period();
                match &section.simulation {
                    Some(simulation) => {
                        let bus = rtcnc_ethercat::SimulatedBus::start(
                            &section.master,
                            &config.simulated_joints()?,
                            simulation,
                            period,
                        )
                        .map_err(KernelError::Ethercat)?;
                        Kernel::assemble(config, options, bus, kinematics)
                    }
                    None => {
                        let bus = rtcnc_ethercat::EthercatMaster::start(&section.master, period)
                            .map_err(KernelError::Ethercat)?;
                        Kernel::assemble(config, options, bus, kinematics)
                    }
                }
            }
        }
    }

    /// Builds the kernel on a fieldbus opened elsewhere (an EtherCAT master, a simulated
    /// machine of one's own), with the machine file's kinematics; see
    /// [`Kernel::build_with`].
    ///
    /// Real-time: no (set-up: allocates).
    pub fn build_with_bus<B: Fieldbus + Send + 'static>(
        config: &MachineConfig,
        options: KernelOptions,
        bus: B,
    ) -> Result<Kernel, KernelError> {
        config.validate()?;
        let kinematics = MachineKinematics::from_config(config)?;
        Kernel::assemble(config, options, bus, kinematics)
    }

    /// Builds the kernel for a validated configuration on `bus` with `kinematics`: runs the
    /// power-up self-test (configuration, persistent files, drive communication, I/O) and
    /// declares the task graph. When `bus` is a [`SimulatedMachine`], the handle reaches
    /// it ([`KernelHandle::simulated_machine`]).
    ///
    /// Real-time: no (set-up: allocates).
    pub fn build_with<B: Fieldbus + Send + 'static>(
        config: &MachineConfig,
        options: KernelOptions,
        bus: B,
        kinematics: MachineKinematics,
    ) -> Result<Kernel, KernelError> {
        config.validate()?;
        Kernel::assemble(config, options, bus, kinematics)
    }

    fn assemble<B: Fieldbus + Send + 'static>(
        config: &MachineConfig,
        options: KernelOptions,
        mut bus: B,
        kinematics: MachineKinematics,
    ) -> Result<Kernel, KernelError> {
        let config = Arc::new(config.clone());
        let threads = config.tasks_checked()?;
        let period_s = threads[0].1.as_secs_f64();
        let mut report = SelfTestReport::default();
        report.checks.push(("configuration", "valid".into()));
        let (parameters, tools) = persistent_files(&config, &mut report)?;
        self_test_bus(&mut bus, &config, period_s, &mut report)?;

        let (shared, writers) = Shared::new();
        let Writers {
            feedback,
            requests,
            logic_outputs,
            status,
        } = writers;
        let (setpoints_out, setpoints_in) = setpoint_channel(&config)?;
        // The link's trace ring takes the recorded samples.
        let record_capacity = match options.link {
            Some(_) => options.record_capacity.max(64),
            None => options.record_capacity,
        };
        let (recorder, mut samples) = recording(record_capacity)?;
        let servo = Arc::new(PiMutex::new(drive_stage(
            &config,
            bus,
            period_s,
            setpoints_in,
            recorder,
            &shared,
            feedback,
        )?));
        let simulated = SimulatedMachineHandle::of(&servo);
        let simulated_ethercat = SimulatedEthercatHandle::of(&servo, &config);
        let core = motion_core(
            &config,
            kinematics,
            &shared,
            requests,
            setpoints_out,
            // With a link, programs are loaded at run time (the link refuses a start
            // without one).
            options.program.is_some() || options.link.is_some(),
            PathInjection {
                freeze_from: options.freeze_path_from,
                refuse_moves: options.refuse_moves,
            },
        )?;
        let (logic, retain, plc) = logic_stage(
            &config,
            options.plc_program.as_ref(),
            &shared,
            logic_outputs,
            &mut report,
        )?;
        let (modal_writer, modal) = rtcnc_rt::seqlock("modal state", Default::default());
        let interpreter = interpreter_stage(&config, &shared, &options, parameters, tools)
            .with_modal(modal_writer);
        let link = match &options.link {
            Some(l) => Some(l.ports(&shared, modal, samples.take())?),
            None => None,
        };
        let stages = Stages {
            servo: servo.clone(),
            core,
            logic,
            status,
            interpreter,
            compensation: CompensationStage::new(
                shared.clone(),
                config.motion.default_blend_tolerance,
            ),
            retain,
            link,
        };
        let tasks = declare_tasks(&config, &threads, &options, &shared, stages)?;
        report.checks.push(("ready", "self-test passed".into()));
        Ok(Kernel {
            tasks,
            handle: KernelHandle {
                shared,
                drives: servo,
                simulated,
                simulated_ethercat,
                config,
                plc,
            },
            samples,
            self_test: report,
        })
    }
}

/// The set-point channel from interpolation to position control: a lead queue with room
/// for the configured lead and the periods a late interpolation run catches up on.
fn setpoint_channel(
    config: &MachineConfig,
) -> Result<(LeadProducer<ServoTarget>, LeadConsumer<ServoTarget>), KernelError> {
    let lead = config.tasks.setpoint_lead_periods(config.servo_period())?;
    let capacity = usize::try_from(lead)
        .unwrap_or(usize::MAX)
        .saturating_add(16);
    // Numbered by exchange: the first set-point is for the first exchange.
    Ok(rtcnc_rt::lead_queue::<ServoTarget>(
        "set-points",
        capacity,
        1,
    )?)
}

/// The ring of recorded servo cycles, when asked for.
#[allow(clippy::type_complexity)]
fn recording(
    capacity: usize,
) -> Result<(Option<RingProducer<Sample>>, Option<RingConsumer<Sample>>), KernelError> {
    if capacity == 0 {
        return Ok((None, None));
    }
    let (tx, rx) = rtcnc_rt::ring::<Sample>("samples", capacity)?;
    Ok((Some(tx), Some(rx)))
}

/// Position control and drive I/O on `bus`: the servo loop of every joint.
fn drive_stage<B: Fieldbus>(
    config: &MachineConfig,
    bus: B,
    period_s: f64,
    setpoints: LeadConsumer<ServoTarget>,
    recorder: Option<RingProducer<Sample>>,
    shared: &Shared,
    feedback: SeqlockWriter<crate::shared::Feedback>,
) -> Result<ServoStage<B>, KernelError> {
    let loops = config
        .joints
        .iter()
        .enumerate()
        .map(|(joint, jc)| {
            ServoLoop::new(joint, &jc.servo).map_err(|source| KernelError::Servo { joint, source })
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(ServoStage::new(
        bus,
        loops,
        period_s,
        setpoints,
        recorder,
        shared.clone(),
        feedback,
        config.io.program_outputs.clone(),
    )
    .with_program_analog_outputs(config.io.program_analog_outputs.clone())
    .with_stop_limits(crate::motion::joint_quick_stop_limits(config))
    .with_plc_joints(
        config
            .plc_axes()
            .iter()
            .fold(0, |mask, (_, joint, _)| mask | 1 << joint),
    ))
}

/// The motion core at rest, ready to be reset into operation.
fn motion_core(
    config: &MachineConfig,
    kinematics: MachineKinematics,
    shared: &Shared,
    requests: SeqlockWriter<LogicRequests>,
    setpoints_out: LeadProducer<ServoTarget>,
    has_program: bool,
    injection: PathInjection,
) -> Result<Arc<PiMutex<MotionCore>>, KernelError> {
    let mut core = MotionCore::new(config, kinematics, shared, requests, setpoints_out)?;
    core.freeze_path_from(injection.freeze_from);
    core.refuse_moves(injection.refuse_moves);
    core.set_has_program(has_program);
    core.self_test_passed();
    Ok(Arc::new(PiMutex::new(core)))
}

/// The stall watchdog's fault injections (`KernelOptions::freeze_path_from`,
/// `KernelOptions::refuse_moves`).
struct PathInjection {
    freeze_from: Option<u64>,
    refuse_moves: bool,
}

/// Where the PLC's RETAIN values wait for the background task to save them, and the file.
type RetainSaver = (Arc<PiMutex<RetainSnapshot>>, PathBuf);

/// The PLC runtime, shared by the machine-logic task and the operator side.
type SharedPlc = Arc<PiMutex<rtcnc_plc::Runtime>>;

/// The machine logic: the machine file's PLC program (compiled, its RETAIN values
/// restored), or the kernel's direct logic.
fn logic_stage(
    config: &MachineConfig,
    compiled: Option<&Arc<rtcnc_plc::Program>>,
    shared: &Shared,
    outputs: SeqlockWriter<crate::shared::LogicOutputs>,
    report: &mut SelfTestReport,
) -> Result<(LogicStage, Option<RetainSaver>, Option<SharedPlc>), KernelError> {
    let logic = match &config.plc {
        None => Logic::Direct,
        Some(plc) => {
            let path = config.resolve(&plc.program);
            let mut runtime = crate::logic::load_plc(
                &path,
                compiled,
                &plc.signals,
                &plc.safe_values,
                &config.plc_axes(),
            )?;
            report
                .checks
                .push(("machine logic", format!("{} compiled", path.display())));
            if let Some(file) = &config.files.plc_retain {
                let file = config.resolve(file);
                let restored =
                    runtime
                        .load_retain(&file)
                        .map_err(|source| KernelError::PlcRetain {
                            path: file.clone(),
                            source,
                        })?;
                report.checks.push((
                    "plc retain",
                    format!(
                        "{}: {} restored, {} skipped",
                        file.display(),
                        restored.restored,
                        restored.skipped
                    ),
                ));
            }
            Logic::Plc(Arc::new(PiMutex::new(runtime)))
        }
    };
    let plc = match &logic {
        Logic::Plc(runtime) => Some(Arc::clone(runtime)),
        Logic::Direct => None,
    };
    let retain = match (&logic, &config.files.plc_retain) {
        (Logic::Plc(runtime), Some(file)) => Some((
            Arc::new(PiMutex::new(runtime.lock().retain_snapshot())),
            config.resolve(file),
        )),
        _ => None,
    };
    let mut stage = LogicStage::new(
        shared.clone(),
        logic,
        outputs,
        config.tool_changer.is_some(),
    );
    if let Some((snapshot, _)) = &retain {
        stage = stage.with_retain(Arc::clone(snapshot));
    }
    if let Some(runtime) = &plc {
        let runtime = runtime.lock();
        let axes = config
            .plc_axes()
            .iter()
            .filter_map(|(var, joint, _)| Some((runtime.axis_index(var)?, *joint)))
            .collect();
        drop(runtime);
        stage = stage.with_plc_axes(axes);
    }
    Ok((stage, retain, plc))
}

/// The interpreter with the persistent parameters and tool table.
fn interpreter_stage(
    config: &MachineConfig,
    shared: &Shared,
    options: &KernelOptions,
    parameters: Parameters,
    tools: ToolTable,
) -> InterpreterStage {
    // The interpreter stops reading after M66 (and G38) until the machine's result is
    // in, as LinuxCNC's task synchronises before such a block.
    let mut settings = Settings {
        wait_for_machine: true,
        ..Settings::default()
    };
    if config.machine.units == LengthUnits::Inch {
        settings.initial_units = rtcnc_gcode::canon::Units::Inches;
    }
    InterpreterStage::new(
        shared.clone(),
        options.program.clone(),
        settings,
        tools,
        parameters,
        config.machine.diameter_mode,
    )
    .with_parameter_file(config.files.parameters.as_ref().map(|p| config.resolve(p)))
    .with_tool_table_file(config.files.tool_table.as_ref().map(|p| config.resolve(p)))
    .with_pallet_shuttle(config.machine.pallet_shuttle)
    .with_spindle_limit(config.spindle.map(|s| (s.max_speed_rpm, s.over_speed)))
    .with_five_axis_kinematics(config.kinematics.five_axis())
}

/// The stages the tasks run, built and ready to be moved into the task bodies.
struct Stages<B: Fieldbus> {
    servo: Arc<PiMutex<ServoStage<B>>>,
    core: Arc<PiMutex<MotionCore>>,
    logic: LogicStage,
    status: SeqlockWriter<Status>,
    interpreter: InterpreterStage,
    compensation: CompensationStage,
    retain: Option<RetainSaver>,
    /// The shared-memory link's ports: urgent commands, normal commands, the publisher.
    link: Option<(
        crate::link::UrgentPort,
        crate::link::CommandPort,
        crate::link::Publisher,
    )>,
}

/// The task graph on the executive: the periodic threads in the order of the seeds'
/// tables, the event tasks and the background check. The order of declaration is the
/// order in which tasks of equal priority run.
fn declare_tasks<B: Fieldbus + Send + 'static>(
    config: &MachineConfig,
    threads: &[(&'static str, Duration, &ThreadConfig); 6],
    options: &KernelOptions,
    shared: &Shared,
    stages: Stages<B>,
) -> Result<TaskSet, KernelError> {
    let mut b = TaskSet::builder();
    if let Some(capacity) = options.trace_capacity {
        b.trace_capacity(capacity);
    }
    let t = &config.tasks;
    let thread = |b: &mut TaskSetBuilder, name: &str, i: usize| {
        b.periodic_thread(name, threads[i].1, threads[i].2.priority)
    };
    let fieldbus = thread(&mut b, "fieldbus", 0);
    let mut real_time = vec![
        position_control_task(&mut b, fieldbus, &stages.servo),
        drive_io_task(&mut b, fieldbus, &stages.servo),
    ];
    let th = thread(&mut b, "machine logic", 1);
    real_time.push(logic_task(&mut b, th, t.machine_logic.runs, stages.logic));
    let th = if t.interpolation_in_fieldbus_thread(threads[0].1) {
        fieldbus
    } else {
        thread(&mut b, "interpolation", 2)
    };
    let (urgent_port, command_port, publisher) = match stages.link {
        Some((u, c, p)) => (Some(u), Some(c), Some(p)),
        None => (None, None, None),
    };
    if let Some(mut port) = urgent_port {
        // First in the interpolation thread: urgent commands from the link reach
        // interpolation within the period they are read in.
        let sh = shared.clone();
        real_time.push(b.periodic(th, "link urgent", 1, move |ctx| port.run(ctx, &sh)));
    }
    let load = options.interpolation_load;
    let stall = options.interpolation_stall;
    let core = &stages.core;
    real_time.push(interpolation_task(&mut b, th, core, shared, load, stall));
    let th = thread(&mut b, "look-ahead", 3);
    real_time.push(look_ahead_task(&mut b, th, t.look_ahead.runs, core, shared));
    let th = thread(&mut b, "command parsing", 4);
    let runs = t.command_parsing.runs;
    real_time.push(command_parsing_task(
        &mut b,
        th,
        runs,
        core,
        shared,
        command_port,
    ));
    let th = thread(&mut b, "status feedback", 5);
    let runs = t.status_feedback.runs;
    real_time.push(status_task(&mut b, th, runs, core, shared, stages.status));
    if let Some(mut publisher) = publisher {
        // After the status, every period: the link's status, events and trace.
        real_time.push(b.periodic(th, "link status", 1, move |ctx| publisher.run(ctx)));
    }
    let miss = miss_reaction(config.safety.deadline_miss, shared);
    for id in real_time {
        b.on_deadline_miss(id, miss.clone());
    }

    let mut compensation = stages.compensation;
    b.event(
        "tool compensation",
        t.tool_compensation.priority,
        shared.program_blocks.data_trigger(),
        move |ctx| compensation.body(ctx),
    );
    let mut interpreter = stages.interpreter;
    b.event(
        "interpreter",
        t.interpreter.priority,
        shared.interpreter_wake.trigger(),
        move |ctx| interpreter.body(ctx),
    );
    background_check(&mut b, config, shared, stages.retain);
    Ok(b.build()?)
}

/// Position control: the first function of the fieldbus thread; it takes this period's
/// set-point from the set-point channel.
fn position_control_task<B: Fieldbus + Send + 'static>(
    b: &mut TaskSetBuilder,
    fieldbus: ThreadId,
    servo: &Arc<PiMutex<ServoStage<B>>>,
) -> TaskId {
    let s = servo.clone();
    b.periodic(fieldbus, "position control", 1, move |ctx| {
        s.lock().position_control(ctx)
    })
}

/// Drive I/O: the exchange with the drives, after position control.
fn drive_io_task<B: Fieldbus + Send + 'static>(
    b: &mut TaskSetBuilder,
    fieldbus: ThreadId,
    servo: &Arc<PiMutex<ServoStage<B>>>,
) -> TaskId {
    let s = servo.clone();
    b.periodic(fieldbus, "drive io", 1, move |ctx| s.lock().drive_io(ctx))
}

/// Machine logic: one scan per activation, whatever `runs` says.
fn logic_task(
    b: &mut TaskSetBuilder,
    thread: ThreadId,
    runs: u32,
    mut logic: LogicStage,
) -> TaskId {
    b.periodic(thread, "machine logic", runs, move |ctx| {
        if ctx.run() == 0 {
            logic.scan(ctx);
        }
        ctx.finish_runs();
    })
}

/// Interpolation: the set-points up to the lead into the set-point channel.
fn interpolation_task(
    b: &mut TaskSetBuilder,
    thread: ThreadId,
    core: &Arc<PiMutex<MotionCore>>,
    shared: &Shared,
    load: Option<Duration>,
    stall: Option<(u64, Duration)>,
) -> TaskId {
    let (c, sh) = (core.clone(), shared.clone());
    b.periodic(thread, "interpolation", 1, move |ctx| {
        c.lock().interpolate(ctx, &sh);
        if let Some(load) = load {
            ctx.consume(load);
        }
        if let Some((at, stall)) = stall
            && ctx.activation() == at
        {
            ctx.consume(stall);
        }
    })
}

/// Moves whose geometry one look-ahead run builds at most (each between two holds of the
/// core's lock), so that a run is bounded.
const BUILDS_PER_RUN: usize = 64;

/// Look-ahead: keeps the planner's window full and sequences the program.
fn look_ahead_task(
    b: &mut TaskSetBuilder,
    thread: ThreadId,
    runs: u32,
    core: &Arc<PiMutex<MotionCore>>,
    shared: &Shared,
) -> TaskId {
    let (c, sh) = (core.clone(), shared.clone());
    let mut more = false;
    // A move's geometry, built here between two holds of the core's lock.
    let mut staging = PreparedMove::new();
    b.periodic(thread, "look-ahead", runs, move |ctx| {
        // The runs after the first only when the one before stopped at its bound of
        // steps, not on something only another task can change.
        if ctx.run() == 0 || more {
            more = false;
            for _ in 0..BUILDS_PER_RUN {
                more = c.lock().look_ahead(ctx, &sh, &mut staging);
                if !staging.build_due() {
                    break;
                }
                staging.build();
                more = true;
            }
        }
        if !more {
            ctx.finish_runs();
        }
    })
}

/// Command parsing: the normal channel, a command per run until it is empty (the urgent
/// channel is read at the start of every interpolation cycle instead).
fn command_parsing_task(
    b: &mut TaskSetBuilder,
    thread: ThreadId,
    runs: u32,
    core: &Arc<PiMutex<MotionCore>>,
    shared: &Shared,
    mut link: Option<crate::link::CommandPort>,
) -> TaskId {
    let (c, sh) = (core.clone(), shared.clone());
    b.periodic(thread, "command parsing", runs, move |ctx| {
        // The kernel's own normal channel, then the link's commands, one per run; each
        // link command is answered with the kernel's verdict. Drained: the remaining runs
        // of this period are not made.
        let next = match sh.normal.try_get() {
            Some(command) => Some((None, command)),
            None => link
                .as_mut()
                .and_then(|p| p.next(ctx))
                .map(|(serial, command)| (Some(serial), command)),
        };
        match next {
            Some((serial, command)) => {
                let ok = c.lock().command(ctx, &sh, command);
                match (serial, link.as_mut()) {
                    (Some(serial), Some(port)) => port.result(ctx, serial, command, ok),
                    (None, Some(port)) => port.watch_keep_alive(ctx, false, command, ok),
                    _ => {}
                }
            }
            None => ctx.finish_runs(),
        }
    })
}

/// Status feedback: the status snapshot, once per activation.
fn status_task(
    b: &mut TaskSetBuilder,
    thread: ThreadId,
    runs: u32,
    core: &Arc<PiMutex<MotionCore>>,
    shared: &Shared,
    mut status_out: SeqlockWriter<Status>,
) -> TaskId {
    let (c, sh) = (core.clone(), shared.clone());
    let mut feedback = Snapshot::new(shared.feedback.clone());
    let mut status = status_out.value();
    b.periodic(thread, "status feedback", runs, move |ctx| {
        ctx.finish_runs();
        if ctx.run() != 0 {
            return;
        }
        c.lock()
            .status(feedback.get(), ctx.now().as_nanos(), &mut status);
        status.fault_count = sh.fault_count.load(std::sync::atomic::Ordering::Relaxed);
        status_out.publish_ref(&status);
    })
}

/// Background checks while running, in what time is left: the drive exchange still
/// advances, the persistent files' folders are still there and writable; and the PLC's
/// RETAIN values are written when they changed, off the real-time tasks.
fn background_check(
    b: &mut TaskSetBuilder,
    config: &MachineConfig,
    shared: &Shared,
    retain: Option<RetainSaver>,
) {
    let sh = shared.clone();
    let folders: Vec<PathBuf> = [
        &config.files.parameters,
        &config.files.tool_table,
        &config.files.plc_retain,
    ]
    .into_iter()
    .flatten()
    .map(|p| {
        config
            .resolve(p)
            .parent()
            .map_or_else(|| PathBuf::from("."), Path::to_path_buf)
    })
    .collect();
    let mut last_cycle = 0u64;
    let mut reported = false;
    let mut feedback = Snapshot::new(shared.feedback.clone());
    let mut retain_saver = retain.map(|(snapshot, file)| (snapshot, file, None, false));
    b.background("self test", move |ctx| {
        if let Some((snapshot, file, saved, failing)) = &mut retain_saver {
            let now = snapshot.lock().clone();
            if saved.as_ref() != Some(&now) {
                let result = now.save(file);
                // A failed write is retried every round but reported once.
                if result.is_err() && !*failing {
                    sh.raise(
                        ctx,
                        FaultCode::BackgroundCheck,
                        TaskName::BackgroundCheck,
                        None,
                        0,
                        3.0,
                    );
                }
                *failing = result.is_err();
                if result.is_ok() {
                    *saved = Some(now);
                }
            }
        }
        let cycle = feedback.get().cycle;
        let stalled = ctx.activation() > 0 && cycle == last_cycle;
        last_cycle = cycle;
        let folder_bad = folders.iter().any(|f| {
            std::fs::metadata(f).map_or(true, |m| !m.is_dir() || m.permissions().readonly())
        });
        if (stalled || folder_bad) && !reported {
            sh.raise(
                ctx,
                FaultCode::BackgroundCheck,
                TaskName::BackgroundCheck,
                None,
                0,
                if stalled { 1.0 } else { 2.0 },
            );
        }
        reported = stalled || folder_bad;
        rtcnc_rt::Next::Sleep(Duration::from_millis(500))
    });
}

fn miss_reaction(config: MissReactionConfig, shared: &Shared) -> MissReaction {
    match config {
        MissReactionConfig::Count => MissReaction::Count,
        MissReactionConfig::Warn => MissReaction::Warn,
        MissReactionConfig::FeedHold => {
            let urgent = shared.urgent.clone();
            MissReaction::Hook(Arc::new(move |_| {
                let _ = urgent.try_put(Urgent::FeedHold);
            }))
        }
        MissReactionConfig::Estop => {
            let urgent = shared.urgent.clone();
            MissReaction::Hook(Arc::new(move |_| {
                let _ = urgent.try_put(Urgent::EStop);
            }))
        }
    }
}

/// The parameter file and the tool table, read (or to be created in a writable folder).
fn persistent_files(
    config: &MachineConfig,
    report: &mut SelfTestReport,
) -> Result<(Parameters, ToolTable), KernelError> {
    let parameters = match &config.files.parameters {
        None => Parameters::new(),
        Some(p) => {
            let path = config.resolve(p);
            if path.exists() {
                let params = Parameters::load(&path)
                    .map_err(|e| KernelError::self_test("parameter file", e))?;
                report
                    .checks
                    .push(("parameter file", format!("{} read", path.display())));
                params
            } else {
                writable_folder(&path, "parameter file")?;
                report.checks.push((
                    "parameter file",
                    format!("{} absent; it will be created", path.display()),
                ));
                Parameters::new()
            }
        }
    };
    let tools = match &config.files.tool_table {
        None => ToolTable::new(),
        Some(p) => {
            let path = config.resolve(p);
            let tools =
                ToolTable::load(&path).map_err(|e| KernelError::self_test("tool table", e))?;
            report.checks.push((
                "tool table",
                format!("{} read, {} tools", path.display(), tools.tools().len()),
            ));
            tools
        }
    };
    Ok((parameters, tools))
}

fn writable_folder(path: &Path, check: &'static str) -> Result<(), KernelError> {
    let folder = path.parent().filter(|p| !p.as_os_str().is_empty());
    let folder = folder.unwrap_or(Path::new("."));
    let meta = std::fs::metadata(folder).map_err(|source| {
        KernelError::self_test(
            check,
            SelfTestFailure::Folder {
                path: folder.to_path_buf(),
                source,
            },
        )
    })?;
    if meta.permissions().readonly() {
        return Err(KernelError::self_test(
            check,
            SelfTestFailure::ReadOnly {
                path: folder.to_path_buf(),
            },
        ));
    }
    Ok(())
}

/// Drive communication and I/O: one exchange with the drives disabled; every configured
/// joint and I/O point must answer, no drive may be faulted.
fn self_test_bus<B: Fieldbus>(
    bus: &mut B,
    config: &MachineConfig,
    period_s: f64,
    report: &mut SelfTestReport,
) -> Result<(), KernelError> {
    const DRIVES: &str = "drive communication";
    let layout = bus.layout().clone();
    if layout.joints.len() != config.joints.len() {
        return Err(KernelError::self_test(
            DRIVES,
            SelfTestFailure::DriveCount {
                answering: layout.joints.len(),
                configured: config.joints.len(),
            },
        ));
    }
    let outputs = rtcnc_fieldbus::ProcessOutputs::new(&layout);
    let mut inputs = rtcnc_fieldbus::ProcessInputs::new(&layout);
    bus.exchange(period_s, &outputs, &mut inputs)
        .map_err(|e| KernelError::self_test(DRIVES, e))?;
    if let Some(j) = inputs.joints.iter().position(|f| f.state().is_fault()) {
        return Err(KernelError::self_test(
            DRIVES,
            SelfTestFailure::DriveFault {
                joint: config.joints[j].name.clone(),
            },
        ));
    }
    report
        .checks
        .push((DRIVES, format!("{} drives answer", layout.joints.len())));
    if layout.digital_inputs != config.io.digital_inputs
        || layout.digital_outputs != config.io.digital_outputs
    {
        return Err(KernelError::self_test(
            "i/o",
            SelfTestFailure::ImageMismatch,
        ));
    }
    report.checks.push((
        "i/o",
        format!(
            "{} digital inputs, {} digital outputs",
            layout.digital_inputs, layout.digital_outputs
        ),
    ));
    Ok(())
}
