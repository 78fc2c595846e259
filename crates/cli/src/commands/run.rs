//! `rtcnc run`: runs a part program in real time on the configured machine, with a live
//! status line. Ctrl-C asks for a feed hold, a second Ctrl-C aborts the program.
//! At the end it prints each real-time task's execution time and CPU share of its period,
//! from the executive's timing monitor.

use std::io::{IsTerminal, Write as _};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};
use rtcnc_kernel::{Command, Kernel, KernelOptions, MachineConfig, MachineState, Urgent};
use rtcnc_rt::{RealTimeConfig, RealTimeRunner, SchedulingMode};

/// Run a G-code program in real time on the configured machine.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The part program (omit with --idle to only run the task graph).
    program: Option<PathBuf>,
    /// Machine configuration (TOML).
    #[arg(long, default_value = "configs/sim-mill.toml")]
    machine: PathBuf,
    /// Home the machine before the program starts.
    #[arg(long)]
    home: bool,
    /// No program: run the task graph with the drives enabled for this long (seconds),
    /// then report the CPU shares (the benchmark of bench/kernel-cpu.sh).
    #[arg(long, value_name = "SECONDS")]
    idle: Option<f64>,
    /// Refuse to run without SCHED_FIFO.
    #[arg(long)]
    require_fifo: bool,
    /// Give up after this many seconds.
    #[arg(long, default_value_t = 3600.0)]
    limit: f64,
}

/// Prints the operator messages the machine reached since the last call (time since the
/// start command, line, text), clearing the status line first.
fn print_messages(handle: &rtcnc_kernel::KernelHandle, start_ns: u64, tty: bool) {
    for m in handle.take_messages() {
        let t = m.time_ns.saturating_sub(start_ns) as f64 * 1e-9;
        if tty {
            eprint!("\r{:100}\r", "");
        }
        println!("message  t {t:.3} s  line {}: {}", m.line, m.text.as_str());
    }
}

static INTERRUPTS: AtomicU32 = AtomicU32::new(0);

extern "C" fn on_sigint(_: libc::c_int) {
    INTERRUPTS.fetch_add(1, Ordering::SeqCst);
}

fn install_sigint() {
    let handler: extern "C" fn(libc::c_int) = on_sigint;
    // SAFETY: the handler only touches an atomic, which is async-signal-safe.
    unsafe {
        libc::signal(libc::SIGINT, handler as libc::sighandler_t);
    }
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let config = MachineConfig::load(&args.machine)
        .with_context(|| format!("machine configuration {}", args.machine.display()))?;
    if args.program.is_none() && args.idle.is_none() {
        bail!("give a PROGRAM, or --idle SECONDS");
    }
    if let Some(p) = &args.program {
        if !p.is_file() {
            bail!("{}: no such program file", p.display());
        }
    }
    let kernel = Kernel::build(
        &config,
        KernelOptions {
            program: args.program.clone(),
            record_capacity: 0,
            trace_capacity: Some(4096),
            ..KernelOptions::default()
        },
    )?;
    let handle = kernel.handle.clone();
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
    install_sigint();
    let wait = |what: &str, limit: Duration, done: &dyn Fn() -> bool| -> anyhow::Result<()> {
        let start = Instant::now();
        while !done() {
            if start.elapsed() > limit {
                bail!("{what} did not happen within {limit:?}");
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        Ok(())
    };
    std::thread::sleep(Duration::from_millis(50));
    handle.command(Command::Reset);
    wait("enabling the drives", Duration::from_secs(2), &|| {
        handle.status().ready
    })?;
    if args.home {
        handle.command(Command::HomeAll);
        std::thread::sleep(Duration::from_millis(20));
        wait("homing", Duration::from_secs(600), &|| {
            handle.status().state != MachineState::Running
        })?;
    }
    let tty = std::io::stderr().is_terminal();
    let started = Instant::now();
    let mut ended = false;
    if let Some(idle) = args.idle {
        std::thread::sleep(Duration::from_secs_f64(idle.max(0.0)));
    } else {
        handle.command(Command::Start { from_line: 0 });
        let kernel_start = handle.status().time_ns;
        let mut seen = 0;
        loop {
            std::thread::sleep(Duration::from_millis(100));
            let interrupts = INTERRUPTS.load(Ordering::SeqCst);
            if interrupts > seen {
                seen = interrupts;
                if seen == 1 {
                    handle.urgent(Urgent::FeedHold);
                    eprintln!("\nrtcnc: feed hold (Ctrl-C again to abort)");
                } else {
                    handle.urgent(Urgent::Abort);
                    eprintln!("\nrtcnc: abort");
                }
            }
            print_messages(&handle, kernel_start, tty);
            let s = handle.status();
            if tty {
                eprint!(
                    "\r{:>8.1} s  line {:5}  X{:9.3} Y{:9.3} Z{:9.3}  F{:8.1} mm/min  {:18}",
                    started.elapsed().as_secs_f64(),
                    s.line,
                    s.axes[0],
                    s.axes[1],
                    s.axes[2],
                    s.path_speed * 60.0,
                    s.state.as_str()
                );
                let _ = std::io::stderr().flush();
            }
            if s.program_ended && s.state == MachineState::Idle {
                ended = true;
                break;
            }
            if matches!(s.state, MachineState::Fault | MachineState::EStop) {
                break;
            }
            if seen >= 2 && s.state == MachineState::Idle {
                break;
            }
            if started.elapsed().as_secs_f64() > args.limit {
                break;
            }
        }
        if tty {
            eprintln!();
        }
        print_messages(&handle, kernel_start, false);
    }
    let elapsed = started.elapsed().as_secs_f64();
    let fifo = runner.is_fifo();
    let recording = runner.stop();
    let faults = handle.take_faults();
    if args.program.is_some() {
        println!(
            "{} in {elapsed:.3} s",
            if ended {
                "program ended"
            } else {
                "program stopped"
            }
        );
    }
    println!(
        "scheduling  {}",
        if fifo {
            "SCHED_FIFO"
        } else {
            "normal threads (no SCHED_FIFO permission)"
        }
    );
    println!(
        "task                 runs     mean µs   p99 µs   max µs   CPU share of its period   misses"
    );
    let t = &config.tasks;
    let period_of = |task: &str| -> Option<(Duration, u32)> {
        let (p, runs) = match task {
            "position control" | "drive io" => (&t.fieldbus.period, 1),
            "machine logic" => (&t.machine_logic.period, 1),
            "interpolation" if t.interpolation_in_fieldbus_thread(config.servo_period()) => {
                (&t.fieldbus.period, 1)
            }
            "interpolation" => (&t.interpolation.period, 1),
            "look-ahead" => (&t.look_ahead.period, t.look_ahead.runs),
            "command parsing" => (&t.command_parsing.period, t.command_parsing.runs),
            "status feedback" => (&t.status_feedback.period, 1),
            _ => return None,
        };
        Some((rtcnc_rt::parse_duration(p).ok()?, runs))
    };
    for stats in recording.monitor().stats() {
        let e = &stats.execution;
        let share = period_of(&stats.name).map(|(period, runs)| {
            // Mean time of one body run × runs per activation / period.
            e.mean as f64 * f64::from(runs) / period.as_nanos() as f64 * 100.0
        });
        println!(
            "{:18} {:8} {:10.2} {:8.2} {:8.2}   {:>10}                {}",
            stats.name,
            stats.activations,
            e.mean as f64 / 1e3,
            e.p99 as f64 / 1e3,
            e.max as f64 / 1e3,
            share.map_or_else(
                || if stats.name == "self test" {
                    "background"
                } else {
                    "event"
                }
                .to_string(),
                |s| format!("{s:.3} %")
            ),
            stats.deadline_misses
        );
    }
    let (lead, gap) = handle.setpoint_lead();
    let period_ms = config.servo_period().as_secs_f64() * 1e3;
    let latest = recording
        .monitor()
        .stats()
        .into_iter()
        .filter(|s| s.name == "interpolation" || s.name == "position control")
        .map(|s| (s.name, s.lateness.max))
        .fold(String::new(), |text, (name, max)| {
            format!("{text}  {name} {:.3} ms", max as f64 / 1e6)
        });
    println!("latest start after release:{latest}");
    println!(
        "set-point lead {lead} periods ({:.1} ms); longest gap between interpolation runs {gap} periods ({:.1} ms)",
        lead as f64 * period_ms,
        gap as f64 * period_ms,
    );
    println!(
        "set-point underruns (periods without a set-point): {}",
        handle.setpoint_underruns()
    );
    for f in faults
        .iter()
        .filter(|f| f.code != rtcnc_kernel::FaultCode::CommandRefused)
    {
        println!("fault  {}", handle.describe(f));
    }
    Ok(if ended || args.idle.is_some() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}
