//! The shipped example programs run to their end on their machines, within every axis
//! limit, without faults.

mod common;
use common::*;
use rtcnc_kernel::report::RunStats;
use rtcnc_kernel::{Command, MachineState};

fn run_example(machine: &str, program: &str) -> (Machine, RunStats) {
    let cfg = config(machine);
    let mut m = Machine::new(&cfg, Some(repo().join("examples").join(program)));
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    let ended = m.until(120.0, |s| s.program_ended && s.state == MachineState::Idle);
    assert!(
        ended,
        "{program}: {:?} {:?}",
        m.faults,
        m.sim.handle().error_text()
    );
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    let mut stats = RunStats::new();
    for s in &m.samples {
        stats.add(s, cfg.servo_period().as_secs_f64());
    }
    for p in cfg.axis_plan() {
        let a = cfg.axis(p.axis).unwrap();
        let i = p.axis as usize;
        let tol = 1.0 + 1e-6;
        assert!(
            stats.max_velocity[i] <= a.max_velocity * tol,
            "{:?} v",
            p.axis
        );
        assert!(
            stats.max_acceleration[i] <= a.max_acceleration * tol,
            "{:?} a",
            p.axis
        );
        assert!(
            stats.max_jerk[i] <= a.max_jerk * tol,
            "{:?} j {}",
            p.axis,
            stats.max_jerk[i]
        );
    }
    (m, stats)
}

#[test]
fn the_bracket_runs_on_the_mill_within_the_limits() {
    let (m, stats) = run_example("sim-mill.toml", "bracket.ngc");
    assert_eq!(&m.status().axes[..3], &[0.0, 0.0, 5.0]);
    assert_eq!(m.status().tool, 2);
    // The rapids reach the X limit; the servo loops follow within 20 µm.
    assert!(stats.max_velocity[0] > 99.9);
    assert!(stats.max_following_error[..3].iter().all(|&e| e < 0.02));
}

#[test]
fn the_shaft_runs_on_the_lathe_in_diameter_mode() {
    let (m, _) = run_example("sim-lathe.toml", "lathe-shaft.ngc");
    // Programmed X42 (a diameter) is 21 mm of cross-slide travel.
    let max_x = m.samples.iter().map(|s| s.axes[0]).fold(f64::MIN, f64::max);
    assert!((max_x - 21.0).abs() < 1e-9, "max X {max_x}");
    let min_z = m.samples.iter().map(|s| s.axes[2]).fold(f64::MAX, f64::min);
    assert!((min_z - -40.0).abs() < 1e-9, "min Z {min_z}");
}

#[test]
fn tool_length_and_cutter_radius_compensation_shape_the_path() {
    let dir = std::env::temp_dir().join(format!("rtcnc-tools-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let table = dir.join("tools.tbl");
    std::fs::write(&table, "T1 P1 Z+10.0 D6.0 ;6 mm cutter, 10 mm long\n").unwrap();
    let mut cfg = config("sim-mill.toml");
    cfg.files.tool_table = Some(table);
    // G43: Z-20 in the program is Z-10 on the machine with the 10 mm tool.
    // G41 on a 20 mm square traversed counter-clockwise: the cutter (radius 3) keeps to
    // the left, inside the square, so its centre never passes X17 or Y17.
    let text = "G21 G90 G61.1\nT1 M6\nG43 H1\nG0 X-4 Y-4 Z-20\nG41\nG1 X0 Y0 F600\nG1 X20\nG1 Y20\nG1 X0\nG1 Y0\nG40\nG1 X-4 Y-4\nM2\n";
    let mut m = Machine::new(&cfg, Some(program(text, "comp.ngc")));
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    let ended = m.until(30.0, |s| s.program_ended && s.state == MachineState::Idle);
    assert!(
        ended,
        "{:?} {:?} {:?}",
        m.faults,
        m.sim.handle().error_text(),
        m.status()
    );
    assert!(
        m.faults.is_empty(),
        "{:?} {:?}",
        m.faults,
        m.sim.handle().error_text()
    );
    let max = |i: usize| m.samples.iter().map(|s| s.axes[i]).fold(f64::MIN, f64::max);
    let min_z = m.samples.iter().map(|s| s.axes[2]).fold(f64::MAX, f64::min);
    assert!((min_z - -10.0).abs() < 1e-12, "min Z {min_z}");
    assert!((max(0) - 17.0).abs() < 1e-9, "max X {}", max(0));
    assert!((max(1) - 17.0).abs() < 1e-9, "max Y {}", max(1));
}

#[test]
fn inch_programs_move_in_millimetres_on_the_machine() {
    let cfg = config("sim-mill.toml");
    let text = "G20 G90 G61.1\nG1 X1 Y0.5 F20\nM2\n";
    let mut m = Machine::new(&cfg, Some(program(text, "inch.ngc")));
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    assert!(m.until(10.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert_eq!(&m.status().axes[..2], &[25.4, 12.7]);
    // F20 in/min along the diagonal: 20 × 25.4 / 60 mm/s.
    let top = m.samples.iter().map(|s| s.path_speed).fold(0.0, f64::max);
    assert!(
        (top - 20.0 * 25.4 / 60.0).abs() < 1e-3 * top,
        "path speed {top}"
    );
}

#[test]
fn the_thread_example_faces_at_constant_surface_speed_and_threads_on_the_lathe() {
    let (m, _) = run_example("sim-lathe.toml", "lathe-thread.ngc");
    // The facing cut reached the centre; the G76 passes went down to Z-22.
    let min = |i: usize| m.samples.iter().map(|s| s.axes[i]).fold(f64::MAX, f64::min);
    assert_eq!(min(0), 0.0);
    assert_eq!(min(2), -30.0);
    let thread_end = m
        .samples
        .iter()
        .filter(|s| s.line == 21)
        .map(|s| s.axes[2])
        .fold(f64::MAX, f64::min);
    assert_eq!(thread_end, -22.0);
}
