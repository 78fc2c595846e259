//! From start-up to the owner's cycle: the bus never goes without process data longer
//! than the devices' sync manager watchdog (100 ms, the simulator's default) while the
//! owner (the kernel) is being assembled, and once the owner cycles, a stalled owner is
//! left to the watchdog as on any master.
//!
//! These run the segment on the monotonic clock (real time): the gap between start-up and
//! the first exchange is a real sleep, as the kernel's assembly is. The assertions are on
//! the devices' AL states and the master's errors, never on durations.

use crate::support;
use std::sync::Arc;
use std::time::Duration;

use rtcnc_ecat_slave_sim::esc::{AlState, al_code};
use rtcnc_ecat_slave_sim::{Segment, SegmentConfig};
use rtcnc_ethercat::{Clock, EthercatConfig, EthercatMaster, SimulatedLink};
use rtcnc_fieldbus::{Fieldbus, FieldbusError, ProcessInputs, ProcessOutputs};
use rtcnc_rt::PiMutex;

/// The simulator's default sync manager watchdog.
const WATCHDOG: Duration = Duration::from_millis(100);

fn start_in_real_time(drives: usize) -> (EthercatMaster, Arc<PiMutex<Segment>>) {
    let segment: SegmentConfig =
        toml::from_str(&support::segment_toml(drives, true, 0.0)).expect("segment TOML");
    let segment = Arc::new(PiMutex::new(segment.build().expect("segment")));
    let config: EthercatConfig =
        toml::from_str(&support::master_toml(drives, true)).expect("master TOML");
    let link = SimulatedLink::new(Arc::clone(&segment), Clock::Monotonic);
    let master = EthercatMaster::start_with_link(
        &config,
        Duration::from_millis(1),
        Box::new(link),
        Clock::Monotonic,
    )
    .expect("bus starts");
    (master, segment)
}

fn states(segment: &PiMutex<Segment>) -> Vec<(AlState, bool, u16)> {
    segment
        .lock()
        .slaves()
        .iter()
        .map(|s| s.al_status())
        .collect()
}

#[test]
fn devices_stay_in_op_through_a_long_gap_before_the_first_exchange() {
    let (mut master, segment) = start_in_real_time(3);
    let mut outputs = ProcessOutputs::new(master.layout());
    let mut inputs = ProcessInputs::new(master.layout());
    // The owner is busy elsewhere (the kernel assembles its tasks, starts its threads) for
    // three watchdog periods after start-up, then makes one exchange (the kernel's
    // self-test) and is away as long again before its cycle starts.
    std::thread::sleep(3 * WATCHDOG);
    assert_eq!(master.exchange(1e-3, &outputs, &mut inputs), Ok(()));
    std::thread::sleep(3 * WATCHDOG);
    for _ in 0..50 {
        assert_eq!(master.exchange(1e-3, &outputs, &mut inputs), Ok(()));
        std::thread::sleep(Duration::from_millis(1));
    }
    for (position, state) in states(&segment).into_iter().enumerate() {
        assert_eq!(state, (AlState::Op, false, 0), "device {position}");
    }
    // The drives answer the owner's controlword once it has the bus.
    for command in &mut outputs.joints {
        command.controlword = rtcnc_fieldbus::ControlWord::shutdown();
    }
    for _ in 0..20 {
        assert_eq!(master.exchange(1e-3, &outputs, &mut inputs), Ok(()));
        std::thread::sleep(Duration::from_millis(1));
    }
    for feedback in &inputs.joints {
        assert_eq!(
            feedback.state(),
            rtcnc_fieldbus::Cia402State::ReadyToSwitchOn
        );
    }
}

#[test]
fn a_stalled_owner_is_left_to_the_watchdog_once_it_has_cycled() {
    let (mut master, segment) = start_in_real_time(2);
    let outputs = ProcessOutputs::new(master.layout());
    let mut inputs = ProcessInputs::new(master.layout());
    for _ in 0..20 {
        assert_eq!(master.exchange(1e-3, &outputs, &mut inputs), Ok(()));
        std::thread::sleep(Duration::from_millis(1));
    }
    // The owner cycled, then stopped: nobody sends its outputs, the devices' watchdogs
    // expire, and the next exchange reports the first device out of OP.
    std::thread::sleep(3 * WATCHDOG);
    match master.exchange(1e-3, &outputs, &mut inputs) {
        Err(FieldbusError::DeviceState {
            position: 0,
            state: "SAFE-OP",
            code,
            ..
        }) => assert_eq!(code, al_code::SM_WATCHDOG),
        other => panic!("{other:?}"),
    }
    for state in states(&segment) {
        assert_eq!(state, (AlState::SafeOp, true, al_code::SM_WATCHDOG));
    }
}
