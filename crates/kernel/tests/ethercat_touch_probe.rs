//! Latches over EtherCAT through the drives' CiA 402 touch probe 1 (0x60B8-0x60BB), on
//! configs/ethercat-sim-12.toml with every drive's PDOs carrying the objects: G38.x takes
//! the position the drives latched at the probe's edge (not the position of the period in
//! which the probe input is seen, up to a period's travel and the bus's latency late),
//! a G38.2 without contact stops the program as on the simulated machine, homing with
//! `use_index` lands on the encoder's index, and a drive that does not map the objects is
//! refused with its name and the object.

use crate::common::*;

use rtcnc_kernel::{Command, MachineConfig, MachineState, ProbeFailure};

/// The gantry's Z meets a surface at -3.00001 (in the joint's own position, unhomed: the
/// program's too), a probe on digital input 6 wired into every drive's touch probe input.
const SURFACE: f64 = -3.00001;

fn touch_probe_gantry(extra: impl Fn(String) -> String) -> MachineConfig {
    let text = std::fs::read_to_string(repo().join("configs/ethercat-sim-12.toml")).unwrap();
    let text = text
        .replace(
            "rated_torque_nm = 1.27\n",
            "rated_torque_nm = 1.27\n\
             rx_pdo = [\"controlword\", \"target_position\", \"velocity_offset\", \"torque_offset\", \"touch_probe_function\"]\n\
             tx_pdo = [\"statusword\", \"position_actual\", \"following_error_actual\", \"digital_inputs\", \"error_code\", \"touch_probe_status\", \"touch_probe_1_positive_edge\", \"touch_probe_1_negative_edge\"]\n",
        )
        .replace(
            "analog_outputs = 0\n",
            "analog_outputs = 0\nprobe_input = 6\n",
        )
        .replace(
            "drift_ppm = 20.0\n",
            &format!(
                "drift_ppm = 20.0\ntouch_probe_latency_s = 0.003\n\
                 [fieldbus.simulation.probe]\ninput = 6\njoint = 8\nsurface = {SURFACE}\n"
            ),
        );
    let mut cfg = MachineConfig::parse(&extra(text), "touch-probe.toml").unwrap();
    cfg.base_dir = repo().join("configs");
    cfg
}

#[test]
fn g38_takes_the_position_the_drives_latched_at_the_probes_edge() {
    let text = "G21 G90
G0 X1 Y2 Z0
G38.2 Z-10 F600
(DEBUG,down z #5063 ok #5070 x #5061 y #5062)
G38.4 Z0 F600
(DEBUG,up z #5063 ok #5070)
M2
";
    let (mut m, messages) = run_to_idle_with_messages(
        &touch_probe_gantry(|t| t),
        text,
        "ecat-probe-latch.ngc",
        60.0,
    );
    assert_eq!(messages.len(), 2, "{messages:?} {:?}", m.faults);
    // Half a second for the loads to settle after the last stop.
    m.cycles(500);
    // The kernel's machine position of a joint is its encoder's plus the offset it took at
    // power-up (the loads' standing error then); at rest the encoder is the load's true
    // position to an increment. So the surface is at SURFACE + that offset in the
    // program's coordinates, and X and Y, standing still, where their feedback says.
    let status = m.status();
    let ethercat = m.sim.handle().simulated_ethercat().unwrap();
    let offset = |j: usize| status.joint_feedback[j] - ethercat.true_state(j).unwrap().0;
    let surface = SURFACE + offset(8);
    // At F600 a period (1 ms) is 10 µm of travel, and the probe input reaches the kernel
    // through the I/O terminal a few periods after the edge: the drives' latch is on the
    // surface, to two encoder increments (the latch's and the offset's, 38 nm each) and
    // the 6 decimals DEBUG prints (0.5 nm): within 0.1 µm.
    let within = 2.0 * 5.0 / 131_072.0 + 5e-7;
    let down = message_number(&messages[0], "down z");
    assert!(
        (down - surface).abs() <= within,
        "{down} {surface} {messages:?}"
    );
    assert_eq!(message_number(&messages[0], "ok"), 1.0);
    // X and Y (their first joints, 0 and 4), latched by their own drives at the same
    // instant, where they stood.
    let x = message_number(&messages[0], "x");
    assert!(
        (x - status.joint_feedback[0]).abs() <= within,
        "{x} {:?}",
        status.joint_feedback
    );
    let y = message_number(&messages[0], "y");
    assert!(
        (y - status.joint_feedback[4]).abs() <= within,
        "{y} {:?}",
        status.joint_feedback
    );
    // Back up until the contact opens: the negative edge (0x60BB), on the surface again.
    let up = message_number(&messages[1], "up z");
    assert!((up - surface).abs() <= within, "{up} {surface}");
    assert_eq!(message_number(&messages[1], "ok"), 1.0);
    assert!(m.faults.is_empty(), "{:?}", m.faults);
}

#[test]
fn a_g38_2_without_contact_stops_the_program_as_on_the_simulated_machine() {
    let text = "G21 G90\nG0 Z0\nG38.2 Z-2.5 F600\nM2\n";
    let (m, _) = run_to_idle_with_messages(
        &touch_probe_gantry(|t| t),
        text,
        "ecat-probe-no-contact.ngc",
        60.0,
    );
    assert_probe_failed(
        &m,
        3,
        ProbeFailure::NoContact,
        "G38.2 move finished without making contact. [kernel.probe_failed]",
    );
    assert_eq!(m.status().axes[2], -2.5);
}

/// Homing X, Y and Z with `use_index`: each latches its encoder's index (every 5 mm from
/// 0 of the joint's own position) as `latch_position` (1005 for X and Y, 10 for Z), then
/// goes to 0. So a load ends where its machine 0 is, latch_position before an index: a
/// multiple of 5 minus 1005 (X, Y) or 10 (Z), to an encoder increment, as on the
/// simulated machine (sim-gantry-12.toml, which homes on the index).
#[test]
fn homing_with_the_index_lands_where_the_index_is() {
    let home = |config: &MachineConfig| {
        let mut m = Machine::new(config, None);
        m.power_on();
        m.command(Command::HomeAll);
        m.cycles(5);
        assert!(
            m.until(300.0, |s| s.state == MachineState::Idle),
            "homing ends"
        );
        m.cycles(10);
        assert!(m.faults.is_empty(), "{:?}", m.faults);
        assert_eq!(m.status().homed.count_ones(), 12);
        let handle = m.sim.handle();
        (0..12)
            .map(|j| match handle.simulated_machine() {
                Ok(machine) => machine.with(|machine| machine.true_state(j).unwrap().0),
                Err(_) => {
                    handle
                        .simulated_ethercat()
                        .unwrap()
                        .true_state(j)
                        .unwrap()
                        .0
                }
            })
            .collect::<Vec<f64>>()
    };
    let bus = home(&touch_probe_gantry(|t| {
        t.replace("use_index = false", "use_index = true")
    }));
    let increment = 5.0 / 131_072.0;
    for (j, at) in bus.iter().enumerate().take(9) {
        let latch_position = if j == 8 { 10.0 } else { 1005.0 };
        let index = at + latch_position;
        let off = index - (index / 5.0).round() * 5.0;
        assert!(off.abs() <= 2.0 * increment, "joint {j}: {at} ({off})");
    }
    let reference = home(&config("sim-gantry-12.toml"));
    for (j, (x, y)) in reference.iter().zip(&bus).enumerate() {
        assert!((x - y).abs() <= 2.0 * increment, "joint {j}: {x} {y}");
    }
}

#[test]
fn a_drive_without_the_touch_probe_objects_is_refused_for_probing_and_index_homing() {
    let text = std::fs::read_to_string(repo().join("configs/ethercat-sim-12.toml")).unwrap();
    let probing = text.replace(
        "analog_outputs = 0\n",
        "analog_outputs = 0\nprobe_input = 6\n",
    );
    let error = MachineConfig::parse(&probing, "probing.toml")
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("fieldbus.slaves[0]")
            && error.contains("drive X0 (joint 0) does not map 0x60B8 touch probe function"),
        "{error}"
    );
    let index = text.replacen("use_index = false", "use_index = true", 1);
    let error = MachineConfig::parse(&index, "index.toml")
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("fieldbus.slaves[0]")
            && error.contains("0x60B8")
            && error.contains("joints[0].homing.use_index"),
        "{error}"
    );
    // The function mapped, the status not: the status is named.
    let half = index.replacen(
        "rated_torque_nm = 1.27\n",
        "rated_torque_nm = 1.27\nrx_pdo = [\"controlword\", \"target_position\", \"touch_probe_function\"]\n",
        1,
    );
    let error = MachineConfig::parse(&half, "half.toml")
        .unwrap_err()
        .to_string();
    assert!(error.contains("0x60B9 touch probe status"), "{error}");
}
