//! Property test: the interpreter never panics, whatever the program. Programs are made of
//! G-code-like tokens (codes, words, expressions, o-words, comments) mixed with random
//! bytes. A short run is part of the normal tests; `scripts/fuzz.sh` runs the coverage-guided fuzzer (fuzz/) for long runs
//! (FUZZ_CASES inputs).

use proptest::prelude::*;
use rtcnc_gcode::{Interpreter, Parameters, Settings, Tool, ToolTable};

const TOKENS: &[&str] = &[
    "G0",
    "G1",
    "G2",
    "G3",
    "G4",
    "G5",
    "G5.1",
    "G7",
    "G8",
    "G10",
    "G17",
    "G18",
    "G19",
    "G17.1",
    "G20",
    "G21",
    "G28",
    "G28.1",
    "G30",
    "G38.2",
    "G38.3",
    "G38.4",
    "G38.5",
    "G40",
    "G41",
    "G42",
    "G41.1",
    "G42.1",
    "G43",
    "G43.1",
    "G49",
    "G53",
    "G54",
    "G55",
    "G59.3",
    "G61",
    "G61.1",
    "G64",
    "G73",
    "G80",
    "G81",
    "G82",
    "G83",
    "G84",
    "G85",
    "G86",
    "G87",
    "G88",
    "G89",
    "G90",
    "G91",
    "G90.1",
    "G91.1",
    "G92",
    "G92.1",
    "G92.2",
    "G92.3",
    "G93",
    "G94",
    "G95",
    "G96",
    "G97",
    "G98",
    "G99",
    "M0",
    "M1",
    "M2",
    "M3",
    "M4",
    "M5",
    "M6",
    "M7",
    "M8",
    "M9",
    "M19",
    "M30",
    "M48",
    "M49",
    "M50",
    "M51",
    "M52",
    "M53",
    "M60",
    "M61",
    "M62",
    "M63",
    "M64",
    "M65",
    "M66",
    "M67",
    "M68",
    "M70",
    "M71",
    "M72",
    "M73",
    "M98",
    "M99",
    "M100",
    "M199",
    "T1",
    "T2",
    "T0",
    "T9",
    "F100",
    "F0",
    "S500",
    "H1",
    "D1",
    "L2",
    "L0",
    "P1",
    "P0.5",
    "Q0.3",
    "R2",
    "R-3",
    "E1",
    "$0",
    "(comment)",
    "(msg,hi)",
    "(debug,#1 #<_x>)",
    "(print,#<_value>)",
    ";rest",
    "/",
    "%",
    "#1=[#1+1]",
    "#<a>=2",
    "#<_g>=#<a>",
    "X[#1*2]",
    "Y[sin[30]]",
    "Z[1/#2]",
    "A[sqrt[#3]]",
    "X[atan[1]/[0]]",
    "Y[#<a>]",
    "Z#<_g>",
    "X##1",
    "o100 if [#1 lt 3]",
    "o100 elseif [1]",
    "o100 else",
    "o100 endif",
    "o101 while [#1 lt 4]",
    "o101 endwhile",
    "o102 do",
    "o102 while [0]",
    "o103 repeat [2]",
    "o103 endrepeat",
    "o101 break",
    "o101 continue",
    "o<s> sub",
    "o<s> endsub",
    "o<s> return [2]",
    "o<s> call [1] [2]",
    "o<nosuch> call",
    "O1000",
    "N10",
    "[",
    "]",
    "#",
    "**",
    "mod",
];

fn word() -> impl Strategy<Value = String> {
    prop_oneof![
        (
            prop::sample::select(&b"XYZABCUVWIJKRPQFSLE"[..]),
            -1000.0f64..1000.0
        )
            .prop_map(|(l, v)| format!("{}{v:.3}", l as char)),
        prop::sample::select(TOKENS).prop_map(str::to_string),
        "[ -~]{0,12}",
    ]
}

fn line() -> impl Strategy<Value = String> {
    prop::collection::vec(word(), 0..6).prop_map(|w| w.join(" "))
}

fn program() -> impl Strategy<Value = String> {
    prop::collection::vec(line(), 1..25).prop_map(|l| l.join("\n"))
}

fn run(text: &str) {
    let mut tools = ToolTable::new();
    let mut t = Tool::new(1, 1);
    t.diameter = 3.0;
    t.offset.z = 10.0;
    tools.set(t);
    tools.set(Tool::new(2, 2));
    let settings = Settings {
        max_lines_without_output: 2_000,
        ..Settings::default()
    };
    let mut interp = Interpreter::new(settings, tools, Parameters::new());
    interp.open_text("fuzz.ngc", text.as_bytes()).expect("open");
    let mut buf = Vec::new();
    for item in (&mut interp).take(5_000) {
        match item {
            Ok(c) => {
                buf.clear();
                c.write_rs274(&mut buf, true);
            }
            Err(e) => {
                assert!(!e.message.is_empty());
                assert!(!e.code().is_empty());
                break;
            }
        }
    }
    // MDI after the program must not panic either.
    let first = text.lines().next().unwrap_or("");
    let _ = interp.execute_mdi(first);
    for _ in (&mut interp).take(1_000) {}
}

fn cases() -> u32 {
    std::env::var("FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(if cfg!(debug_assertions) { 300 } else { 3_000 })
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: cases(),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn interpreter_never_panics(text in program()) {
        run(&text);
    }

    #[test]
    fn lexer_never_panics_on_bytes(bytes in prop::collection::vec(any::<u8>(), 0..200)) {
        run(&String::from_utf8_lossy(&bytes));
    }
}
