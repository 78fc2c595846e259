//! An override raised while the path brakes for the end of an arc: found by the kernel
//! fuzz target (fuzz/defects/kernel/arc-end-reached-at-8-mm-s). The program ran at 42 %
//! feed override; 34 ms before the end of a half circle of 1.35 mm radius (a stop follows:
//! a rapid comes next), braking at 23 mm/s, the override went to 51 %. The path reached
//! the arc's end at 8 mm/s and the set-point stood still there: 8 076 mm/s² on Y against
//! the mill's 1 000. The override is raised here at each of the 30 periods around that
//! moment.

use crate::common::*;
use rtcnc_kernel::{Command, Urgent};

/// The fuzz target's second program (fuzz/src/kernel.rs), as the operator ran it.
const PROGRAM: &str = "G21 G90 G64
G0 X2 Y2
G1 Z-1 F600
G1 X3 Y2.2 F4000
X4 Y2.1
X5 Y2.6
X6 Y2.4
X7 Y3
G3 X9 Y5 R2
G1 X9.2 Y5.1
X9.3 Y5.4
G2 X12 Y5.4 I1.35 J0
G0 Z2
M2
";
const PERIOD: f64 = 0.001;
/// The mill's axis accelerations (configs/sim-mill.toml).
const ACCELERATION: [f64; 3] = [1000.0, 1000.0, 800.0];

/// The largest set-point acceleration of each axis over its limit, with the override
/// raised from 42.4 % to 51 % `raised_at` periods after the start.
fn worst_acceleration_ratio(raised_at: u64) -> f64 {
    let cfg = config("sim-mill.toml");
    let mut m = Machine::new(&cfg, Some(program(PROGRAM, "arc-end.ngc")));
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    m.cycles(491);
    assert!(m.sim.handle().urgent(Urgent::FeedOverride(0.424)));
    m.cycles(raised_at - 491);
    assert!(m.sim.handle().urgent(Urgent::FeedOverride(0.51)));
    assert!(m.until(10.0, |s| s.program_ended));
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    let s = &m.samples;
    let mut worst = 0.0f64;
    for i in 2..s.len() {
        for (axis, limit) in ACCELERATION.iter().enumerate() {
            let v1 = (s[i - 1].setpoint[axis] - s[i - 2].setpoint[axis]) / PERIOD;
            let v2 = (s[i].setpoint[axis] - s[i - 1].setpoint[axis]) / PERIOD;
            worst = worst.max(((v2 - v1) / PERIOD).abs() / limit);
        }
    }
    worst
}

#[test]
fn an_override_raised_while_braking_for_an_arc_end_keeps_the_acceleration_limits() {
    let failures: Vec<_> = (961..991)
        .map(|at| (at, worst_acceleration_ratio(at)))
        .filter(|(_, ratio)| *ratio > 1.0 + 1e-6)
        .collect();
    assert!(
        failures.is_empty(),
        "(period, acceleration / limit): {failures:?}"
    );
}
