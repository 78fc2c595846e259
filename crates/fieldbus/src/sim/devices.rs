//! Small machine devices wired to the general-purpose digital I/O of the simulated machine:
//! the e-stop button's contact, a guard door with a lock, inputs that follow an output
//! after a delay (a pressure switch behind a pump, clamp sensors behind a valve), and a
//! tool carousel turned by an on/off motor. Each is deterministic and advances in whole
//! nanoseconds, so the cycle of every edge can be worked out by hand; none allocates after
//! construction.

use serde::Deserialize;

use crate::sim::config::ConfigError;
use crate::sim::peripherals::seconds_to_ns;

/// Longest delay or index time a device accepts (s).
const LONGEST_TIME_S: f64 = 3600.0;

/// One device on the digital I/O, tagged by `kind` in the configuration.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum DeviceConfig {
    /// The e-stop button's normally closed contact: digital input `input` is TRUE while
    /// the button is released, FALSE while it is pressed
    /// ([`SimulatedMachine::set_estop`](crate::sim::SimulatedMachine::set_estop)).
    EstopContact {
        /// Digital input of the contact.
        input: usize,
    },
    /// A guard door: `closed_input` is TRUE while it is closed. The door is closed unless
    /// the operator (a test) opens it with
    /// [`SimulatedMachine::set_door_open`](crate::sim::SimulatedMachine::set_door_open).
    /// With `lock_output`, a closed door cannot open while that output is on (a solenoid
    /// guard lock); it opens in the first cycle the output is off, if the operator still
    /// pulls it.
    Door {
        /// Digital input of the door-closed switch.
        closed_input: usize,
        /// Digital output of the guard lock (on = locked).
        #[serde(default)]
        lock_output: Option<usize>,
    },
    /// Digital input `input` follows digital output `output` (inverted with `invert`):
    /// it takes a new level once that level has stood at the output for `rise_delay_s`
    /// (input rising) or `fall_delay_s` (input falling). A level that does not stand that
    /// long never reaches the input (a pump pulse too short to build pressure). At power-up
    /// the input has its settled value for an output that is off. A pressure switch behind
    /// a pump, a clamp or unclamp sensor behind a valve, a "valve open" feedback.
    DelayedInput {
        /// Digital output it follows.
        output: usize,
        /// Digital input it drives.
        input: usize,
        /// The input is TRUE while the output is off (e.g. "tool clamped" behind an
        /// unclamp valve).
        #[serde(default)]
        invert: bool,
        /// Time before the input rises (s).
        #[serde(default)]
        rise_delay_s: f64,
        /// Time before the input falls (s).
        #[serde(default)]
        fall_delay_s: f64,
    },
    /// A tool carousel with `pockets` pockets (numbered from 1) on an indexing (Geneva)
    /// drive turned by an on/off motor: while `motor_output` is on, each pocket takes
    /// `index_time_s`, of which the first `in_position_s` after arriving at a pocket are
    /// the dwell with the carousel locked in position; pocket N is followed by pocket 1.
    /// `in_position_input` is TRUE during the dwell; the pocket at the tool-change station
    /// is a binary code on `pocket_inputs` (least significant bit first). Stopping the
    /// motor stops the carousel where it is.
    Carousel {
        /// Digital output of the motor.
        motor_output: usize,
        /// Digital input "in position".
        in_position_input: usize,
        /// Digital inputs of the pocket code, least significant bit first.
        pocket_inputs: Vec<usize>,
        /// Number of pockets.
        pockets: u32,
        /// Time per pocket with the motor on (s).
        index_time_s: f64,
        /// Dwell part of `index_time_s` (s), greater than zero and shorter than it.
        in_position_s: f64,
        /// Pocket at the station at power-up, in position.
        #[serde(default = "first_pocket")]
        initial_pocket: u32,
    },
    /// A touch probe over a flat surface across one joint's travel: `input` is TRUE while
    /// the joint's load stands at or beyond `surface` (below it with `side = "below"`, the
    /// default, above it with `"above"`), in the joint's own position (before the
    /// controller's homing offsets), sensed at the end of every cycle.
    Probe {
        /// Digital input of the probe.
        input: usize,
        /// Joint whose position is sensed.
        joint: usize,
        /// Where the surface is, joint units.
        surface: f64,
        /// Which side of the surface is in contact.
        #[serde(default)]
        side: ProbeSide,
    },
}

/// The side of a probe's surface that is in contact.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ProbeSide {
    /// In contact at and below the surface (a probe moving down onto a part).
    #[default]
    Below,
    /// In contact at and above it.
    Above,
}

fn first_pocket() -> u32 {
    1
}

fn time(field: String, value: f64) -> Result<(), ConfigError> {
    if value.is_finite() && (0.0..=LONGEST_TIME_S).contains(&value) {
        Ok(())
    } else {
        Err(ConfigError {
            field,
            reason: format!("must be a finite number of seconds from 0 to {LONGEST_TIME_S}"),
        })
    }
}

fn refuse(field: String, reason: impl Into<String>) -> ConfigError {
    ConfigError {
        field,
        reason: reason.into(),
    }
}

impl DeviceConfig {
    /// Digital inputs this device drives.
    fn inputs(&self) -> impl Iterator<Item = usize> + '_ {
        let (first, rest): (usize, &[usize]) = match self {
            Self::EstopContact { input }
            | Self::DelayedInput { input, .. }
            | Self::Probe { input, .. } => (*input, &[]),
            Self::Door { closed_input, .. } => (*closed_input, &[]),
            Self::Carousel {
                in_position_input,
                pocket_inputs,
                ..
            } => (*in_position_input, pocket_inputs),
        };
        std::iter::once(first).chain(rest.iter().copied())
    }

    /// Digital outputs this device reads.
    fn outputs(&self) -> Option<usize> {
        match self {
            Self::EstopContact { .. } | Self::Probe { .. } => None,
            Self::Door { lock_output, .. } => *lock_output,
            Self::DelayedInput { output, .. } => Some(*output),
            Self::Carousel { motor_output, .. } => Some(*motor_output),
        }
    }

    fn validate_timing(&self, prefix: &str) -> Result<(), ConfigError> {
        match self {
            Self::EstopContact { .. } | Self::Door { .. } => Ok(()),
            Self::Probe { surface, .. } => {
                if surface.is_finite() {
                    Ok(())
                } else {
                    Err(refuse(
                        format!("{prefix}.surface"),
                        "must be a finite number",
                    ))
                }
            }
            Self::DelayedInput {
                rise_delay_s,
                fall_delay_s,
                ..
            } => {
                time(format!("{prefix}.rise_delay_s"), *rise_delay_s)?;
                time(format!("{prefix}.fall_delay_s"), *fall_delay_s)
            }
            Self::Carousel {
                pocket_inputs,
                pockets,
                index_time_s,
                in_position_s,
                initial_pocket,
                ..
            } => {
                if *pockets == 0 {
                    return Err(refuse(format!("{prefix}.pockets"), "must be at least 1"));
                }
                let bits = pocket_inputs.len();
                if bits > 32 || (bits < 32 && u64::from(*pockets) >= 1u64 << bits) {
                    return Err(refuse(
                        format!("{prefix}.pocket_inputs"),
                        format!("{bits} bits cannot code pocket {pockets}"),
                    ));
                }
                time(format!("{prefix}.index_time_s"), *index_time_s)?;
                if *index_time_s <= 0.0 {
                    return Err(refuse(
                        format!("{prefix}.index_time_s"),
                        "must be greater than zero",
                    ));
                }
                if !(in_position_s.is_finite()
                    && *in_position_s > 0.0
                    && in_position_s < index_time_s)
                {
                    return Err(refuse(
                        format!("{prefix}.in_position_s"),
                        "must be greater than zero and shorter than index_time_s",
                    ));
                }
                if !(1..=*pockets).contains(initial_pocket) {
                    return Err(refuse(
                        format!("{prefix}.initial_pocket"),
                        format!("must be a pocket from 1 to {pockets}"),
                    ));
                }
                Ok(())
            }
        }
    }
}

/// Checks a device list against the I/O counts: points exist, no input is driven twice,
/// at most one door, timings in range. The error names the field (`devices[2].input`).
pub(crate) fn validate_devices(
    devices: &[DeviceConfig],
    digital_inputs: usize,
    digital_outputs: usize,
) -> Result<(), ConfigError> {
    let mut doors = 0;
    let mut driven = vec![false; digital_inputs];
    for (index, device) in devices.iter().enumerate() {
        let prefix = format!("devices[{index}]");
        for input in device.inputs() {
            let Some(slot) = driven.get_mut(input) else {
                return Err(refuse(
                    prefix,
                    format!("digital input {input} is outside the {digital_inputs} inputs"),
                ));
            };
            if *slot {
                return Err(refuse(
                    prefix,
                    format!("digital input {input} is already driven by a device"),
                ));
            }
            *slot = true;
        }
        if let Some(output) = device.outputs() {
            if output >= digital_outputs {
                return Err(refuse(
                    prefix,
                    format!("digital output {output} is outside the {digital_outputs} outputs"),
                ));
            }
        }
        if matches!(device, DeviceConfig::Door { .. }) {
            doors += 1;
            if doors > 1 {
                return Err(refuse(prefix, "a machine has at most one door"));
            }
        }
        device.validate_timing(&prefix)?;
    }
    Ok(())
}

/// What a device sees of the machine in one cycle.
pub(crate) struct DeviceCycle<'a> {
    pub(crate) outputs: &'a [bool],
    pub(crate) estop_pressed: bool,
    pub(crate) door_open_requested: bool,
    pub(crate) period_ns: u64,
}

/// A device's state.
#[derive(Debug, Clone)]
pub(crate) enum Device {
    EstopContact {
        input: usize,
    },
    Door {
        closed_input: usize,
        lock_output: Option<usize>,
        closed: bool,
    },
    DelayedInput {
        output: usize,
        input: usize,
        invert: bool,
        rise_ns: u64,
        fall_ns: u64,
        /// The level at the output (after `invert`) and how long it has stood.
        target: bool,
        held_ns: u64,
        level: bool,
    },
    Carousel {
        motor_output: usize,
        in_position_input: usize,
        /// The code inputs, least significant first (at most 32; built at power-up).
        pocket_inputs: Vec<usize>,
        pockets: u64,
        index_ns: u64,
        in_position_ns: u64,
        pocket: u64,
        phase_ns: u64,
    },
    Probe {
        input: usize,
        joint: usize,
        surface: f64,
        side: ProbeSide,
    },
}

fn output(outputs: &[bool], index: usize) -> bool {
    outputs.get(index).copied().unwrap_or(false)
}

fn set(inputs: &mut [bool], index: usize, value: bool) {
    if let Some(slot) = inputs.get_mut(index) {
        *slot = value;
    }
}

impl Device {
    /// The device at power-up (the configuration was validated).
    pub(crate) fn new(config: &DeviceConfig) -> Self {
        match config {
            DeviceConfig::EstopContact { input } => Self::EstopContact { input: *input },
            DeviceConfig::Door {
                closed_input,
                lock_output,
            } => Self::Door {
                closed_input: *closed_input,
                lock_output: *lock_output,
                closed: true,
            },
            DeviceConfig::DelayedInput {
                output,
                input,
                invert,
                rise_delay_s,
                fall_delay_s,
            } => Self::DelayedInput {
                output: *output,
                input: *input,
                invert: *invert,
                rise_ns: seconds_to_ns(*rise_delay_s),
                fall_ns: seconds_to_ns(*fall_delay_s),
                target: *invert,
                held_ns: 0,
                level: *invert,
            },
            DeviceConfig::Carousel {
                motor_output,
                in_position_input,
                pocket_inputs,
                pockets,
                index_time_s,
                in_position_s,
                initial_pocket,
            } => Self::Carousel {
                motor_output: *motor_output,
                in_position_input: *in_position_input,
                pocket_inputs: pocket_inputs.iter().copied().take(32).collect(),
                pockets: u64::from(*pockets).max(1),
                index_ns: seconds_to_ns(*index_time_s).max(1),
                in_position_ns: seconds_to_ns(*in_position_s),
                pocket: u64::from(*initial_pocket).max(1),
                phase_ns: 0,
            },
            DeviceConfig::Probe {
                input,
                joint,
                surface,
                side,
            } => Self::Probe {
                input: *input,
                joint: *joint,
                surface: *surface,
                side: *side,
            },
        }
    }

    /// A probe's edge within the cycle: whether it closed (else opened) and the share of
    /// the cycle at which its joint crossed the surface, the joints moving from `before`
    /// to `after` (linearly within the cycle).
    pub(crate) fn probe_edge(
        &self,
        before: impl Fn(usize) -> Option<f64>,
        after: impl Fn(usize) -> Option<f64>,
    ) -> Option<(bool, f64)> {
        let Self::Probe {
            joint,
            surface,
            side,
            ..
        } = self
        else {
            return None;
        };
        let (p0, p1) = (before(*joint)?, after(*joint)?);
        let contact = |p: f64| match side {
            ProbeSide::Below => p <= *surface,
            ProbeSide::Above => p >= *surface,
        };
        let (c0, c1) = (contact(p0), contact(p1));
        if c0 == c1 || p0 == p1 {
            return None;
        }
        Some((c1, ((*surface - p0) / (p1 - p0)).clamp(0.0, 1.0)))
    }

    /// Senses the joints' positions at the end of the cycle (the probe).
    pub(crate) fn sense(&self, position: impl Fn(usize) -> Option<f64>, inputs: &mut [bool]) {
        if let Self::Probe {
            input,
            joint,
            surface,
            side,
        } = self
        {
            let contact = position(*joint).is_some_and(|p| match side {
                ProbeSide::Below => p <= *surface,
                ProbeSide::Above => p >= *surface,
            });
            set(inputs, *input, contact);
        }
    }

    /// Advances the device by one cycle with the outputs of this exchange, and writes its
    /// inputs as they are at the end of the cycle. Returns whether it stands still: another
    /// cycle with the same outputs, e-stop and door request would change none of its inputs
    /// nor anything it reports (the time a delayed input has held the level it shows does
    /// not count: it matters only once the output changes, and that starts it afresh).
    pub(crate) fn cycle(&mut self, cycle: &DeviceCycle<'_>, inputs: &mut [bool]) -> bool {
        match self {
            Self::EstopContact { input } => {
                set(inputs, *input, !cycle.estop_pressed);
                true
            }
            Self::Door {
                closed_input,
                lock_output,
                closed,
            } => {
                let locked = lock_output.is_some_and(|o| output(cycle.outputs, o));
                *closed = !cycle.door_open_requested || (*closed && locked);
                set(inputs, *closed_input, *closed);
                // closed = !request || (closed && locked) is its own fixed point.
                true
            }
            Self::DelayedInput {
                output: source,
                input,
                invert,
                rise_ns,
                fall_ns,
                target,
                held_ns,
                level,
            } => {
                let now = output(cycle.outputs, *source) != *invert;
                if now != *target {
                    *target = now;
                    *held_ns = 0;
                }
                *held_ns = held_ns.saturating_add(cycle.period_ns);
                let delay = if *target { *rise_ns } else { *fall_ns };
                if *held_ns >= delay {
                    *level = *target;
                }
                set(inputs, *input, *level);
                *level == *target
            }
            // Sensed after the joints have moved (`sense`).
            Self::Probe { .. } => true,
            Self::Carousel {
                motor_output,
                in_position_input,
                pocket_inputs,
                pockets,
                index_ns,
                in_position_ns,
                pocket,
                phase_ns,
            } => {
                let turning = output(cycle.outputs, *motor_output);
                if turning {
                    let phase = phase_ns.saturating_add(cycle.period_ns);
                    let advanced = (phase / *index_ns) % *pockets;
                    *phase_ns = phase % *index_ns;
                    *pocket = (*pocket - 1 + advanced) % *pockets + 1;
                }
                set(inputs, *in_position_input, *phase_ns < *in_position_ns);
                for (bit, &input) in pocket_inputs.iter().enumerate() {
                    set(inputs, input, (*pocket >> bit) & 1 != 0);
                }
                !turning
            }
        }
    }

    /// Whether the door is closed, for a door.
    pub(crate) fn door_closed(&self) -> Option<bool> {
        match self {
            Self::Door { closed, .. } => Some(*closed),
            _ => None,
        }
    }

    /// The pocket at the station, for a carousel.
    pub(crate) fn carousel_pocket(&self) -> Option<u32> {
        match self {
            Self::Carousel { pocket, .. } => u32::try_from(*pocket).ok(),
            _ => None,
        }
    }
}
