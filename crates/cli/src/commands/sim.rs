//! `rtcnc sim`: runs a part program on a machine configuration in virtual time (as fast as
//! the processor allows, the same result every run) and reports what the machine did:
//! cycle time, limits, following errors, faults; with `--out` also the set-points and
//! feedback as CSV, an SVG plot, the executive's trace and `summary.json`.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use crate::plot::{LineKind, PlotData};
use anyhow::{Context as _, bail};
use rtcnc_kernel::report::RunStats;

use rtcnc_kernel::{
    Command, Fault, FaultCode, Kernel, KernelHandle, KernelOptions, MachineConfig, MachineState,
    Sample, Simulation, Urgent,
};

use crate::recording::SampleCsv;

/// After the program, the recording goes on until every joint has stood still for this
/// many periods...
const SETTLED_PERIODS: u32 = 20;
/// ...or at most this long (a load that never settles is itself worth seeing).
const SETTLE_LIMIT: Duration = Duration::from_secs(5);
/// A simulated joint slower than this (units/s) stands.
const STANDING_VELOCITY: f64 = 1e-6;

/// Run a G-code program on a simulated machine in virtual time.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The part program.
    program: PathBuf,
    /// Machine: a shipped machine's name (`rtcnc machines`) or a machine file (TOML).
    #[arg(long, default_value = crate::machines::DEFAULT)]
    machine: PathBuf,
    /// Write CSV files, plot, trace and summary.json into this folder.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Give up after this much machine time, in seconds.
    #[arg(long, default_value = "3600", value_parser = crate::commands::seconds)]
    limit: Duration,
    /// Home the machine before the program starts.
    #[arg(long)]
    home: bool,
    /// No progress bar.
    #[arg(long, short)]
    quiet: bool,
    /// At a program pause (M0, M1 with the optional stop on) press Resume after this long
    /// (default 0 s: at once), as an operator would, so that the cycle time counts the whole
    /// program. Without it the run stays paused until the time limit.
    #[arg(long, value_name = "SECONDS", num_args = 0..=1, default_missing_value = "0",
          value_parser = crate::commands::seconds_or_zero)]
    resume_after_pause: Option<Duration>,
    /// Print where the host processor time went: each task, the recording, the executive
    /// (measuring adds two clock readings per task run, so the run itself is slower).
    #[arg(long)]
    profile: bool,
}

/// Most operator messages `summary.json` lists (all are printed).
const MAX_KEPT_MESSAGES: usize = 10_000;

/// What `summary.json` holds.
pub struct Summary {
    /// From the start command to the program's end (or to where the run stopped), s.
    pub cycle_time_s: f64,
    /// Whether the program reached its end.
    pub ended: bool,
    /// Whether a set-point exceeded an axis's velocity, acceleration or jerk limit.
    pub limits_exceeded: bool,
    /// The faults, described.
    pub faults: Vec<String>,
    /// Operator messages: time since the program start (s), line, text.
    pub messages: Vec<(f64, u32, String)>,
}

/// Runs `rtcnc sim`.
pub fn run(mut args: Args) -> anyhow::Result<ExitCode> {
    args.machine = crate::machines::locate(&args.machine)?;
    let config = MachineConfig::load(&args.machine)
        // The error names the file.
        .context("machine configuration")?
        // Never a master on a real bus in virtual time.
        .for_virtual_time();
    if !args.program.is_file() {
        bail!("{}: no such program file", args.program.display());
    }
    let mut sim = build_simulation(&args, &config)?;
    let whole_run = Instant::now();
    let handle = sim.handle().clone();
    let mut recorder = Recorder::new(&args, &config)?;
    let mut sink = |s: &Sample| recorder.add(s);

    power_up_and_start(&mut sim, &handle, &mut sink, args.home)?;
    let start = sim.now();
    let wall = Instant::now();
    let bar = progress_bar(args.quiet);
    let mut run = ProgramRun::default();
    follow_program(&mut sim, &handle, &mut sink, &args, start, &bar, &mut run)?;
    let cycle_time = (sim.now() - start).as_secs_f64();
    record_until_standing(&mut sim, &handle, &mut sink, config.joints.len())?;
    run.faults.extend(handle.take_faults());
    take_messages(&handle, start, &bar, &mut run.messages);
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    let wall_s = wall.elapsed().as_secs_f64();
    let whole_run_ns = whole_run.elapsed().as_nanos() as u64;
    if let Some(e) = recorder.io_error.take() {
        return Err(e).context("writing the CSV files");
    }

    let report = Report {
        cycle_time_s: cycle_time,
        ended: run.ended,
        pauses: run.pauses,
        exceeded: limits_exceeded(&config, &recorder.stats),
        fault_texts: run
            .faults
            .iter()
            .filter(|f| f.code != FaultCode::CommandRefused)
            .map(|f| handle.describe(f))
            .collect(),
        error_text: handle.error_text(),
    };
    print_report(&args, &config, &recorder.stats, &report, &sim, wall_s);
    if let Some(profile) = sim.runner().host_profile() {
        print_profile(
            profile,
            whole_run_ns,
            recorder.recording_ns,
            sim.now().as_secs_f64(),
        );
    }
    if let Some(dir) = &args.out {
        write_out_dir(dir, &args, &config, recorder, &report, run.messages, sim)?;
    }
    Ok(
        if report.ended && report.exceeded.is_empty() && report.fault_texts.is_empty() {
            ExitCode::SUCCESS
        } else {
            ExitCode::from(1)
        },
    )
}

/// The kernel on a virtual-time executive, with buffers sized for this run.
fn build_simulation(args: &Args, config: &MachineConfig) -> anyhow::Result<Simulation> {
    let kernel = Kernel::build(
        config,
        KernelOptions {
            program: Some(args.program.clone()),
            // Drained after every servo period (Simulation::run_cycles): a small ring stays in
            // the cache instead of touching fresh memory for most of a run.
            record_capacity: 256,
            // The trace is written only with --out; without it a short ring (the latest
            // events) saves filling and faulting in megabytes of ring that nobody reads.
            trace_capacity: Some(if args.out.is_some() { 1 << 16 } else { 1 << 10 }),
            ..KernelOptions::default()
        },
    )?;
    let mut sim = Simulation::new(kernel);
    if args.profile {
        sim = sim.with_host_profile();
    }
    Ok(sim)
}

/// Where every servo period's sample goes: the limit statistics always, the plot and the
/// CSV files with --out.
struct Recorder {
    stats: RunStats,
    // Only --out draws the plot; its points are decimated to a bounded number.
    plot: Option<PlotData>,
    writers: Option<SampleCsv>,
    // The first write error; the run goes on and reports it at its end.
    io_error: Option<std::io::Error>,
    period_s: f64,
    joints: usize,
    // With --profile: the host time the recording took, which the profile lists apart.
    profile: bool,
    recording_ns: u64,
}

impl Recorder {
    fn new(args: &Args, config: &MachineConfig) -> anyhow::Result<Recorder> {
        Ok(Recorder {
            writers: match &args.out {
                Some(dir) => Some(SampleCsv::create(dir, config)?),
                None => None,
            },
            stats: RunStats::for_machine(config),
            plot: args.out.as_ref().map(|_| PlotData::default()),
            io_error: None,
            period_s: config.servo_period().as_secs_f64(),
            joints: config.joints.len(),
            profile: args.profile,
            recording_ns: 0,
        })
    }

    fn add(&mut self, s: &Sample) {
        let t0 = self.profile.then(Instant::now);
        self.stats.add(s, self.period_s);
        if let Some(plot) = self.plot.as_mut() {
            plot.add(s);
        }
        if let Some(w) = self.writers.as_mut() {
            if let Err(e) = w.write(s, self.joints) {
                self.io_error.get_or_insert(e);
            }
        }
        if let Some(t0) = t0 {
            self.recording_ns += t0.elapsed().as_nanos() as u64;
        }
    }
}

/// Power up, reset, optionally home, start.
fn power_up_and_start(
    sim: &mut Simulation,
    handle: &KernelHandle,
    sink: &mut dyn FnMut(&Sample),
    home: bool,
) -> anyhow::Result<()> {
    sim.run_cycles(2, sink)?;
    handle.command(Command::Reset);
    if !sim.run_until(Duration::from_secs(1), sink, |s| s.ready)? {
        bail!("the drives did not enable within 1 s");
    }
    if home {
        handle.command(Command::HomeAll);
        sim.run_cycles(3, sink)?;
        sim.run_until(Duration::from_secs(600), sink, |s| {
            s.state != MachineState::Running
        })?;
    }
    handle.command(Command::Start { from_line: 0 });
    sim.run_cycles(2, sink)?;
    Ok(())
}

/// What the machine did while the program ran.
#[derive(Default)]
struct ProgramRun {
    /// Whether the program reached its end.
    ended: bool,
    /// Program pauses met: times since the start.
    pauses: Vec<f64>,
    messages: Vec<(f64, u32, String)>,
    faults: Vec<Fault>,
}

/// Runs the program to its end, a fault, a refused block or the time limit, pressing
/// Resume at a pause when --resume-after-pause says so, and shows its progress.
fn follow_program(
    sim: &mut Simulation,
    handle: &KernelHandle,
    sink: &mut dyn FnMut(&Sample),
    args: &Args,
    start: Duration,
    bar: &Option<indicatif::ProgressBar>,
    run: &mut ProgramRun,
) -> anyhow::Result<()> {
    // The simulation's period is the machine file's servo period.
    let period_s = sim.period().as_secs_f64();
    let limit = args.limit;
    let mut was_paused = false;
    loop {
        let resume_after = args.resume_after_pause;
        let done = sim.run_until(Duration::from_millis(100), sink, |s| {
            (s.program_ended && s.state == MachineState::Idle)
                || matches!(s.state, MachineState::Fault | MachineState::EStop)
                || (resume_after.is_some() && s.state == MachineState::Paused)
        })?;
        let status = handle.status();
        if let (Some(wait), MachineState::Paused) = (resume_after, status.state) {
            run.pauses.push((sim.now() - start).as_secs_f64());
            let periods = (wait.as_secs_f64() / period_s).round() as u64;
            sim.run_cycles(periods, sink)?;
            handle.urgent(Urgent::Resume);
            // The pause ends within a period or two.
            sim.run_until(Duration::from_millis(100), sink, |s| {
                s.state != MachineState::Paused
            })?;
            continue;
        }
        let paused = status.state == MachineState::Paused;
        if paused && !was_paused {
            // Without --resume-after-pause: reported once, it lasts to the time limit.
            run.pauses.push((sim.now() - start).as_secs_f64());
        }
        was_paused = paused;
        run.faults.extend(handle.take_faults());
        take_messages(handle, start, bar, &mut run.messages);
        if let Some(bar) = bar {
            bar.set_message(format!(
                "t {:.1} s  line {}  X{:.3} Y{:.3} Z{:.3}  {:.1} mm/s  {}",
                (sim.now() - start).as_secs_f64(),
                status.line,
                status.axes[0],
                status.axes[1],
                status.axes[2],
                status.path_speed,
                status.state_text()
            ));
            bar.tick();
        }
        if done {
            run.ended = status.program_ended && status.state == MachineState::Idle;
            return Ok(());
        }
        if sim.now() - start > limit {
            return Ok(());
        }
        // A block the kernel refused (a program error, a machine function it cannot carry
        // out, an impossible synchronised move) stops the program and leaves the machine
        // idle: nothing more will happen.
        if status.state == MachineState::Idle && run.faults.iter().any(|f| stops_program(f.code)) {
            return Ok(());
        }
    }
}

/// Record until the load stands (after a fault it may coast or quick-stop for a few
/// hundred milliseconds: the recording shows the whole stop), then a moment more.
/// The simulated load's true velocity says it (the feedback is stale once the fieldbus
/// is lost); another bus has its feedback.
fn record_until_standing(
    sim: &mut Simulation,
    handle: &KernelHandle,
    sink: &mut dyn FnMut(&Sample),
    joints: usize,
) -> anyhow::Result<()> {
    let machine = handle.simulated_machine().ok();
    let mut last_feedback = None;
    let mut standing_periods = 0u32;
    sim.run_until(SETTLE_LIMIT, sink, |s| {
        let standing = match &machine {
            Some(m) => m.with(|m| {
                (0..joints).all(|j| {
                    m.true_state(j)
                        .is_none_or(|(_, v)| v.abs() < STANDING_VELOCITY)
                })
            }),
            None => last_feedback == Some(s.joint_feedback),
        };
        last_feedback = Some(s.joint_feedback);
        standing_periods = if standing { standing_periods + 1 } else { 0 };
        standing_periods >= SETTLED_PERIODS
    })?;
    Ok(())
}

/// The run's result, as the report and `summary.json` give it.
struct Report {
    cycle_time_s: f64,
    ended: bool,
    pauses: Vec<f64>,
    /// The axis limits a set-point went beyond, described.
    exceeded: Vec<String>,
    /// The faults, but refused operator commands, described.
    fault_texts: Vec<String>,
    /// Why the program stopped, when it stopped on an error.
    error_text: Option<String>,
}

/// The axis limits (velocity, acceleration, jerk) the set-points went beyond, with a
/// relative margin for rounding.
fn limits_exceeded(config: &MachineConfig, stats: &RunStats) -> Vec<String> {
    let mut exceeded = Vec::new();
    for p in &config.axis_plan() {
        let i = p.axis as usize;
        let Some(a) = config.axis(p.axis) else {
            continue;
        };
        let tol = 1.0 + 1e-6;
        for (what, got, limit) in [
            ("velocity", stats.max_velocity[i], a.max_velocity),
            (
                "acceleration",
                stats.max_acceleration[i],
                a.max_acceleration,
            ),
            ("jerk", stats.max_jerk[i], a.max_jerk),
        ] {
            if got > limit * tol {
                exceeded.push(format!(
                    "axis {}: {what} {got:.6} > limit {limit}",
                    p.axis.letter()
                ));
            }
        }
    }
    exceeded
}

/// Prints the report: cycle time, speed of the simulation, each axis's peaks against its
/// limits, the following errors, pauses, limits and faults.
fn print_report(
    args: &Args,
    config: &MachineConfig,
    stats: &RunStats,
    report: &Report,
    sim: &Simulation,
    wall_s: f64,
) {
    println!("program     {}", args.program.display());
    println!(
        "machine     {} ({})",
        config.machine.name,
        args.machine.display()
    );
    println!(
        "cycle time  {:.3} s{}",
        report.cycle_time_s,
        if report.ended {
            ""
        } else {
            " (did not reach the end)"
        }
    );
    println!(
        "simulated   {:.3} s in {wall_s:.3} s of wall time ({:.0}× real time)",
        sim.now().as_secs_f64(),
        sim.now().as_secs_f64() / wall_s.max(1e-9)
    );
    println!("axis  max |v| (limit)          max |a| (limit)            max |j| (limit)");
    for p in &config.axis_plan() {
        let i = p.axis as usize;
        if let Some(a) = config.axis(p.axis) {
            println!(
                "{}     {:9.3} ({:8.1})   {:11.3} ({:9.1})   {:13.1} ({:10.1})",
                p.axis.letter(),
                stats.max_velocity[i],
                a.max_velocity,
                stats.max_acceleration[i],
                a.max_acceleration,
                stats.max_jerk[i],
                a.max_jerk
            );
        }
    }
    println!("joint  max following error");
    for (j, jc) in config.joints.iter().enumerate() {
        println!("{:6} {:.6}", jc.name, stats.max_following_error[j]);
    }
    for t in &report.pauses {
        match args.resume_after_pause {
            Some(wait) => println!(
                "paused      at {t:.3} s (M0/M1); resumed after {:.3} s",
                wait.as_secs_f64()
            ),
            None => {
                println!("paused      at {t:.3} s (M0/M1); --resume-after-pause [SECONDS] goes on")
            }
        }
    }
    if report.exceeded.is_empty() {
        println!("limits      respected");
    } else {
        println!("limits      EXCEEDED");
        for e in &report.exceeded {
            println!("  {e}");
        }
    }
    if report.fault_texts.is_empty() {
        println!("faults      none");
    } else {
        println!("faults");
        for f in &report.fault_texts {
            println!("  {f}");
        }
        if let Some(t) = &report.error_text {
            println!("  {t}");
        }
    }
}

/// Writes the --out folder: the CSV files' ends, summary.json, the plot and the trace.
fn write_out_dir(
    dir: &Path,
    args: &Args,
    config: &MachineConfig,
    recorder: Recorder,
    report: &Report,
    messages: Vec<(f64, u32, String)>,
    sim: Simulation,
) -> anyhow::Result<()> {
    if let Some(w) = recorder.writers {
        w.finish()?;
    }
    write_summary(
        &dir.join("summary.json"),
        config,
        &recorder.stats,
        &Summary {
            cycle_time_s: report.cycle_time_s,
            ended: report.ended,
            limits_exceeded: !report.exceeded.is_empty(),
            faults: report.fault_texts.clone(),
            messages,
        },
        report.error_text.as_deref(),
    )?;
    let plot = recorder.plot.unwrap_or_default();
    let lathe = config.machine.kind == rtcnc_kernel::config::MachineKind::Lathe;
    let svg = plot.svg(&line_kinds(config, &args.program), lathe);
    std::fs::write(dir.join("plot.svg"), svg)
        .with_context(|| format!("{}", dir.join("plot.svg").display()))?;
    let runner = sim.into_runner();
    runner
        .recording()
        .trace()
        .write_chrome_json(&dir.join("trace.json"))
        .context("trace.json")?;
    println!(
        "wrote       {}/{{setpoints.csv, feedback.csv, plot.svg, trace.json, summary.json}}",
        dir.display()
    );
    Ok(())
}

/// Where the host processor time of the run went, per simulated millisecond.
fn print_profile(
    profile: &rtcnc_rt::HostProfile,
    whole_run_ns: u64,
    recording_ns: u64,
    simulated_s: f64,
) {
    let ms = (simulated_s * 1e3).max(1e-9);
    let per_ms = |ns: u64| ns as f64 / 1e3 / ms;
    let share = |ns: u64| 100.0 * ns as f64 / whole_run_ns.max(1) as f64;
    println!(
        "host time   {:.3} s for {simulated_s:.3} s simulated ({:.3} µs per simulated ms; \
         profiling adds {} ns per task run)",
        whole_run_ns as f64 * 1e-9,
        per_ms(whole_run_ns),
        profile.clock_overhead_ns * 2,
    );
    println!(
        "  {:<22} {:>9} {:>14} {:>7}",
        "task", "runs/ms", "µs per sim ms", "share"
    );
    let mut in_tasks = 0;
    for (name, runs, ns) in &profile.tasks {
        in_tasks += ns;
        println!(
            "  {name:<22} {:>9.2} {:>14.3} {:>6.1}%",
            *runs as f64 / ms,
            per_ms(*ns),
            share(*ns)
        );
    }
    let rest = whole_run_ns.saturating_sub(in_tasks + recording_ns);
    for (name, ns) in [
        ("recording (sim)", recording_ns),
        ("executive + glue", rest),
    ] {
        println!(
            "  {name:<22} {:>9} {:>14.3} {:>6.1}%",
            "",
            per_ms(ns),
            share(ns)
        );
    }
}

/// Prints the operator messages the machine reached (time since the program start, line,
/// text) and keeps them for the summary.
fn take_messages(
    handle: &rtcnc_kernel::KernelHandle,
    start: Duration,
    bar: &Option<indicatif::ProgressBar>,
    messages: &mut Vec<(f64, u32, String)>,
) {
    for m in handle.take_messages() {
        let t = Duration::from_nanos(m.time_ns)
            .saturating_sub(start)
            .as_secs_f64();
        let text = format!(
            "message     t {t:.3} s  line {}: {}",
            m.line,
            m.text.as_str()
        );
        match bar {
            Some(bar) => bar.suspend(|| println!("{text}")),
            None => println!("{text}"),
        }
        // The summary keeps the first ones; a program that prints in an endless loop
        // must not fill the memory.
        if messages.len() < MAX_KEPT_MESSAGES {
            messages.push((t, m.line, m.text.as_str().to_string()));
        }
    }
}

fn progress_bar(quiet: bool) -> Option<indicatif::ProgressBar> {
    if quiet {
        return None;
    }
    let bar = indicatif::ProgressBar::new_spinner();
    bar.set_draw_target(indicatif::ProgressDrawTarget::stderr());
    if let Ok(style) = indicatif::ProgressStyle::with_template("{spinner} {elapsed} {msg}") {
        bar.set_style(style);
    }
    Some(bar)
}

/// Whether a fault leaves the program stopped (and `sim` with nothing more to wait for):
/// every fault but a refused operator command and the ones that only warn.
fn stops_program(code: FaultCode) -> bool {
    !matches!(
        code,
        FaultCode::CommandRefused | FaultCode::DeadlineMiss | FaultCode::BackgroundCheck
    )
}

/// Which program lines move at rapid and which feed, from the interpreter's canonical
/// output (the HMI's preview); a line with both (a canned cycle) counts as a feed. Without
/// the preview (a build without the feature `services`) every line is drawn as a feed.
#[cfg(feature = "services")]
fn line_kinds(config: &MachineConfig, program: &Path) -> HashMap<u32, LineKind> {
    let mut kinds = HashMap::new();
    let Ok(text) = std::fs::read_to_string(program) else {
        return kinds;
    };
    let name = program
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    for path in rtcnc_api::preview::preview(config, &name, &text).paths {
        let kind = if path.kind == "rapid" {
            LineKind::Rapid
        } else {
            LineKind::Feed
        };
        for line in path.lines {
            let k = kinds.entry(line).or_insert(kind);
            if kind == LineKind::Feed {
                *k = LineKind::Feed;
            }
        }
    }
    kinds
}

#[cfg(not(feature = "services"))]
fn line_kinds(_: &MachineConfig, _: &Path) -> HashMap<u32, LineKind> {
    HashMap::new()
}

fn write_summary(
    path: &Path,
    config: &MachineConfig,
    stats: &RunStats,
    summary: &Summary,
    error_text: Option<&str>,
) -> anyhow::Result<()> {
    use serde_json::{Map, Value, json};
    let mut axes = Map::new();
    for p in config.axis_plan() {
        let i = p.axis as usize;
        if let Some(a) = config.axis(p.axis) {
            axes.insert(
                p.axis.letter().to_string(),
                json!({
                    "max_velocity": stats.max_velocity[i],
                    "max_acceleration": stats.max_acceleration[i],
                    "max_jerk": stats.max_jerk[i],
                    "limit_velocity": a.max_velocity,
                    "limit_acceleration": a.max_acceleration,
                    "limit_jerk": a.max_jerk,
                }),
            );
        }
    }
    let mut joints = Map::new();
    for (j, jc) in config.joints.iter().enumerate() {
        joints.insert(
            jc.name.clone(),
            json!({ "max_following_error": stats.max_following_error[j] }),
        );
    }
    let value = json!({
        "machine": config.machine.name,
        "cycle_time_s": summary.cycle_time_s,
        "ended": summary.ended,
        "servo_period_s": config.servo_period().as_secs_f64(),
        "limits_exceeded": summary.limits_exceeded,
        "axes": Value::Object(axes),
        "joints": Value::Object(joints),
        "faults": summary.faults,
        "messages": summary
            .messages
            .iter()
            .map(|(t, line, text)| json!({ "time_s": t, "line": line, "text": text }))
            .collect::<Vec<_>>(),
        "program_error": error_text,
    });
    std::fs::write(path, serde_json::to_string_pretty(&value)? + "\n")
        .with_context(|| format!("{}", path.display()))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_refused_block_stops_the_program_a_warning_does_not() {
        assert!(stops_program(FaultCode::AuxRefused));
        assert!(stops_program(FaultCode::SyncFailed));
        assert!(stops_program(FaultCode::ProgramError));
        assert!(!stops_program(FaultCode::DeadlineMiss));
        assert!(!stops_program(FaultCode::CommandRefused));
    }
}
