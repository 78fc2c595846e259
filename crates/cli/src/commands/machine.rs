//! `rtcnc machine`: the machine process. The kernel on the real-time runner with its
//! shared-memory segment; an API process attaches to it. It never waits on that process:
//! the link's real-time parts only touch wait-free rings and snapshots, and this thread
//! (not real time) serves PLC variable requests and publishes task timing.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use rtcnc_kernel::link::{MachineLink, ServiceThread};
use rtcnc_kernel::{Kernel, KernelOptions, MachineConfig};
use rtcnc_rt::{RealTimeConfig, RealTimeRunner, SchedulingMode};

/// Run the machine process (the kernel in real time, with its shared-memory segment).
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Machine: a shipped machine's name (`rtcnc machines`) or a machine file (TOML).
    #[arg(long, default_value = crate::machines::DEFAULT)]
    pub machine: PathBuf,
    /// Segment name under /dev/shm (default: rtcnc-<machine file name>).
    #[arg(long)]
    pub segment: Option<String>,
    /// Refuse to run without SCHED_FIFO.
    #[arg(long)]
    pub require_fifo: bool,
}

/// The default segment name of a machine file.
pub fn default_segment(machine: &std::path::Path) -> String {
    let stem = machine
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "machine".into());
    let clean: String = stem
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || "._-".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect();
    format!("rtcnc-{clean}")
}

static STOP: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_: libc::c_int) {
    STOP.store(true, Ordering::SeqCst);
}

/// Runs `rtcnc machine`.
pub fn run(mut args: Args) -> anyhow::Result<ExitCode> {
    args.machine = crate::machines::locate(&args.machine)?;
    // The error names the file.
    let config = MachineConfig::load(&args.machine).context("machine configuration")?;
    let segment = args
        .segment
        .clone()
        .unwrap_or_else(|| default_segment(&args.machine));
    let link = MachineLink::create(&segment, &config)?;
    let kernel = Kernel::build(
        &config,
        KernelOptions {
            trace_capacity: Some(4096),
            link: Some(link.clone()),
            ..KernelOptions::default()
        },
    )?;
    let handle = kernel.handle.clone();
    let mut service = ServiceThread::new(&link, handle.plc().cloned());
    let runner = RealTimeRunner::start(
        kernel.tasks,
        RealTimeConfig {
            scheduling: if args.require_fifo {
                SchedulingMode::RequireFifo
            } else {
                SchedulingMode::BestEffort
            },
            ..RealTimeConfig::default()
        },
    )?;
    let handler: extern "C" fn(libc::c_int) = on_signal;
    // SAFETY: the handler only stores into an atomic, which is async-signal-safe.
    unsafe {
        libc::signal(libc::SIGINT, handler as libc::sighandler_t);
        libc::signal(libc::SIGTERM, handler as libc::sighandler_t);
    }
    println!(
        "rtcnc machine: {} on segment {} (pid {}), {}",
        config.machine.name,
        link.mapping().path().display(),
        std::process::id(),
        if runner.is_fifo() {
            "SCHED_FIFO"
        } else {
            "normal threads (no SCHED_FIFO permission)"
        }
    );
    let mut last_timing = Instant::now() - Duration::from_secs(1);
    while !STOP.load(Ordering::SeqCst) {
        service.poll();
        if last_timing.elapsed() >= Duration::from_millis(250) {
            last_timing = Instant::now();
            let stats = runner.monitor().stats();
            service.publish_timing(&stats, runner.is_fifo(), handle.setpoint_underruns());
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    let _recording = runner.stop();
    link.mapping().unlink();
    println!("rtcnc machine: stopped");
    Ok(ExitCode::SUCCESS)
}
