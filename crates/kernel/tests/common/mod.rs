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

    /// Reset and wait until the drives are enabled.
    pub fn power_on(&mut self) {
        self.cycles(2);
        self.command(Command::Reset);
        assert!(self.until(0.1, |s| s.ready), "drives enable");
    }
}
