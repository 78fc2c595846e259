//! One module per subcommand.
pub mod plc;
