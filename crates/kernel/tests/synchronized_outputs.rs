//! M62/M63/M67 change their output at the start of the next move without stopping the
//! path, as LinuxCNC's motion controller does (it attaches them to its next trajectory
//! segment); M64/M65/M68 wait for the motion before them and act at once (LinuxCNC's task
//! waits for motion before issuing them).

use crate::common::*;
use rtcnc_kernel::{Command, MachineConfig, MachineState};

/// The benchmark machine (ideal drives: the set-point of an exchange is where the load is)
/// with digital program output 0 on output 4 and analogue output 0 on analogue output 2.
fn machine() -> MachineConfig {
    let mut cfg = config("bench-xyz.toml");
    cfg.io.program_outputs = vec![4];
    cfg.io.program_analog_outputs = vec![2];
    cfg
}

/// Per exchange: the set-point's X, Y, line and path speed, digital output 4, analogue
/// output 2; until the program has ended and the machine stands.
struct Period {
    axes: [f64; 2],
    line: u32,
    speed: f64,
    digital: bool,
    analog: f64,
}

fn run(text: &str, name: &str) -> Vec<Period> {
    let mut m = Machine::new(&machine(), Some(program(text, name)));
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    let mut trace = Vec::new();
    let mut after_end = 0;
    while after_end < 5 && trace.len() < 10_000 {
        m.cycles(1);
        let s = *m.samples.last().unwrap();
        let (digital, analog) = m.handle_machine(|mach| {
            (
                mach.digital_output(4).unwrap(),
                mach.analog_output(2).unwrap(),
            )
        });
        trace.push(Period {
            axes: [s.axes[0], s.axes[1]],
            line: s.line,
            speed: s.path_speed,
            digital,
            analog,
        });
        if m.status().program_ended && m.status().state == MachineState::Idle {
            after_end += 1;
        }
    }
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    trace
}

/// The last period in which the set-point moved: the cycle time in periods.
fn motion_end(trace: &[Period]) -> usize {
    trace
        .windows(2)
        .rposition(|w| w[0].axes != w[1].axes)
        .unwrap()
        + 1
}

fn first(trace: &[Period], what: impl Fn(&Period) -> bool) -> usize {
    trace.iter().position(what).unwrap()
}

/// Lines 3 and 5 are the output codes (or nothing), line 4 the move after them.
fn blended(first_code: &str, second_code: &str) -> String {
    format!(
        "G21 G90 G64 P0.05 F3000
G1 X10
{first_code}
G1 X20 Y5
{second_code}
G1 X30 Y8
M2
"
    )
}

#[test]
fn m62_and_m67_change_as_the_next_move_starts_without_slowing_the_path() {
    let plain = run(&blended("", ""), "plain.ngc");
    let synced = run(&blended("M62 P0", "M67 E0 Q2.5"), "m62.ngc");
    // The path is the same, period by period: the junctions are blended through as
    // without the codes (same cycle time to the period).
    assert_eq!(motion_end(&plain), motion_end(&synced));
    assert_eq!(plain.len(), synced.len());
    for (p, s) in plain.iter().zip(&synced) {
        assert_eq!(p.axes, s.axes);
    }
    // The digital output goes on in the period of the first set-point of line 4 (after the
    // corner blend, which belongs to the move before), at speed.
    let on = first(&synced, |p| p.digital);
    let line4 = first(&synced, |p| p.line == 4);
    assert_eq!(on, line4);
    assert!(synced[on].speed > 10.0, "{}", synced[on].speed);
    assert!(synced[..on].iter().all(|p| !p.digital));
    // The analogue output with the first set-point of line 6.
    let set = first(&synced, |p| p.analog == 2.5);
    assert_eq!(set, first(&synced, |p| p.line == 6));
    assert!(synced[set].speed > 10.0, "{}", synced[set].speed);
    assert!(plain.iter().all(|p| !p.digital && p.analog == 0.0));
}

#[test]
fn m64_and_m68_wait_for_the_motion_before_them_and_change_at_once() {
    let plain = run(&blended("", ""), "plain.ngc");
    let immediate = run(&blended("M64 P0", "M68 E0 Q1.5"), "m64.ngc");
    // The path stops at X10 and at X20 Y5: longer than the blended one.
    assert!(motion_end(&immediate) > motion_end(&plain) + 10);
    // The output goes on once the path stands at X10 (the move before it ended): in the
    // exchange from which the next move may start, at the latest with its first set-point.
    let at_rest = first(&immediate, |p| p.axes == [10.0, 0.0] && p.speed == 0.0);
    let on = first(&immediate, |p| p.digital);
    assert!(on > at_rest && on <= at_rest + 2, "{at_rest} {on}");
    assert_eq!(immediate[on - 1].axes, [10.0, 0.0]);
    let leaves = first(&immediate, |p| p.axes[1] > 0.0);
    assert!(on <= leaves, "{on} {leaves}");
    let at_second = first(&immediate, |p| p.axes == [20.0, 5.0] && p.speed == 0.0);
    let set = first(&immediate, |p| p.analog == 1.5);
    assert!(set > at_second && set <= at_second + 2, "{at_second} {set}");
    assert_eq!(immediate[set - 1].axes, [20.0, 5.0]);
}

#[test]
fn a_synchronised_output_before_the_end_changes_when_the_path_stands_there() {
    let trace = run("G21 G90 F3000\nG1 X10\nM62 P0\nM2\n", "m62-end.ngc");
    let on = first(&trace, |p| p.digital);
    let stands = first(&trace, |p| p.axes == [10.0, 0.0] && p.speed == 0.0);
    assert!(on > stands && on <= stands + 2, "{stands} {on}");
}

#[test]
fn a_synchronised_output_waits_through_a_dwell_and_a_machine_function_for_the_move() {
    // LinuxCNC attaches M62 to its next motion segment: neither a dwell nor coolant is one.
    let trace = run(
        "G21 G90 F3000\nG1 X10\nM62 P0\nG4 P0.2\nM8\nG1 X20\nM9\nM2\n",
        "m62-dwell.ngc",
    );
    let on = first(&trace, |p| p.digital);
    let moves = first(&trace, |p| p.line == 6);
    assert_eq!(on, moves);
    assert!(trace[on - 1].axes == [10.0, 0.0]);
}

#[test]
fn a_synchronised_output_in_a_loop_changes_at_each_move_after_it() {
    // The same lines again and again: each M62/M63 goes with the move that follows it,
    // never with a line number.
    let text = "G21 G90 G64 P0.05 F3000
o1 repeat [3]
  G91 G1 X5
  M62 P0
  G1 Y5
  M63 P0
o1 endrepeat
M2
";
    let trace = run(text, "m62-loop.ngc");
    let ons: Vec<usize> = trace
        .windows(2)
        .enumerate()
        .filter(|(_, w)| !w[0].digital && w[1].digital)
        .map(|(i, _)| i + 1)
        .collect();
    let offs: Vec<usize> = trace
        .windows(2)
        .enumerate()
        .filter(|(_, w)| w[0].digital && !w[1].digital)
        .map(|(i, _)| i + 1)
        .collect();
    let y_starts: Vec<usize> = trace
        .windows(2)
        .enumerate()
        .filter(|(_, w)| w[0].line != 5 && w[1].line == 5)
        .map(|(i, _)| i + 1)
        .collect();
    let x_starts: Vec<usize> = trace
        .windows(2)
        .enumerate()
        .filter(|(_, w)| w[0].line == 5 && w[1].line == 3)
        .map(|(i, _)| i + 1)
        .collect();
    assert_eq!(ons, y_starts);
    assert_eq!(y_starts.len(), 3);
    // Each M63 with the next X move; the last one at the end.
    assert_eq!(&offs[..2], &x_starts[..]);
    assert_eq!(offs.len(), 3);
}

#[test]
fn the_example_switches_its_dispenser_with_the_moves_on_the_simulated_mill() {
    // examples/gcode/synchronized_outputs.ngc on the mill (program output 0 is its
    // digital output 12): on with the first set-point of line 12 and of line 18, off with
    // that of line 16 and of line 20, the corners between blended as without the codes.
    let text =
        std::fs::read_to_string(repo().join("examples/gcode/synchronized_outputs.ngc")).unwrap();
    let mut m = Machine::new(
        &config("sim-mill.toml"),
        Some(program(&text, "synchronized_outputs.ngc")),
    );
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    let mut trace = Vec::new();
    let mut after_end = 0;
    while after_end < 5 && trace.len() < 60_000 {
        m.cycles(1);
        let line = m.samples.last().unwrap().line;
        let on = m.handle_machine(|mach| mach.digital_output(12).unwrap());
        trace.push((line, on));
        if m.status().program_ended && m.status().state == MachineState::Idle {
            after_end += 1;
        }
    }
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    let first = |l: u32| trace.iter().position(|t| t.0 == l).unwrap();
    let switches: Vec<(usize, bool)> = trace
        .windows(2)
        .enumerate()
        .filter(|(_, w)| w[0].1 != w[1].1)
        .map(|(i, w)| (i + 1, w[1].1))
        .collect();
    assert_eq!(
        switches,
        [
            (first(12), true),
            (first(16), false),
            (first(18), true),
            (first(20), false)
        ]
    );
}
