//! Homing again after a homing stopped while its latch was armed (found by the kernel fuzz
//! target: fuzz/defects/kernel/homing-takes-a-stale-index-latch). Z's index latch stayed
//! armed after the abort; a jog down then passed the index pulse at raw 5 mm, the drive
//! latched it, and the next homing took that old latch as soon as it armed again: Z's
//! set-point jumped 5 mm in one period and the machine frame stood 5 mm off, Z's true
//! position -5 mm where the machine showed 0. The reference is a homing from power-on
//! (`modes.rs`): the index pulses lie at multiples of 5 mm of the raw position, Z's latched
//! one is declared 10, so once homed the raw frame agrees with the machine one.

use crate::common::*;

use rtcnc_kernel::{Command, MachineState, Urgent};

const Z: usize = 2;

/// Z's set-point velocity (mm/s) over the last period recorded.
fn z_velocity(m: &Machine) -> f64 {
    let n = m.samples.len();
    (m.samples[n - 1].axes[Z] - m.samples[n - 2].axes[Z]) / 1e-3
}

#[test]
fn a_homing_after_one_stopped_at_its_latch_takes_a_fresh_latch() {
    let cfg = config("sim-mill.toml");
    let mut m = Machine::new(&cfg, None);
    m.power_on();
    m.command(Command::HomeAll);
    // Z homes first: search up to the switch, back off down at the latch speed (1 mm/s),
    // then up again at it with the index latch armed. Stop it there.
    let (mut backed_off, mut latching) = (false, false);
    for _ in 0..20_000 {
        m.cycles(1);
        let v = z_velocity(&m);
        backed_off |= (v + 1.0).abs() < 1e-6;
        if backed_off && (v - 1.0).abs() < 1e-6 {
            latching = true;
            break;
        }
    }
    assert!(latching, "Z reached its latch move");
    assert!(m.sim.handle().urgent(Urgent::Abort));
    assert!(m.until(1.0, |s| s.state == MachineState::Idle));
    // Down across the index pulse at raw 5 mm.
    m.command(Command::JogIncrement {
        axis: Z as u8,
        distance: -4.0,
    });
    m.cycles(5);
    assert!(m.until(10.0, |s| s.state == MachineState::Idle));
    m.command(Command::HomeAll);
    m.cycles(5);
    assert!(m.until(120.0, |s| s.state == MachineState::Idle));
    assert_eq!(m.status().homed, 0b111);
    assert_eq!(&m.status().axes[..3], &[0.0, 0.0, 0.0]);
    m.handle_machine(|machine| {
        for j in 0..3 {
            let (x, _) = machine.true_state(j).unwrap();
            assert!(x.abs() < 1e-3, "joint {j} at {x}");
        }
    });
    // Z never jumped: its set-point moved at most its top speed in any period.
    for w in m.samples.windows(2) {
        let v = (w[1].axes[Z] - w[0].axes[Z]).abs() / 1e-3;
        assert!(v <= 50.0 + 1e-6, "Z at {v} mm/s");
    }
    assert!(m.faults.is_empty(), "{:?}", m.faults);
}
