//! An EtherCAT slave simulator: a line of simulated devices that answers EtherCAT frames
//! the way real slave controllers do, so that a master can be tested without hardware.
//!
//! - [`esc`]: one slave controller: register space and process RAM, every datagram command
//!   (APRD/APWR/APRW, FPRD/FPWR/FPRW, BRD/BWR/BRW, LRD/LWR/LRW, ARMW/FRMW) with
//!   auto-increment and configured addresses and the working-counter rules, the SII EEPROM
//!   interface, AL control and status with AL status codes, sync managers (mailbox and
//!   buffered), FMMUs (byte- and bit-wise), the distributed clock (receive-time latch,
//!   system time with offset, delay and drift control, SYNC0) and the sync manager watchdog.
//! - [`sii`]: the EEPROM image (identity, mailbox, sync managers, FMMUs, PDO categories,
//!   header CRC). [`coe`] and [`dictionary`]: the CoE mailbox (SDO upload and download,
//!   expedited, normal and segmented, abort codes) over an object dictionary.
//! - Devices ([`application`]): a CiA 402 drive in cyclic synchronous position mode whose
//!   motor is `rtcnc-fieldbus`'s simulated joint ([`drive`]), and an 8-in/8-out digital
//!   I/O terminal ([`dio`]); the drive's CiA 402 touch probe 1 ([`touch_probe`]), on its
//!   encoder's index or on a probe input the segment wires to a simulated surface.
//! - [`segment`]: the line of devices a frame walks, with faults (frame loss, a device
//!   falling to SAFE-OP, a drive fault, link down); [`config`]: a segment from TOML.
//!
//! The library has no threads and no clock of its own: [`Segment::process`] takes each
//! frame with its arrival time, so a test drives it deterministically in virtual time, and
//! the `ecat-slave-sim` binary runs it on a network interface (a raw socket) in real time.

pub mod application;
pub mod coe;
pub mod config;
pub mod dictionary;
pub mod dio;
pub mod drive;
pub mod esc;
pub mod frame;
pub mod raw_socket;
pub mod segment;
pub mod sii;
pub mod touch_probe;

pub use config::{SegmentConfig, SegmentConfigError, SlaveConfig};
pub use segment::{Fault, Outcome, Segment, SegmentError};
