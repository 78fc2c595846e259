//! One module per subcommand.
pub mod latency;
