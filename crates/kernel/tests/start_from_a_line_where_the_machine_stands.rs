//! Run from a line when the machine already stands where that line starts: found by the
//! kernel fuzz target (fuzz/defects/kernel/start-from-a-line-where-the-machine-stands). The
//! approach move to the line's start point had zero length; the planner refused it, the
//! kernel kept it for the next attempt and met the same refusal at every one: the program
//! stood in `running` at line 0 for ever, nothing moving, no fault.

use crate::common::*;
use rtcnc_kernel::{Command, FixedText, MachineState, Urgent};

const PROGRAM: &str = "G21 G90
G1 X5 Y2 F3000
G4 P0.5
G1 X20 Y10
M2
";

fn ends_at_x20_y10(m: &mut Machine) {
    assert!(
        m.until(10.0, |s| s.program_ended && s.state == MachineState::Idle),
        "the program runs to its end: {:?}",
        m.status()
    );
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    let axes = m.status().axes;
    assert!((axes[0] - 20.0).abs() < 1e-9 && (axes[1] - 10.0).abs() < 1e-9);
}

#[test]
fn run_from_the_dwell_after_an_abort_in_it_runs_to_the_end() {
    let cfg = config("sim-mill.toml");
    let mut m = Machine::started(&cfg, PROGRAM, "abort-in-dwell.ngc");
    // In the dwell, at X5 Y2.
    assert!(m.until(5.0, |s| s.line == 3));
    m.cycles(100);
    assert!(m.sim.handle().urgent(Urgent::Abort));
    assert!(m.until(1.0, |s| s.state == MachineState::Idle));
    m.faults.clear();
    m.command(Command::Start { from_line: 3 });
    ends_at_x20_y10(&mut m);
}

#[test]
fn run_from_a_line_whose_start_point_is_where_the_machine_stands() {
    let cfg = config("sim-mill.toml");
    let mut m = Machine::new(&cfg, Some(program(PROGRAM, "already-there.ngc")));
    m.power_on();
    m.command(Command::Mdi(FixedText::new("G0 X5 Y2").unwrap()));
    assert!(m.until(5.0, |s| s.state == MachineState::Idle && s.axes[0] == 5.0));
    m.command(Command::Start { from_line: 3 });
    ends_at_x20_y10(&mut m);
}
