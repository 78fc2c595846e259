//! A segment described in TOML: the devices in line, their clocks, and faults present from
//! the start.
//!
//! ```toml
//! seed = 1                      # frame-loss generator
//! frame_loss_rate = 0.0         # fault: frames lost at this rate
//! [[slaves]]
//! kind = "csp_drive"
//! count = 12                    # twelve identical drives in a row
//! drift_ppm = 20.0              # their clocks run 20 ppm fast
//! [slaves.drive.joint]          # rtcnc-fieldbus' simulated joint (drive = "csp" implied)
//! drive = "csp"
//! units_per_revolution = 5.0
//! [[slaves]]
//! kind = "dio"
//! [[probes]]                    # a touch probe over a surface across drive 2's travel
//! sensed = 2
//! surface = -3.0
//! drives = [0, 1, 2]            # wired into these drives' touch probe 1 inputs
//! input = { device = 12, bit = 5 }  # and into the terminal's input 5
//! ```

use serde::Deserialize;

use crate::dio::{DioConfig, DioTerminal};
use crate::drive::{CspDrive, DriveConfig};
use crate::esc::{LocalClock, Slave};
use crate::segment::{Fault, ProbeWire, Segment};

/// Largest number of devices in a simulated segment.
pub const MAX_SLAVES: usize = 256;

/// The segment.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SegmentConfig {
    /// Seed of the frame-loss generator.
    #[serde(default = "default_seed")]
    pub seed: u64,
    /// Frames lost at this rate from the start (0 to 1).
    #[serde(default)]
    pub frame_loss_rate: f64,
    /// The devices, first to last.
    pub slaves: Vec<SlaveConfig>,
    /// Touch probes wired into the drives (positions count every device, `count` expanded).
    #[serde(default)]
    pub probes: Vec<ProbeWire>,
}

fn default_seed() -> u64 {
    1
}

fn one() -> usize {
    1
}

/// One kind of device, possibly repeated.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum SlaveConfig {
    /// A CiA 402 CSP drive.
    CspDrive {
        /// How many in a row.
        #[serde(default = "one")]
        count: usize,
        /// Clock rate error (ppm).
        #[serde(default)]
        drift_ppm: f64,
        /// The drive.
        #[serde(default)]
        drive: DriveConfig,
    },
    /// An 8-in/8-out digital I/O terminal.
    Dio {
        /// How many in a row.
        #[serde(default = "one")]
        count: usize,
        /// Clock rate error (ppm).
        #[serde(default)]
        drift_ppm: f64,
        /// The terminal.
        #[serde(default)]
        terminal: DioConfig,
    },
}

/// Why a segment could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("segment configuration, {field}: {reason}")]
pub struct SegmentConfigError {
    /// The refused key.
    pub field: String,
    /// Why.
    pub reason: String,
}

impl SegmentConfig {
    /// Builds the segment, or names the first refused key.
    pub fn build(&self) -> Result<Segment, SegmentConfigError> {
        let refuse = |field: String, reason: String| SegmentConfigError { field, reason };
        if !(0.0..=1.0).contains(&self.frame_loss_rate) {
            return Err(refuse(
                "frame_loss_rate".into(),
                "must be between 0 and 1".into(),
            ));
        }
        let mut slaves = Vec::new();
        for (n, slave) in self.slaves.iter().enumerate() {
            let (count, drift_ppm) = match slave {
                SlaveConfig::CspDrive {
                    count, drift_ppm, ..
                }
                | SlaveConfig::Dio {
                    count, drift_ppm, ..
                } => (*count, *drift_ppm),
            };
            if !(drift_ppm.is_finite() && drift_ppm.abs() <= 1000.0) {
                return Err(refuse(
                    format!("slaves[{n}].drift_ppm"),
                    "must be within ±1000 ppm".into(),
                ));
            }
            if count == 0 || slaves.len() + count > MAX_SLAVES {
                return Err(refuse(
                    format!("slaves[{n}].count"),
                    format!("must be at least 1, at most {MAX_SLAVES} devices in all"),
                ));
            }
            for k in 0..count {
                let position = slaves.len() as u64;
                let clock = LocalClock {
                    drift_ppb: (drift_ppm * 1000.0).round() as i64,
                    // Devices power up at different moments: their local times differ.
                    start_ns: 1_000_000 * (position + 1) + 7_919 * position,
                };
                let application: Box<dyn crate::application::Application> = match slave {
                    SlaveConfig::CspDrive { drive, .. } => {
                        let mut drive = drive.clone();
                        drive.identity.serial = drive.identity.serial.wrapping_add(k as u32);
                        Box::new(
                            CspDrive::new(&drive)
                                .map_err(|e| refuse(format!("slaves[{n}].drive"), e.0.clone()))?,
                        )
                    }
                    SlaveConfig::Dio { terminal, .. } => Box::new(DioTerminal::new(terminal)),
                };
                let device = Slave::new(application, clock).ok_or_else(|| {
                    refuse(
                        format!("slaves[{n}]"),
                        "its EEPROM contents do not fit the EEPROM".into(),
                    )
                })?;
                slaves.push(device);
            }
        }
        let mut segment = Segment::new(slaves, self.seed);
        for (n, wire) in self.probes.iter().enumerate() {
            segment
                .wire_probe(wire.clone())
                .map_err(|e| refuse(format!("probes[{n}]"), e.to_string()))?;
        }
        if self.frame_loss_rate > 0.0 {
            segment
                .inject(Fault::FrameLoss {
                    rate: self.frame_loss_rate,
                })
                .map_err(|e| refuse("frame_loss_rate".into(), e.to_string()))?;
        }
        Ok(segment)
    }
}
