//! `rtcnc latency`: the executive's wake-up latency, measured like cyclictest: one periodic
//! task on the real-time runner records, every period, the time between its absolute release
//! and the moment its thread woke up.

use std::io::{IsTerminal, Write as _};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use rtcnc_rt::histogram::{LinearHistogram, Summary};
use rtcnc_rt::{
    BinarySemaphore, RealTimeConfig, RealTimeRunner, SchedulingMode, TaskSet,
    executive_priority_for_os, os_priority, parse_duration,
};

/// Measure the executive's wake-up latency (like cyclictest).
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Period of the measuring task, e.g. 1ms, 500us.
    #[arg(long, default_value = "1ms", value_parser = positive_duration)]
    period: Duration,
    /// How long to measure, e.g. 10s, 1min.
    #[arg(long, default_value = "10s", value_parser = positive_duration)]
    duration: Duration,
    /// SCHED_FIFO priority of the measuring thread (1..=99, as cyclictest's -p).
    #[arg(long, default_value_t = 80, value_parser = clap::value_parser!(i32).range(1..=99))]
    priority: i32,
    /// Run CPU load threads (one per CPU, normal priority) while measuring.
    #[arg(long)]
    load: bool,
    /// Pin the measuring thread to this CPU.
    #[arg(long)]
    cpu: Option<usize>,
    /// Write the latency histogram as an SVG plot to this file.
    #[arg(long, value_name = "FILE")]
    svg: Option<PathBuf>,
    /// Write the run's trace (Chrome trace-event JSON, opens in Perfetto) to this file.
    #[arg(long, value_name = "FILE")]
    trace: Option<PathBuf>,
    /// Histogram range in microseconds (1 µs bins; larger latencies are counted as overflow).
    #[arg(long, default_value_t = 10_000, value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
    histogram_us: u64,
    /// No progress line.
    #[arg(long, short)]
    quiet: bool,
}

fn positive_duration(text: &str) -> Result<Duration, String> {
    parse_duration(text).map_err(|e| e.to_string())
}

/// Starts one spinning thread per CPU at normal priority; they stop when `stop` is raised.
fn start_load(stop: &Arc<AtomicBool>) -> anyhow::Result<Vec<std::thread::JoinHandle<()>>> {
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    (0..cpus)
        .map(|i| {
            let stop = Arc::clone(stop);
            std::thread::Builder::new()
                .name(format!("load{i}"))
                .spawn(move || {
                    // Integer and memory work, so caches and the memory bus are busy too.
                    let mut buf = vec![0u64; 1 << 18];
                    let mut x = 0x9e37_79b9_7f4a_7c15u64 ^ i as u64;
                    while !stop.load(Ordering::Relaxed) {
                        for _ in 0..4096 {
                            x ^= x << 13;
                            x ^= x >> 7;
                            x ^= x << 17;
                            let j = (x as usize) & (buf.len() - 1);
                            buf[j] = buf[j].wrapping_add(x);
                        }
                    }
                    std::hint::black_box(&buf);
                })
                .context("starting a load thread")
        })
        .collect()
}

fn us(ns: u64) -> f64 {
    ns as f64 / 1000.0
}

/// Runs `rtcnc latency`.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let period_ns = u64::try_from(args.period.as_nanos()).unwrap_or(u64::MAX);
    let bins = usize::try_from(args.histogram_us).unwrap_or(10_000);
    let histogram = Arc::new(LinearHistogram::new(1_000, bins));
    let cycles = args.duration.as_nanos() / u128::from(period_ns.max(1));

    let mut builder = TaskSet::builder();
    let priority = executive_priority_for_os(args.priority);
    let thread = builder.periodic_thread("latency", args.period, priority);
    let h = Arc::clone(&histogram);
    let samples = u64::try_from(cycles).unwrap_or(u64::MAX).max(1);
    let done = BinarySemaphore::new("latency done");
    let finished = done.clone();
    let mut taken = 0u64;
    builder.periodic(thread, "measure", 1, move |ctx| {
        // Start lateness of the thread's first task is its wake-up latency.
        if taken < samples {
            h.record(u64::try_from(ctx.lateness().as_nanos()).unwrap_or(u64::MAX));
            taken += 1;
            if taken == samples {
                finished.signal();
            }
        }
    });
    let trace_events = if args.trace.is_some() {
        usize::try_from(cycles)
            .unwrap_or(usize::MAX)
            .saturating_add(16)
            .min(4_000_000)
    } else {
        0
    };
    builder.trace_capacity(trace_events);
    let set = builder.build()?;

    let stop_load = Arc::new(AtomicBool::new(false));
    let load_threads = if args.load {
        start_load(&stop_load)?
    } else {
        Vec::new()
    };

    let config = RealTimeConfig {
        scheduling: SchedulingMode::BestEffort,
        lock_memory: true,
        cpus: args.cpu.map(|c| vec![c]),
        ..RealTimeConfig::default()
    };
    let handle = RealTimeRunner::start(set, config).context("starting the real-time runner")?;
    let fifo = handle.is_fifo();
    eprintln!(
        "rtcnc latency: period {:?}, duration {:?}, {}, load {}",
        args.period,
        args.duration,
        if fifo {
            format!(
                "SCHED_FIFO priority {} (executive priority {priority})",
                os_priority(priority)
            )
        } else {
            "normal thread: NOT real-time".to_string()
        },
        if args.load { "on" } else { "off" }
    );

    let started = Instant::now();
    let progress = !args.quiet && std::io::stderr().is_terminal();
    // Generous bound: a machine that cannot keep up still ends, with the samples it has.
    let give_up = args.duration * 2 + Duration::from_secs(5);
    while done.wait_timeout(Duration::from_secs(1)).is_err() {
        if started.elapsed() > give_up {
            eprintln!("rtcnc latency: the measuring thread fell behind; stopping early");
            break;
        }
        if progress {
            let s = histogram.summary();
            eprint!(
                "\r  {:>5.1} s  samples {:>8}  max {:>8.1} us",
                started.elapsed().as_secs_f64(),
                s.count,
                us(s.max)
            );
            let _ = std::io::stderr().flush();
        }
    }
    if progress {
        eprintln!();
    }
    let recording = handle.stop();
    stop_load.store(true, Ordering::Relaxed);
    for t in load_threads {
        let _ = t.join();
    }

    let summary = histogram.summary();
    let stats = recording
        .monitor()
        .task("measure")
        .map(|t| t.stats())
        .context("measuring task missing from the monitor")?;
    println!(
        "latency (us): samples {}  min {:.1}  mean {:.1}  p99 {:.1}  max {:.1}",
        summary.count,
        us(summary.min),
        us(summary.mean),
        us(summary.p99),
        us(summary.max)
    );
    println!(
        "deadline misses {}  skipped periods {}  over {} us: {}",
        stats.deadline_misses,
        stats.skipped_releases,
        args.histogram_us,
        histogram.overflow()
    );
    print!("{}", text_histogram(&histogram, &summary));

    if let Some(path) = &args.svg {
        std::fs::write(path, svg_histogram(&histogram, &summary, &args, fifo))
            .with_context(|| format!("writing {}", path.display()))?;
        eprintln!("histogram plot written to {}", path.display());
    }
    if let Some(path) = &args.trace {
        recording
            .trace()
            .write_chrome_json(path)
            .with_context(|| format!("writing {}", path.display()))?;
        eprintln!("trace written to {}", path.display());
    }
    Ok(ExitCode::SUCCESS)
}

/// Rows of (first µs, last µs, count) covering the occupied range in at most `rows` rows.
fn histogram_rows(h: &LinearHistogram, summary: &Summary, rows: usize) -> Vec<(u64, u64, u64)> {
    let bins = h.bins();
    let width = h.bin_width();
    let first = (summary.min / width) as usize;
    let last = ((summary.max / width) as usize).min(bins.len().saturating_sub(1));
    if summary.count == 0 || first > last {
        return Vec::new();
    }
    let span = last - first + 1;
    let step = span.div_ceil(rows.max(1));
    (first..=last)
        .step_by(step)
        .map(|start| {
            let stop = (start + step - 1).min(last);
            let count = bins[start..=stop].iter().sum();
            (start as u64, stop as u64, count)
        })
        .collect()
}

/// A cyclictest-like text histogram with logarithmic bars: 1 µs rows from the minimum for
/// the first 16 µs, then rows twice as wide each time up to the maximum; empty rows left out.
fn text_histogram(h: &LinearHistogram, summary: &Summary) -> String {
    let bins = h.bins();
    let mut rows = Vec::new();
    if summary.count > 0 {
        let last = ((summary.max / h.bin_width()) as usize).min(bins.len().saturating_sub(1));
        let mut from = (summary.min / h.bin_width()) as usize;
        let mut width = 1usize;
        let mut n = 0;
        while from <= last {
            let to = (from + width - 1).min(last);
            rows.push((from as u64, to as u64, bins[from..=to].iter().sum::<u64>()));
            from = to + 1;
            n += 1;
            if n >= 16 {
                width *= 2;
            }
        }
    }
    let peak = rows.iter().map(|r| r.2).max().unwrap_or(0).max(1);
    let scale = 50.0 / ((peak + 1) as f64).log10();
    let mut out = String::from("histogram (latency us, samples, logarithmic bars)\n");
    for (from, to, count) in rows {
        if count == 0 {
            continue;
        }
        let bar = (((count + 1) as f64).log10() * scale).ceil() as usize;
        let label = if from == to {
            format!("{from}")
        } else {
            format!("{from}-{to}")
        };
        out.push_str(&format!("{label:>11} {count:>9} {}\n", "#".repeat(bar)));
    }
    if h.overflow() > 0 {
        out.push_str(&format!("{:>11} {:>9}\n", "overflow", h.overflow()));
    }
    out
}

/// An SVG bar chart: latency (µs) across, samples (logarithmic) up, p99 and max marked.
fn svg_histogram(h: &LinearHistogram, summary: &Summary, args: &Args, fifo: bool) -> String {
    const W: f64 = 900.0;
    const HT: f64 = 420.0;
    const LEFT: f64 = 70.0;
    const RIGHT: f64 = 20.0;
    const TOP: f64 = 50.0;
    const BOTTOM: f64 = 60.0;
    let rows = histogram_rows(h, summary, 200);
    let plot_w = W - LEFT - RIGHT;
    let plot_h = HT - TOP - BOTTOM;
    // 5 % room right of the largest value, so the max bar and its label stay visible.
    let x_max = (rows.last().map_or(1, |r| r.1 + 1).max(1) as f64 * 1.05).ceil();
    let peak = rows.iter().map(|r| r.2).max().unwrap_or(1).max(1) as f64;
    let y_top = peak.log10().ceil().max(1.0);
    let x = |v: f64| LEFT + v / x_max * plot_w;
    let y = |count: f64| {
        let l = if count <= 0.0 {
            0.0
        } else {
            (count.log10() + 1.0) / (y_top + 1.0)
        };
        TOP + plot_h * (1.0 - l)
    };
    let mut s = String::new();
    s.push_str(&format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{W}\" height=\"{HT}\" viewBox=\"0 0 {W} {HT}\" font-family=\"sans-serif\" font-size=\"12\">\n"
    ));
    s.push_str(&format!(
        "<rect width=\"{W}\" height=\"{HT}\" fill=\"white\"/>\n"
    ));
    s.push_str(&format!(
        "<text x=\"{}\" y=\"22\" font-size=\"15\" text-anchor=\"middle\">rtcnc wake-up latency: period {:?}, {:?}, priority {}{}{}</text>\n",
        W / 2.0,
        args.period,
        args.duration,
        args.priority,
        if args.load { ", under load" } else { "" },
        if fifo { "" } else { " (NOT real-time)" }
    ));
    s.push_str(&format!(
        "<text x=\"{}\" y=\"40\" text-anchor=\"middle\">samples {}  min {:.1} us  mean {:.1} us  p99 {:.1} us  max {:.1} us</text>\n",
        W / 2.0,
        summary.count,
        us(summary.min),
        us(summary.mean),
        us(summary.p99),
        us(summary.max)
    ));
    // axes and log grid
    for decade in 0..=(y_top as i32) {
        let c = 10f64.powi(decade);
        let yy = y(c);
        s.push_str(&format!(
            "<line x1=\"{LEFT}\" y1=\"{yy:.1}\" x2=\"{}\" y2=\"{yy:.1}\" stroke=\"#ddd\"/><text x=\"{}\" y=\"{:.1}\" text-anchor=\"end\">{}</text>\n",
            W - RIGHT,
            LEFT - 6.0,
            yy + 4.0,
            c as u64
        ));
    }
    s.push_str(&format!(
        "<line x1=\"{LEFT}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"black\"/>\n",
        TOP + plot_h,
        W - RIGHT,
        TOP + plot_h
    ));
    s.push_str(&format!(
        "<line x1=\"{LEFT}\" y1=\"{TOP}\" x2=\"{LEFT}\" y2=\"{}\" stroke=\"black\"/>\n",
        TOP + plot_h
    ));
    let tick = nice_step(x_max / 8.0);
    let mut t = 0.0;
    while t <= x_max {
        s.push_str(&format!(
            "<text x=\"{:.1}\" y=\"{}\" text-anchor=\"middle\">{}</text>\n",
            x(t),
            TOP + plot_h + 16.0,
            t as u64
        ));
        t += tick;
    }
    s.push_str(&format!(
        "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">latency (us)</text>\n",
        LEFT + plot_w / 2.0,
        HT - 16.0
    ));
    s.push_str(&format!(
        "<text transform=\"translate(18 {}) rotate(-90)\" text-anchor=\"middle\">samples (log)</text>\n",
        TOP + plot_h / 2.0
    ));
    for (from, to, count) in &rows {
        if *count == 0 {
            continue;
        }
        let x0 = x(*from as f64);
        let x1 = x((*to + 1) as f64);
        let y0 = y(*count as f64);
        s.push_str(&format!(
            "<rect x=\"{x0:.2}\" y=\"{y0:.2}\" width=\"{:.2}\" height=\"{:.2}\" fill=\"#3572b0\"/>\n",
            (x1 - x0).max(0.8),
            TOP + plot_h - y0
        ));
    }
    for (label, value, color) in [
        ("p99", summary.p99, "#e08000"),
        ("max", summary.max, "#c00000"),
    ] {
        let xx = x(us(value).min(x_max));
        let (tx, anchor) = if xx > W - RIGHT - 40.0 {
            (xx - 3.0, "end")
        } else {
            (xx + 3.0, "start")
        };
        s.push_str(&format!(
            "<line x1=\"{xx:.1}\" y1=\"{TOP}\" x2=\"{xx:.1}\" y2=\"{}\" stroke=\"{color}\" stroke-dasharray=\"4 3\"/><text x=\"{tx:.1}\" y=\"{}\" fill=\"{color}\" text-anchor=\"{anchor}\">{label}</text>\n",
            TOP + plot_h,
            TOP + 12.0
        ));
    }
    s.push_str("</svg>\n");
    s
}

/// 1, 2 or 5 times a power of ten, at least `raw`.
fn nice_step(raw: f64) -> f64 {
    let raw = raw.max(1.0);
    let p = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * p)
        .find(|&v| v >= raw)
        .unwrap_or(10.0 * p)
}
