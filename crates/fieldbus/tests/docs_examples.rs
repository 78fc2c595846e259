//! The TOML examples of docs/machine.md, verbatim: they must stay valid.

use rtcnc_fieldbus::sim::{SimulatedMachine, SimulatedMachineConfig};
use rtcnc_fieldbus::{DriveMode, Fieldbus};
use rtcnc_servo::{ServoLoop, ServoLoopConfig};

const MACHINE: &str = r#"
command_delay_s = 0.0
[[joints]]
drive = "velocity"
units_per_revolution = 5.0
encoder_counts_per_revolution = 131072
negative_limit_switch = -1.0
positive_limit_switch = 301.0
home_switch = { from = 295.0, to = 301.0 }
index_offset = 0.0
motor = { inertia = 1.5e-4, viscous_friction = 2e-4, coulomb_friction = 0.1, torque_limit = 3.8 }
[[joints]]
drive = "csp"
position_loop_gain = 300.0
[spindle]
max_speed_rpm = 24000.0
acceleration_rpm_per_s = 8000.0
[tool_changer]
change_time_s = 3.0
[[devices]]
kind = "delayed_input"
output = 5
input = 2
rise_delay_s = 0.5
fall_delay_s = 0.2
"#;

const SERVO: &str = r#"
loop = "pid"
gains = { p = 200.0, velocity_ff = 1.0, acceleration_ff = 0.0005, output_limit = 150.0 }
following_error = { min_ferror = 0.01, ferror = 0.1, max_velocity = 100.0 }
"#;

#[test]
fn docs_examples_parse() {
    let doc = include_str!("../../../docs/machine.md");
    assert!(
        doc.contains(MACHINE.trim()),
        "docs/machine.md changed: update this test"
    );
    assert!(
        doc.contains(SERVO.trim()),
        "docs/machine.md changed: update this test"
    );
    let machine: SimulatedMachineConfig = toml::from_str(MACHINE).unwrap();
    let machine = SimulatedMachine::new(&machine).unwrap();
    assert_eq!(
        machine.layout().joints,
        [DriveMode::Velocity, DriveMode::Csp]
    );
    let servo: ServoLoopConfig = toml::from_str(SERVO).unwrap();
    assert!(matches!(
        ServoLoop::new(0, &servo).unwrap(),
        ServoLoop::Pid(_)
    ));
}
