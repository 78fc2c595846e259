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
