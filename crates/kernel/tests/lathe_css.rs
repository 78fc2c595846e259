//! G96 constant surface speed on the simulated lathe: the spindle speed follows the X
//! set-point every servo period, as LinuxCNC's motion controller computes it, and a G95
//! feed follows the spindle's measured speed.

use crate::common::*;
use rtcnc_kernel::MachineState;

/// rpm for S m/min at radius r mm: S·1000 / (2π·r), capped at D.
fn css_rpm(surface_m_per_min: f64, radius_mm: f64, max: f64) -> f64 {
    (surface_m_per_min * 1000.0 / (std::f64::consts::TAU * radius_mm)).min(max)
}

#[test]
fn the_spindle_speed_follows_x_under_g96_and_is_fixed_again_after_g97() {
    // X is programmed as a diameter (G7): X100 is a radius of 50 mm.
    let text = "G18 G21 G90 G7 G94 G64 P0.01
G0 X100 Z2
G96 S200 D3000 M3
G4 P1
G1 X40 F300
G4 P1
G1 X10
G4 P1
G97 S800
G4 P1
M5
M2
";
    let cfg = config("sim-lathe.toml");
    let mut m = Machine::started(&cfg, text, "css.ngc");
    let mut checked = 0;
    let mut at_dwell_end = [0.0; 12];
    for _ in 0..20_000 {
        m.cycles(1);
        let s = m.status();
        if (3..=8).contains(&s.line) && s.spindle_command_rpm > 0.0 {
            // Every period: the command from the X set-point (a radius).
            let expected = css_rpm(200.0, s.axes[0], 3000.0);
            assert!(
                (s.spindle_command_rpm - expected).abs() <= 1e-9 * expected,
                "line {} X {}: {} rpm, expected {expected}",
                s.line,
                s.axes[0],
                s.spindle_command_rpm
            );
            checked += 1;
        }
        if let Some(slot) = at_dwell_end.get_mut(s.line as usize) {
            *slot = s.spindle_rpm;
        }
        if s.program_ended && s.state == MachineState::Idle {
            break;
        }
    }
    assert!(
        m.faults.is_empty(),
        "{:?} {:?}",
        m.faults,
        m.sim.handle().error_text()
    );
    assert!(checked > 3000, "{checked}");
    // The measured speed at the end of each dwell, where X stands: radius 50 and 20 mm,
    // then 5 mm, where 6366 rpm is over D3000; after G97 S800, 800 rpm.
    assert_eq!(at_dwell_end[4], css_rpm(200.0, 50.0, 3000.0));
    assert_eq!(at_dwell_end[6], css_rpm(200.0, 20.0, 3000.0));
    assert_eq!(at_dwell_end[8], 3000.0);
    assert_eq!(at_dwell_end[10], 800.0);
    assert!((at_dwell_end[4] - 636.619_772_367_581_4).abs() < 1e-9);
}

#[test]
fn feed_per_revolution_under_g96_follows_the_spindle_as_it_speeds_up_with_the_diameter() {
    // Facing from a diameter of 60 to 10 at 0.2 mm per revolution, 100 m/min capped at
    // 3000 rpm: the spindle speeds up from 531 rpm towards the cap as the radius falls
    // (behind its command near the centre: it turns up at 2000 rpm/s), and X advances
    // 0.2 mm per revolution of the spindle as measured: 0.2 · rpm / 60 mm/s.
    let text = "G18 G21 G90 G7
G0 X60 Z0
G96 S100 D3000 M3
G95 F0.2
G1 X10
G0 Z5
M5
M2
";
    let cfg = config("sim-lathe.toml");
    let mut m = Machine::started(&cfg, text, "css-g95.ngc");
    let mut facing = Vec::new();
    for _ in 0..60_000 {
        m.cycles(1);
        let s = m.status();
        let sample = *m.samples.last().unwrap();
        if sample.line == 5 {
            facing.push((sample.axes[0], sample.path_speed, s.spindle_rpm));
        }
        if s.program_ended && s.state == MachineState::Idle {
            break;
        }
    }
    assert!(
        m.faults.is_empty(),
        "{:?} {:?}",
        m.faults,
        m.sim.handle().error_text()
    );
    assert!(m.status().program_ended);
    // From radius 29 to 6 (after the start, before the stop at radius 5).
    let cutting: Vec<_> = facing.iter().filter(|f| f.0 < 29.0 && f.0 > 6.0).collect();
    let slowest = cutting.iter().map(|f| f.2).fold(f64::MAX, f64::min);
    let fastest = cutting.iter().map(|f| f.2).fold(0.0, f64::max);
    assert!(slowest < 600.0 && fastest > 2500.0, "{slowest} {fastest}");
    let mut worst: f64 = 0.0;
    for &&(x, speed, rpm) in &cutting {
        let expected = 0.2 * rpm / 60.0;
        let error = (speed - expected) / expected;
        worst = worst.max(error.abs());
        // Within the 1 % step the feed is taken in by, and its jerk-limited change.
        assert!(
            error.abs() < 0.02,
            "radius {x}: {speed} mm/s at {rpm} rpm, {expected} by hand"
        );
    }
    eprintln!(
        "feed per revolution under G96: largest error {:.3} %",
        worst * 100.0
    );
    assert!(cutting.len() > 1000, "{}", cutting.len());
}
