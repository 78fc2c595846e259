//! A reset while the fieldbus is lost: found by the kernel fuzz target
//! (fuzz/defects/kernel/reset-during-a-communication-loss: an MDI arc, a communication
//! loss, an abort, then resets while the bus was still lost). The reset was taken: the
//! set-points started again from the feedback of the lost bus, the last received before
//! the loss, while they had quick-stopped further along, so Y's set-point jumped at 215
//! mm/s against its 100 mm/s limit, and the communication fault came again. As LinuxCNC
//! and TwinCAT do, the machine must not leave the fault while its cause stands: the reset
//! is refused until the bus is back, and then the set-points start from fresh feedback,
//! where the load stands.

use crate::common::*;
use rtcnc_fieldbus::sim::InjectedFault;
use rtcnc_kernel::{Command, FaultCode, MachineState, Urgent};

/// configs/sim-mill.toml: X and Y at most 100 mm/s.
const MAX_VELOCITY: f64 = 100.0;
const PERIOD_S: f64 = 1e-3;

/// The largest set-point velocity of X and Y over `samples` (mm/s).
fn fastest(samples: &[rtcnc_kernel::Sample]) -> f64 {
    samples
        .windows(2)
        .flat_map(|w| (0..2).map(move |i| ((w[1].axes[i] - w[0].axes[i]) / PERIOD_S).abs()))
        .fold(0.0, f64::max)
}

#[test]
fn a_reset_is_refused_while_the_bus_is_lost_and_starts_from_fresh_feedback_once_it_is_back() {
    let cfg = config("sim-mill.toml");
    let mut m = Machine::new(&cfg, None);
    m.power_on();
    // A full circle of radius 5 mm at 15 mm/s, aborted as it runs; the bus is lost in
    // the abort's stop.
    m.command(Command::Mdi(rtcnc_kernel::FixedText::truncated(
        "G2 X0 Y0 I5 J0 F900",
    )));
    m.cycles(64);
    assert!(m.sim.handle().urgent(Urgent::Abort));
    m.handle_machine(|machine| machine.inject(InjectedFault::CommunicationLoss).unwrap());
    m.cycles(400);
    assert_eq!(m.status().state, MachineState::Fault);
    assert!(!m.status().ready);
    assert_eq!(
        m.faults.first().map(|f| f.code),
        Some(FaultCode::Communication)
    );
    m.faults.clear();

    // Resets while the bus is still lost: refused, nothing moves, no new fault.
    let from = m.samples.len();
    assert!(m.sim.handle().urgent(Urgent::Abort));
    for _ in 0..8 {
        m.command(Command::Reset);
    }
    m.cycles(100);
    // The set-points stay where the quick stop left them (taken, the reset moved Y's back
    // to the lost bus's last feedback: 0.21 mm in one period, 215 mm/s).
    let v = fastest(&m.samples[from..]);
    assert!(v <= MAX_VELOCITY, "{v} mm/s");
    let held = m.samples[from].axes;
    assert!(m.samples[from..].iter().all(|p| p.axes == held));
    let s = m.status();
    assert_eq!(s.state, MachineState::Fault, "{s:?}");
    assert!(!s.ready);
    assert!(
        m.faults.iter().all(|f| f.code == FaultCode::CommandRefused),
        "{:?}",
        m.faults
    );

    // The bus is back: the reset is taken, the set-points start where the load stands.
    m.handle_machine(|machine| machine.clear(InjectedFault::CommunicationLoss).unwrap());
    m.cycles(10);
    m.faults.clear();
    m.command(Command::Reset);
    assert!(m.until(0.2, |s| s.ready), "{:?}", m.status());
    let s = m.status();
    assert_eq!(s.state, MachineState::Idle);
    let load = m.handle_machine(|machine| {
        [0, 1].map(|j| machine.true_state(j).expect("the mill's joints").0)
    });
    for (j, (setpoint, load)) in s.joint_setpoints.iter().zip(load).enumerate() {
        assert!(
            (setpoint - load).abs() < 1e-3,
            "joint {j}: set-point {setpoint} load {load}"
        );
    }
    // Then a move runs within the limits to its end.
    let from = m.samples.len();
    m.command(Command::Mdi(rtcnc_kernel::FixedText::truncated(
        "G0 X10 Y10",
    )));
    assert!(m.until(2.0, |s| s.axes[0] == 10.0
        && s.axes[1] == 10.0
        && s.state == MachineState::Idle));
    let v = fastest(&m.samples[from..]);
    assert!(v <= MAX_VELOCITY * (1.0 + 1e-9), "{v} mm/s");
    assert!(m.faults.is_empty(), "{:?}", m.faults);
}
