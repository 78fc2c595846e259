//! The Structured Text users bring from CODESYS 3 and TwinCAT 3: their names of the
//! standard blocks' inputs, object-oriented function blocks, interfaces, pointers and
//! references, EN/ENO, several files, pragmas, and errors that say what to add. Expected
//! values are worked out by hand in the comments.

use crate::common::*;
use rtcnc_plc::{CompileOptions, FaultKind, Runtime, Value, compile, compile_sources};
use std::sync::Arc;

fn scan(rt: &mut Runtime, k: u64) {
    if let Err(f) = rt.scan(ms(4 * k)) {
        panic!("scan {k} faulted: {f}");
    }
}

#[test]
fn standard_blocks_take_the_codesys_input_names() {
    let mut rt = plc("PROGRAM P
VAR
  pulse, clear : BOOL;
  cnt : CTU; down : CTD; latch : SR; hold : RS;
  done, empty, latched, held : BOOL;
  n, left : INT;
END_VAR
cnt(CU := pulse, RESET := clear, PV := 3, Q => done, CV => n);
down(CD := pulse, LOAD := clear, PV := 2, Q => empty, CV => left);
latch(SET1 := pulse, RESET := clear, Q1 => latched);
hold(SET := pulse, RESET1 := clear, Q1 => held);
END_PROGRAM");
    // (pulse, clear) per scan, and (n, done, left, empty, latched, held) after it.
    type Outputs = (i64, bool, i64, bool, bool, bool);
    let steps: [((bool, bool), Outputs); 8] = [
        ((false, true), (0, false, 2, false, false, false)), // LOAD: CTD at PV
        ((true, false), (1, false, 1, false, true, true)),
        ((false, false), (1, false, 1, false, true, true)),
        ((true, false), (2, false, 0, true, true, true)),
        ((false, false), (2, false, 0, true, true, true)),
        ((true, false), (3, true, -1, true, true, true)), // CTU reaches PV; CTD goes on down
        ((false, true), (0, false, 2, false, false, false)),
        // Both inputs: SR is set-dominant, RS reset-dominant; RESET wins in CTU.
        ((true, true), (0, false, 2, false, true, false)),
    ];
    for (k, ((pulse, clear), want)) in steps.into_iter().enumerate() {
        set(&mut rt, "pulse", Value::Bool(pulse));
        set(&mut rt, "clear", Value::Bool(clear));
        scan(&mut rt, k as u64);
        let got = (
            int(&rt, "n"),
            boolean(&rt, "done"),
            int(&rt, "left"),
            boolean(&rt, "empty"),
            boolean(&rt, "latched"),
            boolean(&rt, "held"),
        );
        assert_eq!(got, want, "scan {k}");
    }
}

fn error_of(src: &str) -> String {
    match compile(src, "m.st") {
        Ok(_) => panic!("expected a compile error"),
        Err(e) => e.first().expect("an error").to_string(),
    }
}

#[test]
fn unclosed_blocks_are_named_with_where_they_open() {
    let cases = [
        (
            "PROGRAM P\nVAR x : INT; END_VAR\n  IF x > 0 THEN\n    x := 1;\nEND_PROGRAM",
            "m.st:5:1: error[syntax]: END_IF expected to close the IF at 3:3, found 'END_PROGRAM'",
        ),
        (
            "FUNCTION_BLOCK FB\nVAR_INPUT\n  a : INT;\nIF a > 0 THEN\n  a := 0;\nEND_IF\nEND_FUNCTION_BLOCK",
            "m.st:4:1: error[syntax]: END_VAR expected to close the VAR_INPUT at 2:1, found 'IF'",
        ),
        (
            "PROGRAM P\nVAR x : INT; END_VAR\n  IF x > 0\n    x := 1;\n  END_IF\nEND_PROGRAM",
            "m.st:4:5: error[syntax]: THEN expected in the IF at 3:3, found 'x'",
        ),
        (
            "PROGRAM P\nVAR s : INT; END_VAR\nCASE s OF\n  1: s := 2;\nEND_PROGRAM",
            "m.st:5:1: error[syntax]: END_CASE expected to close the CASE at 3:1, found 'END_PROGRAM'",
        ),
        (
            "PROGRAM P\nVAR i, s : INT; END_VAR\nIF s = 0 THEN\n  FOR i := 1 TO 3 DO\n    s := s + i;\nEND_IF;\nEND_PROGRAM",
            "m.st:6:1: error[syntax]: END_FOR expected to close the FOR at 4:3, found 'END_IF'",
        ),
        (
            "PROGRAM P\nVAR i : INT; END_VAR\nREPEAT\n  i := i + 1;\nEND_PROGRAM",
            "m.st:5:1: error[syntax]: UNTIL expected to close the REPEAT at 3:1, found 'END_PROGRAM'",
        ),
        (
            "TYPE S : STRUCT\n  a : INT;\nEND_TYPE",
            "m.st:3:1: error[syntax]: END_STRUCT expected to close the STRUCT at 1:10, found 'END_TYPE'",
        ),
        (
            "FUNCTION_BLOCK FB\nVAR x : INT; END_VAR\nx := 1;\n",
            "m.st:4:1: error[syntax]: END_FUNCTION_BLOCK expected to close the FUNCTION_BLOCK at 1:1, found end of file",
        ),
        (
            "FUNCTION_BLOCK FB\nMETHOD M : INT\n  M := 1;\nEND_FUNCTION_BLOCK",
            "m.st:4:1: error[syntax]: END_METHOD expected to close the METHOD at 2:1, found 'END_FUNCTION_BLOCK'",
        ),
        (
            "PROGRAM P\nVAR x : INT; END_VAR\nx := 1\nEND_PROGRAM",
            "m.st:4:1: error[syntax]: ';' expected to end the statement at 3:1, found 'END_PROGRAM'",
        ),
        (
            "PROGRAM P\nVAR x : INT\nEND_VAR\nx := 1;\nEND_PROGRAM",
            "m.st:3:1: error[syntax]: ';' expected to end the declaration at 2:5, found 'END_VAR'",
        ),
        (
            "PROGRAM P\nVAR x INT; END_VAR\nEND_PROGRAM",
            "m.st:2:7: error[syntax]: ':' and a type expected after the name in the declaration at 2:5, found 'INT'",
        ),
        (
            "PROGRAM P\nVAR x : INT; END_VAR\nx := (1 + 2;\nEND_PROGRAM",
            "m.st:3:12: error[syntax]: ')' expected to close the '(' at 3:6, found ';'",
        ),
        (
            "PROGRAM P\nVAR x : INT; END_VAR\nx = 1;\nEND_PROGRAM",
            "m.st:3:3: error[syntax]: an assignment is written ':=', not '=' ('=' compares)",
        ),
        (
            "PROGRAM P\nVAR t : TON; END_VAR\nt(IN := TRUE, PT := 5);\nEND_PROGRAM",
            "m.st:3:21: error[wrong-argument]: argument 'PT' of TON: type mismatch: an integer literal value where TIME is expected (write a duration as T#5ms)",
        ),
    ];
    for (src, want) in cases {
        assert_eq!(error_of(src), want, "{src}");
    }
}

#[test]
fn unclosed_brackets_literals_and_configurations_say_where_they_open() {
    let cases = [
        (
            "PROGRAM P\nVAR a : ARRAY[1..3 OF INT; END_VAR\nEND_PROGRAM",
            "m.st:2:20: error[syntax]: ']' expected to close the '[' at 2:14, found 'OF'",
        ),
        (
            "PROGRAM P\nVAR s : STRING(10; END_VAR\nEND_PROGRAM",
            "m.st:2:18: error[syntax]: ')' expected to close the '(' at 2:15, found ';'",
        ),
        (
            "PROGRAM P\nVAR a : ARRAY[1..3] OF INT := [1, 2, 3; END_VAR\nEND_PROGRAM",
            "m.st:2:39: error[syntax]: ']' expected to close the '[' at 2:31, found ';'",
        ),
        (
            "TYPE E : (A, B;\nEND_TYPE",
            "m.st:1:15: error[syntax]: ')' expected to close the '(' at 1:10, found ';'",
        ),
        (
            "PROGRAM P\nVAR a : ARRAY[1..3] OF INT; END_VAR\na[1 := 2;\nEND_PROGRAM",
            "m.st:3:5: error[syntax]: ']' expected to close the '[' at 3:2, found ':='",
        ),
        (
            "PROGRAM P\nVAR t : TON; END_VAR\nt(IN := TRUE;\nEND_PROGRAM",
            "m.st:3:13: error[syntax]: ')' expected to close the '(' at 3:2, found ';'",
        ),
        (
            "PROGRAM P\nVAR x : INT;\nx := 1;\nEND_PROGRAM",
            "m.st:3:1: error[syntax]: END_VAR expected to close the VAR at 2:1, found 'x'",
        ),
        (
            "PROGRAM P\nVAR s : STRING := 'abc; END_VAR\nEND_PROGRAM",
            "m.st:2:19: error[syntax]: string literal is not closed: ' expected before the end of the line",
        ),
        (
            "CONFIGURATION C\nRESOURCE R ON PLC\nTASK t (INTERVAL := T#1ms);\nPROGRAM p WITH t : P;\nEND_CONFIGURATION\nPROGRAM P\nEND_PROGRAM",
            "m.st:5:1: error[syntax]: END_RESOURCE expected to close the RESOURCE at 2:1, found 'END_CONFIGURATION'",
        ),
        (
            "CONFIGURATION C\nVAR_GLOBAL x : INT; END_VAR\nPROGRAM P\nEND_PROGRAM",
            "m.st:3:1: error[syntax]: END_CONFIGURATION expected to close the CONFIGURATION at 1:1, found 'PROGRAM' (inside it, a program instance is `PROGRAM name WITH task : Type;`)",
        ),
        (
            "CONFIGURATION C\nTASK t (INTERVAL := T#1ms;\nPROGRAM p WITH t : P;\nEND_CONFIGURATION",
            "m.st:2:26: error[syntax]: ')' expected to close the '(' at 2:8, found ';'",
        ),
        (
            "PROGRAM P\nVAR x : INT; END_VAR\nx := 1;\nEND_IF\nEND_PROGRAM",
            "m.st:4:1: error[syntax]: END_IF without an open IF: remove it or add the IF it closes (the PROGRAM at 1:1 ends with END_PROGRAM)",
        ),
        (
            "FUNCTION_BLOCK F\nMETHOD M\nVAR x : INT; END_VAR\nx := 1; END_WHILE\nEND_METHOD\nEND_FUNCTION_BLOCK",
            "m.st:4:9: error[syntax]: END_WHILE without an open WHILE: remove it or add the WHILE it closes (the METHOD at 2:1 ends with END_METHOD)",
        ),
        (
            "PROGRAM P\nEND_PROGRAM\nEND_PROGRAM",
            "m.st:3:1: error[syntax]: END_PROGRAM closes nothing here: no block is open (a file holds TYPE, PROGRAM, FUNCTION, FUNCTION_BLOCK, INTERFACE, VAR_GLOBAL or CONFIGURATION blocks; is there one END_... too many?)",
        ),
    ];
    for (src, want) in cases {
        assert_eq!(error_of(src), want, "{src}");
    }
}

#[test]
fn semicolons_after_end_keywords_are_optional() {
    let mut rt = plc("PROGRAM P
VAR i, a, b : INT; END_VAR
IF a = 0 THEN a := 1; END_IF
IF b = 0 THEN b := 1; END_IF;
CASE a OF 1: a := 2; END_CASE
FOR i := 1 TO 2 DO b := b + 1; END_FOR;
WHILE b < 5 DO b := b + 1; END_WHILE
REPEAT b := b + 1; UNTIL b >= 6 END_REPEAT;
END_PROGRAM;");
    scan(&mut rt, 0);
    // a: 0 -> 1 -> 2; b: 0 -> 1 -> 3 -> 5 -> 6.
    assert_eq!((int(&rt, "a"), int(&rt, "b")), (2, 6));
}

#[test]
fn pragmas_are_skipped_and_comment_nesting_is_an_option() {
    let mut rt = plc("{attribute 'qualified_only'}
{IF defined (pou:Foo)} {{ nested braces }} {END_IF}
PROGRAM P
VAR x : INT; (* outer (* inner *) still comment *) END_VAR
{warning 'check this'}
x := 5;
END_PROGRAM");
    scan(&mut rt, 0);
    assert_eq!(int(&rt, "x"), 5);

    let src = "PROGRAM P VAR x : INT; END_VAR (* a (* b *) x := 7; END_PROGRAM";
    let err = compile(src, "c.st").expect_err("nested by default: the comment is open");
    assert!(
        err.to_string()
            .contains("comment is not closed: '*)' expected"),
        "{err}"
    );
    let flat = CompileOptions {
        nested_comments: false,
        ..CompileOptions::default()
    };
    let p = compile_sources(&[(src, "c.st")], &flat).expect("the comment ends at the first *)");
    let mut rt = Runtime::new(Arc::new(p));
    scan(&mut rt, 0);
    assert_eq!(int(&rt, "x"), 7);
}

const GVL: &str =
    "VAR_GLOBAL CONSTANT\n  N : INT := 4;\nEND_VAR\nVAR_GLOBAL\n  total : INT;\nEND_VAR\n";
const MAIN: &str = "PROGRAM Main\nVAR s : FB_Sum; END_VAR\ns(k := 3);\nEND_PROGRAM\n";

#[test]
fn a_program_of_several_files_with_a_global_constant_as_array_bound() {
    let fb = "FUNCTION_BLOCK FB_Sum
VAR_INPUT k : INT; END_VAR
VAR buf : ARRAY[1..N] OF INT; i : INT; END_VAR
FOR i := 1 TO N DO buf[i] := i * k; END_FOR
total := 0;
FOR i := 1 TO N DO total := total + buf[i]; END_FOR
END_FUNCTION_BLOCK
";
    let p = compile_sources(
        &[(GVL, "gvl.st"), (fb, "fb_sum.st"), (MAIN, "main.st")],
        &CompileOptions::default(),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let mut rt = Runtime::new(Arc::new(p));
    scan(&mut rt, 0);
    // 3 * (1 + 2 + 3 + 4)
    assert_eq!(int(&rt, "total"), 30);

    // An error names the file and the line in it.
    let bad = "FUNCTION_BLOCK FB_Sum\nVAR_INPUT k : INTT; END_VAR\nEND_FUNCTION_BLOCK\n";
    let err = compile_sources(
        &[(GVL, "gvl.st"), (bad, "fb_sum.st"), (MAIN, "main.st")],
        &CompileOptions::default(),
    )
    .expect_err("unknown type");
    let e = err.first().expect("an error");
    assert_eq!(
        (e.file.as_str(), e.pos.line, e.pos.col),
        ("fb_sum.st", 2, 15)
    );

    // So does a fault.
    let div = "FUNCTION_BLOCK FB_Sum\nVAR_INPUT k : INT; END_VAR\ntotal := N / (k - 3);\nEND_FUNCTION_BLOCK\n";
    let p = compile_sources(
        &[(GVL, "gvl.st"), (div, "fb_sum.st"), (MAIN, "main.st")],
        &CompileOptions::default(),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let mut rt = Runtime::new(Arc::new(p));
    let f = rt.scan(ms(0)).expect_err("division by zero");
    assert_eq!(
        (&*f.pou, f.line, f.kind),
        ("FB_Sum", 3, FaultKind::DivisionByZero)
    );
}

#[test]
fn named_constants_bound_arrays_in_functions_and_blocks() {
    let mut rt = plc("FUNCTION Sum3 : INT
VAR CONSTANT M : INT := 3; END_VAR
VAR a : ARRAY[1..M] OF INT := [1, 2, 3]; i : INT; END_VAR
FOR i := 1 TO M DO Sum3 := Sum3 + a[i]; END_FOR
END_FUNCTION
FUNCTION_BLOCK FB
VAR CONSTANT L : INT := 2; END_VAR
VAR_OUTPUT s : STRING[L + 1]; END_VAR
s := 'abcdef';
END_FUNCTION_BLOCK
PROGRAM P VAR x : INT; b : FB; t : STRING; END_VAR
x := Sum3();
b(s => t);
END_PROGRAM");
    scan(&mut rt, 0);
    assert_eq!(int(&rt, "x"), 6);
    assert_eq!(string(&rt, "t"), "abc"); // STRING[3] keeps three characters
}

const STATIONS: &str = "
INTERFACE I_Station
  METHOD Cycle : INT
    VAR_INPUT dt : INT; END_VAR
  END_METHOD
  PROPERTY Busy : BOOL
  END_PROPERTY
END_INTERFACE

FUNCTION_BLOCK FB_Base IMPLEMENTS I_Station
VAR
  work : INT;
  busy_ : BOOL;
END_VAR
METHOD Cycle : INT
VAR_INPUT dt : INT; END_VAR
  work := work + Step(dt);
  busy_ := THIS^.work < 10;
  Cycle := work;
END_METHOD
METHOD PROTECTED Step : INT
VAR_INPUT dt : INT; END_VAR
  Step := dt;
END_METHOD
PROPERTY Busy : BOOL
GET
  Busy := busy_;
END_GET
END_PROPERTY
PROPERTY Progress : INT
GET
  Progress := work;
END_GET
SET
  work := Progress;
END_SET
END_PROPERTY
END_FUNCTION_BLOCK

FUNCTION_BLOCK FB_Fast EXTENDS FB_Base
METHOD PROTECTED Step : INT
VAR_INPUT dt : INT; END_VAR
  Step := SUPER^.Step(dt) * 3;
END_METHOD
END_FUNCTION_BLOCK

FUNCTION Kick : INT
VAR_IN_OUT st : FB_Base; END_VAR
  Kick := st.Cycle(dt := 1);
END_FUNCTION
";

#[test]
fn methods_inheritance_interfaces_and_properties() {
    let src = format!(
        "{STATIONS}
PROGRAM Main
VAR
  slow : FB_Base;
  fast : FB_Fast;
  stations : ARRAY[1..2] OF I_Station;
  i, sum : INT;
  busy : ARRAY[1..2] OF BOOL;
END_VAR
stations[1] := slow;
stations[2] := fast;
sum := 0;
FOR i := 1 TO 2 DO
  sum := sum + stations[i].Cycle(dt := 2);
  busy[i] := stations[i].Busy;
END_FOR
END_PROGRAM"
    );
    let mut rt = plc(&src);
    // slow adds Step(2) = 2 per scan; fast inherits Cycle, whose Step call reaches the
    // override: SUPER^.Step(2) * 3 = 6 per scan. busy while work < 10.
    let want = [(8, true, true), (16, true, false), (24, true, false)];
    for (k, (sum, b1, b2)) in want.into_iter().enumerate() {
        scan(&mut rt, k as u64);
        assert_eq!(
            (
                int(&rt, "sum"),
                boolean(&rt, "busy[1]"),
                boolean(&rt, "busy[2]")
            ),
            (sum, b1, b2),
            "scan {k}"
        );
    }
    assert_eq!(int(&rt, "slow.work"), 6);
    assert_eq!(int(&rt, "fast.work"), 18);

    // A property written and read from outside; a derived instance through VAR_IN_OUT
    // of the base type still runs its own Step: 100 + 1 * 3.
    let src = format!(
        "{STATIONS}
PROGRAM Main
VAR fast : FB_Fast; w, k : INT; END_VAR
fast.Progress := 100;
k := Kick(fast);
w := fast.Progress;
END_PROGRAM"
    );
    let mut rt = plc(&src);
    scan(&mut rt, 0);
    assert_eq!((int(&rt, "k"), int(&rt, "w")), (103, 103));
}

#[test]
fn object_oriented_mistakes_are_refused_with_what_to_do() {
    let missing = "INTERFACE I_Run METHOD Run : BOOL END_METHOD END_INTERFACE
FUNCTION_BLOCK FB IMPLEMENTS I_Run
END_FUNCTION_BLOCK";
    assert_eq!(
        error_of(missing),
        "m.st:2:30: error[invalid]: 'FB' implements 'I_Run' but has no METHOD 'Run': add it"
    );
    let private = format!(
        "{STATIONS}\nPROGRAM P VAR b : FB_Base; x : INT; END_VAR\nx := b.Step(1);\nEND_PROGRAM"
    );
    assert!(
        error_of(&private).contains("'Step' is PRIVATE to 'FB_Base'"),
        "{}",
        error_of(&private)
    );
    let nosuper = "FUNCTION_BLOCK FB\nSUPER^();\nEND_FUNCTION_BLOCK";
    assert_eq!(
        error_of(nosuper),
        "m.st:2:1: error[invalid]: SUPER^ needs a base block: 'FB' has no EXTENDS"
    );
}

#[test]
fn method_var_inst_survives_between_calls() {
    let mut rt = plc("FUNCTION_BLOCK FB_Calls
METHOD Count : INT
VAR_INST n : INT; END_VAR
VAR tmp : INT; END_VAR
  n := n + 1;
  tmp := tmp + 1;
  Count := n * 10 + tmp;
END_METHOD
END_FUNCTION_BLOCK
PROGRAM Main VAR a, b : FB_Calls; x, y : INT; END_VAR
x := a.Count();
x := a.Count();
y := b.Count();
END_PROGRAM");
    // VAR_INST n counts per instance; the method's VAR starts afresh at every call.
    scan(&mut rt, 0);
    assert_eq!((int(&rt, "x"), int(&rt, "y")), (21, 11));
    scan(&mut rt, 1);
    assert_eq!((int(&rt, "x"), int(&rt, "y")), (41, 21));
}

#[test]
fn pointers_references_adr_and_sizeof() {
    let mut rt = plc("TYPE ST_Part : STRUCT id : INT; weight : REAL; END_STRUCT END_TYPE
FUNCTION_BLOCK FB_Inc
VAR_INPUT target : REFERENCE TO INT; END_VAR
target := target + 1;
END_FUNCTION_BLOCK
PROGRAM Main
VAR
  parts : ARRAY[1..3] OF ST_Part := [(id := 1, weight := 2.5), (id := 2, weight := 4.0), (id := 3, weight := 1.5)];
  p : POINTER TO ST_Part;
  heaviest : REFERENCE TO ST_Part;
  i : INT;
  total : REAL;
  ok, valid_before : BOOL;
  raw : POINTER TO INT;
  n : INT := 7;
  size : DINT;
  inc : FB_Inc;
  counter : INT;
END_VAR
valid_before := __ISVALIDREF(heaviest);
p := ADR(parts[1]);
total := 0;
heaviest REF= parts[1];
FOR i := 1 TO 3 DO
  total := total + p^.weight;
  IF p^.weight > heaviest.weight THEN
    heaviest REF= p^;
  END_IF
  p := p + SIZEOF(ST_Part);
END_FOR
heaviest.id := heaviest.id * 10;
raw := ADR(n);
raw^ := raw^ + 1;
size := SIZEOF(parts);
ok := __ISVALIDREF(heaviest);
inc(target := counter);
inc(target := counter);
END_PROGRAM");
    scan(&mut rt, 0);
    assert_eq!(real(&rt, "total"), 8.0); // 2.5 + 4.0 + 1.5
    assert_eq!(int(&rt, "parts[2].id"), 20); // the heaviest part, through the reference
    assert_eq!(int(&rt, "parts[1].id"), 1);
    assert_eq!(int(&rt, "n"), 8);
    // CODESYS's layout: id (INT) at 0, 2 bytes of padding, weight (REAL) at 4, so a
    // part takes 8 bytes and the array three of them.
    assert_eq!(int(&rt, "size"), 24);
    assert_eq!(
        (boolean(&rt, "valid_before"), boolean(&rt, "ok")),
        (false, true)
    );
    assert_eq!(int(&rt, "counter"), 2);
}

#[test]
fn a_null_pointer_or_interface_faults_the_plc() {
    let mut rt =
        plc("PROGRAM P\nVAR p : POINTER TO INT; x : INT; END_VAR\nx := 1;\nx := p^;\nEND_PROGRAM");
    let f = rt.scan(ms(0)).expect_err("null pointer");
    assert_eq!(
        (f.kind, f.line, f.code()),
        (FaultKind::NullReference, 4, "null-reference")
    );
    assert_eq!(int(&rt, "x"), 1); // the faulting assignment did not happen

    let src = format!(
        "{STATIONS}\nPROGRAM P\nVAR s : I_Station; x : INT; END_VAR\nx := s.Cycle(1);\nEND_PROGRAM"
    );
    let mut rt = plc(&src);
    let f = rt
        .scan(ms(0))
        .expect_err("no instance behind the interface");
    assert_eq!(f.kind, FaultKind::NullReference);
}

#[test]
fn en_and_eno_gate_a_call() {
    let mut rt = plc("PROGRAM P
VAR run, eno : BOOL; c : CTU; n : INT; END_VAR
c(EN := run, CU := TRUE, PV := 5, CV => n, ENO => eno);
END_PROGRAM");
    // (run, n, eno): the block only counts on the scans it runs; CU is TRUE each time, so
    // only its first execution sees a rising edge.
    for (k, (run, n, eno)) in [
        (false, 0, false),
        (true, 1, true),
        (false, 1, false),
        (true, 1, true),
    ]
    .into_iter()
    .enumerate()
    {
        set(&mut rt, "run", Value::Bool(run));
        scan(&mut rt, k as u64);
        assert_eq!((int(&rt, "n"), boolean(&rt, "eno")), (n, eno), "scan {k}");
    }
}

#[test]
fn en_and_eno_gate_a_call_inside_an_expression() {
    let mut rt = plc("FUNCTION Twice : INT
VAR_INPUT x : INT; END_VAR
VAR_IN_OUT calls : INT; END_VAR
calls := calls + 1;
Twice := 2 * x;
END_FUNCTION
PROGRAM P
VAR
  run : BOOL;
  a : INT := 7;
  calls, y, z : INT;
  ok, not_ok : BOOL;
  flags : WORD;
END_VAR
y := 100 + Twice(EN := run, x := a, calls := calls, ENO => ok);
z := ADD(EN := run AND a > 5, IN1 := a, IN2 := 3, NOT ENO => not_ok) * 2;
flags := 0;
flags.2 := FALSE;
a := a + 0 * MUL(EN := run, a, 1, ENO => flags.2);
END_PROGRAM");
    // Scan 0, run FALSE: Twice does not run (calls stays 0) and gives 0, so y = 100; ENO
    // FALSE; ADD does not run: z = 0 * 2 = 0, NOT ENO => TRUE; flags.2 FALSE.
    scan(&mut rt, 0);
    assert_eq!(
        (int(&rt, "y"), int(&rt, "calls"), boolean(&rt, "ok")),
        (100, 0, false)
    );
    assert_eq!((int(&rt, "z"), boolean(&rt, "not_ok")), (0, true));
    assert_eq!(uint(&rt, "flags"), 0);
    // Scan 1, run TRUE: y = 100 + 2 * 7 = 114, calls 1, ENO TRUE; z = (7 + 3) * 2 = 20,
    // NOT ENO => FALSE; flags = 2#100 = 4.
    set(&mut rt, "run", Value::Bool(true));
    scan(&mut rt, 1);
    assert_eq!(
        (int(&rt, "y"), int(&rt, "calls"), boolean(&rt, "ok")),
        (114, 1, true)
    );
    assert_eq!((int(&rt, "z"), boolean(&rt, "not_ok")), (20, false));
    assert_eq!(uint(&rt, "flags"), 4);
}

#[test]
fn en_inside_an_expression_is_refused_where_the_result_is_not_elementary() {
    let err = compile(
        "PROGRAM P VAR s : STRING; run : BOOL; END_VAR
s := CONCAT(EN := run, 'a', 'b');
END_PROGRAM",
        "en.st",
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("en.st:2:6: error[wrong-argument]: EN/ENO inside an expression needs a function with an elementary result"),
        "{err}"
    );
}

#[test]
fn a_state_machine_on_a_qualified_enumeration_with_values_and_base_type() {
    let mut rt = plc("{attribute 'qualified_only'}
{attribute 'strict'}
TYPE E_Step : (Idle := 0, Fill := 10, Heat := 20, Drain := 30) UINT; END_TYPE
PROGRAM Main
VAR
  step : E_Step;
  start : BOOL;
  level : INT;
  heat : TON;
  cycles : INT;
END_VAR
CASE step OF
  E_Step.Idle:
    IF start THEN step := E_Step.Fill; END_IF
  E_Step.Fill:
    level := level + 25;
    IF level >= 100 THEN step := E_Step.Heat; END_IF
  E_Step.Heat:
    heat(IN := TRUE, PT := T#8ms);
    IF heat.Q THEN heat(IN := FALSE); step := E_Step.Drain; END_IF
  E_Step.Drain:
    level := level - 50;
    IF level <= 0 THEN cycles := cycles + 1; step := E_Step.Idle; END_IF
END_CASE
END_PROGRAM");
    set(&mut rt, "start", Value::Bool(true));
    // 4 ms scans. Scan 0: Idle -> Fill. Scans 1-4: level 25..100 -> Heat at scan 4.
    // Scan 5: timer starts (t = 20 ms); Q at t >= 28 ms: scan 7 -> Drain.
    // Scans 8, 9: level 50, 0 -> Idle with one cycle done.
    let want = [10, 10, 10, 10, 20, 20, 20, 30, 30, 0];
    for (k, step) in want.into_iter().enumerate() {
        scan(&mut rt, k as u64);
        assert_eq!(int(&rt, "step"), step, "scan {k}");
    }
    assert_eq!(int(&rt, "cycles"), 1);
}

#[test]
fn dates_and_times_of_day() {
    let mut rt = plc("PROGRAM P
VAR
  d : DATE := D#2024-02-28;
  start : TOD := TOD#23:30:00;
  stamp : DT;
  later : TOD;
  shift, gap : TIME;
  dow, dow2 : INT;
  leap : DATE;
  secs : UDINT;
  ms : UDINT;
  text, text2 : STRING;
  back : DT;
  before : BOOL;
END_VAR
stamp := CONCAT_DATE_TOD(d, start);
later := start + T#45m;                      (* wraps past midnight *)
shift := SUB_TOD_TOD(TOD#06:00:00, TOD#22:00:00) + T#24h;
gap := DT#2024-03-01-00:00:00 - stamp;
dow := DAY_OF_WEEK(d);
leap := CONCAT_DATE(2024, 2, 29);
dow2 := DAY_OF_WEEK(leap);
secs := DATE_TO_UDINT(D#1970-01-02);
ms := TOD_TO_UDINT(TOD#00:00:01.5);
text := DT_TO_STRING(ADD_DT_TIME(stamp, T#1h15m30s250ms));
back := STRING_TO_DT(text);
text2 := TOD_TO_STRING(DT_TO_TOD(back));
before := DT_TO_DATE(back) > d;
END_PROGRAM");
    scan(&mut rt, 0);
    // 2024-02-28 23:30 + 1 h 15 min 30.25 s = 2024-02-29 00:45:30.25 (a leap year).
    assert_eq!(string(&rt, "text"), "DT#2024-02-29-00:45:30.25");
    assert_eq!(string(&rt, "text2"), "TOD#00:45:30.25");
    assert!(boolean(&rt, "before"));
    assert_eq!(get(&rt, "later"), get(&plc_tod("00:15:00"), "t"));
    assert_eq!(time_ms(&rt, "shift"), 8.0 * 3_600_000.0); // 22:00 to 06:00
    // From 2024-02-28 23:30 to 2024-03-01 00:00: 24 h 30 min.
    assert_eq!(time_ms(&rt, "gap"), 24.5 * 3_600_000.0);
    // 2024-02-28 was a Wednesday (3; 0 is Sunday), the 29th a Thursday.
    assert_eq!((int(&rt, "dow"), int(&rt, "dow2")), (3, 4));
    assert_eq!(uint(&rt, "secs"), 86_400);
    assert_eq!(uint(&rt, "ms"), 1_500);

    let err = error_of("PROGRAM P VAR d : DATE := D#2023-02-29; END_VAR END_PROGRAM");
    assert!(
        err.contains("not a valid D# literal: write D#yyyy-mm-dd"),
        "{err}"
    );
    let err = error_of("PROGRAM P VAR d : DATE; e : DATE; END_VAR d := d + e; END_PROGRAM");
    assert!(
        err.contains("operator ADD does not apply to DATE and DATE"),
        "{err}"
    );
}

fn plc_tod(t: &str) -> Runtime {
    let mut rt = plc(&format!(
        "PROGRAM Q VAR t : TOD := TOD#{t}; END_VAR END_PROGRAM"
    ));
    scan(&mut rt, 0);
    rt
}

#[test]
fn counters_take_word_preset_and_count_as_codesys_declares_them() {
    let mut rt = plc("PROGRAM P
VAR
  pulse : BOOL;
  limit : WORD := 2;
  up : CTU; down : CTD;
  count : WORD;
  left : UINT;
  full : BOOL;
END_VAR
up(CU := pulse, PV := limit, Q => full, CV => count);
down(CD := pulse, PV := limit, CV => left);
END_PROGRAM");
    // down starts at 0 (never loaded): three rising edges take it to -3, which a UINT
    // shows as 65536 - 3; up reaches its WORD preset of 2 on the second edge.
    for k in 0..6u64 {
        set(&mut rt, "pulse", Value::Bool(k % 2 == 0));
        scan(&mut rt, k);
    }
    assert_eq!((uint(&rt, "count"), boolean(&rt, "full")), (3, true));
    assert_eq!(uint(&rt, "left"), 65_533);
}

#[test]
fn extreme_dates_convert_without_overflow() {
    // A DATE_AND_TIME far outside the calendar (from the most negative TIME) still
    // converts and prints.
    let mut rt = plc("PROGRAM P
VAR tm : TIME := T#-106751d23h47m16s854ms775us807ns; t : DT; d : DATE; s : STRING; tod : TOD; END_VAR
t := TIME_TO_DT(tm);
d := DT_TO_DATE(t);
tod := DT_TO_TOD(t);
s := DT_TO_STRING(t);
END_PROGRAM");
    scan(&mut rt, 0);
    assert!(string(&rt, "s").starts_with("DT#"));
}

/// The same source compiles to the same program every time: the compiler kept its methods
/// in a map whose order changed from run to run, and with it the numbering of the calls'
/// temporaries.
#[test]
fn a_program_with_methods_compiles_the_same_every_time() {
    let mut source = String::from("FUNCTION_BLOCK FB\nVAR x : INT; t : TON; END_VAR\n");
    for m in 0..8 {
        // Each method calls the next (the last none): calls with temporaries in every body.
        let next = if m < 7 {
            format!(" + THIS^.M{}(a := {m})", m + 1)
        } else {
            String::new()
        };
        source.push_str(&format!(
            "METHOD M{m} : INT\nVAR_INPUT a : INT; END_VAR\n  t(IN := a > {m}, PT := T#{m}ms);\n  M{m} := LIMIT(0, a + x, {m}){next};\nEND_METHOD\n"
        ));
    }
    source.push_str("END_FUNCTION_BLOCK\nPROGRAM P\nVAR f : FB; y : INT; END_VAR\ny := f.M0(a := 3);\nEND_PROGRAM\n");
    let first = format!("{:?}", compile(&source, "m.st").expect("compiles"));
    for _ in 0..20 {
        assert_eq!(format!("{:?}", compile(&source, "m.st").unwrap()), first);
    }
}
