//! Every shipped machine file loads, validates and passes the power-up self-test; bad files
//! are refused naming the key and the reason.

use crate::common::repo;
use rtcnc_kernel::{Kernel, KernelOptions, MachineConfig};

#[test]
fn every_shipped_configuration_builds_a_kernel() {
    let mut names = Vec::new();
    for entry in std::fs::read_dir(repo().join("configs")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            let config =
                MachineConfig::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            let kernel = Kernel::build(&config, KernelOptions::default())
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            assert!(kernel.self_test.checks.iter().any(|(c, _)| *c == "ready"));
            names.push(path.file_name().unwrap().to_string_lossy().into_owned());
        }
    }
    names.sort();
    assert_eq!(
        names,
        [
            "bench-xyz.toml",
            "ethercat-sim-12.toml",
            "experiment-1.toml",
            "sim-5axis-head.toml",
            "sim-5axis-trt.toml",
            "sim-gantry-12.toml",
            "sim-lathe.toml",
            "sim-mill-carousel.toml",
            "sim-mill.toml"
        ]
    );
}

/// `[kinematics]`: a table or head kinematics needs its five axes with one joint each,
/// and takes only its own parameters and a positive tolerance.
#[test]
fn a_five_axis_kinematics_is_checked() {
    let trt = std::fs::read_to_string(repo().join("configs/sim-5axis-trt.toml")).unwrap();
    let without_c = trt.replace("[axes.c]", "[axes.b]");
    assert_eq!(refusal(&without_c), "kinematics.kind: needs an axis C");
    let x_offset = trt.replace("y_offset = 20.0", "y_offset = 20.0\nx_offset = 1.0");
    assert_eq!(
        refusal(&x_offset),
        "kinematics.x_offset: this kinematics has no such parameter"
    );
    let tolerance = trt.replace("tolerance = 0.001", "tolerance = 0.0");
    assert_eq!(
        refusal(&tolerance),
        "kinematics.tolerance: must be greater than zero"
    );
    let unknown = trt.replace("kind = \"xyzac-trt\"", "kind = \"hexapod\"");
    assert!(refusal(&unknown).contains("unknown variant `hexapod`"));
    let bc = trt
        .replace("kind = \"xyzac-trt\"", "kind = \"xyzbc-trt\"")
        .replace("y_offset = 20.0", "x_offset = 20.0")
        .replace("[axes.a]", "[axes.b]")
        .replace("joints = [\"A\"]", "joints = [\"B\"]")
        .replace("name = \"A\"", "name = \"B\"");
    MachineConfig::parse(&bc, "test.toml").expect("an xyzbc-trt machine");
    let pivot = trt.replace("z_offset = 10.0", "z_offset = 10.0\npivot_length = 100.0");
    assert_eq!(
        refusal(&pivot),
        "kinematics.pivot_length: this kinematics has no such parameter"
    );
    let head = std::fs::read_to_string(repo().join("configs/sim-5axis-head.toml")).unwrap();
    MachineConfig::parse(&head, "test.toml").expect("an xyzbc-head machine");
    let rot_point = head.replace(
        "pivot_length = 100.0",
        "pivot_length = 100.0\nz_rot_point = 5.0",
    );
    assert_eq!(
        refusal(&rot_point),
        "kinematics.z_rot_point: this kinematics has no such parameter"
    );
    let infinite = head.replace("pivot_length = 100.0", "pivot_length = inf");
    assert_eq!(
        refusal(&infinite),
        "kinematics.pivot_length: must be a finite number"
    );
    let without_b = head.replace("[axes.b]", "[axes.a]");
    assert_eq!(refusal(&without_b), "kinematics.kind: needs an axis B");
}

fn mill_text() -> String {
    std::fs::read_to_string(repo().join("configs/sim-mill.toml")).unwrap()
}

fn refusal(text: &str) -> String {
    match MachineConfig::parse(text, "test.toml") {
        Ok(_) => panic!("accepted"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn a_zero_limit_is_refused_naming_the_key() {
    let text = mill_text().replacen("max_velocity = 100.0", "max_velocity = 0.0", 1);
    assert_eq!(
        refusal(&text),
        "axes.x.max_velocity: must be greater than zero"
    );
}

#[test]
fn an_unknown_key_is_refused_naming_it() {
    let text = mill_text().replacen(
        "max_jerk = 50000.0",
        "max_jerk = 50000.0\nmax_jerks = 1.0",
        1,
    );
    let e = refusal(&text);
    assert!(e.contains("unknown field `max_jerks`"), "{e}");
    assert!(e.starts_with("test.toml:"), "{e}");
}

fn ethercat_text() -> String {
    std::fs::read_to_string(repo().join("configs/ethercat-sim-12.toml")).unwrap()
}

/// The template for real drives loads and validates (it is not built: that opens its
/// network interface).
#[test]
fn the_real_drive_template_validates() {
    let path = repo().join("configs/templates/ethercat-drives.toml");
    let config = MachineConfig::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let section = config
        .fieldbus
        .ethercat
        .as_ref()
        .expect("an EtherCAT section");
    assert!(section.simulation.is_none());
    assert!(config.joints.iter().all(|j| j.sim.is_none()));
    // In virtual time (rtcnc sim, a preview) it runs on simulated CSP drives instead of
    // opening its bus.
    let copy = config.for_virtual_time();
    assert!(copy.fieldbus.ethercat.is_none());
    let kernel = Kernel::build(&copy, KernelOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    assert!(kernel.self_test.checks.iter().any(|(c, _)| *c == "ready"));
}

#[test]
fn an_ethercat_machine_file_is_checked_against_the_bus() {
    let cases = [
        // A key of the simulated machine in the EtherCAT section.
        (
            (
                "kind = \"ethercat\"",
                "kind = \"ethercat\"\nsubstep_s = 0.001",
            ),
            "fieldbus.substep_s: unknown field `substep_s`",
        ),
        (
            ("drift_ppm = 20.0", "drift_ppm = 20.0\nloss = 1"),
            "fieldbus.simulation.loss: unknown field `loss`",
        ),
        (
            ("joint = 11\n", "joint = 10\n"),
            "fieldbus.slaves[11].joint: another drive has it",
        ),
        (
            ("joint = 11\n", "joint = 12\n"),
            "fieldbus.slaves: joints must be numbered 0 to 11 without a gap: no joint 11",
        ),
        (
            ("digital_inputs = 8", "digital_inputs = 16"),
            "io.digital_inputs: 16, but the EtherCAT terminals give 8",
        ),
        (
            ("working_counter_limit = 3", "working_counter_limit = 0"),
            "fieldbus.working_counter_limit: must be at least 1",
        ),
        (
            (
                "counts_per_unit = 26214.4\nrated_torque_nm = 1.27\n\n[[fieldbus.slaves]]\nkind = \"cia402\"\nname = \"X1\"",
                "counts_per_unit = 1000.0\nrated_torque_nm = 1.27\n\n[[fieldbus.slaves]]\nkind = \"cia402\"\nname = \"X1\"",
            ),
            "fieldbus.slaves[0].counts_per_unit: 1000 is not the simulated drive's 26214.4 (encoder_counts_per_revolution / units_per_revolution of joint 0)",
        ),
    ];
    for ((from, to), expected) in cases {
        let text = ethercat_text();
        assert!(text.contains(from), "{from}");
        let e = refusal(&text.replacen(from, to, 1));
        assert!(e.contains(expected), "{e:?} does not say {expected:?}");
    }
    // Every joint needs its drive.
    let text = ethercat_text();
    let p2 = text
        .find("[[fieldbus.slaves]]\nkind = \"cia402\"\nname = \"P2\"")
        .unwrap();
    let next = p2 + text[p2 + 1..].find("[[fieldbus.slaves]]").unwrap() + 1;
    assert_eq!(
        refusal(&format!("{}{}", &text[..p2], &text[next..])),
        "fieldbus.slaves: no drive moves joint 11 (P2)"
    );
    // An index latch over EtherCAT needs the drive's touch probe objects in its PDOs.
    let text = ethercat_text().replacen("use_index = false, ", "", 1);
    assert!(
        refusal(&text).starts_with(
            "fieldbus.slaves[0]: drive X0 (joint 0) does not map 0x60B8 touch probe function (rx_pdo \"touch_probe_function\"), which joints[0].homing.use_index needs"
        ),
        "{}",
        refusal(&text)
    );
    // A position loop of the controller's own cannot drive a CSP drive.
    let text = ethercat_text().replacen(
        "servo = { loop = \"csp\", following_error",
        "servo = { loop = \"pid\", following_error",
        1,
    );
    assert_eq!(
        refusal(&text),
        "joints[0].servo.loop: EtherCAT drives run in cyclic synchronous position: \"csp\""
    );
    // The simulated devices need each joint's simulated drive, hardware does not.
    let without_sim = ethercat_text().replacen(
        "sim = { drive = \"csp\", initial_position = 0.3,",
        "# sim = {",
        1,
    );
    assert_eq!(
        refusal(&without_sim),
        "joints[1].sim: the simulated drive is required on a simulated machine"
    );
    let hardware = without_sim.replacen("[fieldbus.simulation]\ndrift_ppm = 20.0\n", "", 1);
    MachineConfig::parse(&hardware, "test.toml").expect("hardware needs no simulated drive");
}

#[test]
fn an_axis_naming_a_missing_joint_is_refused() {
    let text = mill_text().replacen("joints = [\"Y\"]", "joints = [\"Q\"]", 1);
    assert_eq!(refusal(&text), "axes.y.joints: no joint named \"Q\"");
}

#[test]
fn a_plc_axis_needs_a_free_joint_without_a_homing_of_the_kernels() {
    let carousel = std::fs::read_to_string(repo().join("configs/sim-mill-carousel.toml")).unwrap();
    assert!(MachineConfig::parse(&carousel, "test.toml").is_ok());
    let on = |joint: &str| {
        carousel.replace(
            "[plc.axes.carousel]\njoint = \"T\"",
            &format!("[plc.axes.carousel]\njoint = \"{joint}\""),
        )
    };
    assert_eq!(
        refusal(&on("Q")),
        "plc.axes.carousel.joint: no joint named Q"
    );
    assert_eq!(
        refusal(&on("X")),
        "plc.axes.carousel.joint: joint X is driven by axis x, not free for the PLC"
    );
    let homed = carousel.replace(
        "sim = { drive = \"velocity\" }\nlimits",
        "sim = { drive = \"velocity\" }\nhoming = { sequence = 2, search_velocity = 10.0, latch_velocity = 1.0, latch_position = 0.0, home_position = 0.0 }\nlimits",
    );
    assert_eq!(
        refusal(&homed),
        "plc.axes.carousel.joint: joint T has a homing sequence; the PLC homes its axes (MC_Home)"
    );
    let twice = carousel.replace(
        "[plc.axes.carousel]\njoint = \"T\"",
        "[plc.axes.carousel]\njoint = \"T\"\n[plc.axes.other]\njoint = \"T\"",
    );
    assert_eq!(
        refusal(&twice),
        "plc.axes.other.joint: joint T is taken by another PLC axis"
    );
    assert_eq!(
        refusal(&on("T\"\nmodulo = \"0").replace("\"0\"", "0.0")),
        "plc.axes.carousel.modulo: must be greater than zero"
    );
}

#[test]
fn interpolation_must_run_at_the_servo_period() {
    let text = mill_text().replace(
        "interpolation = { period = \"1ms\", priority = 124 }",
        "interpolation = { period = \"2ms\", priority = 124 }",
    );
    assert!(refusal(&text).starts_with("tasks.interpolation.period: "));
}

#[test]
fn a_servo_gain_is_checked_by_the_servo_library_and_named_in_full() {
    let text = mill_text().replacen(
        "acceleration_ff = 0.001",
        "acceleration_ff = 0.001, p = -1.0",
        1,
    );
    assert_eq!(
        refusal(&text),
        "joints[0].servo.gains.p: must not be negative"
    );
}

#[test]
fn a_simulated_drive_value_is_named_in_full() {
    let text = mill_text().replacen(
        "sim = { drive = \"velocity\", ",
        "sim = { drive = \"velocity\", units_per_revolution = -5.0, ",
        1,
    );
    assert_eq!(
        refusal(&text),
        "joints[0].sim.units_per_revolution: must be greater than zero"
    );
}

#[test]
fn a_spindle_jerk_out_of_range_is_named() {
    for bad in ["0.0", "-480000.0", "nan", "inf"] {
        let text = mill_text().replacen(
            "jerk_rpm_per_s2 = 480000.0",
            &format!("jerk_rpm_per_s2 = {bad}"),
            1,
        );
        let refused = refusal(&text);
        assert!(
            refused.starts_with("spindle.jerk_rpm_per_s2: must be"),
            "{bad}: {refused}"
        );
    }
}

#[test]
fn a_100_microsecond_servo_period_is_accepted() {
    let text = mill_text()
        .replace(
            "fieldbus = { period = \"1ms\"",
            "fieldbus = { period = \"100us\"",
        )
        .replace(
            "interpolation = { period = \"1ms\"",
            "interpolation = { period = \"100us\"",
        );
    let mut config = MachineConfig::parse(&text, "t").unwrap();
    config.base_dir = repo().join("configs");
    assert_eq!(config.servo_period(), std::time::Duration::from_micros(100));
    Kernel::build(&config, KernelOptions::default()).unwrap();
}

#[test]
fn below_half_a_millisecond_interpolation_runs_in_the_fieldbus_thread_unless_configured() {
    use std::time::Duration;
    let mut t = MachineConfig::load(&repo().join("configs/sim-mill.toml"))
        .unwrap()
        .tasks;
    assert_eq!(t.interpolation_in_fieldbus_thread, None);
    assert!(!t.interpolation_in_fieldbus_thread(Duration::from_millis(1)));
    assert!(!t.interpolation_in_fieldbus_thread(Duration::from_micros(500)));
    assert!(t.interpolation_in_fieldbus_thread(Duration::from_micros(250)));
    assert!(t.interpolation_in_fieldbus_thread(Duration::from_micros(100)));
    t.interpolation_in_fieldbus_thread = Some(false);
    assert!(!t.interpolation_in_fieldbus_thread(Duration::from_micros(100)));
    t.interpolation_in_fieldbus_thread = Some(true);
    assert!(t.interpolation_in_fieldbus_thread(Duration::from_millis(1)));
}

#[derive(Clone, Copy)]
enum Arrangement {
    SeparateThread,
    InFieldbusThread,
    /// Interpolation's thread above the fieldbus thread: every period it runs before the
    /// exchange, as it may on another processor.
    SeparateThreadFirst,
}

#[test]
fn interpolation_may_run_in_the_fieldbus_thread_or_before_it_with_the_same_results() {
    use rtcnc_kernel::{Command, MachineState, Simulation};
    let run = |arrangement: Arrangement| {
        let mut cfg = MachineConfig::load(&repo().join("configs/experiment-1.toml")).unwrap();
        cfg.tasks.interpolation_in_fieldbus_thread =
            Some(matches!(arrangement, Arrangement::InFieldbusThread));
        if let Arrangement::SeparateThreadFirst = arrangement {
            cfg.tasks.interpolation.priority = cfg.tasks.fieldbus.priority + 1;
        }
        let kernel = Kernel::build(
            &cfg,
            KernelOptions {
                program: Some(repo().join("examples/experiment-1.ngc")),
                record_capacity: 4096,
                ..KernelOptions::default()
            },
        )
        .unwrap();
        let mut sim = Simulation::new(kernel);
        let h = sim.handle().clone();
        let mut samples = Vec::new();
        let mut sink = |s: &rtcnc_kernel::Sample| samples.push((s.cycle, s.setpoint[0]));
        sim.run_cycles(2, &mut sink).unwrap();
        h.command(Command::Reset);
        sim.run_cycles(10, &mut sink).unwrap();
        h.command(Command::Start { from_line: 0 });
        let ended = sim
            .run_until(std::time::Duration::from_secs(2), &mut sink, |s| {
                s.program_ended && s.state == MachineState::Idle
            })
            .unwrap();
        assert!(ended);
        // Position control had this period's set-point in every period.
        assert_eq!(h.setpoint_underruns(), 0);
        samples
    };
    let separate = run(Arrangement::SeparateThread);
    let shared = run(Arrangement::InFieldbusThread);
    let first = run(Arrangement::SeparateThreadFirst);
    // The set-point of every cycle is the same; only the thread that computes it, and
    // when, differs: position control takes each exchange's own set-point from the lead
    // queue, whether interpolation ran before it in the period or after it.
    assert_eq!(separate.len(), shared.len());
    assert!(separate == shared);
    assert_eq!(first.len(), separate.len());
    assert!(separate == first);
}

#[test]
fn the_mill_runs_mill_st_with_the_signal_map_of_mill_toml() {
    let config = MachineConfig::load(&repo().join("configs/sim-mill.toml")).unwrap();
    let plc = config.plc.as_ref().expect("the mill has a machine logic");
    assert_eq!(
        config.resolve(&plc.program),
        repo().join("configs/../examples/plc/mill.st")
    );
    let text = std::fs::read_to_string(repo().join("examples/plc/mill.toml")).unwrap();
    let example: rtcnc_plc::PlcConfig = toml::from_str(&text).unwrap();
    assert_eq!(plc.signals, example.signals);
    assert_eq!(plc.safe_values, example.safe_values);
    assert!(!repo().join("examples/plc/sim-mill.st").exists());
}

#[test]
fn a_simulated_device_on_a_missing_input_is_refused_naming_the_key() {
    let text = mill_text().replacen(
        "kind = \"estop_contact\"\ninput = 0",
        "kind = \"estop_contact\"\ninput = 40",
        1,
    );
    assert_eq!(
        refusal(&text),
        "fieldbus.devices[0]: digital input 40 is outside the 32 inputs"
    );
}

#[test]
fn servo_periods_outside_the_executives_range_are_refused() {
    // 1 ns hung the simulation (10^9 periods per simulated second); 1 µs gave set-point
    // jerks of 130 000 000 against a limit of 50 000.
    for period in ["1ns", "1us", "20us", "11ms"] {
        let text = mill_text()
            .replace(
                "fieldbus = { period = \"1ms\"",
                &format!("fieldbus = {{ period = \"{period}\""),
            )
            .replace(
                "interpolation = { period = \"1ms\"",
                &format!("interpolation = {{ period = \"{period}\""),
            );
        let refused = refusal(&text);
        assert!(refused.starts_with("tasks.fieldbus.period: "), "{refused}");
        assert!(refused.contains("50µs..=10ms"), "{refused}");
    }
    let text = mill_text().replace(
        "status_feedback = { period = \"1ms\"",
        "status_feedback = { period = \"2s\"",
    );
    assert!(refusal(&text).starts_with("tasks.status_feedback.period: "));
}

#[test]
fn a_quick_stop_softer_than_a_normal_stop_is_refused() {
    // A hard-limit trip at 100 mm/s ended 104 mm past the switch instead of 4.2 mm.
    let text = mill_text().replacen(
        "quick_stop_acceleration = 2000.0",
        "quick_stop_acceleration = 10.0",
        1,
    );
    assert_eq!(
        refusal(&text),
        "axes.x.quick_stop_acceleration: 10 is below max_acceleration (1000): a quick stop \
         must brake at least as hard as a normal one"
    );
    let text = mill_text().replacen("quick_stop_jerk = 100000.0", "quick_stop_jerk = 1.0", 1);
    assert!(refusal(&text).starts_with("axes.x.quick_stop_jerk: 1 is below max_jerk"));
}

#[test]
fn relations_between_keys_are_checked() {
    let text = mill_text().replacen(
        "max_jerk = 50000.0",
        "max_jerk = 50000.0\njog_velocity = 500.0",
        1,
    );
    assert_eq!(
        refusal(&text),
        "axes.x.jog_velocity: 500 is above max_velocity (100)"
    );
    let text = mill_text().replacen("home_position = 0.0", "home_position = 1000.0", 1);
    assert!(
        refusal(&text).starts_with("joints[0].homing.home_position: 1000 is outside"),
        "{}",
        refusal(&text)
    );
}
