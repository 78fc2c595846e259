//! Plain-data configuration of the simulated machine, read from the machine TOML.

use serde::Deserialize;

use crate::image::DriveMode;
use crate::sim::devices::{DeviceConfig, validate_devices};

/// A refused value names its field; the one type and checks of every machine-file crate.
pub use rtcnc_rt::FieldError as ConfigError;
use rtcnc_rt::check::{finite, non_negative, positive};

/// The whole simulated machine.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimulatedMachineConfig {
    /// Longest integration step (s). Each cycle is split into the fewest equal sub-steps
    /// no longer than this; the drives' internal loops run once per sub-step. Default
    /// 62.5 µs (a 16 kHz drive loop).
    #[serde(default = "defaults::substep_s")]
    pub substep_s: f64,
    /// How long the drives keep going on their last command when process data stops
    /// arriving, before they fault (s). Default 0.1 s (EtherCAT's usual watchdog).
    #[serde(default = "defaults::communication_watchdog_s")]
    pub communication_watchdog_s: f64,
    /// Time from the feedback sample to a new velocity or torque command acting on the
    /// motor (s): the controller's computation and the DAC. Until then the previous
    /// command acts. Default 0; at most 0.01 s.
    #[serde(default)]
    pub command_delay_s: f64,
    /// Time from a touch-probe edge to the drives reporting the position they latched at
    /// it (s): the latch comes back in the exchange that many seconds after the one in
    /// which the edge happened, rounded up to whole exchanges. Default 0.001 s; at most
    /// 0.1 s.
    #[serde(default = "defaults::touch_probe_latency_s")]
    pub touch_probe_latency_s: f64,
    /// The e-stop chain removes drive power (safe torque off), spindle and coolant.
    #[serde(default = "defaults::yes")]
    pub estop_removes_power: bool,
    /// The joints, in order.
    pub joints: Vec<SimulatedJointConfig>,
    /// The spindle.
    #[serde(default)]
    pub spindle: SpindleConfig,
    /// The tool changer.
    #[serde(default)]
    pub tool_changer: ToolChangerConfig,
    /// General-purpose I/O.
    #[serde(default)]
    pub io: IoConfig,
    /// Devices wired to the digital I/O (door, e-stop contact, delayed inputs, carousel).
    #[serde(default)]
    pub devices: Vec<DeviceConfig>,
}

/// One joint: its drive, motor and load, encoder and switches. Positions are in joint
/// units (mm or degrees); the motor side is in radians and N·m.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimulatedJointConfig {
    /// How the drive is commanded.
    pub drive: DriveMode,
    /// Motor and load.
    #[serde(default)]
    pub motor: MotorConfig,
    /// Joint travel per motor revolution (units), e.g. a 5 mm ball-screw lead.
    #[serde(default = "defaults::units_per_revolution")]
    pub units_per_revolution: f64,
    /// Encoder counts per motor revolution.
    #[serde(default = "defaults::encoder_counts")]
    pub encoder_counts_per_revolution: u32,
    /// Crossover frequency of the drive's velocity loop (Hz).
    #[serde(default = "defaults::velocity_bandwidth_hz")]
    pub velocity_loop_bandwidth_hz: f64,
    /// Proportional gain of a CSP drive's position loop (1/s).
    #[serde(default = "defaults::position_loop_gain")]
    pub position_loop_gain: f64,
    /// Deceleration on the quick-stop ramp (units/s²).
    #[serde(default = "defaults::quick_stop_deceleration")]
    pub quick_stop_deceleration: f64,
    /// Position at power-up (units).
    #[serde(default)]
    pub initial_position: f64,
    /// The negative limit switch is on at and below this position.
    #[serde(default)]
    pub negative_limit_switch: Option<f64>,
    /// The positive limit switch is on at and above this position.
    #[serde(default)]
    pub positive_limit_switch: Option<f64>,
    /// The home switch is on inside this range.
    #[serde(default)]
    pub home_switch: Option<SwitchRange>,
    /// Index pulses at `index_offset + n · units_per_revolution`; absent: no index.
    #[serde(default)]
    pub index_offset: Option<f64>,
}

/// Motor plus load, reflected to the motor shaft.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MotorConfig {
    /// Total inertia (kg·m²).
    pub inertia: f64,
    /// Viscous friction (N·m per rad/s).
    pub viscous_friction: f64,
    /// Coulomb friction (N·m); also the break-away torque at rest.
    pub coulomb_friction: f64,
    /// The drive's peak torque (N·m).
    pub torque_limit: f64,
}

impl Default for MotorConfig {
    /// A 400 W servo motor on a 5 mm ball screw with a light table: 1.5·10⁻⁴ kg·m²,
    /// 2·10⁻⁴ N·m·s/rad, 0.1 N·m Coulomb friction, 3.8 N·m peak torque.
    fn default() -> Self {
        Self {
            inertia: 1.5e-4,
            viscous_friction: 2e-4,
            coulomb_friction: 0.1,
            torque_limit: 3.8,
        }
    }
}

/// An inclusive position range.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SwitchRange {
    /// Lower end (units).
    pub from: f64,
    /// Upper end (units).
    pub to: f64,
}

/// The spindle: a jerk-limited speed ramp and an at-speed window.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SpindleConfig {
    /// Highest speed (rev/min); commands are clamped to it.
    pub max_speed_rpm: f64,
    /// Acceleration and deceleration (rev/min per second).
    pub acceleration_rpm_per_s: f64,
    /// Jerk: the rate of change of the acceleration (rev/min per second²). A rigid tap
    /// (G33.1) makes the tapping axis follow the spindle, so that axis's jerk is pitch ×
    /// this (in rev/s³, 1/60 of it), up to 1.55 times that where the spindle's jerk sets
    /// in (the kernel extrapolates the spindle's last period to the next). The default,
    /// 480 000 rev/min/s² (8 000 rev/s³), gives at most 12 400 mm/s³ per mm of pitch: the
    /// simulated mill's Z (40 000 mm/s³) taps up to K3 (M24 coarse) within its jerk, as
    /// within its acceleration (3 mm × 12 000 rev/min/s = 600 mm/s², limit 800). The
    /// acceleration is reached in acceleration / jerk (25 ms on the mill), a spindle
    /// drive's usual ramp rounding.
    pub jerk_rpm_per_s2: f64,
    /// At-speed window, a fraction of the commanded speed.
    pub at_speed_tolerance: f64,
    /// Speed at which an orientation (M19) turns to its angle once stopped (rev/min).
    pub orient_speed_rpm: f64,
    /// Orientation window: oriented within this many degrees of the angle.
    pub orient_tolerance_deg: f64,
}

impl Default for SpindleConfig {
    fn default() -> Self {
        Self {
            max_speed_rpm: 24000.0,
            acceleration_rpm_per_s: 8000.0,
            jerk_rpm_per_s2: 480_000.0,
            at_speed_tolerance: 0.02,
            orient_speed_rpm: 60.0,
            orient_tolerance_deg: 0.5,
        }
    }
}

/// The tool changer.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ToolChangerConfig {
    /// Time one change takes (s).
    pub change_time_s: f64,
    /// Tool in the spindle at power-up (0: none).
    pub initial_tool: u32,
}

impl Default for ToolChangerConfig {
    fn default() -> Self {
        Self {
            change_time_s: 3.0,
            initial_tool: 0,
        }
    }
}

/// Counts of general-purpose I/O points.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct IoConfig {
    /// Digital inputs.
    pub digital_inputs: usize,
    /// Digital outputs.
    pub digital_outputs: usize,
    /// Analogue inputs.
    pub analog_inputs: usize,
    /// Analogue outputs.
    pub analog_outputs: usize,
}

impl Default for IoConfig {
    fn default() -> Self {
        Self {
            digital_inputs: 16,
            digital_outputs: 16,
            analog_inputs: 4,
            analog_outputs: 4,
        }
    }
}

/// Largest I/O count accepted per kind.
pub const MAX_IO_POINTS: usize = 4096;
/// Largest joint count accepted.
pub const MAX_JOINTS: usize = 64;

impl SimulatedMachineConfig {
    /// Checks every field; the error names the first refused one.
    ///
    /// Real-time: no (set-up: a refusal allocates its message).
    pub fn validate(&self) -> Result<(), ConfigError> {
        positive("substep_s", self.substep_s)?;
        if !(1e-6..=1e-3).contains(&self.substep_s) {
            return Err(ConfigError::new(
                "substep_s",
                "must be between 1e-6 and 1e-3 s",
            ));
        }
        positive("communication_watchdog_s", self.communication_watchdog_s)?;
        non_negative("command_delay_s", self.command_delay_s)?;
        if self.command_delay_s > 0.01 {
            return Err(ConfigError::new(
                "command_delay_s",
                "must be at most 0.01 s",
            ));
        }
        non_negative("touch_probe_latency_s", self.touch_probe_latency_s)?;
        if self.touch_probe_latency_s > 0.1 {
            return Err(ConfigError::new(
                "touch_probe_latency_s",
                "must be at most 0.1 s",
            ));
        }
        if self.joints.len() > MAX_JOINTS {
            return Err(ConfigError::new(
                "joints",
                format!("at most {MAX_JOINTS} joints"),
            ));
        }
        for (index, joint) in self.joints.iter().enumerate() {
            joint
                .validate(self.substep_s)
                .map_err(|error| error.within(&format!("joints[{index}]")))?;
        }
        self.spindle
            .validate()
            .map_err(|error| error.within("spindle"))?;
        non_negative(
            "tool_changer.change_time_s",
            self.tool_changer.change_time_s,
        )?;
        if self.tool_changer.change_time_s > 3600.0 {
            return Err(ConfigError::new(
                "tool_changer.change_time_s",
                "must be at most 3600 s",
            ));
        }
        for (name, count) in [
            ("io.digital_inputs", self.io.digital_inputs),
            ("io.digital_outputs", self.io.digital_outputs),
            ("io.analog_inputs", self.io.analog_inputs),
            ("io.analog_outputs", self.io.analog_outputs),
        ] {
            if count > MAX_IO_POINTS {
                return Err(ConfigError::new(name, format!("at most {MAX_IO_POINTS}")));
            }
        }
        for (index, device) in self.devices.iter().enumerate() {
            if let DeviceConfig::Probe { joint, .. } = device {
                if *joint >= self.joints.len() {
                    return Err(ConfigError::new(
                        format!("devices[{index}].joint"),
                        format!("there is no joint {joint}"),
                    ));
                }
            }
        }
        validate_devices(
            &self.devices,
            self.io.digital_inputs,
            self.io.digital_outputs,
        )
    }
}

impl SimulatedJointConfig {
    /// A joint with every default and the given drive mode.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn with_drive(drive: DriveMode) -> Self {
        Self {
            drive,
            motor: MotorConfig::default(),
            units_per_revolution: defaults::units_per_revolution(),
            encoder_counts_per_revolution: defaults::encoder_counts(),
            velocity_loop_bandwidth_hz: defaults::velocity_bandwidth_hz(),
            position_loop_gain: defaults::position_loop_gain(),
            quick_stop_deceleration: defaults::quick_stop_deceleration(),
            initial_position: 0.0,
            negative_limit_switch: None,
            positive_limit_switch: None,
            home_switch: None,
            index_offset: None,
        }
    }

    /// Checks the joint's fields for a machine integrated at `substep_s`.
    ///
    /// Real-time: no (set-up: a refusal allocates its message).
    pub fn validate(&self, substep_s: f64) -> Result<(), ConfigError> {
        positive("motor.inertia", self.motor.inertia)?;
        non_negative("motor.viscous_friction", self.motor.viscous_friction)?;
        non_negative("motor.coulomb_friction", self.motor.coulomb_friction)?;
        positive("motor.torque_limit", self.motor.torque_limit)?;
        positive("units_per_revolution", self.units_per_revolution)?;
        if self.encoder_counts_per_revolution == 0 {
            return Err(ConfigError::new(
                "encoder_counts_per_revolution",
                "must be at least 1",
            ));
        }
        positive(
            "velocity_loop_bandwidth_hz",
            self.velocity_loop_bandwidth_hz,
        )?;
        // The drive's loops run once per sub-step; keep them well inside its Nyquist range.
        let highest = 0.5 / (2.0 * std::f64::consts::PI * substep_s);
        if self.velocity_loop_bandwidth_hz > highest {
            return Err(ConfigError::new(
                "velocity_loop_bandwidth_hz",
                format!("at most {highest:.0} Hz with substep_s = {substep_s} s"),
            ));
        }
        non_negative("position_loop_gain", self.position_loop_gain)?;
        if self.position_loop_gain * substep_s > 0.5 {
            return Err(ConfigError::new(
                "position_loop_gain",
                format!(
                    "at most {:.0} 1/s with substep_s = {substep_s} s",
                    0.5 / substep_s
                ),
            ));
        }
        positive("quick_stop_deceleration", self.quick_stop_deceleration)?;
        finite("initial_position", self.initial_position)?;
        if let Some(position) = self.negative_limit_switch {
            finite("negative_limit_switch", position)?;
        }
        if let Some(position) = self.positive_limit_switch {
            finite("positive_limit_switch", position)?;
        }
        if let (Some(negative), Some(positive)) =
            (self.negative_limit_switch, self.positive_limit_switch)
            && negative >= positive
        {
            return Err(ConfigError::new(
                "positive_limit_switch",
                "must be above negative_limit_switch",
            ));
        }
        if let Some(range) = self.home_switch {
            finite("home_switch.from", range.from)?;
            finite("home_switch.to", range.to)?;
            if range.from > range.to {
                return Err(ConfigError::new(
                    "home_switch.to",
                    "must not be below home_switch.from",
                ));
            }
        }
        if let Some(offset) = self.index_offset {
            finite("index_offset", offset)?;
        }
        Ok(())
    }
}

impl SpindleConfig {
    fn validate(&self) -> Result<(), ConfigError> {
        positive("max_speed_rpm", self.max_speed_rpm)?;
        positive("acceleration_rpm_per_s", self.acceleration_rpm_per_s)?;
        positive("jerk_rpm_per_s2", self.jerk_rpm_per_s2)?;
        non_negative("at_speed_tolerance", self.at_speed_tolerance)?;
        if self.at_speed_tolerance >= 1.0 {
            return Err(ConfigError::new("at_speed_tolerance", "must be below 1"));
        }
        positive("orient_speed_rpm", self.orient_speed_rpm)?;
        non_negative("orient_tolerance_deg", self.orient_tolerance_deg)?;
        Ok(())
    }
}

mod defaults {
    /// Real-time: yes (no allocation, no blocking).
    pub fn touch_probe_latency_s() -> f64 {
        0.001
    }
    /// Real-time: yes (no allocation, no blocking).
    pub fn substep_s() -> f64 {
        62.5e-6
    }
    /// Real-time: yes (no allocation, no blocking).
    pub fn communication_watchdog_s() -> f64 {
        0.1
    }
    /// Real-time: yes (no allocation, no blocking).
    pub fn yes() -> bool {
        true
    }
    /// Real-time: yes (no allocation, no blocking).
    pub fn units_per_revolution() -> f64 {
        5.0
    }
    /// Real-time: yes (no allocation, no blocking).
    pub fn encoder_counts() -> u32 {
        1 << 17
    }
    /// Real-time: yes (no allocation, no blocking).
    pub fn velocity_bandwidth_hz() -> f64 {
        200.0
    }
    /// Real-time: yes (no allocation, no blocking).
    pub fn position_loop_gain() -> f64 {
        300.0
    }
    /// Real-time: yes (no allocation, no blocking).
    pub fn quick_stop_deceleration() -> f64 {
        2000.0
    }
}
