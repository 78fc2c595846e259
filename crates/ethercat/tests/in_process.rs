//! The whole stack in one process: the master on ethercrab, simulated devices behind an
//! in-process link, on a virtual clock.

mod support;

use std::time::Duration;

use rtcnc_fieldbus::{Cia402State, Fieldbus};

#[test]
fn twelve_drives_and_a_dio_terminal_reach_op() {
    let mut bus = support::start(
        &support::segment_toml(12, true, 0.0),
        &support::master_toml(12, true),
        Duration::from_millis(1),
    )
    .expect("bus starts");
    for _ in 0..50 {
        bus.cycle().expect("cycle");
    }
    assert_eq!(bus.master.layout().joints.len(), 12);
    for joint in &bus.inputs.joints {
        assert_eq!(joint.state(), Cia402State::SwitchOnDisabled);
    }
}

#[test]
fn drives_enable_and_follow_a_ramp() {
    let mut bus = support::start(
        &support::segment_toml(12, true, 0.0),
        &support::master_toml(12, true),
        Duration::from_millis(1),
    )
    .expect("bus starts");
    let period = 1e-3;
    // Walk every drive to operation enabled, holding the position it stands at.
    for _ in 0..40 {
        for (command, feedback) in bus.outputs.joints.iter_mut().zip(&bus.inputs.joints) {
            command.controlword = feedback.state().controlword_towards(true);
            command.target_position = feedback.position;
        }
        bus.cycle().expect("cycle");
    }
    for joint in &bus.inputs.joints {
        assert_eq!(joint.state(), Cia402State::OperationEnabled);
    }
    let start: Vec<f64> = bus.inputs.joints.iter().map(|j| j.position).collect();
    let mut targets: Vec<Vec<f64>> = Vec::new();
    let mut truth: Vec<Vec<f64>> = Vec::new();
    let mut feedback: Vec<Vec<f64>> = Vec::new();
    for k in 0..600 {
        let t = k as f64 * period;
        let row: Vec<f64> = (0..12).map(|j| start[j] + (10.0 + j as f64) * t).collect();
        for (j, command) in bus.outputs.joints.iter_mut().enumerate() {
            command.controlword = rtcnc_fieldbus::ControlWord::enable_operation();
            command.target_position = row[j];
            command.velocity_offset = 10.0 + j as f64;
        }
        bus.cycle().expect("cycle");
        targets.push(row);
        truth.push((0..12).map(|j| bus.true_position(j)).collect());
        feedback.push(bus.inputs.joints.iter().map(|j| j.position).collect());
    }
    // The pipeline, by construction: the target of cycle k is taken at the next SYNC0 and
    // reached one period later (a CSP drive interpolates over the period; rtcnc-fieldbus'
    // drive follows a ramp exactly one period behind), so the load stands on it after
    // cycle k+1; the encoder is sampled at the SYNC0 before cycle k+2's frame.
    let count = 1.0 / support::COUNTS_PER_MM;
    let (mut worst_load, mut worst_feedback) = (0.0f64, 0.0f64);
    for k in 100..598 {
        for j in 0..12 {
            worst_load = worst_load.max((truth[k + 1][j] - targets[k][j]).abs());
            let encoder = (truth[k + 1][j] / count).floor() * count;
            worst_feedback = worst_feedback.max((feedback[k + 2][j] - encoder).abs());
        }
    }
    println!("largest |x(k+1) - target(k)| on the ramp: {worst_load:e} mm");
    assert!(worst_load < 1e-4, "{worst_load}");
    println!("largest feedback difference {worst_feedback:e}");
    assert!(worst_feedback < 1e-9, "{worst_feedback}");
}

/// Walks every drive to operation enabled where it stands.
fn enable(bus: &mut support::Bus) {
    for _ in 0..40 {
        for (command, feedback) in bus.outputs.joints.iter_mut().zip(&bus.inputs.joints) {
            command.controlword = feedback.state().controlword_towards(true);
            command.target_position = feedback.position;
        }
        bus.cycle().expect("cycle");
    }
}

#[test]
fn dio_terminal_feeds_the_digital_images() {
    let mut bus = support::start(
        &support::segment_toml(2, true, 0.0),
        &support::master_toml(2, true),
        Duration::from_millis(1),
    )
    .expect("bus starts");
    // SYNC0 starts 20 ms after the distributed clocks are set up.
    for _ in 0..30 {
        bus.cycle().expect("cycle");
    }
    bus.set_dio_inputs(2, 0b1010_0101);
    bus.outputs.digital[1] = true;
    bus.outputs.digital[6] = true;
    // The terminal samples its inputs and applies its outputs at SYNC0: each direction
    // takes at most two cycles.
    for _ in 0..2 {
        bus.cycle().expect("cycle");
    }
    let levels: Vec<bool> = (0..8).map(|bit| 0b1010_0101 & (1 << bit) != 0).collect();
    assert_eq!(bus.inputs.digital, levels);
    assert_eq!(bus.dio_outputs(2), 0b0100_0010);
}

#[test]
fn quick_stop_and_fault_reset_walk_the_drive_state_machine() {
    let mut bus = support::start(
        &support::segment_toml(1, false, 0.0),
        &support::master_toml(1, false),
        Duration::from_millis(1),
    )
    .expect("bus starts");
    enable(&mut bus);
    assert_eq!(bus.inputs.joints[0].state(), Cia402State::OperationEnabled);
    bus.outputs.joints[0].controlword = rtcnc_fieldbus::ControlWord::quick_stop();
    for _ in 0..4 {
        bus.cycle().expect("cycle");
    }
    assert_eq!(bus.inputs.joints[0].state(), Cia402State::QuickStopActive);
    bus.outputs.joints[0].controlword = rtcnc_fieldbus::ControlWord::disable_voltage();
    for _ in 0..4 {
        bus.cycle().expect("cycle");
    }
    assert_eq!(bus.inputs.joints[0].state(), Cia402State::SwitchOnDisabled);
}

#[test]
fn the_master_moves_to_the_cycle_thread() {
    // The kernel builds the bus, then runs its exchanges on the fieldbus thread.
    let bus = support::start(
        &support::segment_toml(2, false, 0.0),
        &support::master_toml(2, false),
        Duration::from_millis(1),
    )
    .expect("bus starts");
    let support::Bus {
        mut master,
        clock,
        outputs,
        mut inputs,
        ..
    } = bus;
    let cycles = std::thread::spawn(move || {
        (0..10)
            .map(|_| {
                clock.advance(1_000_000);
                master.exchange(1e-3, &outputs, &mut inputs)
            })
            .filter(Result::is_ok)
            .count()
    })
    .join()
    .expect("thread");
    assert_eq!(cycles, 10);
}

/// The home switch's edge is latched by the master at the cycle it shows in the inputs, with
/// the position sampled with it; an index-pulse latch stays unarmed (the default PDOs carry
/// no touch probe: tests/touch_probe.rs for the one that does).
#[test]
fn the_home_switch_edge_is_latched_and_the_index_is_not() {
    let segment = "[[slaves]]\nkind = \"csp_drive\"\n[slaves.drive.joint]\ndrive = \"csp\"\n\
                   home_switch = { from = 1.0, to = 5.0 }\n";
    let mut bus = support::start(
        segment,
        &support::master_toml(1, false),
        Duration::from_millis(1),
    )
    .expect("bus starts");
    enable(&mut bus);
    bus.outputs.joints[0].latch = Some(rtcnc_fieldbus::LatchSource::IndexPulse);
    bus.cycle().expect("cycle");
    assert!(!bus.inputs.joints[0].latch.armed);
    bus.outputs.joints[0].latch = Some(rtcnc_fieldbus::LatchSource::HomeSwitch);
    bus.cycle().expect("cycle");
    assert!(bus.inputs.joints[0].latch.armed);
    let start = bus.inputs.joints[0].position;
    let mut previous = start;
    let mut latched = None;
    for k in 1..400 {
        // 10 mm/s towards the switch at 1 mm.
        bus.outputs.joints[0].target_position = start + 0.01 * f64::from(k);
        bus.outputs.joints[0].velocity_offset = 10.0;
        bus.cycle().expect("cycle");
        let feedback = bus.inputs.joints[0];
        if feedback.latch.latched {
            latched = Some((previous, feedback.latch.position, feedback.position));
            break;
        }
        assert!(!feedback.home_switch, "the switch shows with the latch");
        previous = feedback.position;
    }
    let (before, at, now) = latched.expect("the switch edge is latched");
    // The latched position is the first sample on the switch: the one before lies short of
    // the edge, and it lies past it by at most one period's travel (10 µm).
    let count = 1.0 / support::COUNTS_PER_MM;
    assert_eq!(at, now);
    assert!(
        before < 1.0 && at >= 1.0 - count && at - 1.0 < 0.010 + count,
        "{before} {at}"
    );
    // It stays latched while the request stands.
    bus.cycle().expect("cycle");
    assert_eq!(bus.inputs.joints[0].latch.position, at);
    assert!(bus.inputs.joints[0].latch.latched);
}
