//! A feed override changed in the period of a feed hold: found by the kernel fuzz target
//! (fuzz/defects/kernel/hold-at-5-percent-override-on-a-tight-arc). On the arc of the fuzz
//! target's fourth program at about 50 mm/s, a hold and an override of 5.2 % in the same
//! period: the path slowed to 2 mm/s, then went on at the override's 4.4 mm/s, held, for
//! more than half a second. A hold stops the path as its own stop says; an override
//! changed meanwhile applies from the resume on.

use crate::common::*;
use rtcnc_kernel::{Command, Urgent};

const PERIOD: f64 = 0.001;
/// The fuzz target's fourth program: a two-turn circle of 2.54 mm radius at F200 in/min.
const PROGRAM: &str = "G20 G91\nG1 X0.2 Y0.1 F200\nG2 X0.2 Y0 I0.1 J0 P2\nG90 G0 X0 Y0\nM2\n";
/// configs/sim-mill.toml's X and Y: the longest a hold may take from 100 mm/s at half the
/// deceleration and jerk (the fuzz target's bound, 0.59 s) is far above what a stop from
/// 50 mm/s needs (about 0.15 s at 500 mm/s² and 25 000 mm/s³).
const STOPPED_WITHIN_S: f64 = 0.25;

/// Path speed of the set-points from sample `i` on (mm/s, X and Y).
fn speed(m: &Machine, i: usize) -> f64 {
    let (a, b) = (&m.samples[i - 1], &m.samples[i]);
    let dx = b.setpoint[0] - a.setpoint[0];
    let dy = b.setpoint[1] - a.setpoint[1];
    dx.hypot(dy) / PERIOD
}

#[test]
fn a_feed_override_changed_with_a_hold_does_not_keep_the_path_moving() {
    let cfg = config("sim-mill.toml");
    let mut failures = Vec::new();
    for after in (200..=260).step_by(10) {
        for feed in [0.052, 0.3, 0.0, 1.5] {
            let mut m = Machine::new(&cfg, Some(program(PROGRAM, "hold-feed-override.ngc")));
            m.power_on();
            m.command(Command::Start { from_line: 0 });
            m.cycles(after);
            let held_at = m.samples.len();
            assert!(m.sim.handle().urgent(Urgent::FeedHold));
            assert!(m.sim.handle().urgent(Urgent::FeedOverride(feed)));
            m.cycles(600);
            let within = held_at + (STOPPED_WITHIN_S / PERIOD) as usize;
            let moving_after: f64 = (within..m.samples.len())
                .map(|i| speed(&m, i))
                .fold(0.0, f64::max);
            if moving_after > 0.0 {
                failures.push(format!(
                    "override {feed} with a hold {after} periods into the program: \
                     {moving_after:.3} mm/s {STOPPED_WITHIN_S} s after the hold"
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The override given during the hold is the one the path resumes with.
#[test]
fn the_override_changed_during_a_hold_applies_from_the_resume() {
    let cfg = config("sim-mill.toml");
    let mut m = Machine::new(&cfg, Some(program(PROGRAM, "hold-feed-override.ngc")));
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    m.cycles(240);
    assert!(m.sim.handle().urgent(Urgent::FeedHold));
    assert!(m.sim.handle().urgent(Urgent::FeedOverride(0.052)));
    m.cycles(400);
    assert!(m.sim.handle().urgent(Urgent::Resume));
    m.cycles(1000);
    let resumed = m.samples.len() - 1000;
    // F200 in/min is 84.67 mm/s; 5.2 % of it is 4.40 mm/s, well under what the arc allows.
    let top = (resumed + 1..m.samples.len())
        .map(|i| speed(&m, i))
        .fold(0.0, f64::max);
    assert!(top > 0.0, "the path resumed");
    assert!(top <= 84.666_666 * 0.052 * 1.001, "resumed at {top} mm/s");
}
