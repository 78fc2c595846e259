//! Programs that showed planner defects when run as a user would (the cases of the
//! project's defect list, copied into `data/cases/`): each runs to its end within every
//! axis's limits.

mod common;
use common::*;
use rtcnc_kernel::{Command, MachineState, Sample};

/// Largest |v|, |a|, |j| of the axis set-points over their limits (finite differences at
/// the servo period, as the planner checks them).
fn worst_ratio(samples: &[Sample], period: f64, limits: &[(f64, f64, f64)]) -> f64 {
    let mut worst: f64 = 0.0;
    for w in samples.windows(4) {
        for (i, &(v, a, j)) in limits.iter().enumerate() {
            let x: Vec<f64> = w.iter().map(|s| s.axes[i]).collect();
            let d1 = (x[3] - x[2]) / period;
            let d2 = (x[3] - 2.0 * x[2] + x[1]) / (period * period);
            let d3 = (x[3] - 3.0 * x[2] + 3.0 * x[1] - x[0]) / (period * period * period);
            worst = worst.max(d1.abs() / v).max(d2.abs() / a).max(d3.abs() / j);
        }
    }
    worst
}

/// Runs a case on a machine of `configs/` until the program ends (at most `limit_s` of
/// machine time); the samples.
fn run_case(config_name: &str, case: &str, limit_s: f64) -> Vec<Sample> {
    let cfg = config(config_name);
    let text = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/cases")
            .join(case),
    )
    .unwrap();
    let mut m = Machine::new(&cfg, Some(program(&text, case)));
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    let ended = m.until(limit_s, |s| {
        s.program_ended && s.state == MachineState::Idle
    });
    assert!(m.faults.is_empty(), "{case}: {:?}", m.faults);
    assert!(ended, "{case}: did not end within {limit_s} s");
    m.samples
}

/// Twelve 1800 mm rapids (10.8 km of path), then a polyline: the machine came to rest at
/// the end of the last rapid and never moved again (the end of a stop piece was missed by
/// the rounding of path positions counted from the program start), and each rapid beyond
/// about 400 mm from the origin exceeded the jerk limit 8 × while braking.
#[test]
fn long_path_stall_runs_to_its_end_within_the_limits() {
    let samples = run_case("bench-xyz.toml", "long-path-stall.ngc", 400.0);
    let worst = worst_ratio(&samples, 1e-3, &[(100.0, 1000.0, 50_000.0); 3]);
    assert!(worst <= 1.0 + 1e-9, "{worst}");
    let last = samples.last().unwrap().axes;
    // The program's last point.
    assert!(
        (last[0] + 8.6521).abs() < 1e-9 && (last[1] + 5.0141).abs() < 1e-9,
        "{last:?}"
    );
}
