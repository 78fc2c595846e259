//! `rtcnc sim`: runs a part program on a machine configuration in virtual time (as fast as
//! the processor allows, the same result every run) and reports what the machine did:
//! cycle time, limits, following errors, faults; with `--out` also the set-points and
//! feedback as CSV, an SVG plot, the executive's trace and `summary.json`.

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};
use rtcnc_kernel::report::RunStats;
use rtcnc_kernel::{
    Command, Fault, FaultCode, Kernel, KernelOptions, MachineConfig, MachineState, Sample,
    Simulation, Urgent,
};

/// Run a G-code program on a simulated machine in virtual time.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The part program.
    program: PathBuf,
    /// Machine configuration (TOML).
    #[arg(long, default_value = "configs/sim-mill.toml")]
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
    pub cycle_time_s: f64,
    pub ended: bool,
    pub limits_exceeded: bool,
    pub faults: Vec<String>,
    /// Operator messages: time since the program start (s), line, text.
    pub messages: Vec<(f64, u32, String)>,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let config = MachineConfig::load(&args.machine)
        // The error names the file.
        .context("machine configuration")?;
    if !args.program.is_file() {
        bail!("{}: no such program file", args.program.display());
    }
    let kernel = Kernel::build(
        &config,
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
    let period = config.servo_period();
    let period_s = period.as_secs_f64();
    let mut sim = Simulation::new(kernel);
    if args.profile {
        sim = sim.with_host_profile();
    }
    let recording_ns = std::cell::Cell::new(0u64);
    let whole_run = Instant::now();
    let handle = sim.handle().clone();

    let mut writers = match &args.out {
        Some(dir) => Some(Outputs::create(dir, &config)?),
        None => None,
    };
    let mut stats = RunStats::new();
    // Only --out draws the plot; its points are decimated to a bounded number.
    let mut plot = args.out.as_ref().map(|_| PlotData::default());
    let mut faults: Vec<Fault> = Vec::new();
    let mut io_error: Option<std::io::Error> = None;
    let profile = args.profile;
    let mut sink = |s: &Sample| {
        let t0 = profile.then(Instant::now);
        stats.add(s, period_s);
        if let Some(plot) = plot.as_mut() {
            plot.add(s);
        }
        if let Some(w) = writers.as_mut() {
            if let Err(e) = w.write(s, config.joints.len()) {
                io_error.get_or_insert(e);
            }
        }
        if let Some(t0) = t0 {
            recording_ns.set(recording_ns.get() + t0.elapsed().as_nanos() as u64);
        }
    };

    // Power up, reset, optionally home, start.
    sim.run_cycles(2, &mut sink)?;
    handle.command(Command::Reset);
    if !sim.run_until(Duration::from_secs(1), &mut sink, |s| s.ready)? {
        bail!("the drives did not enable within 1 s");
    }
    if args.home {
        handle.command(Command::HomeAll);
        sim.run_cycles(3, &mut sink)?;
        sim.run_until(Duration::from_secs(600), &mut sink, |s| {
            s.state != MachineState::Running
        })?;
    }
    handle.command(Command::Start { from_line: 0 });
    sim.run_cycles(2, &mut sink)?;
    let start = sim.now();
    let wall = Instant::now();
    let bar = progress_bar(args.quiet);
    let mut messages: Vec<(f64, u32, String)> = Vec::new();
    let limit = args.limit;
    let mut ended = false;
    // Program pauses met: times since the start.
    let mut pauses: Vec<f64> = Vec::new();
    let mut was_paused = false;
    loop {
        let resume_after = args.resume_after_pause;
        let done = sim.run_until(Duration::from_millis(100), &mut sink, |s| {
            (s.program_ended && s.state == MachineState::Idle)
                || matches!(s.state, MachineState::Fault | MachineState::EStop)
                || (resume_after.is_some() && s.state == MachineState::Paused)
        })?;
        let status = handle.status();
        if let (Some(wait), MachineState::Paused) = (resume_after, status.state) {
            pauses.push((sim.now() - start).as_secs_f64());
            let periods = (wait.as_secs_f64() / period_s).round() as u64;
            sim.run_cycles(periods, &mut sink)?;
            handle.urgent(Urgent::Resume);
            // The pause ends within a period or two.
            sim.run_until(Duration::from_millis(100), &mut sink, |s| {
                s.state != MachineState::Paused
            })?;
            continue;
        }
        let paused = status.state == MachineState::Paused;
        if paused && !was_paused {
            // Without --resume-after-pause: reported once, it lasts to the time limit.
            pauses.push((sim.now() - start).as_secs_f64());
        }
        was_paused = paused;
        faults.extend(handle.take_faults());
        take_messages(&handle, start, &bar, &mut messages);
        if let Some(bar) = &bar {
            bar.set_message(format!(
                "t {:.1} s  line {}  X{:.3} Y{:.3} Z{:.3}  {:.1} mm/s  {}",
                (sim.now() - start).as_secs_f64(),
                status.line,
                status.axes[0],
                status.axes[1],
                status.axes[2],
                status.path_speed,
                status.state.as_str()
            ));
            bar.tick();
        }
        if done {
            ended = status.program_ended && status.state == MachineState::Idle;
            break;
        }
        if sim.now() - start > limit {
            break;
        }
        // A block the kernel refused (a program error, a machine function it cannot carry
        // out, an impossible synchronised move) stops the program and leaves the machine
        // idle: nothing more will happen.
        if status.state == MachineState::Idle && faults.iter().any(|f| stops_program(f.code)) {
            break;
        }
    }
    let cycle_time = (sim.now() - start).as_secs_f64();
    // Let the machine settle a moment so the feedback of the last move is recorded.
    sim.run_cycles(20, &mut sink)?;
    faults.extend(handle.take_faults());
    take_messages(&handle, start, &bar, &mut messages);
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    let wall_s = wall.elapsed().as_secs_f64();
    let whole_run_ns = whole_run.elapsed().as_nanos() as u64;
    if let Some(e) = io_error {
        return Err(e).context("writing the CSV files");
    }

    // Report.
    let plan = config.axis_plan();
    let mut exceeded = Vec::new();
    for p in &plan {
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
    let fault_texts: Vec<String> = faults
        .iter()
        .filter(|f| f.code != FaultCode::CommandRefused)
        .map(|f| handle.describe(f))
        .collect();
    let error_text = handle.error_text();
    println!("program     {}", args.program.display());
    println!(
        "machine     {} ({})",
        config.machine.name,
        args.machine.display()
    );
    println!(
        "cycle time  {cycle_time:.3} s{}",
        if ended {
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
    for p in &plan {
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
    for t in &pauses {
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
    if exceeded.is_empty() {
        println!("limits      respected");
    } else {
        println!("limits      EXCEEDED");
        for e in &exceeded {
            println!("  {e}");
        }
    }
    if fault_texts.is_empty() {
        println!("faults      none");
    } else {
        println!("faults");
        for f in &fault_texts {
            println!("  {f}");
        }
        if let Some(t) = &error_text {
            println!("  {t}");
        }
    }

    if let Some(profile) = sim.runner().host_profile() {
        print_profile(
            profile,
            whole_run_ns,
            recording_ns.get(),
            sim.now().as_secs_f64(),
        );
    }

    if let Some(dir) = &args.out {
        if let Some(w) = writers.take() {
            w.finish()?;
        }
        write_summary(
            &dir.join("summary.json"),
            &config,
            &stats,
            &Summary {
                cycle_time_s: cycle_time,
                ended,
                limits_exceeded: !exceeded.is_empty(),
                faults: fault_texts.clone(),
                messages,
            },
            error_text.as_deref(),
        )?;
        let plot = plot.unwrap_or_default();
        std::fs::write(dir.join("plot.svg"), plot.svg(&config))
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
    }
    Ok(if ended && exceeded.is_empty() && fault_texts.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
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

/// The CSV files, written row by row into buffers that go to the files in large pieces; the
/// numbers are formatted by `decimal` (the standard formatter's text, several times
/// faster), so that recording every period stays a small part of a run.
struct Outputs {
    setpoints: std::fs::File,
    feedback: std::fs::File,
    setpoints_buf: Vec<u8>,
    feedback_buf: Vec<u8>,
    axes: Vec<usize>,
}

/// Bytes gathered before a write to a CSV file.
const CSV_CHUNK: usize = 1 << 16;

impl Outputs {
    fn create(dir: &Path, config: &MachineConfig) -> anyhow::Result<Outputs> {
        std::fs::create_dir_all(dir).with_context(|| format!("{}", dir.display()))?;
        let open = |name: &str| -> anyhow::Result<std::fs::File> {
            let path = dir.join(name);
            std::fs::File::create(&path).with_context(|| format!("{}", path.display()))
        };
        let setpoints = open("setpoints.csv")?;
        let feedback = open("feedback.csv")?;
        let mut head = String::from("time_s,cycle,line,path_speed");
        for p in config.axis_plan() {
            let _ = write!(head, ",{}", p.axis.letter());
        }
        for j in &config.joints {
            let _ = write!(head, ",{}_setpoint", j.name);
        }
        head.push('\n');
        let mut setpoints_buf = Vec::with_capacity(2 * CSV_CHUNK);
        setpoints_buf.extend_from_slice(head.as_bytes());
        let mut head = String::from("time_s,cycle");
        for j in &config.joints {
            let _ = write!(head, ",{}_feedback,{}_following_error", j.name, j.name);
        }
        head.push('\n');
        let mut feedback_buf = Vec::with_capacity(2 * CSV_CHUNK);
        feedback_buf.extend_from_slice(head.as_bytes());
        Ok(Outputs {
            setpoints,
            feedback,
            setpoints_buf,
            feedback_buf,
            axes: config.axis_plan().iter().map(|p| p.axis as usize).collect(),
        })
    }

    fn write(&mut self, s: &Sample, joints: usize) -> std::io::Result<()> {
        use crate::decimal::{push_fixed, push_u64};
        let t = s.time_ns as f64 * 1e-9;
        let out = &mut self.setpoints_buf;
        push_fixed(out, t, 6);
        out.push(b',');
        push_u64(out, s.cycle);
        out.push(b',');
        push_u64(out, u64::from(s.line));
        out.push(b',');
        push_fixed(out, s.path_speed, 6);
        for &i in &self.axes {
            out.push(b',');
            push_fixed(out, s.axes[i], 6);
        }
        for j in 0..joints {
            out.push(b',');
            push_fixed(out, s.setpoint[j], 6);
        }
        out.push(b'\n');
        let out = &mut self.feedback_buf;
        push_fixed(out, t, 6);
        out.push(b',');
        push_u64(out, s.cycle);
        for j in 0..joints {
            out.push(b',');
            push_fixed(out, s.feedback[j], 6);
            out.push(b',');
            push_fixed(out, s.following_error[j], 7);
        }
        out.push(b'\n');
        if self.setpoints_buf.len() >= CSV_CHUNK {
            self.setpoints.write_all(&self.setpoints_buf)?;
            self.setpoints_buf.clear();
        }
        if self.feedback_buf.len() >= CSV_CHUNK {
            self.feedback.write_all(&self.feedback_buf)?;
            self.feedback_buf.clear();
        }
        Ok(())
    }

    fn finish(mut self) -> anyhow::Result<()> {
        self.setpoints.write_all(&self.setpoints_buf)?;
        self.feedback.write_all(&self.feedback_buf)?;
        self.setpoints.flush()?;
        self.feedback.flush()?;
        Ok(())
    }
}

/// Whether a fault leaves the program stopped (and `sim` with nothing more to wait for):
/// every fault but a refused operator command and the ones that only warn.
fn stops_program(code: FaultCode) -> bool {
    !matches!(
        code,
        FaultCode::CommandRefused | FaultCode::DeadlineMiss | FaultCode::BackgroundCheck
    )
}

/// Most points the plot keeps: once twice this many are gathered, every other one goes and
/// only every other servo period is taken from then on, so memory stays bounded however
/// long the program runs.
const PLOT_POINTS: usize = 20_000;

struct PlotData {
    points: Vec<(f64, f64, f64, f64)>,
    /// A point is kept every `stride` samples.
    stride: u64,
    samples: u64,
}

impl Default for PlotData {
    fn default() -> Self {
        PlotData {
            points: Vec::with_capacity(2 * PLOT_POINTS),
            stride: 1,
            samples: 0,
        }
    }
}

impl PlotData {
    fn add(&mut self, s: &Sample) {
        let keep = self.samples % self.stride == 0;
        self.samples += 1;
        if !keep {
            return;
        }
        self.points
            .push((s.time_ns as f64 * 1e-9, s.axes[0], s.axes[1], s.path_speed));
        if self.points.len() >= 2 * PLOT_POINTS {
            let mut i = 0;
            self.points.retain(|_| {
                i += 1;
                i % 2 == 1
            });
            self.stride *= 2;
        }
    }

    /// Tool path (X-Y, or Z-X on a lathe) and path speed over time, hand-written SVG.
    fn svg(&self, config: &MachineConfig) -> String {
        let lathe = config.machine.kind == rtcnc_kernel::config::MachineKind::Lathe;
        let stride = (self.points.len() / 20_000).max(1);
        let pts: Vec<_> = self.points.iter().step_by(stride).copied().collect();
        let (w, h) = (520.0, 420.0);
        let mut out = String::new();
        let _ = write!(
            out,
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="1100" height="480" font-family="sans-serif" font-size="12">
<rect width="1100" height="480" fill="white"/>
"#
        );
        // Tool path.
        let xy: Vec<(f64, f64)> = pts
            .iter()
            .map(|p| if lathe { (p.2, p.1) } else { (p.1, p.2) })
            .collect();
        let (label_x, label_y) = if lathe { ("Z", "X") } else { ("X", "Y") };
        panel(
            &mut out,
            40.0,
            30.0,
            w,
            h,
            &xy,
            label_x,
            label_y,
            "tool path",
            true,
        );
        let speed: Vec<(f64, f64)> = pts.iter().map(|p| (p.0, p.3)).collect();
        panel(
            &mut out,
            600.0,
            30.0,
            w - 40.0,
            h,
            &speed,
            "t (s)",
            "path speed (mm/s)",
            "velocity over time",
            false,
        );
        out.push_str("</svg>\n");
        out
    }
}

#[allow(clippy::too_many_arguments)]
fn panel(
    out: &mut String,
    x0: f64,
    y0: f64,
    w: f64,
    h: f64,
    pts: &[(f64, f64)],
    label_x: &str,
    label_y: &str,
    title: &str,
    equal: bool,
) {
    let finite = pts.iter().filter(|p| p.0.is_finite() && p.1.is_finite());
    let (mut xmin, mut xmax, mut ymin, mut ymax) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for p in finite {
        xmin = xmin.min(p.0);
        xmax = xmax.max(p.0);
        ymin = ymin.min(p.1);
        ymax = ymax.max(p.1);
    }
    if xmin > xmax {
        (xmin, xmax, ymin, ymax) = (0.0, 1.0, 0.0, 1.0);
    }
    if xmax - xmin < 1e-9 {
        xmax = xmin + 1.0;
    }
    if ymax - ymin < 1e-9 {
        ymax = ymin + 1.0;
    }
    let (mut sx, mut sy) = (w / (xmax - xmin), h / (ymax - ymin));
    if equal {
        let s = sx.min(sy);
        sx = s;
        sy = s;
    }
    let _ = writeln!(
        out,
        r##"<g><rect x="{x0}" y="{y0}" width="{w}" height="{h}" fill="none" stroke="#999"/>
<text x="{}" y="{}" text-anchor="middle" font-weight="bold">{title}</text>
<text x="{}" y="{}" text-anchor="middle">{label_x}: {xmin:.2} … {xmax:.2}</text>
<text x="{}" y="{}" text-anchor="middle" transform="rotate(-90 {} {})">{label_y}: {ymin:.2} … {ymax:.2}</text>"##,
        x0 + w / 2.0,
        y0 - 10.0,
        x0 + w / 2.0,
        y0 + h + 18.0,
        x0 - 12.0,
        y0 + h / 2.0,
        x0 - 12.0,
        y0 + h / 2.0
    );
    out.push_str(r##"<polyline fill="none" stroke="#1565c0" stroke-width="1" points=""##);
    for p in pts {
        if p.0.is_finite() && p.1.is_finite() {
            let _ = write!(
                out,
                "{:.2},{:.2} ",
                x0 + (p.0 - xmin) * sx,
                y0 + h - (p.1 - ymin) * sy
            );
        }
    }
    out.push_str("\"/></g>\n");
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

    fn sample(cycle: u64) -> Sample {
        Sample {
            time_ns: cycle * 1_000_000,
            cycle,
            setpoint: [0.0; 16],
            feedback: [0.0; 16],
            following_error: [0.0; 16],
            axes: [0.0; 9],
            line: 0,
            path_speed: 0.0,
        }
    }

    #[test]
    fn the_plot_keeps_a_bounded_number_of_evenly_spaced_points() {
        let mut plot = PlotData::default();
        // An hour of 1 ms periods.
        for cycle in 0..3_600_000 {
            plot.add(&sample(cycle));
        }
        assert!(plot.points.len() < 2 * PLOT_POINTS, "{}", plot.points.len());
        assert!(plot.points.len() >= PLOT_POINTS / 2);
        // Evenly spaced: every kept point is `stride` periods after the one before.
        let step = plot.points[1].0 - plot.points[0].0;
        assert!((step - plot.stride as f64 * 1e-3).abs() < 1e-9);
        for w in plot.points.windows(2) {
            assert!((w[1].0 - w[0].0 - step).abs() < 1e-6);
        }
        assert_eq!(plot.points[0].0, 0.0);
    }

    #[test]
    fn a_refused_block_stops_the_program_a_warning_does_not() {
        assert!(stops_program(FaultCode::AuxRefused));
        assert!(stops_program(FaultCode::SyncFailed));
        assert!(stops_program(FaultCode::ProgramError));
        assert!(!stops_program(FaultCode::DeadlineMiss));
        assert!(!stops_program(FaultCode::CommandRefused));
    }
}
