//! M19 through the whole kernel on the simulated spindle (orientation at 60 rpm = 0.36° per
//! 1 ms period, oriented within 0.5°): the program goes on once the spindle reports
//! oriented, and stops with a fault when M19 Q's time-out passes first.

use crate::common::*;
use rtcnc_kernel::{FaultCode, MachineState};

#[test]
fn m19_orients_the_spindle_and_q_waits_for_it_or_stops_the_program() {
    let text = "G21 G90
M19 R90 Q1
G1 X5 F600
M19 R0 P1 Q2
G1 X0
S1000 M3
G4 P0.5
M19 R45 Q0.1
G1 X5
M2
";
    let cfg = config("bench-xyz.toml");
    let mut m = Machine::started(&cfg, text, "m19.ngc");
    // (X set-point applied, spindle angle) after every exchange.
    let mut trace: Vec<(f64, f64)> = Vec::new();
    for _ in 0..10_000 {
        m.cycles(1);
        let x = m.samples.last().unwrap().axes[0];
        let angle = m.handle_machine(|mach| mach.spindle_angle_deg());
        trace.push((x, angle));
        if m.status().state == MachineState::Idle && trace.len() > 100 {
            break;
        }
    }
    // The first orientation: clockwise from 0, oriented in the 249th exchange of turning
    // (⌈89.5° / 0.36°⌉). The look-ahead sees it in that period and starts the move;
    // interpolation makes its first set-point in the next period, which the drives apply
    // in the one after: X leaves 248 + 2 exchanges after the first one that turned.
    let turning = trace.iter().position(|t| t.1 > 0.0).unwrap();
    let leaves = trace.iter().position(|t| t.0 > 0.0).unwrap();
    assert!(trace[leaves].1 >= 89.5 && trace[leaves].1 <= 90.0);
    assert_eq!(leaves - turning, 250);
    // The second, always clockwise from 90 to 0: through 180 and 270 before X returns.
    let at_5 = trace.iter().position(|t| t.0 == 5.0).unwrap();
    let back = at_5 + trace[at_5..].iter().position(|t| t.0 < 5.0).unwrap();
    assert!(trace[at_5..back].iter().any(|t| t.1 > 175.0 && t.1 < 185.0));
    assert!(
        trace[back].1 <= 0.5 || trace[back].1 >= 359.5,
        "{}",
        trace[back].1
    );
    // The third: the spindle first has to stop from 1000 rpm (0.125 s at 8000 rpm/s),
    // longer than Q0.1: the program stops at line 8 with the time-out, X stays at 0.
    let f = m
        .faults
        .iter()
        .find(|f| f.code == FaultCode::SpindleOrientTimeout)
        .expect("orientation time-out");
    assert_eq!(f.line, 8);
    assert!(!m.status().program_ended);
    assert_eq!(m.status().axes[0], 0.0);
    // Line 9 never moved X again.
    assert!(trace[back..].iter().all(|t| t.0 < 5.0));
}

#[test]
fn an_m19_time_out_longer_than_the_machine_will_run_waits_for_the_orientation() {
    // The orientation takes 249 periods; a time-out of 10^30 s must not wrap to "now".
    let text = "G21 G90\nM19 R90 Q[10**30]\nG1 X5 F600\nM2\n";
    let cfg = config("bench-xyz.toml");
    let mut m = Machine::started(&cfg, text, "m19-forever.ngc");
    assert!(m.until(10.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert_eq!(m.status().axes[0], 5.0);
    let angle = m.handle_machine(|mach| mach.spindle_angle_deg());
    assert!((89.5..=90.0).contains(&angle), "{angle}");
    assert!(m.faults.is_empty(), "{:?}", m.faults);
}
