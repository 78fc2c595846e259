//! The machine configuration: one TOML file (schema in `docs/configuration.md`).
//!
//! [`MachineConfig::load`] reads, parses (unknown keys are refused) and validates it; a
//! refusal names the key and the reason, e.g. `axes.x.max_velocity: must be greater than
//! zero`. Paths inside the file are relative to the file's folder.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

use rtcnc_fieldbus::sim::{
    DeviceConfig, IoConfig, SimulatedJointConfig, SimulatedMachineConfig, SpindleConfig,
    ToolChangerConfig,
};
use rtcnc_motion::Axis;
use rtcnc_servo::ServoLoopConfig;
use serde::Deserialize;

/// Most joints a machine may have (fixed-size messages carry this many).
pub const MAX_JOINTS: usize = 16;

/// A configuration was refused.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file could not be read.
    #[error("{path}: {source}")]
    Read {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// TOML syntax, an unknown key, or a value of the wrong type (the message names the key
    /// and the line).
    #[error("{path}: {message}")]
    Parse {
        /// The file.
        path: String,
        /// The parser's message.
        message: String,
    },
    /// A value is out of range or inconsistent.
    #[error("{key}: {reason}")]
    Invalid {
        /// Dotted key, e.g. `axes.x.max_velocity`.
        key: String,
        /// Why.
        reason: String,
    },
}

impl From<rtcnc_rt::FieldError> for ConfigError {
    fn from(e: rtcnc_rt::FieldError) -> Self {
        ConfigError::Invalid {
            key: e.field,
            reason: e.reason,
        }
    }
}

impl ConfigError {
    /// Stable code.
    pub fn code(&self) -> &'static str {
        match self {
            ConfigError::Read { .. } => "config.read",
            ConfigError::Parse { .. } => "config.parse",
            ConfigError::Invalid { .. } => "config.invalid",
        }
    }

    fn invalid(key: impl Into<String>, reason: impl Into<String>) -> Self {
        ConfigError::Invalid {
            key: key.into(),
            reason: reason.into(),
        }
    }
}

/// Milling or turning machine.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum MachineKind {
    /// A mill, router or gantry.
    #[default]
    Mill,
    /// A lathe (X and Z).
    Lathe,
}

/// Length units a program starts in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum LengthUnits {
    /// Millimetres (G21).
    #[default]
    Mm,
    /// Inches (G20).
    Inch,
}

/// `[machine]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MachineSection {
    /// Shown to the operator.
    pub name: String,
    /// Mill or lathe.
    #[serde(default)]
    pub kind: MachineKind,
    /// Lathe: X words are diameters (G7).
    #[serde(default)]
    pub diameter_mode: bool,
    /// Units a program starts in.
    #[serde(default)]
    pub units: LengthUnits,
    /// The machine has a pallet shuttle: M30 and M60 ask the machine logic to exchange
    /// the pallets through the user M-code hand-shake, with code 60, before the program
    /// ends (M30) or stops (M60). Without one (the default) M30 just ends and rewinds the
    /// program, as LinuxCNC does.
    #[serde(default)]
    pub pallet_shuttle: bool,
}

/// `[axes.<letter>]`: one axis of the program (mm, or degrees for A B C).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisConfig {
    /// Names of the joints this axis drives (a gantry axis lists several).
    pub joints: Vec<String>,
    /// Lower soft limit (machine coordinates).
    pub min_position: f64,
    /// Upper soft limit.
    pub max_position: f64,
    /// Units/s.
    pub max_velocity: f64,
    /// Units/s².
    pub max_acceleration: f64,
    /// Units/s³.
    pub max_jerk: f64,
    /// Deceleration of a quick stop (e-stop, hard limit); default `max_acceleration`.
    #[serde(default)]
    pub quick_stop_acceleration: Option<f64>,
    /// Jerk of a quick stop; default `max_jerk`.
    #[serde(default)]
    pub quick_stop_jerk: Option<f64>,
    /// Jog speed (units/s); default a tenth of `max_velocity`.
    #[serde(default)]
    pub jog_velocity: Option<f64>,
}

/// A joint's homing sequence (LinuxCNC's order: search the switch, back off, latch on the
/// index, move to the home position).
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HomingConfig {
    /// Joints with a lower sequence number home first; joints of one gantry axis share one.
    #[serde(default)]
    pub sequence: u8,
    /// Velocity of the switch search (its sign is the direction towards the switch).
    pub search_velocity: f64,
    /// Speed of the back-off and of the index search (positive).
    pub latch_velocity: f64,
    /// Latch on the encoder index after backing off the switch (else on the switch edge).
    #[serde(default = "yes")]
    pub use_index: bool,
    /// Machine position the latched point gets.
    #[serde(default)]
    pub latch_position: f64,
    /// Where the joint goes after homing (machine position).
    #[serde(default)]
    pub home_position: f64,
}

fn yes() -> bool {
    true
}

/// `[[joints]]`: one drive.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointConfig {
    /// Name (faults name it), e.g. `X0`.
    pub name: String,
    /// Position loop (rtcnc-servo): `loop = "pid"` or `"csp"`.
    pub servo: ServoLoopConfig,
    /// The simulated drive (rtcnc-fieldbus): required with `fieldbus.kind = "sim"` and with
    /// simulated EtherCAT devices (`[fieldbus.simulation]`, its motor), unused on hardware.
    #[serde(default)]
    pub sim: Option<SimulatedJointConfig>,
    /// Homing sequence; absent: the joint is homed where it stands.
    #[serde(default)]
    pub homing: Option<HomingConfig>,
    /// Limits of a joint no axis drives (an independent joint); required for such a joint.
    #[serde(default)]
    pub limits: Option<JointLimitsConfig>,
}

impl JointConfig {
    /// Where the joint stands at power-up, as far as the file knows (the simulated
    /// drive's initial position; 0 on hardware, whose feedback tells).
    pub fn initial_position(&self) -> f64 {
        self.sim.as_ref().map_or(0.0, |s| s.initial_position)
    }
}

/// Limits of an independent joint.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointLimitsConfig {
    /// Lower position limit.
    pub min_position: f64,
    /// Upper position limit.
    pub max_position: f64,
    /// Units/s.
    pub max_velocity: f64,
    /// Units/s².
    pub max_acceleration: f64,
    /// Units/s³.
    pub max_jerk: f64,
}

/// One thread of the task table.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ThreadConfig {
    /// Period, e.g. `"1ms"`, `"100us"`.
    pub period: String,
    /// Executive priority 0..=127, higher first.
    pub priority: i32,
    /// Runs per activation.
    #[serde(default = "one")]
    pub runs: u32,
}

/// An event-triggered task.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EventTaskConfig {
    /// Executive priority 0..=127.
    pub priority: i32,
}

fn one() -> u32 {
    1
}

/// `[tasks]`: periods, priorities and runs per activation. The defaults are the RTX64 table
/// of the seeds at a 1 ms servo period, with the PLC above interpolation as the RT-Linux
/// table puts it.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TasksConfig {
    /// Position control and drive I/O; its period is the servo period.
    pub fieldbus: ThreadConfig,
    /// Machine logic (PLC scan).
    pub machine_logic: ThreadConfig,
    /// Interpolation: one set-point per run; its period must equal the servo period.
    pub interpolation: ThreadConfig,
    /// Look-ahead: feeds the planner's window.
    pub look_ahead: ThreadConfig,
    /// Operator command parsing (urgent channel first).
    pub command_parsing: ThreadConfig,
    /// Status feedback snapshot.
    pub status_feedback: ThreadConfig,
    /// Tool compensation (woken by blocks from the interpreter).
    pub tool_compensation: EventTaskConfig,
    /// Interpreter (woken by a program start, runs while there is room ahead).
    pub interpreter: EventTaskConfig,
    /// Run interpolation as the last function of the fieldbus thread (as LinuxCNC's servo
    /// thread runs its motion controller) instead of in a thread of its own: no wake-up of
    /// a second thread between the exchange and the next set-point. `tasks.interpolation`'s
    /// period and priority are then unused. Unset: in the fieldbus thread when the servo
    /// period is shorter than [`SEPARATE_INTERPOLATION_MIN_PERIOD`], else in its own thread
    /// (see [`TasksConfig::interpolation_in_fieldbus_thread`]).
    pub interpolation_in_fieldbus_thread: Option<bool>,
    /// How far ahead of position control interpolation computes the set-points (a
    /// duration, rounded up to whole servo periods, at most [`MAX_SETPOINT_LEAD`] of
    /// them): a stall of the interpolation thread this long is ridden through. Urgent
    /// commands and faults still act in the next servo period: the set-points not yet
    /// applied are computed again. Unset: [`DEFAULT_SETPOINT_LEAD`] with interpolation in a
    /// thread of its own, one period in the fieldbus thread (the two cannot stall apart).
    pub setpoint_lead: Option<String>,
}

/// The default of `tasks.setpoint_lead` with interpolation in a thread of its own (at most
/// [`MAX_SETPOINT_LEAD`] periods): longer than the stalls of a thread that a virtual
/// machine without a real-time kernel shows (cyclictest here: 5-8 ms; `rtcnc run` has
/// seen 34 ms once while other processes compiled), with room to spare.
pub const DEFAULT_SETPOINT_LEAD: Duration = Duration::from_millis(50);

/// The most servo periods interpolation may run ahead (memory for them is taken at start).
pub const MAX_SETPOINT_LEAD: u64 = 256;

/// The shortest period of a thread. The seeds' fastest real-time task runs every 100 µs; a
/// host without a real-time kernel has wake-up latencies of that order, and set-points
/// differentiated over much shorter periods carry the planner's rounding as huge
/// accelerations and jerks (1 µs: 130 000 000 mm/s³ measured against a 50 000 limit), while
/// virtual time crawls (1 ns: 10^9 periods per simulated second).
pub const MIN_PERIOD: Duration = Duration::from_micros(50);

/// The longest servo period: ten times the seeds' 1 ms fieldbus cycle.
pub const MAX_SERVO_PERIOD: Duration = Duration::from_millis(10);

/// The longest period of any other thread.
pub const MAX_THREAD_PERIOD: Duration = Duration::from_secs(1);

/// The shortest servo period at which interpolation runs in a thread of its own unless the
/// configuration says otherwise. A thread of its own must wake within the four periods
/// position control can bridge by extrapolating; on a virtual machine without a real-time
/// kernel the wake-up latency has a tail of 1 to 2 ms (cyclictest at 100 µs), which four
/// periods of 100 µs cannot cover and four of 0.5 ms can.
pub const SEPARATE_INTERPOLATION_MIN_PERIOD: Duration = Duration::from_micros(500);

impl TasksConfig {
    /// Whether interpolation runs as the last function of the fieldbus thread: as
    /// configured, else when the servo period (`servo_period`) is shorter than
    /// [`SEPARATE_INTERPOLATION_MIN_PERIOD`].
    pub fn interpolation_in_fieldbus_thread(&self, servo_period: Duration) -> bool {
        self.interpolation_in_fieldbus_thread
            .unwrap_or(servo_period < SEPARATE_INTERPOLATION_MIN_PERIOD)
    }

    /// `setpoint_lead` in whole servo periods (at least one), or why it is refused.
    pub fn setpoint_lead_periods(&self, servo_period: Duration) -> Result<u64, ConfigError> {
        let lead = match &self.setpoint_lead {
            Some(text) => rtcnc_rt::parse_duration(text)
                .map_err(|e| ConfigError::invalid("tasks.setpoint_lead", e.to_string()))?,
            None if self.interpolation_in_fieldbus_thread(servo_period) => servo_period,
            None => DEFAULT_SETPOINT_LEAD.min(servo_period * MAX_SETPOINT_LEAD as u32),
        };
        let periods = lead
            .as_nanos()
            .div_ceil(servo_period.as_nanos().max(1))
            .max(1);
        if periods > u128::from(MAX_SETPOINT_LEAD) {
            return Err(ConfigError::invalid(
                "tasks.setpoint_lead",
                format!(
                    "{} servo periods; at most {MAX_SETPOINT_LEAD} (a shorter lead, or a longer servo period)",
                    periods
                ),
            ));
        }
        Ok(periods as u64)
    }
}

impl Default for TasksConfig {
    fn default() -> Self {
        let t = |period: &str, priority, runs| ThreadConfig {
            period: period.into(),
            priority,
            runs,
        };
        TasksConfig {
            fieldbus: t("1ms", 126, 1),
            machine_logic: t("1ms", 125, 1),
            interpolation: t("1ms", 124, 1),
            look_ahead: t("1ms", 120, 4),
            command_parsing: t("1ms", 117, 4),
            status_feedback: t("1ms", 110, 1),
            tool_compensation: EventTaskConfig { priority: 119 },
            interpreter: EventTaskConfig { priority: 20 },
            interpolation_in_fieldbus_thread: None,
            setpoint_lead: None,
        }
    }
}

/// `[fieldbus]`: `kind` chooses the drive I/O; the other keys are that kind's.
#[derive(Debug, Clone)]
pub struct FieldbusConfig {
    /// `sim` (the in-process simulated machine) or `ethercat` (the EtherCAT master).
    pub kind: FieldbusKind,
    /// Simulated machine: longest integration step (s).
    pub substep_s: Option<f64>,
    /// Simulated machine: computation + DAC delay of velocity and torque commands (s).
    pub command_delay_s: Option<f64>,
    /// Simulated machine: the e-stop input removes drive power.
    pub estop_removes_power: Option<bool>,
    /// Simulated machine: communication watchdog of the drives (s).
    pub communication_watchdog_s: Option<f64>,
    /// Simulated machine: latency of the drives' touch-probe latch (s).
    pub touch_probe_latency_s: Option<f64>,
    /// Simulated machine: devices on the digital I/O (`[[fieldbus.devices]]`, rtcnc-fieldbus'
    /// `DeviceConfig`: e-stop contact, door, delayed inputs, carousel).
    pub devices: Vec<DeviceConfig>,
    /// `kind = "ethercat"`: the master's configuration and, for a machine without hardware,
    /// its simulated devices.
    pub ethercat: Option<EthercatSection>,
}

/// `[fieldbus]` with `kind = "ethercat"`.
#[derive(Debug, Clone)]
pub struct EthercatSection {
    /// Every key of the section but `kind` and `simulation`: `rtcnc-ethercat`'s
    /// configuration (interface, working-counter limit, distributed clocks, the devices in
    /// bus order with their identities and PDO mapping).
    pub master: rtcnc_ethercat::EthercatConfig,
    /// `[fieldbus.simulation]`: the devices are simulated in this process (rtcnc-ecat-slave-sim
    /// on an in-process link) instead of being on `interface`; their motors are the
    /// joints' `sim` drives.
    pub simulation: Option<rtcnc_ethercat::SimulationConfig>,
}

/// The simulated machine's keys of `[fieldbus]`.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct SimulatedBusKeys {
    #[serde(default)]
    substep_s: Option<f64>,
    #[serde(default)]
    command_delay_s: Option<f64>,
    #[serde(default)]
    estop_removes_power: Option<bool>,
    #[serde(default)]
    communication_watchdog_s: Option<f64>,
    #[serde(default)]
    touch_probe_latency_s: Option<f64>,
    #[serde(default)]
    devices: Vec<DeviceConfig>,
}

impl<'de> Deserialize<'de> for FieldbusConfig {
    /// `kind` first, then the rest of the table as that kind's keys: an unknown key (or a
    /// key of the other kind) is refused with its name and path below `fieldbus`.
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        use serde::de::Error as _;
        let mut table = toml::Table::deserialize(deserializer)?;
        let kind = table
            .remove("kind")
            .ok_or_else(|| D::Error::missing_field("kind"))?;
        let kind = FieldbusKind::deserialize(kind)
            .map_err(|e| D::Error::custom(format!("fieldbus.kind: {}", e.message())))?;
        fn keys<T: serde::de::DeserializeOwned>(
            value: toml::Value,
            section: &str,
        ) -> Result<T, String> {
            serde_path_to_error::deserialize(value).map_err(|e| {
                let path = e.path().to_string();
                let message = e.inner().message();
                if path == "." {
                    format!("{section}: {message}")
                } else {
                    format!("{section}.{path}: {message}")
                }
            })
        }
        match kind {
            FieldbusKind::Sim => {
                let k: SimulatedBusKeys =
                    keys(toml::Value::Table(table), "fieldbus").map_err(D::Error::custom)?;
                Ok(FieldbusConfig {
                    kind,
                    substep_s: k.substep_s,
                    command_delay_s: k.command_delay_s,
                    estop_removes_power: k.estop_removes_power,
                    communication_watchdog_s: k.communication_watchdog_s,
                    touch_probe_latency_s: k.touch_probe_latency_s,
                    devices: k.devices,
                    ethercat: None,
                })
            }
            FieldbusKind::Ethercat => {
                let simulation = match table.remove("simulation") {
                    Some(value) => Some(
                        keys::<rtcnc_ethercat::SimulationConfig>(value, "fieldbus.simulation")
                            .map_err(D::Error::custom)?,
                    ),
                    None => None,
                };
                let master =
                    keys(toml::Value::Table(table), "fieldbus").map_err(D::Error::custom)?;
                Ok(FieldbusConfig {
                    kind,
                    substep_s: None,
                    command_delay_s: None,
                    estop_removes_power: None,
                    communication_watchdog_s: None,
                    touch_probe_latency_s: None,
                    devices: Vec::new(),
                    ethercat: Some(EthercatSection { master, simulation }),
                })
            }
        }
    }
}

/// Which fieldbus back-end.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FieldbusKind {
    /// Simulated machine in the process.
    Sim,
    /// EtherCAT with CiA 402 drives.
    Ethercat,
}

/// `[spindle]`.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpindleSection {
    /// Highest speed (rpm).
    pub max_speed_rpm: f64,
    /// Simulated spindle: ramp (rpm/s).
    #[serde(default = "spindle_ramp")]
    pub acceleration_rpm_per_s: f64,
    /// Simulated spindle: jerk of the ramp (rpm/s²).
    #[serde(default = "spindle_jerk")]
    pub jerk_rpm_per_s2: f64,
    /// At-speed window, fraction of the command.
    #[serde(default = "spindle_tolerance")]
    pub at_speed_tolerance: f64,
    /// Simulated spindle: speed of an orientation (M19) once stopped (rpm).
    #[serde(default = "orient_speed")]
    pub orient_speed_rpm: f64,
    /// Simulated spindle: oriented within this many degrees.
    #[serde(default = "orient_tolerance")]
    pub orient_tolerance_deg: f64,
    /// What an S word above `max_speed_rpm` does.
    #[serde(default)]
    pub over_speed: OverSpeed,
}

/// `spindle.over_speed`: what an S word above the spindle's highest speed does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum OverSpeed {
    /// Error in program at the S word's block: the program stops before it.
    #[default]
    Refuse,
    /// The spindle runs at `max_speed_rpm`, and the operator gets a message when the
    /// machine reaches the block.
    Clamp,
}

fn orient_speed() -> f64 {
    SpindleConfig::default().orient_speed_rpm
}
fn orient_tolerance() -> f64 {
    SpindleConfig::default().orient_tolerance_deg
}

fn spindle_ramp() -> f64 {
    SpindleConfig::default().acceleration_rpm_per_s
}
fn spindle_jerk() -> f64 {
    SpindleConfig::default().jerk_rpm_per_s2
}
fn spindle_tolerance() -> f64 {
    SpindleConfig::default().at_speed_tolerance
}

/// `[tool_changer]`.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ToolChangerSection {
    /// Time one change takes (s, simulated changer).
    pub change_time_s: f64,
    /// Tool in the spindle at power-up.
    #[serde(default)]
    pub initial_tool: u32,
}

/// Most program inputs or outputs of one kind (`io.program_*`); the kernel's images carry
/// the first 16 analogue points.
pub const MAX_PROGRAM_IO: usize = 16;

/// `[io]`: process-image sizes and the map from program I/O numbers to image points.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IoSection {
    /// Digital inputs in the image.
    #[serde(default = "sixteen")]
    pub digital_inputs: usize,
    /// Digital outputs in the image.
    #[serde(default = "sixteen")]
    pub digital_outputs: usize,
    /// Analogue inputs.
    #[serde(default = "four")]
    pub analog_inputs: usize,
    /// Analogue outputs.
    #[serde(default = "four")]
    pub analog_outputs: usize,
    /// M62..M65 `P n` drive digital output `program_outputs[n]`.
    #[serde(default)]
    pub program_outputs: Vec<usize>,
    /// M66 `P n` reads digital input `program_inputs[n]`.
    #[serde(default)]
    pub program_inputs: Vec<usize>,
    /// M66 `E n` reads analogue input `program_analog_inputs[n]`.
    #[serde(default)]
    pub program_analog_inputs: Vec<usize>,
    /// M67/M68 `E n` drive analogue output `program_analog_outputs[n]`.
    #[serde(default)]
    pub program_analog_outputs: Vec<usize>,
    /// The feed stop switch (digital input): while it is on, the path holds (M53 P0 lets
    /// the program ignore it, M53 P1 heeds it again; heeded by default).
    #[serde(default)]
    pub feed_stop_input: Option<usize>,
    /// The touch probe's digital input (G38.2-G38.5).
    #[serde(default)]
    pub probe_input: Option<usize>,
    /// The analogue input of adaptive feed (M52 P1): its value, clamped to 0..=1,
    /// multiplies the feed of feed moves.
    #[serde(default)]
    pub adaptive_feed_input: Option<usize>,
}

fn sixteen() -> usize {
    16
}
fn four() -> usize {
    4
}

impl Default for IoSection {
    fn default() -> Self {
        IoSection {
            digital_inputs: 16,
            digital_outputs: 16,
            analog_inputs: 4,
            analog_outputs: 4,
            program_outputs: Vec::new(),
            program_inputs: Vec::new(),
            program_analog_inputs: Vec::new(),
            program_analog_outputs: Vec::new(),
            feed_stop_input: None,
            probe_input: None,
            adaptive_feed_input: None,
        }
    }
}

/// `[plc]`: the machine logic program and its signal map (rtcnc-plc's `PlcConfig`).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlcSection {
    /// Structured Text file, relative to the configuration file.
    pub program: PathBuf,
    /// Machine-interface signal name → PLC variable.
    #[serde(default)]
    pub signals: BTreeMap<String, String>,
    /// PLC variable → value on a PLC fault.
    #[serde(default)]
    pub safe_values: BTreeMap<String, String>,
    /// Auxiliary axes of the PLCopen motion blocks: AXIS_REF variable → the joint whose
    /// drive follows it.
    #[serde(default)]
    pub axes: BTreeMap<String, PlcAxisSection>,
}

/// Most auxiliary axes the PLC may drive (the logic's outputs carry this many set-points).
pub const MAX_PLC_AXES: usize = 4;

/// `[plc.axes.VAR]`: an auxiliary axis (AXIS_REF variable `VAR`) on a joint of its own.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlcAxisSection {
    /// The joint: one no axis drives and that has no homing of the kernel's (MC_Home
    /// homes it); its `limits` are the axis's limits for the motion blocks.
    pub joint: String,
    /// A modulo (rotary) axis of this period (e.g. 360): the PLC counts its position from
    /// 0 up to it and ignores the joint's min/max position.
    #[serde(default)]
    pub modulo: Option<f64>,
}

impl MachineConfig {
    /// The PLC's auxiliary axes: AXIS_REF variable, joint index and the motion blocks'
    /// limits (the joint's own). Empty without `[plc.axes]`; a joint that does not fit
    /// is refused by [`MachineConfig::validate`].
    ///
    /// Real-time: no (set-up: allocates).
    pub fn plc_axes(&self) -> Vec<(String, usize, rtcnc_plc::AxisConfig)> {
        let Some(plc) = &self.plc else {
            return Vec::new();
        };
        plc.axes
            .iter()
            .filter_map(|(var, a)| {
                let j = self.joints.iter().position(|j| j.name == a.joint)?;
                let l = self.joints[j].limits?;
                Some((
                    var.clone(),
                    j,
                    rtcnc_plc::AxisConfig {
                        velocity: l.max_velocity,
                        acceleration: l.max_acceleration,
                        jerk: l.max_jerk,
                        min_position: a.modulo.is_none().then_some(l.min_position),
                        max_position: a.modulo.is_none().then_some(l.max_position),
                        modulo: a.modulo,
                    },
                ))
            })
            .collect()
    }

    /// Each PLC axis names a joint that no axis drives, has no homing of the kernel's and
    /// no other PLC axis takes.
    fn validate_plc_axes(&self, driven: &[Option<String>]) -> Result<(), ConfigError> {
        let Some(plc) = &self.plc else {
            return Ok(());
        };
        if plc.axes.len() > MAX_PLC_AXES {
            return Err(ConfigError::invalid(
                "plc.axes",
                format!("at most {MAX_PLC_AXES} auxiliary axes are supported"),
            ));
        }
        let mut taken: Vec<usize> = Vec::new();
        for (var, a) in &plc.axes {
            let key = format!("plc.axes.{var}.joint");
            let Some(j) = self.joints.iter().position(|j| j.name == a.joint) else {
                return Err(ConfigError::invalid(
                    key,
                    format!("no joint named {}", a.joint),
                ));
            };
            if let Some(letter) = &driven[j] {
                return Err(ConfigError::invalid(
                    key,
                    format!(
                        "joint {} is driven by axis {letter}, not free for the PLC",
                        a.joint
                    ),
                ));
            }
            if self.joints[j].homing.is_some() {
                return Err(ConfigError::invalid(
                    key,
                    format!(
                        "joint {} has a homing sequence; the PLC homes its axes (MC_Home)",
                        a.joint
                    ),
                ));
            }
            if let Some(m) = a.modulo {
                positive_finite(&format!("plc.axes.{var}.modulo"), m)?;
            }
            if taken.contains(&j) {
                return Err(ConfigError::invalid(
                    key,
                    format!("joint {} is taken by another PLC axis", a.joint),
                ));
            }
            taken.push(j);
        }
        Ok(())
    }
}

/// What a deadline miss of a real-time task triggers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum MissReactionConfig {
    /// Record and count.
    Count,
    /// Record and print a warning.
    #[default]
    Warn,
    /// Feed hold.
    FeedHold,
    /// Emergency stop.
    Estop,
}

/// `[safety]`.
#[derive(Debug, Clone, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct SafetySection {
    /// Reaction to a deadline miss.
    #[serde(default)]
    pub deadline_miss: MissReactionConfig,
    /// How long a program's path may stand still while it should move (its planner
    /// moving, speed zero, no hold, no dwell, overrides above zero) before the stall
    /// watchdog stops the program with `kernel.motion_stalled` at the line; a duration.
    /// Default [`DEFAULT_STALL_TIMEOUT`].
    #[serde(default)]
    pub stall_timeout: Option<String>,
}

/// The default of `safety.stall_timeout`: far longer than any legitimate standstill of a
/// moving path (an exact stop lasts a period or two).
pub const DEFAULT_STALL_TIMEOUT: Duration = Duration::from_secs(2);

impl SafetySection {
    /// `stall_timeout` in servo periods, or why it is refused.
    pub fn stall_timeout_periods(&self, servo_period: Duration) -> Result<u64, ConfigError> {
        let timeout = match &self.stall_timeout {
            Some(text) => rtcnc_rt::parse_duration(text)
                .map_err(|e| ConfigError::invalid("safety.stall_timeout", e.to_string()))?,
            None => DEFAULT_STALL_TIMEOUT,
        };
        if timeout < Duration::from_millis(10) {
            return Err(ConfigError::invalid(
                "safety.stall_timeout",
                "at least 10 ms (an exact stop stands still for a period or two)",
            ));
        }
        Ok(timeout.as_nanos().div_ceil(servo_period.as_nanos().max(1)) as u64)
    }
}

/// `[files]`: persistent state, relative to the configuration file.
#[derive(Debug, Clone, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct FilesSection {
    /// LinuxCNC-style `.var` parameter file (work offsets, #5161..).
    #[serde(default)]
    pub parameters: Option<PathBuf>,
    /// LinuxCNC-style `.tbl` tool table.
    #[serde(default)]
    pub tool_table: Option<PathBuf>,
    /// The PLC's RETAIN variables: restored at start-up, saved atomically when they change.
    #[serde(default)]
    pub plc_retain: Option<PathBuf>,
}

/// What the machine does when its API process is lost (no heartbeat): a jog always stops.
#[derive(Debug, Clone, Copy, Deserialize, Default, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum OnLoss {
    /// A running program goes on (as LinuxCNC).
    #[default]
    Continue,
    /// Feed hold.
    Hold,
    /// Emergency stop.
    Estop,
}

/// `[hmi]`.
#[derive(Debug, Clone, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct HmiSection {
    /// Reaction to the loss of the API process.
    #[serde(default)]
    pub on_loss: OnLoss,
    /// TLS certificate (PEM) of the API server, relative to the machine file.
    #[serde(default)]
    pub tls_certificate: Option<PathBuf>,
    /// Its private key (PEM).
    #[serde(default)]
    pub tls_key: Option<PathBuf>,
    /// The users file (default: `users.toml` beside the machine file).
    #[serde(default)]
    pub users: Option<PathBuf>,
    /// Where uploaded programs live (default: `programs/` beside the machine file).
    #[serde(default)]
    pub programs: Option<PathBuf>,
}

/// `[motion]`: the path planner's settings.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotionSection {
    /// Largest distance (mm) of the path from the programmed corners under plain `G64`
    /// (no P, or P0), which LinuxCNC blends "at the best speed" with no bound: the planner
    /// blends and smooths at the best speed within this one.
    #[serde(default = "MotionSection::default_blend_tolerance")]
    pub default_blend_tolerance: f64,
}

impl MotionSection {
    fn default_blend_tolerance() -> f64 {
        0.05
    }
}

impl Default for MotionSection {
    fn default() -> Self {
        MotionSection {
            default_blend_tolerance: MotionSection::default_blend_tolerance(),
        }
    }
}

/// `[kinematics]`: how the joints place the tool relative to the work.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KinematicsSection {
    /// `"trivial"` (every joint follows one axis), `"xyzac-trt"` or `"xyzbc-trt"` (a
    /// tilting table with a rotary table on it, LinuxCNC's modules of those names) or
    /// `"xyzbc-head"` (a tilting/rotating spindle head, LinuxCNC's `5axiskins`); the
    /// program switches tool-centre-point control on with M428 and off with M429.
    #[serde(default)]
    pub kind: KinematicsKind,
    /// Where the C axis meets the pivot plane, machine coordinates (mm): LinuxCNC's
    /// `x-rot-point`, `y-rot-point`, `z-rot-point`.
    #[serde(default)]
    pub x_rot_point: f64,
    /// See `x_rot_point`.
    #[serde(default)]
    pub y_rot_point: f64,
    /// See `x_rot_point`.
    #[serde(default)]
    pub z_rot_point: f64,
    /// xyzbc-trt: the B axis's offset along X from the C axis (mm).
    #[serde(default)]
    pub x_offset: f64,
    /// xyzac-trt: the A axis's offset along Y from the C axis (mm).
    #[serde(default)]
    pub y_offset: f64,
    /// The tilting axis's offset along Z from the rot point (mm).
    #[serde(default)]
    pub z_offset: f64,
    /// xyzbc-head: from the head's pivot to the spindle's gauge line (mm), LinuxCNC's
    /// `pivot-length` without the tool length (the tool length in force is added).
    #[serde(default)]
    pub pivot_length: f64,
    /// Largest distance (mm) of the tool tip from the programmed path that the joint-space
    /// chords of a tool-centre-point move take; blending between them takes as much again.
    #[serde(default = "KinematicsSection::default_tolerance")]
    pub tolerance: f64,
}

/// `kinematics.kind`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
pub enum KinematicsKind {
    /// Every joint follows one axis.
    #[default]
    #[serde(rename = "trivial")]
    Trivial,
    /// LinuxCNC's `xyzac-trt-kins`.
    #[serde(rename = "xyzac-trt")]
    XyzacTrt,
    /// LinuxCNC's `xyzbc-trt-kins`.
    #[serde(rename = "xyzbc-trt")]
    XyzbcTrt,
    /// LinuxCNC's `5axiskins` (W = 0).
    #[serde(rename = "xyzbc-head")]
    XyzbcHead,
}

impl KinematicsSection {
    fn default_tolerance() -> f64 {
        0.001
    }

    /// The five-axis kinematics of a table or head machine.
    pub fn five_axis(&self) -> Option<rtcnc_motion::FiveAxisKinematics> {
        use rtcnc_motion::{HeadKinematics, TableKinematics};
        let r = [self.x_rot_point, self.y_rot_point, self.z_rot_point];
        match self.kind {
            KinematicsKind::Trivial => None,
            KinematicsKind::XyzacTrt => {
                Some(TableKinematics::xyzac_trt(r, self.y_offset, self.z_offset).into())
            }
            KinematicsKind::XyzbcTrt => {
                Some(TableKinematics::xyzbc_trt(r, self.x_offset, self.z_offset).into())
            }
            KinematicsKind::XyzbcHead => Some(HeadKinematics::xyzbc_head(self.pivot_length).into()),
        }
    }
}

impl Default for KinematicsSection {
    fn default() -> Self {
        KinematicsSection {
            kind: KinematicsKind::Trivial,
            x_rot_point: 0.0,
            y_rot_point: 0.0,
            z_rot_point: 0.0,
            x_offset: 0.0,
            y_offset: 0.0,
            z_offset: 0.0,
            pivot_length: 0.0,
            tolerance: KinematicsSection::default_tolerance(),
        }
    }
}

/// `[handwheel]`.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HandwheelSection {
    /// Travel per handwheel count at increment ×1 (units).
    pub units_per_count: f64,
}

impl Default for HandwheelSection {
    fn default() -> Self {
        HandwheelSection {
            units_per_count: 0.001,
        }
    }
}

/// The whole machine file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MachineConfig {
    /// `[machine]`.
    pub machine: MachineSection,
    /// `[axes.<letter>]`, letters x y z a b c u v w.
    pub axes: BTreeMap<String, AxisConfig>,
    /// `[[joints]]`.
    pub joints: Vec<JointConfig>,
    /// `[tasks]`.
    #[serde(default)]
    pub tasks: TasksConfig,
    /// `[fieldbus]`.
    pub fieldbus: FieldbusConfig,
    /// `[spindle]`; absent: no spindle (S words are refused at the PLC hand-shake).
    #[serde(default)]
    pub spindle: Option<SpindleSection>,
    /// `[tool_changer]`; absent: a manual change that completes at once.
    #[serde(default)]
    pub tool_changer: Option<ToolChangerSection>,
    /// `[io]`.
    #[serde(default)]
    pub io: IoSection,
    /// `[plc]`; absent: the kernel's direct logic (spindle, coolant, tool change passed
    /// straight to the machine, M100..M199 acknowledged at once).
    #[serde(default)]
    pub plc: Option<PlcSection>,
    /// `[safety]`.
    #[serde(default)]
    pub safety: SafetySection,
    /// `[files]`.
    #[serde(default)]
    pub files: FilesSection,
    /// `[handwheel]`.
    #[serde(default)]
    pub handwheel: HandwheelSection,
    /// `[hmi]`: the operator's surfaces in processes of their own.
    #[serde(default)]
    pub hmi: HmiSection,
    /// `[motion]`.
    #[serde(default)]
    pub motion: MotionSection,
    /// `[kinematics]`.
    #[serde(default)]
    pub kinematics: KinematicsSection,
    /// `[opcua]`: the OPC UA server of the API process; read and checked by
    /// `rtcnc-factory`, which the machine process does not need.
    #[serde(default)]
    pub opcua: Option<toml::Table>,
    /// `[mqtt]`: the MQTT publisher of the API process; read and checked by
    /// `rtcnc-factory`.
    #[serde(default)]
    pub mqtt: Option<toml::Table>,
    /// Folder of the file (paths are relative to it); set by [`MachineConfig::load`].
    #[serde(skip)]
    pub base_dir: PathBuf,
}

/// One axis after validation.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisPlan {
    /// Which axis.
    pub axis: Axis,
    /// Joint indices it drives.
    pub joints: Vec<usize>,
}

impl MachineConfig {
    /// Reads, parses and validates a machine file.
    pub fn load(path: &Path) -> Result<MachineConfig, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
            path: path.display().to_string(),
            source,
        })?;
        let mut config = Self::parse(&text, &path.display().to_string())?;
        config.base_dir = path
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_else(|| PathBuf::from("."));
        Ok(config)
    }

    /// Parses and validates TOML text; `name` appears in parse errors.
    pub fn parse(text: &str, name: &str) -> Result<MachineConfig, ConfigError> {
        let config: MachineConfig = toml::from_str(text).map_err(|e| ConfigError::Parse {
            path: name.to_string(),
            message: e.to_string().trim_end().replace('\n', " "),
        })?;
        config.validate()?;
        Ok(config)
    }

    /// Checks every value; the error names the first refused key. The checks run in
    /// the order below, and the first one that fails is the error reported: the axes'
    /// checks rely on the joints being checked first, and so on down.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.validate_joint_count()?;
        self.validate_fieldbus()?;
        self.validate_joints()?;
        self.validate_simulated_drives()?;
        let driven = self.validate_axes()?;
        self.validate_independent_joints(&driven)?;
        self.validate_plc_axes(&driven)?;
        self.validate_home_positions(&driven)?;
        self.tasks_checked()?;
        self.validate_motion_spindle_and_tool_changer()?;
        self.validate_kinematics()?;
        self.validate_io()?;
        positive_finite("handwheel.units_per_count", self.handwheel.units_per_count)?;
        if self.machine.diameter_mode && self.machine.kind != MachineKind::Lathe {
            return Err(ConfigError::invalid(
                "machine.diameter_mode",
                "only a lathe has a diameter mode",
            ));
        }
        Ok(())
    }

    /// A machine has at least one joint and no more than the kernel's arrays hold.
    fn validate_joint_count(&self) -> Result<(), ConfigError> {
        if self.joints.is_empty() {
            return Err(ConfigError::invalid(
                "joints",
                "at least one joint is needed",
            ));
        }
        if self.joints.len() > MAX_JOINTS {
            return Err(ConfigError::invalid(
                "joints",
                format!("at most {MAX_JOINTS} joints are supported"),
            ));
        }
        Ok(())
    }

    /// Each joint: a unique name, servo gains, homing speeds and positions.
    fn validate_joints(&self) -> Result<(), ConfigError> {
        for (i, j) in self.joints.iter().enumerate() {
            if j.name.is_empty() {
                return Err(ConfigError::invalid(
                    format!("joints[{i}].name"),
                    "must not be empty",
                ));
            }
            if self.joints[..i].iter().any(|o| o.name == j.name) {
                return Err(ConfigError::invalid(
                    format!("joints[{i}].name"),
                    format!("duplicate joint name {:?}", j.name),
                ));
            }
            j.servo.validate().map_err(|e| {
                ConfigError::invalid(format!("joints[{i}].servo.{}", e.field), e.reason)
            })?;
            if let Some(h) = &j.homing {
                positive_finite(
                    &format!("joints[{i}].homing.latch_velocity"),
                    h.latch_velocity,
                )?;
                if !(h.search_velocity.is_finite() && h.search_velocity != 0.0) {
                    return Err(ConfigError::invalid(
                        format!("joints[{i}].homing.search_velocity"),
                        "must be a finite non-zero number (its sign is the search direction)",
                    ));
                }
                finite(
                    &format!("joints[{i}].homing.latch_position"),
                    h.latch_position,
                )?;
                finite(
                    &format!("joints[{i}].homing.home_position"),
                    h.home_position,
                )?;
            }
        }
        Ok(())
    }

    /// The simulated drives, when there is no real EtherCAT bus.
    fn validate_simulated_drives(&self) -> Result<(), ConfigError> {
        let simulated = match &self.fieldbus.ethercat {
            None => true,
            Some(e) => e.simulation.is_some(),
        };
        if simulated {
            self.simulated_machine()?
                .validate()
                .map_err(|e| ConfigError::invalid(sim_key(&e.field), e.reason))?;
        }
        Ok(())
    }

    /// Each axis: its limits, and the joints it drives (each joint by one axis at most).
    /// Returns, for each joint, the letter of the axis that drives it.
    fn validate_axes(&self) -> Result<Vec<Option<String>>, ConfigError> {
        let mut driven = vec![None::<String>; self.joints.len()];
        if self.axes.is_empty() {
            return Err(ConfigError::invalid("axes", "at least one axis is needed"));
        }
        for (letter, a) in &self.axes {
            let key = format!("axes.{letter}");
            if axis_of(letter).is_none() {
                return Err(ConfigError::invalid(
                    key,
                    "unknown axis letter (use x y z a b c u v w, lower case)",
                ));
            }
            for (field, value) in [
                ("max_velocity", a.max_velocity),
                ("max_acceleration", a.max_acceleration),
                ("max_jerk", a.max_jerk),
            ] {
                positive_finite(&format!("{key}.{field}"), value)?;
            }
            // A quick stop (e-stop, hard limit) must brake at least as hard as a normal stop:
            // a softer one would stop far beyond where the normal limits say.
            for (field, value, normal, normal_key) in [
                (
                    "quick_stop_acceleration",
                    a.quick_stop_acceleration,
                    a.max_acceleration,
                    "max_acceleration",
                ),
                ("quick_stop_jerk", a.quick_stop_jerk, a.max_jerk, "max_jerk"),
            ] {
                if let Some(v) = value {
                    positive_finite(&format!("{key}.{field}"), v)?;
                    if v < normal {
                        return Err(ConfigError::invalid(
                            format!("{key}.{field}"),
                            format!(
                                "{v} is below {normal_key} ({normal}): a quick stop must brake at least as hard as a normal one"
                            ),
                        ));
                    }
                }
            }
            if let Some(v) = a.jog_velocity {
                positive_finite(&format!("{key}.jog_velocity"), v)?;
                if v > a.max_velocity {
                    return Err(ConfigError::invalid(
                        format!("{key}.jog_velocity"),
                        format!("{v} is above max_velocity ({})", a.max_velocity),
                    ));
                }
            }
            finite(&format!("{key}.min_position"), a.min_position)?;
            finite(&format!("{key}.max_position"), a.max_position)?;
            if a.min_position >= a.max_position {
                return Err(ConfigError::invalid(
                    format!("{key}.max_position"),
                    "must be greater than min_position",
                ));
            }
            if a.joints.is_empty() {
                return Err(ConfigError::invalid(
                    format!("{key}.joints"),
                    "an axis drives at least one joint",
                ));
            }
            for name in &a.joints {
                let Some(index) = self.joints.iter().position(|j| &j.name == name) else {
                    return Err(ConfigError::invalid(
                        format!("{key}.joints"),
                        format!("no joint named {name:?}"),
                    ));
                };
                if let Some(other) = &driven[index] {
                    return Err(ConfigError::invalid(
                        format!("{key}.joints"),
                        format!("joint {name:?} is already driven by axis {other}"),
                    ));
                }
                driven[index] = Some(letter.clone());
            }
        }
        Ok(driven)
    }

    /// A joint no axis drives is an independent joint: it moves only by homing or an
    /// independent move (the seeds' gantry has three), and needs its own limits.
    fn validate_independent_joints(&self, driven: &[Option<String>]) -> Result<(), ConfigError> {
        for (i, axis) in driven.iter().enumerate() {
            let key = format!("joints[{i}].limits");
            match (axis, &self.joints[i].limits) {
                (None, None) => {
                    return Err(ConfigError::invalid(
                        key,
                        "a joint that no axis drives needs its own limits",
                    ));
                }
                (Some(a), Some(_)) => {
                    return Err(ConfigError::invalid(
                        key,
                        format!("joint is driven by axis {a}, whose limits apply"),
                    ));
                }
                (None, Some(l)) => {
                    for (field, value) in [
                        ("max_velocity", l.max_velocity),
                        ("max_acceleration", l.max_acceleration),
                        ("max_jerk", l.max_jerk),
                    ] {
                        positive_finite(&format!("{key}.{field}"), value)?;
                    }
                    if !(l.min_position.is_finite()
                        && l.max_position.is_finite()
                        && l.min_position < l.max_position)
                    {
                        return Err(ConfigError::invalid(
                            format!("{key}.max_position"),
                            "must be finite and greater than min_position",
                        ));
                    }
                }
                (Some(_), None) => {}
            }
        }
        Ok(())
    }

    /// A joint goes home to a position inside its limits (the switch, and so the latched
    /// position, may lie beyond them).
    fn validate_home_positions(&self, driven: &[Option<String>]) -> Result<(), ConfigError> {
        for (i, joint) in self.joints.iter().enumerate() {
            let Some(h) = &joint.homing else { continue };
            let (min, max) = match (&driven[i], &joint.limits) {
                (Some(letter), _) => {
                    let a = &self.axes[letter];
                    (a.min_position, a.max_position)
                }
                (None, Some(l)) => (l.min_position, l.max_position),
                (None, None) => continue,
            };
            if !(min..=max).contains(&h.home_position) {
                return Err(ConfigError::invalid(
                    format!("joints[{i}].homing.home_position"),
                    format!(
                        "{} is outside the joint's limits {min}..{max}",
                        h.home_position
                    ),
                ));
            }
        }
        Ok(())
    }

    /// A five-axis kinematics: its parameters are finite, its axes (X Y Z, the tilting
    /// axis and C) each drive one joint, and only its own parameters are set.
    fn validate_kinematics(&self) -> Result<(), ConfigError> {
        let k = &self.kinematics;
        let (tilt, unused): (&str, &[&str]) = match k.kind {
            KinematicsKind::Trivial => return Ok(()),
            KinematicsKind::XyzacTrt => ("a", &["x_offset", "pivot_length"]),
            KinematicsKind::XyzbcTrt => ("b", &["y_offset", "pivot_length"]),
            KinematicsKind::XyzbcHead => (
                "b",
                &[
                    "x_rot_point",
                    "y_rot_point",
                    "z_rot_point",
                    "x_offset",
                    "y_offset",
                    "z_offset",
                ],
            ),
        };
        for (key, v) in [
            ("x_rot_point", k.x_rot_point),
            ("y_rot_point", k.y_rot_point),
            ("z_rot_point", k.z_rot_point),
            ("x_offset", k.x_offset),
            ("y_offset", k.y_offset),
            ("z_offset", k.z_offset),
            ("pivot_length", k.pivot_length),
        ] {
            if !v.is_finite() {
                return Err(ConfigError::invalid(
                    format!("kinematics.{key}"),
                    "must be a finite number",
                ));
            }
            if v != 0.0 && unused.contains(&key) {
                return Err(ConfigError::invalid(
                    format!("kinematics.{key}"),
                    "this kinematics has no such parameter",
                ));
            }
        }
        positive_finite("kinematics.tolerance", k.tolerance)?;
        for axis in ["x", "y", "z", tilt, "c"] {
            match self.axes.get(axis) {
                Some(a) if a.joints.len() == 1 => {}
                Some(_) => {
                    return Err(ConfigError::invalid(
                        format!("axes.{axis}.joints"),
                        "a five-axis kinematics drives one joint per axis",
                    ));
                }
                None => {
                    return Err(ConfigError::invalid(
                        "kinematics.kind",
                        format!("needs an axis {}", axis.to_uppercase()),
                    ));
                }
            }
        }
        Ok(())
    }

    /// The blend tolerance, the spindle's speed and the tool change time.
    fn validate_motion_spindle_and_tool_changer(&self) -> Result<(), ConfigError> {
        positive_finite(
            "motion.default_blend_tolerance",
            self.motion.default_blend_tolerance,
        )?;
        if let Some(s) = &self.spindle {
            positive_finite("spindle.max_speed_rpm", s.max_speed_rpm)?;
        }
        if let Some(t) = &self.tool_changer {
            if !(t.change_time_s.is_finite() && t.change_time_s >= 0.0) {
                return Err(ConfigError::invalid(
                    "tool_changer.change_time_s",
                    "must be a finite number, not negative",
                ));
            }
        }
        Ok(())
    }

    /// The program's I/O points and the feed stop and probe inputs lie inside the
    /// machine's I/O image.
    fn validate_io(&self) -> Result<(), ConfigError> {
        for (list, size, key) in [
            (
                &self.io.program_outputs,
                self.io.digital_outputs,
                "io.program_outputs",
            ),
            (
                &self.io.program_inputs,
                self.io.digital_inputs,
                "io.program_inputs",
            ),
            (
                &self.io.program_analog_inputs,
                self.io.analog_inputs.min(MAX_PROGRAM_IO),
                "io.program_analog_inputs",
            ),
            (
                &self.io.program_analog_outputs,
                self.io.analog_outputs.min(MAX_PROGRAM_IO),
                "io.program_analog_outputs",
            ),
        ] {
            if list.len() > MAX_PROGRAM_IO {
                return Err(ConfigError::invalid(
                    key,
                    format!("at most {MAX_PROGRAM_IO} program points"),
                ));
            }
            if let Some(bad) = list.iter().find(|&&i| i >= size) {
                return Err(ConfigError::invalid(
                    key,
                    format!("point {bad} is outside the image of {size}"),
                ));
            }
        }
        for (key, input) in [
            ("io.feed_stop_input", self.io.feed_stop_input),
            ("io.probe_input", self.io.probe_input),
        ] {
            if let Some(i) = input {
                if i >= self.io.digital_inputs.min(64) {
                    return Err(ConfigError::invalid(
                        key,
                        format!(
                            "input {i} is outside the image of {}",
                            self.io.digital_inputs.min(64)
                        ),
                    ));
                }
            }
        }
        if let Some(i) = self.io.adaptive_feed_input {
            let size = self.io.analog_inputs.min(MAX_PROGRAM_IO);
            if i >= size {
                return Err(ConfigError::invalid(
                    "io.adaptive_feed_input",
                    format!("input {i} is outside the image of {size}"),
                ));
            }
        }
        Ok(())
    }

    /// The servo period (the fieldbus thread's period).
    pub fn servo_period(&self) -> Duration {
        rtcnc_rt::parse_duration(&self.tasks.fieldbus.period).unwrap_or(Duration::from_millis(1))
    }

    /// Each thread with its parsed period, checked against the servo period.
    pub fn tasks_checked(
        &self,
    ) -> Result<[(&'static str, Duration, &ThreadConfig); 6], ConfigError> {
        let t = &self.tasks;
        let mut out = [
            ("fieldbus", Duration::ZERO, &t.fieldbus),
            ("machine_logic", Duration::ZERO, &t.machine_logic),
            ("interpolation", Duration::ZERO, &t.interpolation),
            ("look_ahead", Duration::ZERO, &t.look_ahead),
            ("command_parsing", Duration::ZERO, &t.command_parsing),
            ("status_feedback", Duration::ZERO, &t.status_feedback),
        ];
        for (name, period, thread) in &mut out {
            *period = rtcnc_rt::parse_duration(&thread.period)
                .map_err(|e| ConfigError::invalid(format!("tasks.{name}.period"), e.to_string()))?;
            let longest = if *name == "fieldbus" {
                MAX_SERVO_PERIOD
            } else {
                MAX_THREAD_PERIOD
            };
            if *period < MIN_PERIOD || *period > longest {
                return Err(ConfigError::invalid(
                    format!("tasks.{name}.period"),
                    format!("{:?} is outside {MIN_PERIOD:?}..={longest:?}", *period),
                ));
            }
            if !rtcnc_rt::PRIORITY_RANGE.contains(&thread.priority) {
                return Err(ConfigError::invalid(
                    format!("tasks.{name}.priority"),
                    "must be within 0..=127",
                ));
            }
            if thread.runs == 0 {
                return Err(ConfigError::invalid(
                    format!("tasks.{name}.runs"),
                    "must be at least 1",
                ));
            }
        }
        let servo = out[0].1;
        if out[2].1 != servo || t.interpolation.runs != 1 {
            return Err(ConfigError::invalid(
                "tasks.interpolation.period",
                "the interpolation gives one set-point per servo period: its period must equal tasks.fieldbus.period, with runs = 1",
            ));
        }
        t.setpoint_lead_periods(servo)?;
        self.safety.stall_timeout_periods(servo)?;
        for (name, priority) in [
            ("tool_compensation", t.tool_compensation.priority),
            ("interpreter", t.interpreter.priority),
        ] {
            if !rtcnc_rt::PRIORITY_RANGE.contains(&priority) {
                return Err(ConfigError::invalid(
                    format!("tasks.{name}.priority"),
                    "must be within 0..=127",
                ));
            }
        }
        Ok(out)
    }

    /// The axes in canonical order with their joint indices.
    pub fn axis_plan(&self) -> Vec<AxisPlan> {
        let mut plan: Vec<AxisPlan> = self
            .axes
            .iter()
            .filter_map(|(letter, a)| {
                Some(AxisPlan {
                    axis: axis_of(letter)?,
                    joints: a
                        .joints
                        .iter()
                        .filter_map(|n| self.joints.iter().position(|j| &j.name == n))
                        .collect(),
                })
            })
            .collect();
        plan.sort_by_key(|p| p.axis as usize);
        plan
    }

    /// The axis a joint follows, if any (none: an independent joint).
    pub fn joint_axis(&self, joint: usize) -> Option<Axis> {
        self.axis_plan()
            .into_iter()
            .find(|p| p.joints.contains(&joint))
            .map(|p| p.axis)
    }

    /// Limits of an axis by letter.
    pub fn axis(&self, axis: Axis) -> Option<&AxisConfig> {
        self.axes
            .iter()
            .find(|(l, _)| axis_of(l) == Some(axis))
            .map(|(_, a)| a)
    }

    /// The `[fieldbus]` section against the rest: the simulated machine needs every
    /// joint's `sim`; EtherCAT needs one CSP drive per joint, a position loop of `"csp"`,
    /// the I/O image its terminals give, and (simulated) a motor per joint.
    fn validate_fieldbus(&self) -> Result<(), ConfigError> {
        let Some(ethercat) = &self.fieldbus.ethercat else {
            self.simulated_joints()?;
            return Ok(());
        };
        let master = &ethercat.master;
        master
            .validate()
            .map_err(|e| ConfigError::invalid(format!("fieldbus.{}", e.key), e.reason))?;
        let joints = self.joints.len();
        let mut driven = vec![false; joints];
        let (mut inputs, mut outputs) = (0, 0);
        for (n, slave) in master.slaves.iter().enumerate() {
            match slave {
                rtcnc_ethercat::SlaveConfig::Cia402 { joint, .. } => match driven.get_mut(*joint) {
                    Some(d) => *d = true,
                    None => {
                        return Err(ConfigError::invalid(
                            format!("fieldbus.slaves[{n}].joint"),
                            format!("no joint {joint}: the machine has {joints} joints"),
                        ));
                    }
                },
                rtcnc_ethercat::SlaveConfig::Dio {
                    inputs: first_in,
                    outputs: first_out,
                    input_bits,
                    output_bits,
                    ..
                } => {
                    inputs = inputs.max(first_in + input_bits);
                    outputs = outputs.max(first_out + output_bits);
                }
            }
        }
        if let Some(j) = driven.iter().position(|d| !d) {
            return Err(ConfigError::invalid(
                "fieldbus.slaves",
                format!("no drive moves joint {j} ({})", self.joints[j].name),
            ));
        }
        for (i, j) in self.joints.iter().enumerate() {
            if !matches!(j.servo, ServoLoopConfig::Csp(_)) {
                return Err(ConfigError::invalid(
                    format!("joints[{i}].servo.loop"),
                    "EtherCAT drives run in cyclic synchronous position: \"csp\"",
                ));
            }
        }
        // A latch through the drive's touch probe needs its objects in the PDOs: probing
        // (every axis joint's drive latches the probe's edge) and index homing.
        let axis_joint = |j: usize| {
            self.axes
                .values()
                .any(|a| a.joints.iter().any(|name| self.joints[j].name == *name))
        };
        for (n, slave) in master.slaves.iter().enumerate() {
            let rtcnc_ethercat::SlaveConfig::Cia402 {
                name,
                joint,
                rx_pdo,
                tx_pdo,
                ..
            } = slave
            else {
                continue;
            };
            let mut needs = Vec::new();
            if self.joints[*joint].homing.is_some_and(|h| h.use_index) {
                needs.push((
                    rtcnc_ethercat::pdo::LatchUse::IndexPulse,
                    format!("joints[{joint}].homing.use_index"),
                ));
            }
            if self.io.probe_input.is_some() && axis_joint(*joint) {
                needs.push((
                    rtcnc_ethercat::pdo::LatchUse::ProbeInput,
                    "io.probe_input (probing latches every axis joint)".to_string(),
                ));
            }
            for (what, why) in needs {
                if let Some(object) =
                    rtcnc_ethercat::pdo::missing_touch_probe_object(rx_pdo, tx_pdo, what)
                {
                    return Err(ConfigError::invalid(
                        format!("fieldbus.slaves[{n}]"),
                        format!(
                            "drive {name} (joint {joint}) does not map {object}, which {why} needs: add it to the drive's PDOs"
                        ),
                    ));
                }
            }
        }
        for (key, configured, bus) in [
            ("io.digital_inputs", self.io.digital_inputs, inputs),
            ("io.digital_outputs", self.io.digital_outputs, outputs),
            ("io.analog_inputs", self.io.analog_inputs, 0),
            ("io.analog_outputs", self.io.analog_outputs, 0),
        ] {
            if configured != bus {
                return Err(ConfigError::invalid(
                    key,
                    format!("{configured}, but the EtherCAT terminals give {bus}"),
                ));
            }
        }
        for (key, present) in [
            ("spindle", self.spindle.is_some()),
            ("tool_changer", self.tool_changer.is_some()),
        ] {
            if present {
                return Err(ConfigError::invalid(
                    key,
                    "the EtherCAT master carries no spindle or tool changer yet; drive them from the PLC through I/O terminals",
                ));
            }
        }
        if let Some(simulation) = &ethercat.simulation {
            rtcnc_ethercat::simulated_segment(master, &self.simulated_joints()?, simulation)
                .map_err(|e| ConfigError::invalid(format!("fieldbus.{}", e.key), e.reason))?;
        }
        Ok(())
    }

    /// The machine as a run in virtual time can have it (`rtcnc sim`, a program's
    /// preview): the file itself on the simulated machine or on simulated EtherCAT devices;
    /// a machine on real EtherCAT devices becomes the simulated machine with a CSP drive per
    /// joint (its own `sim` where the file gives one), never a second master on its bus.
    pub fn for_virtual_time(&self) -> MachineConfig {
        let mut config = self.clone();
        let on_hardware = matches!(&self.fieldbus.ethercat, Some(e) if e.simulation.is_none());
        if on_hardware {
            let csp: Option<SimulatedJointConfig> = toml::from_str("drive = \"csp\"").ok();
            for joint in &mut config.joints {
                if joint.sim.is_none() {
                    joint.sim = csp.clone();
                }
            }
            config.fieldbus = FieldbusConfig {
                kind: FieldbusKind::Sim,
                substep_s: None,
                command_delay_s: None,
                estop_removes_power: None,
                communication_watchdog_s: None,
                touch_probe_latency_s: None,
                devices: Vec::new(),
                ethercat: None,
            };
        }
        config
    }

    /// Every joint's simulated drive (`joints[i].sim`), refused where one is missing.
    pub fn simulated_joints(&self) -> Result<Vec<SimulatedJointConfig>, ConfigError> {
        self.joints
            .iter()
            .enumerate()
            .map(|(i, j)| {
                j.sim.clone().ok_or_else(|| {
                    ConfigError::invalid(
                        format!("joints[{i}].sim"),
                        "the simulated drive is required on a simulated machine",
                    )
                })
            })
            .collect()
    }

    /// The simulated machine this file describes.
    pub fn simulated_machine(&self) -> Result<SimulatedMachineConfig, ConfigError> {
        let mut sim: SimulatedMachineConfig = toml::from_str("joints = []")
            .map_err(|e| ConfigError::invalid("fieldbus", e.to_string()))?;
        if let Some(v) = self.fieldbus.substep_s {
            sim.substep_s = v;
        }
        if let Some(v) = self.fieldbus.command_delay_s {
            sim.command_delay_s = v;
        }
        if let Some(v) = self.fieldbus.estop_removes_power {
            sim.estop_removes_power = v;
        }
        if let Some(v) = self.fieldbus.communication_watchdog_s {
            sim.communication_watchdog_s = v;
        }
        if let Some(v) = self.fieldbus.touch_probe_latency_s {
            sim.touch_probe_latency_s = v;
        }
        sim.joints = self.simulated_joints()?;
        sim.devices = self.fieldbus.devices.clone();
        if let Some(s) = &self.spindle {
            sim.spindle = SpindleConfig {
                max_speed_rpm: s.max_speed_rpm,
                acceleration_rpm_per_s: s.acceleration_rpm_per_s,
                jerk_rpm_per_s2: s.jerk_rpm_per_s2,
                at_speed_tolerance: s.at_speed_tolerance,
                orient_speed_rpm: s.orient_speed_rpm,
                orient_tolerance_deg: s.orient_tolerance_deg,
            };
        }
        if let Some(t) = &self.tool_changer {
            sim.tool_changer = ToolChangerConfig {
                change_time_s: t.change_time_s,
                initial_tool: t.initial_tool,
            };
        }
        sim.io = IoConfig {
            digital_inputs: self.io.digital_inputs,
            digital_outputs: self.io.digital_outputs,
            analog_inputs: self.io.analog_inputs,
            analog_outputs: self.io.analog_outputs,
        };
        Ok(sim)
    }

    /// A path of the file resolved against the file's folder.
    pub fn resolve(&self, path: &Path) -> PathBuf {
        if path.is_absolute() {
            path.to_path_buf()
        } else {
            self.base_dir.join(path)
        }
    }
}

/// The axis of a lower-case letter.
pub fn axis_of(letter: &str) -> Option<Axis> {
    let mut chars = letter.chars();
    let c = chars.next()?;
    if chars.next().is_some() || !c.is_ascii_lowercase() {
        return None;
    }
    Axis::from_letter(c.to_ascii_uppercase())
}

/// The simulated machine's field names become keys of this file.
fn sim_key(field: &str) -> String {
    // "joints[2].motor.inertia" -> "joints[2].sim.motor.inertia"
    if let Some(rest) = field.strip_prefix("joints[") {
        if let Some(close) = rest.find(']') {
            return format!("joints[{}].sim{}", &rest[..close], &rest[close + 1..]);
        }
    }
    match field.split_once('.') {
        Some(("spindle", f)) => format!("spindle.{f}"),
        Some(("tool_changer", f)) => format!("tool_changer.{f}"),
        Some(("io", f)) => format!("io.{f}"),
        _ => format!("fieldbus.{field}"),
    }
}

fn finite(key: &str, v: f64) -> Result<(), ConfigError> {
    Ok(rtcnc_rt::check::finite(key, v)?)
}

fn positive_finite(key: &str, v: f64) -> Result<(), ConfigError> {
    Ok(rtcnc_rt::check::positive(key, v)?)
}
