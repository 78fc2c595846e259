//! Inputs the coverage-guided fuzzer (fuzz/, scripts/fuzz.sh) found to crash or hang the
//! interpreter, kept as they were found (tests/fuzz_regressions/), and the defects they
//! showed, as plain cases.

use rtcnc_gcode::compensation::Compensator;
use rtcnc_gcode::{ErrorKind, GcodeError, Interpreter, Parameters, Settings, ToolTable};

/// The fuzz target's body: interpret, compensate, format; every error a located value.
fn run(text: &[u8]) -> Vec<GcodeError> {
    let mut interp = Interpreter::new(Settings::default(), ToolTable::new(), Parameters::new());
    interp.open_text("found.ngc", text.to_vec()).unwrap();
    let mut stage = Compensator::new();
    let mut errors = Vec::new();
    let mut out = Vec::new();
    for _ in 0..100_000 {
        match interp.next_canon() {
            Some(Ok(c)) => {
                if stage.push(c).is_err() {
                    break;
                }
                while let Some(c) = stage.pop() {
                    out.clear();
                    c.write_rs274(&mut out, true);
                }
            }
            Some(Err(e)) => {
                errors.push(e);
                if !interp.resume_after_error() {
                    break;
                }
            }
            None => break,
        }
    }
    errors
}

#[test]
fn every_found_input_ends() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz_regressions");
    let mut count = 0;
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        run(&std::fs::read(&path).unwrap());
        count += 1;
    }
    assert!(count > 0);
}

/// G76 H111111200 expanded a hundred million spring passes at once (the fuzzer's first
/// hang, with 1.7 GB of memory).
#[test]
fn g76_spring_passes_are_bounded() {
    let errors =
        run(b"G18 G21 G90 G0 X10 Z5\nS600 M3\nG76 P1.5 Z-20 I-0.5 J0.2 K0.92 H111111200\nM2\n");
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert_eq!(errors[0].kind, ErrorKind::BadValue);
    assert_eq!(errors[0].line, 3);
    assert!(errors[0].message.contains("spring passes"), "{errors:?}");
    // A usual count is fine.
    assert!(
        run(b"G18 G21 G90 G0 X10 Z5\nS600 M3\nG76 P1.5 Z-20 I-0.5 J0.2 K0.92 H3\nM2\n").is_empty()
    );
}

/// A peck cycle with a tiny Q queued millions of pecks at once.
#[test]
fn peck_cycle_pecks_are_bounded() {
    let errors = run(b"G21 G90 G0 X0 Y0 Z10\nG83 X1 Y1 Z-1000 R1 Q0.000001 F100\nM2\n");
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert_eq!(errors[0].line, 2);
    assert!(errors[0].message.contains("pecks"), "{errors:?}");
    assert!(run(b"G21 G90 G0 X0 Y0 Z10\nG83 X1 Y1 Z-10 R1 Q1 F100\nG80\nM2\n").is_empty());
}
