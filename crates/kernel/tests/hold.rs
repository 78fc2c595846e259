//! A feed hold, an abort and an e-stop requested while a program waits (for a machine
//! function, the spindle, an input, a dwell, a pause, its start, the next MDI line) keep
//! the next motion from starting: on the simulated mill with its machine logic, in virtual
//! time. The program's next move goes from X5 to X100; a held machine must stay at X5.

use crate::common::*;
use rtcnc_kernel::{Command, FaultCode, FixedText, MachineState, Status, Urgent};

/// mill.st's program input 0 (M66 P0) is digital input 8 (`io.program_inputs`).
const PROGRAM_INPUT_0: usize = 8;

/// A program that moves to X5, waits in `wait`, then moves to X100.
fn waiting_program(wait: &str) -> String {
    format!("G21 G90 G61.1\nG1 X5 F3000\n{wait}\nG1 X100\nM2\n")
}

struct Case {
    name: &'static str,
    wait: &'static str,
    /// The machine is in the wait.
    waiting: fn(&Status) -> bool,
    /// What ends the wait from outside (an input); none: it ends by itself.
    end_wait: fn(&mut Machine),
    /// The wait is a pause that the operator's cycle start ends.
    paused: bool,
}

fn at_x5_standing(s: &Status) -> bool {
    s.axes[0] == 5.0 && s.path_speed == 0.0
}

fn nothing(_: &mut Machine) {}

fn cases() -> Vec<Case> {
    vec![
        Case {
            name: "tool change",
            wait: "T2 M6",
            waiting: |s| s.state == MachineState::WaitingForLogic,
            end_wait: nothing,
            paused: false,
        },
        Case {
            name: "spindle at speed",
            wait: "S8000 M3",
            waiting: |s| s.state == MachineState::WaitingForLogic,
            end_wait: nothing,
            paused: false,
        },
        Case {
            name: "machine-function hand-shake (M100 air blast)",
            wait: "M100 P0.5",
            waiting: |s| s.state == MachineState::WaitingForLogic,
            end_wait: nothing,
            paused: false,
        },
        Case {
            name: "M66 wait for an input",
            wait: "M66 P0 L3 Q30",
            waiting: at_x5_standing,
            end_wait: |m| {
                m.handle_machine(|mach| mach.set_digital_input(PROGRAM_INPUT_0, true).unwrap())
            },
            paused: false,
        },
        Case {
            name: "G4 dwell",
            wait: "G4 P1",
            waiting: at_x5_standing,
            end_wait: nothing,
            paused: false,
        },
        Case {
            name: "M0 program stop",
            wait: "M0",
            waiting: |s| s.state == MachineState::Paused,
            end_wait: nothing,
            paused: true,
        },
    ]
}

/// Runs the program until the machine is in the case's wait (`test` names the program
/// file: the tests run in parallel).
fn in_the_wait(case: &Case, test: &str) -> Machine {
    let cfg = config("sim-mill.toml");
    let name = format!("{test}-{}.ngc", case.wait.replace(' ', "_"));
    let mut m = Machine::started(&cfg, &waiting_program(case.wait), &name);
    // The moment the wait starts: X5 reached (and the state, where it shows one).
    let waiting = case.waiting;
    assert!(
        m.until(10.0, |s| s.axes[0] == 5.0 && waiting(s)),
        "{}: never waits: {:?}",
        case.name,
        m.status()
    );
    m
}

/// Runs `seconds` of machine time and asserts that no axis set-point moved.
fn stands_still(m: &mut Machine, seconds: f64, what: &str) {
    let before = m.status().axes;
    let from = m.samples.len();
    m.cycles((seconds * 1000.0) as u64);
    for s in &m.samples[from..] {
        assert_eq!(s.axes, before, "{what}: moved at cycle {}", s.cycle);
    }
}

#[test]
fn a_feed_hold_in_every_waiting_state_keeps_the_next_move_from_starting() {
    for case in cases() {
        let mut m = in_the_wait(&case, "hold");
        assert!(m.sim.handle().urgent(Urgent::FeedHold));
        m.cycles(2);
        assert_eq!(m.status().state, MachineState::Held, "{}", case.name);
        (case.end_wait)(&mut m);
        if case.paused {
            // The operator's cycle start continues a pause, not a hold.
            m.command(Command::Start { from_line: 0 });
        }
        // Longer than any of the waits: the tool change, the spindle's run-up, the air
        // blast and the dwell are over, the input has risen.
        stands_still(&mut m, 4.0, case.name);
        assert_eq!(m.status().state, MachineState::Held, "{}", case.name);
        assert_eq!(m.status().axes[0], 5.0, "{}", case.name);
        assert!(m.sim.handle().urgent(Urgent::Resume));
        assert!(
            m.until(10.0, |s| s.program_ended && s.state == MachineState::Idle),
            "{}: does not end after the resume: {:?}",
            case.name,
            m.status()
        );
        assert_eq!(m.status().axes[0], 100.0, "{}", case.name);
        assert!(m.faults.is_empty(), "{}: {:?}", case.name, m.faults);
    }
}

#[test]
fn an_abort_in_every_waiting_state_ends_the_program_where_it_stands() {
    for case in cases() {
        let mut m = in_the_wait(&case, "abort");
        assert!(m.sim.handle().urgent(Urgent::Abort));
        m.cycles(2);
        (case.end_wait)(&mut m);
        stands_still(&mut m, 4.0, case.name);
        let s = m.status();
        assert_eq!(s.state, MachineState::Idle, "{}", case.name);
        assert!(!s.program_ended, "{}", case.name);
        assert_eq!(s.axes[0], 5.0, "{}", case.name);
        // The machine is ready for the next program at once.
        m.command(Command::Mdi(FixedText::new("G0 X7").unwrap()));
        assert!(m.until(5.0, |s| s.axes[0] == 7.0 && s.state == MachineState::Idle));
    }
}

#[test]
fn an_estop_in_every_waiting_state_disables_the_drives_and_nothing_moves_after_the_reset() {
    for case in cases() {
        let mut m = in_the_wait(&case, "estop");
        assert!(m.sim.handle().urgent(Urgent::EStop));
        assert!(m.until(1.0, |s| s.state == MachineState::EStop && !s.ready));
        (case.end_wait)(&mut m);
        stands_still(&mut m, 2.0, case.name);
        m.command(Command::Reset);
        assert!(m.until(1.0, |s| s.ready), "{}", case.name);
        stands_still(&mut m, 3.0, case.name);
        assert_eq!(m.status().state, MachineState::Idle, "{}", case.name);
        // The set-points start again where the machine stands after the drives were off:
        // within the following-error window of X5.
        assert!((m.status().axes[0] - 5.0).abs() < 0.02, "{}", case.name);
        assert_eq!(m.faults.len(), 1, "{}: {:?}", case.name, m.faults);
        assert_eq!(m.faults[0].code, FaultCode::EStop);
    }
}

#[test]
fn a_hold_at_the_start_of_a_program_keeps_it_from_moving() {
    let cfg = config("sim-mill.toml");
    let mut m = Machine::started(&cfg, &waiting_program("G4 P0.1"), "start.ngc");
    // In the period after the start was taken, before any set-point has moved.
    m.cycles(1);
    assert_eq!(m.status().state, MachineState::Running);
    assert!(m.sim.handle().urgent(Urgent::FeedHold));
    stands_still(&mut m, 2.0, "start");
    assert_eq!(m.status().axes[0], 0.0);
    assert_eq!(m.status().state, MachineState::Held);
    assert!(m.sim.handle().urgent(Urgent::Resume));
    assert!(m.until(10.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert_eq!(m.status().axes[0], 100.0);
    assert!(m.faults.is_empty(), "{:?}", m.faults);
}

#[test]
fn a_hold_between_mdi_lines_refuses_the_next_line_until_resume() {
    let cfg = config("sim-mill.toml");
    let mut m = Machine::new(&cfg, None);
    m.power_on();
    m.command(Command::Mdi(FixedText::new("G21 G90 G0 X5").unwrap()));
    m.cycles(5);
    assert!(m.until(5.0, |s| s.state == MachineState::Idle));
    assert!(m.sim.handle().urgent(Urgent::FeedHold));
    m.cycles(2);
    assert_eq!(m.status().state, MachineState::Held);
    m.command(Command::Mdi(FixedText::new("G0 X100").unwrap()));
    stands_still(&mut m, 2.0, "mdi");
    assert_eq!(m.faults.len(), 1, "{:?}", m.faults);
    assert_eq!(m.faults[0].code, FaultCode::CommandRefused);
    // Nor does a jog start while held.
    m.command(Command::JogContinuous {
        axis: 0,
        velocity: 10.0,
    });
    stands_still(&mut m, 0.5, "jog");
    assert!(m.sim.handle().urgent(Urgent::Resume));
    m.cycles(2);
    m.command(Command::Mdi(FixedText::new("G0 X100").unwrap()));
    m.cycles(5);
    assert!(m.until(5.0, |s| s.state == MachineState::Idle));
    assert_eq!(m.status().axes[0], 100.0);
}

#[test]
fn a_hold_in_the_last_periods_of_a_move_before_a_machine_function_still_holds() {
    // The hold arrives while the path brakes into the stop before M6: the planner comes to
    // rest at the block's end on its own, and the tool change must not release the hold.
    let cfg = config("sim-mill.toml");
    let mut m = Machine::started(&cfg, &waiting_program("T2 M6"), "late.ngc");
    assert!(m.until(5.0, |s| s.axes[0] > 4.999 && s.axes[0] < 5.0));
    assert!(m.sim.handle().urgent(Urgent::FeedHold));
    stands_still_after_stop(&mut m);
    assert_eq!(m.status().state, MachineState::Held);
    assert!(m.sim.handle().urgent(Urgent::Resume));
    assert!(m.until(10.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert_eq!(m.status().axes[0], 100.0);
}

/// Lets a braking path come to rest, then asserts it stays put for 4 s.
fn stands_still_after_stop(m: &mut Machine) {
    assert!(m.until(1.0, |s| s.path_speed == 0.0));
    m.cycles(2);
    let x = m.status().axes[0];
    stands_still(m, 4.0, "after the stop");
    assert!(x <= 5.0, "{x}");
}

#[test]
fn a_hold_during_homing_stops_the_axes_and_homing_starts_again_after_resume() {
    let cfg = config("sim-mill.toml");
    let mut m = Machine::new(&cfg, None);
    m.power_on();
    m.command(Command::HomeAll);
    // Z searches its switch first (sequence 0) at 10 mm/s.
    m.cycles(500);
    assert!(m.status().path_speed == 0.0 && m.status().joint_setpoints[2] > 1.0);
    assert!(m.sim.handle().urgent(Urgent::FeedHold));
    // Z stops within its jerk-limited stop from 10 mm/s (well under 0.1 s) and stays.
    m.cycles(100);
    let z = m.status().joint_setpoints[2];
    let from = m.samples.len();
    m.cycles(2000);
    assert!(m.samples[from..].iter().all(|s| s.setpoint[2] == z));
    assert_eq!(m.status().state, MachineState::Held, "{:?}", m.faults);
    assert_eq!(m.status().homed, 0);
    assert!(m.sim.handle().urgent(Urgent::Resume));
    m.cycles(2);
    assert_eq!(m.status().state, MachineState::Idle);
    // Z was handed back to its axis where it stopped: a jog moves it from there.
    m.command(Command::JogIncrement {
        axis: 2,
        distance: -1.0,
    });
    m.cycles(5);
    assert!(m.until(5.0, |s| s.state == MachineState::Idle));
    assert!((m.status().joint_setpoints[2] - (z - 1.0)).abs() < 1e-9);
    m.command(Command::HomeAll);
    m.cycles(5);
    assert!(m.until(120.0, |s| s.state == MachineState::Idle));
    assert_eq!(m.status().homed, 0b111);
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    // The mill's axes are its joints (trivial kinematics): what the status and the
    // recording show of an axis is where its joint is, while it homes too (the fuzzed
    // kernel saw Z's axis stand at 0 while its joint searched the switch, then jump).
    for s in &m.samples {
        assert_eq!(&s.axes[..3], &s.setpoint[..3], "cycle {}", s.cycle);
    }
}
