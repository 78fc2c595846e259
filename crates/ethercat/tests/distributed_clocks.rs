//! Distributed clocks on the simulated segment: the devices' clocks drift, the cyclic
//! FRMW keeps them on the reference clock, and the master reports its phase against SYNC0.

use crate::support;
use std::time::Duration;

use rtcnc_ecat_slave_sim::esc::{HOP_DELAY_NS, reg};
use rtcnc_fieldbus::Fieldbus;

fn difference_ns(memory: &[u8]) -> i64 {
    let raw = u32::from_le_bytes(
        memory[reg::DC_SYSTEM_TIME_DIFFERENCE..reg::DC_SYSTEM_TIME_DIFFERENCE + 4]
            .try_into()
            .unwrap(),
    );
    let magnitude = i64::from(raw & 0x7FFF_FFFF);
    if raw & 0x8000_0000 != 0 {
        magnitude
    } else {
        -magnitude
    }
}

#[test]
fn drifting_clocks_stay_on_the_reference_and_the_phase_error_shows_its_drift() {
    // Half the drives run 40 ppm fast, half 40 ppm slow: 80 ppm apart, 80 ns per 1 ms
    // cycle, 40 µs over the half second below if nothing corrected them.
    let segment = "[[slaves]]\nkind = \"csp_drive\"\ncount = 3\ndrift_ppm = 40.0\n\
                   [[slaves]]\nkind = \"csp_drive\"\ncount = 3\ndrift_ppm = -40.0\n";
    let mut bus = support::start(
        segment,
        &support::master_toml(6, false),
        Duration::from_millis(1),
    )
    .expect("bus starts");
    let mut phases = Vec::new();
    for _ in 0..500 {
        bus.cycle().expect("cycle");
        phases.push(bus.master.cycle_phase_error_ns().expect("DC"));
    }
    let segment = bus.segment.lock();
    for (position, slave) in segment.slaves().iter().enumerate().skip(1) {
        let difference = difference_ns(slave.memory());
        assert!(difference.abs() < 500, "device {position}: {difference} ns");
        // The master measured each device's delay from the reference: the segment's
        // model puts HOP_DELAY_NS between neighbours.
        let memory = slave.memory();
        let delay = u32::from_le_bytes(
            memory[reg::DC_SYSTEM_TIME_DELAY..reg::DC_SYSTEM_TIME_DELAY + 4]
                .try_into()
                .unwrap(),
        );
        assert_eq!(u64::from(delay), position as u64 * HOP_DELAY_NS);
    }
    drop(segment);
    // The reference clock (device 0) runs 40 ppm fast against the master's clock: the
    // master's send instant moves 40 ns earlier in the reference's cycle every cycle.
    let slope = (phases[499] - phases[100]) as f64 / 399.0;
    assert!((slope - 40.0).abs() < 2.0, "{slope} ns per cycle");
}

#[test]
fn a_cycle_that_follows_the_phase_error_stays_aligned() {
    let segment = "[[slaves]]\nkind = \"csp_drive\"\ncount = 2\ndrift_ppm = 40.0\n";
    let mut bus = support::start(
        segment,
        &support::master_toml(2, false),
        Duration::from_millis(1),
    )
    .expect("bus starts");
    let period = 1_000_000i64;
    let mut phase = 0i64;
    for _ in 0..2000 {
        // A periodic thread moving its next wake-up by a tenth of the error.
        let step = (period - phase / 10) as u64;
        bus.clock.advance(step);
        bus.master
            .exchange(1e-3, &bus.outputs, &mut bus.inputs)
            .expect("cycle");
        phase = bus.master.cycle_phase_error_ns().expect("DC");
    }
    // A proportional correction settles where it makes up the drift: 10 × 40 ns.
    assert!((phase - 400).abs() < 50, "{phase} ns");
}
