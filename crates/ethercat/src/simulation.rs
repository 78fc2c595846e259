//! Simulated devices for a master configuration: the segment of `rtcnc-ecat-slave-sim`
//! devices that a configuration lists, so that a machine configured for EtherCAT runs
//! without hardware (in the same process, on [`SimulatedLink`]).
//!
//! Each CiA 402 entry becomes a simulated CSP drive whose motor, encoder and switches are
//! the given simulated joint; each DIO entry an 8-in/8-out terminal. The devices keep the
//! simulator's own identities, so the master's identity check still compares the
//! configuration with what the devices' EEPROMs say.

use std::sync::Arc;
use std::time::Duration;

use rtcnc_ecat_slave_sim::config::SlaveConfig as SimulatedSlave;
use rtcnc_ecat_slave_sim::dio::DioConfig;
use rtcnc_ecat_slave_sim::drive::DriveConfig;
use rtcnc_ecat_slave_sim::segment::{ProbeInput, ProbeWire};
use rtcnc_ecat_slave_sim::{Segment, SegmentConfig};
use rtcnc_fieldbus::sim::{ProbeSide, SimulatedJointConfig};
use rtcnc_fieldbus::{
    DriveMode, Fieldbus, FieldbusError, ProcessInputs, ProcessLayout, ProcessOutputs,
};
use rtcnc_rt::PiMutex;
use serde::Deserialize;

use crate::clock::Clock;
use crate::config::{ConfigError, EthercatConfig, SlaveConfig};
use crate::link::SimulatedLink;
use crate::master::{EthercatMaster, StartError};
use crate::pdo::RxObject;

/// Where the simulated bus's clock starts (ns): far enough from 0 that no time before it
/// is ever needed.
const START_NS: u64 = 1_000_000_000;

/// The master on simulated devices in this process (a machine configured for EtherCAT
/// without hardware). The devices run in the caller's time: each cycle's
/// [`set_time_ns`](Fieldbus::set_time_ns) moves the bus's virtual clock to it (plus the
/// start-up's length), so a kernel on the virtual-time runner is deterministic and one on
/// the real-time runner runs its devices in real time. A cycle without it moves the clock
/// one period.
pub struct SimulatedBus {
    master: EthercatMaster,
    segment: Arc<PiMutex<Segment>>,
    clock: Clock,
    /// The bus's clock minus the caller's, fixed by the first `set_time_ns`.
    offset_ns: Option<u64>,
    /// `set_time_ns` was given for the coming exchange.
    timed: bool,
}

impl std::fmt::Debug for SimulatedBus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SimulatedBus")
            .field("master", &self.master)
            .finish_non_exhaustive()
    }
}

impl SimulatedBus {
    /// Builds the devices `config` lists (see [`simulated_segment`]) and starts the master
    /// on them, for a cycle of `period`: scan, identities, PDO mapping, distributed clocks,
    /// INIT to OP, all in virtual time.
    pub fn start(
        config: &EthercatConfig,
        joints: &[SimulatedJointConfig],
        simulation: &SimulationConfig,
        period: Duration,
    ) -> Result<Self, StartError> {
        let segment = Arc::new(PiMutex::new(simulated_segment(config, joints, simulation)?));
        let clock = Clock::new_virtual(START_NS);
        let link = SimulatedLink::new(Arc::clone(&segment), clock);
        let master = EthercatMaster::start_with_link(config, period, Box::new(link), clock)?;
        Ok(Self {
            master,
            segment,
            clock,
            offset_ns: None,
            timed: false,
        })
    }

    /// The simulated devices (to inject faults, read a load's true position).
    pub fn segment(&self) -> &Arc<PiMutex<Segment>> {
        &self.segment
    }

    /// The master.
    pub fn master(&self) -> &EthercatMaster {
        &self.master
    }
}

impl Fieldbus for SimulatedBus {
    fn layout(&self) -> &ProcessLayout {
        self.master.layout()
    }

    fn exchange(
        &mut self,
        period_s: f64,
        outputs: &ProcessOutputs,
        inputs: &mut ProcessInputs,
    ) -> Result<(), FieldbusError> {
        if !std::mem::take(&mut self.timed) && period_s.is_finite() && period_s > 0.0 {
            self.clock.advance((period_s.min(1.0) * 1e9) as u64);
        }
        self.master.exchange(period_s, outputs, inputs)
    }

    fn cycle_phase_error_ns(&self) -> Option<i64> {
        self.master.cycle_phase_error_ns()
    }

    fn inputs_fresh(&self) -> bool {
        self.master.inputs_fresh()
    }

    fn set_time_ns(&mut self, now_ns: u64) {
        let clock = self.clock;
        let offset = *self
            .offset_ns
            .get_or_insert_with(|| clock.now_ns().saturating_sub(now_ns));
        // Never backwards: the devices' clocks only run forward.
        clock.sleep_until(now_ns.saturating_add(offset));
        self.timed = true;
    }
}

/// Inputs and outputs of the simulated DIO terminal.
pub const SIMULATED_DIO_BITS: usize = 8;

/// How the simulated devices behave (the machine file's `[fieldbus.simulation]`).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimulationConfig {
    /// Rate error of every device's clock against the master's (ppm): the distributed
    /// clocks compensate it, and the cycle follows the reference clock. Default 0.
    #[serde(default)]
    pub drift_ppm: f64,
    /// Frames lost at this rate from the start (0 to 1). Default 0.
    #[serde(default)]
    pub frame_loss_rate: f64,
    /// Seed of the frame-loss draw. Default 1.
    #[serde(default = "one")]
    pub seed: u64,
    /// A touch probe over a surface (`[fieldbus.simulation.probe]`). Absent: none.
    #[serde(default)]
    pub probe: Option<SimulatedProbe>,
    /// Time from a touch probe's edge to the drives reporting its position (s); default
    /// 0.001.
    #[serde(default = "touch_probe_latency")]
    pub touch_probe_latency_s: f64,
}

fn touch_probe_latency() -> f64 {
    0.001
}

/// A touch probe over a flat surface across one joint's travel, wired into digital input
/// `input` (on an I/O terminal) and into the touch probe 1 input of the drives of `drives`
/// (each latches its own position at the probe's edge). In contact while the joint's load
/// stands at or beyond `surface` (below it with `side = "below"`, the default), in the
/// joint's own position (before homing offsets).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimulatedProbe {
    /// Digital input of the process image (an I/O terminal's) the probe is wired to.
    pub input: usize,
    /// Joint whose load meets the surface.
    pub joint: usize,
    /// Where the surface is, joint units.
    pub surface: f64,
    /// Which side of the surface is in contact.
    #[serde(default)]
    pub side: ProbeSide,
    /// Joints whose drives' touch probe 1 input the probe is wired to; absent: every drive
    /// whose `rx_pdo` maps `touch_probe_function` (0x60B8).
    #[serde(default)]
    pub drives: Option<Vec<usize>>,
}

fn one() -> u64 {
    1
}

impl Default for SimulationConfig {
    fn default() -> Self {
        Self {
            drift_ppm: 0.0,
            frame_loss_rate: 0.0,
            seed: 1,
            probe: None,
            touch_probe_latency_s: touch_probe_latency(),
        }
    }
}

/// The segment of simulated devices that `config` lists, in bus order. `joints[k]` is the
/// simulated motor of the drive that moves process-image joint `k` (its drive mode is CSP
/// whatever it says). Refusals name the key below `fieldbus`.
pub fn simulated_segment(
    config: &EthercatConfig,
    joints: &[SimulatedJointConfig],
    simulation: &SimulationConfig,
) -> Result<Segment, ConfigError> {
    check_simulation(simulation)?;
    let mut slaves = Vec::with_capacity(config.slaves.len());
    // Per device: the joint a drive moves; the first input of a terminal.
    let mut drive_joints = Vec::with_capacity(config.slaves.len());
    let mut terminal_inputs = Vec::with_capacity(config.slaves.len());
    for (n, slave) in config.slaves.iter().enumerate() {
        match slave {
            SlaveConfig::Cia402 { joint, rx_pdo, .. } => {
                drive_joints.push(Some((
                    *joint,
                    rx_pdo.contains(&RxObject::TouchProbeFunction),
                )));
                terminal_inputs.push(None);
            }
            SlaveConfig::Dio { inputs, .. } => {
                drive_joints.push(None);
                terminal_inputs.push(Some(*inputs));
            }
        }
        let device = match slave {
            SlaveConfig::Cia402 {
                joint,
                counts_per_unit,
                rated_torque_nm,
                ..
            } => simulated_drive(
                n,
                *joint,
                *counts_per_unit,
                *rated_torque_nm,
                joints,
                simulation,
            )?,
            SlaveConfig::Dio {
                input_bits,
                output_bits,
                inputs,
                ..
            } => simulated_terminal(
                n,
                [*input_bits, *output_bits],
                *inputs,
                config.estop_input,
                simulation,
            )?,
        };
        slaves.push(device);
    }
    let mut probes = Vec::new();
    if let Some(probe) = &simulation.probe {
        probes.push(probe_wire(probe, &drive_joints, &terminal_inputs)?);
    }
    let segment = SegmentConfig {
        seed: simulation.seed,
        frame_loss_rate: simulation.frame_loss_rate,
        slaves,
        probes,
    };
    segment
        .build()
        .map_err(|e| refuse(format!("simulation.{}", e.field), e.reason))
}

fn refuse(key: String, reason: String) -> ConfigError {
    ConfigError { key, reason }
}

/// The frame loss rate, the clock drift and the touch probe's latency in their ranges.
fn check_simulation(simulation: &SimulationConfig) -> Result<(), ConfigError> {
    if !(0.0..=1.0).contains(&simulation.frame_loss_rate) {
        return Err(refuse(
            "simulation.frame_loss_rate".into(),
            "must be between 0 and 1".into(),
        ));
    }
    if !(simulation.drift_ppm.is_finite() && simulation.drift_ppm.abs() <= 1000.0) {
        return Err(refuse(
            "simulation.drift_ppm".into(),
            "must be within ±1000 ppm".into(),
        ));
    }
    if !(simulation.touch_probe_latency_s.is_finite()
        && (0.0..=0.1).contains(&simulation.touch_probe_latency_s))
    {
        return Err(refuse(
            "simulation.touch_probe_latency_s".into(),
            "must be from 0 to 0.1 s".into(),
        ));
    }
    Ok(())
}

/// Device `n`, a CiA 402 drive of `joint`: the joint's simulated motor in CSP, whose
/// encoder must give the configured counts per unit.
fn simulated_drive(
    n: usize,
    joint: usize,
    counts_per_unit: f64,
    rated_torque_nm: f64,
    joints: &[SimulatedJointConfig],
    simulation: &SimulationConfig,
) -> Result<SimulatedSlave, ConfigError> {
    let key = |k: &str| format!("slaves[{n}].{k}");
    let Some(motor) = joints.get(joint) else {
        return Err(refuse(
            key("joint"),
            format!(
                "joint {joint} has no simulated drive ({} are simulated)",
                joints.len()
            ),
        ));
    };
    let mut motor = motor.clone();
    motor.drive = DriveMode::Csp;
    let simulated = f64::from(motor.encoder_counts_per_revolution) / motor.units_per_revolution;
    if (simulated - counts_per_unit).abs() > 1e-9 * simulated.abs() {
        return Err(refuse(
            key("counts_per_unit"),
            format!(
                "{counts_per_unit} is not the simulated drive's {simulated} \
                 (encoder_counts_per_revolution / units_per_revolution of joint {joint})"
            ),
        ));
    }
    Ok(SimulatedSlave::CspDrive {
        count: 1,
        drift_ppm: simulation.drift_ppm,
        drive: DriveConfig {
            rated_torque_mnm: (rated_torque_nm * 1000.0).round().clamp(1.0, 1e9) as u32,
            joint: motor,
            touch_probe_latency_s: simulation.touch_probe_latency_s,
            ..DriveConfig::default()
        },
    })
}

/// Device `n`, a digital I/O terminal of `[input_bits, output_bits]` whose first input is
/// `inputs`.
fn simulated_terminal(
    n: usize,
    [input_bits, output_bits]: [usize; 2],
    inputs: usize,
    estop_input: Option<usize>,
    simulation: &SimulationConfig,
) -> Result<SimulatedSlave, ConfigError> {
    let key = |k: &str| format!("slaves[{n}].{k}");
    for (what, bits) in [("input_bits", input_bits), ("output_bits", output_bits)] {
        if bits != SIMULATED_DIO_BITS {
            return Err(refuse(
                key(what),
                format!("the simulated terminal has {SIMULATED_DIO_BITS}"),
            ));
        }
    }
    // A simulated machine powers up with its e-stop chain closed.
    let initial_inputs = match estop_input {
        Some(e) if (inputs..inputs + SIMULATED_DIO_BITS).contains(&e) => 1u8 << (e - inputs),
        _ => 0,
    };
    Ok(SimulatedSlave::Dio {
        count: 1,
        drift_ppm: simulation.drift_ppm,
        terminal: DioConfig {
            initial_inputs,
            ..DioConfig::default()
        },
    })
}

/// The touch probe's wiring: the drive of the joint it senses, the drives that move it
/// (those mapped for a touch probe unless listed) and the terminal input it closes.
fn probe_wire(
    probe: &SimulatedProbe,
    drive_joints: &[Option<(usize, bool)>],
    terminal_inputs: &[Option<usize>],
) -> Result<ProbeWire, ConfigError> {
    if !probe.surface.is_finite() {
        return Err(refuse(
            "simulation.probe.surface".into(),
            "must be a number".into(),
        ));
    }
    let device_of = |joint: usize| {
        drive_joints
            .iter()
            .position(|d| d.is_some_and(|(j, _)| j == joint))
    };
    let sensed = device_of(probe.joint).ok_or_else(|| {
        refuse(
            "simulation.probe.joint".into(),
            format!("no drive moves joint {}", probe.joint),
        )
    })?;
    let drives = match &probe.drives {
        Some(joints) => joints
            .iter()
            .map(|&j| {
                device_of(j).ok_or_else(|| {
                    refuse(
                        "simulation.probe.drives".into(),
                        format!("no drive moves joint {j}"),
                    )
                })
            })
            .collect::<Result<Vec<_>, _>>()?,
        None => (0..drive_joints.len())
            .filter(|&n| drive_joints[n].is_some_and(|(_, mapped)| mapped))
            .collect(),
    };
    let input = terminal_inputs
        .iter()
        .enumerate()
        .find_map(|(device, first)| {
            first
                .filter(|&f| (f..f + SIMULATED_DIO_BITS).contains(&probe.input))
                .map(|f| ProbeInput {
                    device,
                    bit: (probe.input - f) as u8,
                })
        })
        .ok_or_else(|| {
            refuse(
                "simulation.probe.input".into(),
                format!("no I/O terminal gives digital input {}", probe.input),
            )
        })?;
    Ok(ProbeWire {
        sensed,
        surface: probe.surface,
        side: probe.side,
        drives,
        input: Some(input),
    })
}
