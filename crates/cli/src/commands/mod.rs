//! One module per subcommand.
pub mod check;
pub mod latency;
pub mod plc;
