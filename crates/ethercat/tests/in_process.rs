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
