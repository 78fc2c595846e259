//! G38.2-G38.5 through the whole kernel on a simulated touch probe over a surface at
//! Z = -3 (a probe device on the Z joint): the move stops where the probe changes, the
//! interpreter waits for the result, and #5061-#5070 hold it for the lines after.

use crate::common::*;
use rtcnc_fieldbus::sim::{DeviceConfig, ProbeSide};
use rtcnc_kernel::{Command, FaultCode, MachineConfig, MachineState, ProbeFailure};

fn machine() -> MachineConfig {
    let mut cfg = config("bench-xyz.toml");
    cfg.io.probe_input = Some(6);
    cfg.fieldbus.devices.push(DeviceConfig::Probe {
        input: 6,
        joint: 2,
        surface: -3.0,
        side: ProbeSide::Below,
    });
    cfg
}

#[test]
fn probing_finds_the_surface_and_the_program_uses_the_result() {
    let text = "G21 G90
G0 X1 Y2 Z0
G38.2 Z-10 F60
(DEBUG,down z #5063 ok #5070 x #5061 y #5062)
#1 = #5063
G38.4 Z0 F30
(DEBUG,up z #5063 ok #5070)
G0 Z[#1 + 5]
G38.3 Z-1 F600
(DEBUG,short z #5063 ok #5070)
G38.2 Z-2.5
M2
";
    let (m, messages) = run_to_idle_with_messages(&machine(), text, "probe.ngc", 30.0);
    assert_eq!(messages.len(), 3, "{messages:?} {:?}", m.faults);
    // Down at 1 mm/s (F60) on ideal drives: the drives latch where the probe closes, on
    // the surface (DEBUG prints 6 decimals); X and Y are where they were.
    let down = message_number(&messages[0], "down z");
    assert!((down + 3.0).abs() <= 5e-7, "{down}");
    assert_eq!(message_number(&messages[0], "ok"), 1.0);
    assert_eq!(message_number(&messages[0], "x"), 1.0);
    assert_eq!(message_number(&messages[0], "y"), 2.0);
    // Up at 0.5 mm/s until it opens: latched where it opens, on the surface again.
    let up = message_number(&messages[1], "up z");
    assert!((up + 3.0).abs() <= 5e-7, "{up}");
    assert_eq!(message_number(&messages[1], "ok"), 1.0);
    // G38.3 to Z-1 from Z2 never touches: no error, #5070 = 0, #5063 where it ended.
    assert_eq!(message_number(&messages[2], "short z"), -1.0);
    assert_eq!(message_number(&messages[2], "ok"), 0.0);
    // The G0 went to the first contact + 5: the interpreter read #5063 after the probe
    // (DEBUG prints 6 decimals).
    let top = m.samples.iter().map(|s| s.axes[2]).fold(f64::MIN, f64::max);
    assert!((top - (down + 5.0)).abs() <= 5e-7, "{top} {down}");
    // G38.2 to Z-2.5 ends without contact: the program stops there with the fault.
    let f = m
        .faults
        .iter()
        .find(|f| f.code == FaultCode::ProbeFailed)
        .unwrap();
    assert_eq!(f.line, 11);
    // With LinuxCNC's words (its motion controller's message for this case).
    assert_eq!(
        ProbeFailure::from_value(f.value),
        Some(ProbeFailure::NoContact)
    );
    assert!(
        f.describe(|_| String::new())
            .starts_with("G38.2 move finished without making contact. [kernel.probe_failed]"),
        "{}",
        f.describe(|_| String::new())
    );
    assert!(!m.status().program_ended);
    assert_eq!(m.status().axes[2], -2.5);
}

#[test]
fn a_probe_already_in_contact_refuses_g38_2() {
    let text = "G21 G90\nG0 Z-4\nG38.2 Z-10 F60\nM2\n";
    let (m, _) = run_to_idle_with_messages(&machine(), text, "probe-tripped.ngc", 10.0);
    assert_probe_failed(
        &m,
        3,
        ProbeFailure::AlreadyTripped,
        "Probe is already tripped when starting G38.2 or G38.3 move",
    );
    assert_eq!(m.status().axes[2], -4.0);
}

/// G38.4 from Z-4 (in contact, the surface is at Z-3) to Z-3.5 stays in contact: the
/// program stops at the move's end with LinuxCNC's "G38.4 move finished without breaking
/// contact.", and G38.5 there (no error wanted) refuses to start with the probe clear.
#[test]
fn a_g38_4_that_never_loses_contact_stops_the_program_with_linuxcncs_error() {
    for (text, line, failure, z) in [
        (
            "G21 G90\nG0 Z-4\nG38.4 Z-3.5 F60\nM2\n",
            3,
            ProbeFailure::ContactNotBroken,
            -3.5,
        ),
        (
            "G21 G90\nG0 Z-2\nG38.5 Z0 F60\nM2\n",
            3,
            ProbeFailure::AlreadyClear,
            -2.0,
        ),
    ] {
        let (m, _) = run_to_idle_with_messages(&machine(), text, "probe-away.ngc", 10.0);
        assert_probe_failed(&m, line, failure, failure.message());
        assert_eq!(m.status().axes[2], z);
    }
}

#[test]
fn the_simulated_mill_probes_the_top_of_its_workpiece_at_z_minus_50() {
    // Velocity drives and PID loops: the drives latch the load's position as the probe
    // closes, in whole encoder counts (0.04 µm), taken to move linearly within the period
    // (off by a·T²/8 at most: nearly at constant speed here).
    let text = "G21 G90\nG0 Z-45\nG38.2 Z-60 F100\n(DEBUG,#5063 #5070)\nG0 Z0\nM2\n";
    let mut m = Machine::new(
        &config("sim-mill.toml"),
        Some(program(text, "mill-probe.ngc")),
    );
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    assert!(m.until(30.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    let message = m.sim.handle().take_messages()[0].text;
    let mut words = message.as_str().split_whitespace();
    let z: f64 = words.next().unwrap().parse().unwrap();
    let ok: f64 = words.next().unwrap().parse().unwrap();
    assert_eq!(ok, 1.0);
    // (DEBUG prints 6 decimals.)
    assert!((z + 50.0).abs() <= 1e-6, "{z}");
}

#[test]
fn the_position_comes_from_the_drives_touch_probe_latch_not_from_the_period() {
    // At F600 (10 mm/s) one servo period's travel is 10 µm. The surface lies between two
    // periods' positions: the feedback of the period in which the probe is seen is up to
    // 10 µm past it; the drives latch where the load was at the edge's instant (the
    // surface, as the probe's own joint crosses it; X and Y where they stand), and report
    // it 3 ms after the edge (their latency here).
    let surface = -3.0037;
    let mut cfg = machine();
    cfg.fieldbus.devices[0] = DeviceConfig::Probe {
        input: 6,
        joint: 2,
        surface,
        side: ProbeSide::Below,
    };
    cfg.fieldbus.touch_probe_latency_s = Some(0.003);
    let text = "G21 G90
G0 X1 Y2 Z0
G38.2 Z-10 F600
(DEBUG,z #5063 ok #5070 x #5061 y #5062)
G0 Z[#5063 + 1]
M2
";
    let mut m = Machine::new(&cfg, Some(program(text, "latch.ngc")));
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    assert!(m.until(30.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    let message = m.sim.handle().take_messages()[0].text;
    let text = message.as_str();
    let z = message_number(text, "z");
    assert!((z - surface).abs() <= 1e-6, "{z}");
    assert_eq!(message_number(text, "ok"), 1.0);
    assert_eq!(message_number(text, "x"), 1.0);
    assert_eq!(message_number(text, "y"), 2.0);
    // What the period-based position would have been: the feedback of the first period
    // that ends at or below the surface (ideal drives: the load is on the set-point).
    let seen = m
        .samples
        .iter()
        .map(|s| s.feedback[2])
        .find(|&z| z <= surface)
        .unwrap();
    assert!(
        surface - seen > 1e-3 && surface - seen <= 0.010 + 1e-9,
        "{seen}"
    );
    // The program went on from the latched position: up to 1 mm above the surface.
    let top = m.samples.iter().rev().map(|s| s.axes[2]).next().unwrap();
    assert!((top - (z + 1.0)).abs() <= 5e-7, "{top}");
}
