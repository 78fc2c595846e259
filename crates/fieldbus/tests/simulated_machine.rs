//! The simulated machine through the `Fieldbus` trait, against analytic references.

use std::f64::consts::PI;

use rtcnc_fieldbus::cia402::error_code;
use rtcnc_fieldbus::sim::{
    InjectedFault, MotorConfig, SimulatedJointConfig, SimulatedMachine, SimulatedMachineConfig,
    SwitchRange,
};
use rtcnc_fieldbus::{
    Cia402State, ControlWord, DriveMode, Fieldbus, FieldbusError, LatchSource, ProcessInputs,
    ProcessOutputs, StatusWord,
};

const T: f64 = 0.001;

struct Bench {
    machine: SimulatedMachine,
    outputs: ProcessOutputs,
    inputs: ProcessInputs,
}

impl Bench {
    fn new(config: SimulatedMachineConfig) -> Self {
        let machine = SimulatedMachine::new(&config).expect("valid config");
        let outputs = ProcessOutputs::new(machine.layout());
        let inputs = ProcessInputs::new(machine.layout());
        Self {
            machine,
            outputs,
            inputs,
        }
    }

    fn with_joints(joints: Vec<SimulatedJointConfig>) -> Self {
        Self::new(SimulatedMachineConfig {
            joints,
            ..toml::from_str("joints = []").unwrap()
        })
    }

    fn cycle(&mut self) -> Result<(), FieldbusError> {
        self.machine.exchange(T, &self.outputs, &mut self.inputs)
    }

    /// Walks every drive to operation enabled (four exchanges from power-up).
    fn enable_all(&mut self) {
        for _ in 0..4 {
            for (command, feedback) in self.outputs.joints.iter_mut().zip(&self.inputs.joints) {
                command.controlword = feedback.state().controlword_towards(true);
            }
            self.cycle().unwrap();
        }
        for feedback in &self.inputs.joints {
            assert_eq!(feedback.state(), Cia402State::OperationEnabled);
        }
    }
}

/// A joint in radians (one unit per radian) with the given motor.
fn radian_joint(drive: DriveMode, motor: MotorConfig) -> SimulatedJointConfig {
    SimulatedJointConfig {
        motor,
        units_per_revolution: 2.0 * PI,
        ..SimulatedJointConfig::with_drive(drive)
    }
}

fn close(actual: f64, expected: f64, tolerance: f64) -> bool {
    (actual - expected).abs() <= tolerance
}

#[test]
fn constant_torque_against_viscous_friction_gives_the_exact_exponential_velocity() {
    let motor = MotorConfig {
        inertia: 2e-4,
        viscous_friction: 1e-3,
        coulomb_friction: 0.0,
        torque_limit: 5.0,
    };
    let mut bench = Bench::with_joints(vec![radian_joint(DriveMode::Torque, motor)]);
    bench.enable_all();
    let torque = 0.4;
    bench.outputs.joints[0].target_torque = torque;
    let (terminal, rate) = (torque / 1e-3, 1e-3 / 2e-4);
    for k in 1..=1000 {
        bench.cycle().unwrap();
        let t = k as f64 * T;
        let (_, velocity) = bench.machine.true_state(0).unwrap();
        let expected = terminal * (1.0 - (-rate * t).exp());
        assert!(
            close(velocity, expected, 1e-9 * terminal),
            "t {t}: {velocity} vs {expected}"
        );
        assert_eq!(bench.inputs.joints[0].torque, torque);
    }
}

#[test]
fn a_new_command_acts_after_the_configured_command_delay() {
    let motor = MotorConfig {
        inertia: 1e-4,
        viscous_friction: 0.0,
        coulomb_friction: 0.0,
        torque_limit: 5.0,
    };
    let mut config: SimulatedMachineConfig =
        toml::from_str("joints = []\ncommand_delay_s = 0.00025").unwrap();
    config.joints.push(radian_joint(DriveMode::Torque, motor));
    let mut bench = Bench::new(config);
    bench.enable_all();
    bench.outputs.joints[0].target_torque = 0.2;
    bench.cycle().unwrap();
    // 0.2 N·m / 1e-4 kg·m² = 2000 rad/s² for the last 0.75 ms of the period.
    let (position, velocity) = bench.machine.true_state(0).unwrap();
    assert!(close(velocity, 2000.0 * 0.75e-3, 1e-12), "{velocity}");
    assert!(close(position, 2000.0 * 0.75e-3 * 0.75e-3 / 2.0, 1e-15));
    bench.outputs.joints[0].target_torque = 0.0;
    bench.cycle().unwrap();
    let (_, velocity) = bench.machine.true_state(0).unwrap();
    assert!(close(velocity, 2000.0 * 1e-3, 1e-12), "{velocity}");
}

#[test]
fn coulomb_friction_holds_a_torque_commanded_joint_at_rest() {
    let motor = MotorConfig {
        inertia: 1e-4,
        viscous_friction: 0.0,
        coulomb_friction: 0.3,
        torque_limit: 5.0,
    };
    let mut bench = Bench::with_joints(vec![radian_joint(DriveMode::Torque, motor)]);
    bench.enable_all();
    bench.outputs.joints[0].target_torque = 0.2;
    bench.outputs.joints[0].torque_offset = 0.09;
    for _ in 0..500 {
        bench.cycle().unwrap();
    }
    assert_eq!(bench.machine.true_state(0), Some((0.0, 0.0)));
    assert_eq!(bench.inputs.joints[0].position_counts, 0);
    bench.outputs.joints[0].torque_offset = 0.11; // 0.31 N·m: breaks away
    for _ in 0..100 {
        bench.cycle().unwrap();
    }
    let (_, velocity) = bench.machine.true_state(0).unwrap();
    assert!(close(velocity, 0.01 / 1e-4 * 0.1, 1e-9), "{velocity}");
}

#[test]
fn torque_limit_caps_the_acceleration_of_a_velocity_drive() {
    let motor = MotorConfig {
        inertia: 1e-4,
        viscous_friction: 0.0,
        coulomb_friction: 0.0,
        torque_limit: 0.5,
    };
    let mut bench = Bench::with_joints(vec![radian_joint(DriveMode::Velocity, motor)]);
    bench.enable_all();
    assert_eq!(bench.machine.true_state(0), Some((0.0, 0.0)));
    bench.outputs.joints[0].target_velocity = 1e6;
    let acceleration = 0.5 / 1e-4; // 5000 rad/s²
    for k in 1..=200 {
        bench.cycle().unwrap();
        let t = k as f64 * T;
        let (position, velocity) = bench.machine.true_state(0).unwrap();
        assert!(close(velocity, acceleration * t, 1e-9), "t {t}");
        assert!(close(position, acceleration * t * t / 2.0, 1e-9), "t {t}");
        assert_eq!(bench.inputs.joints[0].torque, 0.5);
        assert!(
            bench.inputs.joints[0]
                .statusword
                .has(StatusWord::INTERNAL_LIMIT)
        );
    }
}

#[test]
fn encoder_quantises_position_to_whole_counts() {
    // 5 mm per revolution, 1000 counts: 5 µm per count, counts = floor(x / 0.005).
    let joint = |initial_position| SimulatedJointConfig {
        encoder_counts_per_revolution: 1000,
        initial_position,
        ..SimulatedJointConfig::with_drive(DriveMode::Velocity)
    };
    let mut bench = Bench::with_joints(vec![joint(0.0123), joint(-0.0001), joint(2.5)]);
    bench.cycle().unwrap();
    let counts: Vec<i64> = bench
        .inputs
        .joints
        .iter()
        .map(|j| j.position_counts)
        .collect();
    assert_eq!(counts, [2, -1, 500]);
    let positions: Vec<f64> = bench.inputs.joints.iter().map(|j| j.position).collect();
    assert_eq!(positions, [0.01, -0.005, 2.5]);
}

#[test]
fn limit_and_home_switches_change_at_their_exact_positions() {
    // An ideal drive puts the load exactly on each target; 1/1024 mm steps are exact.
    let joint = SimulatedJointConfig {
        negative_limit_switch: Some(-0.125),
        positive_limit_switch: Some(0.5),
        home_switch: Some(SwitchRange {
            from: 0.25,
            to: 0.375,
        }),
        ..SimulatedJointConfig::with_drive(DriveMode::Ideal)
    };
    let mut bench = Bench::with_joints(vec![joint]);
    bench.enable_all();
    let step = 1.0 / 1024.0;
    for k in -200..=600 {
        let position = k as f64 * step;
        bench.outputs.joints[0].target_position = position;
        bench.cycle().unwrap();
        let feedback = &bench.inputs.joints[0];
        assert_eq!(feedback.position, position);
        assert_eq!(feedback.negative_limit, k <= -128, "k {k}");
        assert_eq!(feedback.positive_limit, k >= 512, "k {k}");
        assert_eq!(feedback.home_switch, (256..=384).contains(&k), "k {k}");
    }
}

#[test]
fn index_pulse_latches_its_exact_position_between_samples() {
    // Index pulses at 0.3 + n·5 mm. A velocity drive moving at 37 mm/s never samples
    // there, yet the latch holds the index position (in whole counts).
    let joint = SimulatedJointConfig {
        index_offset: Some(0.3),
        ..SimulatedJointConfig::with_drive(DriveMode::Velocity)
    };
    let mut bench = Bench::with_joints(vec![joint]);
    bench.enable_all();
    bench.outputs.joints[0].latch = Some(LatchSource::IndexPulse);
    bench.cycle().unwrap();
    assert!(bench.inputs.joints[0].latch.armed && !bench.inputs.joints[0].latch.latched);
    bench.outputs.joints[0].target_velocity = 37.0;
    let counts = f64::from(1u32 << 17);
    let quantised = |x: f64| (x / 5.0 * counts).floor() / counts * 5.0;
    let mut latched_at = None;
    for k in 0..300 {
        let before = bench.machine.true_state(0).unwrap().0;
        bench.cycle().unwrap();
        let after = bench.machine.true_state(0).unwrap().0;
        let latch = bench.inputs.joints[0].latch;
        if latch.latched && latched_at.is_none() {
            assert!(
                before < 0.3 && 0.3 <= after,
                "latched at cycle {k} between {before} and {after}"
            );
            latched_at = Some(k);
            assert_eq!(latch.position, quantised(0.3));
        }
    }
    assert!(latched_at.is_some());
    // Re-arming: drop the request, arm again, and catch the next index ahead.
    bench.outputs.joints[0].latch = None;
    bench.cycle().unwrap();
    assert!(!bench.inputs.joints[0].latch.armed);
    bench.outputs.joints[0].latch = Some(LatchSource::IndexPulse);
    let here = bench.machine.true_state(0).unwrap().0;
    let next_index = 0.3 + 5.0 * ((here - 0.3) / 5.0).ceil();
    while !bench.inputs.joints[0].latch.latched {
        bench.cycle().unwrap();
    }
    assert_eq!(bench.inputs.joints[0].latch.position, quantised(next_index));
}

#[test]
fn home_switch_latch_moving_down_catches_the_upper_edge() {
    let joint = SimulatedJointConfig {
        home_switch: Some(SwitchRange {
            from: -2.0,
            to: 1.25,
        }),
        initial_position: 3.0,
        ..SimulatedJointConfig::with_drive(DriveMode::Velocity)
    };
    let mut bench = Bench::with_joints(vec![joint]);
    bench.enable_all();
    bench.outputs.joints[0].latch = Some(LatchSource::HomeSwitch);
    bench.outputs.joints[0].target_velocity = -20.0;
    while !bench.inputs.joints[0].latch.latched {
        bench.cycle().unwrap();
    }
    assert_eq!(bench.inputs.joints[0].latch.position, 1.25);
}

#[test]
fn csp_drive_follows_a_ramp_exactly_one_period_behind() {
    let mut bench = Bench::with_joints(vec![SimulatedJointConfig::with_drive(DriveMode::Csp)]);
    bench.enable_all();
    let v = 20.0;
    for k in 0..=1000 {
        let t = k as f64 * T;
        bench.outputs.joints[0].target_position = v * t;
        bench.outputs.joints[0].velocity_offset = v;
        bench.cycle().unwrap();
    }
    // The exchange that sends the target for t = 1 s ends at t = 1.001 s, with the load
    // where the target was one period earlier: exactly on the last target sent.
    let (position, velocity) = bench.machine.true_state(0).unwrap();
    assert!(close(position, v * 1.0, 1e-9), "{position}");
    assert!(close(velocity, v, 1e-9));
    let count = 5.0 / f64::from(1u32 << 17);
    assert!(close(bench.inputs.joints[0].position, v * 1.0, count));
    assert!(close(bench.inputs.joints[0].velocity, v, count / T));
}

#[test]
fn ideal_drive_moves_only_when_enabled() {
    let mut bench = Bench::with_joints(vec![SimulatedJointConfig::with_drive(DriveMode::Ideal)]);
    bench.outputs.joints[0].target_position = 1.0;
    bench.cycle().unwrap();
    assert_eq!(bench.inputs.joints[0].position, 0.0);
    bench.enable_all();
    assert_eq!(bench.inputs.joints[0].position, 1.0);
    bench.outputs.joints[0].target_position = 1.5;
    bench.cycle().unwrap();
    assert_eq!(bench.inputs.joints[0].position, 1.5);
    assert_eq!(bench.machine.true_state(0), Some((1.5, 0.5 / T)));
}

#[test]
fn quick_stop_ramps_the_joint_to_rest_and_stays_in_quick_stop_active() {
    let mut joint = SimulatedJointConfig::with_drive(DriveMode::Velocity);
    joint.quick_stop_deceleration = 1000.0;
    let mut bench = Bench::with_joints(vec![joint]);
    bench.enable_all();
    bench.outputs.joints[0].target_velocity = 50.0;
    for _ in 0..200 {
        bench.cycle().unwrap();
    }
    bench.outputs.joints[0].controlword = ControlWord::quick_stop();
    // 50 mm/s at 1000 mm/s² stops in 50 ms; the velocity loop follows the ramp closely.
    for k in 1..=80 {
        bench.cycle().unwrap();
        let (_, velocity) = bench.machine.true_state(0).unwrap();
        let ramp = (50.0 - 1000.0 * k as f64 * T).max(0.0);
        assert!(
            close(velocity, ramp, 1.0),
            "cycle {k}: {velocity} vs {ramp}"
        );
    }
    assert!(bench.machine.true_state(0).unwrap().1.abs() < 1e-3);
    assert_eq!(bench.inputs.joints[0].state(), Cia402State::QuickStopActive);
}

/// The speed of an S-curve ramp from rest to `s` (rpm) with acceleration `a` (rpm/s) and
/// jerk `j` (rpm/s²), `t` seconds in, when `s` ≥ a²/j (the acceleration reaches `a` and is
/// held): jerk for a/j, hold, jerk back for a/j, the whole ramp s/a + a/j long.
fn s_curve_rpm(s: f64, a: f64, j: f64, t: f64) -> f64 {
    let rise = a / j;
    let end = s / a + rise;
    if t <= rise {
        j * t * t / 2.0
    } else if t <= end - rise {
        a * a / (2.0 * j) + a * (t - rise)
    } else if t < end {
        s - j * (end - t) * (end - t) / 2.0
    } else {
        s
    }
}

#[test]
fn spindle_reaches_at_speed_at_the_analytic_cycle() {
    let mut config: SimulatedMachineConfig = toml::from_str(
        "joints = []\n[spindle]\nmax_speed_rpm = 12000.0\nacceleration_rpm_per_s = 3000.0\njerk_rpm_per_s2 = 600000.0\nat_speed_tolerance = 0.02\n",
    )
    .unwrap();
    config.joints.clear();
    let mut bench = Bench::new(config);
    bench.outputs.spindle.enable = true;
    bench.outputs.spindle.speed_rpm = 10000.0;
    let (a, j) = (3000.0, 600_000.0);
    // 10 000 ≥ a²/j = 15 rpm: the ramp lasts 10000/3000 + 3000/600000 = 3.338333 s, so the
    // speed is 10 000 from the 3339th cycle on. Within 2 % once 7.5 + 3000·(t − 0.005) ≥
    // 9800: t = 3.269167 s, the 3270th cycle.
    let done = 3339;
    let first = 3270;
    for k in 1..=4000 {
        bench.cycle().unwrap();
        let spindle = bench.inputs.spindle;
        assert_eq!(spindle.at_speed, k >= first, "cycle {k}: {spindle:?}");
        let want = s_curve_rpm(10000.0, a, j, k as f64 * T);
        assert!(
            close(spindle.speed_rpm, want, 1e-6),
            "cycle {k}: {} vs {want}",
            spindle.speed_rpm
        );
        assert_eq!(spindle.speed_rpm == 10000.0, k >= done, "cycle {k}");
    }
    // The e-stop takes power away: the spindle runs down, its deceleration rising at the
    // jerk: 600 000 · 0.001² / 2 = 0.3 rpm in the first period.
    bench.machine.set_estop(true);
    bench.cycle().unwrap();
    assert!(close(bench.inputs.spindle.speed_rpm, 9999.7, 1e-6));
    assert!(!bench.inputs.spindle.at_speed);
}

#[test]
fn a_spindle_reversal_is_one_s_curve_within_the_acceleration_and_jerk() {
    // +800 to −800 rpm from speed: 1600/3000 + 3000/600000 = 0.538333 s, so −800 from the
    // 539th period on; the speed's differences per period never exceed a·T, and their
    // changes never exceed j·T² (+ rounding).
    let mut config: SimulatedMachineConfig = toml::from_str(
        "joints = []\n[spindle]\nacceleration_rpm_per_s = 3000.0\njerk_rpm_per_s2 = 600000.0\n",
    )
    .unwrap();
    config.joints.clear();
    let mut bench = Bench::new(config);
    bench.outputs.spindle.enable = true;
    bench.outputs.spindle.speed_rpm = 800.0;
    for _ in 0..1000 {
        bench.cycle().unwrap();
    }
    assert_eq!(bench.inputs.spindle.speed_rpm, 800.0);
    bench.outputs.spindle.speed_rpm = -800.0;
    let mut speeds = vec![800.0, 800.0];
    for k in 1..=700 {
        bench.cycle().unwrap();
        let speed = bench.inputs.spindle.speed_rpm;
        assert_eq!(speed == -800.0, k >= 539, "cycle {k}: {speed}");
        speeds.push(speed);
    }
    for w in speeds.windows(3) {
        let (dv, dv_before) = (w[2] - w[1], w[1] - w[0]);
        assert!(dv.abs() <= 3000.0 * T + 1e-9, "{w:?}");
        assert!((dv - dv_before).abs() <= 600_000.0 * T * T + 1e-9, "{w:?}");
    }
}

#[test]
fn a_short_spindle_ramp_never_reaches_the_acceleration_limit() {
    // 10 rpm < a²/j = 15 rpm: jerk up for √(s/j), down for as long, the whole ramp
    // 2·√(10/600000) = 8.165 ms (at speed from the 9th cycle), the peak acceleration
    // √(s·j) = 2449 rpm/s; the speed is j·t²/2 up to the middle, s − j·(T − t)²/2 after.
    let mut config: SimulatedMachineConfig = toml::from_str(
        "joints = []\n[spindle]\nacceleration_rpm_per_s = 3000.0\njerk_rpm_per_s2 = 600000.0\n",
    )
    .unwrap();
    config.joints.clear();
    let mut bench = Bench::new(config);
    bench.outputs.spindle.enable = true;
    bench.outputs.spindle.speed_rpm = 10.0;
    let j = 600_000.0;
    let end = 2.0 * (10.0f64 / j).sqrt();
    for k in 1..=12 {
        bench.cycle().unwrap();
        let t = k as f64 * T;
        let want = if t <= end / 2.0 {
            j * t * t / 2.0
        } else if t < end {
            10.0 - j * (end - t) * (end - t) / 2.0
        } else {
            10.0
        };
        let speed = bench.inputs.spindle.speed_rpm;
        assert!(close(speed, want, 1e-9), "cycle {k}: {speed} vs {want}");
        assert_eq!(speed == 10.0, k >= 9, "cycle {k}: {speed}");
    }
}

#[test]
fn tool_change_takes_the_configured_time() {
    let config: SimulatedMachineConfig =
        toml::from_str("joints = []\n[tool_changer]\nchange_time_s = 2.5\ninitial_tool = 3\n")
            .unwrap();
    let mut bench = Bench::new(config);
    bench.cycle().unwrap();
    assert_eq!(bench.inputs.tool_changer.current_tool, 3);
    bench.outputs.tool_changer.tool = 7;
    bench.outputs.tool_changer.start = true;
    for k in 1..=2600 {
        bench.cycle().unwrap();
        let changer = bench.inputs.tool_changer;
        assert_eq!(changer.done, k >= 2500, "cycle {k}");
        assert_eq!(changer.busy, k < 2500, "cycle {k}");
        assert_eq!(changer.current_tool, if k >= 2500 { 7 } else { 3 });
    }
    bench.outputs.tool_changer.start = false;
    bench.cycle().unwrap();
    assert!(!bench.inputs.tool_changer.done);
}

#[test]
fn coolant_and_io_pass_through_and_estop_is_an_input() {
    let mut bench = Bench::with_joints(vec![]);
    bench.outputs.coolant.flood = true;
    bench.outputs.digital[3] = true;
    bench.outputs.analog[1] = 4.5;
    bench.machine.set_digital_input(15, true).unwrap();
    bench.machine.set_analog_input(0, -2.0).unwrap();
    bench.cycle().unwrap();
    assert!(bench.inputs.coolant.flood && !bench.inputs.coolant.mist);
    assert_eq!(bench.machine.digital_output(3), Some(true));
    assert_eq!(bench.machine.analog_output(1), Some(4.5));
    assert!(bench.inputs.digital[15]);
    assert_eq!(bench.inputs.analog[0], -2.0);
    assert!(!bench.inputs.estop_active);
    bench.machine.set_estop(true);
    bench.cycle().unwrap();
    assert!(bench.inputs.estop_active);
    assert!(
        !bench.inputs.coolant.flood,
        "the e-stop drops the coolant pumps"
    );
    bench.machine.turn_handwheel(5);
    bench.machine.turn_handwheel(-2);
    bench.cycle().unwrap();
    assert_eq!(bench.inputs.handwheel_counts, 3);
    let error = bench.machine.set_digital_input(16, true).unwrap_err();
    assert_eq!(error.to_string(), "no digital input 16: the machine has 16");
    assert_eq!(bench.machine.digital_output(99), None);
}

#[test]
fn estop_removes_drive_power_until_released() {
    let mut bench = Bench::with_joints(vec![SimulatedJointConfig::with_drive(DriveMode::Velocity)]);
    bench.enable_all();
    bench.machine.set_estop(true);
    bench.outputs.joints[0].controlword = ControlWord::enable_operation();
    bench.cycle().unwrap();
    assert_eq!(
        bench.inputs.joints[0].state(),
        Cia402State::SwitchOnDisabled
    );
    bench.outputs.joints[0].controlword = ControlWord::shutdown();
    bench.cycle().unwrap();
    assert_eq!(
        bench.inputs.joints[0].state(),
        Cia402State::SwitchOnDisabled,
        "no power"
    );
    bench.machine.set_estop(false);
    bench.enable_all();
}

#[test]
fn encoder_loss_freezes_feedback_of_a_velocity_drive_without_a_drive_fault() {
    let mut bench = Bench::with_joints(vec![SimulatedJointConfig::with_drive(DriveMode::Velocity)]);
    bench.enable_all();
    bench.outputs.joints[0].target_velocity = 10.0;
    for _ in 0..50 {
        bench.cycle().unwrap();
    }
    bench
        .machine
        .inject(InjectedFault::EncoderLoss { joint: 0 })
        .unwrap();
    bench.cycle().unwrap();
    let frozen = bench.inputs.joints[0].position;
    for _ in 0..50 {
        bench.cycle().unwrap();
    }
    assert_eq!(bench.inputs.joints[0].position, frozen);
    assert_eq!(bench.inputs.joints[0].velocity, 0.0);
    assert_eq!(
        bench.inputs.joints[0].state(),
        Cia402State::OperationEnabled
    );
    assert!(
        bench.machine.true_state(0).unwrap().0 > frozen + 0.4,
        "the load keeps moving"
    );
}

#[test]
fn encoder_loss_faults_a_csp_drive_with_the_position_sensor_code() {
    let mut bench = Bench::with_joints(vec![SimulatedJointConfig::with_drive(DriveMode::Csp)]);
    bench.enable_all();
    bench
        .machine
        .inject(InjectedFault::EncoderLoss { joint: 0 })
        .unwrap();
    bench.cycle().unwrap();
    assert_eq!(
        bench.inputs.joints[0].state(),
        Cia402State::FaultReactionActive
    );
    assert_eq!(
        bench.inputs.joints[0].error_code,
        error_code::POSITION_SENSOR
    );
    bench.cycle().unwrap();
    assert_eq!(bench.inputs.joints[0].state(), Cia402State::Fault);
    assert_eq!(bench.inputs.joints[0].torque, 0.0);
}

#[test]
fn injected_drive_fault_removes_torque_and_the_load_coasts_to_rest() {
    let mut bench = Bench::with_joints(vec![SimulatedJointConfig::with_drive(DriveMode::Velocity)]);
    bench.enable_all();
    bench.outputs.joints[0].target_velocity = 30.0;
    for _ in 0..100 {
        bench.cycle().unwrap();
    }
    bench
        .machine
        .inject(InjectedFault::DriveFault {
            joint: 0,
            error_code: 0x2310,
        })
        .unwrap();
    bench.cycle().unwrap();
    assert_eq!(bench.inputs.joints[0].error_code, 0x2310);
    assert_eq!(bench.inputs.joints[0].torque, 0.0);
    for _ in 0..2000 {
        bench.cycle().unwrap();
    }
    assert_eq!(
        bench.machine.true_state(0).unwrap().1,
        0.0,
        "friction stops it"
    );
    assert!(
        bench
            .machine
            .inject(InjectedFault::DriveFault {
                joint: 1,
                error_code: 1
            })
            .is_err()
    );
}

#[test]
fn communication_loss_fails_the_exchange_and_the_watchdog_faults_the_drives() {
    let mut bench = Bench::with_joints(vec![SimulatedJointConfig::with_drive(DriveMode::Velocity)]);
    bench.enable_all();
    bench.outputs.joints[0].target_velocity = 10.0;
    bench.cycle().unwrap();
    let before = bench.inputs.clone();
    bench
        .machine
        .inject(InjectedFault::CommunicationLoss)
        .unwrap();
    // The default watchdog is 0.1 s: 100 silent cycles.
    for _ in 0..99 {
        assert_eq!(bench.cycle(), Err(FieldbusError::CommunicationLost));
    }
    assert_eq!(
        bench.inputs, before,
        "inputs untouched while the bus is silent"
    );
    let moving = bench.machine.true_state(0).unwrap().1;
    assert!(
        close(moving, 10.0, 0.1),
        "the drive runs on its last command: {moving}"
    );
    assert_eq!(
        bench.cycle().unwrap_err().code(),
        "fieldbus.communication_lost"
    );
    bench
        .machine
        .clear(InjectedFault::CommunicationLoss)
        .unwrap();
    bench.cycle().unwrap();
    assert_eq!(bench.inputs.joints[0].state(), Cia402State::Fault);
    assert_eq!(bench.inputs.joints[0].error_code, error_code::COMMUNICATION);
}

#[test]
fn mismatched_images_and_bad_periods_are_errors() {
    let mut bench = Bench::with_joints(vec![SimulatedJointConfig::with_drive(DriveMode::Velocity)]);
    let mut short = ProcessInputs::new(bench.machine.layout());
    short.joints.clear();
    let error = bench
        .machine
        .exchange(T, &bench.outputs, &mut short)
        .unwrap_err();
    assert_eq!(
        error,
        FieldbusError::ImageMismatch {
            image: "inputs",
            what: "joints",
            expected: 1,
            found: 0
        }
    );
    for period in [0.0, -1.0, f64::NAN, 2.0] {
        let error = bench
            .machine
            .exchange(period, &bench.outputs, &mut bench.inputs)
            .unwrap_err();
        assert_eq!(error.code(), "fieldbus.invalid_period");
    }
}

#[test]
fn two_runs_with_the_same_outputs_give_identical_inputs() {
    let run = || {
        let mut bench = Bench::with_joints(vec![
            SimulatedJointConfig::with_drive(DriveMode::Velocity),
            SimulatedJointConfig::with_drive(DriveMode::Csp),
        ]);
        bench.enable_all();
        let mut trace = Vec::new();
        for k in 0..500 {
            let t = k as f64 * T;
            bench.outputs.joints[0].target_velocity = 40.0 * (7.0 * t).sin();
            bench.outputs.joints[1].target_position = 3.0 * (5.0 * t).sin();
            bench.cycle().unwrap();
            trace.push(bench.inputs.clone());
        }
        trace
    };
    assert!(run() == run());
}

#[test]
fn a_period_of_100_us_works_with_two_substeps() {
    let bench = Bench::with_joints(vec![]);
    assert_eq!(bench.machine.substeps_for(100e-6), 2);
    assert_eq!(bench.machine.substeps_for(1e-3), 16);
    assert_eq!(bench.machine.substeps_for(0.5e-3), 8);
}

#[test]
fn configuration_reads_from_toml_and_refusals_name_the_field() {
    let text = r#"
        substep_s = 5e-5
        [[joints]]
        drive = "csp"
        units_per_revolution = 10.0
        positive_limit_switch = 300.0
        home_switch = { from = 290.0, to = 295.0 }
        [joints.motor]
        inertia = 3e-4
        [[joints]]
        drive = "ideal"
        [io]
        digital_inputs = 8
    "#;
    let config: SimulatedMachineConfig = toml::from_str(text).unwrap();
    assert_eq!(config.joints[0].motor.inertia, 3e-4);
    assert_eq!(
        config.joints[0].motor.torque_limit, 3.8,
        "unset fields keep their defaults"
    );
    assert_eq!(config.io.digital_outputs, 16);
    let machine = SimulatedMachine::new(&config).unwrap();
    assert_eq!(machine.layout().joints, [DriveMode::Csp, DriveMode::Ideal]);

    let refused = |edit: &dyn Fn(&mut SimulatedMachineConfig)| {
        let mut bad = config.clone();
        edit(&mut bad);
        SimulatedMachine::new(&bad).unwrap_err().to_string()
    };
    assert_eq!(
        refused(&|c| c.joints[1].motor.inertia = 0.0),
        "joints[1].motor.inertia: must be greater than zero"
    );
    assert_eq!(
        refused(&|c| c.joints[0].velocity_loop_bandwidth_hz = 5000.0),
        "joints[0].velocity_loop_bandwidth_hz: at most 1592 Hz with substep_s = 0.00005 s"
    );
    assert_eq!(
        refused(&|c| c.joints[0].negative_limit_switch = Some(400.0)),
        "joints[0].positive_limit_switch: must be above negative_limit_switch"
    );
    assert_eq!(
        refused(&|c| c.substep_s = 0.01),
        "substep_s: must be between 1e-6 and 1e-3 s"
    );
    assert_eq!(
        refused(&|c| c.spindle.jerk_rpm_per_s2 = 0.0),
        "spindle.jerk_rpm_per_s2: must be greater than zero"
    );
    assert_eq!(
        refused(&|c| c.spindle.at_speed_tolerance = f64::NAN),
        "spindle.at_speed_tolerance: must be a finite number"
    );
    let unknown =
        toml::from_str::<SimulatedMachineConfig>("[[joints]]\ndrive = \"csp\"\ninertia = 1.0\n");
    assert!(
        unknown
            .unwrap_err()
            .to_string()
            .contains("unknown field `inertia`")
    );
    let bad_mode = toml::from_str::<SimulatedMachineConfig>("[[joints]]\ndrive = \"stepper\"\n");
    assert!(
        bad_mode
            .unwrap_err()
            .to_string()
            .contains("unknown variant `stepper`")
    );
}
