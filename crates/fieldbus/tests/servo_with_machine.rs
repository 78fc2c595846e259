//! The servo loop and the simulated machine together: an injected fault reaches the
//! controller as a following-error fault naming the joint, at the analytic cycle.

use rtcnc_fieldbus::sim::{
    InjectedFault, SimulatedJointConfig, SimulatedMachine, SimulatedMachineConfig,
};
use rtcnc_fieldbus::{Cia402State, DriveMode, Fieldbus, ProcessInputs, ProcessOutputs};
use rtcnc_servo::{FollowingErrorLimits, PidConfig, PidController, PidGains, ServoFault, SetPoint};

const T: f64 = 0.001;

#[test]
fn encoder_loss_on_a_velocity_joint_becomes_a_following_error_fault_at_the_analytic_cycle() {
    let mut config: SimulatedMachineConfig = toml::from_str("joints = []").unwrap();
    config.joints = vec![SimulatedJointConfig::with_drive(DriveMode::Velocity); 3];
    let mut machine = SimulatedMachine::new(&config).unwrap();
    let mut outputs = ProcessOutputs::new(machine.layout());
    let mut inputs = ProcessInputs::new(machine.layout());
    // A static limit of 55 µm (the velocity-scaled one stays below it at 10 mm/s).
    let limits = FollowingErrorLimits {
        min_ferror: 0.055,
        ferror: 0.055,
        max_velocity: 100.0,
    };
    let mut loops: Vec<PidController> = (0..3)
        .map(|joint| {
            PidController::new(
                joint,
                &PidConfig {
                    gains: PidGains::default(),
                    following_error: limits,
                },
            )
            .unwrap()
        })
        .collect();
    for _ in 0..4 {
        for (command, feedback) in outputs.joints.iter_mut().zip(&inputs.joints) {
            command.controlword = feedback.state().controlword_towards(true);
        }
        machine.exchange(T, &outputs, &mut inputs).unwrap();
    }
    assert!(
        inputs
            .joints
            .iter()
            .all(|j| j.state() == Cia402State::OperationEnabled)
    );

    // Every joint follows a 10 mm/s ramp; at 0.5 s the encoder of joint 2 stops counting
    // (during that cycle's exchange), so the feedback read at cycle 500 is the last one
    // that moves. From then on its error grows by exactly v·T = 10 µm per cycle from the
    // (sub-micrometre) error of cycle 500: over 55 µm six cycles later.
    let v = 10.0;
    let loss_cycle = 500;
    let mut error_at_loss = None;
    for k in 0..1000 {
        if k == loss_cycle {
            machine
                .inject(InjectedFault::EncoderLoss { joint: 2 })
                .unwrap();
        }
        let setpoint = SetPoint {
            position: v * k as f64 * T,
            velocity: v,
            acceleration: 0.0,
        };
        for (joint, pid) in loops.iter_mut().enumerate() {
            match pid.update(setpoint, inputs.joints[joint].position, T) {
                Ok(command) => outputs.joints[joint].target_velocity = command,
                Err(fault) => {
                    let ServoFault::FollowingError {
                        joint,
                        error,
                        limit,
                    } = fault
                    else {
                        panic!("unexpected fault {fault:?}");
                    };
                    assert_eq!(joint, 2);
                    assert_eq!(limit, 0.055);
                    let frozen_error: f64 = error_at_loss.expect("fault after the loss");
                    assert!(frozen_error.abs() < 1e-3);
                    assert_eq!(k, loss_cycle + 6, "error {error}");
                    assert!((error - (frozen_error + 6.0 * v * T)).abs() < 1e-9);
                    assert_eq!(
                        fault.to_string(),
                        format!("joint 2: following error {error:.6} exceeds the limit 0.055000")
                    );
                    return;
                }
            }
        }
        if k == loss_cycle {
            error_at_loss = Some(loops[2].following_error().last_error());
        }
        machine.exchange(T, &outputs, &mut inputs).unwrap();
    }
    panic!("no following-error fault");
}
