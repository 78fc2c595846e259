//! M48-M53 through the whole kernel: the program switches the operator's overrides and the
//! feed stop switch off and on; each takes effect where the motion before it ends.

use crate::common::*;
use rtcnc_kernel::{Command, MachineState, Urgent};

fn top_speed(m: &Machine, from: f64, to: f64) -> f64 {
    m.samples
        .iter()
        .filter(|s| s.axes[0] > from && s.axes[0] < to)
        .map(|s| s.path_speed)
        .fold(0.0, f64::max)
}

#[test]
fn m49_and_m50_p0_run_at_the_programmed_feed_and_rapid_whatever_the_overrides() {
    let cfg = config("bench-xyz.toml");
    let text = "G21 G90 G61.1
G1 X10 F600
G0 X60
M49
G1 X70
G0 X120
M48
G1 X130
M50 P0
G1 X140
M50 P1
G1 X150
M2
";
    let mut m = Machine::new(&cfg, Some(program(text, "m49.ngc")));
    m.power_on();
    assert!(m.sim.handle().urgent(Urgent::FeedOverride(0.5)));
    assert!(m.sim.handle().urgent(Urgent::RapidOverride(0.5)));
    m.command(Command::Start { from_line: 0 });
    assert!(m.until(20.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    // F600 = 10 mm/s and the machine's 100 mm/s rapid, halved by the overrides where
    // they are in force; each move is long enough to reach its speed.
    let expected = [
        (0.0, 10.0, 5.0),
        (10.0, 60.0, 50.0),
        (60.0, 70.0, 10.0),
        (70.0, 120.0, 100.0),
        (120.0, 130.0, 5.0),
        (130.0, 140.0, 10.0),
        (140.0, 150.0, 5.0),
    ];
    for (from, to, v) in expected {
        let top = top_speed(&m, from, to);
        // The speed controller keeps a hair (1e-7) under its limits.
        assert!(
            (top - v).abs() < 1e-6 * v,
            "X{from}..X{to}: {top} mm/s, expected {v}"
        );
    }
}

#[test]
fn m51_p0_runs_the_spindle_at_the_programmed_speed() {
    let cfg = config("bench-xyz.toml");
    let text = "G21 G90\nS1000 M3\nG4 P0.5\nM51 P0\nG4 P0.5\nM51 P1\nG4 P0.5\nM2\n";
    let mut m = Machine::new(&cfg, Some(program(text, "m51.ngc")));
    m.power_on();
    assert!(m.sim.handle().urgent(Urgent::SpindleOverride(1.2)));
    m.command(Command::Start { from_line: 0 });
    // The spindle speed at the end of each dwell (the simulated spindle ramps at 8000
    // rpm/s, so it has long reached its command).
    let mut last_rpm = [0.0; 8];
    let mut again = false;
    for _ in 0..5000 {
        m.cycles(1);
        let s = m.status();
        if let Some(slot) = last_rpm.get_mut(s.line as usize) {
            *slot = s.spindle_rpm;
        }
        if s.line == 3 && !again {
            // The same override again changes nothing (it is a factor on the programmed
            // speed, not on the last command).
            again = true;
            assert!(m.sim.handle().urgent(Urgent::SpindleOverride(1.2)));
        }
        if s.program_ended && s.state == MachineState::Idle {
            break;
        }
    }
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    assert_eq!(
        [last_rpm[3], last_rpm[5], last_rpm[7]],
        [1200.0, 1000.0, 1200.0]
    );
}

#[test]
fn the_feed_stop_switch_holds_the_path_until_released_unless_m53_p0() {
    let mut cfg = config("bench-xyz.toml");
    cfg.io.feed_stop_input = Some(5);
    let text = "G21 G90 G61.1\nG1 X20 F600\nM53 P0\nG1 X40\nM53 P1\nM2\n";
    let mut m = Machine::started(&cfg, text, "m53.ngc");
    m.cycles(500);
    let switch = |m: &mut Machine, on: bool| {
        m.handle_machine(|mach| mach.set_digital_input(5, on).unwrap());
    };
    switch(&mut m, true);
    m.cycles(1000);
    // Stopped on the path within the 1000 periods, and standing still since.
    let held: Vec<f64> = m.samples[m.samples.len() - 500..]
        .iter()
        .map(|s| s.axes[0])
        .collect();
    assert!(held[0] > 0.0 && held[0] < 20.0, "{}", held[0]);
    assert!(held.iter().all(|&x| x == held[0]));
    assert_eq!(m.status().state, MachineState::Held);
    // Released: the path goes on by itself.
    switch(&mut m, false);
    assert!(m.until(5.0, |s| s.axes[0] == 20.0));
    // After M53 P0 the switch is ignored: switched on as the next move leaves, it does not
    // stop it; the 20 mm at 10 mm/s take their rest-to-rest S-curve time
    // 2 + 2·sqrt(10/50000) s, ceil(2.028284 / 1 ms) = 2029 periods.
    assert!(m.until(1.0, |s| s.axes[0] > 20.0));
    switch(&mut m, true);
    let ended = m.until(10.0, |s| s.program_ended && s.state == MachineState::Idle);
    assert!(ended, "{:?}", m.status());
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    let last_at_20 = m.samples.iter().rfind(|s| s.axes[0] == 20.0).unwrap().cycle;
    let first_at_40 = m.samples.iter().find(|s| s.axes[0] == 40.0).unwrap().cycle;
    assert_eq!(first_at_40 - last_at_20, 2029);
    // M53 P1 (and the program end) heed it again: with the switch still on, an MDI move
    // does not start.
    m.command(Command::Mdi(
        rtcnc_kernel::FixedText::new("G1 X30 F600").unwrap(),
    ));
    m.cycles(300);
    assert_eq!(m.status().axes[0], 40.0);
    switch(&mut m, false);
    assert!(m.until(5.0, |s| s.axes[0] == 30.0));
}

#[test]
fn a_tapping_cycle_which_switches_the_overrides_off_runs() {
    // G84 turns the overrides off for the tap (feed and spindle must stay in step) and
    // back on after it; the kernel used to refuse that.
    let cfg = config("bench-xyz.toml");
    let text = "G21 G90 G17\nS500 M3\nG0 X0 Y0 Z5\nG98 G84 X10 Y0 Z-5 R2 F500\nG80\nM5\nM2\n";
    let mut m = Machine::started(&cfg, text, "g84.ngc");
    assert!(m.until(20.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    let bottom = m.samples.iter().map(|s| s.axes[2]).fold(f64::MAX, f64::min);
    assert_eq!(bottom, -5.0);
    // G98: back to the initial level Z5 over the hole.
    assert_eq!(m.status().axes[..3], [10.0, 0.0, 5.0]);
}
