//! Drives and I/O for rtcnc behind one trait, [`Fieldbus`]: a cyclic exchange of a process
//! image ([`ProcessOutputs`] written, [`ProcessInputs`] read) once per servo cycle, in the
//! vocabulary of CiA 402 drives ([`cia402`]: controlword, statusword, the drive state
//! machine).
//!
//! On a real-time path: [`Fieldbus::exchange`] (implementations allocate nothing there),
//! the trait's other methods, [`check_exchange`], and the simulated machine's exchange and
//! its inputs' setters and outputs' getters (`set_estop`, `turn_handwheel`,
//! `set_digital_input`, ...). Set-up only: the constructors (`SimulatedMachine::new`,
//! [`ProcessOutputs::new`], [`ProcessInputs::new`] allocate the images). Each public
//! function's doc says it in a line of its own, `Real-time: yes (...)` or `Real-time: no
//! (why)`; `crates/kernel/tests/real_time_docs.rs` checks that every one has it.
//!
//! The [`sim`] module holds the in-process simulated machine, the embedded default. The
//! EtherCAT back-end (CiA 402 drives in cyclic synchronous position mode) implements the
//! same trait in its own crate, `rtcnc-ethercat`.
//!
//! A controller's cycle:
//!
//! ```
//! use rtcnc_fieldbus::sim::{SimulatedMachine, SimulatedMachineConfig};
//! use rtcnc_fieldbus::{Fieldbus, ProcessInputs, ProcessOutputs};
//!
//! let config: SimulatedMachineConfig = toml::from_str(r#"
//!     [[joints]]
//!     drive = "velocity"
//! "#).unwrap();
//! let mut machine = SimulatedMachine::new(&config).unwrap();
//! let mut outputs = ProcessOutputs::new(machine.layout());
//! let mut inputs = ProcessInputs::new(machine.layout());
//! for _ in 0..10 {
//!     // read inputs -> servo update -> write outputs -> exchange
//!     let joint = &inputs.joints[0];
//!     outputs.joints[0].controlword = joint.state().controlword_towards(true);
//!     outputs.joints[0].target_velocity = 0.0;
//!     machine.exchange(0.001, &outputs, &mut inputs).unwrap();
//! }
//! assert_eq!(inputs.joints[0].state(), rtcnc_fieldbus::Cia402State::OperationEnabled);
//! ```

#![forbid(unsafe_code)]

mod bus;
pub mod cia402;
mod image;
pub mod sim;

pub use bus::{Fieldbus, FieldbusError, check_exchange};
pub use cia402::{Cia402State, ControlWord, DeviceCommand, StatusWord};
pub use image::{
    Coolant, DriveMode, JointCommand, JointFeedback, LatchFeedback, LatchSource, ProcessInputs,
    ProcessLayout, ProcessOutputs, SpindleCommand, SpindleFeedback, ToolChangeCommand,
    ToolChangerFeedback,
};
