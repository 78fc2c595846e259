//! Faults injected in the simulated segment reach the master as named errors.

use crate::support;
use std::time::Duration;

use rtcnc_ecat_slave_sim::Fault;
use rtcnc_ethercat::StartError;
use rtcnc_fieldbus::cia402::error_code;
use rtcnc_fieldbus::{Cia402State, ControlWord, FieldbusError};

fn bus(drives: usize) -> support::Bus {
    support::start(
        &support::segment_toml(drives, true, 0.0),
        &support::master_toml(drives, true),
        Duration::from_millis(1),
    )
    .expect("bus starts")
}

#[test]
fn lost_frames_are_counted_and_three_in_a_row_are_a_fault() {
    let mut bus = bus(2);
    bus.segment
        .lock()
        .inject(Fault::FrameLoss { rate: 0.3 })
        .unwrap();
    let mut in_a_row = 0;
    let mut faults = 0;
    for _ in 0..2000 {
        let lost_before = bus.segment.lock().lost;
        let result = bus.cycle();
        let lost = bus.segment.lock().lost > lost_before;
        in_a_row = if lost { in_a_row + 1 } else { 0 };
        // The reference: the segment's own record of what it dropped.
        if in_a_row >= 3 {
            assert_eq!(result, Err(FieldbusError::CommunicationLost));
            faults += 1;
        } else {
            assert_eq!(result, Ok(()), "{in_a_row} lost in a row");
        }
    }
    assert!(faults > 0, "2000 cycles at 30 % loss have runs of three");
    assert_eq!(bus.master.statistics().lost_frames, bus.segment.lock().lost);
}

#[test]
fn a_device_falling_to_safe_op_is_named_with_its_al_status_code() {
    let mut bus = bus(6);
    bus.cycle().expect("cycle");
    bus.segment
        .lock()
        .inject(Fault::FallToSafeOp {
            slave: 4,
            code: 0x001A,
        })
        .unwrap();
    let error = bus.cycle().expect_err("a device left OP");
    assert_eq!(
        error,
        FieldbusError::DeviceState {
            position: 4,
            name: "J4",
            state: "SAFE-OP",
            code: 0x001A,
            reason: "synchronization error",
        }
    );
    assert_eq!(error.code(), "fieldbus.device_state");
}

#[test]
fn a_drive_fault_shows_its_error_code() {
    let mut bus = bus(4);
    for _ in 0..40 {
        for (command, feedback) in bus.outputs.joints.iter_mut().zip(&bus.inputs.joints) {
            command.controlword = feedback.state().controlword_towards(true);
            command.target_position = feedback.position;
        }
        bus.cycle().expect("cycle");
    }
    bus.segment
        .lock()
        .inject(Fault::DriveFault {
            slave: 2,
            error_code: 0x2310,
        })
        .unwrap();
    for _ in 0..5 {
        bus.cycle().expect("the bus itself is fine");
    }
    let drive = bus.inputs.joints[2];
    assert_eq!(drive.state(), Cia402State::Fault);
    assert_eq!(drive.error_code, 0x2310);
    assert_eq!(
        error_code::describe(drive.error_code),
        "continuous over-current"
    );
    for other in [0, 1, 3] {
        assert_eq!(
            bus.inputs.joints[other].state(),
            Cia402State::OperationEnabled
        );
    }
    // The cause gone, a fault reset (rising edge of bit 7) clears it.
    bus.segment
        .lock()
        .clear(Fault::DriveFault {
            slave: 2,
            error_code: 0x2310,
        })
        .unwrap();
    bus.outputs.joints[2].controlword = ControlWord::fault_reset();
    for _ in 0..4 {
        bus.cycle().expect("cycle");
    }
    assert_eq!(bus.inputs.joints[2].state(), Cia402State::SwitchOnDisabled);
    assert_eq!(bus.inputs.joints[2].error_code, 0);
}

#[test]
fn link_down_is_named_at_once() {
    let mut bus = bus(2);
    bus.cycle().expect("cycle");
    bus.segment.lock().inject(Fault::LinkDown).unwrap();
    assert_eq!(
        bus.cycle(),
        Err(FieldbusError::LinkDown {
            interface: "simulated"
        })
    );
}

#[test]
fn a_device_with_another_identity_is_refused_with_both() {
    let master = support::master_toml(3, false).replacen(
        "product_code = 1026\nrevision = 0x00010000\njoint = 1",
        "product_code = 1027\nrevision = 0x00010000\njoint = 1",
        1,
    );
    let error = support::start(
        &support::segment_toml(3, false, 0.0),
        &master,
        Duration::from_millis(1),
    )
    .expect_err("identity mismatch");
    let StartError::Identity {
        position,
        name,
        expected,
        found,
    } = &error
    else {
        panic!("{error}");
    };
    assert_eq!((*position, name.as_str()), (1, "J1"));
    assert_eq!(
        (expected.product_code, found.product_code),
        (0x0403, 0x0402)
    );
    assert!(error.to_string().contains("product 0x00000402"), "{error}");
}

#[test]
fn a_refused_state_change_names_the_device_and_its_al_status_code() {
    // An interpolation period of 2 ms against SYNC0 at 1 ms: the drive refuses SAFE-OP.
    let master = support::master_toml(2, false).replace(
        "working_counter_limit = 3",
        "working_counter_limit = 3\nstate_timeout_ms = 300",
    ) + "[[slaves.sdo]]\nindex = 0x60C2\nsub_index = 1\nvalue = 2\nbytes = 1\n";
    let error = support::start(
        &support::segment_toml(2, false, 0.0),
        &master,
        Duration::from_millis(1),
    )
    .expect_err("refused");
    assert_eq!(
        error,
        StartError::StateRefused {
            position: 1,
            name: "J1".into(),
            target: "SAFE-OP",
            state: "PRE-OP",
            code: 0x0036,
            reason: "DC SYNC0 cycle time",
        }
    );
}

#[test]
fn an_sdo_abort_is_named() {
    let master = support::master_toml(1, false)
        + "[[slaves.sdo]]\nindex = 0x5000\nsub_index = 0\nvalue = 1\nbytes = 2\n";
    let error = support::start(
        &support::segment_toml(1, false, 0.0),
        &master,
        Duration::from_millis(1),
    )
    .expect_err("refused");
    let StartError::Sdo {
        position,
        index,
        reason,
        ..
    } = &error
    else {
        panic!("{error}");
    };
    assert_eq!((*position, *index), (0, 0x5000));
    println!("{reason}");
}

/// An exchange with a period out of (0, 1] s or images of another shape than the bus's is
/// refused with the error every bus gives for it (`rtcnc_fieldbus::check_exchange`), and the
/// bus cycles on afterwards.
#[test]
fn bad_periods_and_images_are_refused_and_the_bus_cycles_on() {
    use rtcnc_fieldbus::{Fieldbus, ProcessInputs};
    let mut bus = bus(1);
    bus.cycle().expect("cycle");
    for period in [0.0, -1.0, f64::NAN, 2.0] {
        let error = bus
            .master
            .exchange(period, &bus.outputs, &mut bus.inputs)
            .unwrap_err();
        assert_eq!(error.code(), "fieldbus.invalid_period", "{period}");
    }
    let mut short = ProcessInputs::new(bus.master.layout());
    short.joints.clear();
    let error = bus
        .master
        .exchange(0.001, &bus.outputs, &mut short)
        .unwrap_err();
    assert_eq!(
        error,
        FieldbusError::ImageMismatch {
            image: "inputs",
            what: "joints",
            expected: 1,
            found: 0
        }
    );
    bus.cycle().expect("cycle after the refusals");
}
