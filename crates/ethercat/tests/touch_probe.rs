//! The master's side of a drive's touch probe 1: the controller's latch request written as
//! 0x60B8 (CiA 402: bit 0 enable, bits 2-3 trigger, bit 4 positive edge, bit 5 negative)
//! only once 0x60B9 shows the probe off (so no stored bit of an earlier arming is taken),
//! and the latch taken from the stored bit and 0x60BA/0x60BB.

use rtcnc_ethercat::pdo::{DriveCodec, LatchUse, RxObject, TxObject, missing_touch_probe_object};
use rtcnc_fieldbus::{JointCommand, JointFeedback, LatchFeedback, LatchSource};

const COUNTS_PER_UNIT: f64 = 26214.4;

/// Outputs: controlword, target position, 0x60B8 (at byte 6). Inputs: statusword, position,
/// 0x60B9 (byte 6), 0x60BA (8), 0x60BB (12).
fn codec() -> DriveCodec {
    DriveCodec::new(
        &[
            RxObject::Controlword,
            RxObject::TargetPosition,
            RxObject::TouchProbeFunction,
        ],
        &[
            TxObject::Statusword,
            TxObject::PositionActual,
            TxObject::TouchProbeStatus,
            TxObject::TouchProbe1PositiveEdge,
            TxObject::TouchProbe1NegativeEdge,
        ],
        COUNTS_PER_UNIT,
        1.0,
    )
}

/// Writes the request; returns 0x60B8 as sent.
fn send(codec: &mut DriveCodec, latch: Option<LatchSource>) -> u16 {
    let command = JointCommand {
        latch,
        ..JointCommand::default()
    };
    let mut outputs = [0u8; 8];
    codec.encode(&command, &mut outputs);
    u16::from_le_bytes([outputs[6], outputs[7]])
}

/// Reads a status and the two values; returns the latch the controller sees.
fn receive(codec: &mut DriveCodec, status: u16, positive: i32, negative: i32) -> LatchFeedback {
    let mut inputs = [0u8; 16];
    inputs[6..8].copy_from_slice(&status.to_le_bytes());
    inputs[8..12].copy_from_slice(&positive.to_le_bytes());
    inputs[12..16].copy_from_slice(&negative.to_le_bytes());
    let mut feedback = JointFeedback::default();
    codec.decode(&inputs, 1e-3, &mut feedback);
    feedback.latch
}

const UNARMED: LatchFeedback = LatchFeedback {
    armed: false,
    latched: false,
    position: 0.0,
};
const ARMED: LatchFeedback = LatchFeedback {
    armed: true,
    latched: false,
    position: 0.0,
};

#[test]
fn a_latch_request_arms_the_touch_probe_after_seeing_it_off_and_takes_the_stored_value() {
    let mut c = codec();
    let rising = Some(LatchSource::TouchProbe { rising: true });
    // The drive still shows an earlier arming with a value stored: not taken, probe off.
    assert_eq!(send(&mut c, rising), 0);
    assert_eq!(receive(&mut c, 0x0043, 999, 0), UNARMED);
    assert_eq!(send(&mut c, rising), 0);
    // Off (bits 0-2 clear; the toggle is not looked at): now the function goes out.
    assert_eq!(receive(&mut c, 0x0040, 999, 0), UNARMED);
    assert_eq!(send(&mut c, rising), 0x0011);
    // Until the drive shows it enabled, the latch is not armed.
    assert_eq!(receive(&mut c, 0x0040, 999, 0), UNARMED);
    assert_eq!(send(&mut c, rising), 0x0011);
    assert_eq!(receive(&mut c, 0x0001, 999, 0), ARMED);
    // Stored: the position is 0x60BA's increments over counts_per_unit.
    assert_eq!(send(&mut c, rising), 0x0011);
    assert_eq!(
        receive(&mut c, 0x0043, -78644, 0),
        LatchFeedback {
            armed: false,
            latched: true,
            position: -78644.0 / COUNTS_PER_UNIT,
        }
    );
    // Held while the request stands.
    assert_eq!(send(&mut c, rising), 0x0011);
    assert!(receive(&mut c, 0x0043, 5, 0).latched);

    // The falling edge: off first (the positive value stored is not the negative one's).
    let falling = Some(LatchSource::TouchProbe { rising: false });
    assert_eq!(send(&mut c, falling), 0);
    assert_eq!(receive(&mut c, 0x0043, -78644, 0), UNARMED);
    assert_eq!(send(&mut c, falling), 0);
    assert_eq!(receive(&mut c, 0x0040, -78644, 0), UNARMED);
    assert_eq!(send(&mut c, falling), 0x0021);
    assert_eq!(receive(&mut c, 0x0041, -78644, 0), ARMED);
    assert_eq!(send(&mut c, falling), 0x0021);
    assert_eq!(
        receive(&mut c, 0x00C5, -78644, 1234),
        LatchFeedback {
            armed: false,
            latched: true,
            position: 1234.0 / COUNTS_PER_UNIT,
        }
    );

    // The index: enable, zero impulse, positive edge (0x0015).
    let index = Some(LatchSource::IndexPulse);
    assert_eq!(send(&mut c, index), 0);
    assert_eq!(receive(&mut c, 0x0000, 0, 0), UNARMED);
    assert_eq!(send(&mut c, index), 0x0015);
    assert_eq!(receive(&mut c, 0x0001, 0, 0), ARMED);
    assert_eq!(send(&mut c, index), 0x0015);
    assert_eq!(
        receive(&mut c, 0x0043, 7864, 0).position,
        7864.0 / COUNTS_PER_UNIT
    );

    // No request: the probe off.
    assert_eq!(send(&mut c, None), 0);
    assert_eq!(receive(&mut c, 0x0043, 7864, 0), UNARMED);
}

#[test]
fn without_the_objects_a_touch_probe_latch_stays_unarmed_and_is_named_missing() {
    let mut c = DriveCodec::new(
        &RxObject::CSP_DEFAULT,
        &TxObject::CSP_DEFAULT,
        COUNTS_PER_UNIT,
        1.0,
    );
    let command = JointCommand {
        latch: Some(LatchSource::IndexPulse),
        ..JointCommand::default()
    };
    let mut outputs = [0u8; 12];
    for _ in 0..3 {
        c.encode(&command, &mut outputs);
        let mut feedback = JointFeedback::default();
        c.decode(&[0u8; 16], 1e-3, &mut feedback);
        assert_eq!(feedback.latch, UNARMED);
    }
    assert_eq!(
        missing_touch_probe_object(
            &RxObject::CSP_DEFAULT,
            &TxObject::CSP_DEFAULT,
            LatchUse::IndexPulse
        ),
        Some("0x60B8 touch probe function (rx_pdo \"touch_probe_function\")")
    );
    let rx = [
        RxObject::Controlword,
        RxObject::TargetPosition,
        RxObject::TouchProbeFunction,
    ];
    let tx = [
        TxObject::Statusword,
        TxObject::PositionActual,
        TxObject::TouchProbeStatus,
        TxObject::TouchProbe1PositiveEdge,
    ];
    // The index needs no negative edge; the probe input (G38.4/G38.5) does.
    assert_eq!(
        missing_touch_probe_object(&rx, &tx, LatchUse::IndexPulse),
        None
    );
    assert_eq!(
        missing_touch_probe_object(&rx, &tx, LatchUse::ProbeInput),
        Some("0x60BB touch probe 1 negative edge (tx_pdo \"touch_probe_1_negative_edge\")")
    );
}

#[test]
fn a_simulated_probe_is_wired_to_a_drive_and_a_terminal_input_or_refused_by_key() {
    use rtcnc_ethercat::{EthercatConfig, SimulatedProbe, SimulationConfig, simulated_segment};
    let config: EthercatConfig = toml::from_str(
        r#"
interface = "sim0"
[[slaves]]
kind = "cia402"
name = "Z"
vendor_id = 0x00000E5C
product_code = 0x00000402
revision = 0x00010000
joint = 0
counts_per_unit = 26214.4
rx_pdo = ["controlword", "target_position", "touch_probe_function"]
tx_pdo = ["statusword", "position_actual", "touch_probe_status", "touch_probe_1_positive_edge"]
[[slaves]]
kind = "dio"
name = "IO"
vendor_id = 0x00000E5C
product_code = 0x00000808
revision = 0x00010000
inputs = 8
"#,
    )
    .unwrap();
    let joints = [toml::from_str("drive = \"csp\"").unwrap()];
    let simulation = |input: usize, joint: usize, surface: f64| SimulationConfig {
        probe: Some(SimulatedProbe {
            input,
            joint,
            surface,
            side: Default::default(),
            drives: None,
        }),
        ..SimulationConfig::default()
    };
    assert!(simulated_segment(&config, &joints, &simulation(12, 0, -3.0)).is_ok());
    for (bad, key) in [
        (simulation(7, 0, -3.0), "simulation.probe.input"),
        (simulation(12, 1, -3.0), "simulation.probe.joint"),
        (simulation(12, 0, f64::NAN), "simulation.probe.surface"),
    ] {
        let error = simulated_segment(&config, &joints, &bad).unwrap_err();
        assert_eq!(error.key, key, "{error}");
    }
}
