//! Every canned cycle (G73, G74, G81-G89) in G17, G18 and G19, absolute and incremental,
//! with L repeats, G98 and G99 and R planes above and below the start, through the whole
//! kernel on the benchmark machine (`configs/bench-xyz.toml`, no machine logic: the
//! spindle commands of the cycles pass at once): each program runs to its end (M0 pauses of
//! G88 resumed), with no fault, every axis within its velocity, acceleration and jerk limit
//! at every servo period. A program that ran every cycle in the three planes with L repeats used to
//! exceed the jerk limit 8 × where a stop landed: an isolated line's S-curve far from the
//! origin failed the set-point check (docs/motion.md, "Isolated lines anywhere on the
//! machine").

use crate::common;
use crate::common::*;
use rtcnc_kernel::{Command, MachineState, Sample, Urgent};

/// Linear congruential generator: the programs are the same on every run.
struct Lcg(u64);

impl Lcg {
    fn f(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        ((lo + (hi - lo) * self.f()) * 1000.0).round() / 1000.0
    }
}

/// Per plane (on the benchmark machine's ±1000 mm, far from the origin as on a large
/// table): the letter of the axis the holes step along with where the row starts, the
/// other axis of the plane with its range, and the drilling axis with the range of its
/// start level.
struct Plane {
    code: &'static str,
    row: (char, f64),
    other: (char, f64, f64),
    c: (char, f64, f64),
}

const PLANES: [Plane; 3] = [
    Plane {
        code: "G17",
        row: ('X', 600.0),
        other: ('Y', -900.0, 900.0),
        c: ('Z', -10.0, 3.0),
    },
    Plane {
        code: "G18",
        row: ('X', -700.0),
        other: ('Z', -500.0, 500.0),
        c: ('Y', 400.0, 900.0),
    },
    Plane {
        code: "G19",
        row: ('Y', 300.0),
        other: ('Z', -800.0, -30.0),
        c: ('X', -900.0, 900.0),
    },
];

const CYCLES: [&str; 11] = [
    "G81", "G82", "G73", "G83", "G84", "G74", "G85", "G86", "G87", "G88", "G89",
];

/// One program: every cycle in `plane`, absolute or incremental, G98 or G99, each with L
/// repeats (2-4 holes 1.5-4 mm apart along the row), the R plane from 2 mm below to 2 mm
/// above the start level, 1-8 mm deep.
fn program(rng: &mut Lcg, plane: &Plane, incremental: bool, retract: &str) -> String {
    let (lr, lo, lc) = (plane.row.0, plane.other.0, plane.c.0);
    let mut text = format!(
        "G21 G90 G94 G64 P0.01 {} {retract} F600 S1000 M3\n",
        plane.code
    );
    let start_c = rng.range(plane.c.1, plane.c.2);
    let mut at: f64 = plane.row.1;
    let other = rng.range(plane.other.1, plane.other.2);
    text += &format!("G0 {lr}{at} {lo}{other} {lc}{start_c}\n");
    for cycle in CYCLES {
        text += if cycle == "G74" { "M4\n" } else { "M3\n" };
        // R from 2 mm below to 2 mm above the start level (above: the cycle first rises to it).
        let r_above = rng.range(-2.0, 2.0);
        let r = start_c - r_above;
        let depth = rng.range(1.0, 8.0);
        let bottom = r - depth;
        // G74 takes no L (LinuxCNC refuses it).
        let repeats = if cycle == "G74" {
            1
        } else {
            2 + (rng.f() * 3.0) as u32
        };
        let l = if cycle == "G74" {
            String::new()
        } else {
            format!(" L{repeats}")
        };
        let step = rng.range(1.5, 4.0);
        let mut words = match cycle {
            "G82" | "G86" | "G88" | "G89" => format!(" P{}", rng.range(0.0, 0.3)),
            "G73" | "G83" => format!(" Q{}", rng.range(0.5, 3.0)),
            _ => String::new(),
        };
        if cycle == "G87" {
            // Back boring: the tool's clearance offset (I J, in the plane's order) and the
            // level K, between the bottom and R, where the boring ends.
            let k = if incremental {
                0.5 * depth
            } else {
                bottom + 0.5 * depth
            };
            // The offsets on the plane's axes, the level on the axis normal to it
            // (LinuxCNC: I J / K in G17, K I / J in G18, J K / I in G19).
            words += &match plane.code {
                "G17" => format!(" I0.5 J0.5 K{k}"),
                "G18" => format!(" K0.5 I0.5 J{k}"),
                _ => format!(" J0.5 K0.5 I{k}"),
            };
        }
        if incremental {
            // R from the start level, the depth from R, each hole one step further.
            text += &format!(
                "G91 {cycle} {lr}{step} {lo}0 R{} {lc}{}{l}{words}\nG90 G80\n",
                -r_above, -depth
            );
            at = ((at + step * f64::from(repeats)) * 1000.0).round() / 1000.0;
        } else {
            at = ((at + step) * 1000.0).round() / 1000.0;
            text += &format!("{cycle} {lr}{at} {lo}{other} R{r} {lc}{bottom}{l}{words}\nG80\n");
        }
        if cycle == "G88" {
            // G88 ends at the bottom with the spindle stopped, for a manual retraction.
            text += &format!("G0 {lc}{start_c}\n");
        }
        at = ((at + step) * 1000.0).round() / 1000.0;
        text += &format!("G0 {lr}{at}\n");
    }
    text + "M5\nM2\n"
}

fn worst_ratio(samples: &[Sample], limits: &[(f64, f64, f64)]) -> (f64, usize) {
    let t = 1e-3;
    let mut worst = (0.0f64, 0);
    for (k, w) in samples.windows(4).enumerate() {
        for (i, &(v, a, j)) in limits.iter().enumerate() {
            let x: Vec<f64> = w.iter().map(|s| s.axes[i]).collect();
            let r = ((x[3] - x[2]) / t / v)
                .abs()
                .max(((x[3] - 2.0 * x[2] + x[1]) / (t * t) / a).abs())
                .max(((x[3] - 3.0 * x[2] + 3.0 * x[1] - x[0]) / (t * t * t) / j).abs());
            if r > worst.0 {
                worst = (r, k + 3);
            }
        }
    }
    worst
}

#[test]
fn every_canned_cycle_in_every_plane_keeps_the_limits() {
    let cfg = config("bench-xyz.toml");
    let limits = [(100.0, 1000.0, 50_000.0); 3];
    let mut rng = Lcg(12);
    for plane in &PLANES {
        for incremental in [false, true] {
            for retract in ["G98", "G99"] {
                let text = program(&mut rng, plane, incremental, retract);
                let name = format!("{}-{incremental}-{retract}.ngc", plane.code);
                let mut m = Machine::new(&cfg, Some(program_file(&text, &name)));
                m.power_on();
                m.command(Command::Start { from_line: 0 });
                // Resume at every M0 (G88), until the program ends.
                let mut ended = false;
                for _ in 0..64 {
                    ended = m.until(120.0, |s| {
                        (s.program_ended && s.state == MachineState::Idle)
                            || s.state == MachineState::Paused
                    }) && m.status().program_ended;
                    if ended || m.status().state != MachineState::Paused {
                        break;
                    }
                    assert!(m.sim.handle().urgent(Urgent::Resume));
                }
                assert!(m.faults.is_empty(), "{name}: {:?}\n{text}", m.faults);
                assert!(ended, "{name} did not end\n{text}");
                let (worst, at) = worst_ratio(&m.samples, &limits);
                assert!(
                    worst <= 1.0 + 1e-9,
                    "{name}: {worst} × a limit at sample {at} (line {})\n{text}",
                    m.samples[at].line
                );
            }
        }
    }
}

fn program_file(text: &str, name: &str) -> std::path::PathBuf {
    common::program(text, name)
}
