use crate::bus::{Fieldbus, FieldbusError, check_exchange};
use crate::cia402::Cia402State;
use crate::image::{
    Coolant, JointCommand, ProcessInputs, ProcessLayout, ProcessOutputs, SpindleCommand,
    ToolChangeCommand,
};
use crate::sim::config::{ConfigError, SimulatedMachineConfig};
use crate::sim::devices::{Device, DeviceConfig, DeviceCycle};
use crate::sim::joint::{CycleConditions, SimulatedJoint};
use crate::sim::peripherals::{Spindle, ToolChanger, seconds_to_ns};

/// A fault the test harness (or the operator's "what if" panel) puts into the machine.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InjectedFault {
    /// The joint's drive detects an internal fault with this CiA 402 error code.
    DriveFault {
        /// Joint index.
        joint: usize,
        /// Error code the drive reports (0x603F).
        error_code: u16,
    },
    /// The joint's encoder stops counting. A drive that closes the position loop (CSP,
    /// ideal) faults with [`POSITION_SENSOR`](crate::cia402::error_code::POSITION_SENSOR); in velocity and torque modes
    /// only the controller can notice (its following error grows).
    EncoderLoss {
        /// Joint index.
        joint: usize,
    },
    /// Process data stops: `exchange` fails and the drives run on their last command
    /// until the watchdog makes them fault with [`COMMUNICATION`](crate::cia402::error_code::COMMUNICATION).
    CommunicationLoss,
    /// Digital input `input` reads `value` whatever drives it (a failed sensor, a broken
    /// wire, a jammed mechanism), until cleared.
    StuckInput {
        /// Digital input.
        input: usize,
        /// The level it is stuck at.
        value: bool,
    },
}

/// A request to the simulated machine named something it does not have.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum SimulationError {
    /// No such joint.
    #[error("no joint {joint}: the machine has {joints}")]
    NoSuchJoint {
        /// Index asked for.
        joint: usize,
        /// Joints present.
        joints: usize,
    },
    /// No such input point.
    #[error("no {kind} input {index}: the machine has {count}")]
    NoSuchInput {
        /// "digital" or "analog".
        kind: &'static str,
        /// Index asked for.
        index: usize,
        /// Points present.
        count: usize,
    },
    /// The machine has no such device.
    #[error("the machine has no {0}")]
    NoSuchDevice(&'static str),
}

impl SimulationError {
    /// A stable machine-readable code.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn code(&self) -> &'static str {
        match self {
            Self::NoSuchJoint { .. } => "fieldbus.sim.no_such_joint",
            Self::NoSuchInput { .. } => "fieldbus.sim.no_such_input",
            Self::NoSuchDevice(_) => "fieldbus.sim.no_such_device",
        }
    }
}

/// The in-process simulated machine: drives, motors, switches, spindle, coolant, tool
/// changer and I/O behind the [`Fieldbus`] trait. Deterministic: the same configuration
/// and the same outputs give the same inputs, bit for bit.
#[derive(Debug, Clone)]
pub struct SimulatedMachine {
    layout: ProcessLayout,
    substep_s: f64,
    watchdog_ns: u64,
    estop_removes_power: bool,
    command_delay_s: f64,
    touch_probe_latency_s: f64,
    /// The joints' true positions at the start of the cycle (a probe's edge is placed
    /// between them and the end).
    cycle_start: Vec<f64>,
    joints: Vec<SimulatedJoint>,
    /// The commands the drives last received (they keep acting on them when a cycle is
    /// lost).
    received: Vec<JointCommand>,
    /// Per joint: this cycle has sub-steps to run (not an ideal drive).
    stepping: Vec<bool>,
    spindle: Spindle,
    spindle_command: SpindleCommand,
    coolant: Coolant,
    tool_changer: ToolChanger,
    tool_command: ToolChangeCommand,
    digital_inputs: Vec<bool>,
    /// The digital inputs as the machine reads them: the harness's levels, then the
    /// devices', then stuck inputs.
    digital_image: Vec<bool>,
    devices: Vec<Device>,
    /// Indices of the probes among the devices: the passes after the joints have moved
    /// visit only them.
    probes: Vec<usize>,
    /// The digital image, up to the probes' sensing, is what the next exchange would make
    /// of it again if the outputs stay the same: every device stood still in the last one,
    /// and nothing else they or the image read has changed since. The devices' pass is then
    /// skipped.
    devices_steady: bool,
    stuck_inputs: Vec<Option<bool>>,
    /// Some input is stuck (else the per-cycle passes over `stuck_inputs` are skipped).
    any_stuck: bool,
    /// The last period's sub-step count and length and the sub-steps under the previous
    /// command (the same period comes every cycle).
    cycle_shape: (f64, usize, f64, usize),
    door_open_requested: bool,
    analog_inputs: Vec<f64>,
    digital_outputs: Vec<bool>,
    analog_outputs: Vec<f64>,
    estop_active: bool,
    handwheel_counts: i64,
    communication_lost: bool,
    silent_ns: u64,
    time_ns: u64,
}

impl SimulatedMachine {
    /// Builds the machine at power-up (drives in "not ready to switch on"), or names the
    /// first refused configuration field. All memory is allocated here.
    ///
    /// Real-time: no (set-up: allocates).
    pub fn new(config: &SimulatedMachineConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        let layout = ProcessLayout {
            joints: config.joints.iter().map(|joint| joint.drive).collect(),
            digital_inputs: config.io.digital_inputs,
            digital_outputs: config.io.digital_outputs,
            analog_inputs: config.io.analog_inputs,
            analog_outputs: config.io.analog_outputs,
        };
        Ok(Self {
            substep_s: config.substep_s,
            watchdog_ns: seconds_to_ns(config.communication_watchdog_s),
            estop_removes_power: config.estop_removes_power,
            command_delay_s: config.command_delay_s,
            touch_probe_latency_s: config.touch_probe_latency_s,
            cycle_start: vec![0.0; config.joints.len()],
            joints: config.joints.iter().map(SimulatedJoint::new).collect(),
            received: vec![JointCommand::default(); config.joints.len()],
            stepping: vec![false; config.joints.len()],
            spindle: Spindle::new(config.spindle),
            spindle_command: SpindleCommand::default(),
            coolant: Coolant::default(),
            tool_changer: ToolChanger::new(config.tool_changer),
            tool_command: ToolChangeCommand::default(),
            digital_inputs: vec![false; config.io.digital_inputs],
            digital_image: vec![false; config.io.digital_inputs],
            devices: config.devices.iter().map(Device::new).collect(),
            probes: config
                .devices
                .iter()
                .enumerate()
                .filter(|(_, device)| matches!(device, DeviceConfig::Probe { .. }))
                .map(|(index, _)| index)
                .collect(),
            devices_steady: false,
            stuck_inputs: vec![None; config.io.digital_inputs],
            any_stuck: false,
            cycle_shape: (f64::NAN, 1, f64::NAN, 0),
            door_open_requested: false,
            analog_inputs: vec![0.0; config.io.analog_inputs],
            digital_outputs: vec![false; config.io.digital_outputs],
            analog_outputs: vec![0.0; config.io.analog_outputs],
            estop_active: false,
            handwheel_counts: 0,
            communication_lost: false,
            silent_ns: 0,
            time_ns: 0,
            layout,
        })
    }

    /// Presses (`true`) or releases the e-stop button.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn set_estop(&mut self, pressed: bool) {
        self.estop_active = pressed;
        self.devices_steady = false;
    }

    /// Turns the handwheel by `detents` (negative: the other way).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn turn_handwheel(&mut self, detents: i64) {
        self.handwheel_counts = self.handwheel_counts.wrapping_add(detents);
    }

    /// The operator pulls the door open (`true`) or pushes it shut (`false`). A locked door
    /// stays closed until its lock output drops (see
    /// [`DeviceConfig::Door`](crate::sim::DeviceConfig::Door)); it acts from the next
    /// exchange on.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn set_door_open(&mut self, open: bool) -> Result<(), SimulationError> {
        if !self.devices.iter().any(|d| d.door_closed().is_some()) {
            return Err(SimulationError::NoSuchDevice("door"));
        }
        self.door_open_requested = open;
        self.devices_steady = false;
        Ok(())
    }

    /// Whether the door is closed (`None`: no door).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn door_closed(&self) -> Option<bool> {
        self.devices.iter().find_map(Device::door_closed)
    }

    /// The pocket of the carousel at the tool-change station (`None`: no carousel).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn carousel_pocket(&self) -> Option<u32> {
        self.devices.iter().find_map(Device::carousel_pocket)
    }

    /// Digital input `index` as the machine last reported it (devices and stuck inputs
    /// included).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn digital_input(&self, index: usize) -> Option<bool> {
        self.digital_image.get(index).copied()
    }

    /// Sets digital input `index` (a switch on the machine, a panel button). An input a
    /// device drives takes the device's level instead.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn set_digital_input(&mut self, index: usize, value: bool) -> Result<(), SimulationError> {
        let count = self.digital_inputs.len();
        let slot = self.digital_inputs.get_mut(index);
        let slot = slot.ok_or(SimulationError::NoSuchInput {
            kind: "digital",
            index,
            count,
        })?;
        *slot = value;
        self.devices_steady = false;
        Ok(())
    }

    /// The spindle's angle from its index, degrees (0 ≤ angle < 360).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn spindle_angle_deg(&self) -> f64 {
        self.spindle.angle_deg()
    }

    /// Sets analogue input `index`.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn set_analog_input(&mut self, index: usize, value: f64) -> Result<(), SimulationError> {
        let count = self.analog_inputs.len();
        let slot = self.analog_inputs.get_mut(index);
        let slot = slot.ok_or(SimulationError::NoSuchInput {
            kind: "analog",
            index,
            count,
        })?;
        *slot = value;
        Ok(())
    }

    /// Digital output `index` as the machine last received it.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn digital_output(&self, index: usize) -> Option<bool> {
        self.digital_outputs.get(index).copied()
    }

    /// Analogue output `index` as the machine last received it.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn analog_output(&self, index: usize) -> Option<f64> {
        self.analog_outputs.get(index).copied()
    }

    /// Puts a fault into the machine; it acts from the next exchange on.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn inject(&mut self, fault: InjectedFault) -> Result<(), SimulationError> {
        self.set_fault(fault, true)
    }

    /// Removes an injected fault (a faulted drive still needs a fault reset).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn clear(&mut self, fault: InjectedFault) -> Result<(), SimulationError> {
        self.set_fault(fault, false)
    }

    fn set_fault(&mut self, fault: InjectedFault, active: bool) -> Result<(), SimulationError> {
        match fault {
            InjectedFault::DriveFault { joint, error_code } => self
                .joint_mut(joint)?
                .set_injected_fault(active.then_some(error_code)),
            InjectedFault::EncoderLoss { joint } => self.joint_mut(joint)?.set_encoder_lost(active),
            InjectedFault::CommunicationLoss => self.communication_lost = active,
            InjectedFault::StuckInput { input, value } => {
                let count = self.stuck_inputs.len();
                let slot =
                    self.stuck_inputs
                        .get_mut(input)
                        .ok_or(SimulationError::NoSuchInput {
                            kind: "digital",
                            index: input,
                            count,
                        })?;
                *slot = active.then_some(value);
                self.any_stuck = self.stuck_inputs.iter().any(Option::is_some);
                self.devices_steady = false;
            }
        }
        Ok(())
    }

    fn joint_mut(&mut self, joint: usize) -> Result<&mut SimulatedJoint, SimulationError> {
        let joints = self.joints.len();
        self.joints
            .get_mut(joint)
            .ok_or(SimulationError::NoSuchJoint { joint, joints })
    }

    /// The load's true position and velocity (units, units/s), before the encoder: for
    /// plots and tests, not for control.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn true_state(&self, joint: usize) -> Option<(f64, f64)> {
        self.joints
            .get(joint)
            .map(|j| (j.true_position(), j.true_velocity()))
    }

    /// The CiA 402 state the drive of `joint` is in, as the drive knows it (not as the
    /// controller last heard it): whether it holds the load under control. For tests.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn drive_state(&self, joint: usize) -> Option<Cia402State> {
        self.joints.get(joint).map(SimulatedJoint::drive_state)
    }

    /// Simulated time since power-up (s).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn time_s(&self) -> f64 {
        self.time_ns as f64 * 1e-9
    }

    /// Number of sub-steps a cycle of `period_s` is split into.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn substeps_for(&self, period_s: f64) -> usize {
        // The small slack keeps a period that is a whole multiple of the sub-step from
        // gaining a step through rounding.
        ((period_s / self.substep_s) * (1.0 - 1e-12))
            .ceil()
            .max(1.0) as usize
    }
}

impl SimulatedMachine {
    /// The drives' touch-probe latches: a probe device's edge within this cycle, placed
    /// where its joint crossed the surface (the joints taken to move linearly within the
    /// cycle), latches every joint armed for that edge at its position at that instant.
    fn latch_touch_probes(&mut self, period_s: f64, inputs: &mut ProcessInputs) {
        for device in self.probes.iter().filter_map(|&i| self.devices.get(i)) {
            let start = &self.cycle_start;
            let joints = &self.joints;
            let Some((rising, share)) = device.probe_edge(
                |j| start.get(j).copied(),
                |j| joints.get(j).map(|j| j.true_position()),
            ) else {
                continue;
            };
            let report_after = (self.touch_probe_latency_s / period_s - 1e-9)
                .ceil()
                .max(0.0) as u32;
            for ((joint, &p0), feedback) in self
                .joints
                .iter_mut()
                .zip(&self.cycle_start)
                .zip(inputs.joints.iter_mut())
            {
                let at = p0 + share * (joint.true_position() - p0);
                joint.touch_probe_edge(rising, at, report_after, feedback);
            }
        }
    }
}

impl Fieldbus for SimulatedMachine {
    fn layout(&self) -> &ProcessLayout {
        &self.layout
    }

    fn exchange(
        &mut self,
        period_s: f64,
        outputs: &ProcessOutputs,
        inputs: &mut ProcessInputs,
    ) -> Result<(), FieldbusError> {
        check_exchange(&self.layout, period_s, outputs, inputs)?;
        let period_ns = seconds_to_ns(period_s);
        // A lost exchange builds the image afresh: it ends before the probes' sensing, so
        // its image shows a probe's input at the harness's level, not the sensed level the
        // last exchange left.
        let image_steady = self.devices_steady
            && !self.communication_lost
            && self.digital_outputs == outputs.digital;
        if self.communication_lost {
            self.silent_ns = self.silent_ns.saturating_add(period_ns);
        } else {
            self.silent_ns = 0;
            self.received.copy_from_slice(&outputs.joints);
            self.digital_outputs.copy_from_slice(&outputs.digital);
            self.analog_outputs.copy_from_slice(&outputs.analog);
            self.spindle_command = outputs.spindle;
            self.coolant = outputs.coolant;
            self.tool_command = outputs.tool_changer;
        }
        let power = !(self.estop_active && self.estop_removes_power);
        if self.cycle_shape.0 != period_s {
            let substeps = self.substeps_for(period_s).max(1);
            let step_s = period_s / substeps as f64;
            // A sub-step is under the previous command while it starts before the delay.
            let delay_limit = self.command_delay_s * (1.0 - 1e-9);
            let delayed = (0..substeps)
                .take_while(|&k| (k as f64) * step_s < delay_limit)
                .count();
            self.cycle_shape = (period_s, substeps, step_s, delayed);
        }
        let (_, substeps, step_s, delayed_substeps) = self.cycle_shape;
        let conditions = CycleConditions {
            period_s,
            substeps,
            step_s,
            power,
            watchdog_expired: self.silent_ns >= self.watchdog_ns && self.silent_ns > 0,
            delayed_substeps,
        };
        self.time_ns = self.time_ns.saturating_add(period_ns);
        let spindle = self.spindle.cycle(&self.spindle_command, power, period_s);
        let tool_changer = self.tool_changer.cycle(&self.tool_command, period_ns);
        if !image_steady {
            self.digital_image.copy_from_slice(&self.digital_inputs);
            let device_cycle = DeviceCycle {
                outputs: &self.digital_outputs,
                estop_pressed: self.estop_active,
                door_open_requested: self.door_open_requested,
                period_ns,
            };
            let mut steady = true;
            for device in &mut self.devices {
                steady &= device.cycle(&device_cycle, &mut self.digital_image);
            }
            self.devices_steady = steady;
            if self.any_stuck {
                for (level, stuck) in self.digital_image.iter_mut().zip(&self.stuck_inputs) {
                    if let Some(value) = stuck {
                        *level = *value;
                    }
                }
            }
        }
        if self.communication_lost {
            // The plant runs on; the controller hears nothing. Feedback goes to scratch.
            let mut scratch = crate::image::JointFeedback::default();
            for (joint, command) in self.joints.iter_mut().zip(&self.received) {
                joint.cycle(command, &conditions, &mut scratch);
            }
            return Err(FieldbusError::CommunicationLost);
        }
        // The joints' sub-steps interleaved (sub-step outer, joint inner): each joint's
        // arithmetic is the same as one joint at a time, and the processor overlaps the
        // joints' independent dependency chains.
        let mut any_stepping = false;
        for (((joint, command), stepping), start) in self
            .joints
            .iter_mut()
            .zip(&self.received)
            .zip(self.stepping.iter_mut())
            .zip(self.cycle_start.iter_mut())
        {
            *start = joint.true_position();
            *stepping = joint.begin_cycle(command, &conditions);
            any_stepping |= *stepping;
        }
        // Joints at rest under stiction, ideal drives and velocity drives stepped in one
        // composed step have no sub-steps: when none has, the loop would only visit them.
        let substeps = if any_stepping {
            conditions.substeps.max(1)
        } else {
            0
        };
        for substep in 1..=substeps {
            for ((joint, command), stepping) in self
                .joints
                .iter_mut()
                .zip(&self.received)
                .zip(self.stepping.iter())
            {
                if *stepping {
                    joint.substep(command, &conditions, substep);
                }
            }
        }
        for ((joint, command), feedback) in self
            .joints
            .iter_mut()
            .zip(&self.received)
            .zip(inputs.joints.iter_mut())
        {
            joint.end_cycle(command, &conditions, feedback);
        }
        self.latch_touch_probes(period_s, inputs);
        // A probe senses where the joints are at the end of the cycle.
        let joints = &self.joints;
        for device in self.probes.iter().filter_map(|&i| self.devices.get(i)) {
            device.sense(
                |j| joints.get(j).map(|j| j.true_position()),
                &mut self.digital_image,
            );
        }
        if self.any_stuck {
            for (level, stuck) in self.digital_image.iter_mut().zip(&self.stuck_inputs) {
                if let Some(value) = stuck {
                    *level = *value;
                }
            }
        }
        inputs.digital.copy_from_slice(&self.digital_image);
        inputs.analog.copy_from_slice(&self.analog_inputs);
        inputs.estop_active = self.estop_active;
        inputs.handwheel_counts = self.handwheel_counts;
        inputs.spindle = spindle;
        inputs.coolant = if power {
            self.coolant
        } else {
            Coolant::default()
        };
        inputs.tool_changer = tool_changer;
        Ok(())
    }
}
