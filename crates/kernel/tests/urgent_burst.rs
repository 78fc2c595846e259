//! A burst of aborts in one period, then an MDI line: found by the kernel fuzz target
//! (fuzz/src/kernel.rs). Every abort asks the interpreter to stop; eight of them filled its
//! request mailbox before it ran, the MDI line's request was dropped, and the machine stood
//! in `running` for ever without a fault. A command whose request cannot be delivered is
//! refused (`kernel.command_refused`), as any command refused in its state.

use crate::common::*;
use rtcnc_kernel::{Command, FixedText, MachineState, Urgent};

#[test]
fn an_mdi_line_after_a_burst_of_aborts_runs_or_is_refused() {
    let cfg = config("sim-mill.toml");
    let mut m = Machine::new(&cfg, None);
    m.power_on();
    for _ in 0..8 {
        assert!(m.sim.handle().urgent(Urgent::Abort));
    }
    m.command(Command::Mdi(FixedText::truncated("G0 X1")));
    m.cycles(1000);
    let refused = m
        .faults
        .iter()
        .any(|f| f.code.as_str() == "kernel.command_refused");
    let ran = (m.status().axes[0] - 1.0).abs() < 1e-9;
    assert_eq!(m.status().state, MachineState::Idle, "{:?}", m.status());
    assert!(
        refused != ran,
        "refused {refused}, ran {ran}: {:?}",
        m.faults
    );
    // The interpreter has read the stops by now: the next line runs.
    m.command(Command::Mdi(FixedText::truncated("G0 X2")));
    assert!(m.until(2.0, |s| s.state == MachineState::Idle && s.axes[0] == 2.0));
}
