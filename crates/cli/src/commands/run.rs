//! `rtcnc run`: runs a part program in real time on the configured machine, with a live
//! status line (warnings are printed above it and counted in it). Ctrl-C asks for a feed
//! hold, a second Ctrl-C aborts the program. SIGTERM is a controlled stop: feed hold, abort,
//! drives off, then the summary and exit status [`EXIT_TERMINATED`].
//! At the end it prints each real-time task's execution time and CPU share of its period,
//! from the executive's timing monitor. A closed standard output does not stop the machine:
//! what can no longer be printed is dropped.

use std::io::{IsTerminal, Write as _};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};
use rtcnc_kernel::{Command, Kernel, KernelOptions, MachineConfig, MachineState, Urgent};
use rtcnc_rt::{RealTimeConfig, RealTimeRunner, SchedulingMode};

use crate::commands::seconds;
use crate::recording::SampleCsv;
use crate::say;

/// Exit status after SIGTERM's controlled stop (128 + SIGTERM, as a shell reports a process
/// the signal ended).
pub const EXIT_TERMINATED: u8 = 143;

/// Run a G-code program in real time on the configured machine.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The part program (omit with --idle to only run the task graph).
    program: Option<PathBuf>,
    /// Machine: a shipped machine's name (`rtcnc machines`) or a machine file (TOML).
    #[arg(long, default_value = crate::machines::DEFAULT)]
    machine: PathBuf,
    /// Home the machine before the program starts.
    #[arg(long)]
    home: bool,
    /// No program: run the task graph with the drives enabled for this long (seconds),
    /// then report the CPU shares (the benchmark of bench/kernel-cpu.sh).
    #[arg(long, value_name = "SECONDS", value_parser = seconds)]
    idle: Option<Duration>,
    /// Refuse to run without SCHED_FIFO.
    #[arg(long)]
    require_fifo: bool,
    /// Give up after this many seconds.
    #[arg(long, default_value = "3600", value_parser = seconds)]
    limit: Duration,
    /// Record every servo period into setpoints.csv and feedback.csv in this folder (the
    /// files of `rtcnc sim --out`, so the two runs compare column by column).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
}

/// Servo periods the recording ring holds: far more than the 100 ms between two drains.
const RECORD_CAPACITY: usize = 1 << 15;

/// The recording of `--out`: the kernel's sample ring drained into the CSV files, with the
/// periods the ring lost (a drain later than the ring is long) counted, not hidden.
struct Recording {
    samples: rtcnc_rt::ipc::RingConsumer<rtcnc_kernel::Sample>,
    csv: SampleCsv,
    joints: usize,
    rows: u64,
    last_cycle: Option<u64>,
    missing: u64,
    error: Option<std::io::Error>,
}

impl Recording {
    fn drain(&mut self) {
        let Recording {
            samples,
            csv,
            joints,
            rows,
            last_cycle,
            missing,
            error,
        } = self;
        samples.drain_with(|s| {
            if let Some(last) = *last_cycle {
                *missing += s.cycle.saturating_sub(last + 1);
            }
            *last_cycle = Some(s.cycle);
            *rows += 1;
            if error.is_none() {
                if let Err(e) = csv.write(s, *joints) {
                    *error = Some(e);
                }
            }
        });
    }
}

/// Prints the operator messages the machine reached since the last call (time since the
/// start command, line, text), clearing the status line first.
fn print_messages(handle: &rtcnc_kernel::KernelHandle, start_ns: u64, tty: bool) {
    for m in handle.take_messages() {
        let t = m.time_ns.saturating_sub(start_ns) as f64 * 1e-9;
        if tty {
            clear_status_line();
        }
        say!("message  t {t:.3} s  line {}: {}", m.line, m.text.as_str());
    }
}

/// Wipes the status line, so that what is printed next starts on a clean line above it.
fn clear_status_line() {
    eprint!("\r\x1b[2K");
}

/// Prints a warning above the status line (redrawn by the next status update).
fn warn(text: &str, tty: bool) {
    eprint!("{}", warning_text(text, tty));
}

/// A warning as printed: on a terminal it first wipes the status line it replaces, so the
/// warning stands on a line of its own and the status line is drawn again below it.
fn warning_text(text: &str, tty: bool) -> String {
    let clear = if tty { "\r\x1b[2K" } else { "" };
    format!("{clear}rtcnc: warning: {text}\n")
}

/// The live status line: drawn over the previous one (wiped first), with the count of
/// warnings printed above it so far.
fn status_text(elapsed_s: f64, s: &rtcnc_kernel::Status, warnings: u64) -> String {
    let warnings = if warnings > 0 {
        format!("  warnings {warnings}")
    } else {
        String::new()
    };
    format!(
        "\r\x1b[2K{elapsed_s:>8.1} s  line {:5}  X{:9.3} Y{:9.3} Z{:9.3}  F{:8.1} mm/min  {}{warnings}",
        s.line,
        s.axes[0],
        s.axes[1],
        s.axes[2],
        s.path_speed * 60.0,
        s.state_text()
    )
}

static INTERRUPTS: AtomicU32 = AtomicU32::new(0);
static TERMINATED: AtomicBool = AtomicBool::new(false);

extern "C" fn on_sigint(_: libc::c_int) {
    INTERRUPTS.fetch_add(1, Ordering::SeqCst);
}

extern "C" fn on_sigterm(_: libc::c_int) {
    TERMINATED.store(true, Ordering::SeqCst);
}

fn install_signal_handlers() {
    let sigint: extern "C" fn(libc::c_int) = on_sigint;
    let sigterm: extern "C" fn(libc::c_int) = on_sigterm;
    // SAFETY: the handlers only touch atomics, which is async-signal-safe. SIGPIPE is
    // ignored so that a closed output is an error `say!` drops, not the end of the process.
    unsafe {
        libc::signal(libc::SIGINT, sigint as libc::sighandler_t);
        libc::signal(libc::SIGTERM, sigterm as libc::sighandler_t);
        libc::signal(libc::SIGPIPE, libc::SIG_IGN);
    }
}

/// The deadline misses the executive recorded since the last call, as warnings (when the
/// machine file's reaction is `warn`).
struct MissWarnings {
    seen: usize,
    count: u64,
}

impl MissWarnings {
    fn poll(&mut self, runner: &rtcnc_rt::RealTimeHandle, tty: bool) {
        let monitor = runner.monitor();
        let faults = monitor.raw_faults();
        for f in faults.iter().skip(self.seen) {
            if f.code == rtcnc_rt::FaultCode::DeadlineMiss {
                self.count += 1;
                warn(&monitor.describe(f).to_string(), tty);
            }
        }
        self.seen = faults.len();
    }
}

/// SIGTERM: feed hold until the path stands, abort, then drives off (e-stop at standstill).
/// Each step waits a bounded time; the e-stop comes whatever the steps before found.
fn controlled_stop(handle: &rtcnc_kernel::KernelHandle) {
    let wait = |limit: Duration, done: &dyn Fn(&rtcnc_kernel::Status) -> bool| {
        let start = Instant::now();
        while start.elapsed() < limit && !done(&handle.status()) {
            std::thread::sleep(Duration::from_millis(5));
        }
    };
    handle.urgent(Urgent::FeedHold);
    wait(Duration::from_secs(5), &|s| {
        s.path_speed.abs() < 1e-9 && s.state != MachineState::Running
    });
    handle.urgent(Urgent::Abort);
    wait(Duration::from_secs(2), &|s| {
        matches!(
            s.state,
            MachineState::Idle | MachineState::Fault | MachineState::EStop
        )
    });
    handle.urgent(Urgent::EStop);
    wait(Duration::from_secs(2), &|s| {
        matches!(s.state, MachineState::EStop | MachineState::Fault)
    });
}

/// Runs `rtcnc run`.
pub fn run(mut args: Args) -> anyhow::Result<ExitCode> {
    // First: a Ctrl-C or SIGTERM while the machine starts up is kept for when it runs
    // (a hold before the first move, or the controlled stop), not the end of the process.
    install_signal_handlers();
    let config = load_machine(&mut args)?;
    let mut kernel = build_kernel(&args, &config)?;
    let mut recording = match (&args.out, kernel.samples.take()) {
        (Some(dir), Some(samples)) => Some(Recording {
            samples,
            csv: SampleCsv::create(dir, &config)?,
            joints: config.joints.len(),
            rows: 0,
            last_cycle: None,
            missing: 0,
            error: None,
        }),
        _ => None,
    };
    let handle = kernel.handle.clone();
    let tty = std::io::stderr().is_terminal();
    let runner = start_executive(kernel.tasks, args.require_fifo)?;
    let mut live = Live {
        runner: &runner,
        recording: recording.as_mut(),
        misses: MissWarnings { seen: 0, count: 0 },
        warn_misses: config.safety.deadline_miss == rtcnc_kernel::config::MissReactionConfig::Warn,
    };
    enable_and_home(&handle, args.home)?;
    let started = Instant::now();
    let ended = match args.idle {
        Some(idle) => {
            run_idle(&handle, &mut live, started, idle);
            false
        }
        None => {
            if let Some(program) = &args.program {
                say!(
                    "running {} on {} (Ctrl-C: feed hold; again: abort)",
                    program.display(),
                    config.machine.name
                );
            }
            follow_program(&handle, &mut live, started, args.limit, tty)
        }
    };
    live.poll_misses(false);
    let misses = live.misses.count;
    let terminated = TERMINATED.load(Ordering::SeqCst);
    let elapsed = started.elapsed().as_secs_f64();
    let fifo = runner.is_fifo();
    let executive = runner.stop();
    let faults = handle.take_faults();
    if let Some(r) = recording {
        finish_recording(r, args.out.as_deref())?;
    }
    if terminated {
        say!("terminated (SIGTERM) after {elapsed:.3} s: feed hold, abort, drives off");
    } else if args.program.is_some() {
        say!(
            "{} in {elapsed:.3} s",
            if ended {
                "program ended"
            } else {
                "program stopped"
            }
        );
    }
    say!(
        "scheduling  {}",
        if fifo {
            "SCHED_FIFO"
        } else {
            "normal threads (no SCHED_FIFO permission)"
        }
    );
    print_task_times(&config, &executive);
    print_setpoint_timing(&config, &executive, &handle);
    if misses > 0 {
        say!("deadline-miss warnings: {misses}");
    }
    print_faults(&handle, &faults, terminated);
    Ok(if terminated {
        ExitCode::from(EXIT_TERMINATED)
    } else if ended || args.idle.is_some() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// The machine file, and the arguments checked against it: a program or --idle.
fn load_machine(args: &mut Args) -> anyhow::Result<MachineConfig> {
    args.machine = crate::machines::locate(&args.machine)?;
    let config = MachineConfig::load(&args.machine)
        // The error names the file.
        .context("machine configuration")?;
    if args.program.is_none() && args.idle.is_none() {
        bail!("give a PROGRAM, or --idle SECONDS");
    }
    if let Some(p) = &args.program {
        if !p.is_file() {
            bail!("{}: no such program file", p.display());
        }
    }
    Ok(config)
}

/// The kernel, with a recording ring only for --out.
fn build_kernel(args: &Args, config: &MachineConfig) -> anyhow::Result<Kernel> {
    Ok(Kernel::build(
        config,
        KernelOptions {
            program: args.program.clone(),
            record_capacity: if args.out.is_some() {
                RECORD_CAPACITY
            } else {
                0
            },
            trace_capacity: Some(4096),
            ..KernelOptions::default()
        },
    )?)
}

/// The kernel's tasks on the real-time executive.
fn start_executive(
    tasks: rtcnc_rt::TaskSet,
    require_fifo: bool,
) -> anyhow::Result<rtcnc_rt::RealTimeHandle> {
    Ok(RealTimeRunner::start(
        tasks,
        RealTimeConfig {
            scheduling: if require_fifo {
                SchedulingMode::RequireFifo
            } else {
                SchedulingMode::BestEffort
            },
            // Printed here, above the status line.
            print_warnings: false,
            ..RealTimeConfig::default()
        },
    )?)
}

/// The faults of the run, but refused operator commands and, after SIGTERM, the e-stop
/// that switched the drives off.
fn print_faults(
    handle: &rtcnc_kernel::KernelHandle,
    faults: &[rtcnc_kernel::Fault],
    terminated: bool,
) {
    for f in faults.iter().filter(|f| {
        f.code != rtcnc_kernel::FaultCode::CommandRefused
            // The drives-off step of SIGTERM's stop is no fault of the machine.
            && !(terminated && f.code == rtcnc_kernel::FaultCode::EStop)
    }) {
        say!("fault  {}", handle.describe(f));
    }
}

/// What is kept up while the machine runs, every 100 ms: the deadline-miss warnings and
/// the drain of the recording ring.
struct Live<'a> {
    runner: &'a rtcnc_rt::RealTimeHandle,
    recording: Option<&'a mut Recording>,
    misses: MissWarnings,
    warn_misses: bool,
}

impl Live<'_> {
    fn poll_misses(&mut self, tty: bool) {
        if self.warn_misses {
            self.misses.poll(self.runner, tty);
        }
    }

    fn drain_recording(&mut self) {
        if let Some(r) = self.recording.as_mut() {
            r.drain();
        }
    }
}

/// Waits until `done`, for at most `limit`; an error names `what` did not happen.
fn wait_for(what: &str, limit: Duration, done: &dyn Fn() -> bool) -> anyhow::Result<()> {
    let start = Instant::now();
    // SIGTERM ends the wait; the run loop then makes the controlled stop.
    while !done() && !TERMINATED.load(Ordering::SeqCst) {
        if start.elapsed() > limit {
            bail!("{what} did not happen within {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    Ok(())
}

/// Reset (the drives enable), then home all joints when asked.
fn enable_and_home(handle: &rtcnc_kernel::KernelHandle, home: bool) -> anyhow::Result<()> {
    std::thread::sleep(Duration::from_millis(50));
    handle.command(Command::Reset);
    wait_for("enabling the drives", Duration::from_secs(2), &|| {
        handle.status().ready
    })
    .map_err(|e| {
        // Say why: the faults that kept the drives off.
        let faults: Vec<String> = handle
            .take_faults()
            .iter()
            .map(|f| handle.describe(f))
            .collect();
        if faults.is_empty() {
            e
        } else {
            e.context(faults.join("; "))
        }
    })?;
    if home {
        handle.command(Command::HomeAll);
        std::thread::sleep(Duration::from_millis(20));
        wait_for("homing", Duration::from_secs(600), &|| {
            handle.status().state != MachineState::Running
        })?;
    }
    Ok(())
}

/// --idle: the task graph runs with the drives enabled and no program, for `idle` or
/// until Ctrl-C or SIGTERM.
fn run_idle(
    handle: &rtcnc_kernel::KernelHandle,
    live: &mut Live,
    started: Instant,
    idle: Duration,
) {
    let stopped = || TERMINATED.load(Ordering::SeqCst) || INTERRUPTS.load(Ordering::SeqCst) > 0;
    while started.elapsed() < idle && !stopped() {
        std::thread::sleep((idle - started.elapsed().min(idle)).min(Duration::from_millis(100)));
        live.poll_misses(false);
        live.drain_recording();
    }
    if stopped() {
        controlled_stop(handle);
    }
}

/// Starts the program and follows it to its end, a fault, an abort, SIGTERM or the time
/// limit, with the status line and the operator's Ctrl-C (feed hold, then abort).
/// Returns whether the program reached its end.
fn follow_program(
    handle: &rtcnc_kernel::KernelHandle,
    live: &mut Live,
    started: Instant,
    limit: Duration,
    tty: bool,
) -> bool {
    handle.command(Command::Start { from_line: 0 });
    let kernel_start = handle.status().time_ns;
    let mut ended = false;
    let mut seen = 0;
    let mut hold = None;
    loop {
        std::thread::sleep(Duration::from_millis(100));
        if TERMINATED.load(Ordering::SeqCst) {
            if tty {
                clear_status_line();
            }
            eprintln!("rtcnc: SIGTERM: feed hold, abort, drives off");
            controlled_stop(handle);
            break;
        }
        // One at a time: two that came together (while the machine started up) are still
        // a hold, then an abort.
        if INTERRUPTS.load(Ordering::SeqCst) > seen {
            seen += 1;
            if tty {
                clear_status_line();
            }
            if seen == 1 {
                handle.urgent(Urgent::FeedHold);
                eprintln!("rtcnc: feed hold (Ctrl-C again to abort)");
            } else {
                handle.urgent(Urgent::Abort);
                eprintln!("rtcnc: abort");
            }
        }
        live.poll_misses(tty);
        live.drain_recording();
        print_messages(handle, kernel_start, tty);
        let s = handle.status();
        // What holds the machine, said once as it begins (the status line keeps it).
        if s.hold != hold {
            hold = s.hold;
            if let Some(cause) = hold {
                if tty {
                    clear_status_line();
                }
                let t = s.time_ns.saturating_sub(kernel_start) as f64 * 1e-9;
                say!("{}  t {t:.3} s  line {}", cause.message(), s.line);
            }
        }
        if tty {
            eprint!(
                "{}",
                status_text(started.elapsed().as_secs_f64(), &s, live.misses.count)
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
        if started.elapsed() > limit {
            break;
        }
    }
    if tty {
        eprintln!();
    }
    print_messages(handle, kernel_start, false);
    ended
}

/// Drains the last samples, closes the CSV files and says how many periods they hold and
/// how many the ring lost.
fn finish_recording(mut r: Recording, out: Option<&std::path::Path>) -> anyhow::Result<()> {
    r.drain();
    let dir = out.unwrap_or(std::path::Path::new("."));
    if let Some(e) = r.error {
        bail!("{}: {e}", dir.display());
    }
    r.csv.finish()?;
    say!(
        "recording   {} periods in {}/setpoints.csv, feedback.csv; {} periods missing",
        r.rows,
        dir.display(),
        r.missing
    );
    Ok(())
}

/// Each real-time task's execution times and CPU share of its period, from the
/// executive's timing monitor.
fn print_task_times(config: &MachineConfig, executive: &rtcnc_rt::Recording) {
    say!(
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
    for stats in executive.monitor().stats() {
        let e = &stats.execution;
        let share = period_of(&stats.name).map(|(period, runs)| {
            // Mean time of one body run × runs per activation / period.
            e.mean as f64 * f64::from(runs) / period.as_nanos() as f64 * 100.0
        });
        say!(
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
}

/// How far the set-points ran ahead of the servo and how late the two tasks that make
/// and take them started: the margin the interpolation had.
fn print_setpoint_timing(
    config: &MachineConfig,
    executive: &rtcnc_rt::Recording,
    handle: &rtcnc_kernel::KernelHandle,
) {
    let (lead, gap) = handle.setpoint_lead();
    let period_ms = config.servo_period().as_secs_f64() * 1e3;
    let latest = executive
        .monitor()
        .stats()
        .into_iter()
        .filter(|s| s.name == "interpolation" || s.name == "position control")
        .map(|s| (s.name, s.lateness.max))
        .fold(String::new(), |text, (name, max)| {
            format!("{text}  {name} {:.3} ms", max as f64 / 1e6)
        });
    say!("latest start after release:{latest}");
    say!(
        "set-point lead {lead} periods ({:.1} ms); longest gap between interpolation runs {gap} periods ({:.1} ms)",
        lead as f64 * period_ms,
        gap as f64 * period_ms,
    );
    say!(
        "set-point underruns (periods without a set-point): {}",
        handle.setpoint_underruns()
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_warning_takes_the_status_lines_place_and_the_line_counts_it() {
        // On a terminal the warning wipes the status line first and ends its own line: the
        // next status update is drawn below it, whole.
        let w = warning_text("late", true);
        assert!(w.starts_with("\r\x1b[2K"), "{w:?}");
        assert!(w.ends_with("rtcnc: warning: late\n"), "{w:?}");
        assert_eq!(warning_text("late", false), "rtcnc: warning: late\n");
        let status = rtcnc_kernel::Status {
            line: 12,
            ..rtcnc_kernel::Status::default()
        };
        let line = status_text(1.5, &status, 0);
        assert!(line.starts_with("\r\x1b[2K"), "{line:?}");
        assert!(!line.contains("warnings"), "{line:?}");
        assert!(!line.contains('\n'), "{line:?}");
        assert!(status_text(1.5, &status, 3).ends_with("  warnings 3"));
        // Held: the line says by what.
        let held = rtcnc_kernel::Status {
            state: MachineState::Held,
            hold: Some(rtcnc_kernel::HoldCause::MachineLogic),
            ..rtcnc_kernel::Status::default()
        };
        assert!(
            status_text(1.5, &held, 0)
                .ends_with("held: machine logic requests a feed hold (door open?)"),
            "{:?}",
            status_text(1.5, &held, 0)
        );
    }
}
