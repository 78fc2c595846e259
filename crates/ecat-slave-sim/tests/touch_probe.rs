//! The simulated drive's CiA 402 touch probe 1 (0x60B8-0x60BB): the status bits through a
//! sequence of arm and disarm as CiA 402 defines them, and the position a drive latches at
//! a probe input's edge between two cycles and at its encoder's index, read back through
//! its PDOs as a master reads them.

use rtcnc_ecat_slave_sim::application::Application;
use rtcnc_ecat_slave_sim::drive::{CspDrive, DriveConfig};
use rtcnc_ecat_slave_sim::esc::AlState;
use rtcnc_ecat_slave_sim::touch_probe::{TouchProbe, Trigger, function as f, status as s};

#[test]
fn status_bits_follow_arm_and_disarm_as_cia402_defines_them() {
    let mut probe = TouchProbe::new(2_000);
    probe.command(0, 0);
    assert_eq!(probe.status(), 0);
    // Enable, first event only, probe input, positive edge: 0x0011.
    probe.command(f::ENABLE | f::POSITIVE_EDGE, 1_000);
    assert_eq!(probe.trigger(), Some(Trigger::Input));
    assert_eq!(probe.status(), s::ENABLED);
    // An edge before the arming cycle is not the probe's.
    probe.latch(true, 500, 7);
    probe.report(100_000);
    assert_eq!(probe.status(), 0x0001);
    // The first edge after it: reported 2 µs later, stored bit and toggle set.
    probe.latch(true, 1_500, 42);
    probe.report(3_499);
    assert_eq!(probe.status(), 0x0001);
    probe.report(3_500);
    assert_eq!(probe.status(), 0x0043);
    assert_eq!(probe.positive_value(), 42);
    // Single event: a second edge, and a negative edge not sampled, change nothing.
    probe.latch(true, 4_000, 43);
    probe.latch(false, 4_000, 5);
    probe.report(100_000);
    assert_eq!(probe.status(), 0x0043);
    assert_eq!(probe.positive_value(), 42);
    // Sampling off clears the stored bit; the toggle keeps its level.
    probe.command(f::ENABLE, 5_000);
    assert_eq!(probe.status(), 0x0041);
    // On again: armed afresh, the next edge stored, the toggle back to 0.
    probe.command(f::ENABLE | f::POSITIVE_EDGE, 6_000);
    probe.latch(true, 6_500, 44);
    probe.report(8_500);
    assert_eq!(probe.status(), 0x0003);
    assert_eq!(probe.positive_value(), 44);
    // Disabled: bits 0-2 cleared.
    probe.command(0, 9_000);
    assert_eq!(probe.status(), 0x0000);
    // Continuous on both edges (0x0033): every edge stored, each toggle once per value.
    probe.command(
        f::ENABLE | f::CONTINUOUS | f::POSITIVE_EDGE | f::NEGATIVE_EDGE,
        10_000,
    );
    probe.latch(true, 10_100, 1);
    probe.latch(false, 10_200, 2);
    probe.latch(true, 10_300, 3);
    probe.report(20_000);
    assert_eq!(probe.status(), 0x0087);
    assert_eq!((probe.positive_value(), probe.negative_value()), (3, 2));
    // The trigger field: 01 the zero impulse, 10 (0x60D0's source) not offered.
    probe.command(f::ENABLE | f::TRIGGER_INDEX | f::POSITIVE_EDGE, 30_000);
    assert_eq!(probe.trigger(), Some(Trigger::IndexPulse));
    probe.command(f::ENABLE | (0b10 << 2) | f::POSITIVE_EDGE, 31_000);
    assert_eq!(probe.trigger(), None);
}

const PERIOD_NS: u64 = 1_000_000;
/// 17-bit encoder on 5 mm: 26 214.4 increments per mm.
const COUNTS_PER_MM: f64 = 131_072.0 / 5.0;
const RX_LEN: usize = 8;
const TX_LEN: usize = 16;

/// A drive mapping controlword, target position and 0x60B8 out; statusword, position,
/// 0x60B9, 0x60BA and 0x60BB in; its index 0.3 mm from 0, its latency 1 ms.
fn drive() -> CspDrive {
    let mut config = DriveConfig::default();
    config.joint.index_offset = Some(0.3);
    config.touch_probe_latency_s = 0.001;
    let mut drive = CspDrive::new(&config).unwrap();
    let mut download = |index: u16, sub: u8, value: &[u8]| {
        drive
            .download(index, sub, value, AlState::PreOp)
            .unwrap_or_else(|code| panic!("{index:#06x}:{sub} aborted {code:#010x}"));
    };
    download(0x1600, 0, &[0]);
    for (sub, entry) in [0x6040_0010u32, 0x607A_0020, 0x60B8_0010]
        .into_iter()
        .enumerate()
    {
        download(0x1600, sub as u8 + 1, &entry.to_le_bytes());
    }
    download(0x1600, 0, &[3]);
    download(0x1A00, 0, &[0]);
    for (sub, entry) in [
        0x6041_0010u32,
        0x6064_0020,
        0x60B9_0010,
        0x60BA_0020,
        0x60BB_0020,
    ]
    .into_iter()
    .enumerate()
    {
        download(0x1A00, sub as u8 + 1, &entry.to_le_bytes());
    }
    download(0x1A00, 0, &[5]);
    download(0x6060, 0, &[8]);
    assert_eq!(drive.process_data_len(), (RX_LEN, TX_LEN));
    drive
}

/// What the master reads: 0x60B9, 0x60BA, 0x60BB.
fn probe_inputs(inputs: &[u8]) -> (u16, i32, i32) {
    (
        u16::from_le_bytes([inputs[6], inputs[7]]),
        i32::from_le_bytes(inputs[8..12].try_into().unwrap()),
        i32::from_le_bytes(inputs[12..16].try_into().unwrap()),
    )
}

struct Run {
    drive: CspDrive,
    now_ns: u64,
    target_mm: f64,
}

impl Run {
    /// One cycle at SYNC0: the outputs given, the inputs as the master would read them.
    fn cycle(&mut self, controlword: u16, touch_probe: u16) -> [u8; TX_LEN] {
        let target = (self.target_mm * COUNTS_PER_MM).round() as i32;
        let mut outputs = [0u8; RX_LEN];
        outputs[0..2].copy_from_slice(&controlword.to_le_bytes());
        outputs[2..6].copy_from_slice(&target.to_le_bytes());
        outputs[6..8].copy_from_slice(&touch_probe.to_le_bytes());
        let mut inputs = [0u8; TX_LEN];
        self.drive.begin_cycle(self.now_ns);
        self.drive.cycle(1e-3, Some(&outputs), &mut inputs);
        self.now_ns += PERIOD_NS;
        inputs
    }

    /// Enabled and standing at 0.
    fn enabled() -> Self {
        let mut run = Run {
            drive: drive(),
            now_ns: 5_000_000_000,
            target_mm: 0.0,
        };
        for controlword in [0x06, 0x07, 0x0F, 0x0F, 0x0F] {
            run.cycle(controlword, 0);
        }
        assert_eq!(
            run.drive.state(),
            rtcnc_fieldbus::Cia402State::OperationEnabled
        );
        run
    }
}

#[test]
fn the_drive_latches_the_position_at_the_probe_inputs_instant_between_two_cycles() {
    let mut run = Run::enabled();
    // Arm probe 1 on the input's rising edge, first event (0x0011), and move at 10 mm/s.
    let arm = f::ENABLE | f::POSITIVE_EDGE;
    for _ in 0..50 {
        run.target_mm += 0.01;
        run.cycle(0x0F, arm);
    }
    // The input closes a quarter of the way through the next cycle.
    let start = run.now_ns;
    let from = run.drive.true_position();
    run.target_mm += 0.01;
    let inputs = run.cycle(0x0F, arm);
    let to = run.drive.true_position();
    assert!(to - from > 0.005, "{from} {to}");
    run.drive.touch_probe_input(start + PERIOD_NS / 4, true);
    assert_eq!(probe_inputs(&inputs).0, s::ENABLED);
    // The load there (moving linearly within the cycle), in whole increments as the
    // encoder counts: floor(position × 131072 / 5).
    let expected = ((from + 0.25 * (to - from)) * COUNTS_PER_MM).floor() as i32;
    // Reported 1 ms after the edge: by the end of the cycle after, so in the inputs of the
    // cycle after that one.
    run.target_mm += 0.01;
    let next = run.cycle(0x0F, arm);
    assert_eq!(probe_inputs(&next).0, s::ENABLED);
    run.target_mm += 0.01;
    let reported = run.cycle(0x0F, arm);
    assert_eq!(probe_inputs(&reported), (0x0043, expected, 0));
    // The falling edge is not sampled, a second rising one not taken (first event only).
    run.drive
        .touch_probe_input(run.now_ns - PERIOD_NS / 2, false);
    run.drive
        .touch_probe_input(run.now_ns - PERIOD_NS / 2, true);
    for _ in 0..3 {
        run.cycle(0x0F, arm);
    }
    assert_eq!(probe_inputs(&run.cycle(0x0F, arm)), (0x0043, expected, 0));
    // Disarmed: bits 0-2 clear, the toggle stays, the value stays.
    assert_eq!(probe_inputs(&run.cycle(0x0F, 0)), (0x0043, expected, 0));
    assert_eq!(probe_inputs(&run.cycle(0x0F, 0)), (0x0040, expected, 0));
    // An edge while disarmed is not latched.
    run.drive
        .touch_probe_input(run.now_ns - PERIOD_NS / 2, true);
    for _ in 0..3 {
        run.cycle(0x0F, 0);
    }
    assert_eq!(probe_inputs(&run.cycle(0x0F, 0)), (0x0040, expected, 0));
}

#[test]
fn the_drive_latches_its_encoder_index_through_the_touch_probe() {
    let mut run = Run::enabled();
    // Enable, zero impulse, positive edge (0x0015); then move from 0 to 1 mm at 10 mm/s
    // over the index at 0.3 mm.
    let arm = f::ENABLE | f::TRIGGER_INDEX | f::POSITIVE_EDGE;
    let mut seen = None;
    for _ in 0..150 {
        run.target_mm = (run.target_mm + 0.01).min(1.0);
        let inputs = run.cycle(0x0F, arm);
        let (status, value, _) = probe_inputs(&inputs);
        if status & s::POSITIVE_STORED != 0 && seen.is_none() {
            seen = Some((status, value));
        }
    }
    // floor(0.3 × 26214.4) = floor(7864.32) = 7864 increments.
    assert_eq!(seen, Some((0x0043, 7864)));
}
