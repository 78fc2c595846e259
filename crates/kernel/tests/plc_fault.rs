//! A PLC run-time fault reaches the operator with the PLC's own code, POU and line (before:
//! only "machine logic fault ... (-1)").

use crate::common::*;
use rtcnc_kernel::{FaultCode, MachineState};

#[test]
fn a_plc_fault_names_the_plcs_code_pou_and_line() {
    let mut cfg = config("sim-mill.toml");
    let plc = cfg.plc.as_mut().unwrap();
    let source = std::fs::read_to_string(repo().join("examples/plc/mill.st")).unwrap();
    let marker = "  (* ---- e-stop chain ---- *)";
    let line = source.lines().position(|l| l == marker).unwrap() + 1;
    // A division by zero once the spindle is asked for, on the marker's line.
    let faulty = source.replacen(
        marker,
        &format!(
            "  IF spindle_on THEN lube_cycles := lube_cycles / (lube_cycles - lube_cycles); END_IF;\n{marker}"
        ),
        1,
    );
    let path = program(&faulty, "faulty_mill.st");
    plc.program = path;
    let mut m = Machine::started(
        &cfg,
        "G21 G90\nS1000 M3\nG1 X10 F100\nM2\n",
        "plc_fault.ngc",
    );
    m.until(5.0, |s| {
        matches!(s.state, MachineState::Fault | MachineState::EStop)
    });
    let fault = m
        .faults
        .iter()
        .find(|f| f.code == FaultCode::LogicFault)
        .unwrap_or_else(|| panic!("{:?}", m.faults));
    let text = m.sim.handle().describe(fault);
    assert!(
        text.starts_with("machine logic fault [kernel.logic_fault]"),
        "{text}"
    );
    assert!(
        text.ends_with(&format!(
            ": PLC fault [division-by-zero] in MillLogic line {line}: division by zero"
        )),
        "{text}"
    );
    assert!(!text.contains("(-1)"), "{text}");
}
