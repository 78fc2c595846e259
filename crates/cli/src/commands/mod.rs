//! One module per subcommand.
pub mod latency;
pub mod check;
pub mod plc;
