//! `rtcnc serve`: starts the machine process and the API process (two OS processes) and
//! restarts either when it dies, until SIGINT or SIGTERM stops both.

use std::process::{Child, Command, ExitCode};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Run the machine and the API server as two processes.
#[derive(Debug, clap::Args)]
pub struct ServeArgs {
    /// The API server's arguments (the machine process takes the machine and segment).
    #[command(flatten)]
    pub api: super::api::Args,
    /// Refuse to run without SCHED_FIFO.
    #[arg(long)]
    pub require_fifo: bool,
}

static STOP: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_: libc::c_int) {
    STOP.store(true, Ordering::SeqCst);
}

struct Supervised {
    what: &'static str,
    args: Vec<String>,
    child: Option<Child>,
    started: Instant,
}

impl Supervised {
    fn start(&mut self) -> anyhow::Result<()> {
        let exe = std::env::current_exe()?;
        let child = Command::new(exe).args(&self.args).spawn()?;
        println!("rtcnc serve: {} process {} started", self.what, child.id());
        self.child = Some(child);
        self.started = Instant::now();
        Ok(())
    }

    /// Restarts the process when it has ended (at most once a second).
    fn watch(&mut self) -> anyhow::Result<()> {
        if let Some(child) = self.child.as_mut() {
            if let Some(status) = child.try_wait()? {
                println!(
                    "rtcnc serve: {} process {} ended ({status})",
                    self.what,
                    child.id()
                );
                self.child = None;
            }
        }
        if self.child.is_none() && self.started.elapsed() >= Duration::from_millis(500) {
            self.start()?;
        }
        Ok(())
    }

    fn stop(&mut self) {
        if let Some(mut child) = self.child.take() {
            // SAFETY: a signal to our own child.
            unsafe { libc::kill(child.id() as i32, libc::SIGTERM) };
            let t = Instant::now();
            while t.elapsed() < Duration::from_secs(5) {
                if let Ok(Some(_)) = child.try_wait() {
                    return;
                }
                std::thread::sleep(Duration::from_millis(20));
            }
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// Runs `rtcnc serve`.
#[cfg(feature = "services")]
pub fn run(mut args: ServeArgs) -> anyhow::Result<ExitCode> {
    // Located once here: both processes get the machine file's path.
    args.api.machine = crate::machines::locate(&args.api.machine)?;
    // The API process reads [opcua] and [mqtt]; a mistake there is said once here, not at
    // every restart of that process.
    let config = rtcnc_kernel::MachineConfig::load(&args.api.machine)
        .map_err(|e| anyhow::anyhow!("machine configuration: {e}"))?;
    rtcnc_factory::FactoryConfig::from_machine(&config)
        .map_err(|e| anyhow::anyhow!("{}: {e}", args.api.machine.display()))?;
    let segment = args
        .api
        .segment
        .clone()
        .unwrap_or_else(|| super::machine::default_segment(&args.api.machine));
    let mut api_args = args.api.clone();
    api_args.segment = Some(segment.clone());
    let mut machine_args = vec![
        "machine".to_string(),
        "--machine".into(),
        args.api.machine.display().to_string(),
        "--segment".into(),
        segment,
    ];
    if args.require_fifo {
        machine_args.push("--require-fifo".into());
    }
    let mut api_line = vec!["api".to_string()];
    api_line.extend(api_args.to_command_line());
    let handler: extern "C" fn(libc::c_int) = on_signal;
    // SAFETY: the handler only stores into an atomic.
    unsafe {
        libc::signal(libc::SIGINT, handler as libc::sighandler_t);
        libc::signal(libc::SIGTERM, handler as libc::sighandler_t);
    }
    let long_ago = Instant::now() - Duration::from_secs(10);
    let mut machine = Supervised {
        what: "machine",
        args: machine_args,
        child: None,
        started: long_ago,
    };
    let mut api = Supervised {
        what: "api",
        args: api_line,
        child: None,
        started: long_ago,
    };
    machine.start()?;
    api.start()?;
    while !STOP.load(Ordering::SeqCst) {
        machine.watch()?;
        api.watch()?;
        std::thread::sleep(Duration::from_millis(20));
    }
    api.stop();
    machine.stop();
    println!("rtcnc serve: stopped");
    Ok(ExitCode::SUCCESS)
}
