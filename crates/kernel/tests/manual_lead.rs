#![allow(clippy::needless_range_loop)]
//! Jogs, homing and spindle-synchronised moves have the set-point lead that programs have
//! (`tasks.setpoint_lead`): a stall of interpolation's thread shorter than the lead is
//! ridden through with no fault, and a jog release, a hold or an e-stop still acts in the
//! next servo period. References: the same machine with a lead of one period (each
//! set-point computed in the period before its exchange), and limits and stop times
//! derived by hand from the machine file.

use crate::common::*;
use std::time::Duration;

use rtcnc_kernel::{Command, Fault, FaultCode, KernelHandle, MachineState, Sample, Status, Urgent};

const DT: f64 = 1e-3;

struct Run {
    samples: Vec<Sample>,
    faults: Vec<Fault>,
    status: Status,
    underruns: u64,
    /// The longest gap between two runs of interpolation, in periods.
    gap: u64,
}

/// Runs `config` with the lead `lead` and one stall of interpolation, after a reset; before
/// each cycle `script(cycle, handle)` may send commands; ends `settle` cycles after
/// `done` first holds (or after `max` cycles).
fn run(
    config_name: &str,
    lead: &str,
    stall: Option<(u64, Duration)>,
    program_text: Option<(&str, &str)>,
    max: u64,
    mut script: impl FnMut(u64, &KernelHandle),
    done: impl Fn(u64, &Status) -> bool,
) -> Run {
    let mut sim = simulation_with_lead(
        config_name,
        lead,
        stall,
        program_text.map(|(text, name)| program(text, name)),
    );
    let h = sim.handle().clone();
    let mut samples = Vec::new();
    let mut sink = |s: &Sample| samples.push(*s);
    sim.run_cycles(2, &mut sink).unwrap();
    h.command(Command::Reset);
    sim.run_cycles(20, &mut sink).unwrap();
    let mut faults = Vec::new();
    let mut ended = None;
    for cycle in 22..max {
        script(cycle, &h);
        sim.run_cycles(1, &mut sink).unwrap();
        faults.extend(h.take_faults());
        if ended.is_none() && done(cycle, &h.status()) {
            ended = Some(cycle);
        }
        if ended.is_some_and(|e| cycle >= e + 300) {
            break;
        }
    }
    faults.extend(h.take_faults());
    Run {
        samples,
        faults,
        status: h.status(),
        underruns: h.setpoint_underruns(),
        gap: h.setpoint_lead().1,
    }
}

/// Velocity, acceleration and jerk of joint `j` by finite differences of its set-points;
/// each is the mean of the true one over one to three periods, so bounded by its limit.
fn check_limits(samples: &[Sample], j: usize, v: f64, a: f64, jerk: f64) {
    let p: Vec<f64> = samples.iter().map(|s| s.setpoint[j]).collect();
    for i in 3..p.len() {
        let v0 = (p[i] - p[i - 1]) / DT;
        let v1 = (p[i - 1] - p[i - 2]) / DT;
        let v2 = (p[i - 2] - p[i - 3]) / DT;
        let a0 = (v0 - v1) / DT;
        let a1 = (v1 - v2) / DT;
        let j0 = (a0 - a1) / DT;
        let c = samples[i].cycle;
        assert!(v0.abs() <= v * (1.0 + 1e-9), "joint {j} cycle {c}: v {v0}");
        assert!(a0.abs() <= a * (1.0 + 1e-6), "joint {j} cycle {c}: a {a0}");
        assert!(
            j0.abs() <= jerk * (1.0 + 1e-5),
            "joint {j} cycle {c}: jerk {j0}"
        );
    }
}

/// The first sample at which the two runs' set-points differ (by more than `tol`).
fn first_difference(a: &Run, b: &Run, joints: usize, tol: f64) -> Option<u64> {
    let n = a.samples.len().min(b.samples.len());
    (0..n)
        .find(|&i| {
            a.samples[i].cycle != b.samples[i].cycle
                || (0..joints)
                    .any(|j| (a.samples[i].setpoint[j] - b.samples[i].setpoint[j]).abs() > tol)
        })
        .map(|i| a.samples[i].cycle)
}

/// Continuous jog of X at 50 mm/s from cycle 30, released at cycle `release`.
fn jog(lead: &str, stall: Option<(u64, Duration)>, release: u64) -> Run {
    run(
        "sim-mill.toml",
        lead,
        stall,
        None,
        3000,
        |cycle, h| {
            if cycle == 30 {
                jog_continuously(h, 0, 50.0);
            }
            if cycle == release {
                assert!(h.command(Command::JogStop { axis: 0 }));
            }
        },
        |cycle, s| cycle > release && s.state == MachineState::Idle,
    )
}

#[test]
fn a_stall_during_a_jog_shorter_than_the_lead_changes_nothing() {
    let reference = jog("50ms", None, 400);
    assert!(reference.faults.is_empty(), "{:?}", reference.faults);
    assert_eq!(reference.gap, 1);
    for periods in [8, 15, 45] {
        // At cycle 200 the jog runs at 50 mm/s.
        let stalled = jog("50ms", Some((200, Duration::from_millis(periods))), 400);
        assert!(stalled.faults.is_empty(), "{periods}: {:?}", stalled.faults);
        assert_eq!(stalled.underruns, 0);
        assert!(stalled.gap >= periods, "{periods}: gap {}", stalled.gap);
        assert_eq!(first_difference(&reference, &stalled, 3, 0.0), None);
        assert_eq!(stalled.status.state, MachineState::Idle);
        check_limits(&stalled.samples, 0, 100.0, 1000.0, 50_000.0);
    }
    // With a lead of one period the same stall runs the set-points dry.
    let short = jog("1ms", Some((200, Duration::from_millis(8))), 400);
    assert_eq!(short.faults[0].code, FaultCode::SetpointsRanDry);
}

#[test]
fn a_stall_longer_than_the_lead_is_a_fault_and_the_jog_stops_within_the_quick_stop_limits() {
    let stalled = jog("20ms", Some((200, Duration::from_millis(60))), 2000);
    assert_eq!(stalled.faults[0].code, FaultCode::SetpointsRanDry);
    assert_eq!(stalled.status.state, MachineState::Fault);
    assert!(!stalled.status.ready);
    // Position control's own stop from 50 mm/s with X's quick-stop limits (2000 mm/s²,
    // 100 000 mm/s³): the machine stands, every set-point within those limits.
    check_limits(&stalled.samples, 0, 100.0, 2000.0, 100_000.0);
    let s = &stalled.samples;
    let n = s.len();
    assert_eq!(s[n - 1].setpoint[0], s[n - 2].setpoint[0]);
}

/// The cycle of the first set-point (from `from` on) at which X's velocity falls below
/// the one before it.
fn first_slower(r: &Run, from: u64) -> u64 {
    let s = &r.samples;
    (2..s.len())
        .find(|&i| {
            s[i].cycle > from && {
                let v = s[i].setpoint[0] - s[i - 1].setpoint[0];
                let before = s[i - 1].setpoint[0] - s[i - 2].setpoint[0];
                v < before - 1e-9
            }
        })
        .map(|i| s[i].cycle)
        .expect("slows down")
}

/// The cycle from which X stands (its set-point no longer changes).
fn stands_from(r: &Run) -> u64 {
    let s = &r.samples;
    let i = (1..s.len())
        .rev()
        .find(|&i| s[i].setpoint[0] != s[i - 1].setpoint[0])
        .unwrap();
    s[i].cycle
}

#[test]
fn jog_release_hold_abort_and_estop_act_in_the_next_period_with_any_lead() {
    // X at 50 mm/s, acceleration 1000 mm/s², jerk 50 000 mm/s³: a jerk-limited stop takes
    // v/a + a/j = 0.05 + 0.02 s = 70 periods (the acceleration ramp a/j = 20 ms fits
    // within v/a). With the quick-stop limits (2000, 100 000): 0.025 + 0.02 = 45 periods.
    // The command is sent before cycle 400 runs; position control applies a set-point of
    // the stop at the latest two periods later (read in the period, acting from the next
    // exchange), and then stands within the stop's length, plus a period of rounding.
    let release = jog("50ms", None, 400);
    let reference = jog("1ms", None, 400);
    assert_eq!(first_difference(&reference, &release, 3, 0.0), None);
    let slower = first_slower(&release, 300);
    assert!((400..=402).contains(&slower), "release acts at {slower}");
    let stood = stands_from(&release);
    assert!(
        stood <= slower + 71,
        "stands at {stood}, slowed at {slower}"
    );

    let urgent = |lead: &str, command: Urgent| {
        run(
            "sim-mill.toml",
            lead,
            None,
            None,
            3000,
            |cycle, h| {
                if cycle == 30 {
                    jog_continuously(h, 0, 50.0);
                }
                if cycle == 400 {
                    assert!(h.urgent(command));
                }
            },
            |cycle, s| cycle > 400 && s.path_speed == 0.0,
        )
    };
    for (command, stop_periods) in [
        (Urgent::FeedHold, 70),
        (Urgent::Abort, 70),
        (Urgent::EStop, 45),
    ] {
        let ahead = urgent("50ms", command);
        let reference = urgent("1ms", command);
        assert_eq!(
            first_difference(&reference, &ahead, 3, 0.0),
            None,
            "{command:?}"
        );
        let slower = first_slower(&ahead, 300);
        assert!(
            (400..=402).contains(&slower),
            "{command:?} acts at {slower}"
        );
        let stood = stands_from(&ahead);
        assert!(
            stood <= slower + stop_periods + 1,
            "{command:?}: stands at {stood}, slowed at {slower}"
        );
        eprintln!(
            "{command:?}: sent before cycle 400, first slower set-point at {slower}, stands at {stood}"
        );
    }
    eprintln!(
        "jog release: sent before cycle 400, first slower set-point at {slower}, stands at {stood}"
    );
}

/// Homes Z on the mill (search +10 mm/s to the switch at 7 mm, back off at 1 mm/s, latch
/// on the switch edge at 1 mm/s, move to 0).
fn home_z(lead: &str, stall: Option<(u64, Duration)>) -> Run {
    run(
        "sim-mill.toml",
        lead,
        stall,
        None,
        20_000,
        |cycle, h| {
            if cycle == 30 {
                assert!(h.command(Command::HomeAxis { axis: 2 }));
            }
        },
        |cycle, s| cycle > 40 && s.state == MachineState::Idle,
    )
}

/// The middle cycle of each homing phase of joint 2, by its set-point velocity: search
/// (+10 mm/s), back-off (-1), latch (+1), move home (towards 0 faster than the latch).
fn homing_phases(r: &Run) -> Vec<(&'static str, u64)> {
    let s = &r.samples;
    let v = |i: usize| (s[i].setpoint[2] - s[i - 1].setpoint[2]) / DT;
    let mut phases = Vec::new();
    let mut from = 1;
    for (name, test) in [
        (
            "search",
            &(|v: f64| (v - 10.0).abs() < 1e-6) as &dyn Fn(f64) -> bool,
        ),
        ("back-off", &|v: f64| (v + 1.0).abs() < 1e-6),
        ("latch", &|v: f64| (v - 1.0).abs() < 1e-6),
        ("move home", &|v: f64| v < -5.0),
    ] {
        let start = (from..s.len()).find(|&i| test(v(i))).expect(name);
        let end = (start..s.len()).find(|&i| !test(v(i))).unwrap();
        phases.push((name, s[(start + end) / 2].cycle));
        from = end;
    }
    phases
}

#[test]
fn a_stall_in_each_homing_phase_is_ridden_through_and_homes_to_the_same_place() {
    let reference = home_z("50ms", None);
    assert!(reference.faults.is_empty(), "{:?}", reference.faults);
    assert_eq!(reference.status.homed & 4, 4);
    // The lead changes nothing without a stall.
    let one = home_z("1ms", None);
    assert_eq!(first_difference(&one, &reference, 3, 0.0), None);
    let phases = homing_phases(&reference);
    let home = reference.status.joint_feedback[2];
    for (name, at) in phases {
        for periods in [8u64, 15] {
            let stall = Some((at, Duration::from_millis(periods)));
            let stalled = home_z("50ms", stall);
            assert!(
                stalled.faults.is_empty(),
                "{name} {periods}: {:?}",
                stalled.faults
            );
            assert_eq!(stalled.underruns, 0, "{name} {periods}");
            assert!(
                stalled.gap >= periods,
                "{name} {periods}: gap {}",
                stalled.gap
            );
            assert_eq!(stalled.status.state, MachineState::Idle, "{name} {periods}");
            assert_eq!(stalled.status.homed & 4, 4, "{name} {periods}");
            assert_eq!(stalled.status.axes[2], 0.0, "{name} {periods}");
            // The same home: the latch is the drive's, on the switch edge, whatever the
            // stall did to the approach.
            let f = stalled.status.joint_feedback[2];
            assert!((f - home).abs() < 1e-3, "{name} {periods}: {f} vs {home}");
            // Z's limits: 50 mm/s, 800 mm/s², 40 000 mm/s³ (the simulated drive's latch
            // agrees with the position it was powered up at: the offset does not jump).
            check_limits(&stalled.samples, 2, 50.0, 800.0, 40_000.0);
            // The same stall with a lead of one period runs dry.
            let short = home_z("1ms", stall);
            assert_eq!(
                short.faults.first().map(|f| f.code),
                Some(FaultCode::SetpointsRanDry),
                "{name} {periods}"
            );
        }
    }
}

/// A G33 pass on the lathe (600 rpm, 1.5 mm per revolution: 15 mm/s along -Z).
fn thread(lead: &str, stall: Option<(u64, Duration)>) -> Run {
    let text = "G18 G21 G90 G7\nG0 X20 Z5\nS600 M3\nG33 Z-20 K1.5\nG0 X30\nM5\nM2\n";
    run(
        "sim-lathe.toml",
        lead,
        stall,
        Some((text, &format!("g33-{lead}-{stall:?}.ngc"))),
        60_000,
        |cycle, h| {
            if cycle == 30 {
                assert!(h.command(Command::Start { from_line: 0 }));
            }
        },
        |cycle, s| cycle > 40 && s.program_ended && s.state == MachineState::Idle,
    )
}

#[test]
fn a_stall_during_a_thread_pass_is_ridden_through_on_the_same_helix() {
    let reference = thread("50ms", None);
    assert!(reference.faults.is_empty(), "{:?}", reference.faults);
    assert!(reference.status.program_ended);
    // The lead changes nothing without a stall.
    let one = thread("1ms", None);
    assert_eq!(first_difference(&one, &reference, 2, 0.0), None);
    // The middle of the pass: line 4 with Z moving.
    let on_line: Vec<u64> = reference
        .samples
        .iter()
        .filter(|s| s.line == 4)
        .map(|s| s.cycle)
        .collect();
    let middle = on_line[on_line.len() / 2];
    for periods in [8u64, 15] {
        let stalled = thread("50ms", Some((middle, Duration::from_millis(periods))));
        assert!(stalled.faults.is_empty(), "{periods}: {:?}", stalled.faults);
        assert!(stalled.status.program_ended);
        assert_eq!(stalled.underruns, 0);
        assert!(stalled.gap >= periods);
        // The simulated spindle turns at a steady speed, so the set-points computed ahead
        // with its speed are those computed period by period (to rounding).
        assert_eq!(first_difference(&reference, &stalled, 2, 1e-9), None);
        // Z: 120 mm/s, 1000 mm/s², 50 000 mm/s³ (joint 1 of the lathe).
        check_limits(&stalled.samples, 1, 120.0, 1000.0, 50_000.0);
        let short = thread("1ms", Some((middle, Duration::from_millis(periods))));
        assert_eq!(
            short.faults.first().map(|f| f.code),
            Some(FaultCode::SetpointsRanDry)
        );
    }
}
