//! `rtcnc machines`: the machines built into the binary, by the name `--machine` takes;
//! with `--write`, one of them written into a folder to be adapted.

use std::path::PathBuf;
use std::process::ExitCode;

use crate::machines::{DEFAULT, SHIPPED, shipped};

/// List the shipped machines (for `--machine NAME`), or write one into a folder.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Write the machine NAME's files (machine file, PLC program, tool table) into DIR.
    #[arg(long, num_args = 2, value_names = ["NAME", "DIR"])]
    write: Option<Vec<String>>,
}

/// Runs `rtcnc machines`.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    if let Some(write) = args.write {
        let [name, dir] = [&write[0], &write[1]];
        let Some(machine) = shipped(name) else {
            anyhow::bail!("no shipped machine named '{name}' (`rtcnc machines` lists them)");
        };
        let path = machine.write_into(&PathBuf::from(dir))?;
        println!("{}", path.display());
        return Ok(ExitCode::SUCCESS);
    }
    let width = SHIPPED.iter().map(|m| m.name.len()).max().unwrap_or(0);
    for m in SHIPPED {
        let default = if m.name == DEFAULT { "  (default)" } else { "" };
        println!("{:width$}  {}{default}", m.name, m.title());
    }
    Ok(ExitCode::SUCCESS)
}
