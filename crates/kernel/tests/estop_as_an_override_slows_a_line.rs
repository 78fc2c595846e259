//! An e-stop (or any fault) while an isolated straight line slows down to a lower feed
//! override's speed (found by the kernel fuzz target: fuzz/defects/kernel/
//! drive-fault-as-an-override-slows-a-line). The planner took the line's S-curve, which
//! was braking, as the stop: but it braked to the new speed and then cruised on, so the
//! machine ran on to the line's end at the overridden feed, the quick stop never stood and
//! the other drives stayed enabled. The reference is docs/safety.md's e-stop bound: from
//! 100 mm/s the mill stands within 4.3 mm and 90 ms; here from 50 mm/s or less.

use crate::common::*;

use rtcnc_kernel::{MachineState, Urgent};

const X: usize = 0;

/// The mill cruising along a 200 mm line at 50 mm/s when its feed override drops to 50 %,
/// `periods_after_override` periods later; returns the machine and X there.
fn slowing_line(cfg: &rtcnc_kernel::MachineConfig, periods_after_override: u64) -> (Machine, f64) {
    let mut m = Machine::started(cfg, "G21 G90\nG1 X200 F3000\nM2\n", "line.ngc");
    assert!(m.until(5.0, |s| s.axes[X] > 20.0));
    assert!(m.sim.handle().urgent(Urgent::FeedOverride(0.5)));
    m.cycles(periods_after_override);
    let x = m.status().axes[X];
    (m, x)
}

#[test]
fn an_estop_as_the_override_slows_a_line_stops_at_once() {
    let cfg = config("sim-mill.toml");
    for periods_after_override in [1u64, 5, 20, 60] {
        let (mut m, at_estop) = slowing_line(&cfg, periods_after_override);
        assert!(m.sim.handle().urgent(Urgent::EStop));
        m.cycles(300);
        let s = m.status();
        assert_eq!(s.state, MachineState::EStop);
        let travel = s.axes[X] - at_estop;
        assert!(
            travel < 4.3,
            "{periods_after_override} periods after the override: {travel} mm after the e-stop"
        );
        let load = m.handle_machine(|machine| machine.true_state(X).unwrap());
        assert!(load.1.abs() < 1e-6, "X still moves at {} mm/s", load.1);
        assert!(load.0 < 100.0, "X ran on to {}", load.0);
    }
}

/// The same at a 0 % feed override given as the line slows to a 50 % one: the path stops
/// (the gentle stop of a hold, 50 % of the weakest axis's deceleration: from 50 mm/s about
/// 3 mm) instead of running on to the line's end at 25 mm/s.
#[test]
fn a_zero_override_as_the_override_slows_a_line_stops_the_line() {
    let cfg = config("sim-mill.toml");
    for periods_after_override in [1u64, 5, 20, 60] {
        let (mut m, at_zero) = slowing_line(&cfg, periods_after_override);
        assert!(m.sim.handle().urgent(Urgent::FeedOverride(0.0)));
        m.cycles(1000);
        let s = m.status();
        let travel = s.axes[X] - at_zero;
        assert!(
            travel < 10.0,
            "{periods_after_override} periods after the override: {travel} mm after 0 %"
        );
        let n = m.samples.len();
        assert_eq!(
            m.samples[n - 1].axes[X],
            m.samples[n - 50].axes[X],
            "X stands"
        );
    }
}
