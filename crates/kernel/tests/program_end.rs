//! M2 and M30 end the program and rewind it (as in LinuxCNC, whose M30 is M2 with a pallet
//! shuttle that its task leaves undone); a machine with a pallet shuttle has its logic
//! exchange the pallets before the end.

use crate::common::*;
use rtcnc_kernel::config::PlcSection;
use rtcnc_kernel::{Command, MachineState};

/// `../shared/cases/m30-end.ngc`: a move and M30, which used to wait for ever.
const M30_CASE: &str = include_str!("data/cases/m30-end.ngc");

#[test]
fn m30_ends_the_program_and_a_second_start_runs_it_again() {
    let cfg = config("sim-mill.toml");
    let mut m = Machine::started(&cfg, M30_CASE, "m30-end.ngc");
    assert!(m.until(5.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert_eq!(m.status().axes[0], 10.0);
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    // Rewound: a new start runs the whole program again (X is already at 10, so it
    // reaches the end at once, without an error).
    m.command(Command::Mdi(rtcnc_kernel::FixedText::new("G0 X0").unwrap()));
    assert!(m.until(5.0, |s| s.axes[0] == 0.0 && s.state == MachineState::Idle));
    m.command(Command::Start { from_line: 0 });
    m.cycles(5);
    assert!(!m.status().program_ended);
    assert!(m.until(5.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert_eq!(m.status().axes[0], 10.0);
}

#[test]
fn m30_on_a_machine_with_a_pallet_shuttle_has_the_logic_exchange_the_pallets_first() {
    let mut cfg = config("sim-mill.toml");
    cfg.machine.pallet_shuttle = true;
    cfg.plc = Some(PlcSection {
        program: repo().join("crates/kernel/tests/data/pallet.st"),
        signals: [
            ("m_code_request", "Logic.m_req"),
            ("m_code_number", "Logic.m_num"),
            ("m_code_done", "Logic.m_done"),
        ]
        .iter()
        .map(|(s, v)| (s.to_string(), v.to_string()))
        .collect(),
        safe_values: Default::default(),
        axes: Default::default(),
    });
    let mut m = Machine::started(&cfg, M30_CASE, "m30-shuttle.ngc");
    let mut lamp = Vec::new();
    for _ in 0..2000 {
        m.cycles(1);
        lamp.push(m.handle_machine(|mach| mach.digital_output(1).unwrap()));
        if m.status().program_ended {
            break;
        }
    }
    assert!(m.status().program_ended);
    // The shuttle ran for the PLC's 50 ms (whole scans of 1 ms; the output is exchanged
    // one period after the scan that set it) and the program ended after it.
    let on = lamp.iter().filter(|&&l| l).count();
    assert!((49..=51).contains(&on), "{on}");
    assert!(!lamp.last().unwrap());
    assert!(m.faults.is_empty(), "{:?}", m.faults);
}
