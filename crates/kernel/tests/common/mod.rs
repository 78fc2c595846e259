//! Helpers of the whole-machine tests: build a kernel from a configuration in `configs/`
//! (or TOML text), run it in virtual time, collect samples and faults.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::time::Duration;

use rtcnc_kernel::{
    Command, Fault, Kernel, KernelHandle, KernelOptions, MachineConfig, Sample, Simulation, Status,
};

pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

pub fn config(name: &str) -> MachineConfig {
    MachineConfig::load(&repo().join("configs").join(name)).expect("configuration loads")
}

/// `name` from `configs/` with every task period set to `period_us`, as a user changes the
/// `[tasks]` of a machine file to run it at another servo period.
pub fn config_at_period(name: &str, period_us: u64) -> MachineConfig {
    let mut config = config(name);
    let period = format!("{period_us}us");
    let tasks = &mut config.tasks;
    for task in [
        &mut tasks.fieldbus,
        &mut tasks.machine_logic,
        &mut tasks.interpolation,
        &mut tasks.look_ahead,
        &mut tasks.command_parsing,
        &mut tasks.status_feedback,
    ] {
        task.period = period.clone();
    }
    config
}

pub fn program(text: &str, name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rtcnc-kernel-tests-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    // Written aside and renamed into place: tests of one binary run in parallel and may
    // write the same program under the same name while another's kernel reads it (a
    // reader of a file being rewritten saw it empty).
    static WRITES: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = WRITES.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let aside = dir.join(format!(".{name}.{n}"));
    std::fs::write(&aside, text).unwrap();
    std::fs::rename(&aside, &path).unwrap();
    path
}

/// A kernel on `name` from `configs/` that computes its set-points `lead` ahead of position
/// control (`tasks.setpoint_lead`, e.g. "50ms"), with `program` loaded and an optional
/// stall of interpolation's thread (from a cycle, for a time), recording every servo
/// period, in virtual time.
pub fn simulation_with_lead(
    name: &str,
    lead: &str,
    stall: Option<(u64, Duration)>,
    program: Option<PathBuf>,
) -> Simulation {
    let mut cfg = config(name);
    cfg.tasks.setpoint_lead = Some(lead.into());
    let kernel = Kernel::build(
        &cfg,
        KernelOptions {
            program,
            record_capacity: 1 << 14,
            interpolation_stall: stall,
            ..KernelOptions::default()
        },
    )
    .expect("kernel builds");
    Simulation::new(kernel)
}

/// Starts a continuous jog of `axis` at `velocity` (units/s; its sign is the direction).
pub fn jog_continuously(h: &KernelHandle, axis: u8, velocity: f64) {
    assert!(h.command(Command::JogContinuous { axis, velocity }));
}

pub struct Machine {
    pub sim: Simulation,
    pub samples: Vec<Sample>,
    pub faults: Vec<Fault>,
}

impl Machine {
    pub fn new(config: &MachineConfig, program: Option<PathBuf>) -> Machine {
        let kernel = Kernel::build(
            config,
            KernelOptions {
                program,
                record_capacity: 1 << 14,
                ..KernelOptions::default()
            },
        )
        .expect("kernel builds");
        Machine {
            sim: Simulation::new(kernel),
            samples: Vec::new(),
            faults: Vec::new(),
        }
    }

    pub fn command(&mut self, c: Command) {
        assert!(self.sim.handle().command(c));
    }

    pub fn cycles(&mut self, n: u64) {
        let samples = &mut self.samples;
        self.sim
            .run_cycles(n, &mut |s| samples.push(*s))
            .expect("runs");
        self.faults.extend(self.sim.handle().take_faults());
    }

    pub fn until(&mut self, limit_s: f64, done: impl FnMut(&Status) -> bool) -> bool {
        let samples = &mut self.samples;
        let ok = self
            .sim
            .run_until(
                Duration::from_secs_f64(limit_s),
                &mut |s| samples.push(*s),
                done,
            )
            .expect("runs");
        self.faults.extend(self.sim.handle().take_faults());
        ok
    }

    /// Acts on the simulated machine (inputs, faults).
    pub fn handle_machine<R>(
        &self,
        f: impl FnOnce(&mut rtcnc_fieldbus::sim::SimulatedMachine) -> R,
    ) -> R {
        self.sim.handle().simulated_machine().unwrap().with(f)
    }

    pub fn status(&self) -> Status {
        self.sim.handle().status()
    }

    /// A machine on `config` with the program `text` (written as `name`), powered on and
    /// the program started.
    pub fn started(config: &MachineConfig, text: &str, name: &str) -> Machine {
        let mut m = Machine::new(config, Some(program(text, name)));
        m.power_on();
        m.command(Command::Start { from_line: 0 });
        m
    }

    /// The texts of the operator messages shown since the last call.
    pub fn take_message_texts(&self) -> Vec<String> {
        self.sim
            .handle()
            .take_messages()
            .iter()
            .map(|msg| msg.text.as_str().to_string())
            .collect()
    }

    /// Reset and wait until the drives are enabled.
    pub fn power_on(&mut self) {
        self.cycles(2);
        self.command(Command::Reset);
        assert!(self.until(0.1, |s| s.ready), "drives enable");
    }
}

/// `text` run on `config` until it ends with the machine idle, or faults (at most 120 s).
pub fn run_to_the_end(config: &MachineConfig, text: &str, name: &str) -> Machine {
    let mut m = Machine::started(config, text, name);
    m.until(120.0, |s| {
        (s.program_ended && s.state == rtcnc_kernel::MachineState::Idle) || s.last_fault.is_some()
    });
    m
}

/// `text` started on `config` and run until the machine is idle (at most `limit_s`), with
/// the operator messages it showed (its DEBUG lines).
pub fn run_to_idle_with_messages(
    config: &MachineConfig,
    text: &str,
    name: &str,
    limit_s: f64,
) -> (Machine, Vec<String>) {
    let mut m = Machine::started(config, text, name);
    m.cycles(2);
    assert!(m.until(limit_s, |s| s.state == rtcnc_kernel::MachineState::Idle));
    let messages = m.take_message_texts();
    (m, messages)
}

/// The number after `key` in an operator message (`(DEBUG,z #5063 ok #5070)` shows
/// `z -3.000000 ok 1.000000`).
pub fn message_number(text: &str, key: &str) -> f64 {
    let start = text.find(key).unwrap() + key.len();
    text[start..]
        .split_whitespace()
        .next()
        .unwrap()
        .parse()
        .unwrap()
}

/// Asserts that `m` stopped its program with a probing failure `failure` at `line`, its
/// message starting with `message`.
pub fn assert_probe_failed(
    m: &Machine,
    line: u32,
    failure: rtcnc_kernel::ProbeFailure,
    message: &str,
) {
    let f = m
        .faults
        .iter()
        .find(|f| f.code == rtcnc_kernel::FaultCode::ProbeFailed)
        .unwrap_or_else(|| panic!("{:?}", m.faults));
    assert_eq!(f.line, line);
    assert_eq!(
        rtcnc_kernel::ProbeFailure::from_value(f.value),
        Some(failure)
    );
    let described = f.describe(|_| String::new());
    assert!(described.starts_with(message), "{described}");
    assert!(!m.status().program_ended);
}

/// Velocity, acceleration and jerk of every joint by finite differences of its set-points
/// (each the mean of the true one over one to three periods, so bounded by its limit):
/// `limits[j]` = (velocity, acceleration, jerk) of joint j, `dt` the servo period.
pub fn assert_joint_limits(samples: &[Sample], limits: &[(f64, f64, f64)], dt: f64) {
    for (j, &(v, a, jerk)) in limits.iter().enumerate() {
        let p: Vec<f64> = samples.iter().map(|s| s.setpoint[j]).collect();
        for i in 3..p.len() {
            let v0 = (p[i] - p[i - 1]) / dt;
            let v1 = (p[i - 1] - p[i - 2]) / dt;
            let v2 = (p[i - 2] - p[i - 3]) / dt;
            let a0 = (v0 - v1) / dt;
            let j0 = (a0 - (v1 - v2) / dt) / dt;
            let c = samples[i].cycle;
            assert!(v0.abs() <= v * (1.0 + 1e-9), "joint {j} cycle {c}: v {v0}");
            assert!(a0.abs() <= a * (1.0 + 1e-6), "joint {j} cycle {c}: a {a0}");
            assert!(
                j0.abs() <= jerk * (1.0 + 1e-5),
                "joint {j} cycle {c}: jerk {j0}"
            );
        }
    }
}

/// Distance from `p` to the segment from `a` to `b`.
pub fn distance_to_segment(p: [f64; 3], a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let q = [p[0] - a[0], p[1] - a[1], p[2] - a[2]];
    let len2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    let u = if len2 > 0.0 {
        ((q[0] * d[0] + q[1] * d[1] + q[2] * d[2]) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    ((q[0] - u * d[0]).powi(2) + (q[1] - u * d[1]).powi(2) + (q[2] - u * d[2]).powi(2)).sqrt()
}

/// Per programmed line `(line, from, to)`, the tool tip's worst distance from that segment
/// over the line's set-points, the tip computed from the joint set-points by `tip`; each
/// line must have more than 100 set-points.
pub fn worst_tip_distance_per_line(
    samples: &[Sample],
    lines: &[(u32, [f64; 3], [f64; 3])],
    tip: impl Fn(&[f64]) -> [f64; 3],
) -> Vec<(u32, f64)> {
    lines
        .iter()
        .map(|&(line, a, b)| {
            let on: Vec<&Sample> = samples.iter().filter(|s| s.line == line).collect();
            assert!(on.len() > 100, "line {line}: {} set-points", on.len());
            let worst = on
                .iter()
                .map(|s| distance_to_segment(tip(&s.setpoint), a, b))
                .fold(0.0, f64::max);
            (line, worst)
        })
        .collect()
}

/// The tool tip's speed between consecutive set-points of `line` (the tip from the joint
/// set-points by `tip`), in units per second at the period `dt`.
pub fn tip_speeds_on_line(
    samples: &[Sample],
    line: u32,
    dt: f64,
    tip: impl Fn(&[f64]) -> [f64; 3],
) -> Vec<f64> {
    let tips: Vec<[f64; 3]> = samples
        .iter()
        .filter(|s| s.line == line)
        .map(|s| tip(&s.setpoint))
        .collect();
    tips.windows(2)
        .map(|w| {
            ((w[1][0] - w[0][0]).powi(2)
                + (w[1][1] - w[0][1]).powi(2)
                + (w[1][2] - w[0][2]).powi(2))
            .sqrt()
                / dt
        })
        .collect()
}

/// Asserts that the middle third of `speeds` is `want` within 1 %.
pub fn assert_middle_speed(speeds: &[f64], want: f64, what: &str) {
    let n = speeds.len();
    for v in &speeds[n / 3..2 * n / 3] {
        assert!(
            (v - want).abs() < want * 0.01,
            "{what}: tip at {v}, not {want}"
        );
    }
}
