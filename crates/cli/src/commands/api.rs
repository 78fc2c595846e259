//! `rtcnc api`: the API server process, attached to a machine process's segment.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::Context as _;
use rtcnc_kernel::MachineConfig;

/// Run the API server (REST + WebSocket) for a machine process.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Machine: a shipped machine's name (`rtcnc machines`) or a machine file (TOML).
    #[arg(long, default_value = crate::machines::DEFAULT)]
    pub machine: PathBuf,
    /// Segment name under /dev/shm (default: rtcnc-<machine file name>).
    #[arg(long)]
    pub segment: Option<String>,
    /// Address to listen on (port 0: any free port, printed at start).
    #[arg(long, default_value = "127.0.0.1:8080")]
    pub listen: SocketAddr,
    /// TLS certificate, PEM (default: [hmi] tls_certificate).
    #[arg(long)]
    pub tls_cert: Option<PathBuf>,
    /// TLS private key, PEM (default: [hmi] tls_key).
    #[arg(long)]
    pub tls_key: Option<PathBuf>,
    /// Serve plain HTTP on an address other than loopback.
    #[arg(long)]
    pub insecure_http: bool,
    /// Users file (default: [hmi] users, else users.toml beside the machine file).
    #[arg(long)]
    pub users: Option<PathBuf>,
    /// Program store (default: [hmi] programs, else programs/ beside the machine file).
    #[arg(long)]
    pub programs: Option<PathBuf>,
    /// Session lifetime, seconds.
    #[arg(long, default_value_t = 8 * 3600)]
    pub session_seconds: u64,
    /// Largest program upload, bytes.
    #[arg(long, default_value_t = 8 << 20)]
    pub max_upload: usize,
    /// Print the OpenAPI document and exit.
    #[arg(long)]
    pub print_openapi: bool,
}

impl Args {
    /// The arguments as a command line (for `rtcnc serve`).
    pub fn to_command_line(&self) -> Vec<String> {
        let mut v = vec![
            "--machine".to_string(),
            self.machine.display().to_string(),
            "--listen".into(),
            self.listen.to_string(),
            "--session-seconds".into(),
            self.session_seconds.to_string(),
            "--max-upload".into(),
            self.max_upload.to_string(),
        ];
        let mut opt = |name: &str, p: &Option<PathBuf>| {
            if let Some(p) = p {
                v.push(name.into());
                v.push(p.display().to_string());
            }
        };
        opt("--tls-cert", &self.tls_cert);
        opt("--tls-key", &self.tls_key);
        opt("--users", &self.users);
        opt("--programs", &self.programs);
        if let Some(s) = &self.segment {
            v.push("--segment".into());
            v.push(s.clone());
        }
        if self.insecure_http {
            v.push("--insecure-http".into());
        }
        v
    }
}

/// Runs `rtcnc api`.
#[cfg(feature = "services")]
pub fn run(mut args: Args) -> anyhow::Result<ExitCode> {
    if args.print_openapi {
        print!("{}", rtcnc_api::openapi_json());
        return Ok(ExitCode::SUCCESS);
    }
    args.machine = crate::machines::locate(&args.machine)?;
    // The error names the file.
    let config = MachineConfig::load(&args.machine).context("machine configuration")?;
    let beside = |name: &str| {
        args.machine
            .parent()
            .unwrap_or(std::path::Path::new("."))
            .join(name)
    };
    let tls = match (
        args.tls_cert.clone().or_else(|| {
            config
                .hmi
                .tls_certificate
                .as_ref()
                .map(|p| config.resolve(p))
        }),
        args.tls_key
            .clone()
            .or_else(|| config.hmi.tls_key.as_ref().map(|p| config.resolve(p))),
    ) {
        (Some(c), Some(k)) => Some((c, k)),
        (None, None) => None,
        _ => anyhow::bail!("TLS needs both a certificate and a key"),
    };
    let options = rtcnc_api::ApiOptions {
        config_path: args.machine.clone(),
        segment: args
            .segment
            .clone()
            .unwrap_or_else(|| super::machine::default_segment(&args.machine)),
        listen: args.listen,
        tls,
        insecure_http: args.insecure_http,
        users_file: args
            .users
            .clone()
            .unwrap_or_else(|| rtcnc_api::default_users_file(&config, &args.machine)),
        programs_dir: args
            .programs
            .clone()
            .unwrap_or_else(|| match &config.hmi.programs {
                Some(p) => config.resolve(p),
                None => beside("programs"),
            }),
        session_ttl: Duration::from_secs(args.session_seconds.max(1)),
        max_upload_bytes: args.max_upload,
    };
    rtcnc_api::run_with(options, rtcnc_factory::start)?;
    Ok(ExitCode::SUCCESS)
}
