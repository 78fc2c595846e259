//! `rtcnc`: the command-line surface. Each subcommand lives in its own module under
//! `commands/` and only calls the public API of the layers below.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod commands;
mod decimal;

#[derive(Debug, Parser)]
#[command(
    name = "rtcnc",
    version,
    about = "Open software CNC and motion controller"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    Latency(commands::latency::Args),
    /// Interpret a G-code program: report errors or print the canonical commands.
    Check(commands::check::Args),
    /// Soft PLC: check or run a Structured Text program.
    Plc(commands::plc::Args),
    /// Run a program on a simulated machine in virtual time.
    Sim(commands::sim::Args),
    /// Run a program in real time on the configured machine.
    Run(commands::run::Args),
    /// Run the machine process and the API server (two processes).
    Serve(commands::serve::ServeArgs),
    /// Run the machine process alone (the kernel in real time with its shared-memory segment).
    Machine(commands::machine::Args),
    /// Run the API server alone, attached to a machine process.
    Api(commands::api::Args),
    /// Manage the API's users.
    User(commands::user::Args),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result: anyhow::Result<ExitCode> = match cli.command {
        Command::Latency(args) => commands::latency::run(args),
        Command::Check(args) => commands::check::run(args),
        Command::Plc(args) => commands::plc::run(args),
        Command::Sim(args) => commands::sim::run(args),
        Command::Run(args) => commands::run::run(args),
        Command::Serve(args) => commands::serve::run(args),
        Command::Machine(args) => commands::machine::run(args),
        Command::Api(args) => commands::api::run(args),
        Command::User(args) => commands::user::run(args),
    };
    match result {
        Ok(code) => code,
        Err(error) => {
            eprintln!("rtcnc: error: {error:#}");
            ExitCode::from(2)
        }
    }
}
