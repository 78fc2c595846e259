//! Every shipped machine file loads, validates and passes the power-up self-test; bad files
//! are refused naming the key and the reason.

mod common;
use common::repo;
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
            "experiment-1.toml",
            "sim-gantry-12.toml",
            "sim-lathe.toml",
            "sim-mill.toml"
        ]
    );
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

#[test]
fn ethercat_is_refused_as_not_available() {
    let text = mill_text().replace("kind = \"sim\"", "kind = \"ethercat\"");
    assert_eq!(
        refusal(&text),
        "fieldbus.kind: \"ethercat\" is not available yet in this build; use \"sim\""
    );
}

#[test]
fn an_axis_naming_a_missing_joint_is_refused() {
    let text = mill_text().replacen("joints = [\"Y\"]", "joints = [\"Q\"]", 1);
    assert_eq!(refusal(&text), "axes.y.joints: no joint named \"Q\"");
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
