#![allow(clippy::needless_range_loop)]
//! Cycle time of the benchmark polylines (1 µm chords, G64 P0.001, F6000) against the
//! physical limit (toppra, no jerk limit) and LinuxCNC 2.9, with the limits measured on our
//! set-points.
//!
//! Usage: `cargo run --release -p rtcnc-motion --example bench_paths [DIR]`; DIR defaults to
//! `$RTCNC_PEERS/bench-paths` or `../shared/peers/bench-paths` from the repository root.
//! The reference figures are the ones measured by the peers on this project's machine.

use rtcnc_motion::{
    AXES, Axis, AxisLimits, MachineLimits, Move, PathMode, Planner, TrivialKinematics,
};
use std::path::PathBuf;

/// BENCHMARK-ONLY reader of the simple programs in bench-paths: `G64 P.. [Q..]`, one `G0 X Y Z`
/// and `G1 X Y Z [F]` lines. To be replaced by the interpreter crate.
fn read_bench_program(text: &str) -> ([f64; AXES], Vec<Move>) {
    let mut start = [0.0; AXES];
    let mut moves = Vec::new();
    let mut p = 0.0;
    let mut q = None;
    let mut feed = 0.0;
    let mut pos = [0.0; AXES];
    for (n, raw) in text.lines().enumerate() {
        let line = raw.split('(').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let words: Vec<(char, f64)> = line
            .split_whitespace()
            .filter_map(|w| {
                let c = w.chars().next()?.to_ascii_uppercase();
                Some((c, w[1..].parse().ok()?))
            })
            .collect();
        let g: Vec<f64> = words.iter().filter(|w| w.0 == 'G').map(|w| w.1).collect();
        for (c, v) in &words {
            match c {
                'P' => p = *v,
                'Q' => q = Some(*v),
                'F' => feed = *v / 60.0,
                'X' | 'Y' | 'Z' => pos[Axis::from_letter(*c).map_or(0, |a| a as usize)] = *v,
                _ => {}
            }
        }
        if g.contains(&0.0) {
            start = pos;
        } else if g.contains(&1.0) {
            let mode = PathMode::Blend {
                tolerance: p,
                merge_tolerance: q.unwrap_or(p),
            };
            moves.push(Move::line(pos, feed, mode, n as u32 + 1));
        }
    }
    (start, moves)
}

struct Measured {
    time: f64,
    vmax: [f64; 3],
    amax: [f64; 3],
    jmax: [f64; 3],
    end_err: f64,
    violations: u64,
    plan_s: f64,
    segments: usize,
    geo: String,
    ns_per_period: f64,
    /// Calls of `Planner::next` (for instruction counts per period).
    calls: usize,
}

fn run(start: [f64; AXES], moves: &[Move], t: f64) -> Measured {
    let lim = AxisLimits::new(100.0, 1000.0, 50_000.0, -1000.0, 1000.0);
    let machine = MachineLimits::uniform(&[Axis::X, Axis::Y, Axis::Z], lim);
    let kin = TrivialKinematics::identity(&[Axis::X, Axis::Y, Axis::Z]);
    let trickle = std::env::var_os("BENCH_PATHS_TRICKLE").is_some();
    let window = std::env::var("BENCH_PATHS_WINDOW")
        .ok()
        .and_then(|w| w.parse().ok())
        .unwrap_or(if trickle { 256 } else { 1024 });
    let mut pl = Planner::new(&machine, kin, t, window, start).expect("planner");
    let mut joints = [0.0; 3];
    let mut pts: Vec<[f64; AXES]> = vec![start; 3];
    let mut k = 0;
    let mut flushed = false;
    let mut plan = std::time::Duration::ZERO;
    let mut interp = std::time::Duration::ZERO;
    let mut moving_periods = 0usize;
    let mut calls = 0usize;
    let mut speeds = Vec::new();
    for _ in 0..10_000_000 {
        let t0 = std::time::Instant::now();
        if k < moves.len() && pl.free() > 0 {
            // BENCH_PATHS_TRICKLE: one move per period into a 256-piece window, as a
            // kernel feeding the planner while it runs.
            let n = if trickle { 1 } else { moves.len() - k };
            let pushed = pl.push_all(&moves[k..k + n]).expect("push");
            if pushed > 0 && std::env::var_os("BENCH_PATHS_PUSHLOG").is_some() {
                eprintln!("period {calls}: pushed moves {k}..{}", k + pushed);
            }
            k += pushed;
        }
        if k == moves.len() && !flushed {
            pl.flush();
            flushed = true;
        }
        plan += t0.elapsed();
        let t1 = std::time::Instant::now();
        let st = pl.next(&mut joints);
        calls += 1;
        interp += t1.elapsed();
        if st.state == rtcnc_motion::MotionState::Idle && flushed {
            break;
        }
        pts.push(st.axes);
        speeds.push(st.path_speed);
        moving_periods += 1;
    }
    if let Some(path) = std::env::var_os("BENCH_PATHS_SPEED") {
        // Diagnostics: the path speed of every period, one per line (last program run).
        let text: String = speeds.iter().map(|v| format!("{v}\n")).collect();
        let _ = std::fs::write(path, text);
        eprintln!("{:?}", pl.stats());
    }
    if let Some(path) = std::env::var_os("BENCH_PATHS_POINTS") {
        // Diagnostics: the set-point of every period, x y z (last program run).
        let text: String = pts
            .iter()
            .map(|p| format!("{} {} {}\n", p[0], p[1], p[2]))
            .collect();
        let _ = std::fs::write(path, text);
    }
    let mut m = Measured {
        time: 0.0,
        vmax: [0.0; 3],
        amax: [0.0; 3],
        jmax: [0.0; 3],
        end_err: 0.0,
        violations: pl.stats().limit_violations,
        geo: format!("{:?} {:?}", pl.geometry_stats(), pl.stats()),
        plan_s: plan.as_secs_f64(),
        segments: moves.len(),
        ns_per_period: interp.as_secs_f64() * 1e9 / moving_periods.max(1) as f64,
        calls,
    };
    // Time: periods until the set-point reaches the end and stays (within 1e-9 mm: a last
    // set-point off by a rounding error, 1e-16 mm, is there).
    let end = moves.last().map(|mv| match mv.kind {
        rtcnc_motion::MoveKind::Line { end, .. } => end,
        _ => start,
    });
    let end = end.unwrap_or(start);
    let away = |p: &[f64; AXES]| (0..AXES).any(|i| (p[i] - end[i]).abs() > 1e-9);
    let last_move = pts.iter().rposition(away).map_or(0, |i| i + 1);
    let first_move = pts.iter().position(|p| p != &start).unwrap_or(0);
    m.time = (last_move - first_move + 1) as f64 * t;
    m.end_err = (0..3)
        .map(|i| (pts[pts.len() - 1][i] - end[i]).abs())
        .fold(0.0, f64::max);
    for w in pts.windows(4) {
        for i in 0..3 {
            let v = (w[3][i] - w[2][i]) / t;
            let a = (w[3][i] - 2.0 * w[2][i] + w[1][i]) / (t * t);
            let j = (w[3][i] - 3.0 * w[2][i] + 3.0 * w[1][i] - w[0][i]) / (t * t * t);
            m.vmax[i] = m.vmax[i].max(v.abs());
            m.amax[i] = m.amax[i].max(a.abs());
            m.jmax[i] = m.jmax[i].max(j.abs());
        }
    }
    m
}

/// `--programs DIR`: every `*.ngc` of DIR (bench/motion_curves.py's curves), one line each:
/// name, time, the largest |v|, |a|, |j| of any axis over its limit, counted violations.
fn run_programs(dir: &std::path::Path) {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .expect("programs folder")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "ngc"))
        .collect();
    files.sort();
    println!("program time_s v_ratio a_ratio j_ratio violations");
    for file in files {
        let text = std::fs::read_to_string(&file).expect("program");
        let (start, moves) = read_bench_program(&text);
        let m = run(start, &moves, 1e-3);
        let ratio = |x: &[f64; 3]| x.iter().fold(0.0f64, |a, b| a.max(*b));
        println!(
            "{} {:.4} {:.6} {:.6} {:.6} {}",
            file.file_stem()
                .map_or(String::new(), |s| s.to_string_lossy().into_owned()),
            m.time,
            ratio(&m.vmax) / 100.0,
            ratio(&m.amax) / 1000.0,
            ratio(&m.jmax) / 50_000.0,
            m.violations
        );
        if std::env::var("RTCNC_DEBUG_GEO").is_ok() {
            eprintln!("  {}", m.geo);
        }
    }
}

fn main() {
    let mut args = std::env::args().skip(1);
    if let Some("--programs") = args.next().as_deref() {
        run_programs(&PathBuf::from(args.next().expect("--programs DIR")));
        return;
    }
    let dir = std::env::args()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            if let Ok(p) = std::env::var("RTCNC_PEERS") {
                return PathBuf::from(p).join("bench-paths");
            }
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/peers/bench-paths")
        });
    // Peer figures measured on this machine (docs/motion.md): toppra optimum, LinuxCNC 2.9.
    let refs = [
        ("circle", 0.727, 0.872),
        ("ellipse", 1.102, 1.216),
        ("helix", 1.989, 2.222),
        ("lemniscate", 1.190, 1.337),
    ];
    println!(
        "{:<11} {:>8} {:>7} {:>8} {:>7} {:>8} {:>18} {:>22} {:>29} {:>9} {:>5} {:>11} {:>10}",
        "path",
        "ours[s]",
        "toppra",
        "ours/tp",
        "lcnc",
        "ours/lc",
        "max|v| x,y,z",
        "max|a| x,y,z",
        "max|j| x,y,z",
        "end err",
        "viol",
        "plan[seg/s]",
        "ns/period"
    );
    let mut calls = 0;
    for (name, tp, lc) in refs {
        let file = dir.join(format!("{name}.ngc"));
        let Ok(text) = std::fs::read_to_string(&file) else {
            println!("{name}: {} not found, skipped", file.display());
            continue;
        };
        let (start, moves) = read_bench_program(&text);
        let m = run(start, &moves, 1e-3);
        calls += m.calls;
        println!(
            "{:<11} {:>8.3} {:>7.3} {:>8.3} {:>7.3} {:>8.3} {:>6.1},{:>5.1},{:>5.1} {:>7.0},{:>6.0},{:>6.0} {:>8.1},{:>8.1},{:>8.1} {:>9.1e} {:>5} {:>11.0} {:>10.0}",
            name,
            m.time,
            tp,
            m.time / tp,
            lc,
            m.time / lc,
            m.vmax[0],
            m.vmax[1],
            m.vmax[2],
            m.amax[0],
            m.amax[1],
            m.amax[2],
            m.jmax[0],
            m.jmax[1],
            m.jmax[2],
            m.end_err,
            m.violations,
            m.segments as f64 / m.plan_s.max(1e-12),
            m.ns_per_period
        );
        if std::env::var("RTCNC_DEBUG_GEO").is_ok() {
            println!("  {}", m.geo);
        }
    }
    if std::env::var("RTCNC_DEBUG_GEO").is_ok() {
        println!("(set RTCNC_DEBUG_GEO to print geometry counters)");
    }
    println!(
        "limits per axis: 100 mm/s, 1000 mm/s², 50000 mm/s³; servo period 1 ms; {calls} servo periods"
    );
}
