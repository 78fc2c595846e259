//! Overrides changed while a feed hold stops a rapid: found by the kernel fuzz target
//! (fuzz/defects/kernel/rapid-override-0-during-a-hold), where a rapid override of 0 %
//! during the hold's stop decelerated X at 5 246 mm/s² against its 1 000. Every set-point
//! must keep the axes' limits whatever the overrides do (a hold is no quick stop).

use crate::common::*;
use rtcnc_kernel::{Command, FixedText, Urgent};

const PERIOD: f64 = 0.001;
/// configs/sim-mill.toml's X and Y.
const V_MAX: f64 = 100.0;
const A_MAX: f64 = 1000.0;
const J_MAX: f64 = 50_000.0;

/// The fuzz target's fourth program: from line 4, the machine first goes at rapid to where
/// that line starts, then the line's rapid.
const PROGRAM: &str = "G20 G91\nG1 X0.2 Y0.1 F200\nG2 X0.2 Y0 I0.1 J0 P2\nG90 G0 X0 Y0\nM2\n";

/// Largest |velocity|, |acceleration| and |jerk| of X and Y over the set-points.
fn peaks(m: &Machine) -> (f64, f64, f64) {
    let (mut v, mut a, mut j) = (0.0f64, 0.0f64, 0.0f64);
    for w in m.samples.windows(4) {
        for ax in 0..2 {
            let d = |i: usize| (w[i].setpoint[ax] - w[i - 1].setpoint[ax]) / PERIOD;
            let (v1, v2, v3) = (d(1), d(2), d(3));
            let (a2, a3) = ((v2 - v1) / PERIOD, (v3 - v2) / PERIOD);
            v = v.max(v3.abs());
            a = a.max(a3.abs());
            j = j.max(((a3 - a2) / PERIOD).abs());
        }
    }
    (v, a, j)
}

#[test]
fn a_rapid_override_changed_during_a_holds_stop_keeps_the_limits() {
    let cfg = config("sim-mill.toml");
    let mut failures = Vec::new();
    for override_after in (45..=70).step_by(3) {
        for rapid in [0.0, 0.25, 0.5, 1.0] {
            let mut m = Machine::new(&cfg, Some(program(PROGRAM, "hold-override.ngc")));
            m.power_on();
            m.command(Command::Start { from_line: 4 });
            m.cycles(88);
            assert!(m.sim.handle().urgent(Urgent::FeedHold));
            m.cycles(override_after);
            assert!(m.sim.handle().urgent(Urgent::RapidOverride(rapid)));
            m.cycles(400);
            let (v, a, j) = peaks(&m);
            if v > V_MAX * 1.001 || a > A_MAX * 1.001 || j > J_MAX * 1.001 {
                failures.push(format!(
                    "override {rapid} {override_after} periods into the hold: \
                     v {v:.1} a {a:.0} j {j:.0}"
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Found by the kernel fuzz target once the case above was fixed: MDI `G0 X10 Y10`, 115
/// periods, a rapid override of 0 % and a feed hold in the same period (X at 6 985 mm/s²).
/// An override of 0 % while the rapid's S-curve brakes for its end, with or without a hold.
#[test]
fn a_zero_rapid_override_while_a_rapid_brakes_for_its_end_keeps_the_limits() {
    let cfg = config("sim-mill.toml");
    let mut failures = Vec::new();
    for after in (20..=200).step_by(5) {
        for hold in [false, true] {
            let mut m = Machine::new(&cfg, None);
            m.power_on();
            m.command(Command::Mdi(FixedText::new("G0 X10 Y10").unwrap()));
            m.cycles(after);
            assert!(m.sim.handle().urgent(Urgent::RapidOverride(0.0)));
            if hold {
                assert!(m.sim.handle().urgent(Urgent::FeedHold));
            }
            m.cycles(400);
            let (v, a, j) = peaks(&m);
            if v > V_MAX * 1.001 || a > A_MAX * 1.001 || j > J_MAX * 1.001 {
                failures.push(format!(
                    "0 % {after} periods after the line, hold {hold}: v {v:.1} a {a:.0} j {j:.0}"
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
