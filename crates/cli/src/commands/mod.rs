//! One module per subcommand.
pub mod check;
pub mod latency;
pub mod plc;
pub mod sim;
pub mod run;
