//! A reset taken as an e-stop's quick stop stands: found by the kernel fuzz target
//! (fuzz/defects/kernel/reset-as-an-estops-quick-stop-stands). The quick stop stood, the
//! kernel's drives-off state began, and a reset in that period (before any drive had
//! heard it was to go off) took the set-points from the measured positions: Z's set-point
//! stepped back by its following error, 0.9 µm in one period (915 mm/s² against 800),
//! while its drive followed it. Resets are sent every period from the e-stop on, so the
//! first one taken is the earliest the kernel takes; later ones too, after the drives
//! are off, where starting again from the measured positions is right.

use crate::common::*;
use rtcnc_fieldbus::cia402::Cia402State;
use rtcnc_kernel::{Command, MachineState, Urgent};

const PERIOD: f64 = 0.001;
/// The mill's Z (configs/sim-mill.toml).
const Z: usize = 2;
const Z_ACCELERATION: f64 = 800.0;
const Z_QUICK_STOP_ACCELERATION: f64 = 1600.0;

struct Outcome {
    /// Periods from the e-stop to the reset the kernel took.
    taken: usize,
    /// Z's largest set-point acceleration while its drive was in operation enabled for
    /// three periods running: from the e-stop to the reset, and after the reset.
    during_stop: f64,
    after_reset: f64,
}

/// Jogs Z at 10 mm/s (the fuzz case homed it at that speed), e-stops it, then sends a
/// reset every period from `first_reset` periods after the e-stop on, until one is taken.
fn reset_after(first_reset: usize) -> Outcome {
    let cfg = config("sim-mill.toml");
    let mut m = Machine::new(&cfg, None);
    m.power_on();
    jog_continuously(m.sim.handle(), Z as u8, -10.0);
    m.cycles(200);
    assert!(m.sim.handle().urgent(Urgent::EStop));
    let estop_at = m.samples.len();
    let mut enabled = Vec::new();
    let mut taken = None;
    for k in 0..400 {
        if taken.is_none() && k >= first_reset {
            m.command(Command::Reset);
        }
        m.cycles(1);
        if taken.is_none() && k > 0 && m.status().state != MachineState::EStop {
            taken = Some(k);
        }
        enabled.push(
            m.handle_machine(|mach| mach.drive_state(Z) == Some(Cia402State::OperationEnabled)),
        );
    }
    let taken = taken.expect("a reset is taken once the quick stop stands");
    let s = &m.samples[estop_at..];
    assert_eq!(s.len(), enabled.len(), "one sample a period");
    let (mut during_stop, mut after_reset) = (0.0f64, 0.0f64);
    for i in 2..s.len() {
        if !(enabled[i] && enabled[i - 1] && enabled[i - 2]) {
            continue;
        }
        let v1 = (s[i - 1].setpoint[Z] - s[i - 2].setpoint[Z]) / PERIOD;
        let v2 = (s[i].setpoint[Z] - s[i - 1].setpoint[Z]) / PERIOD;
        let a = ((v2 - v1) / PERIOD).abs();
        if i > taken {
            after_reset = after_reset.max(a);
        } else {
            during_stop = during_stop.max(a);
        }
    }
    Outcome {
        taken,
        during_stop,
        after_reset,
    }
}

#[test]
fn a_reset_as_the_quick_stop_stands_moves_no_set_point_its_drive_follows() {
    let mut failures = Vec::new();
    // 0: a reset every period from the e-stop on, the first taken as the stop stands;
    // then resets that begin later, across the periods in which the drives go off.
    for first in [0, 10, 20, 25, 30, 35, 40, 50, 80] {
        let o = reset_after(first);
        if o.during_stop > Z_QUICK_STOP_ACCELERATION * 1.001
            || o.after_reset > Z_ACCELERATION * 1.001
        {
            failures.push(format!(
                "resets from {first} periods, taken at {}: {:.0} mm/s² in the stop, {:.0} after the reset",
                o.taken, o.during_stop, o.after_reset
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
