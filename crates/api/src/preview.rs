//! What the API computes from a program without the machine: the interpreter's errors (on
//! upload), the tool-path preview (canonical motion as polylines) and the cycle-time
//! estimate (the kernel on the same machine file in virtual time, as `rtcnc sim`).

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use rtcnc_gcode::canon::{CanonCommand, Plane, Units};
use rtcnc_gcode::compensation::Compensator;
use rtcnc_gcode::{Interpreter, Parameters, Settings, ToolTable};
use rtcnc_kernel::{Command, Kernel, KernelOptions, MachineConfig, MachineState, Simulation};

use crate::models::{Estimate, Polyline, Preview, ProgramError};

/// Most errors reported for one program.
const MAX_ERRORS: usize = 100;
/// Largest chord error when arcs become polylines, mm.
const CHORD_TOLERANCE: f64 = 0.01;
/// Most points in one preview.
const MAX_POINTS: usize = 2_000_000;

fn interpreter(config: &MachineConfig) -> Interpreter {
    let tools = config
        .files
        .tool_table
        .as_ref()
        .and_then(|p| ToolTable::load(&config.resolve(p)).ok());
    let params = config
        .files
        .parameters
        .as_ref()
        .and_then(|p| Parameters::load(&config.resolve(p)).ok())
        .unwrap_or_default();
    let settings = Settings {
        accept_unknown_tools: tools.is_none(),
        ..Settings::default()
    };
    Interpreter::new(settings, tools.unwrap_or_default(), params)
}

fn error_of(e: &rtcnc_gcode::GcodeError) -> ProgramError {
    ProgramError {
        line: e.line,
        column: e.column,
        code: e.code().to_string(),
        message: e.message.clone(),
    }
}

/// Every interpreter error of a program (up to 100), with line and column.
pub fn check(config: &MachineConfig, name: &str, text: &str) -> Vec<ProgramError> {
    let mut interp = interpreter(config);
    let mut errors = Vec::new();
    if let Err(e) = interp.open_text(name, text.as_bytes().to_vec()) {
        return vec![error_of(&e)];
    }
    let mut comp = Compensator::new();
    loop {
        match interp.next_canon() {
            Some(Ok(c)) => {
                if let Err(e) = comp.push(c) {
                    let name = interp.file_name(e.at.file);
                    errors.push(error_of(&e.into_gcode_error(name)));
                    break;
                }
                while comp.pop().is_some() {}
            }
            Some(Err(e)) => {
                errors.push(error_of(&e));
                if errors.len() >= MAX_ERRORS || !interp.resume_after_error() {
                    break;
                }
            }
            None => break,
        }
    }
    errors
}

struct PathBuilder {
    paths: Vec<Polyline>,
    at: [f64; 3],
    points: usize,
    min: [f64; 3],
    max: [f64; 3],
}

impl PathBuilder {
    fn to(&mut self, kind: &str, line: u32, p: [f64; 3]) {
        if self.points >= MAX_POINTS {
            return;
        }
        let extend = self.paths.last().is_some_and(|l| l.kind == kind);
        if !extend {
            for i in 0..3 {
                self.min[i] = self.min[i].min(self.at[i]);
                self.max[i] = self.max[i].max(self.at[i]);
            }
            self.paths.push(Polyline {
                kind: kind.into(),
                lines: Vec::new(),
                points: vec![self.at],
            });
            self.points += 1;
        }
        if let Some(l) = self.paths.last_mut() {
            l.points.push(p);
            l.lines.push(line);
        }
        for i in 0..3 {
            self.min[i] = self.min[i].min(p[i]);
            self.max[i] = self.max[i].max(p[i]);
        }
        self.points += 1;
        self.at = p;
    }
}

/// The canonical motion (after cutter compensation) as polylines, arcs within 0.01 mm.
pub fn preview(config: &MachineConfig, name: &str, text: &str) -> Preview {
    let mut interp = interpreter(config);
    let mut errors = Vec::new();
    let mut b = PathBuilder {
        paths: Vec::new(),
        at: [0.0; 3],
        points: 0,
        min: [f64::INFINITY; 3],
        max: [f64::NEG_INFINITY; 3],
    };
    if let Err(e) = interp.open_text(name, text.as_bytes().to_vec()) {
        errors.push(error_of(&e));
    }
    let mut comp = Compensator::new();
    let mut units = Units::Mm;
    let mut plane = Plane::XY;
    let mut done = !errors.is_empty();
    while !done {
        let next = interp.next_canon();
        match next {
            Some(Ok(c)) => {
                if let Err(e) = comp.push(c) {
                    let name = interp.file_name(e.at.file);
                    errors.push(error_of(&e.into_gcode_error(name)));
                    done = true;
                }
            }
            Some(Err(e)) => {
                errors.push(error_of(&e));
                done = true;
            }
            None => {
                comp.finish();
                done = true;
            }
        }
        while let Some(c) = comp.pop() {
            let line = c.source.line;
            match c.command {
                CanonCommand::UseLengthUnits(u) => units = u,
                CanonCommand::SelectPlane(p) => plane = p,
                cmd => match cmd.to_mm(units) {
                    CanonCommand::StraightTraverse(p) => b.to("rapid", line, [p.x, p.y, p.z]),
                    CanonCommand::StraightFeed(p) | CanonCommand::StraightProbe { end: p, .. } => {
                        b.to("feed", line, [p.x, p.y, p.z])
                    }
                    CanonCommand::ArcFeed(a) => arc(&mut b, line, &a, plane),
                    CanonCommand::SplineFeed(s) => {
                        // Control polygon points sampled along the Bézier curve.
                        let from = b.at;
                        let (p1, p2) = if s.order == 3 {
                            (s.p1, s.p1)
                        } else {
                            (s.p1, s.p2)
                        };
                        let n = 32;
                        for k in 1..=n {
                            let t = f64::from(k) / f64::from(n);
                            let u = 1.0 - t;
                            let bez = |a: f64, c1: f64, c2: f64, e: f64| {
                                if s.order == 3 {
                                    u * u * a + 2.0 * u * t * c1 + t * t * e
                                } else {
                                    u * u * u * a
                                        + 3.0 * u * u * t * c1
                                        + 3.0 * u * t * t * c2
                                        + t * t * t * e
                                }
                            };
                            let x = bez(from[0], p1[0], p2[0], s.end[0]);
                            let y = bez(from[1], p1[1], p2[1], s.end[1]);
                            b.to("feed", line, [x, y, from[2]]);
                        }
                    }
                    _ => {}
                },
            }
        }
    }
    if b.points == 0 {
        b.min = [0.0; 3];
        b.max = [0.0; 3];
    }
    Preview {
        paths: b.paths,
        min: b.min,
        max: b.max,
        errors,
    }
}

/// An arc (or helix) in the active plane, as chords within the tolerance.
fn arc(b: &mut PathBuilder, line: u32, a: &rtcnc_gcode::canon::Arc, plane: Plane) {
    let (f, s, n) = match plane {
        Plane::XY | Plane::UV => (0, 1, 2),
        Plane::XZ | Plane::WU => (2, 0, 1),
        Plane::YZ | Plane::VW => (1, 2, 0),
    };
    let from = b.at;
    let (cf, cs) = (a.first_axis, a.second_axis);
    let r0 = ((from[f] - cf).powi(2) + (from[s] - cs).powi(2)).sqrt();
    let r1 = ((a.first_end - cf).powi(2) + (a.second_end - cs).powi(2)).sqrt();
    let t0 = (from[s] - cs).atan2(from[f] - cf);
    let t1 = (a.second_end - cs).atan2(a.first_end - cf);
    let turns = f64::from(a.rotation.unsigned_abs().saturating_sub(1));
    let tau = std::f64::consts::TAU;
    let mut sweep = if a.rotation >= 0 {
        (t1 - t0).rem_euclid(tau)
    } else {
        -(t0 - t1).rem_euclid(tau)
    };
    if sweep == 0.0 {
        sweep = if a.rotation >= 0 { tau } else { -tau };
    }
    sweep += sweep.signum() * turns * tau;
    let r = r0.max(r1).max(1e-9);
    let step = 2.0 * (1.0 - CHORD_TOLERANCE / r).clamp(-1.0, 1.0).acos();
    let count = ((sweep.abs() / step.max(1e-3)).ceil() as usize).clamp(1, 100_000);
    for k in 1..=count {
        let t = k as f64 / count as f64;
        let angle = t0 + sweep * t;
        let radius = r0 + (r1 - r0) * t;
        let mut p = from;
        p[f] = cf + radius * angle.cos();
        p[s] = cs + radius * angle.sin();
        p[n] = from[n] + (a.axis_end_point - from[n]) * t;
        if k == count {
            p[f] = a.first_end;
            p[s] = a.second_end;
        }
        b.to("feed", line, p);
    }
}

/// The cycle time of the program at `program` on this machine, in virtual time: the kernel
/// as `rtcnc sim` runs it, with copies of the persistent files (the machine's own are not
/// written).
pub fn estimate(
    config: &MachineConfig,
    program: &Path,
    limit: Duration,
) -> anyhow::Result<Estimate> {
    let started = Instant::now();
    let scratch = std::env::temp_dir().join(format!(
        "rtcnc-estimate-{}-{}",
        std::process::id(),
        rtcnc_kernel::link::monotonic_ns()
    ));
    std::fs::create_dir_all(&scratch)?;
    let result = estimate_in(config, program, limit, &scratch);
    let _ = std::fs::remove_dir_all(&scratch);
    let (cycle_time_s, ended, faults) = result?;
    Ok(Estimate {
        cycle_time_s,
        ended,
        faults,
        computed_in_s: started.elapsed().as_secs_f64(),
    })
}

fn estimate_in(
    config: &MachineConfig,
    program: &Path,
    limit: Duration,
    scratch: &Path,
) -> anyhow::Result<(f64, bool, Vec<String>)> {
    // A machine on real EtherCAT devices is previewed on simulated drives, never with a
    // second master on its bus.
    let mut config = config.for_virtual_time();
    let copy = |p: &Option<PathBuf>, name: &str| -> Option<PathBuf> {
        let p = p.as_ref()?;
        let src = config.resolve(p);
        let dst = scratch.join(name);
        if src.exists() {
            let _ = std::fs::copy(&src, &dst);
        }
        Some(dst)
    };
    let parameters = copy(&config.files.parameters, "parameters.var");
    let retain = copy(&config.files.plc_retain, "retain.dat");
    config.files.parameters = parameters;
    config.files.plc_retain = retain;
    let kernel = Kernel::build(
        &config,
        KernelOptions {
            program: Some(program.to_path_buf()),
            ..KernelOptions::default()
        },
    )?;
    let mut sim = Simulation::new(kernel);
    let mut sink = |_: &rtcnc_kernel::Sample| {};
    sim.run_cycles(2, &mut sink)?;
    sim.handle().command(Command::Reset);
    if !sim.run_until(Duration::from_secs(1), &mut sink, |s| s.ready)? {
        anyhow::bail!("the simulated drives did not enable within 1 s");
    }
    sim.handle().command(Command::Start { from_line: 0 });
    sim.run_cycles(2, &mut sink)?;
    let start = sim.now();
    let mut faults = Vec::new();
    let ended = loop {
        let stop = sim.run_until(Duration::from_millis(100), &mut sink, |s| {
            (s.program_ended && s.state == MachineState::Idle)
                || matches!(s.state, MachineState::Fault | MachineState::EStop)
        })?;
        faults.extend(
            sim.handle()
                .take_faults()
                .into_iter()
                .filter(|f| f.code != rtcnc_kernel::FaultCode::CommandRefused)
                .map(|f| f.code.as_str().to_string()),
        );
        let status = sim.handle().status();
        if stop {
            break status.program_ended && status.state == MachineState::Idle;
        }
        if status.state == MachineState::Idle && !faults.is_empty() {
            break false;
        }
        if sim.now() - start > limit {
            break false;
        }
    };
    Ok(((sim.now() - start).as_secs_f64(), ended, faults))
}

/// Magic of the binary preview.
pub const BINARY_MAGIC: &[u8; 8] = b"RTCNCPV1";

/// The preview as one chain of points in a compact binary form (a million segments are
/// 17 MB here against about 60 MB of JSON, and a browser reads it without parsing), all
/// little-endian:
///
/// | bytes | what |
/// |---|---|
/// | 8 | `RTCNCPV1` |
/// | 4 | `n`, u32: points |
/// | 4 | `m`, u32: bytes of the error list |
/// | 24 | bounding box, f32: min X Y Z, max X Y Z (mm) |
/// | 12 n | points, f32 X Y Z (mm) |
/// | 4 n | u32: program line of the move that ends at each point (0 for the first) |
/// | n | u8: 0 the first point, 1 reached by a rapid, 2 by a feed |
/// | m | the errors, a JSON array of `ProgramError` |
pub fn encode_binary(p: &Preview) -> Vec<u8> {
    let mut points: Vec<[f64; 3]> = Vec::new();
    let mut lines: Vec<u32> = Vec::new();
    let mut kinds: Vec<u8> = Vec::new();
    for (k, poly) in p.paths.iter().enumerate() {
        let kind = if poly.kind == "rapid" { 1 } else { 2 };
        // Each polyline starts where the one before ended.
        if k == 0 {
            if let Some(first) = poly.points.first() {
                points.push(*first);
                lines.push(0);
                kinds.push(0);
            }
        }
        for (pt, line) in poly.points.iter().skip(1).zip(&poly.lines) {
            points.push(*pt);
            lines.push(*line);
            kinds.push(kind);
        }
    }
    let errors = serde_json::to_vec(&p.errors).unwrap_or_else(|_| b"[]".to_vec());
    let n = points.len();
    let mut out = Vec::with_capacity(40 + 17 * n + errors.len());
    out.extend_from_slice(BINARY_MAGIC);
    out.extend_from_slice(&(n as u32).to_le_bytes());
    out.extend_from_slice(&(errors.len() as u32).to_le_bytes());
    for v in p.min.iter().chain(&p.max) {
        out.extend_from_slice(&(*v as f32).to_le_bytes());
    }
    for pt in &points {
        for v in pt {
            out.extend_from_slice(&(*v as f32).to_le_bytes());
        }
    }
    for l in &lines {
        out.extend_from_slice(&l.to_le_bytes());
    }
    out.extend_from_slice(&kinds);
    out.extend_from_slice(&errors);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn f32_at(b: &[u8], at: usize) -> f32 {
        f32::from_le_bytes(b[at..at + 4].try_into().unwrap())
    }

    fn u32_at(b: &[u8], at: usize) -> u32 {
        u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
    }

    #[test]
    fn the_binary_preview_is_one_chain_with_the_kind_and_line_of_every_move() {
        // By hand: a rapid from the origin to (10, 10), then a feed to (20, 10) and (20, 0).
        let p = Preview {
            paths: vec![
                Polyline {
                    kind: "rapid".into(),
                    lines: vec![2],
                    points: vec![[0.0, 0.0, 0.0], [10.0, 10.0, 0.0]],
                },
                Polyline {
                    kind: "feed".into(),
                    lines: vec![3, 4],
                    points: vec![[10.0, 10.0, 0.0], [20.0, 10.0, 0.0], [20.0, 0.0, -1.5]],
                },
            ],
            min: [0.0, 0.0, -1.5],
            max: [20.0, 10.0, 0.0],
            errors: vec![],
        };
        let b = encode_binary(&p);
        assert_eq!(&b[..8], BINARY_MAGIC);
        let n = u32_at(&b, 8) as usize;
        assert_eq!(n, 4);
        assert_eq!(u32_at(&b, 12), 2);
        assert_eq!(f32_at(&b, 16 + 8), -1.5);
        assert_eq!(f32_at(&b, 16 + 12), 20.0);
        let pts = 40;
        assert_eq!(
            (0..12).map(|i| f32_at(&b, pts + 4 * i)).collect::<Vec<_>>(),
            vec![
                0.0, 0.0, 0.0, 10.0, 10.0, 0.0, 20.0, 10.0, 0.0, 20.0, 0.0, -1.5
            ]
        );
        let lines = pts + 12 * n;
        assert_eq!(
            (0..4)
                .map(|i| u32_at(&b, lines + 4 * i))
                .collect::<Vec<_>>(),
            vec![0, 2, 3, 4]
        );
        let kinds = lines + 4 * n;
        assert_eq!(&b[kinds..kinds + 4], &[0, 1, 2, 2]);
        assert_eq!(&b[kinds + 4..], b"[]");
        assert_eq!(b.len(), 40 + 17 * n + 2);
    }
}
