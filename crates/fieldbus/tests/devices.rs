//! The devices on the simulated machine's digital I/O, with the exact exchange of every
//! edge worked out from their timing. Exchange k (counted from 1) applies the outputs it is
//! given from time (k − 1)·T and reports the inputs at time k·T; a device's timer counts
//! whole periods, so a delay d seen from an output first given in exchange k ends in
//! exchange k − 1 + ⌈d / T⌉ (k itself for d = 0).

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use rtcnc_fieldbus::sim::{InjectedFault, SimulatedMachine, SimulatedMachineConfig};
use rtcnc_fieldbus::{Fieldbus, LatchSource, ProcessInputs, ProcessOutputs};

struct CountingAllocator;

thread_local! {
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|count| count.set(count.get() + 1));
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

/// The devices of the simulated mill (configs/sim-mill.toml), at a 1 ms period.
const MILL_DEVICES: &str = r#"
joints = []
[io]
digital_inputs = 32
digital_outputs = 16
[[devices]]
kind = "estop_contact"
input = 0
[[devices]]
kind = "door"
closed_input = 1
lock_output = 6
[[devices]]
kind = "delayed_input"
output = 5
input = 2
rise_delay_s = 0.5
fall_delay_s = 0.2
[[devices]]
kind = "delayed_input"
output = 7
input = 3
invert = true
rise_delay_s = 0.3
[[devices]]
kind = "delayed_input"
output = 7
input = 4
rise_delay_s = 0.3
[[devices]]
kind = "carousel"
motor_output = 8
in_position_input = 5
pocket_inputs = [16, 17, 18, 19]
pockets = 12
index_time_s = 0.2
in_position_s = 0.05
"#;

const ESTOP_OK: usize = 0;
const DOOR_CLOSED: usize = 1;
const PRESSURE: usize = 2;
const CLAMPED: usize = 3;
const UNCLAMPED: usize = 4;
const IN_POSITION: usize = 5;
const DOOR_LOCK: usize = 6;
const PUMP: usize = 5;
const UNCLAMP_VALVE: usize = 7;
const CAROUSEL_MOTOR: usize = 8;

struct Bench {
    machine: SimulatedMachine,
    outputs: ProcessOutputs,
    inputs: ProcessInputs,
    period_s: f64,
    /// Exchanges done.
    k: u64,
}

impl Bench {
    fn new(text: &str, period_s: f64) -> Self {
        let config: SimulatedMachineConfig = toml::from_str(text).unwrap();
        let machine = SimulatedMachine::new(&config).unwrap();
        Self {
            outputs: ProcessOutputs::new(machine.layout()),
            inputs: ProcessInputs::new(machine.layout()),
            machine,
            period_s,
            k: 0,
        }
    }
    fn mill() -> Self {
        Self::new(MILL_DEVICES, 0.001)
    }
    /// One exchange; returns its number.
    fn exchange(&mut self) -> u64 {
        self.machine
            .exchange(self.period_s, &self.outputs, &mut self.inputs)
            .unwrap();
        self.k += 1;
        self.k
    }
    fn input(&self, i: usize) -> bool {
        self.inputs.digital[i]
    }
    fn pocket_code(&self) -> u32 {
        (16..20).map(|i| u32::from(self.input(i)) << (i - 16)).sum()
    }
    /// Runs until `input` reads `level`; returns the exchange it first did.
    fn until(&mut self, input: usize, level: bool, limit: u64) -> u64 {
        for _ in 0..limit {
            let k = self.exchange();
            if self.input(input) == level {
                return k;
            }
        }
        panic!("input {input} did not become {level} within {limit} exchanges");
    }
}

#[test]
fn a_pressure_switch_rises_its_delay_after_the_pump_starts_and_falls_after_the_fall_delay() {
    let mut b = Bench::mill();
    b.exchange();
    assert!(!b.input(PRESSURE));
    // The pump output is given in exchange 2 (it acts from 1 ms): the 0.5 s rise delay
    // ends at 501 ms, the end of exchange 2 − 1 + 500 = 501.
    b.outputs.digital[PUMP] = true;
    assert_eq!(b.until(PRESSURE, true, 1000), 501);
    b.exchange(); // 502
    assert!(b.input(PRESSURE));
    for _ in 502..1000 {
        b.exchange();
    }
    // Off from exchange 1001: the 0.2 s fall delay ends in exchange 1000 + 200 = 1200.
    b.outputs.digital[PUMP] = false;
    assert_eq!(b.until(PRESSURE, false, 1000), 1200);
}

#[test]
fn a_pump_pulse_shorter_than_the_rise_delay_never_reaches_the_switch() {
    let mut b = Bench::mill();
    b.outputs.digital[PUMP] = true;
    for _ in 0..499 {
        b.exchange();
        assert!(!b.input(PRESSURE));
    }
    b.outputs.digital[PUMP] = false;
    for _ in 0..2000 {
        b.exchange();
        assert!(!b.input(PRESSURE));
    }
}

#[test]
fn clamp_sensors_follow_the_unclamp_valve_after_their_delays() {
    let mut b = Bench::mill();
    b.exchange();
    // Valve off at power-up: clamped, not unclamped.
    assert!(b.input(CLAMPED) && !b.input(UNCLAMPED));
    // Valve on from exchange 2: "clamped" has no fall delay and drops in exchange 2;
    // "unclamped" rises after 0.3 s, in exchange 2 − 1 + 300 = 301.
    b.outputs.digital[UNCLAMP_VALVE] = true;
    b.exchange();
    assert!(!b.input(CLAMPED) && !b.input(UNCLAMPED));
    assert_eq!(b.until(UNCLAMPED, true, 1000), 301);
    assert!(!b.input(CLAMPED));
    // Valve off from exchange 302: "unclamped" drops at once, "clamped" rises in 601.
    b.outputs.digital[UNCLAMP_VALVE] = false;
    b.exchange();
    assert!(!b.input(UNCLAMPED) && !b.input(CLAMPED));
    assert_eq!(b.until(CLAMPED, true, 1000), 601);
}

#[test]
fn a_delay_that_is_not_a_whole_number_of_periods_ends_in_the_period_it_falls_in() {
    // T = 0.3 ms, rise delay 1 ms: ⌈1 / 0.3⌉ = 4 periods.
    let text = "joints = []\n[[devices]]\nkind = \"delayed_input\"\noutput = 0\ninput = 0\n\
                rise_delay_s = 0.001\n";
    let mut b = Bench::new(text, 0.0003);
    b.outputs.digital[0] = true;
    assert_eq!(b.until(0, true, 100), 4);
}

#[test]
fn the_door_is_closed_until_opened_and_a_locked_door_stays_closed() {
    let mut b = Bench::mill();
    b.exchange();
    assert!(b.input(DOOR_CLOSED));
    assert_eq!(b.machine.door_closed(), Some(true));
    // Locked: pulling the door does nothing.
    b.outputs.digital[DOOR_LOCK] = true;
    b.machine.set_door_open(true).unwrap();
    for _ in 0..10 {
        b.exchange();
        assert!(b.input(DOOR_CLOSED));
    }
    // Unlocked in exchange 12: the operator still pulls, it opens in that exchange.
    b.outputs.digital[DOOR_LOCK] = false;
    assert_eq!(b.exchange(), 12);
    assert!(!b.input(DOOR_CLOSED));
    // The lock cannot engage on an open door.
    b.outputs.digital[DOOR_LOCK] = true;
    b.exchange();
    assert!(!b.input(DOOR_CLOSED));
    // Pushed shut: closed in the next exchange, and locked again.
    b.machine.set_door_open(false).unwrap();
    b.exchange();
    assert!(b.input(DOOR_CLOSED));
    b.machine.set_door_open(true).unwrap();
    b.exchange();
    assert!(b.input(DOOR_CLOSED));
}

#[test]
fn the_estop_contact_opens_with_the_button() {
    let mut b = Bench::mill();
    b.exchange();
    assert!(b.input(ESTOP_OK));
    b.machine.set_estop(true);
    b.exchange();
    assert!(!b.input(ESTOP_OK));
    assert!(b.inputs.estop_active);
    b.machine.set_estop(false);
    b.exchange();
    assert!(b.input(ESTOP_OK));
}

#[test]
fn the_carousel_indexes_one_pocket_per_index_time_with_a_dwell_in_position() {
    let mut b = Bench::mill();
    b.exchange();
    assert!(b.input(IN_POSITION));
    assert_eq!(b.pocket_code(), 1);
    // Motor on from exchange 2 (phase 0 at 1 ms): still in the dwell while the phase is
    // under 50 ms, i.e. through exchange 50; moving from exchange 51.
    b.outputs.digital[CAROUSEL_MOTOR] = true;
    assert_eq!(b.until(IN_POSITION, false, 1000), 51);
    assert_eq!(b.pocket_code(), 1);
    // At pocket 2 when the phase reaches 200 ms: exchange 201, in position.
    assert_eq!(b.until(IN_POSITION, true, 1000), 201);
    assert_eq!(b.pocket_code(), 2);
    assert_eq!(b.machine.carousel_pocket(), Some(2));
    // Eleven pockets on: pocket 12 in exchange 201 + 10·200 = 2201, then pocket 1 again.
    for _ in 201..2201 {
        b.exchange();
    }
    assert_eq!(b.pocket_code(), 12);
    assert!(b.input(IN_POSITION));
    for _ in 2201..2401 {
        b.exchange();
    }
    assert_eq!(b.pocket_code(), 1);
    // Stopped in the dwell it stays in position; stopped while moving it does not.
    b.outputs.digital[CAROUSEL_MOTOR] = false;
    for _ in 0..500 {
        b.exchange();
    }
    assert!(b.input(IN_POSITION));
    assert_eq!(b.pocket_code(), 1);
    b.outputs.digital[CAROUSEL_MOTOR] = true;
    for _ in 0..100 {
        b.exchange();
    }
    b.outputs.digital[CAROUSEL_MOTOR] = false;
    for _ in 0..500 {
        b.exchange();
    }
    assert!(!b.input(IN_POSITION));
    assert_eq!(b.pocket_code(), 1);
}

#[test]
fn a_stuck_sensor_reads_its_stuck_level_until_cleared() {
    let mut b = Bench::mill();
    let stuck = InjectedFault::StuckInput {
        input: UNCLAMPED,
        value: false,
    };
    b.machine.inject(stuck).unwrap();
    b.outputs.digital[UNCLAMP_VALVE] = true;
    for _ in 0..1000 {
        b.exchange();
        assert!(!b.input(UNCLAMPED));
    }
    assert_eq!(b.machine.digital_input(UNCLAMPED), Some(false));
    b.machine.clear(stuck).unwrap();
    b.exchange();
    assert!(b.input(UNCLAMPED));
    let error = b
        .machine
        .inject(InjectedFault::StuckInput {
            input: 32,
            value: true,
        })
        .unwrap_err();
    assert_eq!(error.code(), "fieldbus.sim.no_such_input");
}

#[test]
fn a_machine_without_a_door_refuses_to_open_one() {
    let config: SimulatedMachineConfig = toml::from_str("joints = []").unwrap();
    let mut machine = SimulatedMachine::new(&config).unwrap();
    let error = machine.set_door_open(true).unwrap_err();
    assert_eq!(error.code(), "fieldbus.sim.no_such_device");
    assert_eq!(machine.door_closed(), None);
}

fn refusal(extra: &str) -> String {
    let text = format!("joints = []\n{extra}");
    let config: SimulatedMachineConfig = toml::from_str(&text).unwrap();
    SimulatedMachine::new(&config).unwrap_err().to_string()
}

#[test]
fn bad_devices_are_refused_naming_the_field() {
    assert_eq!(
        refusal("[[devices]]\nkind = \"estop_contact\"\ninput = 16\n"),
        "devices[0]: digital input 16 is outside the 16 inputs"
    );
    assert_eq!(
        refusal(
            "[[devices]]\nkind = \"estop_contact\"\ninput = 3\n\
             [[devices]]\nkind = \"door\"\nclosed_input = 3\n"
        ),
        "devices[1]: digital input 3 is already driven by a device"
    );
    assert_eq!(
        refusal(
            "[[devices]]\nkind = \"delayed_input\"\noutput = 0\ninput = 0\nrise_delay_s = -1.0\n"
        ),
        "devices[0].rise_delay_s: must be a finite number of seconds from 0 to 3600"
    );
    assert_eq!(
        refusal(
            "[[devices]]\nkind = \"carousel\"\nmotor_output = 0\nin_position_input = 0\n\
             pocket_inputs = [1, 2, 3]\npockets = 8\nindex_time_s = 0.2\nin_position_s = 0.05\n"
        ),
        "devices[0].pocket_inputs: 3 bits cannot code pocket 8"
    );
    assert_eq!(
        refusal(
            "[[devices]]\nkind = \"carousel\"\nmotor_output = 0\nin_position_input = 0\n\
             pocket_inputs = [1, 2, 3, 4]\npockets = 8\nindex_time_s = 0.2\nin_position_s = 0.2\n"
        ),
        "devices[0].in_position_s: must be greater than zero and shorter than index_time_s"
    );
    let unknown: Result<SimulatedMachineConfig, _> =
        toml::from_str("joints = []\n[[devices]]\nkind = \"door\"\nclosed_input = 1\nlock = 2\n");
    assert!(unknown.is_err());
}

#[test]
fn devices_allocate_nothing_per_cycle() {
    let mut b = Bench::mill();
    b.machine
        .inject(InjectedFault::StuckInput {
            input: PRESSURE,
            value: true,
        })
        .unwrap();
    let before = ALLOCATIONS.with(Cell::get);
    for k in 0..3000 {
        b.outputs.digital[PUMP] = k % 700 < 600;
        b.outputs.digital[UNCLAMP_VALVE] = k % 900 < 400;
        b.outputs.digital[CAROUSEL_MOTOR] = k % 500 < 300;
        b.outputs.digital[DOOR_LOCK] = k % 300 < 100;
        b.machine.set_door_open(k % 200 < 50).unwrap();
        b.machine.set_estop(k % 1000 == 999);
        b.exchange();
    }
    assert_eq!(ALLOCATIONS.with(Cell::get) - before, 0);
}

#[test]
fn a_probe_input_is_on_while_its_joint_stands_at_or_beyond_the_surface() {
    // An ideal drive stands on its target at the end of each exchange: stepping the target
    // down by 0.1 from 0, the probe over a surface at -0.45 closes in the exchange that
    // reaches -0.5 (the first at or below it) and opens again on the way back up at -0.4.
    let config: SimulatedMachineConfig = toml::from_str(
        r#"
[[joints]]
drive = "ideal"
[[devices]]
kind = "probe"
input = 4
joint = 0
surface = -0.45
"#,
    )
    .unwrap();
    let mut machine = SimulatedMachine::new(&config).unwrap();
    let mut outputs = ProcessOutputs::new(machine.layout());
    let mut inputs = ProcessInputs::new(machine.layout());
    let mut seen = Vec::new();
    for k in (0..=10).chain((0..10).rev()) {
        outputs.joints[0].target_position = -0.1 * f64::from(k);
        // Walk the drive to operation enabled first (it ignores targets until then).
        for _ in 0..4 {
            outputs.joints[0].controlword = inputs.joints[0].state().controlword_towards(true);
            machine.exchange(0.001, &outputs, &mut inputs).unwrap();
        }
        seen.push((k, inputs.digital[4]));
    }
    let closed: Vec<i32> = seen.iter().filter(|s| s.1).map(|s| s.0).collect();
    assert_eq!(closed, [5, 6, 7, 8, 9, 10, 9, 8, 7, 6, 5]);
    // A probe on a joint that does not exist is refused, naming the field.
    let bad: SimulatedMachineConfig = toml::from_str(
        "joints = []\n[[devices]]\nkind = \"probe\"\ninput = 1\njoint = 0\nsurface = 0.0\n",
    )
    .unwrap();
    let err = SimulatedMachine::new(&bad).err().unwrap().to_string();
    assert!(err.contains("devices[0].joint"), "{err}");
}

#[test]
fn the_drives_latch_where_the_probe_trips_and_report_it_after_their_latency() {
    // Two ideal drives: joint 0 (the probe's) steps 0 → -1 in one 1 ms exchange across a
    // surface at -0.3, joint 1 steps 10 → 12 in the same exchange. Taken linearly within
    // the cycle, joint 0 crosses -0.3 at 30 % of it, where joint 1 stands at 10.6. The
    // drives armed for the rising edge latch those positions and report them 2.5 ms later:
    // in the third exchange after the edge's (latency rounded up to whole exchanges).
    let config: SimulatedMachineConfig = toml::from_str(
        r#"
touch_probe_latency_s = 0.0025
[[joints]]
drive = "ideal"
[[joints]]
drive = "ideal"
initial_position = 10.0
[[devices]]
kind = "probe"
input = 4
joint = 0
surface = -0.3
"#,
    )
    .unwrap();
    let mut machine = SimulatedMachine::new(&config).unwrap();
    let mut outputs = ProcessOutputs::new(machine.layout());
    let mut inputs = ProcessInputs::new(machine.layout());
    outputs.joints[1].target_position = 10.0;
    for _ in 0..4 {
        for j in 0..2 {
            outputs.joints[j].controlword = inputs.joints[j].state().controlword_towards(true);
        }
        machine.exchange(0.001, &outputs, &mut inputs).unwrap();
    }
    for j in 0..2 {
        outputs.joints[j].latch = Some(LatchSource::TouchProbe { rising: true });
    }
    machine.exchange(0.001, &outputs, &mut inputs).unwrap();
    assert!(inputs.joints[0].latch.armed && !inputs.joints[0].latch.latched);
    outputs.joints[0].target_position = -1.0;
    outputs.joints[1].target_position = 12.0;
    machine.exchange(0.001, &outputs, &mut inputs).unwrap();
    assert!(inputs.digital[4], "the probe closed in this exchange");
    let mut reported = None;
    for k in 1..=5 {
        if inputs.joints[0].latch.latched {
            reported = Some(k - 1);
            break;
        }
        machine.exchange(0.001, &outputs, &mut inputs).unwrap();
    }
    assert_eq!(reported, Some(3));
    assert!((inputs.joints[0].latch.position + 0.3).abs() < 1e-12);
    assert!(inputs.joints[1].latch.latched);
    assert!((inputs.joints[1].latch.position - 10.6).abs() < 1e-12);
    // A drive armed for the other edge latches nothing on this one.
    let mut other = SimulatedMachine::new(&config).unwrap();
    let mut inputs = ProcessInputs::new(other.layout());
    outputs.joints[0].target_position = 0.0;
    outputs.joints[1].target_position = 10.0;
    outputs.joints[0].latch = Some(LatchSource::TouchProbe { rising: false });
    for _ in 0..5 {
        for j in 0..2 {
            outputs.joints[j].controlword = inputs.joints[j].state().controlword_towards(true);
        }
        other.exchange(0.001, &outputs, &mut inputs).unwrap();
    }
    outputs.joints[0].target_position = -1.0;
    for _ in 0..5 {
        other.exchange(0.001, &outputs, &mut inputs).unwrap();
    }
    assert!(inputs.digital[4]);
    assert!(!inputs.joints[0].latch.latched);
}
