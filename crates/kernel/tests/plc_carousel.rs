//! The simulated mill with a servo carousel (configs/sim-mill-carousel.toml): the machine
//! logic (examples/plc/mill_carousel.st) turns the carousel, joint T, with the PLCopen
//! motion blocks on its auxiliary axis, and the joint's drive follows the PLC's set-point
//! under position control like X, Y and Z.
//!
//! Hand-worked profile of a turn (joint T's limits: 360 °/s, 3600 °/s², 72 000 °/s³):
//! reaching 360 °/s takes a/j + v/a = 0.05 + 0.1 = 0.15 s and covers 360 · 0.15 / 2 = 27°
//! (a symmetric profile); T5 from pocket 1 is 120°: 27 + 66 + 27, so 0.15 + 66/360 + 0.15
//! = 0.4833 s; T3 then is 60° back: 0.15 + 6/360 + 0.15 = 0.3167 s.

use crate::common::*;
use rtcnc_fieldbus::sim::InjectedFault;
use rtcnc_kernel::{FaultCode, MachineState};

const T: usize = 3;

/// The periods in which joint T's set-point moved, as (first, last) runs of motion.
fn turns(m: &Machine) -> Vec<(usize, usize)> {
    let mut runs = Vec::new();
    let mut start = None;
    for (i, w) in m.samples.windows(2).enumerate() {
        let moving = (w[1].setpoint[T] - w[0].setpoint[T]).abs() > 1e-9;
        match (moving, start) {
            (true, None) => start = Some(i + 1),
            (false, Some(s)) => {
                runs.push((s, i));
                start = None;
            }
            _ => {}
        }
    }
    runs
}

#[test]
fn t5_and_t3_turn_the_carousel_axis_to_their_pockets_within_its_limits() {
    let cfg = config("sim-mill-carousel.toml");
    let text = "G21 G90 G61.1\nG1 X1 F600\nT5 M6\nG1 X2\nT3 M6\nG1 X3\nM2\n";
    let mut m = Machine::started(&cfg, text, "carousel.ngc");
    assert!(m.until(20.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    assert_eq!(m.status().tool, 3);
    assert_eq!(m.status().axes[0], 3.0);
    let runs = turns(&m);
    assert_eq!(runs.len(), 2, "{runs:?}");
    // Each turn ends on its pocket: the set-point exactly, the drive within 5 µ°.
    let at = |i: usize| m.samples[i].setpoint[T];
    assert_eq!(at(runs[0].1), 120.0);
    assert_eq!(at(runs[1].1), 60.0);
    let last = m.samples.last().unwrap();
    assert!(
        (last.feedback[T] - 60.0).abs() < 5e-3,
        "{}",
        last.feedback[T]
    );
    // The turns take the closed-form times, to a period (1 ms samples).
    let secs = |(a, b): (usize, usize)| (b + 1 - a) as f64 * 1e-3;
    assert!(
        (secs(runs[0]) - 0.4833).abs() <= 1.5e-3,
        "{}",
        secs(runs[0])
    );
    assert!(
        (secs(runs[1]) - 0.3167).abs() <= 1.5e-3,
        "{}",
        secs(runs[1])
    );
    // Within the axis's limits: position, velocity, and acceleration (a difference of
    // differences of 1 ms samples).
    let p: Vec<f64> = m.samples.iter().map(|s| s.setpoint[T]).collect();
    assert!(p.iter().all(|&x| (0.0..=330.0).contains(&x)));
    let v: Vec<f64> = p.windows(2).map(|w| (w[1] - w[0]) / 1e-3).collect();
    assert!(v.iter().all(|x| x.abs() <= 360.0 * (1.0 + 1e-9)));
    let a = v.windows(2).map(|w| (w[1] - w[0]) / 1e-3);
    let a_max = a.fold(0.0, |m: f64, x| m.max(x.abs()));
    assert!(a_max <= 3600.0 * (1.0 + 1e-6), "{a_max}");
    // The drive followed: its following error stayed inside the joint's min_ferror.
    let fe = m
        .samples
        .iter()
        .map(|s| s.following_error[T].abs())
        .fold(0.0, f64::max);
    assert!(fe < 0.05, "{fe}");
}

#[test]
fn a_fault_of_the_carousel_drive_is_a_drive_fault_and_stops_the_change() {
    let cfg = config("sim-mill-carousel.toml");
    let text = "G21 G90 G61.1\nG1 X1 F600\nT5 M6\nG1 X2\nM2\n";
    let mut m = Machine::started(&cfg, text, "carousel-fault.ngc");
    // The turn starts after the unclamp (0.3 s): fault the drive once it is past 20°.
    let fault = InjectedFault::DriveFault {
        joint: T,
        error_code: 0x2310,
    };
    let mut turning = false;
    for _ in 0..5000 {
        m.cycles(1);
        if m.samples.len() > 1 {
            let n = m.samples.len();
            turning = m.samples[n - 1].setpoint[T] > 20.0;
        }
        if turning {
            break;
        }
    }
    assert!(turning, "the carousel turns");
    m.handle_machine(|machine| machine.inject(fault).unwrap());
    // The exchange of the next period brings the fault; the logic, after it in that
    // period, puts the PLC's axis into ErrorStop (16#12) before anything else changed.
    m.cycles(1);
    {
        let plc = m.sim.handle().plc().unwrap().lock();
        let axis = plc.axis("carousel").unwrap();
        assert_eq!(axis.state, rtcnc_plc::AxisState::ErrorStop);
        assert_eq!(axis.error_id, rtcnc_plc::motion_error_id::DRIVE);
    }
    m.cycles(50);
    let drive_fault = m
        .faults
        .iter()
        .find(|f| f.code == FaultCode::DriveFault)
        .expect("a drive fault");
    assert_eq!(drive_fault.joint, Some(T as u8));
    // The machine went off: mill_carousel.st switched the axis off and reset its error.
    {
        let plc = m.sim.handle().plc().unwrap().lock();
        let axis = plc.axis("carousel").unwrap();
        assert_eq!(
            (axis.state, axis.error_id),
            (rtcnc_plc::AxisState::Disabled, 0)
        );
    }
    // The program does not go on to X2; the tool is not changed.
    assert!(!m.until(2.0, |s| s.program_ended));
    assert_eq!(m.status().axes[0], 1.0);
    assert_ne!(m.status().tool, 5);
}
