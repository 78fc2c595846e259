//! Building the task graph from a machine configuration, the power-up self-test, and the
//! handle through which the operator side (CLI, tests, a later API server) talks to it.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use rtcnc_fieldbus::Fieldbus;
use rtcnc_fieldbus::sim::SimulatedMachine;
use rtcnc_gcode::{Parameters, Settings, ToolTable};
use rtcnc_rt::{MissReaction, PiMutex, RingConsumer, TaskSet};
use rtcnc_servo::ServoLoop;

use crate::compensation::CompensationStage;
use crate::config::{LengthUnits, MachineConfig, MissReactionConfig};
use crate::fault::Fault;
use crate::interpreter::InterpreterStage;
use crate::logic::{Logic, LogicStage};
use crate::messages::{Command, OperatorMessage, Status, Urgent};
use crate::motion::{MotionCore, ServoTarget};
use crate::servo::{Sample, ServoStage};
use crate::shared::{Shared, Snapshot};

/// Why the kernel could not be built or did not pass its self-test.
#[derive(Debug, thiserror::Error)]
pub enum KernelError {
    /// The configuration.
    #[error("{0}")]
    Config(#[from] crate::config::ConfigError),
    /// The simulated machine refused its configuration.
    #[error("fieldbus: {0}")]
    Fieldbus(String),
    /// A servo loop refused its configuration.
    #[error("{0}")]
    Servo(String),
    /// The planner refused the machine.
    #[error("motion: {0}")]
    Motion(String),
    /// The PLC program.
    #[error("plc: {0}")]
    Plc(String),
    /// The executive refused the task set.
    #[error("executive: {0}")]
    Executive(String),
    /// The power-up self-test failed.
    #[error("self-test: {check}: {reason}")]
    SelfTest {
        /// Which check.
        check: &'static str,
        /// Why.
        reason: String,
    },
    /// The program file.
    #[error("program: {0}")]
    Program(String),
}

impl KernelError {
    /// Stable code.
    pub fn code(&self) -> &'static str {
        match self {
            KernelError::Config(e) => e.code(),
            KernelError::Fieldbus(_) => "kernel.fieldbus",
            KernelError::Servo(_) => "kernel.servo",
            KernelError::Motion(_) => "kernel.motion",
            KernelError::Plc(_) => "kernel.plc",
            KernelError::Executive(_) => "kernel.executive",
            KernelError::SelfTest { .. } => "kernel.self_test",
            KernelError::Program(_) => "kernel.program",
        }
    }
}

/// Options of one kernel instance.
#[derive(Debug, Clone, Default)]
pub struct KernelOptions {
    /// The part program auto mode runs.
    pub program: Option<PathBuf>,
    /// Record every servo cycle (ring of this many samples; drain it often enough).
    pub record_capacity: usize,
    /// Trace events kept per executive thread.
    pub trace_capacity: Option<usize>,
    /// Processor time the interpolation task declares per run on top of its own work:
    /// virtual time charges it, real time spins for it. For load and deadline-miss tests.
    pub interpolation_load: Option<Duration>,
}

/// The result of the power-up self-test.
#[derive(Debug, Clone, Default)]
pub struct SelfTestReport {
    /// Each check and what it found.
    pub checks: Vec<(&'static str, String)>,
}

/// What the operator side holds: channels in, snapshots and faults out.
#[derive(Clone)]
pub struct KernelHandle {
    shared: Shared,
    servo: Arc<PiMutex<ServoStage<SimulatedMachine>>>,
    config: Arc<MachineConfig>,
}

impl KernelHandle {
    /// Sends an urgent command; false when the channel is full.
    pub fn urgent(&self, command: Urgent) -> bool {
        self.shared.urgent.try_put(command).is_ok()
    }

    /// Sends a normal command; false when the channel is full.
    pub fn command(&self, command: Command) -> bool {
        self.shared.normal.try_put(command).is_ok()
    }

    /// The latest status snapshot.
    pub fn status(&self) -> Status {
        self.shared.status.read()
    }

    /// Operator messages (`(MSG,...)`, `(DEBUG,...)`) the machine reached since the last
    /// call, in program order.
    pub fn take_messages(&self) -> Vec<OperatorMessage> {
        std::iter::from_fn(|| self.shared.operator_messages.try_get()).collect()
    }

    /// Faults raised since the last call.
    pub fn take_faults(&self) -> Vec<Fault> {
        std::iter::from_fn(|| self.shared.faults.try_get()).collect()
    }

    /// The last program error in words: the interpreter's or tool compensation's, else the
    /// planner's (a soft limit, a bad arc).
    pub fn error_text(&self) -> Option<String> {
        self.shared.error_text.lock().clone().or_else(|| {
            self.shared
                .motion_error
                .lock()
                .as_ref()
                .map(|e| format!("planner: {e}"))
        })
    }

    /// Acts on the simulated machine (press the e-stop, turn the handwheel, inject faults).
    pub fn with_machine<R>(&self, f: impl FnOnce(&mut SimulatedMachine) -> R) -> R {
        f(&mut self.servo.lock().bus)
    }

    /// Servo periods in which position control had no fresh set-point (real-time overruns
    /// of interpolation) and extrapolated.
    pub fn setpoint_underruns(&self) -> u64 {
        self.servo.lock().underruns()
    }

    /// The configuration.
    pub fn config(&self) -> &MachineConfig {
        &self.config
    }

    /// A joint's configured name.
    pub fn joint_name(&self, joint: usize) -> String {
        self.config
            .joints
            .get(joint)
            .map_or_else(|| format!("#{joint}"), |j| j.name.clone())
    }

    /// A fault in words, with the joint's name.
    pub fn describe(&self, fault: &Fault) -> String {
        fault.describe(|j| self.joint_name(j))
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
    /// Builds the kernel for a validated configuration on the simulated machine, runs the
    /// power-up self-test (configuration, drive communication, I/O, persistent files) and
    /// declares the task graph.
    pub fn build(config: &MachineConfig, options: KernelOptions) -> Result<Kernel, KernelError> {
        config.validate()?;
        let config = Arc::new(config.clone());
        let threads = config.tasks_checked()?;
        let period = threads[0].1;
        let period_s = period.as_secs_f64();
        let mut report = SelfTestReport::default();
        report.checks.push(("configuration", "valid".into()));

        // Persistent files.
        let (parameters, tools) = persistent_files(&config, &mut report)?;

        // Drive communication and I/O.
        let sim = config
            .simulated_machine()
            .map_err(|e| KernelError::Fieldbus(e.to_string()))?;
        let mut machine =
            SimulatedMachine::new(&sim).map_err(|e| KernelError::Fieldbus(e.to_string()))?;
        self_test_bus(&mut machine, &config, period_s, &mut report)?;

        let loops = config
            .joints
            .iter()
            .enumerate()
            .map(|(j, jc)| {
                ServoLoop::new(j, &jc.servo)
                    .map_err(|e| KernelError::Servo(format!("joints[{j}].servo.{}", e)))
            })
            .collect::<Result<Vec<_>, _>>()?;

        let (shared, writers) = Shared::new();
        let (target_tx, target_rx) = rtcnc_rt::ring::<ServoTarget>("set-points", 4)
            .map_err(|e| KernelError::Executive(e.to_string()))?;
        let (recorder, samples) = if options.record_capacity > 0 {
            let (tx, rx) = rtcnc_rt::ring::<Sample>("samples", options.record_capacity)
                .map_err(|e| KernelError::Executive(e.to_string()))?;
            (Some(tx), Some(rx))
        } else {
            (None, None)
        };
        let servo = Arc::new(PiMutex::new(
            ServoStage::new(
                machine,
                loops,
                period_s,
                target_rx,
                recorder,
                shared.clone(),
                writers.feedback,
                config.io.program_outputs.clone(),
            )
            .with_program_analog_outputs(config.io.program_analog_outputs.clone()),
        ));

        let mut core = MotionCore::new(&config, &shared, writers.requests)
            .map_err(|e| KernelError::Motion(e.to_string()))?;
        core.set_has_program(options.program.is_some());
        core.set_ready(true);
        let core = Arc::new(PiMutex::new(core));

        let logic = match &config.plc {
            None => Logic::Direct,
            Some(plc) => {
                let path = config.resolve(&plc.program);
                let mut runtime = crate::logic::load_plc(&path, &plc.signals, &plc.safe_values)
                    .map_err(|e| KernelError::Plc(format!("{}: {e}", path.display())))?;
                report
                    .checks
                    .push(("machine logic", format!("{} compiled", path.display())));
                if let Some(file) = &config.files.plc_retain {
                    let file = config.resolve(file);
                    let restored = runtime
                        .load_retain(&file)
                        .map_err(|e| KernelError::Plc(format!("{}: {e}", file.display())))?;
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
                Logic::Plc(Box::new(runtime))
            }
        };
        let retain = match (&logic, &config.files.plc_retain) {
            (Logic::Plc(runtime), Some(file)) => {
                let file = config.resolve(file);
                Some((Arc::new(PiMutex::new(runtime.retain_snapshot())), file))
            }
            _ => None,
        };
        let mut logic = LogicStage::new(
            shared.clone(),
            logic,
            writers.logic_outputs,
            config.tool_changer.is_some(),
        );
        if let Some((snapshot, _)) = &retain {
            logic = logic.with_retain(Arc::clone(snapshot));
        }

        // The interpreter stops reading after M66 (and G38) until the machine's result is
        // in, as LinuxCNC's task synchronises before such a block.
        let mut settings = Settings {
            wait_for_machine: true,
            ..Settings::default()
        };
        if config.machine.units == LengthUnits::Inch {
            settings.initial_units = rtcnc_gcode::canon::Units::Inches;
        }
        let mut interpreter = InterpreterStage::new(
            shared.clone(),
            options.program.clone(),
            settings,
            tools,
            parameters,
            config.machine.diameter_mode,
        )
        .with_parameter_file(config.files.parameters.as_ref().map(|p| config.resolve(p)));
        let mut compensation =
            CompensationStage::new(shared.clone(), config.motion.default_blend_tolerance);

        let mut b = TaskSet::builder();
        if let Some(capacity) = options.trace_capacity {
            b.trace_capacity(capacity);
        }
        let t = &config.tasks;
        let miss = miss_reaction(config.safety.deadline_miss, &shared);
        let thread = |b: &mut rtcnc_rt::TaskSetBuilder, name: &str, i: usize| {
            b.periodic_thread(name, threads[i].1, threads[i].2.priority)
        };

        let fieldbus = thread(&mut b, "fieldbus", 0);
        let s = servo.clone();
        let id = b.periodic(fieldbus, "position control", 1, move |ctx| {
            s.lock().position_control(ctx)
        });
        b.on_deadline_miss(id, miss.clone());
        let s = servo.clone();
        let id = b.periodic(fieldbus, "drive io", 1, move |ctx| s.lock().drive_io(ctx));
        b.on_deadline_miss(id, miss.clone());

        let th = thread(&mut b, "machine logic", 1);
        let id = b.periodic(th, "machine logic", t.machine_logic.runs, move |ctx| {
            if ctx.run() == 0 {
                logic.scan(ctx);
            }
            // One scan per activation, whatever `runs` says.
            ctx.finish_runs();
        });
        b.on_deadline_miss(id, miss.clone());

        let th = if t.interpolation_in_fieldbus_thread(period) {
            fieldbus
        } else {
            thread(&mut b, "interpolation", 2)
        };
        let (c, sh) = (core.clone(), shared.clone());
        let mut target_tx = target_tx;
        let load = options.interpolation_load;
        let id = b.periodic(th, "interpolation", 1, move |ctx| {
            c.lock().interpolate(ctx, &sh, &mut target_tx);
            if let Some(load) = load {
                ctx.consume(load);
            }
        });
        b.on_deadline_miss(id, miss.clone());

        let th = thread(&mut b, "look-ahead", 3);
        let (c, sh) = (core.clone(), shared.clone());
        let mut more = false;
        let id = b.periodic(th, "look-ahead", t.look_ahead.runs, move |ctx| {
            // The runs after the first only when the one before stopped at its bound of
            // steps, not on something only another task can change.
            if ctx.run() == 0 || more {
                more = c.lock().look_ahead(ctx, &sh);
            }
            if !more {
                ctx.finish_runs();
            }
        });
        b.on_deadline_miss(id, miss.clone());

        let th = thread(&mut b, "command parsing", 4);
        let (c, sh) = (core.clone(), shared.clone());
        let id = b.periodic(th, "command parsing", t.command_parsing.runs, move |ctx| {
            // The urgent channel is read before this, at the start of every interpolation
            // cycle; here the normal one, a command per run until it is empty.
            // Drained: the remaining runs of this period are not made.
            match sh.normal.try_get() {
                Some(command) => {
                    c.lock().command(ctx, &sh, command);
                }
                None => ctx.finish_runs(),
            }
        });
        b.on_deadline_miss(id, miss.clone());

        let th = thread(&mut b, "status feedback", 5);
        let (c, sh) = (core.clone(), shared.clone());
        let mut feedback = Snapshot::new(shared.feedback.clone());
        let mut status_out = writers.status;
        let mut status = status_out.value();
        let id = b.periodic(th, "status feedback", t.status_feedback.runs, move |ctx| {
            ctx.finish_runs();
            if ctx.run() != 0 {
                return;
            }
            c.lock()
                .status(feedback.get(), ctx.now().as_nanos(), &mut status);
            status.fault_count = sh.fault_count.load(std::sync::atomic::Ordering::Relaxed);
            status_out.publish(status);
        });
        b.on_deadline_miss(id, miss);

        let sh = shared.clone();
        b.event(
            "tool compensation",
            t.tool_compensation.priority,
            sh.program_blocks.data_trigger(),
            move |ctx| compensation.body(ctx),
        );
        b.event(
            "interpreter",
            t.interpreter.priority,
            shared.interpreter_wake.trigger(),
            move |ctx| interpreter.body(ctx),
        );
        // Background checks while running, in what time is left: the drive exchange still
        // advances, the persistent files' folders are still there and writable.
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
        // The RETAIN values are written here, off the real-time tasks, when they changed.
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
                            crate::FaultCode::BackgroundCheck,
                            crate::TaskName::BackgroundCheck,
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
                    crate::FaultCode::BackgroundCheck,
                    crate::TaskName::BackgroundCheck,
                    None,
                    0,
                    if stalled { 1.0 } else { 2.0 },
                );
            }
            reported = stalled || folder_bad;
            rtcnc_rt::Next::Sleep(Duration::from_millis(500))
        });
        let tasks = b
            .build()
            .map_err(|e| KernelError::Executive(e.to_string()))?;
        report.checks.push(("ready", "self-test passed".into()));
        Ok(Kernel {
            tasks,
            handle: KernelHandle {
                shared,
                servo,
                config,
            },
            samples,
            self_test: report,
        })
    }
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

fn persistent_files(
    config: &MachineConfig,
    report: &mut SelfTestReport,
) -> Result<(Parameters, ToolTable), KernelError> {
    let parameters = match &config.files.parameters {
        None => Parameters::new(),
        Some(p) => {
            let path = config.resolve(p);
            if path.exists() {
                let params = Parameters::load(&path).map_err(|e| KernelError::SelfTest {
                    check: "parameter file",
                    reason: format!("{}: {e}", path.display()),
                })?;
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
            let tools = ToolTable::load(&path).map_err(|e| KernelError::SelfTest {
                check: "tool table",
                reason: format!("{}: {e}", path.display()),
            })?;
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
    let meta = std::fs::metadata(folder).map_err(|e| KernelError::SelfTest {
        check,
        reason: format!("{}: {e}", folder.display()),
    })?;
    if meta.permissions().readonly() {
        return Err(KernelError::SelfTest {
            check,
            reason: format!("{} is read-only", folder.display()),
        });
    }
    Ok(())
}

/// Drive communication and I/O: one exchange with the drives disabled; every configured
/// joint and I/O point must answer, no drive may be faulted.
fn self_test_bus(
    machine: &mut SimulatedMachine,
    config: &MachineConfig,
    period_s: f64,
    report: &mut SelfTestReport,
) -> Result<(), KernelError> {
    let layout = machine.layout().clone();
    if layout.joints.len() != config.joints.len() {
        return Err(KernelError::SelfTest {
            check: "drive communication",
            reason: format!(
                "{} drives answer, {} are configured",
                layout.joints.len(),
                config.joints.len()
            ),
        });
    }
    let outputs = rtcnc_fieldbus::ProcessOutputs::new(&layout);
    let mut inputs = rtcnc_fieldbus::ProcessInputs::new(&layout);
    machine
        .exchange(period_s, &outputs, &mut inputs)
        .map_err(|e| KernelError::SelfTest {
            check: "drive communication",
            reason: e.to_string(),
        })?;
    if let Some(j) = inputs.joints.iter().position(|f| f.state().is_fault()) {
        return Err(KernelError::SelfTest {
            check: "drive communication",
            reason: format!("drive {} reports a fault", config.joints[j].name),
        });
    }
    report.checks.push((
        "drive communication",
        format!("{} drives answer", layout.joints.len()),
    ));
    if layout.digital_inputs != config.io.digital_inputs
        || layout.digital_outputs != config.io.digital_outputs
    {
        return Err(KernelError::SelfTest {
            check: "i/o",
            reason: "the process image does not match the configuration".into(),
        });
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
