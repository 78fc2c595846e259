//! G33 and G76 through the whole kernel on the simulated lathe: a threading pass waits for
//! the spindle's index, then its progress follows pitch × spindle revolutions, so every
//! pass cuts the same helix.

mod common;
use common::*;
use rtcnc_kernel::{Command, FaultCode, MachineState};

/// Runs `text` on the lathe and records, per exchange, (Z set-point applied, spindle angle,
/// program line).
fn run(text: &str, name: &str) -> (Machine, Vec<(f64, f64, u32)>) {
    let cfg = config("sim-lathe.toml");
    let mut m = Machine::new(&cfg, Some(program(text, name)));
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    let mut trace = Vec::new();
    for _ in 0..60_000 {
        m.cycles(1);
        let s = *m.samples.last().unwrap();
        let angle = m.handle_machine(|mach| mach.spindle_angle_deg());
        trace.push((s.axes[2], angle, s.line));
        let st = m.status();
        if trace.len() > 10 && st.state == MachineState::Idle {
            break;
        }
    }
    (m, trace)
}

/// The thread's phase at a sample: revolutions the spindle is ahead of the tool's Z
/// (`z0 - z` = pitch × revolutions since the index for a synchronised pass), as a fraction
/// of a turn, in (-0.5, 0.5].
fn phase(z0: f64, pitch: f64, z: f64, angle: f64) -> f64 {
    let p = (z0 - z) / pitch - angle / 360.0;
    p - p.round()
}

#[test]
fn g33_passes_follow_the_spindle_and_cut_the_same_helix() {
    // 600 rpm, 1.5 mm per revolution: 15 mm/s along -Z. Two passes from Z5 to Z-20.
    let text = "G18 G21 G90 G7
G0 X20 Z5
S600 M3
G33 Z-20 K1.5
G0 X30
G0 Z5
G0 X20
G33 Z-20 K1.5
G0 X30
M5
M2
";
    let (m, trace) = run(text, "g33.ngc");
    assert!(
        m.faults.is_empty(),
        "{:?} {:?}",
        m.faults,
        m.sim.handle().error_text()
    );
    assert!(m.status().program_ended);
    for pass_line in [4, 8] {
        // Between Z0 and Z-15 the pass has caught up with the spindle: its phase is the
        // index's (0) within a micrometre of Z (1 µm / 1.5 mm of a turn).
        let steady: Vec<_> = trace
            .iter()
            .filter(|t| t.2 == pass_line && t.0 < 0.0 && t.0 > -15.0)
            .collect();
        assert!(steady.len() > 900, "{}", steady.len());
        for t in steady {
            let p = phase(5.0, 1.5, t.0, t.1);
            assert!(
                p.abs() < 1e-3 / 1.5,
                "line {pass_line} Z {} angle {}: {p}",
                t.0,
                t.1
            );
        }
        // It ends on the programmed end.
        let last = trace.iter().rfind(|t| t.2 == pass_line).unwrap();
        assert_eq!(last.0, -20.0);
    }
    // Catching up and stopping keep Z's limits.
    let cfg = config("sim-lathe.toml");
    let mut stats = rtcnc_kernel::report::RunStats::new();
    for s in &m.samples {
        stats.add(s, 0.001);
    }
    let z = cfg.axis(rtcnc_motion::Axis::Z).unwrap();
    assert!(stats.max_velocity[2] <= z.max_velocity * (1.0 + 1e-6));
    assert!(
        stats.max_acceleration[2] <= z.max_acceleration * (1.0 + 1e-6),
        "{}",
        stats.max_acceleration[2]
    );
    assert!(
        stats.max_jerk[2] <= z.max_jerk * (1.0 + 1e-6),
        "{}",
        stats.max_jerk[2]
    );
}

#[test]
fn a_feed_hold_in_a_thread_pass_takes_effect_at_its_end() {
    let text = "G18 G21 G90 G7\nG0 X20 Z5\nS600 M3\nG33 Z-20 K1.5\nG0 X30\nM2\n";
    let cfg = config("sim-lathe.toml");
    let mut m = Machine::started(&cfg, text, "g33-hold.ngc");
    assert!(m.until(10.0, |s| s.axes[2] < 0.0));
    assert!(m.sim.handle().urgent(rtcnc_kernel::Urgent::FeedHold));
    // The pass goes on to its end, then the program waits (X stays at the thread).
    assert!(m.until(5.0, |s| s.axes[2] == -20.0 && s.path_speed == 0.0));
    m.cycles(500);
    assert_eq!(m.status().state, MachineState::Held);
    assert_eq!(m.status().axes[0], 10.0);
    assert!(m.sim.handle().urgent(rtcnc_kernel::Urgent::Resume));
    assert!(m.until(5.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert_eq!(m.status().axes[0], 15.0);
}

#[test]
fn a_g76_cycle_runs_its_passes_on_the_same_helix() {
    // G76 on a 20 mm diameter: pitch 1.5, the drive line at X22 (diameter), thread peak
    // 1 mm (radius) below it, first cut 0.3, full depth 0.9, straight infeed (Q0), from Z5
    // to Z-20: every pass starts at Z5 and waits for the index, so all cut one helix.
    let text = "G18 G21 G90 G7
G0 X22 Z5
S600 M3
G76 P1.5 Z-20 I-1 J0.3 K0.9 Q0 H1
G0 X30
M5
M2
";
    let (m, trace) = run(text, "g76.ngc");
    assert!(
        m.faults.is_empty(),
        "{:?} {:?}",
        m.faults,
        m.sim.handle().error_text()
    );
    assert!(m.status().program_ended);
    // The cutting samples: line 4, moving towards -Z, between Z0 and Z-15 (each pass has
    // caught up with the spindle by Z0, see the G33 test).
    let cutting: Vec<_> = trace
        .windows(2)
        .filter(|w| w[1].2 == 4 && w[1].0 < w[0].0 && w[1].0 < 0.0 && w[1].0 > -15.0)
        .map(|w| w[1])
        .collect();
    // Pass n cuts to J·n^(1/R) (R1, the default): 0.3, 0.6, 0.9 = K, then H1 spring pass.
    let passes = 1 + cutting.windows(2).filter(|w| w[1].0 > w[0].0).count();
    assert_eq!(passes, 4);
    assert!(cutting.len() > 900 * passes, "{}", cutting.len());
    for t in &cutting {
        let p = phase(5.0, 1.5, t.0, t.1);
        assert!(p.abs() < 1e-3 / 1.5, "Z {} angle {}: {p}", t.0, t.1);
    }
}

#[test]
fn a_spindle_too_fast_for_the_pitch_stops_the_program_before_the_pass() {
    // 3000 rpm at 5 mm per revolution is 250 mm/s along Z, over the lathe's 120 mm/s.
    let text = "G18 G21 G90 G7\nG0 X20 Z5\nS3000 M3\nG33 Z-20 K5\nM2\n";
    let cfg = config("sim-lathe.toml");
    let mut m = Machine::started(&cfg, text, "g33-fast.ngc");
    m.cycles(2);
    assert!(m.until(10.0, |s| s.state == MachineState::Idle));
    let f = m.faults.iter().find(|f| f.code == FaultCode::SyncFailed);
    assert!(f.is_some_and(|f| f.line == 4), "{:?}", m.faults);
    assert!(m.samples.iter().all(|s| s.axes[2] == 5.0 || s.line < 4));
}

#[test]
fn a_g76_with_tapers_is_refused_before_its_first_chained_move() {
    // E1 L3: taper entry and exit, which chain synchronised moves through corners.
    let text = "G18 G21 G90 G7\nG0 X22 Z5\nS600 M3\nG76 P1.5 Z-20 I-1 J0.3 K0.9 Q0 E1 L3\nM2\n";
    let cfg = config("sim-lathe.toml");
    let mut m = Machine::started(&cfg, text, "g76-taper.ngc");
    m.cycles(2);
    assert!(m.until(20.0, |s| s.state == MachineState::Idle));
    let f = m.faults.iter().find(|f| f.code == FaultCode::ProgramError);
    assert!(f.is_some_and(|f| f.line == 4), "{:?}", m.faults);
    let words = m.sim.handle().error_text().unwrap();
    assert!(
        words.contains("consecutive spindle-synchronised moves"),
        "{words}"
    );
    // Nothing of it cut: on line 4 Z stayed on the drive line's Z5 (the pass went only to
    // its depth in X at the start).
    assert!(
        m.samples
            .iter()
            .filter(|s| s.line == 4)
            .all(|s| s.axes[2] == 5.0)
    );
    assert!(m.samples.iter().any(|s| s.line == 4));
}
