//! Safety on the whole machine, in virtual time: e-stop, hard limit, following error, an
//! error in a block ahead, machine functions waiting for the logic.

use crate::common::*;
use rtcnc_fieldbus::sim::InjectedFault;
use rtcnc_kernel::{Command, FaultCode, MachineState, TaskName, Urgent};

const LONG_LINE: &str = "G21 G90 G61.1\nG1 X200 F3000\nM2\n";

/// Runs the long line, optionally pressing e-stop on the urgent channel after `at` cycles.
fn long_line(estop_after: Option<u64>) -> (Machine, u64) {
    let cfg = config("sim-mill.toml");
    let mut m = Machine::started(&cfg, LONG_LINE, "long-line.ngc");
    let mut put_period = 0;
    match estop_after {
        Some(n) => {
            m.cycles(n);
            put_period = m.sim.now().as_millis() as u64;
            assert!(m.sim.handle().urgent(Urgent::EStop));
            m.cycles(600);
        }
        None => m.cycles(n_cycles_for_reference()),
    }
    (m, put_period)
}

fn n_cycles_for_reference() -> u64 {
    1100
}

#[test]
fn estop_starts_the_stop_in_the_cycle_it_is_read_then_disables_the_drives() {
    let (reference, _) = long_line(None);
    let (stopped, put) = long_line(Some(500));
    // The e-stop was put into the urgent channel between periods `put - 1` and `put`. The
    // command parser reads it in period `put` (it runs after
    // interpolation within a period) and raises the stop; interpolation in period 501
    // computes the first set-point of the quick stop. Set-points carry the cycle number of
    // the interpolation run that made them (period p makes cycle p + 1).
    let first_difference = reference
        .samples
        .iter()
        .zip(&stopped.samples)
        .find(|(a, b)| a.setpoint[0] != b.setpoint[0])
        .map(|(_, b)| b.cycle)
        .expect("the stop changes the set-points");
    let received = stopped
        .faults
        .iter()
        .find(|f| f.code == FaultCode::EStop)
        .expect("e-stop fault");
    // Interpolation reads the urgent channel first thing in every period: the e-stop put
    // between periods `put - 1` and `put` is received in period `put`.
    assert_eq!(received.task, TaskName::Interpolation);
    assert_eq!(received.time_ns, put * 1_000_000);
    // The quick stop is requested before the planner computes period `put`'s set-point, so
    // that set-point (numbered put + 1: period p computes the set-point numbered p + 1,
    // which position control applies in period p + 1) is the first one of the stop: the
    // stop starts in the very cycle the e-stop is read.
    assert_eq!(first_difference, put + 1);
    // It is a stop: the speed falls monotonically to zero, and the drives are disabled.
    let v: Vec<f64> = stopped
        .samples
        .windows(2)
        .filter(|w| w[1].cycle > first_difference)
        .map(|w| (w[1].setpoint[0] - w[0].setpoint[0]) / 0.001)
        .collect();
    assert!(v.windows(2).all(|w| w[1] <= w[0] + 1e-9));
    assert_eq!(*v.last().unwrap(), 0.0);
    let status = stopped.status();
    assert_eq!(status.state, MachineState::EStop);
    assert_eq!(status.fault_count, 1);
    assert_eq!(status.last_fault.map(|f| f.code), Some(FaultCode::EStop));
    assert!(!status.ready);
    stopped
        .sim
        .handle()
        .simulated_machine()
        .unwrap()
        .with(|machine| assert!((0..3).all(|j| machine.true_state(j).unwrap().1.abs() < 1e-3)));
}

#[test]
fn a_hard_limit_switch_stops_the_machine_with_a_fault_naming_the_joint() {
    let text = std::fs::read_to_string(repo().join("configs/sim-mill.toml"))
        .unwrap()
        .replacen(
            "positive_limit_switch = 312.0",
            "positive_limit_switch = 50.0",
            1,
        );
    let mut cfg = rtcnc_kernel::MachineConfig::parse(&text, "limit.toml").unwrap();
    cfg.base_dir = repo().join("configs");
    let mut m = Machine::started(&cfg, LONG_LINE, "long-line.ngc");
    assert!(m.until(5.0, |s| s.state == MachineState::Fault));
    m.cycles(500);
    let f = m
        .faults
        .iter()
        .find(|f| f.code == FaultCode::HardLimit)
        .expect("hard limit fault");
    assert_eq!(f.joint, Some(0));
    assert_eq!(f.task, TaskName::DriveIo);
    assert!(f.value >= 50.0 && f.value < 50.2, "tripped at {}", f.value);
    let text = m.sim.handle().describe(f);
    assert!(
        text.starts_with("hard limit switch [kernel.hard_limit]"),
        "{text}"
    );
    assert!(text.contains("joint X"), "{text}");
    // Stopped: the load is at rest past the switch, the drives are off.
    let status = m.status();
    assert_eq!(status.state, MachineState::Fault);
    assert!(!status.ready);
    m.sim.handle().simulated_machine().unwrap().with(|machine| {
        let (x, v) = machine.true_state(0).unwrap();
        assert!(v.abs() < 1e-3 && x > 50.0 && x < 55.0, "x {x} v {v}");
    });
}

#[test]
fn a_following_error_stops_the_machine_with_a_fault_naming_the_joint() {
    let cfg = config("sim-mill.toml");
    let mut m = Machine::new(
        &cfg,
        Some(program(
            "G21 G90 G61.1\nG1 X100 Y100 F3000\nM2\n",
            "diag.ngc",
        )),
    );
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    m.cycles(800);
    m.sim.handle().simulated_machine().unwrap().with(|machine| {
        machine
            .inject(InjectedFault::EncoderLoss { joint: 1 })
            .unwrap()
    });
    assert!(m.until(1.0, |s| s.state == MachineState::Fault));
    m.cycles(1000);
    let f = m
        .faults
        .iter()
        .find(|f| f.code == FaultCode::FollowingError)
        .expect("following-error fault");
    assert_eq!(f.joint, Some(1));
    assert_eq!(f.task, TaskName::PositionControl);
    assert_eq!(f.line, 2);
    assert!(m.sim.handle().describe(f).contains("joint Y"));
    // The drives were quick-stopped: the table stands.
    m.sim.handle().simulated_machine().unwrap().with(|machine| {
        assert!((0..3).all(|j| machine.true_state(j).unwrap().1.abs() < 1e-3));
    });
    assert!(!m.status().ready);
}

#[test]
fn an_error_in_a_block_ahead_stops_the_machine_before_that_block_naming_its_line() {
    let text = "G21 G90 G61.1\nG1 X10 F3000\nG1 Y10\nG1 X0\nG1 Y0\nG1 X5 Y5 Z-1 Q\nG1 X50\nM2\n";
    let cfg = config("sim-mill.toml");
    let mut m = Machine::started(&cfg, text, "bad-line-6.ngc");
    m.cycles(20);
    // The interpreter is far ahead: the error is already known while line 2 moves.
    assert!(m.samples.last().unwrap().line == 2);
    assert!(m.until(5.0, |s| s.state == MachineState::Idle && s.line == 0));
    let f = m
        .faults
        .iter()
        .find(|f| f.code == FaultCode::ProgramError)
        .expect("error in program");
    assert_eq!(f.line, 6);
    assert_eq!(f.task, TaskName::LookAhead);
    let text = m.sim.handle().describe(f);
    assert!(text.starts_with("error in program"), "{text}");
    assert!(text.contains("line 6"), "{text}");
    // Lines 2 to 5 ran to their ends; nothing of line 6 moved.
    assert!(m.samples.iter().all(|s| s.line <= 5));
    let last = m.samples.last().unwrap();
    assert_eq!(&last.axes[..3], &[0.0, 0.0, 0.0]);
    let words = m.sim.handle().error_text().unwrap();
    assert!(words.contains(":6:"), "{words}");
}

#[test]
fn a_tool_change_waits_for_the_machine_logic_before_motion_continues() {
    // The kernel's direct logic (no [plc]) with the simulated timed changer of 1.5 s;
    // the mill's own logic and carousel are tested in mill_logic.rs.
    let text = "G21 G90 G61.1\nG1 X10 F3000\nT2 M6\nG1 X20\nM2\n";
    let mut cfg = config("sim-mill.toml");
    cfg.plc = None;
    cfg.tool_changer = Some(rtcnc_kernel::config::ToolChangerSection {
        change_time_s: 1.5,
        initial_tool: 1,
    });
    let mut m = Machine::started(&cfg, text, "tool.ngc");
    assert!(m.until(10.0, |s| s.program_ended && s.state == MachineState::Idle));
    let arrived = m.samples.iter().position(|s| s.axes[0] == 10.0).unwrap();
    let left = m.samples.iter().position(|s| s.axes[0] > 10.0).unwrap();
    let waited = (left - arrived) as f64 * 0.001;
    assert!((1.5..1.6).contains(&waited), "waited {waited} s");
    assert_eq!(m.status().tool, 2);
    assert!(
        m.faults.iter().all(|f| f.code == FaultCode::CommandRefused),
        "{:?}",
        m.faults
    );
}

#[test]
fn a_move_beyond_a_soft_limit_is_refused_before_the_machine_gets_there() {
    let text = "G21 G90 G61.1\nG1 X50 F3000\nG1 X400\nM2\n";
    let cfg = config("sim-mill.toml");
    let mut m = Machine::started(&cfg, text, "far.ngc");
    m.cycles(50);
    assert!(m.until(5.0, |s| s.state == MachineState::Idle && s.line == 0));
    let f = m
        .faults
        .iter()
        .find(|f| f.code == FaultCode::MotionError)
        .expect("refused move");
    assert_eq!(f.line, 3);
    let words = m.sim.handle().error_text().unwrap();
    assert!(words.contains("soft limit"), "{words}");
    let max_x = m.samples.iter().map(|s| s.axes[0]).fold(f64::MIN, f64::max);
    assert_eq!(max_x, 50.0);
}

/// The configured deadline-miss reaction: with `safety.deadline_miss = "feed_hold"`, an
/// interpolation task that declares 1.2 ms of work per 1 ms period misses its deadlines,
/// the misses are recorded, and the reaction holds the feed of the running program.
#[test]
fn a_deadline_miss_triggers_the_configured_reaction() {
    let text = std::fs::read_to_string(repo().join("configs/sim-mill.toml"))
        .unwrap()
        .replace("deadline_miss = \"warn\"", "deadline_miss = \"feed_hold\"");
    let mut cfg = rtcnc_kernel::MachineConfig::parse(&text, "miss.toml").unwrap();
    cfg.base_dir = repo().join("configs");
    let kernel = rtcnc_kernel::Kernel::build(
        &cfg,
        rtcnc_kernel::KernelOptions {
            program: Some(program(LONG_LINE, "long-line.ngc")),
            interpolation_load: Some(std::time::Duration::from_micros(1200)),
            ..Default::default()
        },
    )
    .unwrap();
    let mut sim = rtcnc_kernel::Simulation::new(kernel);
    let handle = sim.handle().clone();
    let mut none = |_: &rtcnc_kernel::Sample| {};
    sim.run_cycles(2, &mut none).unwrap();
    handle.command(Command::Reset);
    sim.run_until(std::time::Duration::from_secs(1), &mut none, |s| s.ready)
        .unwrap();
    handle.command(Command::Start { from_line: 0 });
    let held = sim
        .run_until(std::time::Duration::from_secs(5), &mut none, |s| {
            s.state == MachineState::Held
        })
        .unwrap();
    assert!(held, "{:?}", handle.status());
    let misses = sim
        .runner()
        .recording()
        .monitor()
        .task("interpolation")
        .unwrap()
        .stats()
        .deadline_misses;
    assert!(misses > 0);
}

#[test]
fn a_background_check_notices_a_persistent_files_folder_that_went_away() {
    let dir = std::env::temp_dir().join(format!("rtcnc-bg-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut cfg = config("sim-mill.toml");
    cfg.files.parameters = Some(dir.join("mill.var"));
    let mut m = Machine::new(&cfg, None);
    m.power_on();
    m.cycles(1200);
    assert!(
        m.faults
            .iter()
            .all(|f| f.code != FaultCode::BackgroundCheck)
    );
    std::fs::remove_dir_all(&dir).unwrap();
    m.cycles(1200);
    let f = m
        .faults
        .iter()
        .find(|f| f.code == FaultCode::BackgroundCheck)
        .expect("background check fault");
    assert_eq!(f.task, TaskName::BackgroundCheck);
    assert_eq!(f.value, 2.0);
    // It is reported, not a reason to stop the machine.
    assert_eq!(m.status().state, MachineState::Idle);
}

#[test]
fn m66_waits_for_a_digital_input_or_its_timeout() {
    // P0 is digital input 8 (io.program_inputs of sim-mill.toml).
    let text = "G21 G90 G61.1\nG1 X10 F3000\nM66 P0 L3 Q5\nG1 X20\nM66 P1 L3 Q0.5\nG1 X30\nM2\n";
    let cfg = config("sim-mill.toml");
    let mut m = Machine::started(&cfg, text, "m66.ngc");
    assert!(m.until(3.0, |s| s.axes[0] == 10.0 && s.path_speed == 0.0));
    m.cycles(1000);
    // Still waiting for the input after a second.
    assert_eq!(m.status().axes[0], 10.0);
    m.sim
        .handle()
        .simulated_machine()
        .unwrap()
        .with(|machine| machine.set_digital_input(8, true).unwrap());
    assert!(m.until(3.0, |s| s.axes[0] == 20.0 && s.path_speed == 0.0));
    // P1 (input 9) never comes: the program goes on after the 0.5 s timeout.
    let arrived = m.samples.len();
    assert!(m.until(5.0, |s| s.program_ended && s.state == MachineState::Idle));
    let left = m.samples[arrived..]
        .iter()
        .position(|s| s.axes[0] > 20.0)
        .unwrap();
    assert!(
        (500..520).contains(&left),
        "left {left} periods after arriving"
    );
    assert_eq!(m.status().axes[0], 30.0);
}

#[test]
fn a_probing_move_without_a_probe_input_stops_the_program_before_it() {
    // G38.2 needs a probe input (io.probe_input), taken away from the simulated mill here:
    // running it as a plain feed would drive the stylus into the part, so the program
    // stops at the end of line 2.
    let text = "G21 G90 G61.1\nG1 X10 F3000\nG38.2 Z-5 F100\nG1 X20\nM2\n";
    let mut cfg = config("sim-mill.toml");
    cfg.io.probe_input = None;
    let mut m = Machine::started(&cfg, text, "probe.ngc");
    assert!(m.until(5.0, |s| s.state == MachineState::Idle && s.line == 0));
    let f = m
        .faults
        .iter()
        .find(|f| f.code == FaultCode::ProbeFailed)
        .expect("probe failed");
    assert_eq!(f.line, 3);
    assert_eq!(
        rtcnc_kernel::ProbeFailure::from_value(f.value),
        Some(rtcnc_kernel::ProbeFailure::NoProbeInput)
    );
    // Line 2 ran to its end (X10); nothing of line 3 or later moved.
    assert!(m.samples.iter().all(|s| s.line <= 2));
    let last = m.samples.last().unwrap();
    assert_eq!(&last.axes[..3], &[10.0, 0.0, 0.0]);
}

#[test]
fn a_spline_whose_bulge_leaves_the_envelope_is_refused_with_its_line() {
    // Both ends at Y0, inner control points at Y270: the curve's top is at 3/4 of that,
    // Y202.5, beyond the mill's Y200.
    let text = "G21 G90 G17 G61.1\nG1 X50 F3000\nG5 I0 J270 P0 Q270 X100 Y0\nM2\n";
    let cfg = config("sim-mill.toml");
    let mut m = Machine::started(&cfg, text, "bulge.ngc");
    m.cycles(50);
    assert!(m.until(5.0, |s| s.state == MachineState::Idle && s.line == 0));
    let f = m
        .faults
        .iter()
        .find(|f| f.code == FaultCode::MotionError)
        .expect("refused spline");
    assert_eq!(f.line, 3);
    let words = m.sim.handle().error_text().unwrap();
    assert!(
        words.contains("soft limit") && words.contains("202.5"),
        "{words}"
    );
    let max_y = m.samples.iter().map(|s| s.axes[1]).fold(f64::MIN, f64::max);
    assert_eq!(max_y, 0.0);
}
