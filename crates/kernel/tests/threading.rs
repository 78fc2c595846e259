//! G33 and G76 through the whole kernel on the simulated lathe: a threading pass waits for
//! the spindle's index, then its progress follows pitch × spindle revolutions, so every
//! pass cuts the same helix.

use crate::common::*;
use rtcnc_kernel::{Command, FaultCode, MachineState};

/// Runs `text` on the lathe and records, per exchange, (Z set-point applied, spindle angle,
/// program line).
fn run(text: &str, name: &str) -> (Machine, Vec<(f64, f64, u32)>) {
    let cfg = config("sim-lathe.toml");
    let mut m = Machine::new(&cfg, Some(program(text, name)));
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    let mut trace = Vec::new();
    for _ in 0..60_000 {
        m.cycles(1);
        let s = *m.samples.last().unwrap();
        let angle = m.handle_machine(|mach| mach.spindle_angle_deg());
        trace.push((s.axes[2], angle, s.line));
        let st = m.status();
        if trace.len() > 10 && st.state == MachineState::Idle {
            break;
        }
    }
    (m, trace)
}

/// The thread's phase at a sample: revolutions the spindle is ahead of the tool's Z
/// (`z0 - z` = pitch × revolutions since the index for a synchronised pass), as a fraction
/// of a turn, in (-0.5, 0.5].
fn phase(z0: f64, pitch: f64, z: f64, angle: f64) -> f64 {
    let p = (z0 - z) / pitch - angle / 360.0;
    p - p.round()
}

#[test]
fn g33_passes_follow_the_spindle_and_cut_the_same_helix() {
    // 600 rpm, 1.5 mm per revolution: 15 mm/s along -Z. Two passes from Z5 to Z-20.
    let text = "G18 G21 G90 G7
G0 X20 Z5
S600 M3
G33 Z-20 K1.5
G0 X30
G0 Z5
G0 X20
G33 Z-20 K1.5
G0 X30
M5
M2
";
    let (m, trace) = run(text, "g33.ngc");
    assert!(
        m.faults.is_empty(),
        "{:?} {:?}",
        m.faults,
        m.sim.handle().error_text()
    );
    assert!(m.status().program_ended);
    for pass_line in [4, 8] {
        // Between Z0 and Z-15 the pass has caught up with the spindle: its phase is the
        // index's (0) within a micrometre of Z (1 µm / 1.5 mm of a turn).
        let steady: Vec<_> = trace
            .iter()
            .filter(|t| t.2 == pass_line && t.0 < 0.0 && t.0 > -15.0)
            .collect();
        assert!(steady.len() > 900, "{}", steady.len());
        for t in steady {
            let p = phase(5.0, 1.5, t.0, t.1);
            assert!(
                p.abs() < 1e-3 / 1.5,
                "line {pass_line} Z {} angle {}: {p}",
                t.0,
                t.1
            );
        }
        // It ends on the programmed end.
        let last = trace.iter().rfind(|t| t.2 == pass_line).unwrap();
        assert_eq!(last.0, -20.0);
    }
    // Catching up and stopping keep Z's limits.
    let cfg = config("sim-lathe.toml");
    let mut stats = rtcnc_kernel::report::RunStats::new();
    for s in &m.samples {
        stats.add(s, 0.001);
    }
    let z = cfg.axis(rtcnc_motion::Axis::Z).unwrap();
    assert!(stats.max_velocity[2] <= z.max_velocity * (1.0 + 1e-6));
    assert!(
        stats.max_acceleration[2] <= z.max_acceleration * (1.0 + 1e-6),
        "{}",
        stats.max_acceleration[2]
    );
    assert!(
        stats.max_jerk[2] <= z.max_jerk * (1.0 + 1e-6),
        "{}",
        stats.max_jerk[2]
    );
}

#[test]
fn a_feed_hold_in_a_thread_pass_takes_effect_at_its_end() {
    let text = "G18 G21 G90 G7\nG0 X20 Z5\nS600 M3\nG33 Z-20 K1.5\nG0 X30\nM2\n";
    let cfg = config("sim-lathe.toml");
    let mut m = Machine::started(&cfg, text, "g33-hold.ngc");
    assert!(m.until(10.0, |s| s.axes[2] < 0.0));
    assert!(m.sim.handle().urgent(rtcnc_kernel::Urgent::FeedHold));
    // The pass goes on to its end, then the program waits (X stays at the thread).
    assert!(m.until(5.0, |s| s.axes[2] == -20.0 && s.path_speed == 0.0));
    m.cycles(500);
    assert_eq!(m.status().state, MachineState::Held);
    assert_eq!(m.status().axes[0], 10.0);
    assert!(m.sim.handle().urgent(rtcnc_kernel::Urgent::Resume));
    assert!(m.until(5.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert_eq!(m.status().axes[0], 15.0);
}

#[test]
fn a_g76_cycle_runs_its_passes_on_the_same_helix() {
    // G76 on a 20 mm diameter: pitch 1.5, the drive line at X22 (diameter), thread peak
    // 1 mm (radius) below it, first cut 0.3, full depth 0.9, straight infeed (Q0), from Z5
    // to Z-20: every pass starts at Z5 and waits for the index, so all cut one helix.
    let text = "G18 G21 G90 G7
G0 X22 Z5
S600 M3
G76 P1.5 Z-20 I-1 J0.3 K0.9 Q0 H1
G0 X30
M5
M2
";
    let (m, trace) = run(text, "g76.ngc");
    assert!(
        m.faults.is_empty(),
        "{:?} {:?}",
        m.faults,
        m.sim.handle().error_text()
    );
    assert!(m.status().program_ended);
    // The cutting samples: line 4, moving towards -Z, between Z0 and Z-15 (each pass has
    // caught up with the spindle by Z0, see the G33 test).
    let cutting: Vec<_> = trace
        .windows(2)
        .filter(|w| w[1].2 == 4 && w[1].0 < w[0].0 && w[1].0 < 0.0 && w[1].0 > -15.0)
        .map(|w| w[1])
        .collect();
    // Pass n cuts to J·n^(1/R) (R1, the default): 0.3, 0.6, 0.9 = K, then H1 spring pass.
    let passes = 1 + cutting.windows(2).filter(|w| w[1].0 > w[0].0).count();
    assert_eq!(passes, 4);
    assert!(cutting.len() > 900 * passes, "{}", cutting.len());
    for t in &cutting {
        let p = phase(5.0, 1.5, t.0, t.1);
        assert!(p.abs() < 1e-3 / 1.5, "Z {} angle {}: {p}", t.0, t.1);
    }
}

#[test]
fn a_spindle_too_fast_for_the_pitch_stops_the_program_before_the_pass() {
    // 3000 rpm at 5 mm per revolution is 250 mm/s along Z, over the lathe's 120 mm/s.
    let text = "G18 G21 G90 G7\nG0 X20 Z5\nS3000 M3\nG33 Z-20 K5\nM2\n";
    let cfg = config("sim-lathe.toml");
    let mut m = Machine::started(&cfg, text, "g33-fast.ngc");
    m.cycles(2);
    assert!(m.until(10.0, |s| s.state == MachineState::Idle));
    let f = m.faults.iter().find(|f| f.code == FaultCode::SyncFailed);
    assert!(f.is_some_and(|f| f.line == 4), "{:?}", m.faults);
    assert!(m.samples.iter().all(|s| s.axes[2] == 5.0 || s.line < 4));
}

/// Runs `text` on the lathe and records, per exchange, (X set-point (radius), Z set-point,
/// unwrapped spindle angle in degrees, program line).
fn run_xz(text: &str, name: &str) -> (Machine, Vec<(f64, f64, f64, u32)>) {
    let cfg = config("sim-lathe.toml");
    let mut m = Machine::new(&cfg, Some(program(text, name)));
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    let mut trace: Vec<(f64, f64, f64, u32)> = Vec::new();
    let mut before: Option<f64> = None;
    let mut angle = 0.0;
    for _ in 0..120_000 {
        m.cycles(1);
        let s = *m.samples.last().unwrap();
        let reading = m.handle_machine(|mach| mach.spindle_angle_deg());
        // Unwrapped: the spindle turns far less than half a turn per period.
        let mut d = before.map_or(reading, |b| reading - b);
        if d > 180.0 {
            d -= 360.0;
        } else if d <= -180.0 {
            d += 360.0;
        }
        angle += d;
        before = Some(reading);
        trace.push((s.axes[0], s.axes[2], angle, s.line));
        if trace.len() > 10 && m.status().state == MachineState::Idle {
            break;
        }
    }
    assert!(
        m.faults.is_empty(),
        "{:?} {:?}",
        m.faults,
        m.sim.handle().error_text()
    );
    assert!(m.status().program_ended);
    (m, trace)
}

/// The spindle-synchronised part of a run kept every axis within its limits.
fn within_limits(m: &Machine, synced_lines: &[u32]) {
    let cfg = config("sim-lathe.toml");
    // Over each stretch of those lines, from the sample before it.
    let mut stats = rtcnc_kernel::report::RunStats::new();
    let mut worst = rtcnc_kernel::report::RunStats::new();
    let mut inside = false;
    for w in m.samples.windows(2) {
        if synced_lines.contains(&w[1].line) {
            if !inside {
                stats = rtcnc_kernel::report::RunStats::new();
                stats.add(&w[0], 0.001);
                inside = true;
            }
            stats.add(&w[1], 0.001);
            for i in 0..3 {
                worst.max_velocity[i] = worst.max_velocity[i].max(stats.max_velocity[i]);
                worst.max_acceleration[i] =
                    worst.max_acceleration[i].max(stats.max_acceleration[i]);
                worst.max_jerk[i] = worst.max_jerk[i].max(stats.max_jerk[i]);
            }
        } else {
            inside = false;
        }
    }
    let stats = worst;
    for axis in [rtcnc_motion::Axis::X, rtcnc_motion::Axis::Z] {
        let l = cfg.axis(axis).unwrap();
        let i = axis as usize;
        assert!(stats.max_velocity[i] <= l.max_velocity * (1.0 + 1e-6));
        assert!(
            stats.max_acceleration[i] <= l.max_acceleration * (1.0 + 1e-6),
            "{axis:?} {}",
            stats.max_acceleration[i]
        );
        assert!(
            stats.max_jerk[i] <= l.max_jerk * (1.0 + 1e-6),
            "{axis:?} {}",
            stats.max_jerk[i]
        );
    }
}

/// The largest spread of `values` taken as fractions of a turn (mod 1).
fn spread_of_turns(values: &[f64]) -> f64 {
    let first = values[0];
    values
        .iter()
        .map(|v| {
            let d = v - first;
            (d - d.round()).abs()
        })
        .fold(0.0, f64::max)
}

#[test]
fn chained_g33_moves_stay_on_one_helix_through_the_corner() {
    // Two passes of a chain: along Z from Z5 to Z-10, then a 1:2 taper out to X26 (radius
    // 13) at Z-16, both 1.5 mm per revolution along their lines, no stop between them.
    // By hand, the revolutions the tool is into the chain at (x, z): on the first line
    // (5 - z) / 1.5, on the second 10 + |(x, z) - (10, -10)| / 1.5. Less the spindle's
    // revolutions, that is the same number all along a pass (one helix), and the same
    // fraction of a turn for both passes.
    let text = "G18 G21 G90 G7
G0 X20 Z5
S600 M3
G33 Z-10 K1.5
G33 X26 Z-16 K1.5
G0 X30
G0 Z5
G0 X20
G33 Z-10 K1.5
G33 X26 Z-16 K1.5
G0 X30
M5
M2
";
    let (m, trace) = run_xz(text, "g33-chain.ngc");
    let taper_length = (3.0f64 * 3.0 + 6.0 * 6.0).sqrt();
    let mut passes = Vec::new();
    for (first, second) in [(4, 5), (9, 10)] {
        let mut lag = Vec::new();
        for &(x, z, angle, line) in &trace {
            let revolutions = if line == first && z < 3.5 && z > -9.0 {
                // On the first line: X stays at the radius 10.
                assert!((x - 10.0).abs() < 1e-9, "{x}");
                (5.0 - z) / 1.5
            } else if line == second {
                let along = (x - 10.0).hypot(z + 10.0);
                // Past the corner's blend, before the stop at the end.
                if along < 1.0 || along > taper_length - 1.0 {
                    continue;
                }
                // On the taper line through (10, -10) and (13, -16).
                let off = ((x - 10.0) * 6.0 + (z + 10.0) * 3.0) / taper_length;
                assert!(off.abs() < 1e-6, "off the taper by {off} at X {x} Z {z}");
                10.0 + along / 1.5
            } else {
                continue;
            };
            lag.push(revolutions - angle / 360.0);
        }
        // 12.5 mm of the first line and 4.7 mm of the second at 15 mm/s.
        assert!(lag.len() > 1100, "{}", lag.len());
        let spread = lag.iter().fold(f64::MIN, |a, &b| a.max(b))
            - lag.iter().fold(f64::MAX, |a, &b| a.min(b));
        eprintln!(
            "pass on lines {first}-{second}: lag spread {:e} mm",
            spread * 1.5
        );
        assert!(spread * 1.5 < 1e-3, "{spread} turns");
        passes.push(lag[0]);
    }
    let between = spread_of_turns(&passes) * 1.5;
    eprintln!("between the passes: {between:e} mm");
    assert!(between < 1e-3, "{between}");
    within_limits(&m, &[4, 5, 9, 10]);
}

#[test]
fn a_g76_with_tapers_cuts_its_tapers_on_the_helix() {
    // G76 P1.5 Z-20 I-1 J0.3 K0.9 Q0 H1 E1 L3 from X22 Z5 (diameters), by hand from
    // LinuxCNC's G76 description: drive line at radius 11, thread peak I/2 = 0.5 below it,
    // full thread K/2 = 0.45 deep, passes at the depths 0.65, 0.8, 0.95, and the spring
    // pass at 0.95 (H1). Each pass with depth d: from radius 11 - d + 0.95 at Z5 a
    // synchronised infeed to 11 - d + 0.45, the entry taper to 11 - d at Z4 (E1), the thread
    // to Z-19, the exit taper to 11 - d + 0.45 at Z-20. On the tapers the Z advance is the
    // thread's 1.5 mm per revolution (their drive-line pitch is 1.5·√(1 + 0.45²)).
    let text = "G18 G21 G90 G7
G0 X22 Z5
S600 M3
G76 P1.5 Z-20 I-1 J0.3 K0.9 Q0 H1 E1 L3
G0 X30
M5
M2
";
    let (m, trace) = run_xz(text, "g76-taper.ngc");
    // The passes: line 4 along -Z, each from Z5.
    let mut passes: Vec<Vec<(f64, f64, f64, u32)>> = Vec::new();
    for w in trace.windows(2) {
        if w[1].3 != 4 || w[1].1 >= w[0].1 {
            continue;
        }
        if w[0].3 != 4 || passes.is_empty() || w[0].1 > passes.last().unwrap().last().unwrap().1 {
            passes.push(Vec::new());
        }
        passes.last_mut().unwrap().push(w[1]);
    }
    assert_eq!(passes.len(), 4);
    let mut depths_seen = Vec::new();
    let mut lags = Vec::new();
    for (cut, depth) in passes.iter().zip([0.65, 0.8, 0.95, 0.95]) {
        let bottom = 11.0 - depth;
        // The pass starts at rest at radius 11 - d + 0.95 at Z5 (its synchronised infeed
        // to 11 - d + 0.45 there is blended into the taper all along: 0.304 turns long,
        // its corner's blend takes 0.3).
        let back = bottom + 0.95;
        assert!(
            trace
                .iter()
                .any(|t| t.3 == 4 && (t.0 - back).abs() < 1e-9 && t.1 == 5.0)
        );
        // The samples of the passes at this depth: Z from 5 to -20 on the way down.
        // Off the corners' blends, worked out as the kernel sizes them (half the limits
        // at 10 rev/s; docs/kernel.md): the infeed-to-taper corner's velocity per
        // revolution changes by (0.97, -1.5) mm (X, Z), its blend takes ±0.3 turns (Z's
        // jerk: √(1.5·1.5·10³ / 25 000)), to Z4.55; the taper-to-thread corners by 0.675
        // in X, ±0.225 turns (X's jerk: √(1.5·0.675·10³ / 20 000)), 0.3375 mm of Z either
        // side; the stop at the end starts about 0.46 mm of Z before Z-20.
        let on = |x: f64, z: f64| {
            if z < 4.53 && z > 4.36 {
                Some((x - (bottom + 0.45 * (z - 4.0)), 5.0 - z))
            } else if z < 3.6 && z > -18.6 {
                Some((x - bottom, 5.0 - z))
            } else if z < -19.36 && z > -19.5 {
                Some((x - (bottom + 0.45 * (-19.0 - z)), 5.0 - z))
            } else {
                None
            }
        };
        let mut n = 0;
        let mut lag = Vec::new();
        for &(x, z, angle, _) in cut {
            let Some((off, travelled)) = on(x, z) else {
                continue;
            };
            assert!(off.abs() < 1e-6, "depth {depth}: {off} off at X {x} Z {z}");
            n += 1;
            // Z advances 1.5 per revolution along the tapers and the thread alike.
            lag.push(travelled / 1.5 - angle / 360.0);
        }
        assert!(n > 1000, "{n}");
        depths_seen.push(depth);
        lags.extend(lag);
    }
    assert_eq!(depths_seen.len(), 4);
    // Every pass (each waits for the index and locks on at the same speed) on one helix.
    let spread = spread_of_turns(&lags) * 1.5;
    eprintln!("G76 with tapers: helix spread {spread:e} mm");
    assert!(spread < 1e-3, "{spread}");
    within_limits(&m, &[4]);
}

#[test]
fn a_corner_too_sharp_to_blend_in_its_lines_stops_the_program_before_the_chain() {
    // From the thread along Z straight out along X in 0.2 mm: at 10 rev/s X must reach
    // 15 mm/s within a blend of at most half of 0.2 / 1.5 turns, far above X's limits.
    let text = "G18 G21 G90 G7\nG0 X20 Z5\nS600 M3\nG33 Z-10 K1.5\nG33 X20.4 K1.5\nM2\n";
    let cfg = config("sim-lathe.toml");
    let mut m = Machine::started(&cfg, text, "g33-sharp.ngc");
    m.cycles(2);
    assert!(m.until(10.0, |s| s.state == MachineState::Idle));
    let f = m.faults.iter().find(|f| f.code == FaultCode::SyncFailed);
    assert!(f.is_some_and(|f| f.line == 5), "{:?}", m.faults);
    assert!(m.samples.iter().all(|s| s.axes[2] == 5.0 || s.line < 4));
}

#[test]
fn a_chain_longer_than_the_kernel_takes_is_refused_before_its_first_move() {
    // 17 G33 blocks one after the other (the kernel takes 16).
    let mut text = String::from("G18 G21 G90 G7\nG0 X20 Z5\nS600 M3\n");
    for k in 1..=17 {
        text.push_str(&format!("G33 Z{} K1.5\n", 5.0 - f64::from(k)));
    }
    text.push_str("M2\n");
    let cfg = config("sim-lathe.toml");
    let mut m = Machine::started(&cfg, &text, "g33-long-chain.ngc");
    m.cycles(2);
    assert!(m.until(10.0, |s| s.state == MachineState::Idle));
    let f = m.faults.iter().find(|f| f.code == FaultCode::ProgramError);
    assert!(f.is_some_and(|f| f.line == 4), "{:?}", m.faults);
    let words = m.sim.handle().error_text().unwrap();
    assert!(
        words.contains("more than 16 consecutive spindle-synchronised moves"),
        "{words}"
    );
    assert!(m.samples.iter().all(|s| s.axes[2] == 5.0 || s.line < 4));
}
