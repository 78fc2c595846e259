//! A quick stop while the rapid override is 0 % during a rapid: found by the kernel fuzz
//! target (fuzz/src/kernel.rs), where the planner's preparation of the stop never ended
//! and the machine hung in the period the drive fault was seen.

use crate::common::*;
use rtcnc_fieldbus::sim::InjectedFault;
use rtcnc_kernel::{Command, MachineState, Urgent};

#[test]
fn a_drive_fault_during_a_rapid_held_at_zero_override_stops_the_machine() {
    let cfg = config("sim-mill.toml");
    let text = "G21 G90 G64\nG0 X2 Y2\nG1 Z-1 F600\nG1 X3 Y2.2 F4000\nX4 Y2.1\nX5 Y2.6\nM2\n";
    let mut m = Machine::new(&cfg, Some(program(text, "zero-override.ngc")));
    m.power_on();
    // From line 4: the machine first goes at rapid to where that line starts.
    m.command(Command::Start { from_line: 4 });
    m.cycles(99);
    assert!(m.status().path_speed > 0.0, "{:?}", m.status());
    m.handle_machine(|mach| {
        mach.inject(InjectedFault::DriveFault {
            joint: 1,
            error_code: 0x2310,
        })
        .unwrap()
    });
    // Not a number: the override falls to 0 % (the safe side).
    assert!(m.sim.handle().urgent(Urgent::RapidOverride(f64::NAN)));
    m.cycles(400);
    assert_eq!(m.status().state, MachineState::Fault, "{:?}", m.faults);
    assert!(!m.status().ready);
    assert_eq!(m.faults[0].code.as_str(), "kernel.drive_fault");
}
