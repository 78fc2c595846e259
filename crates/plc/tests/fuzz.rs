//! Fuzzing of the lexer, parser and compiler (and a few scans of whatever compiles):
//! nothing may panic, every failure must be a positioned error or a fault value.
//! `PLC_FUZZ_CASES` sets the number of cases per property (default: a short run);
//! `scripts/fuzz.sh` runs the coverage-guided fuzzer (fuzz/) for long runs.

use std::sync::Arc;
use std::time::Duration;

use proptest::prelude::*;
use rtcnc_plc::{Runtime, RuntimeOptions, compile};

const MILL: &str = include_str!("../../../examples/plc/mill.st");
const STATIONS: &str = include_str!("../../../examples/plc/stations.st");
const CAROUSEL: &str = include_str!("../../../examples/plc/carousel.st");

fn cases() -> u32 {
    std::env::var("PLC_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(if cfg!(debug_assertions) { 48 } else { 256 })
}

const VOCAB: &[&str] = &[
    "PROGRAM",
    "END_PROGRAM",
    "FUNCTION",
    "END_FUNCTION",
    "FUNCTION_BLOCK",
    "END_FUNCTION_BLOCK",
    "VAR",
    "VAR_INPUT",
    "VAR_OUTPUT",
    "VAR_IN_OUT",
    "VAR_TEMP",
    "VAR_GLOBAL",
    "VAR_EXTERNAL",
    "END_VAR",
    "CONSTANT",
    "RETAIN",
    "TYPE",
    "END_TYPE",
    "STRUCT",
    "END_STRUCT",
    "ARRAY",
    "OF",
    "IF",
    "THEN",
    "ELSIF",
    "ELSE",
    "END_IF",
    "CASE",
    "END_CASE",
    "FOR",
    "TO",
    "BY",
    "DO",
    "END_FOR",
    "WHILE",
    "END_WHILE",
    "REPEAT",
    "UNTIL",
    "END_REPEAT",
    "EXIT",
    "RETURN",
    "CONTINUE",
    "AND",
    "OR",
    "XOR",
    "NOT",
    "MOD",
    "TRUE",
    "FALSE",
    "CONFIGURATION",
    "END_CONFIGURATION",
    "RESOURCE",
    "END_RESOURCE",
    "TASK",
    "WITH",
    "ON",
    "AT",
    "INT",
    "DINT",
    "BOOL",
    "REAL",
    "LREAL",
    "TIME",
    "STRING",
    "WORD",
    "TON",
    "CTU",
    "R_TRIG",
    "x",
    "y",
    "z",
    "P",
    "F",
    "t",
    "a",
    ":=",
    "=>",
    ":",
    ";",
    ",",
    ".",
    "..",
    "(",
    ")",
    "[",
    "]",
    "+",
    "-",
    "*",
    "**",
    "/",
    "&",
    "=",
    "<>",
    "<",
    "<=",
    ">",
    ">=",
    "0",
    "1",
    "42",
    "-7",
    "16#FF",
    "2#1010",
    "1.5",
    "1e3",
    "T#20ms",
    "T#1s500ms",
    "'txt'",
    "'$N'",
    "%IX0.0",
    "%QW1",
    "%MD2",
    "INT#5",
    "(*c*)",
    "//c\n",
    "ABS",
    "LIMIT",
    "SEL",
    "MAX",
    "CONCAT",
    "INT_TO_REAL",
    "REAL_TO_INT",
    "LEN",
    "MID",
    "METHOD",
    "END_METHOD",
    "PRIVATE",
    "GT",
    "STRING_TO_TIME",
    "AND(",
    "THIS",
    "^",
    "THIS^.",
    "SUPER^.",
    "REF=",
    "POINTER TO",
    "REFERENCE TO",
    "ADR(",
    "SIZEOF(",
    "__ISVALIDREF(",
    "EXTENDS",
    "IMPLEMENTS",
    "INTERFACE",
    "END_INTERFACE",
    "PROPERTY",
    "END_PROPERTY",
    "GET",
    "END_GET",
    "SET",
    "END_SET",
    "VAR_INST",
    "{attribute 'x'}",
    "EN :=",
    "ENO =>",
    "D#2024-02-29",
    "TOD#23:59:59.5",
    "DT#2024-01-01-00:00:00",
    "DT_TO_DATE(",
    "CONCAT_DATE(",
    "TIME_TO_DT(",
    "AXIS_REF",
    "MC_MoveAbsolute",
    "MC_Power",
];

/// A skeleton that makes token soups land inside a POU body more often.
fn in_program(body: &str) -> String {
    format!(
        "PROGRAM P VAR x : INT; y : BOOL; z : REAL; t : TON; a : ARRAY[0..3] OF INT; END_VAR\n{body}\nEND_PROGRAM"
    )
}

fn run_some(src: &str) {
    run_configured(src, None)
}

/// As `run_some`, with a PLC configuration (axes for the motion blocks) when it applies.
fn run_configured(src: &str, cfg: Option<&rtcnc_plc::PlcConfig>) {
    if let Ok(p) = compile(src, "fuzz.st") {
        let mut rt = Runtime::with_options(
            Arc::new(p),
            RuntimeOptions {
                watchdog_budget: 20_000,
                ..Default::default()
            },
        );
        if let Some(c) = cfg {
            let _ = rt.configure(c);
            rt.set_signal_bool(rtcnc_plc::Signal::MachineOnRequest, true);
            rt.set_signal_bool(rtcnc_plc::Signal::ToolChangeRequest, true);
            rt.set_signal(rtcnc_plc::Signal::ToolNumber, 5.0);
        }
        let scans = if cfg.is_some() { 40 } else { 3 };
        for k in 0..scans {
            if rt.scan(Duration::from_millis(4 * k)).is_err() {
                break;
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_text_never_panics(s in "\\PC{0,300}") {
        run_some(&s);
    }

    #[test]
    fn arbitrary_bytes_never_panic(b in proptest::collection::vec(any::<u8>(), 0..300)) {
        run_some(&String::from_utf8_lossy(&b));
    }

    #[test]
    fn token_soup_never_panics(toks in proptest::collection::vec(0..VOCAB.len(), 0..80), wrap in any::<bool>()) {
        let text: Vec<&str> = toks.iter().map(|i| VOCAB[*i]).collect();
        let body = text.join(" ");
        let src = if wrap { in_program(&body) } else { body };
        run_some(&src);
    }

    #[test]
    fn mutated_stations_never_panic(edits in proptest::collection::vec((0..STATIONS.len(), 0..40usize, 0..VOCAB.len()), 1..6)) {
        let mut src = STATIONS.to_string();
        for (at, len, tok) in edits {
            let at = at.min(src.len());
            let end = (at + len).min(src.len());
            if src.is_char_boundary(at) && src.is_char_boundary(end) {
                src.replace_range(at..end, VOCAB[tok]);
            }
        }
        run_some(&src);
    }

    #[test]
    fn mutated_carousel_never_panics(edits in proptest::collection::vec((0..CAROUSEL.len(), 0..40usize, 0..VOCAB.len()), 1..6)) {
        let mut src = CAROUSEL.to_string();
        for (at, len, tok) in edits {
            let at = at.min(src.len());
            let end = (at + len).min(src.len());
            if src.is_char_boundary(at) && src.is_char_boundary(end) {
                src.replace_range(at..end, VOCAB[tok]);
            }
        }
        let cfg: rtcnc_plc::PlcConfig =
            toml::from_str(include_str!("../../../examples/plc/carousel.toml")).unwrap();
        run_configured(&src, Some(&cfg));
    }

    #[test]
    fn mutated_mill_never_panics(edits in proptest::collection::vec((0..MILL.len(), 0..40usize, 0..VOCAB.len()), 1..6)) {
        let mut src = MILL.to_string();
        for (at, len, tok) in edits {
            let at = at.min(src.len());
            let end = (at + len).min(src.len());
            if src.is_char_boundary(at) && src.is_char_boundary(end) {
                src.replace_range(at..end, VOCAB[tok]);
            }
        }
        run_some(&src);
    }
}

/// Runs `f` on a thread with half the default test stack, to keep a margin.
fn on_small_stack(f: impl FnOnce() + Send + 'static) {
    std::thread::Builder::new()
        .stack_size(1 << 20)
        .spawn(f)
        .unwrap()
        .join()
        .unwrap();
}

#[test]
fn nesting_at_the_limits_fits_a_small_stack() {
    on_small_stack(|| {
        // The deepest accepted program: 32 nested IFs around an expression nested to the
        // expression limit (unary minus around parentheses costs two levels).
        let e = format!("{}x{}", "-(".repeat(31), ")".repeat(31));
        let body = format!(
            "x := 1;{}x := {e};{}",
            "IF NOT y THEN ".repeat(31),
            " END_IF;".repeat(31)
        );
        let p = compile(&in_program(&body), "deep.st").unwrap_or_else(|e| panic!("{e}"));
        let mut rt = Runtime::new(Arc::new(p));
        rt.scan(Duration::ZERO).unwrap();
        assert_eq!(rt.read_name("x").unwrap(), rtcnc_plc::Value::Int(-1));
        // One more level of either is refused.
        let e = format!("{}x{}", "-(".repeat(33), ")".repeat(33));
        assert!(compile(&in_program(&format!("x := {e};")), "deep.st").is_err());
        let body = format!(
            "{}x := 1;{}",
            "IF y THEN ".repeat(33),
            " END_IF;".repeat(33)
        );
        assert!(compile(&in_program(&body), "deep.st").is_err());
    });
}

#[test]
fn deep_nesting_is_an_error_not_a_stack_overflow() {
    let deep = format!("{}1{}", "-(".repeat(5000), ")".repeat(5000));
    let src = in_program(&format!("x := {deep};"));
    let e = compile(&src, "deep.st").unwrap_err();
    assert_eq!(e.first().unwrap().code(), "syntax");
    let chain = format!("x := {};", vec!["1"; 5000].join(" + "));
    assert!(compile(&in_program(&chain), "chain.st").is_err());
    let ifs = format!("{}{}", "IF y THEN ".repeat(3000), "END_IF; ".repeat(3000));
    assert!(compile(&in_program(&ifs), "ifs.st").is_err());
}

#[test]
fn huge_declarations_are_errors_not_allocation_failures() {
    let src = "PROGRAM P VAR a : ARRAY[0..2000000000] OF LREAL; END_VAR END_PROGRAM";
    assert!(compile(src, "huge.st").is_err());
    let src =
        "PROGRAM P VAR a : ARRAY[0..9999, 0..9999] OF ARRAY[0..9999] OF INT; END_VAR END_PROGRAM";
    assert!(compile(src, "huge.st").is_err());
}

#[test]
fn nesting_below_the_limit_compiles_and_runs() {
    let n = 20;
    let sum = format!("{}1{}", "1 + (".repeat(n), ")".repeat(n));
    let ifs = format!(
        "{}x := {sum};{}",
        "IF NOT y THEN ".repeat(n),
        " END_IF;".repeat(n)
    );
    let mut rt = Runtime::new(Arc::new(compile(&in_program(&ifs), "nest.st").unwrap()));
    rt.scan(Duration::ZERO).unwrap();
    assert_eq!(rt.read_name("x").unwrap(), rtcnc_plc::Value::Int(21));
}

#[test]
fn long_contact_chains_are_fine() {
    // A 3000-contact rung: AND/OR chains are balanced, so depth is no issue.
    let contacts: Vec<String> = (0..3000)
        .map(|i| {
            if i == 2999 {
                "y".to_string()
            } else {
                "FALSE".to_string()
            }
        })
        .collect();
    let src = format!(
        "PROGRAM P VAR y : BOOL := TRUE; q : BOOL; r : BOOL; END_VAR q := {}; r := {}; END_PROGRAM",
        contacts.join(" OR "),
        contacts.join(" AND ")
    );
    let mut rt = Runtime::new(Arc::new(compile(&src, "chain.st").unwrap()));
    rt.scan(Duration::ZERO).unwrap();
    assert_eq!(rt.read_name("q").unwrap(), rtcnc_plc::Value::Bool(true));
    assert_eq!(rt.read_name("r").unwrap(), rtcnc_plc::Value::Bool(false));
}

#[test]
fn a_flat_sum_is_no_nesting_and_the_deepest_tree_fits_a_small_stack() {
    // A sum of 65 terms was refused as "nested more than 64 deep".
    let sum = |terms: usize| format!("x := {};", vec!["1"; terms].join(" + "));
    for terms in [65, 120] {
        let p = compile(&in_program(&sum(terms)), "sum.st").unwrap_or_else(|e| panic!("{e}"));
        let mut rt = Runtime::new(Arc::new(p));
        rt.scan(Duration::ZERO).unwrap();
        assert_eq!(
            rt.read_name("x").unwrap(),
            rtcnc_plc::Value::Int(terms as i64)
        );
    }
    let e = compile(&in_program(&sum(130)), "sum.st")
        .unwrap_err()
        .to_string();
    assert!(e.contains("expression too long"), "{e}");
    on_small_stack(|| {
        // The tree limit reached inside the deepest nesting, inside the deepest IFs, in a
        // variable's chain (not constants, which would be folded).
        let mut deepest = None;
        for terms in (20..130).rev() {
            let chain = vec!["x"; terms].join(" - ");
            let e = format!("{}{chain}{}", "-(".repeat(31), ")".repeat(31));
            let body = format!(
                "x := 1;{}x := {e};{}",
                "IF NOT y THEN ".repeat(31),
                " END_IF;".repeat(31)
            );
            if let Ok(p) = compile(&in_program(&body), "deep.st") {
                let mut rt = Runtime::new(Arc::new(p));
                rt.scan(Duration::ZERO).unwrap();
                // 1 - 1 - ... (terms times) = 2 - terms; 31 minus signs negate it.
                let want = -(2 - terms as i64);
                assert_eq!(rt.read_name("x").unwrap(), rtcnc_plc::Value::Int(want));
                deepest = Some(terms);
                break;
            }
        }
        assert!(deepest.is_some_and(|t| t >= 60), "{deepest:?}");
    });
}
