//! A digital I/O terminal with 8 inputs and 8 outputs (one byte each way), without a
//! mailbox: its PDOs come from the EEPROM alone, like the simplest I/O terminals.

use std::any::Any;

use serde::Deserialize;

use crate::application::{Application, TransitionContext};
use crate::dictionary::Dictionary;
use crate::esc::AlState;
use crate::sii::{
    FmmuUse, Identity, Pdo, PdoEntry, SiiContents, SyncManagerDefault, SyncManagerUse,
};

/// Product code of the simulated terminal.
pub const DIO_PRODUCT_CODE: u32 = 0x0000_0808;

/// One terminal's configuration.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DioConfig {
    /// Identity in the EEPROM.
    #[serde(default = "default_identity")]
    pub identity: Identity,
    /// Device name.
    #[serde(default = "default_name")]
    pub name: String,
    /// Inputs at power-up (bit n: input n).
    #[serde(default)]
    pub initial_inputs: u8,
}

impl Default for DioConfig {
    fn default() -> Self {
        Self {
            identity: default_identity(),
            name: default_name(),
            initial_inputs: 0,
        }
    }
}

fn default_identity() -> Identity {
    Identity {
        vendor_id: crate::drive::SIMULATOR_VENDOR_ID,
        product_code: DIO_PRODUCT_CODE,
        revision: 0x0001_0000,
        serial: 0,
    }
}

fn default_name() -> String {
    "rtcnc sim DIO 8/8".into()
}

/// The terminal: what the master last wrote, and the input levels.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DioTerminal {
    config: DioConfig,
    outputs: u8,
    inputs: u8,
}

impl DioTerminal {
    /// A terminal at power-up: outputs off.
    pub fn new(config: &DioConfig) -> Self {
        Self {
            config: config.clone(),
            outputs: 0,
            inputs: config.initial_inputs,
        }
    }

    /// The output levels (bit n: output n); all off outside OP.
    pub fn outputs(&self) -> u8 {
        self.outputs
    }

    /// The input levels (bit n: input n).
    pub fn inputs(&self) -> u8 {
        self.inputs
    }

    /// Sets the input levels (bit n: input n).
    pub fn set_inputs(&mut self, levels: u8) {
        self.inputs = levels;
    }
}

fn bits(index: u16) -> Vec<PdoEntry> {
    (1..=8)
        .map(|sub_index| PdoEntry {
            index,
            sub_index,
            bits: 1,
            data_type: 0x01,
        })
        .collect()
}

impl Application for DioTerminal {
    fn sii(&self) -> SiiContents {
        SiiContents {
            identity: self.config.identity,
            alias: 0,
            name: self.config.name.clone(),
            mailbox: None,
            coe_details: 0,
            fmmus: vec![FmmuUse::Outputs, FmmuUse::Inputs],
            sync_managers: vec![
                SyncManagerDefault {
                    start: 0x1000,
                    length: 1,
                    control: 0x44,
                    enable: true,
                    usage: SyncManagerUse::Outputs,
                },
                SyncManagerDefault {
                    start: 0x1100,
                    length: 1,
                    control: 0x00,
                    enable: true,
                    usage: SyncManagerUse::Inputs,
                },
            ],
            tx_pdos: vec![Pdo {
                index: 0x1A00,
                sync_manager: 1,
                entries: bits(0x6000),
            }],
            rx_pdos: vec![Pdo {
                index: 0x1600,
                sync_manager: 0,
                entries: bits(0x7000),
            }],
        }
    }

    fn dictionary(&self) -> Option<&Dictionary> {
        None
    }

    fn download(&mut self, _: u16, _: u8, _: &[u8], _: AlState) -> Result<(), u32> {
        Err(crate::dictionary::abort::NO_OBJECT)
    }

    fn process_data_len(&self) -> (usize, usize) {
        (1, 1)
    }

    fn check_transition(&mut self, _: AlState, _: &TransitionContext) -> Result<(), u16> {
        Ok(())
    }

    fn cycle(&mut self, _period_s: f64, outputs: Option<&[u8]>, inputs: &mut [u8]) {
        self.outputs = outputs.and_then(|o| o.first().copied()).unwrap_or(0);
        if let Some(byte) = inputs.first_mut() {
            *byte = self.inputs;
        }
    }

    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}
