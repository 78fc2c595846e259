//! `rtcnc user add NAME --role ROLE`: adds or replaces a user of the API (argon2id hash in
//! the users file, written atomically).

use std::io::{BufRead as _, IsTerminal as _};
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context as _;
#[cfg(feature = "services")]
use rtcnc_api::auth::{Role, add_user};
use rtcnc_kernel::MachineConfig;

/// Manage the API's users.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    command: UserCommand,
}

#[derive(Debug, clap::Subcommand)]
enum UserCommand {
    /// Add a user, or replace one of the same name.
    Add {
        /// User name.
        name: String,
        /// viewer, operator, setter or admin.
        #[arg(long)]
        role: String,
        /// Users file (default: the one of --machine).
        #[arg(long)]
        users: Option<PathBuf>,
        /// Machine: a shipped machine's name (`rtcnc machines`) or a machine file (TOML).
        #[arg(long, default_value = crate::machines::DEFAULT)]
        machine: PathBuf,
        /// Read the password from the first line of standard input (else it is asked for).
        #[arg(long)]
        password_stdin: bool,
    },
}

/// Runs `rtcnc user`.
#[cfg(feature = "services")]
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    match args.command {
        UserCommand::Add {
            name,
            role,
            users,
            machine,
            password_stdin,
        } => {
            let role = Role::parse(&role)
                .ok_or_else(|| anyhow::anyhow!("--role is viewer, operator, setter or admin"))?;
            let users = match users {
                Some(u) => u,
                None => {
                    let machine = crate::machines::locate(&machine)?;
                    // The error names the file.
                    let config = MachineConfig::load(&machine).context("machine configuration")?;
                    rtcnc_api::default_users_file(&config, &machine)
                }
            };
            if !password_stdin && std::io::stdin().is_terminal() {
                eprint!("password for {name} (shown as you type; at least 8 characters): ");
            }
            let mut line = String::new();
            std::io::stdin().lock().read_line(&mut line)?;
            let password = line.trim_end_matches(['\n', '\r']);
            add_user(&users, &name, role, password)?;
            println!("{name} ({}) written to {}", role.as_str(), users.display());
            Ok(ExitCode::SUCCESS)
        }
    }
}
