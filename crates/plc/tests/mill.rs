//! The simulated mill's machine logic (examples/plc/mill.st) driven through its sequences
//! at the 4 ms scan of its CONFIGURATION. Scan numbers are worked out from the timer
//! presets in the program: a TON of PT started on scan k has Q on scan k + PT / 4 ms.

use std::sync::Arc;
use std::time::Duration;

use rtcnc_plc::{PlcConfig, Runtime, Signal, compile};

const MILL: &str = include_str!("../../../examples/plc/mill.st");
const MILL_TOML: &str = include_str!("../../../examples/plc/mill.toml");

// Input bits (byte 0).
const ESTOP_OK: u8 = 0;
const DOOR_CLOSED: u8 = 1;
const LUBE_PRESSURE: u8 = 2;
const TOOL_CLAMPED: u8 = 3;
const TOOL_UNCLAMPED: u8 = 4;
const CAROUSEL_IN_POS: u8 = 5;
// Output bits (byte 0, then byte 1).
const SAFETY_RELAY: u8 = 0;
const SPINDLE_FWD: u8 = 1;
const SPINDLE_REV: u8 = 2;
const MIST: u8 = 3;
const FLOOD: u8 = 4;
const LUBE_PUMP: u8 = 5;
const DOOR_LOCK: u8 = 6;
const UNCLAMP_VALVE: u8 = 7;
const CAROUSEL_MOTOR: u8 = 8;
const AIR_BLAST: u8 = 9;

struct Mill {
    rt: Runtime,
    scan: u64,
}

impl Mill {
    fn new() -> Mill {
        let program = compile(MILL, "mill.st").unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(program.tasks()[0].interval, Some(Duration::from_millis(4)));
        let mut rt = Runtime::new(Arc::new(program));
        let cfg: PlcConfig = toml::from_str(MILL_TOML).unwrap();
        rt.configure(&cfg).unwrap();
        let mut m = Mill { rt, scan: 0 };
        m.input(ESTOP_OK, true);
        m.input(DOOR_CLOSED, true);
        m.input(LUBE_PRESSURE, true);
        m.input(TOOL_CLAMPED, true);
        m
    }
    fn input(&mut self, bit: u8, v: bool) {
        let img = self.rt.input_image_mut();
        let (byte, b) = (bit as usize / 8, bit % 8);
        img[byte] = (img[byte] & !(1 << b)) | ((v as u8) << b);
    }
    fn pocket(&mut self, p: i16) {
        self.rt.input_image_mut()[2..4].copy_from_slice(&p.to_le_bytes());
    }
    fn out(&self, bit: u8) -> bool {
        let img = self.rt.output_image();
        img[bit as usize / 8] >> (bit % 8) & 1 != 0
    }
    fn speed_ref(&self) -> f32 {
        let b = &self.rt.output_image()[4..8];
        f32::from_le_bytes([b[0], b[1], b[2], b[3]])
    }
    /// Runs one scan; returns its number (1-based).
    fn step(&mut self) -> u64 {
        self.rt.scan(Duration::from_millis(4 * self.scan)).unwrap();
        self.scan += 1;
        self.scan
    }
    fn steps(&mut self, n: u64) {
        for _ in 0..n {
            self.step();
        }
    }
    fn sig(&self, s: Signal) -> bool {
        self.rt.signal_bool(s)
    }
    fn num(&self, s: Signal) -> f64 {
        self.rt.signal(s).unwrap()
    }
    fn set(&mut self, s: Signal, v: bool) {
        self.rt.set_signal_bool(s, v);
    }
    /// Resets the e-stop and switches the machine on.
    fn power_up(&mut self) {
        self.set(Signal::EstopReset, true);
        self.set(Signal::MachineOnRequest, true);
        self.step();
        self.set(Signal::EstopReset, false);
        self.step();
        assert!(self.sig(Signal::MachineOn));
    }
}

#[test]
fn mill_starts_in_estop_and_needs_a_reset() {
    let mut m = Mill::new();
    m.step();
    assert!(!m.sig(Signal::EstopChainOut));
    assert!(!m.out(SAFETY_RELAY));
    assert!(m.sig(Signal::FeedHoldRequest));
    // Reset edge closes the chain on the same scan.
    m.set(Signal::EstopReset, true);
    m.step();
    assert!(m.sig(Signal::EstopChainOut));
    assert!(m.out(SAFETY_RELAY));
    // Holding reset does not matter; pressing the button opens the chain at once.
    m.step();
    m.input(ESTOP_OK, false);
    m.step();
    assert!(!m.sig(Signal::EstopChainOut));
    assert!(!m.out(SAFETY_RELAY));
    // Releasing the button does not close the chain: a new reset edge is needed.
    m.input(ESTOP_OK, true);
    m.step();
    assert!(!m.sig(Signal::EstopChainOut));
    m.set(Signal::EstopReset, false);
    m.step();
    m.set(Signal::EstopReset, true);
    m.step();
    assert!(m.sig(Signal::EstopChainOut));
}

#[test]
fn reset_while_the_button_is_pressed_does_nothing() {
    let mut m = Mill::new();
    m.input(ESTOP_OK, false);
    m.set(Signal::EstopReset, true);
    m.step();
    assert!(!m.sig(Signal::EstopChainOut));
}

#[test]
fn machine_on_follows_the_request_only_with_the_chain_closed() {
    let mut m = Mill::new();
    m.set(Signal::MachineOnRequest, true);
    m.step();
    assert!(!m.sig(Signal::MachineOn));
    m.power_up();
    m.input(ESTOP_OK, false);
    m.step();
    assert!(!m.sig(Signal::MachineOn));
}

#[test]
fn spindle_reports_at_speed_after_200ms_within_tolerance() {
    let mut m = Mill::new();
    m.power_up();
    m.rt.set_signal(Signal::SpindleSpeedCommand, 1000.0);
    m.set(Signal::SpindleOn, true);
    m.step();
    assert!(m.out(SPINDLE_FWD) && !m.out(SPINDLE_REV));
    assert_eq!(m.speed_ref(), 1000.0);
    assert_eq!(m.num(Signal::SpindleSpeedOut), 1000.0);
    assert!(!m.sig(Signal::SpindleAtSpeed));
    // Feed is held while the spindle is on but not at speed.
    assert!(m.sig(Signal::FeedHoldRequest));
    // Still accelerating: 900 rpm is outside 2 % of 1000.
    m.rt.set_signal(Signal::SpindleSpeedActual, 900.0);
    m.steps(100);
    assert!(!m.sig(Signal::SpindleAtSpeed));
    // Within tolerance from scan k: at speed on scan k + 50 (200 ms / 4 ms).
    m.rt.set_signal(Signal::SpindleSpeedActual, 985.0);
    let k = m.step();
    for _ in 0..48 {
        m.step();
    }
    assert_eq!(m.scan, k + 48);
    assert!(!m.sig(Signal::SpindleAtSpeed));
    m.step();
    assert_eq!(m.scan, k + 49);
    assert!(!m.sig(Signal::SpindleAtSpeed));
    m.step();
    assert_eq!(m.scan, k + 50);
    assert!(m.sig(Signal::SpindleAtSpeed));
    assert!(!m.sig(Signal::FeedHoldRequest));
    // The door stays locked while the spindle runs.
    assert!(m.out(DOOR_LOCK));
}

#[test]
fn spindle_reverse_gives_a_negative_set_point() {
    let mut m = Mill::new();
    m.power_up();
    m.rt.set_signal(Signal::SpindleSpeedCommand, 500.0);
    m.set(Signal::SpindleOn, true);
    m.set(Signal::SpindleReverse, true);
    m.step();
    assert!(m.out(SPINDLE_REV) && !m.out(SPINDLE_FWD));
    assert_eq!(m.speed_ref(), -500.0);
}

#[test]
fn open_door_holds_feed_stops_spindle_and_flood_but_stays_locked_while_coasting() {
    let mut m = Mill::new();
    m.power_up();
    m.rt.set_signal(Signal::SpindleSpeedCommand, 1000.0);
    m.set(Signal::SpindleOn, true);
    m.set(Signal::CoolantFlood, true);
    m.set(Signal::CoolantMist, true);
    m.rt.set_signal(Signal::SpindleSpeedActual, 1000.0);
    m.steps(60);
    assert!(!m.sig(Signal::FeedHoldRequest));
    assert!(m.out(FLOOD) && m.out(MIST));
    m.input(DOOR_CLOSED, false);
    m.step();
    assert!(m.sig(Signal::FeedHoldRequest));
    assert!(!m.out(SPINDLE_FWD));
    assert!(!m.out(FLOOD));
    assert!(m.out(MIST));
    assert_eq!(m.speed_ref(), 0.0);
    // Coasting at 400 rpm: still locked; stopped: unlocked.
    m.rt.set_signal(Signal::SpindleSpeedActual, 400.0);
    m.step();
    assert!(m.out(DOOR_LOCK));
    m.rt.set_signal(Signal::SpindleSpeedActual, 0.0);
    m.step();
    assert!(!m.out(DOOR_LOCK));
}

#[test]
fn tool_change_sequence_and_handshake() {
    let mut m = Mill::new();
    m.power_up();
    m.rt.set_signal(Signal::ToolNumber, 3.0);
    m.set(Signal::ToolChangeRequest, true);
    m.step(); // IDLE -> UNCLAMP
    assert!(!m.out(UNCLAMP_VALVE));
    m.step();
    assert!(m.out(UNCLAMP_VALVE));
    // The spindle may not start during a change.
    assert!(
        !m.rt
            .read_name("Mill.spindle_enable")
            .map(|v| v == rtcnc_plc::Value::Bool(true))
            .unwrap()
    );
    m.input(TOOL_CLAMPED, false);
    m.input(TOOL_UNCLAMPED, true);
    m.step(); // -> ROTATE
    m.step();
    assert!(m.out(CAROUSEL_MOTOR));
    m.pocket(3);
    m.input(CAROUSEL_IN_POS, true);
    m.step(); // motor stops -> CLAMP
    assert!(!m.out(CAROUSEL_MOTOR));
    m.step();
    assert!(!m.out(UNCLAMP_VALVE));
    assert!(!m.sig(Signal::ToolChangeDone));
    m.input(TOOL_UNCLAMPED, false);
    m.input(TOOL_CLAMPED, true);
    m.step(); // -> DONE
    m.step();
    assert!(m.sig(Signal::ToolChangeDone));
    assert_eq!(
        m.rt.read_name("current_tool").unwrap(),
        rtcnc_plc::Value::Int(3)
    );
    // The kernel drops the request, the PLC drops done.
    m.set(Signal::ToolChangeRequest, false);
    m.step();
    assert!(!m.sig(Signal::ToolChangeDone));
    // Asking for the tool already in the spindle is acknowledged at once.
    m.set(Signal::ToolChangeRequest, true);
    m.step();
    assert!(m.sig(Signal::ToolChangeDone));
    assert!(!m.out(UNCLAMP_VALVE));
}

#[test]
fn tool_change_step_timeout_faults_after_3s() {
    let mut m = Mill::new();
    m.power_up();
    m.rt.set_signal(Signal::ToolNumber, 5.0);
    m.set(Signal::ToolChangeRequest, true);
    let a = m.step(); // IDLE -> UNCLAMP; the step timer runs from scan a + 1.
    // No "unclamped" feedback: TC_TIMEOUT = 3 s = 750 scans after scan a + 1.
    while m.scan < a + 750 {
        m.step();
    }
    assert!(!m.sig(Signal::MachineFault));
    assert!(m.out(UNCLAMP_VALVE));
    m.step();
    assert_eq!(m.scan, a + 751);
    assert!(m.sig(Signal::MachineFault));
    assert_eq!(m.num(Signal::MachineFaultCode), 2.0);
    assert!(!m.out(UNCLAMP_VALVE));
    assert!(m.sig(Signal::FeedHoldRequest));
    assert!(!m.sig(Signal::ToolChangeDone));
    // An e-stop reset clears the fault.
    m.set(Signal::ToolChangeRequest, false);
    m.set(Signal::EstopReset, true);
    m.step();
    assert!(!m.sig(Signal::MachineFault));
    assert_eq!(m.num(Signal::MachineFaultCode), 0.0);
}

#[test]
fn tool_number_out_of_range_faults() {
    let mut m = Mill::new();
    m.power_up();
    m.rt.set_signal(Signal::ToolNumber, 13.0);
    m.set(Signal::ToolChangeRequest, true);
    m.step();
    assert!(m.sig(Signal::MachineFault));
    assert_eq!(m.num(Signal::MachineFaultCode), 4.0);
}

#[test]
fn m100_air_blast_for_p_seconds_then_done() {
    let mut m = Mill::new();
    m.power_up();
    m.rt.set_signal(Signal::MCodeNumber, 100.0);
    m.rt.set_signal(Signal::MCodeP, 0.1);
    m.set(Signal::MCodeRequest, true);
    let k = m.step();
    assert!(m.out(AIR_BLAST));
    // P = 0.1 s = 25 scans: done on scan k + 25.
    while m.scan < k + 24 {
        m.step();
    }
    assert!(!m.sig(Signal::MCodeDone));
    assert!(m.out(AIR_BLAST));
    m.step();
    assert!(m.sig(Signal::MCodeDone));
    assert!(!m.out(AIR_BLAST));
    m.set(Signal::MCodeRequest, false);
    m.step();
    assert!(!m.sig(Signal::MCodeDone));
}

#[test]
fn other_user_m_codes_are_acknowledged_at_once() {
    let mut m = Mill::new();
    m.power_up();
    m.rt.set_signal(Signal::MCodeNumber, 150.0);
    m.set(Signal::MCodeRequest, true);
    m.step();
    assert!(m.sig(Signal::MCodeDone));
}

#[test]
fn lubrication_pulse_at_machine_on_and_pressure_fault() {
    let mut m = Mill::new();
    m.set(Signal::EstopReset, true);
    m.step();
    m.input(LUBE_PRESSURE, false);
    m.set(Signal::MachineOnRequest, true);
    let on = m.step();
    assert!(m.out(LUBE_PUMP));
    assert_eq!(
        m.rt.read_name("lube_cycles").unwrap(),
        rtcnc_plc::Value::UInt(1)
    );
    // No pressure for LUBE_CHECK_TIME = 2 s = 500 scans: fault on scan on + 500.
    while m.scan < on + 499 {
        m.step();
    }
    assert!(!m.sig(Signal::MachineFault));
    m.step();
    assert!(m.sig(Signal::MachineFault));
    assert_eq!(m.num(Signal::MachineFaultCode), 3.0);
}

#[test]
fn lubrication_pulse_lasts_5s_with_pressure() {
    let mut m = Mill::new();
    m.power_up();
    let on = m.scan - 1; // power_up switched the machine on in its first scan
    while m.scan < on + 1249 {
        m.step();
        assert!(m.out(LUBE_PUMP), "scan {}", m.scan);
    }
    // TP of 5 s started on scan `on`: Q falls on scan on + 1250.
    m.step();
    assert!(!m.out(LUBE_PUMP));
    assert!(!m.sig(Signal::MachineFault));
}

#[test]
fn a_tripped_limit_is_a_fault_until_clear_and_reset() {
    let mut m = Mill::new();
    m.power_up();
    m.rt.set_signal(Signal::LimitMax, 0b100 as f64); // joint 2 (Z) positive limit
    m.step();
    assert!(m.sig(Signal::MachineFault));
    assert_eq!(m.num(Signal::MachineFaultCode), 5.0);
    assert!(m.sig(Signal::FeedHoldRequest));
    // A reset while the limit is still tripped does not clear the fault.
    m.set(Signal::EstopReset, true);
    m.step();
    assert!(m.sig(Signal::MachineFault));
    m.set(Signal::EstopReset, false);
    m.step();
    m.rt.set_signal(Signal::LimitMax, 0.0);
    m.step();
    assert!(m.sig(Signal::MachineFault));
    m.set(Signal::EstopReset, true);
    m.step();
    assert!(!m.sig(Signal::MachineFault));
    assert_eq!(m.num(Signal::MachineFaultCode), 0.0);
}
