//! Every integration test of this crate but those that need a process of their own (see
//! Cargo.toml), as one test binary: one link instead of one per file.

mod support;

mod config;
mod distributed_clocks;
mod faults;
mod hand_over;
mod touch_probe;
