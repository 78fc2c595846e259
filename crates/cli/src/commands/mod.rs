//! One module per subcommand.
pub mod api;
pub mod check;
pub mod latency;
pub mod machine;
pub mod plc;
pub mod run;
pub mod serve;
pub mod sim;
pub mod user;
