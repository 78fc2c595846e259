//! What sits behind a slave controller: the device's application (a CiA 402 drive, a
//! digital I/O terminal). The slave controller calls it on state changes, SDO downloads and
//! every process-data cycle.

use std::any::Any;

use crate::dictionary::Dictionary;
use crate::esc::AlState;
use crate::sii::SiiContents;

/// What the slave controller knows when the master asks for a state change.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TransitionContext {
    /// Length the master gave the outputs sync manager (SM2), 0 if disabled.
    pub outputs_len: usize,
    /// Length the master gave the inputs sync manager (SM3), 0 if disabled.
    pub inputs_len: usize,
    /// The SYNC0 cycle time (ns) when the master activated SYNC0.
    pub sync0_cycle_ns: Option<u32>,
}

/// A device application.
pub trait Application: Send {
    /// The EEPROM contents (identity, mailbox, sync managers, default PDOs).
    fn sii(&self) -> SiiContents;

    /// The object dictionary, for devices with a CoE mailbox.
    fn dictionary(&self) -> Option<&Dictionary>;

    /// An SDO download: the generic checks of the dictionary, then the device's own; the
    /// value is stored on success. Returns the abort code otherwise.
    fn download(
        &mut self,
        index: u16,
        sub_index: u8,
        data: &[u8],
        state: AlState,
    ) -> Result<(), u32>;

    /// The process data lengths (outputs, inputs) in bytes of the current PDO mapping.
    fn process_data_len(&self) -> (usize, usize);

    /// The master asks for `to`; an error is the AL status code refusing it.
    fn check_transition(&mut self, to: AlState, context: &TransitionContext) -> Result<(), u16>;

    /// The system time (ns, the distributed clock's) at which the coming [`cycle`](Self::cycle)
    /// starts: devices that time events within a cycle (a drive's touch probe) need it.
    fn begin_cycle(&mut self, system_ns: u64) {
        let _ = system_ns;
    }

    /// One process-data cycle of `period_s` seconds (a SYNC0 event, or an outputs write in
    /// free run): `outputs` are the master's (`None` outside OP, where outputs are not
    /// applied); the device writes `inputs`.
    fn cycle(&mut self, period_s: f64, outputs: Option<&[u8]>, inputs: &mut [u8]);

    /// Puts a device fault (CiA 402 error code) in, or takes it out with `None`; returns
    /// false if the device has no such fault.
    fn inject_fault(&mut self, error_code: Option<u16>) -> bool {
        let _ = error_code;
        false
    }

    /// The concrete device, for a harness that sets its inputs or reads its state.
    fn as_any_mut(&mut self) -> &mut dyn Any;
}
