//! Modes and operator commands on the whole machine, in virtual time.

use crate::common::*;
use rtcnc_kernel::{Command, FixedText, MachineState, Urgent};

#[test]
fn a_program_ends_exactly_at_its_programmed_end_point() {
    let text =
        "G21 G90 G61.1\nG0 X3 Y4 Z-1\nG1 X12.5 Y7.25 F1500\nG2 X22.5 Y7.25 I5 J0\nG1 Z-2.125\nM2\n";
    let cfg = config("sim-mill.toml");
    let mut m = Machine::started(&cfg, text, "end.ngc");
    assert!(m.until(10.0, |s| s.program_ended && s.state == MachineState::Idle));
    m.cycles(200);
    let last = m.samples.last().unwrap();
    assert_eq!(&last.axes[..3], &[22.5, 7.25, -2.125]);
    assert_eq!(&last.setpoint[..3], &[22.5, 7.25, -2.125]);
    for j in 0..3 {
        assert!(
            (last.feedback[j] - last.setpoint[j]).abs() < 1e-4,
            "joint {j}"
        );
    }
    // The arc passed through its top, 5 mm above the chord.
    let top = m.samples.iter().map(|s| s.axes[1]).fold(f64::MIN, f64::max);
    assert!((top - 12.25).abs() < 1e-3, "top {top}");
}

#[test]
fn feed_hold_stops_on_the_path_and_resume_continues_to_the_end() {
    let text = "G21 G90 G61.1\nG1 X100 Y50 F3000\nM2\n";
    let cfg = config("sim-mill.toml");
    let mut m = Machine::started(&cfg, text, "hold.ngc");
    m.cycles(600);
    assert!(m.sim.handle().urgent(Urgent::FeedHold));
    assert!(m.until(2.0, |s| s.state == MachineState::Held
        && s.path_speed == 0.0));
    // Position control applies a set-point one period after interpolation made it.
    m.cycles(1);
    let held_at = m.samples.last().unwrap().axes;
    m.cycles(500);
    // Held: not a micrometre of motion, and still on the line (y = x / 2).
    assert_eq!(m.samples.last().unwrap().axes, held_at);
    assert!((held_at[1] - held_at[0] / 2.0).abs() < 1e-9);
    assert!(held_at[0] > 20.0 && held_at[0] < 100.0);
    assert!(m.sim.handle().urgent(Urgent::Resume));
    assert!(m.until(10.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert_eq!(&m.samples.last().unwrap().axes[..3], &[100.0, 50.0, 0.0]);
    assert!(m.faults.is_empty(), "{:?}", m.faults);
}

#[test]
fn mdi_lines_move_the_machine() {
    let cfg = config("sim-mill.toml");
    let mut m = Machine::new(&cfg, None);
    m.power_on();
    m.command(Command::Mdi(FixedText::new("G21 G90 G0 X5 Y6").unwrap()));
    m.cycles(5);
    assert!(m.until(5.0, |s| s.state == MachineState::Idle));
    m.command(Command::Mdi(FixedText::new("G91 G1 Z-1.5 F600").unwrap()));
    m.cycles(5);
    assert!(m.until(5.0, |s| s.state == MachineState::Idle));
    assert_eq!(&m.status().axes[..3], &[5.0, 6.0, -1.5]);
    assert!(m.faults.is_empty(), "{:?}", m.faults);
}

#[test]
fn jog_increments_and_the_handwheel_move_the_axes_by_exact_amounts() {
    let cfg = config("sim-mill.toml");
    let mut m = Machine::new(&cfg, None);
    m.power_on();
    m.command(Command::JogIncrement {
        axis: 0,
        distance: 10.0,
    });
    m.cycles(5);
    assert!(m.until(5.0, |s| s.state == MachineState::Idle));
    assert_eq!(m.status().axes[0], 10.0);
    // Continuous jog at 20 mm/s, stopped 300 ms later: the stop ramp mirrors the start
    // ramp, so the axis travels exactly 20 mm/s × 0.3 s.
    m.command(Command::JogContinuous {
        axis: 1,
        velocity: 20.0,
    });
    m.cycles(300);
    m.command(Command::JogStop { axis: 1 });
    m.cycles(5);
    assert!(m.until(5.0, |s| s.state == MachineState::Idle));
    let y = m.status().axes[1];
    assert!((y - 6.0).abs() < 1e-9, "y {y}");
    // Handwheel on Z at ×10: 0.01 mm per count; 250 counts down.
    m.command(Command::Handwheel {
        axis: Some(2),
        scale: 10.0,
    });
    m.cycles(5);
    m.sim
        .handle()
        .simulated_machine()
        .unwrap()
        .with(|machine| machine.turn_handwheel(-250));
    m.cycles(5);
    assert!(m.until(5.0, |s| s.state == MachineState::Idle));
    assert!(
        (m.status().axes[2] - -2.5).abs() < 1e-12,
        "z {}",
        m.status().axes[2]
    );
    // A program afterwards starts from where the jogs left the machine.
    assert!(m.faults.is_empty(), "{:?}", m.faults);
}

#[test]
fn homing_finds_switch_and_index_and_ends_at_the_home_positions() {
    let cfg = config("sim-mill.toml");
    let mut m = Machine::new(&cfg, None);
    m.power_on();
    m.command(Command::HomeAll);
    m.cycles(5);
    assert!(m.until(120.0, |s| s.state == MachineState::Idle));
    assert_eq!(m.status().homed, 0b111);
    assert_eq!(&m.status().axes[..3], &[0.0, 0.0, 0.0]);
    // The index pulses are at multiples of 5 mm of the raw (motor) position and the
    // latched one is declared 305 / 205 / 10: the raw frame agrees with the machine one.
    m.sim.handle().simulated_machine().unwrap().with(|machine| {
        for j in 0..3 {
            let (x, _) = machine.true_state(j).unwrap();
            assert!(x.abs() < 1e-3, "joint {j} at {x}");
        }
    });
    assert!(m.faults.is_empty(), "{:?}", m.faults);
}

#[test]
fn gantry_joints_are_homed_together_and_squared() {
    let cfg = config("sim-gantry-12.toml");
    let mut m = Machine::new(&cfg, None);
    m.power_on();
    let true_x = |m: &Machine| -> Vec<f64> {
        m.sim
            .handle()
            .simulated_machine()
            .unwrap()
            .with(|machine| (0..8).map(|j| machine.true_state(j).unwrap().0).collect())
    };
    // Racked at power-up: X1 stands 0.3 mm ahead of X0, Y2 0.2 mm ahead of Y0.
    let before = true_x(&m);
    assert!((before[1] - before[0] - 0.3).abs() < 1e-6);
    m.command(Command::HomeAll);
    m.cycles(5);
    assert!(m.until(300.0, |s| s.state == MachineState::Idle));
    assert_eq!(m.status().homed, (1 << 12) - 1);
    let after = true_x(&m);
    for (j, x) in after.iter().enumerate() {
        assert!(x.abs() < 1e-3, "joint {j} at {x}");
    }
    for g in [&after[0..4], &after[4..8]] {
        let spread =
            g.iter().fold(f64::MIN, |a, &b| a.max(b)) - g.iter().fold(f64::MAX, |a, &b| a.min(b));
        // Within 1 µm of each other (the encoder count is 38 nm).
        assert!(spread < 1e-3, "gantry joints {g:?}");
    }
    assert!(m.faults.is_empty(), "{:?}", m.faults);
}

#[test]
fn two_runs_give_byte_identical_traces() {
    let run = || {
        let cfg = config("sim-mill.toml");
        let mut m = Machine::new(&cfg, Some(repo().join("examples/bracket.ngc")));
        m.power_on();
        m.command(Command::Start { from_line: 0 });
        m.cycles(3000);
        let samples = m.samples.len();
        (
            m.sim.into_runner().recording().trace().to_chrome_json(),
            samples,
        )
    };
    let (a, n) = run();
    let (b, _) = run();
    assert!(n > 2900);
    assert!(a.len() > 100_000);
    assert!(a == b, "traces differ");
}

#[test]
fn work_offsets_persist_in_the_parameter_file_across_runs() {
    let dir = std::env::temp_dir().join(format!("rtcnc-params-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let var = dir.join("mill.var");
    let _ = std::fs::remove_file(&var);
    let mut cfg = config("sim-mill.toml");
    cfg.files.parameters = Some(var.clone());
    // First run: set G54's X offset to 12.5.
    let mut m = Machine::started(&cfg, "G10 L2 P1 X12.5\nM2\n", "set.ngc");
    assert!(m.until(2.0, |s| s.program_ended));
    assert!(var.exists());
    // A new kernel (a restart) reads it: X0 in G54 is machine X12.5.
    let mut m = Machine::started(&cfg, "G21 G90 G54 G0 X0\nM2\n", "use.ngc");
    assert!(m.until(5.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert_eq!(m.status().axes[0], 12.5);
}

#[test]
fn single_block_optional_stop_and_run_from_line() {
    let text = "G21 G90 G61.1\nG1 X10 F3000\nG1 Y10\nM1\nG1 X0\nG1 Y0\nM2\n";
    let cfg = config("sim-mill.toml");
    // Single block: the machine stops after each motion block until Resume.
    let mut m = Machine::new(&cfg, Some(program(text, "blocks.ngc")));
    m.power_on();
    m.command(Command::SingleBlock(true));
    m.command(Command::Start { from_line: 0 });
    assert!(m.until(3.0, |s| s.state == MachineState::Paused));
    assert_eq!(&m.status().axes[..2], &[10.0, 0.0]);
    m.cycles(300);
    assert_eq!(&m.status().axes[..2], &[10.0, 0.0]);
    assert!(m.sim.handle().urgent(Urgent::Resume));
    m.cycles(3);
    assert!(m.until(3.0, |s| s.state == MachineState::Paused));
    assert_eq!(&m.status().axes[..2], &[10.0, 10.0]);
    // Optional stop on: M1 pauses too (single block off from here on).
    m.command(Command::SingleBlock(false));
    m.command(Command::OptionalStop(true));
    m.cycles(3);
    assert!(m.sim.handle().urgent(Urgent::Resume));
    m.cycles(3);
    assert!(m.until(3.0, |s| s.state == MachineState::Paused));
    assert_eq!(&m.status().axes[..2], &[10.0, 10.0]);
    assert!(m.sim.handle().urgent(Urgent::Resume));
    assert!(m.until(5.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert_eq!(&m.status().axes[..2], &[0.0, 0.0]);

    // Run from line 6 (G1 Y0): the motion before it is skipped; the machine goes at rapid
    // to where line 6 starts (X0 Y10, the end of line 5), then runs line 6.
    let mut m = Machine::new(&cfg, Some(program(text, "blocks.ngc")));
    m.power_on();
    m.command(Command::Start { from_line: 6 });
    assert!(m.until(5.0, |s| s.program_ended && s.state == MachineState::Idle));
    let max_x = m.samples.iter().map(|s| s.axes[0]).fold(f64::MIN, f64::max);
    assert_eq!(max_x, 0.0, "never went to X10");
    let max_y = m.samples.iter().map(|s| s.axes[1]).fold(f64::MIN, f64::max);
    assert_eq!(max_y, 10.0);
    assert_eq!(&m.status().axes[..2], &[0.0, 0.0]);
}

#[test]
fn block_delete_skips_slashed_lines() {
    let text = "G21 G90 G61.1\n/G1 X10 F3000\nG1 Y5 F3000\nM2\n";
    let cfg = config("sim-mill.toml");
    for (on, x) in [(false, 10.0), (true, 0.0)] {
        let mut m = Machine::new(&cfg, Some(program(text, "slash.ngc")));
        m.power_on();
        m.command(Command::BlockDelete(on));
        m.cycles(2);
        m.command(Command::Start { from_line: 0 });
        assert!(m.until(5.0, |s| s.program_ended && s.state == MachineState::Idle));
        let max_x = m.samples.iter().map(|s| s.axes[0]).fold(f64::MIN, f64::max);
        assert_eq!(max_x, x, "block delete {on}");
        assert_eq!(m.status().axes[1], 5.0);
    }
}

#[test]
fn feed_override_scales_the_path_speed() {
    // 600 mm/min = 10 mm/s; at 50 % override the cruise is 5 mm/s.
    let text = "G21 G90 G61.1\nG1 X20 F600\nM2\n";
    let cfg = config("sim-mill.toml");
    let mut m = Machine::new(&cfg, Some(program(text, "slow.ngc")));
    m.power_on();
    assert!(m.sim.handle().urgent(Urgent::FeedOverride(0.5)));
    m.command(Command::Start { from_line: 0 });
    m.cycles(1500);
    // The planner cruises a few parts per million under the programmed feed.
    let v = m.status().path_speed;
    assert!((v - 5.0).abs() < 5e-5 * 5.0, "path speed {v}");
    assert!(m.sim.handle().urgent(Urgent::FeedOverride(1.0)));
    m.cycles(500);
    let v = m.status().path_speed;
    assert!((v - 10.0).abs() < 5e-5 * 10.0, "path speed {v}");
}

#[test]
fn abort_stops_along_the_path_and_a_new_start_runs_the_program_again() {
    let text = "G21 G90 G61.1\nG1 X100 Y50 F3000\nG1 X0 Y0\nM2\n";
    let cfg = config("sim-mill.toml");
    let mut m = Machine::started(&cfg, text, "abort.ngc");
    m.cycles(800);
    assert!(m.sim.handle().urgent(Urgent::Abort));
    assert!(m.until(2.0, |s| s.state == MachineState::Idle
        && s.path_speed == 0.0));
    m.cycles(300);
    let at = m.samples.last().unwrap().axes;
    // Stopped on the first line (y = x / 2), short of its end, and stays there.
    assert!((at[1] - at[0] / 2.0).abs() < 1e-9);
    assert!(at[0] > 10.0 && at[0] < 100.0);
    assert!(!m.status().program_ended);
    m.cycles(200);
    assert_eq!(m.samples.last().unwrap().axes, at);
    // Start again: the program runs from its first line, from where the machine stands.
    m.command(Command::Start { from_line: 0 });
    assert!(m.until(10.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert_eq!(&m.status().axes[..2], &[0.0, 0.0]);
    let max_x = m.samples.iter().map(|s| s.axes[0]).fold(f64::MIN, f64::max);
    assert_eq!(max_x, 100.0);
}

#[test]
fn after_an_estop_a_reset_enables_the_drives_again() {
    let cfg = config("sim-mill.toml");
    let mut m = Machine::new(&cfg, None);
    m.power_on();
    m.command(Command::JogIncrement {
        axis: 0,
        distance: 50.0,
    });
    m.cycles(500);
    assert!(m.sim.handle().urgent(Urgent::EStop));
    assert!(m.until(2.0, |s| s.state == MachineState::EStop && !s.ready));
    // Commands other than reset are refused in e-stop.
    m.command(Command::Mdi(FixedText::new("G0 X1").unwrap()));
    m.cycles(5);
    assert_eq!(m.status().state, MachineState::EStop);
    m.command(Command::Reset);
    assert!(m.until(1.0, |s| s.ready && s.state == MachineState::Idle));
    m.command(Command::Mdi(FixedText::new("G21 G90 G0 X1 Y2").unwrap()));
    m.cycles(5);
    assert!(m.until(5.0, |s| s.state == MachineState::Idle));
    assert_eq!(&m.status().axes[..2], &[1.0, 2.0]);
}

#[test]
fn rapid_and_spindle_overrides() {
    let text = "G21 G90 G61.1\nS6000 M3\nG0 X200\nM2\n";
    let cfg = config("sim-mill.toml");
    let mut m = Machine::new(&cfg, Some(program(text, "rapid.ngc")));
    m.power_on();
    assert!(m.sim.handle().urgent(Urgent::RapidOverride(0.5)));
    assert!(m.sim.handle().urgent(Urgent::SpindleOverride(1.2)));
    m.command(Command::Start { from_line: 0 });
    assert!(m.until(10.0, |s| s.program_ended && s.state == MachineState::Idle));
    // The rapid runs at half the X limit of 100 mm/s.
    let mut stats = rtcnc_kernel::report::RunStats::new();
    for s in &m.samples {
        stats.add(s, 0.001);
    }
    assert!(
        (stats.max_velocity[0] - 50.0).abs() < 0.01,
        "{}",
        stats.max_velocity[0]
    );
    // The spindle turns at 120 % of S6000.
    assert!(
        (m.status().spindle_rpm - 7200.0).abs() < 1e-6,
        "{}",
        m.status().spindle_rpm
    );
}

#[test]
fn homing_one_axis_homes_its_joints_only() {
    let cfg = config("sim-mill.toml");
    let mut m = Machine::new(&cfg, None);
    m.power_on();
    m.command(Command::JogIncrement {
        axis: 0,
        distance: 10.0,
    });
    m.cycles(5);
    assert!(m.until(5.0, |s| s.state == MachineState::Idle));
    m.command(Command::HomeAxis { axis: 1 });
    m.cycles(5);
    assert!(m.until(120.0, |s| s.state == MachineState::Idle));
    assert_eq!(m.status().homed, 0b010);
    // Y at its home position; X where the jog left it, Z where it was.
    assert_eq!(&m.status().axes[..3], &[10.0, 0.0, 0.0]);
    m.sim.handle().simulated_machine().unwrap().with(|machine| {
        let (y, _) = machine.true_state(1).unwrap();
        assert!(y.abs() < 1e-3, "Y at {y}");
    });
    m.command(Command::HomeAxis { axis: 0 });
    m.cycles(5);
    assert!(m.until(120.0, |s| s.state == MachineState::Idle));
    assert_eq!(m.status().homed, 0b011);
    assert_eq!(&m.status().axes[..3], &[0.0, 0.0, 0.0]);
    assert!(m.faults.is_empty(), "{:?}", m.faults);
}

#[test]
fn homing_a_gantry_axis_squares_its_joints_and_leaves_the_others() {
    let cfg = config("sim-gantry-12.toml");
    let mut m = Machine::new(&cfg, None);
    m.power_on();
    m.command(Command::HomeAxis { axis: 0 });
    m.cycles(5);
    assert!(m.until(300.0, |s| s.state == MachineState::Idle));
    // X's four joints (0..4, as in the homing-all test) and no other.
    assert_eq!(m.status().homed, 0b1111);
    let x: Vec<f64> = m
        .sim
        .handle()
        .simulated_machine()
        .unwrap()
        .with(|machine| (0..4).map(|j| machine.true_state(j).unwrap().0).collect());
    for (j, p) in x.iter().enumerate() {
        assert!(p.abs() < 1e-3, "joint {j} at {p}");
    }
    assert!(m.faults.is_empty(), "{:?}", m.faults);
}

#[test]
fn distance_to_go_is_from_the_set_point_to_the_programmed_end_of_the_line() {
    let text = "G21 G90 G61.1\nG1 X100 F3000\nG1 Y50 Z-5\nM2\n";
    let cfg = config("sim-mill.toml");
    let mut m = Machine::started(&cfg, text, "togo.ngc");
    for (line, end) in [(2, [100.0, 0.0, 0.0]), (3, [100.0, 50.0, -5.0])] {
        assert!(m.until(10.0, |s| s.line == line && s.path_speed > 10.0));
        for _ in 0..50 {
            m.cycles(7);
            let s = m.status();
            if s.line != line {
                break;
            }
            for (a, e) in end.iter().enumerate() {
                let expected = e - s.axes[a];
                assert!(
                    (s.distance_to_go[a] - expected).abs() < 1e-9,
                    "line {line} axis {a}: {} vs {expected}",
                    s.distance_to_go[a]
                );
            }
        }
    }
    assert!(m.until(10.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert_eq!(&m.status().distance_to_go[..3], &[0.0, 0.0, 0.0]);
}

#[test]
fn the_mode_switches_when_idle_only() {
    use rtcnc_kernel::Mode;
    let text = "G21 G90 G61.1\nG1 X50 F3000\nM2\n";
    let cfg = config("sim-mill.toml");
    let mut m = Machine::started(&cfg, text, "mode.ngc");
    assert!(m.until(5.0, |s| s.state == MachineState::Running));
    assert_eq!(m.status().mode, Mode::Auto);
    m.command(Command::SetMode(Mode::Manual));
    m.cycles(10);
    assert_eq!(
        m.status().mode,
        Mode::Auto,
        "refused while the program runs"
    );
    assert_eq!(m.status().state, MachineState::Running);
    assert!(m.until(10.0, |s| s.program_ended && s.state == MachineState::Idle));
    for mode in [Mode::Mdi, Mode::Manual, Mode::Auto] {
        m.command(Command::SetMode(mode));
        m.cycles(5);
        assert_eq!(m.status().mode, mode);
    }
    // From manual a jog works, and the axis stays where the program left it until then.
    m.command(Command::SetMode(Mode::Manual));
    m.cycles(5);
    assert_eq!(m.status().axes[0], 50.0);
    m.command(Command::JogIncrement {
        axis: 0,
        distance: -5.0,
    });
    m.cycles(5);
    assert!(m.until(5.0, |s| s.state == MachineState::Idle));
    assert_eq!(m.status().axes[0], 45.0);
}
