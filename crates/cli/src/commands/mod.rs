//! One module per subcommand.
pub mod latency;
pub mod check;
