//! `spindle.over_speed`: an S word above `spindle.max_speed_rpm` stops the program before
//! its block (refuse) or runs the spindle at its highest speed with a message (clamp).
//! Before, the mill waited for a speed its spindle cannot reach: no motion, no message.

use crate::common::*;
use rtcnc_kernel::config::OverSpeed;
use rtcnc_kernel::{FaultCode, MachineState};

const PROGRAM: &str = "G21 G90\nS30000 M3\nG1 X10 F1000\nM2\n";

#[test]
fn an_s_word_above_the_spindle_maximum_is_refused_by_default() {
    let cfg = config("sim-mill.toml");
    assert_eq!(cfg.spindle.unwrap().max_speed_rpm, 24_000.0);
    assert_eq!(cfg.spindle.unwrap().over_speed, OverSpeed::Refuse);
    let mut m = Machine::started(&cfg, PROGRAM, "over_speed.ngc");
    m.until(10.0, |s| s.state == MachineState::Idle && s.line >= 2);
    m.cycles(100);
    let error = m
        .faults
        .iter()
        .find(|f| f.code == FaultCode::ProgramError)
        .unwrap_or_else(|| panic!("{:?}", m.faults));
    assert_eq!(error.line, 2);
    let text = m.sim.handle().error_text().unwrap();
    assert!(text.contains("S30000"), "{text}");
    assert!(text.contains("spindle.max_speed_rpm"), "{text}");
    assert_eq!(m.status().state, MachineState::Idle);
    assert!(!m.status().program_ended);
    // Nothing after the refused block moved.
    assert!(m.samples.iter().all(|s| s.axes[0] == 0.0));
}

#[test]
fn clamp_runs_the_spindle_at_its_maximum_and_tells_the_operator() {
    let mut cfg = config("sim-mill.toml");
    if let Some(spindle) = cfg.spindle.as_mut() {
        spindle.over_speed = OverSpeed::Clamp;
    }
    let mut m = Machine::started(&cfg, PROGRAM, "over_speed_clamp.ngc");
    let mut commanded: f64 = 0.0;
    let ended = m.until(30.0, |s| {
        commanded = commanded.max(s.spindle_command_rpm.abs());
        s.program_ended && s.state == MachineState::Idle
    });
    assert!(ended, "{:?} {:?}", m.status(), m.faults);
    assert_eq!(commanded, 24_000.0);
    let last = m.samples.last().unwrap();
    assert!((last.axes[0] - 10.0).abs() < 1e-9, "{}", last.axes[0]);
    let messages = m.sim.handle().take_messages();
    assert!(
        messages.iter().any(|msg| msg.line == 2
            && msg.text.as_str() == "S30000 clamped to 24000 rpm (spindle.max_speed_rpm)"),
        "{messages:?}"
    );
}

#[test]
fn the_key_is_checked() {
    let text = std::fs::read_to_string(repo().join("configs/sim-mill.toml")).unwrap();
    let bad = text.replace(
        "max_speed_rpm = 24000.0",
        "max_speed_rpm = 24000.0\nover_speed = \"ignore\"",
    );
    let error = rtcnc_kernel::MachineConfig::parse(&bad, "mill.toml").unwrap_err();
    assert!(error.to_string().contains("over_speed"), "{error}");
}
