//! The motion kernel under random sequences of operator commands, urgent commands and
//! machine faults, on the simulated mill with its machine logic (examples/plc/mill.st), in
//! virtual time. The input's bytes choose a program and the sequence; after every servo
//! period the harness checks from outside the kernel, on the set-points it records and on
//! the simulated load, that
//!
//! - the limits are kept: every axis' set-point velocity within its `max_velocity`, its
//!   acceleration within `max_acceleration` and its jerk within `max_jerk` (within
//!   `quick_stop_acceleration` and `quick_stop_jerk` while an e-stop or an abort stops
//!   it), its position within the soft limits once homed;
//! - a hold holds: after a feed hold, once the path has had the time to decelerate, no axis
//!   moves until the operator releases it (resume, cycle start, abort, e-stop, reset, a
//!   jog, homing), whatever else arrives (MDI lines, program starts, machine functions);
//! - nothing stalls without a fault: a program that runs (not held, paused, waiting for
//!   the machine logic, or at a zero override) makes progress within the stall watchdog's
//!   time plus the programs' longest dwell;
//! - every fault that stops the machine reaches the safe state: the load stands, the drives
//!   are off (as the simulated drives know it) and the machine is in e-stop or fault within the worst bound of
//!   docs/safety.md's matrix, and the load stays there until a reset.
//!
//! A broken invariant panics with the operations that led to it.

use std::path::PathBuf;
use std::sync::{Arc, OnceLock};

use arbitrary::Unstructured;
use rtcnc_fieldbus::Cia402State;
use rtcnc_fieldbus::sim::InjectedFault;
use rtcnc_kernel::{
    Command, FixedText, Kernel, KernelOptions, MachineConfig, MachineState, Sample, Simulation,
    Status, Urgent,
};

/// Machine time one input may run (periods of 1 ms), operations and settling included.
const MAX_PERIODS: u64 = 3000;
/// The stall watchdog of the fuzzed machine (shorter than the default: short inputs).
const STALL_TIMEOUT_S: f64 = 0.4;
/// The longest standstill of a running program below: its dwells and input waits.
const LONGEST_WAIT_S: f64 = 0.3;
/// A hold has stopped the path once the set-points have stood this many periods (after
/// the set-point lead: what was computed before the hold still runs out).
const HOLD_STANDING_PERIODS: u32 = 3;
/// From a fault to the safe state: docs/safety.md's worst bound (fieldbus loss, 295 ms)
/// with room for the periods a fault needs to be noticed at lower speeds.
const SAFE_STATE_S: f64 = 0.35;
/// A reset is taken within this time of being sent (behind at most a full command
/// mailbox: 64 commands, taken four a period).
const RESET_TAKEN_S: f64 = 0.05;
/// A load slower than this (mm/s) for `STANDING_PERIODS` periods stands; from then on it
/// may creep no further than `STAYS_WITHIN` (mm): a coasting load's last micrometre.
const STANDING_VELOCITY: f64 = 1e-4;
const STANDING_PERIODS: u32 = 10;
const STAYS_WITHIN: f64 = 1e-3;
/// Axes checked (X, Y, Z of the mill).
const AXES: usize = 3;

/// Programs the kernel may be given: every waiting state, blending, arcs, canned cycles,
/// splines, probing. The input's first byte chooses one, modulo 7 (6: none); adding a
/// program changes that modulus, so the kept defect inputs' first bytes are rewritten to
/// keep their choice.
const PROGRAMS: &[&str] = &[
    "G21 G90 G64 P0.02\nG1 X5 Y2 F3000\nT2 M6\nS8000 M3\nG4 P0.3\nG1 X20 Y10\n\
     M66 P0 L3 Q0.3\nG2 X30 Y20 I5 J5\nM100 P0.1\nM1\nG0 Z-2\nM0\nG1 X5\nM5\nM30\n",
    "G21 G90 G64\nG0 X2 Y2\nG1 Z-1 F600\nG1 X3 Y2.2 F4000\nX4 Y2.1\nX5 Y2.6\nX6 Y2.4\n\
     X7 Y3\nG3 X9 Y5 R2\nG1 X9.2 Y5.1\nX9.3 Y5.4\nG2 X12 Y5.4 I1.35 J0\nG0 Z2\nM2\n",
    "G21 G90 G17\nG0 X10 Y10 Z2\nS3000 M3\nG81 R1 Z-3 F900\nX14\nY14\nG83 R1 Z-6 Q1.5\n\
     X10\nG80\nG0 Z5\nM5\nM2\n",
    "G20 G91\nG1 X0.2 Y0.1 F200\nG2 X0.2 Y0 I0.1 J0 P2\nG90 G0 X0 Y0\nM2\n",
    // Cubic and quadratic splines blended in G64 P, one that closes on itself.
    "G21 G90 G64 P0.01\nG0 X5 Y5 Z0\nG1 F2000\nG5 I5 J0 P-5 Q0 X20 Y10\nG5 P-5 Q-5 X35 Y5\n\
     G5.1 I5 J5 X45 Y10\nG5 I0 J10 P0 Q-10 X45 Y10\nG0 Z5\nM2\n",
    // Probing the workpiece top (Z-50): down to contact, up until it breaks, a move that
    // stops short of it.
    "G21 G90\nG0 X10 Y10 Z-45\nG38.2 Z-60 F300\nG38.4 Z-45 F100\nG0 Z-40\n\
     G38.3 Z-48 F300\nG0 Z0\nM2\n",
];

/// MDI lines the operator may type.
const MDI_LINES: &[&str] = &[
    "G0 X10 Y10",
    "G1 X20 F1200",
    "G91 G1 Y-5 F2000",
    "G90",
    "T3 M6",
    "S6000 M4",
    "M5",
    "G4 P0.2",
    "M66 P0 L3 Q0.2",
    "G2 X0 Y0 I5 J0 F900",
    "G0 X400",
    "G1 X",
    "M0",
];

struct Fixture {
    config: MachineConfig,
    /// The machine logic, compiled once for every kernel built.
    plc_program: Arc<rtcnc_plc::Program>,
    programs: Vec<PathBuf>,
}

fn fixture() -> &'static Fixture {
    static FIXTURE: OnceLock<Fixture> = OnceLock::new();
    FIXTURE.get_or_init(|| {
        let configs = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../configs");
        let text = std::fs::read_to_string(configs.join("sim-mill.toml"))
            .expect("configs/sim-mill.toml")
            .replacen(
                "[safety]\n",
                &format!(
                    "[safety]\nstall_timeout = \"{}ms\"\n",
                    STALL_TIMEOUT_S * 1000.0
                ),
                1,
            );
        let mut config = MachineConfig::parse(&text, "sim-mill.toml").expect("sim-mill parses");
        config.base_dir = configs;
        let plc = config.plc.as_ref().expect("the mill has machine logic");
        let plc_program =
            Arc::new(rtcnc_plc::compile_file(&config.resolve(&plc.program)).expect("mill.st"));
        let dir = std::env::temp_dir().join(format!("rtcnc-fuzz-kernel-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("a temporary folder");
        let programs = PROGRAMS
            .iter()
            .enumerate()
            .map(|(i, text)| {
                let path = dir.join(format!("program{i}.ngc"));
                std::fs::write(&path, text).expect("program written");
                path
            })
            .collect();
        Fixture {
            config,
            plc_program,
            programs,
        }
    })
}

/// The longest a feed hold may take to stop the path: the set-point lead, then from the
/// fastest path (every axis at its top speed) still accelerating at the axes' limits, the
/// planner's hold profile (50 % of the slowest axis' deceleration and jerk, docs/motion.md):
/// the acceleration brought down, the speed braked, the landing; with 10 % and 20 periods
/// of room.
fn hold_bound(config: &MachineConfig) -> f64 {
    let axes = ["x", "y", "z"].map(|name| config.axes.get(name).expect("the mill's axes"));
    let norm = |f: fn(&rtcnc_kernel::config::AxisConfig) -> f64| {
        axes.iter().map(|a| f(a).powi(2)).sum::<f64>().sqrt()
    };
    let slowest = |f: fn(&rtcnc_kernel::config::AxisConfig) -> f64| {
        axes.iter().map(|a| f(a)).fold(f64::INFINITY, f64::min)
    };
    let (speed, acceleration) = (norm(|a| a.max_velocity), norm(|a| a.max_acceleration));
    let hold_a = 0.5 * slowest(|a| a.max_acceleration);
    let hold_j = 0.5 * slowest(|a| a.max_jerk);
    let period = config.servo_period().as_secs_f64();
    let lead = config
        .tasks
        .setpoint_lead_periods(config.servo_period())
        .expect("the mill's set-point lead") as f64
        * period;
    let stop = acceleration / hold_j + speed / hold_a + hold_a / hold_j;
    lead + 1.1 * stop + 20.0 * period
}

/// One step of the sequence.
#[derive(Debug, Clone, Copy)]
enum Op {
    Run(u64),
    Urgent(Urgent),
    Command(Command),
    Inject(InjectedFault),
    Clear(InjectedFault),
    EStopButton(bool),
    Door(bool),
    Input(usize, bool),
    Handwheel(i64),
}

/// A number the operator (or a broken client) might send: mostly sensible, sometimes at
/// the ends of the range or not a number at all.
fn number(u: &mut Unstructured, sensible: f64) -> arbitrary::Result<f64> {
    Ok(match u.int_in_range(0..=15u8)? {
        0 => f64::NAN,
        1 => f64::INFINITY,
        2 => -f64::INFINITY,
        3 => 1e30,
        4 => -sensible * 3.0,
        5 => sensible * 3.0,
        _ => (u.int_in_range(-1000..=1000i32)? as f64) / 1000.0 * sensible,
    })
}

fn op(u: &mut Unstructured) -> arbitrary::Result<Op> {
    let axis = |u: &mut Unstructured| -> arbitrary::Result<u8> {
        Ok(if u.ratio(1, 16)? {
            9
        } else {
            u.int_in_range(0..=2)?
        })
    };
    Ok(match u.int_in_range(0..=23u8)? {
        0..=5 => Op::Run(u.int_in_range(1..=300u64)?),
        6 => Op::Urgent(Urgent::FeedHold),
        7 => Op::Urgent(Urgent::Resume),
        8 => Op::Urgent(Urgent::Abort),
        9 => Op::Urgent(Urgent::EStop),
        10 => Op::Urgent(match u.int_in_range(0..=2u8)? {
            0 => Urgent::FeedOverride(number(u, 2.0)?),
            1 => Urgent::RapidOverride(number(u, 1.0)?),
            _ => Urgent::SpindleOverride(number(u, 1.5)?),
        }),
        11 => Op::Command(Command::Reset),
        12 => Op::Command(Command::Start {
            from_line: u.int_in_range(0..=14)?,
        }),
        13 => Op::Command(Command::Mdi(FixedText::truncated(
            MDI_LINES[u.choose_index(MDI_LINES.len())?],
        ))),
        14 => Op::Command(Command::JogContinuous {
            axis: axis(u)?,
            velocity: number(u, 100.0)?,
        }),
        15 => Op::Command(Command::JogIncrement {
            axis: axis(u)?,
            distance: number(u, 10.0)?,
        }),
        16 => Op::Command(Command::JogStop { axis: axis(u)? }),
        17 => Op::Command(match u.int_in_range(0..=5u8)? {
            0 => Command::HomeAll,
            1 => Command::Handwheel {
                axis: if u.arbitrary()? { Some(axis(u)?) } else { None },
                scale: number(u, 10.0)?,
            },
            2 => Command::JointMove {
                joint: u.int_in_range(0..=3)?,
                position: number(u, 10.0)?,
            },
            3 => Command::SingleBlock(u.arbitrary()?),
            4 => Command::OptionalStop(u.arbitrary()?),
            _ => Command::BlockDelete(u.arbitrary()?),
        }),
        18 | 19 => {
            let fault = match u.int_in_range(0..=3u8)? {
                0 => InjectedFault::DriveFault {
                    joint: u.int_in_range(0..=2)?,
                    error_code: 0x2310,
                },
                1 => InjectedFault::EncoderLoss {
                    joint: u.int_in_range(0..=2)?,
                },
                2 => InjectedFault::CommunicationLoss,
                _ => InjectedFault::StuckInput {
                    input: u.int_in_range(0..=15)?,
                    value: u.arbitrary()?,
                },
            };
            if u.ratio(1, 3)? {
                Op::Clear(fault)
            } else {
                Op::Inject(fault)
            }
        }
        20 => Op::EStopButton(u.arbitrary()?),
        21 => Op::Door(u.arbitrary()?),
        22 => Op::Input(u.int_in_range(8..=11)?, u.arbitrary()?),
        _ => Op::Handwheel(u.int_in_range(-50..=50)?),
    })
}

/// What the harness knows of the machine from the commands it gave and what it saw.
struct Harness {
    sim: Simulation,
    ops: Vec<Op>,
    period_s: f64,
    max_velocity: [f64; AXES],
    max_acceleration: [f64; AXES],
    quick_stop_acceleration: [f64; AXES],
    max_jerk: [f64; AXES],
    quick_stop_jerk: [f64; AXES],
    previous_acceleration: Option<[f64; AXES]>,
    soft_limits: [(f64, f64); AXES],
    /// The last two recorded set-points (for velocity and acceleration).
    previous: Option<Sample>,
    previous_velocity: Option<[f64; AXES]>,
    /// An e-stop or an abort stops the path with the quick-stop limits until it stands.
    quick_stopping: bool,
    /// A feed hold is in force since this time (s), and where the axes stood once it
    /// settled.
    hold_since: Option<f64>,
    held_at: Option<[f64; AXES]>,
    /// The longest a hold may take to stop the path (s), and the set-point lead (s).
    hold_bound: f64,
    setpoint_lead: f64,
    /// Periods the set-points have stood still.
    standing_setpoints: u32,
    /// The first fault that stops the machine since the last reset (time, s), and where
    /// the load stood once in the safe state.
    fault_since: Option<f64>,
    safe_at: Option<[f64; AXES]>,
    /// When the last reset was sent (ns): a fault raised before then is cleared by it.
    reset_ns: Option<u64>,
    /// Periods the load has stood in the safe state.
    standing_periods: u32,
    /// The last time the running program made progress, and what it was.
    progress_at: f64,
    progress: (Status, [f64; AXES]),
    rapid_override: f64,
    /// A saved input replayed with RTCNC_FUZZ_TRACE=1 prints the operations, with 2 every
    /// period's set-points too.
    trace: u8,
}

fn axes_of(s: &Sample) -> [f64; AXES] {
    [s.axes[0], s.axes[1], s.axes[2]]
}

impl Harness {
    fn new(program: Option<PathBuf>) -> Harness {
        let config = &fixture().config;
        let kernel = Kernel::build(
            config,
            KernelOptions {
                program,
                plc_program: Some(Arc::clone(&fixture().plc_program)),
                // Drained after every period; the executive's trace is not read.
                record_capacity: 16,
                trace_capacity: Some(16),
                ..KernelOptions::default()
            },
        )
        .expect("the mill builds");
        let sim = Simulation::new(kernel);
        let axis = |i: usize| {
            let name = ["x", "y", "z"][i];
            config.axes.get(name).expect("the mill has X, Y, Z")
        };
        let status = sim.handle().status();
        Harness {
            period_s: sim.period().as_secs_f64(),
            max_velocity: std::array::from_fn(|i| axis(i).max_velocity),
            max_acceleration: std::array::from_fn(|i| axis(i).max_acceleration),
            quick_stop_acceleration: std::array::from_fn(|i| {
                axis(i)
                    .quick_stop_acceleration
                    .unwrap_or(axis(i).max_acceleration)
            }),
            max_jerk: std::array::from_fn(|i| axis(i).max_jerk),
            quick_stop_jerk: std::array::from_fn(|i| {
                axis(i).quick_stop_jerk.unwrap_or(axis(i).max_jerk)
            }),
            previous_acceleration: None,
            soft_limits: std::array::from_fn(|i| (axis(i).min_position, axis(i).max_position)),
            sim,
            ops: Vec::new(),
            previous: None,
            previous_velocity: None,
            quick_stopping: false,
            hold_since: None,
            held_at: None,
            hold_bound: hold_bound(config),
            setpoint_lead: config
                .tasks
                .setpoint_lead_periods(config.servo_period())
                .expect("the mill's set-point lead") as f64
                * config.servo_period().as_secs_f64(),
            standing_setpoints: 0,
            fault_since: None,
            safe_at: None,
            reset_ns: None,
            standing_periods: 0,
            progress_at: 0.0,
            progress: (status, [0.0; AXES]),
            rapid_override: 1.0,
            trace: std::env::var("RTCNC_FUZZ_TRACE")
                .ok()
                .and_then(|v| v.parse().ok())
                .unwrap_or(0),
        }
    }

    fn now(&self) -> f64 {
        self.sim.now().as_secs_f64()
    }

    fn broken(&self, what: String) -> ! {
        panic!(
            "invariant broken at t = {:.3} s: {what}\nstatus: {:?}\noperations: {:?}",
            self.now(),
            self.sim.handle().status(),
            self.ops
        );
    }

    fn load(&self) -> [(f64, f64); AXES] {
        self.sim
            .handle()
            .simulated_machine()
            .expect("simulated")
            .with(|m| std::array::from_fn(|j| m.true_state(j).expect("the mill's joints")))
    }

    /// Every drive of the mill holds no torque (not in operation enabled or quick stop).
    fn drives_off(&self) -> bool {
        self.machine(|m| {
            (0..AXES).all(|j| {
                !matches!(
                    m.drive_state(j),
                    Some(Cia402State::OperationEnabled | Cia402State::QuickStopActive)
                )
            })
        })
    }

    fn machine<R>(&self, f: impl FnOnce(&mut rtcnc_fieldbus::sim::SimulatedMachine) -> R) -> R {
        self.sim
            .handle()
            .simulated_machine()
            .expect("simulated")
            .with(f)
    }

    fn apply(&mut self, op: Op) {
        if self.trace > 0 {
            eprintln!("t {:.3} s: {op:?}", self.now());
        }
        self.ops.push(op);
        let handle = self.sim.handle();
        match op {
            Op::Run(periods) => {
                for _ in 0..periods {
                    self.period();
                }
            }
            Op::Urgent(urgent) => {
                // A full urgent channel refuses the command (the operator's key does
                // nothing): the model follows what the kernel took.
                if !handle.urgent(urgent) {
                    return;
                }
                match urgent {
                    // In e-stop or fault the kernel latches no hold (it would outlive the
                    // reset that must follow; docs/kernel.md), also when resets sent before
                    // it wait in the command mailbox: the urgent hold overtakes them.
                    Urgent::FeedHold
                        if matches!(
                            handle.status().state,
                            MachineState::EStop | MachineState::Fault
                        ) => {}
                    Urgent::FeedHold => {
                        if self.hold_since.is_none() {
                            self.hold_since = Some(self.now());
                        }
                    }
                    Urgent::Resume => self.release_hold(),
                    Urgent::Abort | Urgent::EStop => {
                        self.release_hold();
                        self.quick_stopping = true;
                    }
                    // As the kernel takes it: a value that is not a number is 0 %.
                    Urgent::RapidOverride(v) => {
                        self.rapid_override = if v.is_finite() {
                            v.clamp(0.0, 1.0)
                        } else {
                            0.0
                        };
                    }
                    _ => {}
                }
            }
            Op::Command(command) => {
                if !handle.command(command) {
                    return;
                }
                match command {
                    Command::Reset => {
                        self.reset_ns = Some(self.sim.now().as_nanos() as u64);
                        self.release_hold();
                        self.fault_since = None;
                        self.safe_at = None;
                        self.standing_periods = 0;
                    }
                    // The operator's own motions and the cycle start release a hold.
                    Command::Start { .. }
                    | Command::JogContinuous { .. }
                    | Command::JogIncrement { .. }
                    | Command::Handwheel { .. }
                    | Command::HomeAll
                    | Command::JointMove { .. } => self.release_hold(),
                    _ => {}
                }
            }
            Op::Inject(fault) => {
                let _ = self.machine(|m| m.inject(fault));
            }
            Op::Clear(fault) => {
                let _ = self.machine(|m| m.clear(fault));
            }
            Op::EStopButton(pressed) => self.machine(|m| m.set_estop(pressed)),
            Op::Door(open) => {
                let _ = self.machine(|m| m.set_door_open(open));
            }
            Op::Input(input, value) => {
                let _ = self.machine(|m| m.set_digital_input(input, value));
            }
            Op::Handwheel(detents) => {
                self.machine(|m| m.turn_handwheel(detents));
                // Turning the wheel is the operator's own motion.
                self.release_hold();
            }
        }
    }

    /// Nothing left to check: no program or manual motion runs, the set-points stand (or
    /// the drives are off), a hold has settled and been seen to hold, a fault has reached
    /// the safe state.
    fn at_rest(&self) -> bool {
        let status = self.sim.handle().status();
        let standing = !status.ready
            || self
                .previous_velocity
                .is_some_and(|v| v.iter().all(|v| *v == 0.0));
        !matches!(status.state, MachineState::Running | MachineState::Starting)
            && standing
            && (self.hold_since.is_none() || self.held_at.is_some())
            && (self.fault_since.is_none() || self.safe_at.is_some())
    }

    fn release_hold(&mut self) {
        self.hold_since = None;
        self.held_at = None;
    }

    /// One servo period, then every invariant.
    fn period(&mut self) {
        let mut samples = Vec::with_capacity(2);
        self.sim
            .run_cycles(1, &mut |s| samples.push(*s))
            .expect("the virtual executive runs");
        let now = self.now();
        let status = self.sim.handle().status();
        for fault in self.sim.handle().take_faults() {
            if self.trace > 0 {
                eprintln!("t {now:.3} s: fault {fault:?}");
            }
            let cleared = self.reset_ns.is_some_and(|reset| fault.time_ns < reset);
            if fault.code.stops_machine() && !cleared && self.fault_since.is_none() {
                self.fault_since = Some(now);
                self.release_hold();
            }
            // A fault that stops the machine stops it with the quick-stop limits, even
            // when a reset queued before it is taken to have cleared it (the e-stop chain
            // opened by a stuck input as a reset was sent: the status still showed the
            // state before the e-stop, the model let the reset clear the fault and held the
            // quick stop to the normal limits).
            if fault.code.stops_machine() {
                self.quick_stopping = true;
            }
        }
        // A reset waits behind the commands sent before it: a fault raised after it was
        // sent but before it was taken is cleared by it too, and the machine then leaves
        // e-stop or fault, which nothing but a reset does.
        let reset_queued = self
            .reset_ns
            .is_some_and(|reset| now - reset as f64 * 1e-9 <= RESET_TAKEN_S);
        if reset_queued
            && self.fault_since.is_some()
            && !matches!(status.state, MachineState::EStop | MachineState::Fault)
        {
            self.fault_since = None;
            self.safe_at = None;
            self.standing_periods = 0;
        }
        for sample in &samples {
            let standing = self
                .previous
                .is_some_and(|p| axes_of(&p) == axes_of(sample));
            self.standing_setpoints = if standing {
                self.standing_setpoints.saturating_add(1)
            } else {
                0
            };
            if self.trace > 1 {
                eprintln!(
                    "  t {now:.3} s: {:?} {:?} {:?}",
                    axes_of(sample),
                    status.state,
                    self.previous_velocity
                );
            }
            self.limits(sample, &status);
            self.previous = Some(*sample);
        }
        self.hold_holds();
        self.no_stall(&status);
        self.safe_state(&status);
    }

    fn limits(&mut self, sample: &Sample, status: &Status) {
        let axes = axes_of(sample);
        let Some(previous) = self.previous else {
            return;
        };
        // Drives off or stopping for a fault: the set-points follow the load.
        if !status.ready || self.fault_since.is_some() {
            self.previous_velocity = None;
            self.previous_acceleration = None;
            return;
        }
        let before = axes_of(&previous);
        let velocity: [f64; AXES] = std::array::from_fn(|i| (axes[i] - before[i]) / self.period_s);
        for i in 0..AXES {
            if velocity[i].abs() > self.max_velocity[i] * (1.0 + 1e-6) + 1e-9 {
                self.broken(format!(
                    "axis {i} at {} mm/s, above its {} mm/s",
                    velocity[i], self.max_velocity[i]
                ));
            }
        }
        let mut accelerations = None;
        if let Some(v0) = self.previous_velocity {
            let acceleration: [f64; AXES] =
                std::array::from_fn(|i| (velocity[i] - v0[i]) / self.period_s);
            for i in 0..AXES {
                let limit = if self.quick_stopping {
                    self.quick_stop_acceleration[i]
                } else {
                    self.max_acceleration[i]
                };
                if acceleration[i].abs() > limit * (1.0 + 1e-6) + 1e-6 {
                    self.broken(format!(
                        "axis {i} accelerates at {} mm/s², above its {limit} mm/s²",
                        acceleration[i]
                    ));
                }
            }
            if let Some(a0) = self.previous_acceleration {
                for i in 0..AXES {
                    let limit = if self.quick_stopping {
                        self.quick_stop_jerk[i]
                    } else {
                        self.max_jerk[i]
                    };
                    let jerk = (acceleration[i] - a0[i]) / self.period_s;
                    if jerk.abs() > limit * (1.0 + 1e-6) + 1e-3 {
                        self.broken(format!(
                            "axis {i} jerks at {jerk} mm/s³, above its {limit} mm/s³"
                        ));
                    }
                }
            }
            accelerations = Some(acceleration);
        }
        self.previous_acceleration = accelerations;
        if velocity.iter().all(|v| *v == 0.0) {
            self.quick_stopping = false;
        }
        self.previous_velocity = Some(velocity);
        if status.homed & 0b111 == 0b111 {
            for (i, (min, max)) in self.soft_limits.iter().enumerate() {
                if axes[i] < min - 1e-9 || axes[i] > max + 1e-9 {
                    self.broken(format!("axis {i} at {} outside [{min}, {max}]", axes[i]));
                }
            }
        }
    }

    fn hold_holds(&mut self) {
        let Some(since) = self.hold_since else {
            return;
        };
        let Some(sample) = self.previous else {
            return;
        };
        let axes = axes_of(&sample);
        let held_for = self.now() - since;
        match self.held_at {
            None if held_for > self.setpoint_lead
                && self.standing_setpoints >= HOLD_STANDING_PERIODS =>
            {
                self.held_at = Some(axes)
            }
            None if held_for > self.hold_bound => self.broken(format!(
                "a feed hold since t = {since:.3} s, and the axes still move after {:.3} s",
                self.hold_bound
            )),
            Some(held) if held != axes => self.broken(format!(
                "a feed hold since t = {since:.3} s, yet the axes moved from {held:?} to {axes:?}"
            )),
            _ => {}
        }
    }

    fn no_stall(&mut self, status: &Status) {
        let axes = self.previous.map(|s| axes_of(&s)).unwrap_or([0.0; AXES]);
        let (was, was_axes) = &self.progress;
        let moved = axes != *was_axes
            || status.state != was.state
            || status.line != was.line
            || status.spindle_rpm != was.spindle_rpm
            || status.tool != was.tool
            || status.fault_count != was.fault_count;
        let may_stand = status.state != MachineState::Running
            || self.hold_since.is_some()
            || !(status.feed_override > 0.0)
            || self.rapid_override <= 0.0;
        if moved || may_stand {
            self.progress = (*status, axes);
            self.progress_at = self.now();
            return;
        }
        let standing = self.now() - self.progress_at;
        if standing > STALL_TIMEOUT_S + LONGEST_WAIT_S + 0.1 {
            self.broken(format!(
                "the program runs, yet nothing moved for {standing:.3} s and no fault"
            ));
        }
    }

    fn safe_state(&mut self, status: &Status) {
        let Some(since) = self.fault_since else {
            return;
        };
        let load = self.load();
        let positions = load.map(|(p, _)| p);
        match self.safe_at {
            None => {
                let standing = load.iter().all(|(_, v)| v.abs() < STANDING_VELOCITY);
                // Drives off as the drives know it, not as the kernel last commanded it:
                // after a communication loss they follow their last command until their
                // own watchdog faults them, and after an e-stop they hear the disable an
                // exchange later.
                let safe = matches!(status.state, MachineState::EStop | MachineState::Fault)
                    && !status.ready
                    && self.drives_off();
                self.standing_periods = if standing && safe {
                    self.standing_periods + 1
                } else {
                    0
                };
                if self.standing_periods >= STANDING_PERIODS {
                    self.safe_at = Some(positions);
                } else if self.now() - since > SAFE_STATE_S {
                    self.broken(format!(
                        "a fault at t = {since:.3} s, and no safe state yet: load {load:?}"
                    ));
                }
            }
            Some(at) => {
                for i in 0..AXES {
                    if (positions[i] - at[i]).abs() > STAYS_WITHIN {
                        self.broken(format!(
                            "in the safe state since a fault, yet the load moved from {at:?} to {positions:?}"
                        ));
                    }
                }
            }
        }
    }
}

pub fn run(data: &[u8]) {
    let mut u = Unstructured::new(data);
    let Ok(choice) = u.int_in_range(0..=PROGRAMS.len()) else {
        return;
    };
    let program = fixture().programs.get(choice).cloned();
    let mut h = Harness::new(program);
    if h.trace > 0 {
        eprintln!("program {choice}");
    }
    // Power on as an operator would, then what the input says.
    h.apply(Op::Run(2));
    h.apply(Op::Command(Command::Reset));
    h.apply(Op::Run(20));
    while !u.is_empty() && h.now() < MAX_PERIODS as f64 * h.period_s {
        match op(&mut u) {
            Ok(o) => h.apply(o),
            Err(_) => break,
        }
    }
    // Long enough for a pending hold to settle and a pending fault to reach its safe state;
    // over sooner once nothing is pending and the machine stands.
    let settle = ((h.hold_bound.max(SAFE_STATE_S) + 0.05) / h.period_s) as u64;
    h.ops.push(Op::Run(settle));
    for _ in 0..settle {
        if h.at_rest() {
            break;
        }
        h.period();
    }
}
