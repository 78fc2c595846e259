#![allow(clippy::needless_range_loop)]
//! The set-point lead (`tasks.setpoint_lead`): interpolation computes the set-points ahead
//! of position control, so that a stall of its thread is ridden through, and takes back
//! those not yet applied before every change, so that urgent commands still act in the
//! next servo period. The reference is the same machine with a lead of one period (each
//! set-point computed in the period before its exchange), bit for bit.

use crate::common::*;
use std::time::Duration;

use rtcnc_kernel::{Command, FaultCode, Kernel, KernelOptions, MachineState, Status, Urgent};

/// Lines, arcs and blended corners on the benchmark machine (100 mm/s, 1000 mm/s²).
const PROGRAM: &str = "G21 G90 G64 P0.02
G0 X5 Y5
G1 X40 F3000
G2 X60 Y25 R20
G1 Y60
G3 X30 Y60 R15
G1 X5 Y5 Z-2
G1 X45 Y15 Z0
M2
";

struct Run {
    /// (cycle, X, Y, Z set-point) of every servo period.
    samples: Vec<(u64, [f64; 3])>,
    faults: Vec<rtcnc_kernel::Fault>,
    underruns: u64,
    /// The longest gap between interpolation runs, in periods.
    gap: u64,
    status: Status,
}

/// The program on bench-xyz with the lead `lead`, an interpolation stall, and urgent
/// commands sent before the given cycles.
fn run(lead: &str, stall: Option<(u64, Duration)>, urgent: &[(u64, Urgent)], name: &str) -> Run {
    let mut sim = simulation_with_lead("bench-xyz.toml", lead, stall, Some(program(PROGRAM, name)));
    let h = sim.handle().clone();
    let mut samples = Vec::new();
    let mut sink = |s: &rtcnc_kernel::Sample| {
        samples.push((s.cycle, [s.setpoint[0], s.setpoint[1], s.setpoint[2]]))
    };
    sim.run_cycles(2, &mut sink).unwrap();
    h.command(Command::Reset);
    sim.run_cycles(10, &mut sink).unwrap();
    h.command(Command::Start { from_line: 0 });
    for cycle in 12..8000u64 {
        for (_, u) in urgent.iter().filter(|(at, _)| *at == cycle) {
            assert!(h.urgent(*u));
        }
        sim.run_cycles(1, &mut sink).unwrap();
        let s = h.status();
        if cycle > 100 && s.state == MachineState::Idle || s.state == MachineState::Fault {
            break;
        }
    }
    // Whatever was still moving comes to rest.
    sim.run_cycles(300, &mut sink).unwrap();
    let (_, gap) = h.setpoint_lead();
    Run {
        samples,
        faults: h.take_faults(),
        underruns: h.setpoint_underruns(),
        gap,
        status: h.status(),
    }
}

fn first_difference(a: &Run, b: &Run) -> Option<usize> {
    (0..a.samples.len().max(b.samples.len())).find(|&i| a.samples.get(i) != b.samples.get(i))
}

#[test]
fn urgent_commands_act_as_with_each_set_point_computed_just_before_its_exchange() {
    let urgent = [
        (400, Urgent::FeedOverride(0.5)),
        (900, Urgent::FeedHold),
        (1500, Urgent::Resume),
        (1520, Urgent::FeedOverride(1.5)),
        (2300, Urgent::RapidOverride(0.3)),
        (2600, Urgent::Abort),
    ];
    let reference = run("1ms", None, &urgent, "urgent-1.ngc");
    assert!(reference.faults.is_empty(), "{:?}", reference.faults);
    // The abort ended the program part-way.
    assert!(!reference.status.program_ended);
    for lead in ["2ms", "7ms", "50ms", "200ms"] {
        let ahead = run(lead, None, &urgent, &format!("urgent-{lead}.ngc"));
        assert_eq!(first_difference(&reference, &ahead), None, "lead {lead}");
        assert!(ahead.faults.is_empty(), "{lead}: {:?}", ahead.faults);
        assert_eq!(ahead.underruns, 0);
    }
}

#[test]
fn an_estop_acts_in_the_next_period_whatever_the_lead() {
    let urgent = [(1100, Urgent::EStop)];
    let reference = run("1ms", None, &urgent, "estop-1.ngc");
    let ahead = run("50ms", None, &urgent, "estop-50.ngc");
    assert_eq!(first_difference(&reference, &ahead), None);
    assert_eq!(ahead.faults.len(), 1);
    assert_eq!(ahead.faults[0].code, FaultCode::EStop);
    assert_eq!(ahead.status.state, MachineState::EStop);
}

#[test]
fn a_stall_of_interpolation_shorter_than_the_lead_changes_nothing() {
    let reference = run("50ms", None, &[], "stall-none.ngc");
    assert!(reference.status.program_ended);
    assert_eq!(reference.gap, 1);
    // At activation 700 the path moves at speed; the thread then does not run for 45 ms.
    let stalled = run(
        "50ms",
        Some((700, Duration::from_millis(45))),
        &[],
        "stall-45.ngc",
    );
    assert_eq!(first_difference(&reference, &stalled), None);
    assert_eq!(stalled.underruns, 0);
    assert!(stalled.faults.is_empty(), "{:?}", stalled.faults);
    assert!(stalled.gap >= 45, "{}", stalled.gap);
    // With the lead of one period, the same stall leaves position control without
    // set-points: it brings the machine to rest by itself and raises the fault.
    let short = run(
        "1ms",
        Some((700, Duration::from_millis(45))),
        &[],
        "stall-45-short.ngc",
    );
    assert_eq!(short.faults[0].code, FaultCode::SetpointsRanDry);
}

#[test]
fn set_points_that_run_dry_are_a_fault_and_position_control_stops_every_joint_itself() {
    let stalled = run(
        "20ms",
        Some((700, Duration::from_millis(120))),
        &[],
        "stall-120.ngc",
    );
    let fault = stalled.faults[0];
    assert_eq!(fault.code, FaultCode::SetpointsRanDry);
    assert_eq!(stalled.status.state, MachineState::Fault);
    // The set-points: at speed before, then position control's quick stop (the axes'
    // limits: 1000 mm/s², 50 000 mm/s³) from the velocity of the last two, to rest.
    let s = &stalled.samples;
    // A sample is recorded every period with the number of the set-point position
    // control took; while none comes, the number stands. The fifth period without one
    // starts the stop.
    let first_missing = (1..s.len()).find(|&i| s[i].0 == s[i - 1].0).unwrap();
    assert!(
        s[first_missing..first_missing + 5]
            .iter()
            .all(|x| x.0 == s[first_missing].0)
    );
    let dry = first_missing + 4;
    let dt = 1e-3;
    let v = |i: usize, k: usize| (s[i].1[k] - s[i - 1].1[k]) / dt;
    let speed_at_dry = (0..3).map(|k| v(dry, k).abs()).fold(0.0, f64::max);
    assert!(speed_at_dry > 10.0, "{speed_at_dry}");
    let mut stood = None;
    for i in dry + 2..s.len() {
        for k in 0..3 {
            let a = (v(i, k) - v(i - 1, k)) / dt;
            assert!(
                a.abs() <= 1000.0 * 1.001,
                "cycle {}: axis {k} at {a} mm/s²",
                s[i].0
            );
        }
        if (0..3).all(|k| v(i, k) == 0.0) && stood.is_none() {
            stood = Some(i);
        }
    }
    // From ≤ 100 mm/s the stop takes at most v/a + a/j = 0.12 s.
    let stood = stood.expect("comes to rest");
    assert!(stood - dry <= 125, "{} periods", stood - dry);
}

#[test]
fn the_lead_is_refused_beyond_its_maximum_with_the_key_named() {
    let mut cfg = config("bench-xyz.toml");
    cfg.tasks.setpoint_lead = Some("2s".into());
    let err = Kernel::build(&cfg, KernelOptions::default())
        .err()
        .expect("refused");
    let text = format!("{err:#}");
    assert!(text.contains("tasks.setpoint_lead"), "{text}");
}
