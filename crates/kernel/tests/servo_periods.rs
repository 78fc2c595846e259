//! The same program at any servo period from 100 µs to 4 ms, changing only the task
//! periods of the machine file: the same path, the same machine-logic behaviour (the PLC's
//! timers count time, not scans) and a cycle time within a few periods, within the limits.
//! Swept on the shipped example (the bracket: blends, tangent arcs, a helix, two tool
//! changes, spindle and coolant hand-shakes), on the 12-drive gantry and on the programs of
//! the defect list.

use crate::common::*;
use rtcnc_kernel::{Command, Kernel, KernelOptions, MachineConfig, Simulation};
use std::time::Duration;

const PERIODS_US: [u64; 6] = [100, 250, 500, 1000, 2000, 4000];

/// What a run leaves: the axis path (consecutive equal points once), the program's time
/// from the start command to its end, the largest v, a, j of any axis over its limit.
struct Run {
    path: Vec<[f64; 3]>,
    cycle_time: f64,
    worst_ratio: f64,
}

fn run(config: &MachineConfig, program_path: std::path::PathBuf, limit_s: f64) -> Run {
    let limits: Vec<(f64, f64, f64)> = ["x", "y", "z"]
        .iter()
        .map(|a| {
            let axis = &config.axes[*a];
            (axis.max_velocity, axis.max_acceleration, axis.max_jerk)
        })
        .collect();
    let period = config.servo_period().as_secs_f64();
    let kernel = Kernel::build(
        config,
        KernelOptions {
            program: Some(program_path),
            record_capacity: 1 << 14,
            ..KernelOptions::default()
        },
    )
    .expect("kernel builds");
    let mut sim = Simulation::new(kernel);
    sim.run_cycles(2, &mut |_| {}).unwrap();
    assert!(sim.handle().command(Command::Reset));
    let ready = sim
        .run_until(Duration::from_millis(100), &mut |_| {}, |s| s.ready)
        .unwrap();
    assert!(ready, "drives enable");
    let start_ns = sim.handle().status().time_ns;
    assert!(sim.handle().command(Command::Start { from_line: 0 }));
    let mut path: Vec<[f64; 3]> = Vec::new();
    let mut window = [[0.0f64; 3]; 4];
    let mut seen = 0usize;
    let mut worst = 0.0f64;
    let mut end_ns = 0;
    let ended = sim
        .run_until(
            Duration::from_secs_f64(limit_s),
            &mut |s| {
                let p = [s.axes[0], s.axes[1], s.axes[2]];
                if path.last() != Some(&p) {
                    path.push(p);
                }
                window.rotate_left(1);
                window[3] = p;
                seen += 1;
                if seen >= 4 {
                    for (i, &(v, a, j)) in limits.iter().enumerate() {
                        let x = [window[0][i], window[1][i], window[2][i], window[3][i]];
                        let d1 = (x[3] - x[2]) / period;
                        let d2 = (x[3] - 2.0 * x[2] + x[1]) / period.powi(2);
                        let d3 = (x[3] - 3.0 * x[2] + 3.0 * x[1] - x[0]) / period.powi(3);
                        worst = worst.max(d1.abs() / v).max(d2.abs() / a).max(d3.abs() / j);
                    }
                }
                end_ns = s.time_ns;
            },
            |s| s.program_ended,
        )
        .unwrap();
    let faults = sim.handle().take_faults();
    assert!(faults.is_empty(), "{faults:?}");
    assert!(ended, "did not end within {limit_s} s");
    Run {
        path,
        cycle_time: (end_ns - start_ns) as f64 * 1e-9,
        worst_ratio: worst,
    }
}

fn distance_to_segment(p: &[f64; 3], a: &[f64; 3], b: &[f64; 3]) -> f64 {
    let ab = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let ap = [p[0] - a[0], p[1] - a[1], p[2] - a[2]];
    let len2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
    let t = if len2 > 0.0 {
        ((ap[0] * ab[0] + ap[1] * ab[1] + ap[2] * ab[2]) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let d = [ap[0] - t * ab[0], ap[1] - t * ab[1], ap[2] - t * ab[2]];
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}

/// The largest distance from a point of `run` to the polyline of `reference`, walking both
/// in order (each point matched among the segments at or after the last match: a run at
/// 4 ms moves about 40 reference points of 100 µs per set-point), and whether the walk
/// reached the reference's end.
fn path_distance(reference: &[[f64; 3]], run: &[[f64; 3]]) -> (f64, bool) {
    const WINDOW: usize = 256;
    let segments = reference.len() - 1;
    let mut at = 0;
    let mut worst = 0.0f64;
    for p in run {
        // Where the path turns back on itself (a drill's feed down and rapid up) both ways
        // are at about the same distance: the first within rounding of the nearest is the
        // match, so that the walk does not skip the turn.
        let window = at..(at + WINDOW).min(segments);
        let distance = |k: usize| distance_to_segment(p, &reference[k], &reference[k + 1]);
        let nearest = window.clone().map(distance).fold(f64::INFINITY, f64::min);
        let k = window
            .clone()
            .find(|&k| distance(k) <= nearest + 1e-9)
            .unwrap_or(at);
        let best = (k, distance(k));
        at = best.0;
        worst = worst.max(best.1);
    }
    (worst, at + 1 >= segments)
}

/// Sweeps `program` (a file of the repository) on `machine` over the periods; `handshakes`
/// is how many hand-shakes with the machine logic the program makes (each may wait up to a
/// period for the logic's scan).
fn sweep(machine: &str, program: &str, handshakes: u32, limit_s: f64) {
    let path = repo().join(program);
    let runs: Vec<(u64, Run)> = PERIODS_US
        .iter()
        .map(|&us| {
            (
                us,
                run(&config_at_period(machine, us), path.clone(), limit_s),
            )
        })
        .collect();
    let reference = &runs[0].1;
    for (us, r) in &runs[1..] {
        assert!(
            r.worst_ratio <= 1.0 + 1e-9,
            "{program} at {us} µs: a limit exceeded {}×",
            r.worst_ratio
        );
        let (distance, reached) = path_distance(&reference.path, &r.path);
        assert!(
            distance <= 1e-6 && reached,
            "{program} at {us} µs: {distance} mm off the 100 µs path (end reached: {reached})"
        );
        // Within two periods per hand-shake and the start's and end's period each.
        let allowed = (2 * handshakes + 2) as f64 * *us as f64 * 1e-6;
        assert!(
            (r.cycle_time - reference.cycle_time).abs() <= allowed,
            "{program} at {us} µs: {} s, at 100 µs {} s",
            r.cycle_time,
            reference.cycle_time
        );
    }
}

/// The bracket: hand-shakes, counted in the program: two tool changes, two spindle starts
/// and two stops, flood, mist, two coolant stops and the program's end.
#[test]
fn the_bracket_runs_alike_at_every_servo_period() {
    sweep("sim-mill.toml", "examples/bracket.ngc", 11, 60.0);
}

/// The defect list's cases that take seconds: the arc with a half-micron radius difference
/// and the M30 end. (The long-path case and the near-cusp splines take 400 s and 3 184 s of
/// machine time, too long at 100 µs in a test; `bench/servo-periods.sh` sweeps them.)
#[test]
fn the_cases_run_alike_at_every_servo_period() {
    for (case, handshakes) in [("arc-radius-0.5um.ngc", 1), ("m30-end.ngc", 1)] {
        sweep(
            "bench-xyz.toml",
            &format!("crates/kernel/tests/data/cases/{case}"),
            handshakes,
            60.0,
        );
    }
}

/// The 12-drive gantry (CSP drives one period behind, its following-error limit 2 ms of
/// travel at 100 mm/s): its machine file names that delay, so the following error does not
/// count a period of 2 or 4 ms of travel as lag. Its six moves each end in an exact stop
/// (G61.1), which rounds the move up to a whole period: with the program's end that is
/// counted as four hand-shakes (two periods each).
#[test]
fn the_gantry_runs_alike_at_every_servo_period() {
    sweep("sim-gantry-12.toml", "examples/gantry-12.ngc", 4, 60.0);
}
