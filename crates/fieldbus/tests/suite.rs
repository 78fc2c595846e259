//! Every integration test of this crate but those that need a process of their own (see
//! Cargo.toml), as one test binary: one link instead of one per file.

mod cia402;
mod docs_examples;
mod experiment1;
mod motor;
mod servo_with_machine;
mod simulated_machine;
mod spindle_orient;
