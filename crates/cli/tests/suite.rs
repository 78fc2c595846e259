//! Every integration test of this crate but those that need a process of their own (see
//! Cargo.toml), as one test binary: one link instead of one per file.

mod common;

mod check;
mod machines;
mod plc;
mod robustness;
mod sim;
