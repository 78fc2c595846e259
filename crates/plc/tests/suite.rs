//! Every integration test of this crate but those that need a process of their own (see
//! Cargo.toml), as one test binary: one link instead of one per file.

mod common;
#[path = "../benches/generated.rs"]
mod generated;

mod codesys2;
mod dialect;
mod differential;
mod encoding;
mod faults_and_errors;
mod fuzz;
mod generated_ladder;
mod language;
mod memory_layout;
mod mill;
mod plcopen;
mod runtime;
mod standard_fbs;
mod wstring;
