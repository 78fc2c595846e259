//! An e-stop early in a rapid from rest: found by the kernel fuzz target
//! (fuzz/defects/kernel/estop-in-a-rapids-first-70ms), where the state became e-stop but
//! the path went on with the drives enabled. Swept over every period of the rapid's first
//! 80 ms: the machine must stand within the quick-stop bound computed from the limits, with
//! the drives off, in e-stop, and no set-point beyond the quick-stop limits.

use crate::common::*;
use rtcnc_kernel::{Command, FixedText, MachineState, Urgent};

const PERIOD: f64 = 0.001;

/// The mill's X and Y (configs/sim-mill.toml): velocity, quick-stop acceleration and jerk.
const V_MAX: f64 = 100.0;
const A_QS: f64 = 2000.0;
const J_QS: f64 = 100_000.0;

struct Outcome {
    estop_cycle: u64,
    last_motion_cycle: u64,
    state: MachineState,
    ready: bool,
    load_speed: f64,
    max_accel_after: f64,
    max_jerk_after: f64,
    max_speed: f64,
}

fn estop_into_rapid(periods_after_motion: u64) -> Outcome {
    let cfg = config("sim-mill.toml");
    let mut m = Machine::new(&cfg, None);
    m.power_on();
    m.command(Command::Mdi(FixedText::new("G0 X10 Y10").unwrap()));
    assert!(m.until(1.0, |s| s.path_speed > 0.0), "the rapid starts");
    m.cycles(periods_after_motion);
    let estop_cycle = m.samples.last().unwrap().cycle;
    assert!(m.sim.handle().urgent(Urgent::EStop));
    m.cycles(500);
    let s = &m.samples;
    let mut last_motion_cycle = estop_cycle;
    let mut max_accel_after: f64 = 0.0;
    let mut max_speed: f64 = 0.0;
    let mut max_jerk_after: f64 = 0.0;
    for w in s.windows(4) {
        for j in 0..2 {
            let v = |a: usize| (w[a].setpoint[j] - w[a - 1].setpoint[j]) / PERIOD;
            let (v1, v2, v3) = (v(1), v(2), v(3));
            max_speed = max_speed.max(v3.abs());
            if w[3].cycle > estop_cycle {
                let (a2, a3) = ((v2 - v1) / PERIOD, (v3 - v2) / PERIOD);
                max_accel_after = max_accel_after.max(a3.abs());
                max_jerk_after = max_jerk_after.max(((a3 - a2) / PERIOD).abs());
                if v3.abs() > 1e-9 {
                    last_motion_cycle = w[3].cycle;
                }
            }
        }
    }
    let status = m.status();
    let load_speed = m.handle_machine(|mach| {
        (0..3)
            .map(|j| mach.true_state(j).unwrap().1.abs())
            .fold(0.0, f64::max)
    });
    Outcome {
        estop_cycle,
        last_motion_cycle,
        state: status.state,
        ready: status.ready,
        load_speed,
        max_accel_after,
        max_jerk_after,
        max_speed,
    }
}

#[test]
fn an_estop_in_the_first_80_ms_of_a_rapid_stops_it_within_the_quick_stop_bound() {
    let cfg = config("sim-mill.toml");
    let lead_periods = {
        let m = Machine::new(&cfg, None);
        m.sim.handle().setpoint_lead().0 as f64
    };
    // From the highest speed, a jerk-limited stop at the quick-stop limits lasts at most
    // v / a + a / j; the set-points already handed over (the lead) go first, plus one period
    // for the exchange that reads the e-stop.
    let bound = ((V_MAX / A_QS + A_QS / J_QS) / PERIOD).ceil() + lead_periods + 2.0;
    let mut failures = Vec::new();
    for k in 10..=80 {
        let o = estop_into_rapid(k);
        let stop_periods = o.last_motion_cycle.saturating_sub(o.estop_cycle) as f64;
        let ok = stop_periods <= bound
            && o.state == MachineState::EStop
            && !o.ready
            && o.load_speed < 1e-3
            && o.max_accel_after <= A_QS * 1.001
            && o.max_jerk_after <= J_QS * 1.001
            && o.max_speed <= V_MAX * 1.001;
        if !ok {
            failures.push(format!(
                "{k} ms: stood after {stop_periods} periods (bound {bound}), state {:?}, \
                 ready {}, load {:.3} mm/s, accel {:.0}, jerk {:.0}, speed {:.1}",
                o.state, o.ready, o.load_speed, o.max_accel_after, o.max_jerk_after, o.max_speed
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Found by the kernel fuzz target once the case above was fixed: an abort in the period
/// after the e-stop, during its quick stop, replaced it with the abort's gentler stop from
/// the set-point position control was about to take, and X jumped at 6 800-13 000 mm/s².
#[test]
fn an_abort_during_an_estops_quick_stop_leaves_it_alone() {
    let text = "G21 G90 G64\nG0 X2 Y2\nG1 Z-1 F600\nG1 X3 Y2.2 F4000\nX4 Y2.1\nX5 Y2.6\n\
                X6 Y2.4\nX7 Y3\nG3 X9 Y5 R2\nG1 X9.2 Y5.1\nM2\n";
    let cfg = config("sim-mill.toml");
    let mut failures = Vec::new();
    for k in (40..=130).step_by(3) {
        let mut m = Machine::new(&cfg, Some(program(text, "abort-in-estop.ngc")));
        m.power_on();
        // From line 7: first a rapid to where it starts.
        m.command(Command::Start { from_line: 7 });
        m.cycles(k);
        let estop_cycle = m.samples.last().unwrap().cycle;
        assert!(m.sim.handle().urgent(Urgent::EStop));
        m.cycles(1);
        assert!(m.sim.handle().urgent(Urgent::Abort));
        m.cycles(300);
        let mut accel: f64 = 0.0;
        for w in m.samples.windows(3).filter(|w| w[2].cycle > estop_cycle) {
            for j in 0..3 {
                let a = (w[2].setpoint[j] - 2.0 * w[1].setpoint[j] + w[0].setpoint[j])
                    / (PERIOD * PERIOD);
                accel = accel.max(a.abs());
            }
        }
        let s = m.status();
        if accel > A_QS * 1.001 || s.state != MachineState::EStop || s.ready {
            failures.push(format!(
                "{k}: accel {accel:.0}, {:?}, ready {}",
                s.state, s.ready
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Found by the kernel fuzz target (fuzz/defects/kernel/estop-released-during-its-quick-stop):
/// the e-stop button cuts the drives' power. Released while the kernel's quick stop still
/// ran, the quick stop brought the drives up again, and they pulled the load onto the
/// stop's set-points with the machine in e-stop and no reset. Released at any time of the
/// stop, no drive may be enabled again before a reset.
#[test]
fn an_estop_button_released_during_the_quick_stop_leaves_the_drives_off() {
    let cfg = config("sim-mill.toml");
    let mut failures = Vec::new();
    for release_after in [1, 2, 4, 8, 16, 32, 48, 64, 80] {
        let mut m = Machine::new(&cfg, None);
        m.power_on();
        m.command(Command::Mdi(FixedText::new("G1 X40 Y30 F3000").unwrap()));
        assert!(m.until(2.0, |s| s.path_speed > 40.0), "the feed move runs");
        m.handle_machine(|mach| mach.set_estop(true));
        m.cycles(release_after);
        m.handle_machine(|mach| mach.set_estop(false));
        let mut enabled_periods = 0;
        for _ in 0..500 {
            m.cycles(1);
            let any_on = m.handle_machine(|mach| {
                (0..3).any(|j| {
                    matches!(
                        mach.drive_state(j),
                        Some(
                            rtcnc_fieldbus::Cia402State::OperationEnabled
                                | rtcnc_fieldbus::Cia402State::QuickStopActive
                        )
                    )
                })
            });
            enabled_periods += u32::from(any_on);
        }
        let s = m.status();
        if enabled_periods > 0 || s.state != MachineState::EStop || s.ready {
            failures.push(format!(
                "released after {release_after} ms: a drive enabled in {enabled_periods} \
                 periods, {:?}, ready {}",
                s.state, s.ready
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
