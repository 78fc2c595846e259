//! Compile errors name file, line and column; runtime faults stop the PLC with safe
//! outputs and come back as values.

use crate::common::*;
use rtcnc_plc::{FaultKind, PlcConfig, Restart, Runtime, RuntimeOptions, Value, compile};
use std::sync::Arc;

#[test]
fn syntax_error_position() {
    let src = "PROGRAM P\nVAR x : INT; END_VAR\nx := 1\nx := 2;\nEND_PROGRAM";
    let (line, col, code, msg) = compile_error(src);
    assert_eq!((line, col, code), (4, 1, "syntax"));
    assert_eq!(msg, "';' expected to end the statement at 3:1, found 'x'");
}

#[test]
fn undeclared_name_position() {
    let src = "PROGRAM P\nVAR x : INT; END_VAR\n  x := y + 1;\nEND_PROGRAM";
    assert_eq!(compile_error(src).0..=compile_error(src).1, 3..=8);
    assert_eq!(compile_error(src).2, "undeclared");
}

#[test]
fn type_mismatch_position() {
    let src = "PROGRAM P\nVAR b : BOOL; i : INT; END_VAR\n  b := i;\nEND_PROGRAM";
    let (line, col, code, _) = compile_error(src);
    assert_eq!((line, col, code), (3, 8, "type-mismatch"));
    // Narrowing is not implicit.
    let src = "PROGRAM P\nVAR d : DINT; i : INT; END_VAR\n  i := d;\nEND_PROGRAM";
    assert_eq!(compile_error(src).2, "type-mismatch");
    // Bit strings and integers do not mix implicitly.
    let src = "PROGRAM P\nVAR w : WORD; i : INT; END_VAR\n  i := w + 1;\nEND_PROGRAM";
    assert_eq!(compile_error(src).2, "type-mismatch");
    // A literal that does not fit.
    let src = "PROGRAM P\nVAR s : SINT; END_VAR\n  s := 200;\nEND_PROGRAM";
    let (line, col, code, _) = compile_error(src);
    assert_eq!((line, col, code), (3, 8, "type-mismatch"));
}

#[test]
fn wrong_argument_positions() {
    let fb = "FUNCTION F : INT VAR_INPUT a : INT; END_VAR F := a; END_FUNCTION\n";
    let src = format!("{fb}PROGRAM P\nVAR x : INT; END_VAR\n  x := F(b := 1);\nEND_PROGRAM");
    let (line, col, code, _) = compile_error(&src);
    assert_eq!((line, col, code), (4, 10, "wrong-argument"));
    let src = format!("{fb}PROGRAM P\nVAR x : INT; END_VAR\n  x := F(1, 2);\nEND_PROGRAM");
    assert_eq!(compile_error(&src).2, "wrong-argument");
    let src = "PROGRAM P\nVAR t : TON; END_VAR\n  t(IN := 5);\nEND_PROGRAM";
    let (line, col, code, _) = compile_error(src);
    assert_eq!((line, col, code), (3, 11, "wrong-argument"));
    let src = "PROGRAM P\nVAR x : INT; END_VAR\n  x := LIMIT(1, 2);\nEND_PROGRAM";
    assert_eq!(compile_error(src).2, "wrong-argument");
}

#[test]
fn assignment_to_constant_and_inputs() {
    let src = "PROGRAM P\nVAR CONSTANT k : INT := 3; END_VAR\n  k := 4;\nEND_PROGRAM";
    let (line, col, code, _) = compile_error(src);
    assert_eq!((line, col, code), (3, 3, "assign-to-constant"));
    // CODESYS and TwinCAT accept writing an input of the POU itself, with a warning.
    let src = "FUNCTION_BLOCK B\nVAR_INPUT i : INT; END_VAR\n  i := 1;\nEND_FUNCTION_BLOCK";
    let p = compile(src, "b.st").expect("compiles with a warning");
    let w = &p.warnings()[0];
    assert_eq!((w.pos.line, w.pos.col, w.code), (3, 3, "assign-to-input"));
    assert!(
        w.to_string()
            .starts_with("b.st:3:3: warning[assign-to-input]: 'i' is a VAR_INPUT")
    );
    let src = "PROGRAM P\nVAR sw AT %IX0.0 : BOOL; END_VAR\n  sw := TRUE;\nEND_PROGRAM";
    assert_eq!(compile_error(src).2, "assign-to-input");
    let src = "PROGRAM P\nVAR t : TON; END_VAR\n  t.Q := TRUE;\nEND_PROGRAM";
    assert_eq!(compile_error(src).0, 3);
}

#[test]
fn other_semantic_errors() {
    let cases: &[(&str, &str)] = &[
        (
            "PROGRAM P VAR a : ARRAY[1..3] OF INT; END_VAR a[4] := 1; END_PROGRAM",
            "invalid",
        ),
        (
            "PROGRAM P VAR i : INT; END_VAR EXIT; END_PROGRAM",
            "invalid",
        ),
        ("FUNCTION F : INT F := F(); END_FUNCTION", "invalid"),
        (
            "PROGRAM P VAR x : INT; x : BOOL; END_VAR END_PROGRAM",
            "duplicate",
        ),
        (
            "PROGRAM P VAR x : Unknown; END_VAR END_PROGRAM",
            "undeclared",
        ),
        (
            "PROGRAM P VAR r : REAL; END_VAR r := 1.0 MOD 2.0; END_PROGRAM",
            "type-mismatch",
        ),
        (
            "PROGRAM P VAR x : INT(0..10); END_VAR x := 11; END_PROGRAM",
            "type-mismatch",
        ),
        (
            "PROGRAM P VAR x : INT; END_VAR x := 1 / 0; END_PROGRAM",
            "invalid",
        ),
    ];
    for (src, code) in cases {
        assert_eq!(compile_error(src).2, *code, "{src}");
    }
}

#[test]
fn compile_error_message_names_the_file() {
    let e = compile(
        "PROGRAM P VAR x : INT; END_VAR x := ; END_PROGRAM",
        "machine/logic.st",
    )
    .unwrap_err();
    assert!(
        e.to_string()
            .starts_with("machine/logic.st:1:37: error[syntax]"),
        "{e}"
    );
}

#[test]
fn several_errors_are_reported_together() {
    let src = "PROGRAM P\nVAR x : INT; END_VAR\n  x := a;\n  x := b;\nEND_PROGRAM";
    let e = compile(src, "t.st").unwrap_err();
    let lines: Vec<u32> = e.0.iter().map(|e| e.pos.line).collect();
    assert_eq!(lines, [3, 4]);
}

fn faulting(src: &str) -> Runtime {
    plc(src)
}

#[test]
fn division_by_zero_faults_with_pou_and_line() {
    let src = "PROGRAM P\nVAR a : INT := 5; b : INT; c : INT; END_VAR\n  c := 1;\n  c := a / b;\n  c := 99;\nEND_PROGRAM";
    let mut rt = faulting(src);
    let f = rt.scan(ms(0)).unwrap_err();
    assert_eq!(f.kind, FaultKind::DivisionByZero);
    assert_eq!(f.code(), "division-by-zero");
    assert_eq!((&*f.pou, f.line, f.scan), ("P", 4, 1));
    // The statement after the fault did not run.
    assert_eq!(int(&rt, "c"), 1);
    // The PLC stays stopped.
    assert_eq!(rt.scan(ms(4)).unwrap_err(), f);
    assert_eq!(rt.fault(), Some(&f));
}

#[test]
fn real_division_and_mod_by_zero_fault_too() {
    for body in ["r := r / z;", "i := i MOD j;"] {
        let src = format!(
            "PROGRAM P VAR r : REAL := 1.0; z : REAL; i : INT; j : INT; END_VAR {body} END_PROGRAM"
        );
        let mut rt = faulting(&src);
        assert_eq!(
            rt.scan(ms(0)).unwrap_err().kind,
            FaultKind::DivisionByZero,
            "{body}"
        );
    }
}

#[test]
fn index_out_of_range_faults_inside_a_function_block() {
    let src = "FUNCTION_BLOCK Table\nVAR_INPUT k : INT; END_VAR\nVAR data : ARRAY[0..3] OF INT; END_VAR\n  data[k] := 1;\nEND_FUNCTION_BLOCK\nPROGRAM P VAR t : Table; END_VAR t(k := 4); END_PROGRAM";
    let mut rt = faulting(src);
    let f = rt.scan(ms(0)).unwrap_err();
    assert_eq!(
        f.kind,
        FaultKind::IndexOutOfRange {
            index: 4,
            low: 0,
            high: 3
        }
    );
    assert_eq!((&*f.pou, f.line), ("Table", 4));
}

#[test]
fn subrange_violation_faults() {
    let src = "PROGRAM P VAR p : INT(0..100); x : INT := 101; END_VAR p := x; END_PROGRAM";
    let mut rt = faulting(src);
    let f = rt.scan(ms(0)).unwrap_err();
    assert_eq!(
        f.kind,
        FaultKind::SubrangeViolation {
            value: 101,
            low: 0,
            high: 100
        }
    );
    assert_eq!(int(&rt, "p"), 0);
}

#[test]
fn endless_while_is_caught_by_the_watchdog_budget() {
    let src = "PROGRAM P\nVAR n : DINT; END_VAR\n  WHILE TRUE DO\n    n := n + 1;\n  END_WHILE;\nEND_PROGRAM";
    let program = Arc::new(compile(src, "t.st").unwrap());
    let mut rt = Runtime::with_options(
        program,
        RuntimeOptions {
            watchdog_budget: 1000,
            ..RuntimeOptions::default()
        },
    );
    let f = rt.scan(ms(0)).unwrap_err();
    assert_eq!(f.kind, FaultKind::WatchdogExceeded { budget: 1000 });
    assert_eq!(f.code(), "watchdog");
    // Deterministic: each iteration costs one tick for the loop and one for its statement;
    // iteration 500 exhausts the budget of 1000 right after `n := n + 1` (line 4).
    assert_eq!(f.line, 4);
    assert_eq!(int(&rt, "n"), 500);
}

#[test]
fn endless_repeat_in_a_function_is_caught_too() {
    let src = "FUNCTION Spin : INT VAR i : INT; END_VAR REPEAT i := i + 1; UNTIL FALSE END_REPEAT; Spin := i; END_FUNCTION
        PROGRAM P VAR x : INT; END_VAR x := Spin(); END_PROGRAM";
    let mut rt = faulting(src);
    let f = rt.scan(ms(0)).unwrap_err();
    assert!(matches!(f.kind, FaultKind::WatchdogExceeded { .. }));
    assert_eq!(&*f.pou, "Spin");
}

#[test]
fn a_fault_drives_outputs_to_safe_values_and_restart_recovers() {
    let src = "PROGRAM P
        VAR lamp AT %QX0.0 : BOOL; lock AT %QX0.1 : BOOL; speed AT %QW1 : INT; hold : BOOL; go : BOOL; d : INT; boom : BOOL; END_VAR
        lamp := TRUE; lock := FALSE; speed := 1200; hold := FALSE; go := TRUE;
        IF boom THEN d := d / d; END_IF;
        END_PROGRAM";
    let mut rt = plc(src);
    let cfg: PlcConfig = toml::from_str(
        r#"
        [signals]
        feed_hold_request = "hold"
        estop_chain_out = "go"
        [safe_values]
        lock = "TRUE"
        "#,
    )
    .unwrap();
    rt.configure(&cfg).unwrap();
    rt.scan(ms(0)).unwrap();
    assert_eq!(rt.output_image(), &[0b01, 0, 0xB0, 0x04]);
    assert!(!rt.signal_bool(rtcnc_plc::Signal::FeedHoldRequest));
    set(&mut rt, "boom", Value::Bool(true));
    let f = rt.scan(ms(4)).unwrap_err();
    assert_eq!(f.kind, FaultKind::DivisionByZero);
    // Lamp off, lock on (configured), speed 0; feed hold requested, chain open.
    assert_eq!(rt.output_image(), &[0b10, 0, 0, 0]);
    assert!(rt.signal_bool(rtcnc_plc::Signal::FeedHoldRequest));
    assert!(!rt.signal_bool(rtcnc_plc::Signal::EstopChainOut));
    rt.restart(Restart::Cold);
    assert!(rt.fault().is_none());
    rt.scan(ms(8)).unwrap();
    assert_eq!(rt.output_image(), &[0b01, 0, 0xB0, 0x04]);
}

#[test]
fn programs_outside_the_configuration_are_still_checked() {
    let src = "PROGRAM Used VAR x : INT; END_VAR x := 1; END_PROGRAM
        PROGRAM Unused VAR x : INT; END_VAR\n x := nothing;\nEND_PROGRAM
        CONFIGURATION C RESOURCE R ON PLC TASK T (INTERVAL := T#10ms); PROGRAM u WITH T : Used; END_RESOURCE END_CONFIGURATION";
    let (line, _, code, _) = compile_error(src);
    assert_eq!((line, code), (3, "undeclared"));
}

#[test]
fn program_inputs_are_written_with_a_warning_too() {
    let src = "PROGRAM P\nVAR_INPUT start : BOOL; END_VAR\n  start := FALSE;\nEND_PROGRAM";
    let p = compile(src, "p.st").expect("compiles with a warning");
    assert_eq!(p.warnings().len(), 1);
    assert_eq!(p.warnings()[0].code, "assign-to-input");
}

#[test]
fn programs_and_runtimes_can_move_to_the_plc_thread() {
    fn send<T: Send>() {}
    fn share<T: Send + Sync>() {}
    send::<Runtime>();
    share::<rtcnc_plc::Program>();
    share::<rtcnc_plc::Fault>();
}

#[test]
fn a_signal_is_refused_on_a_variable_of_another_kind() {
    let src = "PROGRAM Main
        VAR flag : BOOL; span : TIME; speed : LREAL; count : DINT; mask : WORD; END_VAR
        flag := NOT flag;
        END_PROGRAM";
    let refused = |signal: &str, variable: &str| {
        let mut rt = plc(src);
        let cfg: PlcConfig =
            toml::from_str(&format!("[signals]\n{signal} = \"{variable}\"\n")).unwrap();
        match rt.configure(&cfg) {
            Ok(()) => false,
            Err(e) => {
                let text = e.to_string();
                assert!(text.contains(signal) && text.contains(variable), "{text}");
                true
            }
        }
    };
    // A number (the S word) or an integer (the T word) in a BOOL reads as 0 or 1, in a
    // TIME as nanoseconds: both refused, naming the signal and the variable.
    assert!(refused("spindle_speed_command", "flag"));
    assert!(refused("spindle_speed_out", "flag"));
    assert!(refused("tool_number", "flag"));
    assert!(refused("spindle_speed_command", "span"));
    assert!(refused("limit_min", "flag"));
    // Their own kinds are taken.
    assert!(!refused("spindle_speed_command", "speed"));
    assert!(!refused("tool_number", "count"));
    assert!(!refused("spindle_on", "flag"));
}

/// A duration whose fractional part alone is beyond TIME's range (about 292 years) is
/// refused, not an overflow (found by the st_text fuzz target:
/// `T#222222h999…9.2…23m`).
#[test]
fn a_duration_with_a_huge_fractional_part_is_too_large() {
    let huge = format!("T#1h{}.5m", "9".repeat(200));
    let src = format!("PROGRAM P VAR t : TIME; END_VAR t := {huge}; END_PROGRAM");
    let e = compile(&src, "t.st").unwrap_err();
    assert!(e.to_string().contains("duration is too large"), "{e}");
    // At the end of the range, as a whole number and as a fraction: accepted.
    for ok in ["T#106751d23h47m16s854ms775us807ns", "T#2562047.5h"] {
        let src = format!("PROGRAM P VAR t : TIME; END_VAR t := {ok}; END_PROGRAM");
        assert!(compile(&src, "t.st").is_ok(), "{ok}");
    }
}
