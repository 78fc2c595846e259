//! Cost of one exchange (1 ms, and 100 µs) of the simulated machine with 12 joints (the seeds' 12-drive
//! machine), per drive mode. A velocity or CSP cycle runs 16 sub-steps of 62.5 µs per joint.

// criterion_group! and criterion_main! make public functions without docs.
#![allow(missing_docs)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use rtcnc_fieldbus::sim::{SimulatedJointConfig, SimulatedMachine, SimulatedMachineConfig};
use rtcnc_fieldbus::{DriveMode, Fieldbus, ProcessInputs, ProcessOutputs};

fn twelve_joints(
    drive: DriveMode,
    period: f64,
) -> (SimulatedMachine, ProcessOutputs, ProcessInputs) {
    let mut config: SimulatedMachineConfig = toml::from_str("joints = []").unwrap();
    config.joints = vec![SimulatedJointConfig::with_drive(drive); 12];
    let mut machine = SimulatedMachine::new(&config).unwrap();
    let mut outputs = ProcessOutputs::new(machine.layout());
    let mut inputs = ProcessInputs::new(machine.layout());
    for _ in 0..4 {
        for (command, feedback) in outputs.joints.iter_mut().zip(&inputs.joints) {
            command.controlword = feedback.state().controlword_towards(true);
        }
        machine.exchange(period, &outputs, &mut inputs).unwrap();
    }
    (machine, outputs, inputs)
}

fn sim_step(c: &mut Criterion) {
    for (name, drive, period) in [
        (
            "sim_exchange_12_joints_velocity_1ms",
            DriveMode::Velocity,
            1e-3,
        ),
        ("sim_exchange_12_joints_csp_1ms", DriveMode::Csp, 1e-3),
        ("sim_exchange_12_joints_ideal_1ms", DriveMode::Ideal, 1e-3),
        (
            "sim_exchange_12_joints_velocity_100us",
            DriveMode::Velocity,
            1e-4,
        ),
    ] {
        let (mut machine, mut outputs, mut inputs) = twelve_joints(drive, period);
        let mut k = 0u32;
        c.bench_function(name, |b| {
            b.iter(|| {
                k = k.wrapping_add(1);
                // A slow back-and-forth so the joints stay in a realistic range.
                let phase = f64::from(k % 2000) * 1e-3;
                for (index, joint) in outputs.joints.iter_mut().enumerate() {
                    let v = 20.0 * (phase * 3.0 + index as f64).sin();
                    joint.target_velocity = v;
                    joint.target_position += v * period;
                    joint.velocity_offset = v;
                }
                machine.exchange(period, &outputs, &mut inputs).unwrap();
                black_box(&inputs);
            })
        });
    }
}

criterion_group!(benches, sim_step);
criterion_main!(benches);
