//! A resume a few periods after a feed hold, as the path brakes into the exact stop at the
//! end of a tight arc: found by the kernel fuzz target
//! (fuzz/defects/kernel/acceleration-after-a-resume-on-a-tight-arc). The hold's stop
//! brakes with half the weakest axis's deceleration (Z: 800 mm/s²); at the end of this
//! arc the path's own stop model allows less, the centripetal load taking most of X's and
//! Y's 1000 mm/s². Continued by the path's model from the hold's braking, the set-points
//! reached the arc's end at 1.24 mm/s in Y and stopped within one period: 1045.7 mm/s².
//! The resume now waits until the path's model can stop from where the hold has brought
//! the machine.

use crate::common::*;
use rtcnc_kernel::{Command, MachineConfig, MachineState, Urgent};

const PERIOD: f64 = 0.001;
/// The fuzz target's fourth program: a circle and a half of 2.54 mm radius at F200 in/min.
const PROGRAM: &str = "G20 G91\nG1 X0.2 Y0.1 F200\nG2 X0.2 Y0 I0.1 J0 P2\nG90 G0 X0 Y0\nM2\n";
/// configs/sim-mill.toml's X and Y acceleration limit (mm/s²).
const MAX_ACCELERATION: f64 = 1000.0;

/// The largest acceleration of X or Y over the recorded set-points (second differences).
fn largest_acceleration(m: &Machine) -> f64 {
    let s = &m.samples;
    (2..s.len())
        .flat_map(|i| {
            (0..2).map(move |j| {
                (s[i].axes[j] - 2.0 * s[i - 1].axes[j] + s[i - 2].axes[j]).abs() / (PERIOD * PERIOD)
            })
        })
        .fold(0.0, f64::max)
}

/// The mill started on the program at period 84, held `run` periods later, and `then`
/// sent `gap` periods after the hold.
fn held_then(cfg: &MachineConfig, run: u64, gap: u64, then: Urgent) -> Machine {
    let mut m = Machine::new(cfg, Some(program(PROGRAM, "near-an-arc-end.ngc")));
    m.cycles(2);
    m.command(Command::Reset);
    m.cycles(82);
    m.command(Command::Start { from_line: 0 });
    m.cycles(run);
    assert!(m.sim.handle().urgent(Urgent::FeedHold));
    m.cycles(gap);
    assert!(m.sim.handle().urgent(then));
    m
}

#[test]
fn a_resume_while_a_hold_brakes_into_a_tight_arcs_end_keeps_the_acceleration_limit() {
    // Started at period 84, held 700-706 periods later (the fuzz input: 704), resumed 3-7
    // periods after the hold (the input: 5). Before the fix: 4 of these 35 runs over the
    // limit, up to 1180.6 mm/s².
    let cfg = config("sim-mill.toml");
    let mut over = Vec::new();
    for run in 700..=706 {
        for gap in 3..=7 {
            let mut m = held_then(&cfg, run, gap, Urgent::Resume);
            assert!(
                m.until(5.0, |s| s.program_ended),
                "the program ends after a hold at {run} and a resume {gap} periods later"
            );
            assert!(m.faults.is_empty(), "{:?}", m.faults);
            let a = largest_acceleration(&m);
            if a > MAX_ACCELERATION * (1.0 + 1e-6) {
                over.push(format!(
                    "hold at {run}, resume {gap} periods later: {a:.1} mm/s²"
                ));
            }
        }
    }
    assert!(over.is_empty(), "{}", over.join("\n"));
}

/// configs/sim-mill.toml's X and Y jerk limit (mm/s³). An abort's stop, as a hold's, is
/// a normal stop: it keeps the normal limits.
const MAX_JERK: f64 = 50_000.0;

/// The largest jerk of X or Y over the recorded set-points (third differences).
fn largest_jerk(m: &Machine) -> f64 {
    let s = &m.samples;
    (3..s.len())
        .flat_map(|i| {
            (0..2).map(move |j| {
                (s[i].axes[j] - 3.0 * s[i - 1].axes[j] + 3.0 * s[i - 2].axes[j] - s[i - 3].axes[j])
                    .abs()
                    / (PERIOD * PERIOD * PERIOD)
            })
        })
        .fold(0.0, f64::max)
}

#[test]
fn an_abort_while_a_hold_brakes_into_a_tight_arcs_end_keeps_the_jerk_limit() {
    // Found in the kernel fuzz target's corpus once the harness checked the jerk
    // (fuzz/defects/kernel/abort-during-a-holds-stop-at-an-arc-end). The abort's stop was
    // recomputed from the hold's braking state and fell past the arc's end; that end then
    // became the goal under the path's own model, which had no stop left from there: the
    // set-points reached the end at 1 mm/s. Before the fix 47 of these 77 runs went over
    // the jerk limit, up to 1 095 666 mm/s³ (22 × 50 000).
    let cfg = config("sim-mill.toml");
    let mut over = Vec::new();
    for run in 700..=706 {
        for gap in 1..=11 {
            let mut m = held_then(&cfg, run, gap, Urgent::Abort);
            assert!(
                m.until(1.0, |s| s.state == MachineState::Idle),
                "the abort ends"
            );
            assert!(m.faults.is_empty(), "{:?}", m.faults);
            let (a, j) = (largest_acceleration(&m), largest_jerk(&m));
            if a > MAX_ACCELERATION * (1.0 + 1e-6) || j > MAX_JERK * (1.0 + 1e-6) {
                over.push(format!(
                    "hold at {run}, abort {gap} periods later: {a:.1} mm/s², {j:.0} mm/s³"
                ));
            }
        }
    }
    assert!(over.is_empty(), "{}", over.join("\n"));
}
