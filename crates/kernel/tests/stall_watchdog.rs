//! The stall watchdog (`safety.stall_timeout`, 2 s by default): a program's path that
//! stands still while it should move stops the program with `kernel.motion_stalled` at its
//! line; standing still on purpose (a hold, a dwell, a feed override of 0 %) does not.

use crate::common::*;
use rtcnc_kernel::{
    Command, FaultCode, FixedText, Kernel, KernelOptions, MachineState, Simulation, Urgent,
};

const PROGRAM: &str = "G21 G90 G61\nG1 X50 F600\nG1 X0\nM2\n";

fn machine(freeze_from: Option<u64>, name: &str) -> Machine {
    machine_with(freeze_from, false, name)
}

/// The bench machine with `PROGRAM` and the watchdog's fault injections.
fn machine_with(freeze_from: Option<u64>, refuse_moves: bool, name: &str) -> Machine {
    let cfg = config("bench-xyz.toml");
    let kernel = Kernel::build(
        &cfg,
        KernelOptions {
            program: Some(program(PROGRAM, name)),
            record_capacity: 1 << 14,
            freeze_path_from: freeze_from,
            refuse_moves,
            ..KernelOptions::default()
        },
    )
    .expect("kernel builds");
    let mut m = Machine {
        sim: Simulation::new(kernel),
        samples: Vec::new(),
        faults: Vec::new(),
    };
    m.power_on();
    m
}

#[test]
fn a_path_that_stalls_stops_the_program_with_the_line_after_the_timeout() {
    // The planner freezes half a second into the first line (10 mm/s: X about 4.6).
    let mut m = machine(Some(500), "stall.ngc");
    m.command(Command::Start { from_line: 0 });
    assert!(m.until(10.0, |s| s.state == MachineState::Idle && s.cycle > 100));
    let fault = m
        .faults
        .iter()
        .find(|f| f.code == FaultCode::MotionStalled)
        .copied()
        .expect("the watchdog's fault");
    assert_eq!(fault.line, 2);
    assert_eq!(fault.value, 2.0);
    // Counted from the period in which the first standing set-point (number 500) is the
    // next to apply, 2000 periods earlier than the one it is raised in: 499 + 2000 ms.
    assert_eq!(fault.time_ns, 2_499_000_000);
    assert!(!m.status().program_ended);
    let x = m.status().axes[0];
    assert!(x > 3.0 && x < 6.0, "{x}");
    // The machine is usable at once: an MDI move runs.
    m.command(Command::Mdi(FixedText::new("G1 X10 F600").unwrap()));
    assert!(m.until(5.0, |s| s.axes[0] == 10.0 && s.state == MachineState::Idle));
}

#[test]
fn standing_still_on_purpose_is_not_a_stall() {
    let text = "G21 G90 G61\nG1 X20 F600\nG4 P3\nG1 X0\nM2\n";
    let cfg = config("bench-xyz.toml");
    let mut m = Machine::started(&cfg, text, "still.ngc");
    // A 3 s dwell.
    m.cycles(2500);
    // A feed override of 0 % for 3 s while moving back.
    assert!(m.until(10.0, |s| s.axes[0] < 19.0));
    assert!(m.sim.handle().urgent(Urgent::FeedOverride(0.0)));
    m.cycles(3000);
    assert!(m.sim.handle().urgent(Urgent::FeedOverride(1.0)));
    // A 3 s hold.
    m.cycles(200);
    assert!(m.sim.handle().urgent(Urgent::FeedHold));
    m.cycles(3000);
    assert!(m.sim.handle().urgent(Urgent::Resume));
    assert!(m.until(20.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert!(m.faults.is_empty(), "{:?}", m.faults);
}

#[test]
fn a_block_that_cannot_be_handed_on_stops_the_program_with_its_line_after_the_timeout() {
    // The planner takes no move (injected), so the first G1 waits with the planner empty:
    // as the run from a line whose zero-length approach the planner kept refusing
    // (fuzz/defects/kernel/start-from-a-line-where-the-machine-stands) stood in `running`.
    let mut m = machine_with(None, true, "refused.ngc");
    m.command(Command::Start { from_line: 0 });
    assert!(m.until(10.0, |s| s.state == MachineState::Idle && s.cycle > 100));
    let fault = m
        .faults
        .iter()
        .find(|f| f.code == FaultCode::MotionStalled)
        .copied()
        .expect("the watchdog's fault");
    assert_eq!(fault.line, 2, "the waiting block's line");
    assert_eq!(fault.value, 2.0);
    assert!(!m.status().program_ended);
    assert_eq!(m.status().axes[0], 0.0);
}
