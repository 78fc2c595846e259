//! rtcnc motion: motion planning and interpolation for CNC machines.
//!
//! This crate is a layer-2 library of rtcnc: no threads, no I/O, no dependency on the other
//! rtcnc crates. [`otg`] holds the time-optimal jerk-limited trajectory generator.

pub mod otg;
