//! The guard door opened just before or as a program starts: found by the kernel fuzz
//! target (fuzz/defects/kernel/door-opened-as-a-program-starts), where the machine
//! logic's hold request rose before the program's first step, no hold was latched, and the
//! program waited for ever in `running` with nothing moving. The state must say held, as
//! when the door opens between moves, the resume is refused while the door is open, and
//! after it is closed the operator's resume runs the program (closing the door does not
//! start the machine by itself: tests/mill_logic.rs).

mod common;
use common::*;
use rtcnc_kernel::{Command, MachineState, Urgent};

const PROGRAM: &str = "G21 G90 G61.1\nG1 X10 F1200\nM2\n";

fn set_door(m: &Machine, open: bool) {
    m.handle_machine(|machine| machine.set_door_open(open).unwrap());
}

#[test]
fn a_program_started_as_the_door_opens_is_held_until_it_is_closed_and_resumed() {
    let cfg = config("sim-mill.toml");
    // The start in the door's period and in each of the next ones (the logic scans every
    // fourth period, so the hold request rises before, with or after the start).
    for start_after in 0..=9 {
        let mut m = Machine::new(&cfg, Some(program(PROGRAM, "door-start.ngc")));
        m.power_on();
        set_door(&m, true);
        m.cycles(start_after);
        m.command(Command::Start { from_line: 0 });
        m.cycles(100);
        let s = m.status();
        assert_eq!(s.state, MachineState::Held, "start {start_after}: {s:?}");
        assert_eq!(s.axes[0], 0.0, "start {start_after}");
        // Refused while the door is open.
        assert!(m.sim.handle().urgent(Urgent::Resume));
        m.cycles(100);
        assert_eq!(m.status().state, MachineState::Held, "start {start_after}");
        assert_eq!(m.status().axes[0], 0.0, "start {start_after}");
        set_door(&m, false);
        m.cycles(100);
        assert_eq!(m.status().state, MachineState::Held, "start {start_after}");
        assert_eq!(m.status().axes[0], 0.0, "start {start_after}");
        assert!(m.sim.handle().urgent(Urgent::Resume));
        assert!(
            m.until(5.0, |s| s.program_ended && s.state == MachineState::Idle),
            "start {start_after}: {:?}",
            m.status()
        );
        assert_eq!(m.status().axes[0], 10.0, "start {start_after}");
        assert!(m.faults.is_empty(), "start {start_after}: {:?}", m.faults);
    }
}
