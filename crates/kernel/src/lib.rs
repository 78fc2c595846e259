//! `rtcnc-kernel`: the motion kernel (layer 3). It puts the CNC libraries onto the
//! real-time executive as the task graph of the seeds (command parsing, interpreter, tool
//! compensation, look-ahead, interpolation, position control, drive I/O, machine logic,
//! status feedback), built from one machine configuration file over a fieldbus (the
//! simulated machine the file describes, or any `Fieldbus` handed to
//! `Kernel::build_with_bus`) and a kinematics, and owns the machine state: modes, e-stop,
//! faults, the command channels and the status snapshot.
//!
//! ```no_run
//! use rtcnc_kernel::{Command, Kernel, KernelOptions, MachineConfig, Simulation};
//! let config = MachineConfig::load("configs/sim-mill.toml".as_ref())?;
//! let kernel = Kernel::build(&config, KernelOptions {
//!     program: Some("examples/part.ngc".into()),
//!     record_capacity: 4096,
//!     ..KernelOptions::default()
//! })?;
//! let mut sim = Simulation::new(kernel);
//! sim.handle().command(Command::Reset);
//! sim.handle().command(Command::Start { from_line: 0 });
//! let ended = sim.run_until(std::time::Duration::from_secs(60), &mut |_| {}, |s| s.program_ended)?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Messages between stages are plain data (`messages`); per-cycle code does not allocate.
//! See `docs/configuration.md` for the machine file and `docs/kernel.md` for the graph.
#![allow(clippy::needless_range_loop)]

mod compensation;
pub mod config;
mod error;
mod fault;
mod interpreter;
mod kernel;
mod kinematics;
pub mod link;
mod logic;
pub mod messages;
pub mod modal;
mod motion;
pub mod report;
mod servo;
mod shared;
mod sim;

pub use config::{ConfigError, MAX_JOINTS, MachineConfig};
pub use error::{KernelError, SelfTestFailure};
pub use fault::{Fault, FaultCode, ProbeFailure, TaskName};
pub use kernel::{Kernel, KernelHandle, KernelOptions, SelfTestReport};
pub use kinematics::MachineKinematics;
pub use messages::{
    Command, FixedText, HoldCause, MachineState, Mode, OperatorMessage, Status, Urgent,
};
pub use motion::{DriveEnable, LatchRequest, ProgramOutputs, ServoTarget};
pub use servo::Sample;
pub use shared::{Feedback, LogicOutputs, LogicRequests, PlcAxisSetpoints};
pub use sim::{SimulatedEthercatHandle, SimulatedMachineHandle, Simulation};
