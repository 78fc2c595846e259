//! Every integration test of this crate but those that need a process of their own (see
//! Cargo.toml), as one test binary: one link instead of one per file.

mod common;

mod compensation_corpus;
mod compensation_stage;
mod corpus;
mod diagnostics;
mod examples;
mod fuzz;
mod fuzz_regressions;
mod interp;
mod lathe_cycles;
mod nurbs;
mod rs274_data;
