//! The EtherCAT master of rtcnc, on ethercrab: CiA 402 servo drives in cyclic synchronous
//! position mode with distributed clocks, and digital I/O terminals, behind the
//! [`Fieldbus`](rtcnc_fieldbus::Fieldbus) trait.
//!
//! - [`EthercatMaster::start`] scans the bus on the configured interface, checks every
//!   device's identity against the configuration, maps the PDOs and writes the SDOs in
//!   PRE-OP (mode 8, interpolation period, sync mode, limits), sets up SYNC0 at the cycle
//!   period and takes the bus to OP; a refusal names the device and its AL status code.
//! - Each [`exchange`](rtcnc_fieldbus::Fieldbus::exchange) sends the outputs and reads the
//!   inputs in one frame with the reference clock's time, checks every device's state
//!   and the working counter, and reports the cycle's phase against SYNC0.
//! - [`simulation`] makes the simulated devices a configuration lists, to run a machine
//!   without hardware.
//! - [`driver`] explains how ethercrab's futures run on the caller's real-time thread.
//!
//! See docs/ethercat.md for the configuration keys.

pub mod al_status;
pub mod clock;
pub mod config;
pub mod driver;
pub mod link;
mod master;
pub mod pdo;
pub mod simulation;

pub use clock::Clock;
pub use config::{ConfigError, EthercatConfig, ExpectedIdentity, SdoWrite, SlaveConfig};
pub use link::{Link, NetworkLink, SimulatedLink};
pub use master::{EthercatMaster, MAX_PDI, MasterStatistics, StartError};
pub use simulation::{SimulatedBus, SimulatedProbe, SimulationConfig, simulated_segment};

/// Mode of operation "cyclic synchronous position" (0x6060).
pub const MODE_CSP: i8 = 8;
