//! The kernel on EtherCAT: configs/ethercat-sim-12.toml, the seeds' 12-drive gantry with
//! every joint a CiA 402 CSP drive on simulated EtherCAT devices in the process, against
//! the same gantry on the simulated machine (configs/sim-gantry-12.toml): the same
//! set-points, the loads at the same places, the bus's latency in the following error as
//! its closed form says, the kernel's cycle following the devices' distributed clock, the
//! drives' CiA 402 state machine walked by enable, fault and reset, and each bus fault
//! named.

use crate::common::*;

use rtcnc_ecat_slave_sim::Fault as SegmentFault;
use rtcnc_fieldbus::{Fieldbus, FieldbusError, ProcessInputs, ProcessLayout, ProcessOutputs};
use rtcnc_kernel::{Command, FaultCode, Kernel, MachineState};

const GANTRY: &str = "examples/gantry-12.ngc";

fn gantry(config_name: &str) -> Machine {
    let mut m = Machine::new(&config(config_name), Some(repo().join(GANTRY)));
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    assert!(
        m.until(20.0, |s| s.program_ended),
        "{config_name}: the program ends"
    );
    m
}

/// Each joint's load, where it stands.
fn loads(m: &Machine) -> Vec<f64> {
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
        .collect()
}

#[test]
fn the_gantry_runs_on_ethercat_drives_as_on_the_simulated_machine() {
    let reference = gantry("sim-gantry-12.toml");
    let bus = gantry("ethercat-sim-12.toml");
    assert!(reference.faults.is_empty(), "{:?}", reference.faults);
    assert!(bus.faults.is_empty(), "{:?}", bus.faults);
    // The same set-points, cycle by cycle, from the first move on.
    let moving = |m: &Machine| -> Vec<[f64; 12]> {
        m.samples
            .iter()
            .skip_while(|s| s.path_speed == 0.0)
            .map(|s| {
                let mut joints = [0.0; 12];
                joints.copy_from_slice(&s.setpoint[..12]);
                joints
            })
            .collect()
    };
    let (a, b) = (moving(&reference), moving(&bus));
    assert!(a.len() > 8000, "{}", a.len());
    let n = a.len().min(b.len());
    assert!(a.len().abs_diff(b.len()) <= 2, "{} {}", a.len(), b.len());
    for k in 0..n {
        for j in 0..12 {
            assert!((a[k][j] - b[k][j]).abs() < 1e-9, "cycle {k} joint {j}");
        }
    }
    // The loads end where the simulated machine's do (X1 and Y2 stay racked as they
    // started), to an encoder increment.
    let count = 5.0 / 131072.0;
    for (j, (x, y)) in loads(&reference).iter().zip(loads(&bus)).enumerate() {
        assert!((x - y).abs() <= count, "joint {j}: {x} {y}");
    }
    // At 100 mm/s the following error is the travel of the latency the machine file does
    // not declare: on EtherCAT three periods (the drive reaches each target by the end of
    // its period, the target is applied at the next SYNC0, the position latched there
    // comes back one cycle later), 0.3 mm; the simulated machine declares its drives' one
    // period (`feedback_delay_periods = 1`), so what is left is tracking, under a
    // twentieth of a period's travel.
    let largest = |m: &Machine| {
        m.samples
            .iter()
            .map(|s| s.following_error[0].abs())
            .fold(0.0, f64::max)
    };
    let (one, three) = (largest(&reference), largest(&bus));
    assert!(one < 0.005, "{one}");
    assert!((three - 0.3).abs() < 1e-3, "{three}");
}

/// Homing on the home switches squares the gantry (X1 and Y2 start racked) as on the
/// simulated machine homing on the same switches: the master latches a switch's edge at
/// the cycle it shows in the inputs, with the position sampled with it, so each load ends
/// within a period's travel at the latch velocity (2 µm at 2 mm/s) of where the simulated
/// machine's exact edge puts it.
#[test]
fn homing_on_the_switches_squares_the_gantry_as_on_the_simulated_machine() {
    let home = |config: &rtcnc_kernel::MachineConfig| {
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
        assert_eq!(
            m.status().homed.count_ones(),
            12,
            "every joint (P0..P2 where they stand)"
        );
        m
    };
    let text = std::fs::read_to_string(repo().join("configs/sim-gantry-12.toml")).unwrap();
    let mut on_switches = rtcnc_kernel::MachineConfig::parse(
        &text.replace(
            "homing = { sequence",
            "homing = { use_index = false, sequence",
        ),
        "sim-gantry-12.toml",
    )
    .unwrap();
    on_switches.base_dir = repo().join("configs");
    let reference = home(&on_switches);
    let bus = home(&config("ethercat-sim-12.toml"));
    // A period at the latch velocity (2 mm/s × 1 ms), and an encoder increment.
    let step = 2.0 * 1e-3 + 5.0 / 131072.0;
    for (j, (x, y)) in loads(&reference).iter().zip(loads(&bus)).enumerate() {
        assert!((x - y).abs() <= step, "joint {j}: {x} {y}");
    }
    // Squared: the four X loads stand together, the four Y loads too.
    let at = loads(&bus);
    assert!(
        at[..4].iter().all(|x| (x - at[0]).abs() <= 2.0 * step),
        "{at:?}"
    );
    assert!(
        at[4..8].iter().all(|y| (y - at[4]).abs() <= 2.0 * step),
        "{at:?}"
    );
}

/// The devices' clocks run 20 ppm fast (`drift_ppm`): SYNC0 comes every 1 ms of theirs,
/// 999 980 ns of the executive's. The fieldbus thread, nudged by a tenth of the phase error
/// every cycle, settles on that period and stays in phase.
#[test]
fn the_kernel_cycle_follows_the_distributed_clock() {
    let mut m = Machine::new(&config("ethercat-sim-12.toml"), None);
    m.power_on();
    m.cycles(4000);
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    let times: Vec<u64> = m.samples.iter().map(|s| s.time_ns).collect();
    let last = &times[times.len() - 2001..];
    let mean = (last[2000] - last[0]) as f64 / 2000.0;
    let expected = 1e6 / (1.0 + 20e-6);
    assert!((mean - expected).abs() < 1.0, "{mean} ns, {expected} ns");
}

/// A bus of the caller's own that fails the way a master does: a wrong working counter
/// from a given exchange on.
struct FailingBus {
    inner: rtcnc_fieldbus::sim::SimulatedMachine,
    exchanges: u64,
    fail_from: u64,
}

impl Fieldbus for FailingBus {
    fn layout(&self) -> &ProcessLayout {
        self.inner.layout()
    }

    fn exchange(
        &mut self,
        period_s: f64,
        outputs: &ProcessOutputs,
        inputs: &mut ProcessInputs,
    ) -> Result<(), FieldbusError> {
        self.exchanges += 1;
        self.inner.exchange(period_s, outputs, inputs)?;
        if self.exchanges >= self.fail_from {
            return Err(FieldbusError::WorkingCounter {
                expected: 39,
                received: 36,
                consecutive: 3,
            });
        }
        Ok(())
    }
}

/// Each fieldbus error is its own kernel fault, named with the bus's words.
#[test]
fn a_working_counter_error_is_a_fault_named_with_the_counts() {
    let cfg = config("sim-mill.toml");
    let machine =
        rtcnc_fieldbus::sim::SimulatedMachine::new(&cfg.simulated_machine().unwrap()).unwrap();
    let bus = FailingBus {
        inner: machine,
        exchanges: 0,
        fail_from: 100,
    };
    let kernel =
        Kernel::build_with_bus(&cfg, rtcnc_kernel::KernelOptions::default(), bus).expect("builds");
    let mut sim = rtcnc_kernel::Simulation::new(kernel);
    sim.run_cycles(200, &mut |_| {}).unwrap();
    let faults = sim.handle().take_faults();
    assert_eq!(faults.len(), 1, "{faults:?}");
    assert_eq!(faults[0].code, FaultCode::WorkingCounter);
    assert_eq!(
        sim.handle().describe(&faults[0]).split(" at ").next(),
        Some("fieldbus working counter wrong [kernel.working_counter]")
    );
    assert!(
        sim.handle().describe(&faults[0]).ends_with(
            "(working counter 36): fieldbus working counter 36 instead of 39, 3 cycles in a row"
        ),
        "{}",
        sim.handle().describe(&faults[0])
    );
}

/// The drives' CiA 402 state machine is walked by the kernel: a reset enables every drive
/// (shutdown, switch on, enable operation), a drive fault disables the machine and names
/// the error code, and once its cause is gone a reset clears it (fault reset) and enables
/// the drives again.
#[test]
fn a_drive_fault_is_reset_through_the_cia402_state_machine() {
    let mut m = Machine::new(&config("ethercat-sim-12.toml"), None);
    m.power_on();
    assert!(m.status().ready);
    let bus = m.sim.handle().simulated_ethercat().unwrap().clone();
    let drive = bus.drive_position(4).unwrap();
    assert_eq!(drive, 4);
    bus.inject(SegmentFault::DriveFault {
        slave: drive,
        error_code: 0x7305,
    })
    .unwrap();
    m.cycles(20);
    assert_eq!(m.faults[0].code, FaultCode::DriveFault);
    let text = m.sim.handle().describe(&m.faults[0]);
    assert!(text.contains("joint Y0"), "{text}");
    assert!(text.contains("(error code 0x7305: "), "{text}");
    assert!(m.until(1.0, |s| s.state == MachineState::Fault));
    // With the cause still there, a reset does not enable the machine.
    m.command(Command::Reset);
    m.cycles(100);
    assert!(!m.status().ready);
    bus.clear(SegmentFault::DriveFault {
        slave: drive,
        error_code: 0,
    })
    .unwrap();
    m.command(Command::Reset);
    assert!(
        m.until(1.0, |s| s.ready),
        "enabled again after the fault reset"
    );
}

/// A device that falls out of OP stays out (the master does not take devices back to OP):
/// the fault names the device and its AL status code, and a reset is refused while the
/// exchange fails, so the machine stays faulted.
#[test]
fn a_device_out_of_op_keeps_the_machine_faulted() {
    let mut m = Machine::new(&config("ethercat-sim-12.toml"), None);
    m.power_on();
    let bus = m.sim.handle().simulated_ethercat().unwrap().clone();
    bus.inject(SegmentFault::FallToSafeOp {
        slave: 12,
        code: 0x001B,
    })
    .unwrap();
    m.cycles(5);
    assert_eq!(m.faults[0].code, FaultCode::DeviceState);
    let text = m.sim.handle().describe(&m.faults[0]);
    assert!(
        text.ends_with(
            "fieldbus device 12 (IO) is in SAFE-OP: AL status code 0x001b, sync manager watchdog"
        ),
        "{text}"
    );
    m.command(Command::Reset);
    m.cycles(100);
    assert!(!m.status().ready);
    assert_eq!(m.status().state, MachineState::Fault);
    assert_eq!(
        m.faults.iter().skip(1).map(|f| f.code).collect::<Vec<_>>(),
        [FaultCode::CommandRefused]
    );
}

/// The I/O terminal is the machine's digital I/O: a program's M64/M65 switch its outputs,
/// its inputs release an M66 wait, and its input 7 is the e-stop chain (normally closed):
/// opening it is the e-stop.
#[test]
fn the_io_terminal_is_the_machines_digital_io_and_carries_the_estop_chain() {
    let text = std::fs::read_to_string(repo().join("configs/ethercat-sim-12.toml"))
        .unwrap()
        .replacen(
            "analog_outputs = 0\n",
            "analog_outputs = 0\nprogram_outputs = [0, 1]\nprogram_inputs = [0, 1]\n",
            1,
        );
    let mut cfg = rtcnc_kernel::MachineConfig::parse(&text, "io.toml").unwrap();
    cfg.base_dir = repo().join("configs");
    let mut m = Machine::started(&cfg, "M64 P1\nM66 P0 L3 Q10\nM65 P1\nM2\n", "io.ngc");
    let bus = m.sim.handle().simulated_ethercat().unwrap().clone();
    let terminal = 12;
    m.cycles(50);
    assert_eq!(bus.terminal_outputs(terminal), Some(0b10), "M64 P1");
    assert!(!m.status().program_ended, "waits for input 0");
    // Input 0 on, the e-stop chain (input 7) still closed.
    assert!(bus.set_terminal_inputs(terminal, 0b1000_0001));
    assert!(m.until(1.0, |s| s.program_ended), "M66 released");
    // Through the next exchanges to the terminal's SYNC0.
    m.cycles(3);
    assert_eq!(bus.terminal_outputs(terminal), Some(0), "M65 P1");
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    // The e-stop chain opens.
    assert!(bus.set_terminal_inputs(terminal, 0b0000_0001));
    m.cycles(5);
    assert_eq!(m.faults[0].code, FaultCode::EStop);
    assert!(m.until(1.0, |s| s.state == MachineState::EStop));
}

/// Frames lost at 2 % from the start (`[fieldbus.simulation] frame_loss_rate`): fewer than
/// `working_counter_limit` in a row are ridden through on the last good inputs, checked as
/// they stood, so the gantry program runs to its end without a fault and its loads end
/// where they end without loss.
#[test]
fn lost_frames_below_the_limit_are_ridden_through() {
    let text = std::fs::read_to_string(repo().join("configs/ethercat-sim-12.toml"))
        .unwrap()
        .replacen(
            "drift_ppm = 20.0\n",
            "drift_ppm = 20.0\nframe_loss_rate = 0.02\nseed = 7\n",
            1,
        );
    let mut lossy = rtcnc_kernel::MachineConfig::parse(&text, "lossy.toml").unwrap();
    lossy.base_dir = repo().join("configs");
    let mut m = Machine::new(&lossy, Some(repo().join(GANTRY)));
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    assert!(m.until(20.0, |s| s.program_ended), "the program ends");
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    let (frames, lost) = m
        .sim
        .handle()
        .simulated_ethercat()
        .unwrap()
        .with(|segment| (segment.frames, segment.lost));
    let rate = lost as f64 / frames as f64;
    assert!((0.015..0.025).contains(&rate), "{lost} of {frames}");
    let clean = gantry("ethercat-sim-12.toml");
    let count = 5.0 / 131072.0;
    for (j, (x, y)) in loads(&clean).iter().zip(loads(&m)).enumerate() {
        assert!((x - y).abs() <= count, "joint {j}: {x} {y}");
    }
}
