//! G33.1 rigid tapping through the whole kernel on the simulated lathe (a tap on the
//! spindle's axis), with LinuxCNC 2.9's sequence (its G-code manual, "G33.1 Rigid
//! Tapping"): in synchronised from the spindle's index, the spindle reversed at the bottom
//! and followed through its deceleration, out synchronised, the spindle's first direction
//! again at the start point and followed through that reversal, then back to the start
//! point unsynchronised.

use crate::common::*;
use rtcnc_kernel::{MachineState, Urgent};

/// The start point, bottom and pitch of the taps below (an M6×1 tap, 12 mm deep from Z2).
const Z0: f64 = 2.0;
const BOTTOM: f64 = -10.0;
const PITCH: f64 = 1.0;

/// The simulated lathe's spindle: 600 rpm programmed, turning up and down at 2000 rpm/s
/// with a jerk of 480 000 rpm/s² (`configs/sim-lathe.toml`).
const RPM: f64 = 600.0;
const SPINDLE_ACCELERATION_RPM_S: f64 = 2000.0;
const SPINDLE_JERK_RPM_S2: f64 = 480_000.0;

/// Revolutions a spindle turns while it brakes from `rpm` to rest along an S-curve with
/// acceleration `a` (rpm/s) and jerk `j` (rpm/s²), when rpm ≥ a²/j: the ramp lasts
/// rpm/a + a/j and its speed is symmetric about its middle, so it turns half of
/// rpm × that time: n²/(2α) + n·α/(2ȷ) in rev/s, rev/s², rev/s³.
fn braking_turns(rpm: f64, a: f64, j: f64) -> f64 {
    let (n, alpha, jerk) = (rpm.abs() / 60.0, a / 60.0, j / 60.0);
    n * n / (2.0 * alpha) + n * alpha / (2.0 * jerk)
}

/// Finite differences of the set-points of every sample: each axis's largest velocity,
/// acceleration and jerk, checked against its limits.
fn check_limits(
    cfg: &rtcnc_kernel::MachineConfig,
    samples: &[rtcnc_kernel::Sample],
    axes: &[rtcnc_motion::Axis],
) -> rtcnc_kernel::report::RunStats {
    let mut stats = rtcnc_kernel::report::RunStats::new();
    for s in samples {
        stats.add(s, 0.001);
    }
    for &axis in axes {
        let limits = cfg.axis(axis).unwrap();
        let i = axis as usize;
        assert!(
            stats.max_velocity[i] <= limits.max_velocity * (1.0 + 1e-6),
            "{axis:?} {}",
            stats.max_velocity[i]
        );
        assert!(
            stats.max_acceleration[i] <= limits.max_acceleration * (1.0 + 1e-6),
            "{axis:?} {}",
            stats.max_acceleration[i]
        );
        assert!(
            stats.max_jerk[i] <= limits.max_jerk * (1.0 + 1e-6),
            "{axis:?} {}",
            stats.max_jerk[i]
        );
        for s in samples {
            assert!(
                s.axes[i] <= limits.max_position && s.axes[i] >= limits.min_position,
                "{axis:?} {}",
                s.axes[i]
            );
        }
    }
    stats
}

/// One exchange: Z set-point, spindle angle (degrees, 0..360), measured spindle speed
/// (rpm), program line.
#[derive(Debug, Clone, Copy)]
struct Exchange {
    z: f64,
    angle: f64,
    rpm: f64,
    line: u32,
}

fn record(m: &mut Machine, trace: &mut Vec<Exchange>) {
    m.cycles(1);
    let s = *m.samples.last().unwrap();
    let angle = m.handle_machine(|mach| mach.spindle_angle_deg());
    trace.push(Exchange {
        z: s.axes[2],
        angle,
        rpm: m.status().spindle_rpm,
        line: s.line,
    });
}

/// The spindle angle unwrapped from 0..360 readings a millisecond apart (it turns far less
/// than half a turn per millisecond).
fn unwrapped(trace: &[Exchange]) -> Vec<f64> {
    let mut out = Vec::with_capacity(trace.len());
    let mut angle = trace.first().map_or(0.0, |e| e.angle);
    let mut before = angle;
    for e in trace {
        let mut d = e.angle - before;
        if d > 180.0 {
            d -= 360.0;
        } else if d <= -180.0 {
            d += 360.0;
        }
        angle += d;
        before = e.angle;
        out.push(angle);
    }
    out
}

/// A tap from `z0` to `bottom` (I word `scale`), with `during` acting on the machine at
/// every exchange of the tap. Checks the tap against the hand-worked motion and returns the
/// trace.
fn check_tap(
    z0: f64,
    bottom: f64,
    scale: Option<f64>,
    mut during: impl FnMut(&mut Machine, &Exchange),
) -> Vec<Exchange> {
    let i_word = scale.map_or(String::new(), |i| format!(" I{i}"));
    let text = format!(
        "G18 G21 G90 G7\nG0 X0 Z{z0}\nS{RPM} M3\nG33.1 Z{bottom} K{PITCH}{i_word}\nG0 X20\nM5\nM2\n"
    );
    let cfg = config("sim-lathe.toml");
    let mut m = Machine::started(&cfg, &text, "rigid-tap.ngc");
    let mut trace = Vec::new();
    for _ in 0..60_000 {
        record(&mut m, &mut trace);
        let last = *trace.last().unwrap();
        if last.line == 4 {
            during(&mut m, &last);
        }
        if trace.len() > 10 && m.status().state == MachineState::Idle {
            break;
        }
    }
    assert!(
        m.faults.is_empty(),
        "{:?} {:?}",
        m.faults,
        m.sim.handle().error_text()
    );
    assert!(m.status().program_ended);
    let angles = unwrapped(&trace);
    let tap: Vec<usize> = (0..trace.len()).filter(|&i| trace[i].line == 4).collect();
    assert!(!tap.is_empty());

    // Once locked on (the catching up is done well within 1.5 mm of the start), Z is the
    // start minus pitch × the spindle's revolutions since the index it locked on, both
    // ways: the same whole number of turns n in (z0 - z)/pitch - angle/360 throughout, and
    // the rest within 1 µm of a turn's pitch.
    let synced: Vec<usize> = tap
        .iter()
        .copied()
        .filter(|&i| trace[i].z < z0 - 1.5)
        .collect();
    let turns = |i: usize| (z0 - trace[i].z) / PITCH - angles[i] / 360.0;
    let n = turns(synced[0]).round();
    let mut worst: f64 = 0.0;
    for &i in &synced {
        let off = (turns(i) - n) * PITCH;
        worst = worst.max(off.abs());
        assert!(
            off.abs() < 1e-3,
            "Z {} angle {}: {off} mm off the helix",
            trace[i].z,
            angles[i]
        );
    }
    eprintln!("largest distance from the helix: {worst:e} mm");
    // Both ways: in with the spindle forward at its speed, out with it reversed at
    // `scale` times it.
    let scale = scale.unwrap_or(1.0);
    let going = |down: bool| {
        synced
            .windows(2)
            .filter(|w| (trace[w[1]].z < trace[w[0]].z) == down && trace[w[1]].z != trace[w[0]].z)
            .count()
    };
    let depth = z0 - 1.5 - bottom;
    let seconds = |rpm: f64| depth / (PITCH * rpm / 60.0);
    assert!(
        going(true) as f64 > 1000.0 * seconds(RPM),
        "{}",
        going(true)
    );
    assert!(
        going(false) as f64 > 1000.0 * seconds(RPM * scale),
        "{}",
        going(false)
    );
    let near = |rpm: f64, want: f64| (rpm - want).abs() < 0.01 * want.abs();
    assert!(synced.iter().any(|&i| near(trace[i].rpm, RPM)));
    assert!(synced.iter().any(|&i| near(trace[i].rpm, -RPM * scale)));
    assert!(
        synced
            .iter()
            .all(|&i| trace[i].rpm <= RPM * 1.001 && trace[i].rpm >= -RPM * scale * 1.001)
    );

    // The overrun past the bottom: the spindle, reversed there, turns on while it brakes
    // from 600 rpm at 2000 rpm/s and 480 000 rpm/s²: 1.5 + 0.0208 turns (`braking_turns`),
    // 1.521 mm, plus the few milliseconds (10 µm each) between the command and the drive.
    let overrun =
        |rpm: f64| PITCH * braking_turns(rpm, SPINDLE_ACCELERATION_RPM_S, SPINDLE_JERK_RPM_S2);
    let deepest = tap
        .iter()
        .map(|&i| trace[i].z)
        .fold(f64::INFINITY, f64::min);
    let want = bottom - overrun(RPM);
    eprintln!("deepest Z {deepest}, hand-worked {want}");
    assert!(deepest < want + 1e-3 && deepest > want - 0.05, "{deepest}");
    // The same above the start, where the spindle brakes from `scale` times the speed and
    // turns forward again.
    let highest = tap.iter().map(|&i| trace[i].z).fold(f64::MIN, f64::max);
    let want = z0 + overrun(RPM * scale);
    eprintln!("highest Z {highest}, hand-worked {want}");
    assert!(highest > want - 1e-3 && highest < want + 0.05, "{highest}");

    // It ends at the start, the spindle turning forward again (still speeding up: the
    // tool does not wait for it), and up to its speed during the next block.
    let last = *tap.last().unwrap();
    assert_eq!(trace[last].z, z0);
    assert!(trace[last].rpm > 0.0, "{}", trace[last].rpm);
    // Then the program goes on from there (G0 X20, a diameter).
    assert_eq!(m.status().axes[0], 10.0);
    assert_eq!(m.status().axes[2], z0);

    // Every axis kept its limits (the spindle's braking is 33 mm/s² on Z at this pitch,
    // its jerk 8 000 mm/s³, up to 1.5 times that where it sets in).
    check_limits(
        &cfg,
        &m.samples,
        &[rtcnc_motion::Axis::X, rtcnc_motion::Axis::Z],
    );
    trace
}

#[test]
fn a_rigid_tap_follows_the_spindle_in_and_out_and_ends_where_it_started() {
    let trace = check_tap(Z0, BOTTOM, None, |_, _| {});
    // The spindle back at its speed forwards during the next block.
    assert!(
        trace
            .iter()
            .any(|e| e.line == 5 && (e.rpm - RPM).abs() < 0.01 * RPM)
    );
}

#[test]
fn a_rigid_tap_comes_out_at_i_times_the_speed() {
    // I2: out at 1200 rpm, 20 mm/s; braking from it above the start takes 6.04 turns,
    // 6.04 mm, so the tap starts 7 mm below Z's upper limit (Z5).
    check_tap(-2.0, -14.0, Some(2.0), |_, _| {});
}

#[test]
fn the_overrides_do_not_change_a_rigid_tap() {
    // 150 % spindle override and 50 % feed override once the tap has started: the spindle
    // stays at 600 rpm, Z on the helix (both checked by `check_tap`); after the tap the
    // spindle override applies.
    let mut set = false;
    let trace = check_tap(Z0, BOTTOM, None, |m, e| {
        if !set && e.z < 0.0 {
            set = true;
            assert!(m.sim.handle().urgent(Urgent::SpindleOverride(1.5)));
            assert!(m.sim.handle().urgent(Urgent::FeedOverride(0.5)));
        }
    });
    assert!(set);
    // (Towards 900 rpm: the next block is over before the spindle gets there.)
    assert!(trace.iter().any(|e| e.line == 5 && e.rpm > 1.1 * RPM));
}

#[test]
fn a_feed_hold_in_a_rigid_tap_takes_effect_after_the_retract() {
    let text = format!(
        "G18 G21 G90 G7\nG0 X0 Z{Z0}\nS{RPM} M3\nG33.1 Z{BOTTOM} K{PITCH}\nG0 X20\nM5\nM2\n"
    );
    let cfg = config("sim-lathe.toml");
    let mut m = Machine::started(&cfg, &text, "rigid-tap-hold.ngc");
    assert!(m.until(10.0, |s| s.axes[2] < -2.0));
    assert!(m.sim.handle().urgent(Urgent::FeedHold));
    // The tap goes to the bottom and back out to its start, then the program waits there
    // (X stays on the hole's axis).
    assert!(m.until(10.0, |s| s.axes[2] < BOTTOM - 1.0));
    assert!(m.until(10.0, |s| s.axes[2] == Z0 && s.path_speed == 0.0));
    m.cycles(500);
    assert_eq!(m.status().state, MachineState::Held);
    assert_eq!(m.status().axes[0], 0.0);
    assert_eq!(m.status().axes[2], Z0);
    assert!(m.status().spindle_rpm > 0.99 * RPM);
    assert!(m.sim.handle().urgent(Urgent::Resume));
    assert!(m.until(5.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert_eq!(m.status().axes[0], 10.0);
    assert!(m.faults.is_empty(), "{:?}", m.faults);
}

#[test]
fn an_abort_in_a_rigid_tap_stops_the_spindle_with_the_tool() {
    // A tool left standing in the hole with the spindle turning would break: the abort
    // stops both (LinuxCNC's abort stops the spindle too).
    let text = format!(
        "G18 G21 G90 G7\nG0 X0 Z{Z0}\nS{RPM} M3\nG33.1 Z{BOTTOM} K{PITCH}\nG0 X20\nM5\nM2\n"
    );
    let cfg = config("sim-lathe.toml");
    let mut m = Machine::started(&cfg, &text, "rigid-tap-abort.ngc");
    assert!(m.until(10.0, |s| s.axes[2] < -2.0));
    assert!(m.sim.handle().urgent(Urgent::Abort));
    assert!(m.until(5.0, |s| s.state == MachineState::Idle
        && s.spindle_rpm == 0.0));
    let z = m.status().axes[2];
    assert!(z < -2.0 && z > BOTTOM, "{z}");
    m.cycles(500);
    assert_eq!(m.status().axes[2], z);
    assert_eq!(m.status().spindle_rpm, 0.0);
}

#[test]
fn the_example_taps_within_the_lathes_limits() {
    // examples/gcode/rigid_tap.ngc: from Z3 to Z-12 and back, 1.52 mm overrun each end
    // (as its comment works out), Z never above its 5 mm limit.
    let overrun = PITCH * braking_turns(RPM, SPINDLE_ACCELERATION_RPM_S, SPINDLE_JERK_RPM_S2);
    let text = std::fs::read_to_string(repo().join("examples/gcode/rigid_tap.ngc")).unwrap();
    let cfg = config("sim-lathe.toml");
    let mut m = Machine::started(&cfg, &text, "rigid_tap.ngc");
    assert!(m.until(30.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    let tap = || m.samples.iter().filter(|s| s.line == 10).map(|s| s.axes[2]);
    let deepest = tap().fold(f64::INFINITY, f64::min);
    let highest = tap().fold(f64::MIN, f64::max);
    assert!((deepest - (-12.0 - overrun)).abs() < 0.05, "{deepest}");
    assert!(
        (highest - (3.0 + overrun)).abs() < 0.05 && highest <= 5.0,
        "{highest}"
    );
    assert_eq!(m.samples.last().unwrap().axes[2], 3.0);
}

#[test]
fn on_the_mill_the_block_after_a_tap_waits_for_the_spindle_at_speed_without_a_resume() {
    // configs/sim-mill.toml runs examples/plc/mill.st, which asks for a feed hold while the
    // spindle is out of its at-speed window (2 % for 200 ms), as the tap's reversals take
    // it. The tap goes on to its end (it cannot stop in the hole), nothing latches, and
    // the next block starts by itself once the logic reports the spindle at speed again.
    let text = "G21 G90\nG0 X10 Y10 Z2\nS600 M3\nG33.1 Z-10 K1\nG0 Z5\nM5\nM2\n";
    let cfg = config("sim-mill.toml");
    let mut m = Machine::started(&cfg, text, "mill-tap.ngc");
    let mut rpm_when_next_block_moved = None;
    for _ in 0..30_000 {
        m.cycles(1);
        let s = *m.samples.last().unwrap();
        let st = m.status();
        if s.line == 5 && s.axes[2] > 2.0 && rpm_when_next_block_moved.is_none() {
            rpm_when_next_block_moved = Some(st.spindle_rpm);
        }
        if st.program_ended && st.state == MachineState::Idle {
            break;
        }
    }
    assert!(
        m.status().program_ended,
        "{:?} {:?}",
        m.faults,
        m.sim.handle().error_text()
    );
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    // The tap went to the bottom and on while the spindle braked from 600 rpm at
    // 12 000 rpm/s and 480 000 rpm/s²: 0.25 + 0.125 turns (`braking_turns`), 0.375 mm, plus a
    // few milliseconds (10 µm each) between the command and the drive.
    let deepest = m
        .samples
        .iter()
        .map(|s| s.axes[2])
        .fold(f64::INFINITY, f64::min);
    let want = -10.0 - PITCH * braking_turns(RPM, 12_000.0, 480_000.0);
    eprintln!("deepest Z {deepest}, hand-worked {want}");
    assert!(deepest < want + 1e-3 && deepest > want - 0.05, "{deepest}");
    let rpm = rpm_when_next_block_moved.unwrap();
    assert!((rpm - RPM).abs() <= 0.02 * RPM, "{rpm}");
    // Z follows the spindle's S-curve. Synchronised (below Z0.5: the catching up is done
    // above it, and the tap's unsynchronised moves there run at Z's own limits), its jerk
    // is pitch × the spindle's, 1 mm × 8 000 rev/s³, and up to 1.55 times that where the
    // spindle's jerk sets in: the set-point extrapolates the angle by the last period
    // (2·θₖ − θₖ₋₁), so a jerk step at a period boundary, whose third differences are
    // 1/6, 5/6, 1, 1 × j·T³, gives 1/3, 3/2, 7/6, 1 (and one within a period at most 1.545).
    let tap: Vec<_> = m.samples.iter().filter(|s| s.line == 4).copied().collect();
    let stats = check_limits(&cfg, &tap, &[rtcnc_motion::Axis::Z]);
    let mut synced = rtcnc_kernel::report::RunStats::new();
    for s in tap.iter().filter(|s| s.axes[2] < 0.5) {
        synced.add(s, 0.001);
    }
    eprintln!(
        "mill tap: Z velocity {} mm/s, acceleration {} mm/s², jerk {} mm/s³ ({} mm/s³ synchronised)",
        stats.max_velocity[2], stats.max_acceleration[2], stats.max_jerk[2], synced.max_jerk[2]
    );
    let spindle_jerk = PITCH * 480_000.0 / 60.0;
    assert!(
        synced.max_jerk[2] >= spindle_jerk && synced.max_jerk[2] <= 1.55 * spindle_jerk,
        "{}",
        synced.max_jerk[2]
    );
    // And every axis keeps its limits throughout the program.
    check_limits(
        &cfg,
        &m.samples,
        &[
            rtcnc_motion::Axis::X,
            rtcnc_motion::Axis::Y,
            rtcnc_motion::Axis::Z,
        ],
    );
}
