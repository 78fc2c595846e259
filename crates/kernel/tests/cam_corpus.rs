//! Every program of the CAM corpus (`examples/cam-corpus`: FreeCAD Path, dxf2gcode and
//! bCNC output, see its README) runs to its end on the benchmark machine
//! (`configs/bench-xyz.toml` with the corpus's tool table), in virtual time, without a
//! fault, and no axis ever exceeds its velocity, acceleration or jerk limit. The reference
//! is the machine file's limits and LinuxCNC 2.9, which runs every one of these programs to
//! its end (`examples/cam-corpus/linuxcnc-times.tsv`).
//!
//! A program that cannot end is given up early instead of running to the time limit: paused
//! (nothing resumes it), idle without having ended (a program error), or standing still
//! while running for longer than any dwell of the corpus.

use crate::common::*;

use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

use rtcnc_kernel::report::RunStats;
use rtcnc_kernel::{Command, FaultCode, MachineConfig, MachineState};

/// Machine time a corpus program may take (LinuxCNC's longest is under 4 minutes).
const TIME_LIMIT_S: f64 = 1200.0;
/// Standing still this long while running is a stall (the corpus dwells at most 2 s).
const STALL_S: f64 = 30.0;

fn corpus_dir() -> PathBuf {
    repo().join("examples/cam-corpus")
}

fn corpus_programs() -> Vec<PathBuf> {
    let mut programs: Vec<PathBuf> = std::fs::read_dir(corpus_dir())
        .expect("examples/cam-corpus")
        .map(|e| e.expect("directory entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "ngc"))
        .collect();
    programs.sort();
    programs
}

fn machine() -> MachineConfig {
    let mut cfg = config("bench-xyz.toml");
    cfg.files.tool_table = Some(corpus_dir().join("tools.tbl"));
    cfg
}

/// What happened to one program.
struct Outcome {
    name: String,
    ended: bool,
    /// Why it did not end, or the faults it raised.
    trouble: Vec<String>,
    /// Largest |v|, |a|, |j| over all axes as a share of the axis' limit.
    ratios: [f64; 3],
    cycle_time_s: f64,
}

impl Outcome {
    fn passed(&self) -> bool {
        self.ended && self.trouble.is_empty() && self.ratios.iter().all(|&r| r <= 1.0 + 1e-6)
    }

    fn line(&self) -> String {
        format!(
            "{:<28} {:<5} t {:8.2} s  v {:.3} a {:.3} j {:.3}  {}",
            self.name,
            if self.passed() { "ok" } else { "FAIL" },
            self.cycle_time_s,
            self.ratios[0],
            self.ratios[1],
            self.ratios[2],
            self.trouble.join("; ")
        )
    }
}

fn run(cfg: &MachineConfig, program: &Path) -> Outcome {
    let name = program
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mut m = Machine::new(cfg, Some(program.to_path_buf()));
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    let period_s = cfg.servo_period().as_secs_f64();
    let mut stats = RunStats::new();
    let start = m.sim.now();
    let mut trouble = Vec::new();
    let mut faults = std::mem::take(&mut m.faults);
    let mut last_axes = m.status().axes;
    let mut still_since = m.sim.now();
    // The status names no line once the program has stopped: keep the last one moved on.
    let mut line = 0u32;
    let ended;
    loop {
        let finished = m
            .sim
            .run_until(
                Duration::from_secs(1),
                &mut |s| {
                    stats.add(s, period_s);
                    if s.line != 0 {
                        line = s.line;
                    }
                },
                |s| {
                    (s.program_ended && s.state == MachineState::Idle)
                        || matches!(
                            s.state,
                            MachineState::Fault | MachineState::EStop | MachineState::Paused
                        )
                },
            )
            .expect("runs");
        faults.extend(m.sim.handle().take_faults());
        let s = m.status();
        let now = m.sim.now();
        let t = (now - start).as_secs_f64();
        if finished {
            ended = s.program_ended && s.state == MachineState::Idle;
            if !ended {
                trouble.push(format!(
                    "{} at line {line} after {t:.1} s",
                    s.state.as_str()
                ));
            }
            break;
        }
        if s.state == MachineState::Idle {
            trouble.push(format!(
                "idle without reaching the end, at line {line} after {t:.1} s"
            ));
            ended = false;
            break;
        }
        if s.axes != last_axes {
            last_axes = s.axes;
            still_since = now;
        } else if (now - still_since).as_secs_f64() > STALL_S {
            trouble.push(format!(
                "{} at line {line}, standing still since {:.1} s (speed {}), given up at {t:.1} s",
                s.state.as_str(),
                (still_since - start).as_secs_f64(),
                s.path_speed
            ));
            ended = false;
            break;
        }
        if t > TIME_LIMIT_S {
            trouble.push(format!(
                "still {} at line {line} after {t:.1} s",
                s.state.as_str()
            ));
            ended = false;
            break;
        }
    }
    let cycle_time_s = (m.sim.now() - start).as_secs_f64();
    for f in faults
        .iter()
        .filter(|f| f.code != FaultCode::CommandRefused)
    {
        trouble.push(m.sim.handle().describe(f));
    }
    if let Some(e) = m.sim.handle().error_text() {
        trouble.push(e);
    }
    let mut ratios = [0.0f64; 3];
    for p in cfg.axis_plan() {
        let a = cfg.axis(p.axis).expect("planned axis is configured");
        let i = p.axis as usize;
        ratios[0] = ratios[0].max(stats.max_velocity[i] / a.max_velocity);
        ratios[1] = ratios[1].max(stats.max_acceleration[i] / a.max_acceleration);
        ratios[2] = ratios[2].max(stats.max_jerk[i] / a.max_jerk);
    }
    Outcome {
        name,
        ended,
        trouble,
        ratios,
        cycle_time_s,
    }
}

#[test]
fn every_cam_corpus_program_runs_to_its_end_within_the_limits() {
    let programs = corpus_programs();
    assert!(
        programs.len() >= 40,
        "the corpus holds {} programs",
        programs.len()
    );
    let cfg = machine();
    let next = AtomicUsize::new(0);
    let outcomes = Mutex::new(Vec::new());
    let workers = std::thread::available_parallelism().map_or(2, |n| n.get().min(4));
    std::thread::scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    let Some(program) = programs.get(i) else {
                        break;
                    };
                    let outcome = run(&cfg, program);
                    eprintln!("{}", outcome.line());
                    outcomes.lock().expect("no worker panicked").push(outcome);
                }
            });
        }
    });
    let mut outcomes = outcomes.into_inner().expect("no worker panicked");
    outcomes.sort_by(|a, b| a.name.cmp(&b.name));
    let failed: Vec<String> = outcomes
        .iter()
        .filter(|o| !o.passed())
        .map(Outcome::line)
        .collect();
    assert!(
        failed.is_empty(),
        "{} of {} corpus programs did not run to their end within the limits:\n{}",
        failed.len(),
        outcomes.len(),
        failed.join("\n")
    );
}

/// A machine builder who has no jerk figure gives a huge one (LinuxCNC has none): 10^7 and
/// 10^8 mm/s³ against 1 000 mm/s², a jerk phase of 0.1 and 0.01 ms at a 1 ms servo period.
/// Before the planner planned no jerk phase shorter than two periods, the engraving
/// exceeded Y's acceleration 9.6 × at 10^7 and stood still at line 116 at 10^8, and the
/// adaptive clearing stood still; both run to their end within the limits now.
#[test]
fn programs_run_within_the_limits_with_a_jerk_limit_far_above_the_period() {
    for jerk in [1e7, 1e8] {
        let mut cfg = machine();
        for axis in cfg.axes.values_mut() {
            axis.max_jerk = jerk;
            axis.quick_stop_jerk = axis.quick_stop_jerk.map(|q| q.max(jerk));
        }
        for name in ["engrave-text", "adaptive-pocket-3mm"] {
            let outcome = run(&cfg, &corpus_dir().join(format!("{name}.ngc")));
            assert!(outcome.passed(), "jerk {jerk}: {}", outcome.line());
        }
    }
}
