//! The simulator as its own process on one end of a veth pair, the master (rtcnc-ethercat,
//! on a raw socket) on the other, inside an unprivileged network namespace: the whole
//! stack over a real kernel network path. Timing is whatever the machine gives, so
//! nothing here asserts a time; faults are expected within a number of cycles.

mod support;

use std::time::Duration;

use rtcnc_ecat_slave_sim::dio::DIO_PRODUCT_CODE;
use rtcnc_ecat_slave_sim::drive::{DRIVE_PRODUCT_CODE, SIMULATOR_VENDOR_ID};
use rtcnc_ethercat::clock::monotonic_ns;
use rtcnc_ethercat::{EthercatConfig, EthercatMaster};
use rtcnc_fieldbus::{
    Cia402State, ControlWord, Fieldbus, FieldbusError, ProcessInputs, ProcessOutputs,
};

const DRIVES: usize = 12;
const COUNTS_PER_MM: f64 = 131072.0 / 5.0;

fn master_config() -> EthercatConfig {
    // A loaded machine can hold a process off its core for long: the master waits up to
    // 0.9 ms for each reply, the devices 2 s for outputs before they leave OP.
    let mut text = format!(
        "interface = \"{}\"\nreply_timeout_us = 900\nsm_watchdog_ms = 2000\n",
        support::MASTER_END
    );
    for joint in 0..DRIVES {
        text.push_str(&format!(
            "[[slaves]]\nkind = \"cia402\"\nname = \"J{joint}\"\nvendor_id = {SIMULATOR_VENDOR_ID}\nproduct_code = {DRIVE_PRODUCT_CODE}\nrevision = 0x00010000\njoint = {joint}\ncounts_per_unit = {COUNTS_PER_MM:?}\n"
        ));
    }
    text.push_str(&format!(
        "[[slaves]]\nkind = \"dio\"\nname = \"IO\"\nvendor_id = {SIMULATOR_VENDOR_ID}\nproduct_code = {DIO_PRODUCT_CODE}\nrevision = 0x00010000\n"
    ));
    toml::from_str(&text).expect("master configuration")
}

struct Cycler {
    master: EthercatMaster,
    outputs: ProcessOutputs,
    inputs: ProcessInputs,
    period_ns: u64,
    next: u64,
}

impl Cycler {
    /// One cycle at the next period boundary, the wake-up moved by a tenth of the phase
    /// error against SYNC0.
    fn cycle(&mut self) -> Result<(), FieldbusError> {
        let correction = self.master.cycle_phase_error_ns().unwrap_or(0) / 10;
        let step = (self.period_ns as i64 - correction.clamp(-50_000, 50_000)) as u64;
        self.next += step;
        rtcnc_ethercat::Clock::Monotonic.sleep_until(self.next);
        self.master.exchange(
            self.period_ns as f64 * 1e-9,
            &self.outputs,
            &mut self.inputs,
        )
    }

    /// Cycles until `done` says so, at most `limit` cycles; returns the cycles taken.
    fn until(
        &mut self,
        limit: usize,
        mut done: impl FnMut(&Result<(), FieldbusError>, &ProcessInputs) -> bool,
    ) -> Option<usize> {
        (0..limit).find(|_| {
            let result = self.cycle();
            done(&result, &self.inputs)
        })
    }
}

#[test]
fn master_and_simulator_over_veth() {
    if support::inside() {
        return;
    }
    if let Some(reason) = support::namespaces_refused() {
        println!("skipped: {reason}");
        return;
    }
    assert!(support::run_inside("inside_the_namespace"));
}

#[test]
#[ignore = "runs inside the namespace that master_and_simulator_over_veth makes"]
fn inside_the_namespace() {
    assert!(support::inside(), "run by master_and_simulator_over_veth");
    support::veth();
    let mut simulator = support::Simulator::start(&format!(
        "[[slaves]]\nkind = \"csp_drive\"\ncount = {DRIVES}\n[[slaves]]\nkind = \"dio\"\n"
    ));
    let period = Duration::from_millis(1);
    let master = EthercatMaster::start(&master_config(), period).expect("bus starts over veth");
    let outputs = ProcessOutputs::new(master.layout());
    let inputs = ProcessInputs::new(master.layout());
    let mut bus = Cycler {
        master,
        outputs,
        inputs,
        period_ns: 1_000_000,
        next: monotonic_ns(),
    };

    // Enable every drive where it stands, then a ramp of 10 mm/s for 1.5 s.
    for _ in 0..100 {
        for (command, feedback) in bus.outputs.joints.iter_mut().zip(&bus.inputs.joints) {
            command.controlword = feedback.state().controlword_towards(true);
            command.target_position = feedback.position;
        }
        let _ = bus.cycle();
    }
    for joint in &bus.inputs.joints {
        assert_eq!(joint.state(), Cia402State::OperationEnabled);
    }
    let start: Vec<f64> = bus.inputs.joints.iter().map(|j| j.position).collect();
    let cycles = 1500;
    let mut failed = 0;
    for k in 0..cycles {
        for (j, command) in bus.outputs.joints.iter_mut().enumerate() {
            command.controlword = ControlWord::enable_operation();
            command.target_position = start[j] + 10.0 * k as f64 * 1e-3;
            command.velocity_offset = 10.0;
        }
        if let Err(error) = bus.cycle() {
            if failed == 0 {
                println!("first failed cycle: {k}: {error}");
            }
            failed += 1;
        }
    }
    let stats = bus.master.statistics();
    println!(
        "over veth: {} cycles, {} lost frames, {} working counter errors, last round trip {} µs",
        stats.cycles,
        stats.lost_frames,
        stats.working_counter_errors,
        stats.tx_rx.last_round_trip_ns / 1000
    );
    // Lateness is the machine's; a run where most cycles fail is not.
    assert!(failed < cycles / 20, "{failed} of {cycles} cycles failed");
    // Hold the end of the ramp: every drive comes to stand on it.
    for command in bus.outputs.joints.iter_mut() {
        command.velocity_offset = 0.0;
    }
    for _ in 0..100 {
        let _ = bus.cycle();
    }
    let end = 10.0 * (cycles - 1) as f64 * 1e-3;
    for (j, joint) in bus.inputs.joints.iter().enumerate() {
        assert_eq!(joint.state(), Cia402State::OperationEnabled);
        assert!(
            (joint.position - (start[j] + end)).abs() < 2e-3,
            "joint {j} at {} for {}",
            joint.position,
            start[j] + end
        );
    }

    // A drive fault: the drive shows it, the bus goes on.
    assert_eq!(simulator.command("drive-fault 3 0x2310"), "ok");
    let seen = bus.until(50, |_, inputs| {
        inputs.joints[3].state() == Cia402State::Fault && inputs.joints[3].error_code == 0x2310
    });
    assert!(seen.is_some(), "drive 3 shows its fault");

    // Every frame lost: three in a row are a fault.
    assert_eq!(simulator.command("loss 1"), "ok");
    let lost = bus.until(10, |result, _| {
        *result == Err(FieldbusError::CommunicationLost)
    });
    assert!(lost.is_some_and(|k| k >= 2), "{lost:?}");
    assert_eq!(simulator.command("loss 0"), "ok");
    assert!(bus.until(20, |result, _| result.is_ok()).is_some());

    // A device falls to SAFE-OP.
    assert_eq!(simulator.command("safeop 5 0x001a"), "ok");
    let fell = bus.until(20, |result, _| {
        matches!(
            result,
            Err(FieldbusError::DeviceState {
                position: 5,
                code: 0x001A,
                ..
            })
        )
    });
    assert!(fell.is_some(), "device 5 left OP");

    // The cable is pulled.
    assert_eq!(simulator.command("link down"), "ok");
    let down = bus.until(50, |result, _| {
        *result == Err(FieldbusError::LinkDown { interface: "m0" })
    });
    assert!(down.is_some(), "link down seen");
}
