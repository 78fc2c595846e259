//! `rtcnc-gcode`: an RS274/NGC G-code interpreter in the dialect of LinuxCNC 2.9.
//!
//! The interpreter reads a program a line at a time (memory stays constant however long the
//! program is) and yields [`Canon`] commands, one at a time, each with the file and line it
//! came from. Errors are [`GcodeError`] values naming file, line and column.

pub mod canon;
pub mod error;

pub use canon::{Canon, CanonCommand, Pose, Source};
pub use error::{ErrorKind, GcodeError};
