//! `rtcnc`: the command-line surface. Each subcommand lives in its own module under
//! `commands/` and only calls the public API of the layers below. The library holds the
//! argument grammar, so that tests and the fuzz targets parse exactly what the binary does.

// The doc comments of the argument types are clap's help texts, written as plain text
// (`[hmi] users`, `rtcnc-<machine file name>`), not as rustdoc's Markdown.
#![allow(rustdoc::broken_intra_doc_links, rustdoc::invalid_html_tags)]
// Without the servers the three commands keep their arguments and lose their bodies; what
// only those bodies used is then unused.
#![cfg_attr(not(feature = "services"), allow(unused_imports, dead_code))]

use std::process::ExitCode;

use clap::{Parser, Subcommand};

pub mod commands;
mod decimal;
pub mod machines;
pub mod output;
mod plot;
pub mod recording;

/// The command line.
#[derive(Debug, Parser)]
#[command(
    name = "rtcnc",
    version,
    about = "Open software CNC and motion controller"
)]
pub struct Cli {
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
    /// List the machines built into rtcnc (`--machine NAME`), or write one into a folder.
    Machines(commands::machines::Args),
}

/// Exit status of an error that stopped a command (bad arguments, unreadable files).
pub const EXIT_ERROR: u8 = 2;

/// Runs the command line: parses the process's arguments, runs the subcommand, reports an
/// error once on stderr.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    // The processes that drive the machine keep running when their output goes away.
    if !matches!(
        cli.command,
        Command::Run(_) | Command::Serve(_) | Command::Machine(_) | Command::Api(_)
    ) {
        output::end_quietly_when_output_closes();
    }
    let result: anyhow::Result<ExitCode> = match cli.command {
        Command::Latency(args) => commands::latency::run(args),
        Command::Check(args) => commands::check::run(args),
        Command::Plc(args) => commands::plc::run(args),
        Command::Sim(args) => commands::sim::run(args),
        Command::Run(args) => commands::run::run(args),
        #[cfg(feature = "services")]
        Command::Serve(args) => commands::serve::run(args),
        Command::Machine(args) => commands::machine::run(args),
        #[cfg(feature = "services")]
        Command::Api(args) => commands::api::run(args),
        #[cfg(feature = "services")]
        Command::User(args) => commands::user::run(args),
        #[cfg(not(feature = "services"))]
        Command::Serve(_) | Command::Api(_) | Command::User(_) => Err(anyhow::anyhow!(
            "this rtcnc was built without its servers (the cargo feature `services`)"
        )),
        Command::Machines(args) => commands::machines::run(args),
    };
    match result {
        Ok(code) => code,
        Err(error) if output::is_broken_pipe(&error) => output::exit_on_closed_output(),
        Err(error) => {
            eprintln!("rtcnc: error: {}", output::error_chain(&error));
            ExitCode::from(EXIT_ERROR)
        }
    }
}
