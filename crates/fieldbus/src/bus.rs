use crate::image::{ProcessInputs, ProcessLayout, ProcessOutputs};

/// Why a cyclic exchange failed.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum FieldbusError {
    /// No answer from the bus this cycle; the inputs were not updated.
    #[error("fieldbus communication lost: no process data this cycle")]
    CommunicationLost,
    /// A process image does not match the bus's layout.
    #[error("process image {image}: {found} {what}, the bus has {expected}")]
    ImageMismatch {
        /// "outputs" or "inputs".
        image: &'static str,
        /// Which part: "joints", "digital", "analog".
        what: &'static str,
        /// Length the bus expects.
        expected: usize,
        /// Length passed in.
        found: usize,
    },
    /// The cycle period was not a positive finite number of seconds in range.
    #[error("cycle period {period_s} s is not a positive finite number of at most 1 s")]
    InvalidPeriod {
        /// The period passed in (seconds).
        period_s: f64,
    },
    /// The bus answered, but with a wrong working counter (some device did not take part)
    /// `consecutive` cycles in a row: the limit the configuration allows.
    #[error(
        "fieldbus working counter {received} instead of {expected}, {consecutive} cycles in a row"
    )]
    WorkingCounter {
        /// The working counter the devices should return.
        expected: u16,
        /// The one that came back last.
        received: u16,
        /// Wrong or missing answers in a row.
        consecutive: u32,
    },
    /// A device left the operational state (EtherCAT: its AL state, with the AL status
    /// code it gives as the reason).
    #[error(
        "fieldbus device {position} ({name}) is in {state}: AL status code {code:#06x}, {reason}"
    )]
    DeviceState {
        /// Position of the device on the bus (0 is the first).
        position: u16,
        /// The device's name in the configuration.
        name: &'static str,
        /// The state it is in.
        state: &'static str,
        /// The reason code it gives (0 if none).
        code: u16,
        /// The code's meaning.
        reason: &'static str,
    },
    /// The network link (cable, port) is down.
    #[error("fieldbus link down: {interface}")]
    LinkDown {
        /// The network interface.
        interface: &'static str,
    },
}

impl FieldbusError {
    /// A stable machine-readable code.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn code(&self) -> &'static str {
        match self {
            Self::CommunicationLost => "fieldbus.communication_lost",
            Self::ImageMismatch { .. } => "fieldbus.image_mismatch",
            Self::InvalidPeriod { .. } => "fieldbus.invalid_period",
            Self::WorkingCounter { .. } => "fieldbus.working_counter",
            Self::DeviceState { .. } => "fieldbus.device_state",
            Self::LinkDown { .. } => "fieldbus.link_down",
        }
    }
}

/// Drives and I/O reached through one cyclic exchange per servo cycle: the simulated
/// machine, or an EtherCAT master with CiA 402 drives (`rtcnc-ethercat`).
///
/// The controller's cycle is: read the inputs of the last exchange, compute (servo loops,
/// machine logic), write the outputs, call [`exchange`](Fieldbus::exchange). The exchange
/// sends the outputs and fills the inputs with the machine's state at the end of the cycle
/// (for the simulated machine: after integrating it over `period_s`).
///
/// Implementations allocate nothing in `exchange`, never panic on data, and check its
/// arguments with [`check_exchange`] (a bus that hands the exchange to another leaves it to
/// that one).
pub trait Fieldbus {
    /// The shape of the process images this bus exchanges.
    ///
    /// Real-time: yes (no allocation, no blocking).
    fn layout(&self) -> &ProcessLayout;

    /// One cyclic exchange: apply `outputs` for the next `period_s` seconds and read the
    /// inputs back into `inputs`.
    ///
    /// Real-time: yes (no allocation, no blocking).
    fn exchange(
        &mut self,
        period_s: f64,
        outputs: &ProcessOutputs,
        inputs: &mut ProcessInputs,
    ) -> Result<(), FieldbusError>;

    /// For a bus with its own clock (EtherCAT distributed clocks): how far (ns) the last
    /// exchange came after the instant in the bus cycle it aims for; negative when early.
    /// A periodic thread that moves its next wake-up by minus a filtered share of this stays
    /// aligned to the bus clock. `None`: the bus follows the caller's timing (the simulated
    /// machine), or the last exchange measured nothing (its frame was lost).
    ///
    /// Real-time: yes (no allocation, no blocking).
    fn cycle_phase_error_ns(&self) -> Option<i64> {
        None
    }

    /// The caller's clock (ns since it started), given just before each exchange. A bus
    /// whose devices are simulated in the same process on a virtual clock takes it as their
    /// time, so that they run in the caller's time, virtual or real, and follow its phase
    /// corrections; a bus on hardware, and the simulated machine (which integrates
    /// `period_s`), ignore it.
    ///
    /// Real-time: yes (no allocation, no blocking).
    fn set_time_ns(&mut self, now_ns: u64) {
        let _ = now_ns;
    }

    /// Whether the last exchange brought fresh inputs. False when it rode through a lost
    /// frame or a wrong working counter below the bus's limit: the inputs are then those of
    /// the last good cycle, and a position loop must not read the set-point's progress
    /// since as following error.
    ///
    /// Real-time: yes (no allocation, no blocking).
    fn inputs_fresh(&self) -> bool {
        true
    }
}

/// Checks the arguments of [`Fieldbus::exchange`] the same way for every bus: both images
/// have the layout's shape ([`FieldbusError::ImageMismatch`]), then the period is a finite
/// number of seconds in (0, 1] ([`FieldbusError::InvalidPeriod`]). A bus calls it first
/// and exchanges nothing when it fails.
///
/// Real-time: yes (no allocation, no blocking).
pub fn check_exchange(
    layout: &ProcessLayout,
    period_s: f64,
    outputs: &ProcessOutputs,
    inputs: &ProcessInputs,
) -> Result<(), FieldbusError> {
    check_images(layout, outputs, inputs)?;
    if !(period_s.is_finite() && period_s > 0.0 && period_s <= 1.0) {
        return Err(FieldbusError::InvalidPeriod { period_s });
    }
    Ok(())
}

/// Checks that both images have the layout's shape.
fn check_images(
    layout: &ProcessLayout,
    outputs: &ProcessOutputs,
    inputs: &ProcessInputs,
) -> Result<(), FieldbusError> {
    check_length(
        "outputs",
        "joints",
        layout.joints.len(),
        outputs.joints.len(),
    )?;
    check_length(
        "outputs",
        "digital",
        layout.digital_outputs,
        outputs.digital.len(),
    )?;
    check_length(
        "outputs",
        "analog",
        layout.analog_outputs,
        outputs.analog.len(),
    )?;
    check_length("inputs", "joints", layout.joints.len(), inputs.joints.len())?;
    check_length(
        "inputs",
        "digital",
        layout.digital_inputs,
        inputs.digital.len(),
    )?;
    check_length(
        "inputs",
        "analog",
        layout.analog_inputs,
        inputs.analog.len(),
    )
}

/// One part of an image against the layout. Inlined, a matching image costs a comparison
/// per part (a table of the six parts cost a hundred instructions every exchange).
#[inline]
fn check_length(
    image: &'static str,
    what: &'static str,
    expected: usize,
    found: usize,
) -> Result<(), FieldbusError> {
    if expected == found {
        Ok(())
    } else {
        Err(FieldbusError::ImageMismatch {
            image,
            what,
            expected,
            found,
        })
    }
}
