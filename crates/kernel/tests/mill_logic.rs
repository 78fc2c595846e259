//! The simulated mill (configs/sim-mill.toml) running its machine logic,
//! examples/plc/mill.st, against the simulated machine's devices, in virtual time.
//!
//! Every expectation is worked out by hand from the program's timers and the devices'
//! timing, on the kernel's schedule: in a servo period n (release time n ms) the fieldbus
//! thread exchanges first, then the machine logic reads that exchange's inputs and scans
//! (mill.st's task runs every 4 ms, i.e. in the periods n ≡ 0 mod 4), then interpolation,
//! then look-ahead (the hand-shakes), then command parsing. What the logic writes in period
//! n reaches the machine in the exchange of period n + 1. A device delay d seen from an
//! output first exchanged in period k ends in the exchange of period k − 1 + d / 1 ms.

use crate::common::*;
use rtcnc_fieldbus::sim::InjectedFault;
use rtcnc_kernel::{Command, FaultCode, MachineState, TaskName, Urgent};

// mill.st's I/O: %IX0.b is digital input b, %QX0.b output b, %QX1.b output 8 + b.
const PRESSURE: usize = 2;
const CLAMPED: usize = 3;
const UNCLAMPED: usize = 4;
const SAFETY_RELAY: usize = 0;
const SPINDLE_FWD: usize = 1;
const LUBE_PUMP: usize = 5;
const UNCLAMP_VALVE: usize = 7;
const CAROUSEL_MOTOR: usize = 8;
const AIR_BLAST: usize = 9;

// mill.st's fault codes.
const FAULT_TOOL_CHANGE: f64 = 2.0;
const FAULT_LUBE: f64 = 3.0;

fn mill(text: &str, name: &str) -> Machine {
    let cfg = config("sim-mill.toml");
    assert!(cfg.plc.as_ref().unwrap().program.ends_with("mill.st"));
    Machine::new(&cfg, Some(program(text, name)))
}

/// Runs one servo period; returns its number (its release time in ms).
fn step(m: &mut Machine) -> u64 {
    let n = m.sim.now().as_millis() as u64;
    m.cycles(1);
    n
}

/// Runs periods until `done` holds after one; returns that period.
fn until(m: &mut Machine, limit: u64, mut done: impl FnMut(&Machine) -> bool) -> u64 {
    for _ in 0..limit {
        let n = step(m);
        if done(m) {
            return n;
        }
    }
    panic!("not within {limit} periods: {:?}", m.status());
}

/// Digital output `i` as the machine received it in the last exchange.
fn output(m: &Machine, i: usize) -> bool {
    m.sim
        .handle()
        .simulated_machine()
        .unwrap()
        .with(|machine| machine.digital_output(i).unwrap())
}

/// Digital input `i` as the machine reported it in the last exchange.
fn input(m: &Machine, i: usize) -> bool {
    m.sim
        .handle()
        .simulated_machine()
        .unwrap()
        .with(|machine| machine.digital_input(i).unwrap())
}

fn next_scan(n: u64) -> u64 {
    n.div_ceil(4) * 4
}

#[test]
fn m3_waits_for_the_logic_to_report_the_spindle_at_speed_before_motion_continues() {
    let mut m = mill("G21 G90 G61.1\nS5000 M3\nG1 X1 F600\nM2\n", "m3.ngc");
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    // The scan of period a enables the spindle; the drive gets it in period a + 1 and
    // ramps along an S-curve (12 000 rpm/s, 480 000 rpm/s²): 480000 · 0.001² / 2 rpm in
    // the first period.
    let a = until(&mut m, 1000, |m| output(m, SPINDLE_FWD)) - 1;
    assert_eq!(a % 4, 0);
    assert!((m.status().spindle_rpm - 0.24).abs() < 1e-9);
    // The ramp lasts 5000/12000 + 12000/480000 = 0.441667 s and its last 25 ms are
    // 5000 − 240000·(0.441667 − t)² (from 4850 on): after 422 periods 4907.17 rpm is the
    // first speed within mill.st's 2 % of 5000 (100 rpm; 4897.5 after 421 is not); the
    // next scan, a + 424, starts SPINDLE_SETTLE_TIME (200 ms): at speed in the scan of
    // a + 624, which also drops the feed hold. Look-ahead releases the move in that
    // period; interpolation moves in a + 625.
    let end = 5000.0 / 12000.0 + 12000.0 / 480000.0;
    let at = |k: f64| 5000.0 - 240000.0 * (end - k / 1000.0) * (end - k / 1000.0);
    while m.sim.now().as_millis() as u64 <= a + 421 {
        step(&mut m);
    }
    assert!((m.status().spindle_rpm - at(421.0)).abs() < 1e-6);
    assert!(m.status().spindle_rpm < 4900.0);
    step(&mut m);
    assert!((m.status().spindle_rpm - at(422.0)).abs() < 1e-6);
    assert!(m.status().spindle_rpm >= 4900.0);
    let moved = until(&mut m, 1000, |m| m.status().axes[0] > 0.0);
    assert_eq!(moved, a + 625);
    assert!(m.until(5.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert_eq!(m.status().axes[0], 1.0);
    assert!(m.faults.is_empty(), "{:?}", m.faults);
}

#[test]
fn t2_m6_runs_the_carousel_sequence_of_the_logic_and_motion_waits_for_it() {
    let text = "G21 G90 G61.1\nG1 X1 F600\nT2 M6\nG1 X2\nM2\n";
    let mut m = mill(text, "t2m6.ngc");
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    // The scan s that sees the request goes to TC_UNCLAMP; the scan s + 4 opens the
    // unclamp valve, which the machine gets in period s + 5 = v.
    let v = until(&mut m, 5000, |m| output(m, UNCLAMP_VALVE));
    let s = v - 5;
    assert_eq!(s % 4, 0);
    assert_eq!(m.status().axes[0], 1.0);
    assert!(!input(&m, CLAMPED), "the clamped sensor drops at once");
    // Unclamped 0.3 s later, in period v + 299 = s + 304 (a scan): TC_ROTATE; the scan of
    // s + 308 starts the carousel motor (pocket 1 is not pocket 2), exchanged in s + 309.
    let unclamped = until(&mut m, 1000, |m| input(m, UNCLAMPED));
    assert_eq!(unclamped, s + 304);
    let motor_on = until(&mut m, 1000, |m| output(m, CAROUSEL_MOTOR));
    assert_eq!(motor_on, s + 309);
    // One pocket takes 0.2 s: pocket 2 in position in period s + 309 + 199 = s + 508, a
    // scan, which stops the motor (exchanged in s + 509) and goes to TC_CLAMP; the scan of
    // s + 512 closes the valve (exchanged in s + 513).
    let motor_off = until(&mut m, 1000, |m| !output(m, CAROUSEL_MOTOR));
    assert_eq!(motor_off, s + 509);
    m.sim
        .handle()
        .simulated_machine()
        .unwrap()
        .with(|machine| assert_eq!(machine.carousel_pocket(), Some(2)));
    let valve_closed = until(&mut m, 1000, |m| !output(m, UNCLAMP_VALVE));
    assert_eq!(valve_closed, s + 513);
    // Clamped 0.3 s later, in s + 812 (a scan): the tool is 2, TC_DONE; the scan of s + 816
    // acknowledges; the kernel drops the request; the scan of s + 820 drops done and the
    // look-ahead releases the next move; interpolation moves in s + 821.
    let clamped = until(&mut m, 1000, |m| input(m, CLAMPED));
    assert_eq!(clamped, s + 812);
    let moved = until(&mut m, 1000, |m| m.status().axes[0] > 1.0);
    assert_eq!(moved, s + 821);
    assert!(m.until(5.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert_eq!(m.status().tool, 2);
    assert_eq!(m.status().axes[0], 2.0);
    assert!(m.faults.is_empty(), "{:?}", m.faults);
}

#[test]
fn a_tool_change_with_a_stuck_unclamped_sensor_times_out_and_stops_the_machine() {
    let text = "G21 G90 G61.1\nG1 X1 F600\nT2 M6\nG1 X2\nM2\n";
    let mut m = mill(text, "stuck.ngc");
    let stuck = InjectedFault::StuckInput {
        input: UNCLAMPED,
        value: false,
    };
    m.sim
        .handle()
        .simulated_machine()
        .unwrap()
        .with(|machine| machine.inject(stuck).unwrap());
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    let v = until(&mut m, 5000, |m| output(m, UNCLAMP_VALVE));
    let s = v - 5;
    // TC_UNCLAMP's step timer runs from the scan of s + 4: TC_TIMEOUT (3 s) ends in the
    // scan of s + 3004, which faults with code 2 and closes the valve.
    let faulted = until(&mut m, 4000, |m| !m.faults.is_empty());
    assert_eq!(faulted, s + 3004);
    let f = m.faults[0];
    assert_eq!(f.code, FaultCode::LogicFault);
    assert_eq!(f.task, TaskName::MachineLogic);
    assert_eq!(f.value, FAULT_TOOL_CHANGE);
    assert_eq!(f.time_ns, (s + 3004) * 1_000_000);
    step(&mut m);
    assert!(!output(&m, UNCLAMP_VALVE));
    assert!(m.until(1.0, |s| s.state == MachineState::Fault && !s.ready));
    assert_eq!(m.status().axes[0], 1.0);
    assert_eq!(m.faults.len(), 1, "{:?}", m.faults);
    // With the sensor repaired, a reset clears the logic's fault and the change succeeds.
    m.sim
        .handle()
        .simulated_machine()
        .unwrap()
        .with(|machine| machine.clear(stuck).unwrap());
    m.command(Command::Reset);
    assert!(m.until(1.0, |s| s.ready && s.state == MachineState::Idle));
    m.command(Command::Start { from_line: 0 });
    assert!(m.until(10.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert_eq!(m.status().tool, 2);
    assert_eq!(m.faults.len(), 1, "{:?}", m.faults);
}

#[test]
fn opening_the_door_holds_the_feed_and_resume_continues_once_it_is_closed() {
    let mut m = mill("G21 G90 G61.1\nG1 X100 F1200\nM2\n", "door.ngc");
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    m.cycles(1002);
    assert_eq!(m.status().state, MachineState::Running);
    // The spindle is off, so the door is not locked: it opens in the exchange of period d;
    // the next scan asks for a feed hold, and interpolation holds in that same period.
    m.sim
        .handle()
        .simulated_machine()
        .unwrap()
        .with(|machine| machine.set_door_open(true).unwrap());
    let d = m.sim.now().as_millis() as u64;
    let held = until(&mut m, 100, |m| m.status().state == MachineState::Held);
    assert_eq!(held, next_scan(d));
    assert!(m.until(1.0, |s| s.path_speed == 0.0));
    let x = m.status().axes[0];
    assert!(x > 10.0 && x < 100.0, "held at {x}");
    // Resume is refused while the door is open.
    assert!(m.sim.handle().urgent(Urgent::Resume));
    m.cycles(200);
    assert_eq!(m.status().state, MachineState::Held);
    assert_eq!(m.status().axes[0], x);
    // Closing the door does not start the machine by itself; resume does.
    m.sim
        .handle()
        .simulated_machine()
        .unwrap()
        .with(|machine| machine.set_door_open(false).unwrap());
    m.cycles(200);
    assert_eq!(m.status().state, MachineState::Held);
    assert_eq!(m.status().axes[0], x);
    assert!(m.sim.handle().urgent(Urgent::Resume));
    assert!(m.until(10.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert_eq!(m.status().axes[0], 100.0);
    assert!(m.faults.is_empty(), "{:?}", m.faults);
}

#[test]
fn the_door_stays_locked_while_the_spindle_turns() {
    let mut m = mill("G21 G90 G61.1\nS3000 M3\nG1 X100 F1200\nM2\n", "lock.ngc");
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    assert!(m.until(3.0, |s| s.path_speed > 0.0));
    m.sim
        .handle()
        .simulated_machine()
        .unwrap()
        .with(|machine| machine.set_door_open(true).unwrap());
    m.cycles(500);
    assert_eq!(m.status().state, MachineState::Running);
    m.sim
        .handle()
        .simulated_machine()
        .unwrap()
        .with(|machine| assert_eq!(machine.door_closed(), Some(true)));
}

#[test]
fn the_estop_chain_opens_with_the_button_and_closes_only_on_a_reset() {
    let mut m = mill("G21 G90 G61.1\nG1 X10 F1200\nM2\n", "chain.ngc");
    m.power_on();
    m.cycles(10);
    assert!(output(&m, SAFETY_RELAY));
    // Pressed before period p: the contact opens in its exchange, the scan of the next
    // scan period drops the safety relay, exchanged one period later.
    m.sim
        .handle()
        .simulated_machine()
        .unwrap()
        .with(|machine| machine.set_estop(true));
    let p = m.sim.now().as_millis() as u64;
    let opened = until(&mut m, 10, |m| !output(m, SAFETY_RELAY));
    assert_eq!(opened, next_scan(p) + 1);
    assert_eq!(m.status().state, MachineState::EStop);
    // Released: the chain stays open until a reset.
    m.sim
        .handle()
        .simulated_machine()
        .unwrap()
        .with(|machine| machine.set_estop(false));
    m.cycles(100);
    assert!(!output(&m, SAFETY_RELAY));
    // A reset read by command parsing in period r is held for the PLC from period r + 1
    // for one PLC interval: the first scan from r + 1 closes the chain and switches the
    // machine on (the lubrication pulse starts), exchanged one period later.
    m.command(Command::Reset);
    let r = m.sim.now().as_millis() as u64;
    let closed = until(&mut m, 10, |m| output(m, SAFETY_RELAY));
    assert_eq!(closed, next_scan(r + 1) + 1);
    assert!(output(&m, LUBE_PUMP));
    assert!(m.until(1.0, |s| s.ready && s.state == MachineState::Idle));
    m.command(Command::Start { from_line: 0 });
    assert!(m.until(5.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert_eq!(m.status().axes[0], 10.0);
    let codes: Vec<_> = m.faults.iter().map(|f| f.code).collect();
    assert_eq!(codes, [FaultCode::EStop]);
}

#[test]
fn no_lubrication_pressure_within_two_seconds_is_a_machine_fault() {
    let mut m = mill("G21 G90 G61.1\nG1 X10 F1200\nM2\n", "lube.ngc");
    m.sim.handle().simulated_machine().unwrap().with(|machine| {
        machine
            .inject(InjectedFault::StuckInput {
                input: PRESSURE,
                value: false,
            })
            .unwrap()
    });
    m.cycles(2);
    m.command(Command::Reset);
    // The scan that switches the machine on (period c) starts the pump (exchanged in
    // c + 1) and LUBE_CHECK_TIME; 2 s later, the scan of c + 2000 faults with code 3.
    let c = until(&mut m, 10, |m| output(m, LUBE_PUMP)) - 1;
    assert_eq!(c % 4, 0);
    let faulted = until(&mut m, 3000, |m| !m.faults.is_empty());
    assert_eq!(faulted, c + 2000);
    let f = m.faults[0];
    assert_eq!((f.code, f.value), (FaultCode::LogicFault, FAULT_LUBE));
    assert!(m.until(1.0, |s| s.state == MachineState::Fault));
    // The machine is off: the pump stops.
    m.cycles(10);
    assert!(!output(&m, LUBE_PUMP));
}

#[test]
fn lubrication_with_pressure_runs_its_pulse_without_a_fault() {
    let mut m = mill("G21 G90 G61.1\nG1 X10 F1200\nM2\n", "lube-ok.ngc");
    m.cycles(2);
    m.command(Command::Reset);
    let c = until(&mut m, 10, |m| output(m, LUBE_PUMP)) - 1;
    // Pressure 0.5 s after the pump starts; LUBE_RUN_TIME (5 s) ends in the scan of
    // c + 5000, exchanged in c + 5001.
    let pressure = until(&mut m, 1000, |m| input(m, PRESSURE));
    assert_eq!(pressure, c + 500);
    let off = until(&mut m, 5000, |m| !output(m, LUBE_PUMP));
    assert_eq!(off, c + 5001);
    assert!(m.faults.is_empty(), "{:?}", m.faults);
}

#[test]
fn m100_blows_air_for_p_seconds_before_motion_continues() {
    let mut m = mill("G21 G90 G61.1\nM100 P0.5\nG1 X1 F600\nM2\n", "m100.ngc");
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    // The scan q opens the valve (exchanged in q + 1) and starts a 500 ms timer; the scan
    // of q + 500 closes it and acknowledges; the scan of q + 504 drops the
    // acknowledgement after the kernel dropped the request; motion in q + 505.
    let q = until(&mut m, 1000, |m| output(m, AIR_BLAST)) - 1;
    let closed = until(&mut m, 1000, |m| !output(m, AIR_BLAST));
    assert_eq!(closed, q + 501);
    let moved = until(&mut m, 100, |m| m.status().axes[0] > 0.0);
    assert_eq!(moved, q + 505);
    assert!(m.until(5.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert!(m.faults.is_empty(), "{:?}", m.faults);
}

#[test]
fn a_tripped_limit_is_a_logic_fault_until_jogged_clear_and_reset() {
    let text = std::fs::read_to_string(repo().join("configs/sim-mill.toml"))
        .unwrap()
        .replacen(
            "positive_limit_switch = 312.0",
            "positive_limit_switch = 50.0",
            1,
        );
    let mut cfg = rtcnc_kernel::MachineConfig::parse(&text, "limit.toml").unwrap();
    cfg.base_dir = repo().join("configs");
    let program = program("G21 G90 G61.1\nG1 X200 F3000\nM2\n", "limit.ngc");
    let mut m = Machine::new(&cfg, Some(program));
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    assert!(m.until(5.0, |s| s.state == MachineState::Fault && !s.ready));
    m.cycles(500);
    let codes: Vec<_> = m
        .faults
        .iter()
        .map(|f| (f.code, f.joint, f.value))
        .collect();
    assert_eq!(codes[0].0, FaultCode::HardLimit);
    assert_eq!(codes[0].1, Some(0));
    // mill.st's limit fault (code 5), raised by the next scan.
    assert_eq!(codes[1..], [(FaultCode::LogicFault, None, 5.0)]);
    // A reset enables the drives, but the logic keeps its fault while the switch is
    // pressed: a program would not move. The jog takes the table off the switch.
    m.command(Command::Reset);
    assert!(m.until(1.0, |s| s.ready && s.state == MachineState::Idle));
    let x = m.status().axes[0];
    m.command(Command::Start { from_line: 0 });
    m.cycles(300);
    assert_eq!(m.status().axes[0], x);
    assert!(m.sim.handle().urgent(Urgent::Abort));
    assert!(m.until(1.0, |s| s.state == MachineState::Idle));
    m.command(Command::JogIncrement {
        axis: 0,
        distance: -5.0,
    });
    assert!(m.until(5.0, |s| s.axes[0] == x - 5.0
        && s.state == MachineState::Idle));
    m.command(Command::Reset);
    m.cycles(20);
    m.command(Command::Mdi(
        rtcnc_kernel::FixedText::new("G1 X10 F3000").unwrap(),
    ));
    assert!(m.until(5.0, |s| s.axes[0] == 10.0 && s.state == MachineState::Idle));
    assert_eq!(m.faults.len(), 2, "{:?}", m.faults);
}

#[test]
fn a_door_opened_during_a_tool_change_keeps_the_program_held_until_a_resume() {
    let text = "G21 G90 G61.1\nG1 X1 F600\nT2 M6\nG1 X2\nM2\n";
    let mut m = mill(text, "door-change.ngc");
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    until(&mut m, 5000, |m| output(m, UNCLAMP_VALVE));
    assert_eq!(m.status().state, MachineState::WaitingForLogic);
    // Opened and closed again while the changer works: the change completes, then the
    // program waits for the operator.
    m.sim
        .handle()
        .simulated_machine()
        .unwrap()
        .with(|machine| machine.set_door_open(true).unwrap());
    m.cycles(100);
    m.sim
        .handle()
        .simulated_machine()
        .unwrap()
        .with(|machine| machine.set_door_open(false).unwrap());
    m.cycles(2000);
    assert_eq!(m.status().tool, 2);
    assert_eq!(m.status().state, MachineState::Held);
    assert_eq!(m.status().axes[0], 1.0);
    assert!(m.sim.handle().urgent(Urgent::Resume));
    assert!(m.until(5.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert_eq!(m.status().axes[0], 2.0);
    assert!(m.faults.is_empty(), "{:?}", m.faults);
}

#[test]
fn a_spindle_override_while_cutting_holds_the_feed_until_at_speed_and_a_resume() {
    let mut m = mill(
        "G21 G90 G61.1\nS6000 M3\nG1 X100 F1200\nM2\n",
        "override.ngc",
    );
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    assert!(m.until(3.0, |s| s.path_speed > 0.0));
    m.cycles(500);
    assert!(m.sim.handle().urgent(Urgent::SpindleOverride(1.2)));
    // 7200 rpm is outside mill.st's 2 % window of the new speed: the feed is held.
    assert!(m.until(0.1, |s| s.state == MachineState::Held));
    assert!(m.sim.handle().urgent(Urgent::Resume));
    m.cycles(10);
    assert_eq!(m.status().state, MachineState::Held);
    // Within 144 rpm of 7200 after (7056 − 6000) / 12 = 88 periods, at speed 200 ms later.
    m.cycles(400);
    assert!(m.sim.handle().urgent(Urgent::Resume));
    assert!(m.until(10.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert_eq!(m.status().axes[0], 100.0);
    assert!(m.faults.is_empty(), "{:?}", m.faults);
}

#[test]
fn retained_values_survive_a_restart() {
    let dir = std::env::temp_dir().join(format!("rtcnc-retain-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("mill.retain");
    let _ = std::fs::remove_file(&file);
    let mut cfg = config("sim-mill.toml");
    cfg.files.plc_retain = Some(file.clone());
    let text = "G21 G90 G61.1\nG1 X1 F600\nT2 M6\nG1 X2\nM2\n";

    // First run: the change puts tool 2 in the spindle; mill.st keeps it in RETAIN
    // current_tool, which the background task (every 0.5 s) writes once it changed.
    let mut m = Machine::started(&cfg, text, "retain1.ngc");
    assert!(m.until(10.0, |s| s.program_ended && s.state == MachineState::Idle));
    m.cycles(600);
    let saved = std::fs::read_to_string(&file).unwrap();
    assert!(
        saved
            .lines()
            .any(|l| l.eq_ignore_ascii_case("MILL.current_tool = 2")),
        "{saved}"
    );

    // A restart restores both retained variables (current_tool, lube_cycles) ...
    let kernel = rtcnc_kernel::Kernel::build(&cfg, rtcnc_kernel::KernelOptions::default())
        .expect("kernel builds");
    let (_, found) = kernel
        .self_test
        .checks
        .iter()
        .find(|(name, _)| *name == "plc retain")
        .expect("retain check");
    assert!(found.ends_with(": 2 restored, 0 skipped"), "{found}");
    // ... so asking for tool 2 again finds it in the spindle: the unclamp valve never opens.
    let mut m = Machine::started(&cfg, text, "retain2.ngc");
    let mut valve_opened = false;
    for _ in 0..5000 {
        step(&mut m);
        valve_opened |= output(&m, UNCLAMP_VALVE);
        if m.status().program_ended && m.status().state == MachineState::Idle {
            break;
        }
    }
    assert!(m.status().program_ended);
    assert!(!valve_opened);
    assert_eq!(m.status().axes[0], 2.0);
    assert!(m.faults.is_empty(), "{:?}", m.faults);
}
