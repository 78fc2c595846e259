//! The simulated machine: the embedded default back-end of [`Fieldbus`](crate::Fieldbus).
//!
//! Per joint a CiA 402 drive in one of four modes ([`DriveMode`](crate::DriveMode)), a
//! motor and load with inertia, viscous and Coulomb friction and a torque limit
//! ([`MotorModel`]), an incremental encoder, limit and home switches and index pulses at
//! configured positions; an e-stop input, a spindle with an at-speed signal, coolant, a
//! tool changer that takes a configured time, and general-purpose I/O with small devices
//! wired to it ([`DeviceConfig`]: the e-stop button's contact, a guard door with a lock,
//! inputs that follow an output after a delay, a tool carousel). Faults can be injected
//! ([`InjectedFault`]), including an input stuck at a level (a failed sensor).
//!
//! Each cycle is split into equal sub-steps no longer than
//! [`SimulatedMachineConfig::substep_s`] (62.5 µs by default); the drives' loops run once
//! per sub-step and hold their torque over it; the motor integrates that exactly.

mod composed;
mod config;
mod devices;
mod joint;
mod machine;
mod motor;
mod peripherals;

pub use config::{
    ConfigError, IoConfig, MAX_IO_POINTS, MAX_JOINTS, MotorConfig, SimulatedJointConfig,
    SimulatedMachineConfig, SpindleConfig, SwitchRange, ToolChangerConfig,
};
pub use devices::{DeviceConfig, ProbeSide};
pub use machine::{InjectedFault, SimulatedMachine, SimulationError};
pub use motor::MotorModel;
