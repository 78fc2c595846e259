//! A feed hold in a canned cycle's rapid to its R plane: found by the kernel fuzz target
//! (fuzz/defects/kernel/z-moves-at-1.35-mm-s-in-a-feed-hold). Held while the rapid still
//! accelerated, the hold's gentler stop model put its stopping point past the R plane,
//! 2.2 mm on; the path itself braked harder, for the slow drilling feed below R, and
//! came down to that feed well before the point. The planner then fed on to the point:
//! at a 9 % feed override, Z drilled on at 1.35 mm/s for a second with the machine in
//! `Held`.

use crate::common::*;
use rtcnc_kernel::{Command, MachineState, Urgent};

const PERIOD: f64 = 0.001;
/// The fuzz target's third program.
const PROGRAM: &str = "G21 G90 G17\nG0 X10 Y10 Z2\nS3000 M3\nG81 R1 Z-3 F900\nX14\nY14\n\
                       G83 R1 Z-6 Q1.5\nX10\nG80\nG0 Z5\nM5\nM2\n";
/// configs/sim-mill.toml's Z, the weakest axis: the hold brakes with half its acceleration
/// and jerk (docs/motion.md).
const Z_VELOCITY: f64 = 50.0;
const Z_ACCELERATION: f64 = 800.0;
const Z_JERK: f64 = 40_000.0;

/// The longest a hold may take on this path, from its worst state: Z at full acceleration
/// and top speed. The acceleration comes down to 0 at the hold's jerk (the speed still
/// grows meanwhile), the hold's deceleration brakes that speed, and its jerk ramps the
/// deceleration in and out; plus 20 periods for the set-points computed ahead and the
/// landing.
fn hold_bound() -> f64 {
    let (a, j) = (0.5 * Z_ACCELERATION, 0.5 * Z_JERK);
    let release = Z_ACCELERATION / j;
    let speed = Z_VELOCITY + Z_ACCELERATION * Z_ACCELERATION / (2.0 * j);
    release + speed / a + a / j + 20.0 * PERIOD
}

#[test]
fn a_hold_in_the_rapid_to_the_r_plane_stops_at_any_feed_override() {
    // Held at each of the first 40 periods from the rapid's start (it lasts about 30), at
    // feed overrides from 9 % (the fuzz input) to 100 %. Before the fix, 39 of these 160
    // runs moved longer than the bound, up to 1.0 s, most of them drilling below R.
    let cfg = config("sim-mill.toml");
    let bound = hold_bound();
    let mut failures = Vec::new();
    for feed_override in [0.09, 0.25, 0.5, 1.0] {
        for periods_in in 0..40 {
            let mut m = Machine::new(&cfg, Some(program(PROGRAM, "hold-in-a-canned-cycle.ngc")));
            m.power_on();
            assert!(m.sim.handle().urgent(Urgent::FeedOverride(feed_override)));
            m.command(Command::Start { from_line: 0 });
            assert!(
                m.until(10.0, |s| s.line == 4 && s.axes[2] < 2.0 - 1e-5),
                "the rapid to R starts"
            );
            m.cycles(periods_in);
            assert!(m.sim.handle().urgent(Urgent::FeedHold));
            let held_from = m.samples.len();
            m.cycles(1000);
            let s = &m.samples[held_from..];
            let last_move = (1..s.len())
                .rev()
                .find(|&i| s[i].axes[2] != s[i - 1].axes[2])
                .unwrap_or(0);
            let moved_for = last_move as f64 * PERIOD;
            let state = m.status().state;
            if moved_for > bound || state != MachineState::Held {
                failures.push(format!(
                    "feed override {feed_override}, held {periods_in} periods into the rapid: \
                     {state:?}, Z moved for {moved_for:.3} s (bound {bound:.3} s), \
                     stands at {:.4}",
                    s[s.len() - 1].axes[2]
                ));
            }
            assert!(m.faults.is_empty(), "{:?}", m.faults);
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
