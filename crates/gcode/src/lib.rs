//! `rtcnc-gcode`: an RS274/NGC G-code interpreter in the dialect of LinuxCNC 2.9.
//!
//! The interpreter reads a program a line at a time (memory stays constant however long the
//! program is: loops and subroutine calls remember file offsets, not lines) and yields
//! [`Canon`] commands one at a time, each with the file and line it came from. Errors are
//! [`GcodeError`] values naming file, line and column.
//!
//! ```no_run
//! use rtcnc_gcode::{Interpreter, Parameters, Settings, ToolTable};
//! let mut interp = Interpreter::new(Settings::default(), ToolTable::new(), Parameters::new());
//! interp.open("part.ngc")?;
//! for command in &mut interp {
//!     let command = command?;
//!     // hand `command` to the next stage (tool compensation, look-ahead)
//! }
//! # Ok::<(), rtcnc_gcode::GcodeError>(())
//! ```

#![warn(missing_docs)]

mod arc_tolerance;
mod block;
pub mod canon;
pub mod compensation;
mod control;
mod cycles;
pub mod error;
mod exec;
mod interp;
mod lathe_cycles;
mod lathe_profile;
mod mcodes;
mod motion;
mod nurbs;
mod offsets;
pub mod params;
mod program_end;
mod source;
mod threading;
pub mod tools;

pub use arc_tolerance::ArcRadiusTolerance;
pub use canon::{Canon, CanonCommand, Nurbs, NurbsPoint, Pose, Source};
pub use error::{ErrorKind, GcodeError};
pub use interp::{Interpreter, ModalState, Settings};
pub use params::Parameters;
pub use tools::{Tool, ToolTable};
