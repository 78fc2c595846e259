//! The per-cycle paths allocate nothing and survive any data.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use proptest::prelude::*;
use rtcnc_fieldbus::sim::{SimulatedJointConfig, SimulatedMachine, SimulatedMachineConfig};
use rtcnc_fieldbus::{
    ControlWord, DriveMode, Fieldbus, LatchSource, ProcessInputs, ProcessOutputs,
};
use rtcnc_servo::{FollowingErrorLimits, PidConfig, PidController, PidGains, SetPoint};

struct CountingAllocator;

thread_local! {
    // Counts only this thread's allocations: other tests run on other threads.
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|count| count.set(count.get() + 1));
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

fn all_modes_machine() -> SimulatedMachine {
    let mut config: SimulatedMachineConfig = toml::from_str("joints = []").unwrap();
    for drive in [
        DriveMode::Velocity,
        DriveMode::Csp,
        DriveMode::Torque,
        DriveMode::Ideal,
    ] {
        config.joints.push(SimulatedJointConfig {
            index_offset: Some(0.1),
            ..SimulatedJointConfig::with_drive(drive)
        });
    }
    SimulatedMachine::new(&config).unwrap()
}

#[test]
fn servo_update_and_exchange_allocate_nothing() {
    let mut machine = all_modes_machine();
    let mut outputs = ProcessOutputs::new(machine.layout());
    let mut inputs = ProcessInputs::new(machine.layout());
    let limits = FollowingErrorLimits {
        min_ferror: 10.0,
        ferror: 10.0,
        max_velocity: 100.0,
    };
    let config = PidConfig {
        gains: PidGains::default(),
        following_error: limits,
    };
    let mut pid = PidController::new(0, &config).unwrap();
    outputs.spindle.enable = true;
    outputs.spindle.speed_rpm = 5000.0;
    outputs.tool_changer = rtcnc_fieldbus::ToolChangeCommand {
        tool: 2,
        start: true,
    };
    let before = ALLOCATIONS.with(Cell::get);
    for k in 0..2000 {
        let t = k as f64 * 1e-3;
        let setpoint = SetPoint {
            position: 5.0 * t,
            velocity: 5.0,
            acceleration: 0.0,
        };
        let velocity = pid
            .update(setpoint, inputs.joints[0].position, 1e-3)
            .unwrap();
        for (command, feedback) in outputs.joints.iter_mut().zip(&inputs.joints) {
            command.controlword = feedback.state().controlword_towards(true);
            command.target_velocity = velocity;
            command.target_position = 5.0 * t;
            command.target_torque = 0.2;
            command.latch = Some(LatchSource::IndexPulse);
        }
        machine.exchange(1e-3, &outputs, &mut inputs).unwrap();
    }
    assert_eq!(ALLOCATIONS.with(Cell::get) - before, 0);
}

fn any_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        any::<f64>(),
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(f64::NEG_INFINITY),
        -1e3..1e3f64,
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(if cfg!(debug_assertions) { 64 } else { 1024 }))]

    #[test]
    fn pid_never_outputs_a_non_finite_command(
        inputs in proptest::collection::vec((any_f64(), any_f64(), any_f64(), any_f64(), any_f64()), 1..40)
    ) {
        let limits = FollowingErrorLimits { min_ferror: 1e300, ferror: 1e300, max_velocity: 1.0 };
        let gains = PidGains { i: 50.0, d: 0.01, ..PidGains::default() };
        let mut pid = PidController::new(0, &PidConfig { gains, following_error: limits }).unwrap();
        for (position, velocity, acceleration, feedback, period) in inputs {
            let setpoint = SetPoint { position, velocity, acceleration };
            if let Ok(output) = pid.update(setpoint, feedback, period) {
                prop_assert!(output.is_finite());
            }
        }
    }

    #[test]
    fn exchange_survives_any_command_and_recovers(
        commands in proptest::collection::vec((any::<u16>(), any_f64(), any_f64(), any_f64(), any_f64()), 1..30)
    ) {
        let mut machine = all_modes_machine();
        let mut outputs = ProcessOutputs::new(machine.layout());
        let mut inputs = ProcessInputs::new(machine.layout());
        for (word, position, velocity, torque, offset) in commands {
            for command in outputs.joints.iter_mut() {
                command.controlword = ControlWord(word);
                command.target_position = position;
                command.target_velocity = velocity;
                command.target_torque = torque;
                command.velocity_offset = offset;
                command.torque_offset = offset;
            }
            outputs.spindle.speed_rpm = velocity;
            outputs.spindle.enable = true;
            machine.exchange(1e-3, &outputs, &mut inputs).unwrap();
        }
        // Sane commands afterwards: every joint's state stays finite.
        for command in outputs.joints.iter_mut() {
            *command = rtcnc_fieldbus::JointCommand::default();
        }
        machine.exchange(1e-3, &outputs, &mut inputs).unwrap();
        for joint in 0..4 {
            let (position, velocity) = machine.true_state(joint).unwrap();
            prop_assert!(position.is_finite() && velocity.is_finite(), "joint {}", joint);
        }
        prop_assert!(inputs.spindle.speed_rpm.is_finite());
    }
}
