//! Program I/O through the whole kernel: M66 waits on the simulated machine's inputs and
//! the interpreter reads #5399 only once the machine has answered (as LinuxCNC's
//! interpreter synchronises), M67/M68 analogue outputs, M62..M65 digital outputs.

use crate::common::*;
use rtcnc_kernel::{Command, MachineConfig, MachineState};

/// The benchmark machine with program input 0 on digital input 3, analogue input 0 on
/// analogue input 1, digital program output 0 on output 4 and analogue output 0 on
/// analogue output 2.
fn machine() -> MachineConfig {
    let mut cfg = config("bench-xyz.toml");
    cfg.io.program_inputs = vec![3];
    cfg.io.program_analog_inputs = vec![1];
    cfg.io.program_outputs = vec![4];
    cfg.io.program_analog_outputs = vec![2];
    cfg
}

fn first_cycle(m: &Machine, what: impl Fn(&rtcnc_kernel::Sample) -> bool) -> u64 {
    m.samples.iter().find(|s| what(s)).unwrap().cycle
}

#[test]
fn m66_waits_for_the_input_and_the_program_branches_on_its_value() {
    // The branch is decided by #5399 as the machine reports it: read ahead, the
    // interpreter would take the else branch (its own model of an unread input is 0).
    let text = "G21 G90
G1 X5 F600
M66 P0 L3 Q5
o1 if [#5399 EQ 1]
  G1 Y5
o1 else
  G1 Y-5
o1 endif
M66 P0 L4 Q0.5
o2 if [#5399 EQ -1]
  G1 X0
o2 endif
M66 E0 L0
G1 Z[#5399]
M2
";
    let mut m = Machine::new(&machine(), Some(program(text, "m66.ngc")));
    m.handle_machine(|mach| mach.set_analog_input(1, 2.5).unwrap());
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    // X5 takes about 0.53 s; the machine then waits for input 3.
    m.cycles(1500);
    let standing = m.status();
    assert_eq!(standing.axes[..3], [5.0, 0.0, 0.0]);
    assert!(!standing.program_ended);
    m.handle_machine(|mach| mach.set_digital_input(3, true).unwrap());
    let raised = m.samples.last().unwrap().cycle;
    assert!(m.until(10.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert!(
        m.faults.is_empty(),
        "{:?} {:?}",
        m.faults,
        m.sim.handle().error_text()
    );
    // Took the "input high" branch; the L4 wait timed out (the input stays high): -1,
    // so X went back to 0; Z went to the analogue input's value.
    assert_eq!(m.status().axes[..3], [0.0, 5.0, 2.5]);
    assert!(m.samples.iter().all(|s| s.axes[1] >= 0.0));
    // The Y move leaves a few periods after the input rose (the drive exchange, the
    // look-ahead, the interpreter and tool compensation each take their turn).
    let y_leaves = first_cycle(&m, |s| s.axes[1] > 0.0);
    assert!(
        y_leaves > raised && y_leaves <= raised + 5,
        "{raised} {y_leaves}"
    );
    // The L4 wait begins the period after the Y move's last set-point and times out
    // 0.5 s = 500 periods later; X leaves within the same few periods after that.
    let y_done = first_cycle(&m, |s| s.axes[1] == 5.0);
    let x_leaves = first_cycle(&m, |s| s.axes[1] == 5.0 && s.axes[0] < 5.0);
    let gap = x_leaves - y_done;
    assert!(gap > 500 && gap <= 500 + 5, "{gap}");
}

#[test]
fn immediate_outputs_change_where_the_motion_before_them_ends_synchronised_ones_with_the_next_move()
{
    let text = "G21 G90
M68 E0 Q3.5
G1 X5 F600
M67 E0 Q1.25
M62 P0
G1 X0
M65 P0
M2
";
    let mut m = Machine::new(&machine(), Some(program(text, "outputs.ngc")));
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    // (X set-point applied to the drives, analogue output 2, digital output 4) after every
    // exchange with the machine.
    let mut trace = Vec::new();
    let mut after_end = 0;
    while after_end < 5 && trace.len() < 4000 {
        m.cycles(1);
        let x = m.samples.last().unwrap().axes[0];
        let outputs = m.handle_machine(|mach| {
            (
                mach.analog_output(2).unwrap(),
                mach.digital_output(4).unwrap(),
            )
        });
        trace.push((x, outputs.0, outputs.1));
        if m.status().program_ended && m.status().state == MachineState::Idle {
            after_end += 1;
        }
    }
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    let changes: Vec<(f64, f64, bool)> = trace
        .windows(2)
        .filter(|w| w[0].1 != w[1].1 || w[0].2 != w[1].2)
        .map(|w| w[1])
        .collect();
    // M68 before any motion, from the exchange the first move starts in; M67 and M62
    // together with the first set-point of the return move (they change with the next
    // move, without stopping the path: here it stops anyway, to reverse); M65 back at X0
    // once the return move has ended.
    let starts = trace.iter().position(|t| t.0 > 0.0).unwrap();
    let at_five = trace.iter().position(|t| t.0 == 5.0).unwrap();
    let returns = at_five + trace[at_five..].iter().position(|t| t.0 < 5.0).unwrap();
    let change_at: Vec<usize> = trace
        .windows(2)
        .enumerate()
        .filter(|(_, w)| w[0].1 != w[1].1 || w[0].2 != w[1].2)
        .map(|(i, _)| i + 1)
        .collect();
    assert_eq!(change_at[..2], [starts, returns]);
    assert_eq!((changes[0].1, changes[1].1), (3.5, 1.25));
    assert!(!changes[0].2 && changes[1].2);
    assert_eq!(changes[2], (0.0, 1.25, false));
    assert_eq!(trace[change_at[2] - 1].0, 0.0);
}

#[test]
fn an_unmapped_analogue_input_stops_the_program_at_its_block() {
    let text = "G21 G90\nG1 X1 F600\nM66 E3 L0\nG1 X2\nM2\n";
    let mut m = Machine::new(&machine(), Some(program(text, "unmapped.ngc")));
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    m.cycles(2);
    assert!(m.until(5.0, |s| s.state == MachineState::Idle));
    assert_eq!(m.status().axes[0], 1.0);
    assert!(m.faults.iter().any(|f| f.line == 3), "{:?}", m.faults);
}

#[test]
fn an_m66_time_out_longer_than_the_machine_will_run_waits_for_the_input() {
    // 10^30 s is as good as forever: the wait must neither end at once (a deadline that
    // wrapped) nor overflow; the input ends it and the program takes the "high" branch.
    let text = "G21 G90
M66 P0 L3 Q[10**30]
o1 if [#5399 EQ 1]
  G1 X5 F600
o1 endif
M2
";
    let mut m = Machine::new(&machine(), Some(program(text, "m66-forever.ngc")));
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    m.cycles(5000);
    assert!(!m.status().program_ended);
    assert_eq!(m.status().axes[0], 0.0);
    m.handle_machine(|mach| mach.set_digital_input(3, true).unwrap());
    assert!(m.until(10.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert_eq!(m.status().axes[0], 5.0);
    assert!(m.faults.is_empty(), "{:?}", m.faults);
}
