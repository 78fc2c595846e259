//! The kernel runs over any fieldbus and any kinematics handed to it: the same program on
//! the same simulated machine gives the same set-points whether `Kernel::build` opens the
//! machine from the file or the caller hands it over (behind a bus of its own, or with a
//! kinematics of its own), and the simulated machine's accessors answer only on it.

use crate::common;
use std::error::Error as _;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use crate::common::{config, program};
use rtcnc_fieldbus::sim::SimulatedMachine;
use rtcnc_fieldbus::{Fieldbus, FieldbusError, ProcessInputs, ProcessLayout, ProcessOutputs};
use rtcnc_kernel::{
    Command, Kernel, KernelOptions, MachineConfig, MachineKinematics, MachineState, Simulation,
};
use rtcnc_motion::{Axis, AxisVec, JointLimits, Kinematics, TrivialKinematics};

/// A bus of the caller's own: the simulated machine behind it, every exchange counted.
struct CountingBus {
    machine: SimulatedMachine,
    exchanges: Arc<AtomicU64>,
}

impl Fieldbus for CountingBus {
    fn layout(&self) -> &ProcessLayout {
        self.machine.layout()
    }

    fn exchange(
        &mut self,
        period_s: f64,
        outputs: &ProcessOutputs,
        inputs: &mut ProcessInputs,
    ) -> Result<(), FieldbusError> {
        self.exchanges.fetch_add(1, Ordering::Relaxed);
        self.machine.exchange(period_s, outputs, inputs)
    }
}

/// Trivial kinematics of the caller's own, every inverse transformation counted.
struct CountingKinematics {
    inner: TrivialKinematics,
    calls: Arc<AtomicU64>,
}

impl Kinematics for CountingKinematics {
    fn joint_count(&self) -> usize {
        self.inner.joint_count()
    }
    fn axes_to_joints(&self, axes: &AxisVec, joints: &mut [f64]) {
        self.calls.fetch_add(1, Ordering::Relaxed);
        self.inner.axes_to_joints(axes, joints);
    }
    fn joints_to_axes(&self, joints: &[f64]) -> AxisVec {
        self.inner.joints_to_axes(joints)
    }
    fn joint_axis(&self, joint: usize) -> Option<Axis> {
        self.inner.joint_axis(joint)
    }
    fn joint_limits(&self, joint: usize) -> Option<JointLimits> {
        self.inner.joint_limits(joint)
    }
}

const PROGRAM: &str = "G21 G90 G64 P0.05\nG1 X10 Y5 F1200\nG2 X20 Y5 I5 J0\nG0 Z5\nM2\n";

fn options(name: &str) -> KernelOptions {
    KernelOptions {
        program: Some(program(PROGRAM, name)),
        record_capacity: 1 << 14,
        ..KernelOptions::default()
    }
}

fn machine_of(config: &MachineConfig) -> SimulatedMachine {
    SimulatedMachine::new(&config.simulated_machine().unwrap()).unwrap()
}

/// Runs the program to its end; every joint set-point of every cycle.
fn setpoints(kernel: Kernel) -> Vec<(u64, [f64; 3])> {
    let mut sim = Simulation::new(kernel);
    let handle = sim.handle().clone();
    let mut out = Vec::new();
    let mut sink = |s: &rtcnc_kernel::Sample| {
        out.push((s.cycle, [s.setpoint[0], s.setpoint[1], s.setpoint[2]]))
    };
    sim.run_cycles(2, &mut sink).unwrap();
    handle.command(Command::Reset);
    sim.run_cycles(10, &mut sink).unwrap();
    handle.command(Command::Start { from_line: 0 });
    let ended = sim
        .run_until(Duration::from_secs(20), &mut sink, |s| {
            s.program_ended && s.state == MachineState::Idle
        })
        .unwrap();
    assert!(ended);
    assert!(handle.take_faults().is_empty());
    out
}

#[test]
fn a_bus_and_a_kinematics_handed_over_give_the_set_points_of_the_machine_file() {
    let config = config("sim-mill.toml");
    let reference = setpoints(Kernel::build(&config, options("bus-file.ngc")).unwrap());
    assert!(reference.len() > 500);

    let exchanges = Arc::new(AtomicU64::new(0));
    let bus = CountingBus {
        machine: machine_of(&config),
        exchanges: exchanges.clone(),
    };
    let kernel = Kernel::build_with_bus(&config, options("bus-own.ngc"), bus).unwrap();
    // Not the simulated machine itself: its accessors are refused, with a clear error.
    let refused = kernel.handle.simulated_machine().err().unwrap();
    assert_eq!(refused.code(), "kernel.not_simulated");
    assert!(refused.to_string().contains("not the simulated machine"));
    assert_eq!(setpoints(kernel), reference);
    // The self-test's exchange and one per servo period went through the bus handed over.
    assert!(exchanges.load(Ordering::Relaxed) as usize > reference.len());

    let calls = Arc::new(AtomicU64::new(0));
    let kinematics = MachineKinematics::new(CountingKinematics {
        inner: TrivialKinematics::identity(&[Axis::X, Axis::Y, Axis::Z]),
        calls: calls.clone(),
    });
    let kernel = Kernel::build_with(
        &config,
        options("kin-own.ngc"),
        machine_of(&config),
        kinematics,
    )
    .unwrap();
    // The simulated machine handed over is reachable as the one the file opens.
    let door_closed = kernel
        .handle
        .simulated_machine()
        .unwrap()
        .with(|m| m.door_closed());
    assert_eq!(door_closed, Some(true));
    assert_eq!(setpoints(kernel), reference);
    assert!(calls.load(Ordering::Relaxed) > 0);
}

#[test]
fn a_kinematics_without_the_machines_joints_is_refused() {
    let config = config("sim-mill.toml");
    let kinematics = MachineKinematics::new(TrivialKinematics::identity(&[Axis::X, Axis::Y]));
    let e = Kernel::build_with(
        &config,
        KernelOptions::default(),
        machine_of(&config),
        kinematics,
    )
    .err()
    .unwrap();
    assert_eq!(e.code(), "kernel.kinematics");
    assert_eq!(
        e.to_string(),
        "kinematics: it has 2 joints, the machine file has 3 joints driven by axes"
    );
}

#[test]
fn a_build_error_names_what_failed_and_gives_its_cause_once() {
    let mut config = config("sim-mill.toml");
    let missing = common::repo().join("examples/plc/no-such-program.st");
    config.plc.as_mut().unwrap().program = missing.clone();
    let e = Kernel::build(&config, KernelOptions::default())
        .err()
        .unwrap();
    assert_eq!(e.code(), "kernel.plc");
    assert_eq!(e.to_string(), format!("plc program {}", missing.display()));
    let cause = e.source().expect("the cause is the source").to_string();
    assert!(cause.contains("no-such-program.st"), "{cause}");
    assert!(!e.to_string().contains(&cause));

    // A drive that does not answer: the bus has fewer drives than the file has joints.
    let mut fewer = config.clone();
    fewer.plc = None;
    let mut sim = fewer.simulated_machine().unwrap();
    sim.joints.pop();
    sim.devices.clear();
    let e = Kernel::build_with_bus(
        &fewer,
        KernelOptions::default(),
        SimulatedMachine::new(&sim).unwrap(),
    )
    .err()
    .unwrap();
    assert_eq!(e.code(), "kernel.self_test");
    assert_eq!(e.to_string(), "self-test: drive communication");
    assert_eq!(
        e.source().unwrap().to_string(),
        "2 drives answer, 3 are configured"
    );
}
