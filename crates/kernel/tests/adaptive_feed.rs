//! M52 adaptive feed, as LinuxCNC's `motion.adaptive-feed` input: with M52 P1 the machine's
//! adaptive-feed analogue input, clamped to 0..=1, multiplies the programmed feed; M52 P0
//! runs at the programmed feed again; a machine without the input refuses M52 P1.

use crate::common::*;
use rtcnc_kernel::{Command, FaultCode, MachineState};

#[test]
fn the_analogue_input_scales_the_feed_while_m52_p1_is_in_force() {
    let mut cfg = config("bench-xyz.toml");
    cfg.io.adaptive_feed_input = Some(1);
    let text = "G21 G90 F3000
M52 P1
G1 X40
M52 P0
G1 X80
M2
";
    let mut m = Machine::new(&cfg, Some(program(text, "m52.ngc")));
    m.handle_machine(|mach| mach.set_analog_input(1, 0.5).unwrap());
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    // F3000 is 50 mm/s: half of it while the input reads 0.5 (the planner holds a feed to
    // within a few parts in 10^7).
    m.cycles(800);
    let s = m.samples.last().unwrap();
    assert_eq!(s.line, 3);
    assert!((s.path_speed - 25.0).abs() < 1e-3, "{}", s.path_speed);
    // The input rises to 0.8: the path speeds up to 40 mm/s within the limits.
    m.handle_machine(|mach| mach.set_analog_input(1, 0.8).unwrap());
    m.cycles(200);
    let s = m.samples.last().unwrap();
    assert_eq!(s.line, 3);
    assert!((s.path_speed - 40.0).abs() < 1e-3, "{}", s.path_speed);
    // Above 1 it counts as 1: the programmed feed.
    m.handle_machine(|mach| mach.set_analog_input(1, 1.7).unwrap());
    m.cycles(100);
    let s = m.samples.last().unwrap();
    assert_eq!(s.line, 3);
    assert!((s.path_speed - 50.0).abs() < 1e-3, "{}", s.path_speed);
    m.handle_machine(|mach| mach.set_analog_input(1, 0.5).unwrap());
    assert!(m.until(10.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    // After M52 P0 the input no longer counts: the second move at 50 mm/s.
    let second = m
        .samples
        .iter()
        .filter(|s| s.line == 5)
        .map(|s| s.path_speed)
        .fold(0.0f64, f64::max);
    assert!((second - 50.0).abs() < 1e-3, "{second}");
    // The first move's speed never went above what the input allowed at the time, nor did
    // any axis exceed its limits (100 mm/s, 1000 mm/s², by differences).
    let xs: Vec<f64> = m.samples.iter().map(|s| s.axes[0]).collect();
    for w in xs.windows(3) {
        let v = (w[2] - w[1]) / 1e-3;
        let a = (w[2] - 2.0 * w[1] + w[0]) / 1e-6;
        assert!(
            v.abs() <= 100.0 + 1e-6 && a.abs() <= 1000.0 + 1e-3,
            "{v} {a}"
        );
    }
}

#[test]
fn m52_p1_on_a_machine_without_the_input_stops_the_program_at_its_line() {
    let text = "G21 G90 F3000\nG1 X5\nM52 P1\nG1 X10\nM2\n";
    let mut m = Machine::started(&config("bench-xyz.toml"), text, "m52-none.ngc");
    assert!(m.until(5.0, |s| s.state == MachineState::Idle && s.axes[0] == 5.0));
    m.cycles(10);
    assert!(
        m.faults
            .iter()
            .any(|f| f.line == 3 && f.code == FaultCode::AuxRefused),
        "{:?}",
        m.faults
    );
    assert_eq!(m.status().axes[0], 5.0);
}
