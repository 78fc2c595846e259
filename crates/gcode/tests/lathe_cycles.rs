//! G70-G72 where rs274 gives no output to compare with: profiles on which LinuxCNC 2.9
//! loops for ever, and cycles too large for one block. (The cycles themselves are compared
//! with rs274 in rs274_data.rs.)

use rtcnc_gcode::canon::CanonCommand;
use rtcnc_gcode::{ErrorKind, GcodeError, Interpreter, Parameters, Settings, ToolTable};

fn run(text: &str) -> (Vec<CanonCommand>, Option<GcodeError>) {
    let mut it = Interpreter::new(Settings::default(), ToolTable::new(), Parameters::new());
    it.open_text("cycle.ngc", text).unwrap();
    let mut out = Vec::new();
    for c in &mut it {
        match c {
            Ok(c) => out.push(c.command),
            Err(e) => return (out, Some(e)),
        }
    }
    (out, None)
}

#[test]
fn a_profile_on_which_linuxcnc_repeats_a_pass_for_ever_is_an_error() {
    // rs274 prints STRAIGHT_TRAVERSE(7.0953, 0, -0.8266, ...) without end on this one
    // (found by scripts/differential-lathe-cycles.sh).
    let text = "G18 G21 G90 F100\nG0 X14.0953 Z2.6793\no10 sub\n  G1 X6.7490 Z0.0000\n\
                  G2 X3.5200 Z-3.2290 I0.0000 K-3.2290\n  G3 X6.6840 Z-6.3940 I0.0000 K-3.1650\n\
                  G3 X8.9110 Z-8.6210 I0.0000 K-2.2270\n  G1 X11.6380\no10 endsub\n\
                G71 Q10 D1.0000 I1.0000 R0.3000\nM2\n";
    let (out, err) = run(text);
    let err = err.expect("an error");
    assert_eq!(err.line, 10);
    assert!(err.message.contains("lost track"), "{err}");
    // What came before is rs274's: its passes down to X7.0953, then the pass it repeats
    // (once here).
    let repeated = out
        .iter()
        .filter(|c| {
            matches!(c, CanonCommand::StraightTraverse(p)
                if (p.x - 7.0953).abs() < 1e-4 && (p.z + 0.8266).abs() < 1e-4)
        })
        .count();
    assert!((1..=2).contains(&repeated), "{repeated}");
}

#[test]
fn a_cycle_of_too_many_passes_is_refused_not_run() {
    // 20 mm of stock in cuts of 0.0001 mm: 200 000 passes.
    let text = "G18 G21 G90 F100\nG0 X30 Z2\no10 sub\n  G1 X10 Z0\n  Z-20\n  X30\no10 endsub\n\
                G71 Q10 I0.0001\nM2\n";
    let (out, err) = run(text);
    let err = err.expect("an error");
    assert_eq!(err.kind, ErrorKind::BadValue);
    assert!(err.message.contains("more than 100000 moves"), "{err}");
    assert!(out.len() <= 100_000 + 16);
}

#[test]
fn the_profile_is_read_not_run() {
    // Nothing of the profile's own words is done: no coolant, no speed, no dwell; the
    // profile's G91 does not change the distance mode; its F does not change the feed.
    let text = "G18 G21 G90 F100\nG0 X20 Z2\no10 sub\n  G1 X10 Z0 F999 S2000 M8\n  G91 G4 P5\n\
                  G90 Z-10\n  X20\no10 endsub\nG71 Q10 I2\nX25\nM2\n";
    let (out, err) = run(text);
    assert_eq!(err, None);
    assert!(!out.iter().any(|c| matches!(
        c,
        CanonCommand::FloodOn | CanonCommand::Dwell(_) | CanonCommand::SetSpindleSpeed { .. }
    )));
    assert!(!out.contains(&CanonCommand::SetFeedRate(999.0)));
    // After the cycle: absolute, G1 (its last move), from its end at (X20, Z-10).
    assert!(matches!(
        out.iter().rev().find(|c| matches!(c, CanonCommand::StraightFeed(_))),
        Some(CanonCommand::StraightFeed(p)) if p.x == 25.0 && p.z == -10.0
    ));
}

#[test]
fn a_cycle_in_mdi_reads_its_profile_from_the_subroutine_path_and_runs_nothing_else() {
    let dir = std::env::temp_dir().join(format!("rtcnc-g71-mdi-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(
        dir.join("10.ngc"),
        "o10 sub\n  G1 X10 Z0\n  Z-10\n  X20\no10 endsub\nG0 X99 (not part of the profile)\nM2\n",
    )
    .unwrap();
    let settings = Settings {
        subroutine_path: vec![dir.clone()],
        ..Settings::default()
    };
    let mut it = Interpreter::new(settings, ToolTable::new(), Parameters::new());
    let mut out = Vec::new();
    for line in ["G18 G21 G90 F100", "G0 X20 Z2", "G71 Q10 I2"] {
        it.execute_mdi(line).unwrap();
        for c in &mut it {
            out.push(c.unwrap().command);
        }
        assert!(!it.is_running(), "after {line}");
    }
    std::fs::remove_dir_all(&dir).ok();
    let moves: Vec<f64> = out
        .iter()
        .filter_map(|c| match c {
            CanonCommand::StraightTraverse(p) | CanonCommand::StraightFeed(p) => Some(p.x),
            _ => None,
        })
        .collect();
    // Passes at X18 ... X12, then along the profile; X99 is never reached.
    assert!(moves.contains(&12.0) && moves.contains(&10.0), "{moves:?}");
    assert!(!moves.contains(&99.0), "{moves:?}");
}
