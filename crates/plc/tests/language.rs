//! Semantics of statements, operators, conversions and standard functions. Expected values
//! are worked out by hand from IEC 61131-3 (3rd edition) rules.

use crate::common::*;
use rtcnc_plc::Value;

#[test]
fn integer_arithmetic_wraps_in_the_type_width() {
    let rt = eval(
        "a : INT := 32767; b : INT; c : SINT := -128; d : SINT; u : USINT := 250; w : USINT;
         q : DINT; r : DINT; m : DINT; n : DINT;",
        "b := a + 1; d := -c; w := u + 10; q := 7 / 2; r := -7 / 2; m := 7 MOD 3; n := -7 MOD 3;",
    );
    assert_eq!(int(&rt, "b"), -32768);
    assert_eq!(int(&rt, "d"), -128);
    assert_eq!(uint(&rt, "w"), 4);
    // Integer division truncates toward zero; MOD takes the sign of the dividend.
    assert_eq!(int(&rt, "q"), 3);
    assert_eq!(int(&rt, "r"), -3);
    assert_eq!(int(&rt, "m"), 1);
    assert_eq!(int(&rt, "n"), -1);
}

#[test]
fn operator_precedence_follows_the_standard() {
    let rt = eval(
        "a : DINT; b : DINT; c : BOOL; d : BOOL; e : LREAL; f : DINT;",
        "a := 2 + 3 * 4; b := (2 + 3) * 4; c := 1 < 2 AND 3 > 2; d := TRUE OR FALSE AND FALSE;
         e := 2.0 ** 3.0 ** 2.0; f := 10 - 4 - 3;",
    );
    assert_eq!(int(&rt, "a"), 14);
    assert_eq!(int(&rt, "b"), 20);
    assert!(boolean(&rt, "c"));
    // AND binds tighter than OR.
    assert!(boolean(&rt, "d"));
    // ** is left-associative: (2**3)**2 = 64.
    assert_eq!(real(&rt, "e"), 64.0);
    assert_eq!(int(&rt, "f"), 3);
}

#[test]
fn real_is_single_precision_and_lreal_double() {
    let rt = eval(
        "a : REAL; b : LREAL; c : REAL := 1.0; d : REAL;",
        "a := 0.1; b := 0.1; d := c / 3.0;",
    );
    assert_eq!(real(&rt, "a"), 0.1f32 as f64);
    assert_eq!(real(&rt, "b"), 0.1);
    assert_eq!(real(&rt, "d"), (1.0f32 / 3.0f32) as f64);
}

#[test]
fn boolean_and_bit_string_operators() {
    let rt = eval(
        "a : BOOL := TRUE; b : BOOL; x : BOOL; w : WORD := 16#00FF; v : WORD; y : BYTE := 2#1010_0101; z : BYTE; n : WORD;",
        "b := NOT a; x := a XOR TRUE; v := w AND 16#0F0F OR 16#F000; z := NOT y; n := w XOR 16#FFFF;",
    );
    assert!(!boolean(&rt, "b"));
    assert!(!boolean(&rt, "x"));
    assert_eq!(uint(&rt, "v"), 0xF00F);
    assert_eq!(uint(&rt, "z"), 0b0101_1010);
    assert_eq!(uint(&rt, "n"), 0xFF00);
}

#[test]
fn comparisons_of_every_kind() {
    let rt = eval(
        "s1 : STRING := 'abc'; s2 : STRING := 'abd'; t1 : TIME := T#1s; u : UDINT := 4000000000;
         a : BOOL; b : BOOL; c : BOOL; d : BOOL; e : BOOL; f : BOOL;",
        "a := s1 < s2; b := s1 = 'abc'; c := t1 >= T#1000ms; d := u > 1; e := 1.5 <> 1.5; f := s1 <> s2;",
    );
    assert!(boolean(&rt, "a"));
    assert!(boolean(&rt, "b"));
    assert!(boolean(&rt, "c"));
    // UDINT 4e9 compares unsigned.
    assert!(boolean(&rt, "d"));
    assert!(!boolean(&rt, "e"));
    assert!(boolean(&rt, "f"));
}

#[test]
fn if_elsif_else_picks_the_first_true_branch() {
    let rt = eval(
        "x : INT := 5; r1 : INT; r2 : INT; r3 : INT;",
        "IF x > 10 THEN r1 := 1; ELSIF x > 3 THEN r1 := 2; ELSIF x > 0 THEN r1 := 3; ELSE r1 := 4; END_IF;
         IF x < 0 THEN r2 := 1; ELSE r2 := 9; END_IF;
         IF x = 5 THEN r3 := 7; END_IF;",
    );
    assert_eq!(int(&rt, "r1"), 2);
    assert_eq!(int(&rt, "r2"), 9);
    assert_eq!(int(&rt, "r3"), 7);
}

#[test]
fn case_with_lists_ranges_enums_and_else() {
    let src = "TYPE Mode : (IDLE, RUN, STOPPING); END_TYPE
        PROGRAM P VAR x : INT; r : INT; m : Mode := RUN; s : INT; END_VAR
        CASE x OF
          1, 2: r := 10;
          3..5, 9: r := 20;
          -3..-1: r := 30;
        ELSE r := 99;
        END_CASE;
        CASE m OF IDLE: s := 1; RUN: s := 2; STOPPING: s := 3; END_CASE;
        END_PROGRAM";
    for (x, want) in [
        (1, 10),
        (2, 10),
        (4, 20),
        (9, 20),
        (-2, 30),
        (6, 99),
        (0, 99),
    ] {
        let mut rt = plc(src);
        set(&mut rt, "x", Value::Int(x));
        rt.scan(ms(0)).unwrap();
        assert_eq!(int(&rt, "r"), want, "x = {x}");
        assert_eq!(int(&rt, "s"), 2);
    }
}

#[test]
fn for_loops_count_including_the_end_value() {
    let rt = eval(
        "i : INT; s : DINT; t : DINT; n : INT; k : SINT; c : INT;",
        "FOR i := 1 TO 10 DO s := s + i; END_FOR;
         FOR i := 10 TO 1 BY -3 DO t := t * 10 + i; END_FOR;
         FOR i := 5 TO 1 DO n := n + 1; END_FOR;
         FOR k := 120 TO 127 DO c := c + 1; END_FOR;",
    );
    assert_eq!(int(&rt, "s"), 55);
    // 10, 7, 4, 1
    assert_eq!(int(&rt, "t"), 10_741);
    assert_eq!(int(&rt, "n"), 0);
    // The loop up to the type's maximum ends (no wrap-around into an endless loop).
    assert_eq!(int(&rt, "c"), 8);
    // The control variable is set to the start value before the first test, even when
    // the body never runs.
    assert_eq!(int(&rt, "i"), 5);
    // After the loop it holds the value that failed the test: 127 + 1 wrapped to SINT.
    assert_eq!(int(&rt, "k"), -128);
}

#[test]
fn while_repeat_exit_continue() {
    let rt = eval(
        "n : INT := 1; r : INT; i : INT; odd : INT; w : INT;",
        "WHILE n < 100 DO n := n * 3; END_WHILE;
         REPEAT r := r + 1; UNTIL r >= 5 END_REPEAT;
         FOR i := 1 TO 10 DO IF i MOD 2 = 0 THEN CONTINUE; END_IF; odd := odd + i; END_FOR;
         WHILE TRUE DO w := w + 1; IF w = 4 THEN EXIT; END_IF; END_WHILE;",
    );
    assert_eq!(int(&rt, "n"), 243);
    assert_eq!(int(&rt, "r"), 5);
    assert_eq!(int(&rt, "odd"), 25);
    assert_eq!(int(&rt, "w"), 4);
}

#[test]
fn repeat_runs_its_body_at_least_once() {
    let rt = eval("r : INT;", "REPEAT r := r + 1; UNTIL TRUE END_REPEAT;");
    assert_eq!(int(&rt, "r"), 1);
}

#[test]
fn exit_leaves_only_the_innermost_loop() {
    let rt = eval(
        "i : INT; j : INT; n : INT;",
        "FOR i := 1 TO 3 DO FOR j := 1 TO 3 DO IF j = 2 THEN EXIT; END_IF; n := n + 1; END_FOR; END_FOR;",
    );
    assert_eq!(int(&rt, "n"), 3);
}

#[test]
fn return_leaves_the_program_body() {
    let rt = eval(
        "a : INT; b : INT;",
        "a := 1; IF a = 1 THEN RETURN; END_IF; b := 2;",
    );
    assert_eq!(int(&rt, "a"), 1);
    assert_eq!(int(&rt, "b"), 0);
}

#[test]
fn implicit_widening_is_accepted() {
    let rt = eval(
        "s : SINT := -5; i : INT; d : DINT; l : LINT; r : REAL; lr : LREAL; us : USINT := 200; ui : UINT; b : BYTE := 16#AB; w : WORD; dw : DWORD;",
        "i := s; d := i; l := d; r := i; lr := r; ui := us; i := us; w := b; dw := w;",
    );
    assert_eq!(int(&rt, "d"), -5);
    assert_eq!(int(&rt, "l"), -5);
    assert_eq!(real(&rt, "r"), -5.0);
    assert_eq!(real(&rt, "lr"), -5.0);
    assert_eq!(uint(&rt, "ui"), 200);
    assert_eq!(int(&rt, "i"), 200);
    assert_eq!(uint(&rt, "dw"), 0xAB);
}

#[test]
fn explicit_conversions() {
    let rt = eval(
        "a : INT; b : INT; c : INT; d : INT; e : DINT; f : BOOL; g : INT; h : REAL; i : USINT; j : SINT; k : DINT; l : DINT;
         t : TIME; m : DINT; n : WORD; o : INT; p : BYTE; q : INT; r : WORD; s : LREAL;",
        "a := REAL_TO_INT(2.5); b := REAL_TO_INT(3.5); c := REAL_TO_INT(-2.5); d := REAL_TO_INT(1.4);
         e := TRUNC(-3.7); f := INT_TO_BOOL(7); g := BOOL_TO_INT(TRUE); h := DINT_TO_REAL(16777217);
         i := INT_TO_USINT(300); j := INT_TO_SINT(200); k := TIME_TO_DINT(T#1s500ms); l := REAL_TRUNC_DINT(9.99);
         t := DINT_TO_TIME(250); m := WORD_TO_DINT(16#FFFF); n := INT_TO_WORD(-1); o := WORD_TO_INT(16#8000);
         p := USINT_TO_BCD_BYTE(42); q := BYTE_BCD_TO_INT(16#59); r := TO_WORD(300); s := TO_LREAL(3);",
    );
    // REAL -> integer rounds half to even (IEC 60559).
    assert_eq!(int(&rt, "a"), 2);
    assert_eq!(int(&rt, "b"), 4);
    assert_eq!(int(&rt, "c"), -2);
    assert_eq!(int(&rt, "d"), 1);
    assert_eq!(int(&rt, "e"), -3);
    assert!(boolean(&rt, "f"));
    assert_eq!(int(&rt, "g"), 1);
    // 16777217 is not representable in f32: nearest is 16777216.
    assert_eq!(real(&rt, "h"), 16_777_216.0);
    // Narrowing keeps the low bits.
    assert_eq!(uint(&rt, "i"), 44);
    assert_eq!(int(&rt, "j"), -56);
    // TIME converts through milliseconds.
    assert_eq!(int(&rt, "k"), 1500);
    assert_eq!(int(&rt, "l"), 9);
    assert_eq!(time_ms(&rt, "t"), 250.0);
    assert_eq!(int(&rt, "m"), 65535);
    assert_eq!(uint(&rt, "n"), 0xFFFF);
    assert_eq!(int(&rt, "o"), -32768);
    assert_eq!(uint(&rt, "p"), 0x42);
    assert_eq!(int(&rt, "q"), 59);
    assert_eq!(uint(&rt, "r"), 300);
    assert_eq!(real(&rt, "s"), 3.0);
}

#[test]
fn string_conversions() {
    let rt = eval(
        "a : STRING; b : STRING; c : STRING; d : INT; e : REAL; f : BOOL; g : STRING; h : STRING;",
        "a := INT_TO_STRING(-42); b := BOOL_TO_STRING(TRUE); c := TIME_TO_STRING(T#1m2s3ms);
         d := STRING_TO_INT('  123 '); e := STRING_TO_REAL('2.5'); f := STRING_TO_BOOL('TRUE'); g := LREAL_TO_STRING(0.25);
         h := UDINT_TO_STRING(4000000000);",
    );
    assert_eq!(string(&rt, "a"), "-42");
    assert_eq!(string(&rt, "b"), "TRUE");
    assert_eq!(string(&rt, "c"), "T#1m2s3ms");
    assert_eq!(int(&rt, "d"), 123);
    assert_eq!(real(&rt, "e"), 2.5);
    assert!(boolean(&rt, "f"));
    assert_eq!(string(&rt, "g"), "0.25");
    assert_eq!(string(&rt, "h"), "4000000000");
}

#[test]
fn numeric_functions() {
    let rt = eval(
        "a : INT; b : REAL; c : LREAL; d : LREAL; e : LREAL; f : LREAL; g : LREAL; h : LREAL; i : LREAL; j : LREAL; k : LREAL; l : LREAL; m : LREAL; n : DINT; o : DINT;",
        "a := ABS(-7); b := ABS(-2.5); c := SQRT(16.0); d := LN(1.0); e := LOG(1000.0); f := EXP(0.0);
         g := SIN(0.0); h := COS(0.0); i := TAN(0.0); j := ASIN(1.0); k := ACOS(1.0); l := ATAN(1.0); m := EXPT(2.0, 10);
         n := ADD(1, 2, 3, 4); o := MUL(2, 3, 4);",
    );
    assert_eq!(int(&rt, "a"), 7);
    assert_eq!(real(&rt, "b"), 2.5);
    assert_eq!(real(&rt, "c"), 4.0);
    assert_eq!(real(&rt, "d"), 0.0);
    assert_eq!(real(&rt, "e"), 3.0);
    assert_eq!(real(&rt, "f"), 1.0);
    assert_eq!(real(&rt, "g"), 0.0);
    assert_eq!(real(&rt, "h"), 1.0);
    assert_eq!(real(&rt, "i"), 0.0);
    assert_eq!(real(&rt, "j"), std::f64::consts::FRAC_PI_2);
    assert_eq!(real(&rt, "k"), 0.0);
    assert_eq!(real(&rt, "l"), std::f64::consts::FRAC_PI_4);
    assert_eq!(real(&rt, "m"), 1024.0);
    assert_eq!(int(&rt, "n"), 10);
    assert_eq!(int(&rt, "o"), 24);
}

#[test]
fn bit_shift_and_rotate() {
    let rt = eval(
        "a : BYTE; b : BYTE; c : BYTE; d : BYTE; e : WORD; f : DWORD;",
        "a := SHL(BYTE#2#1000_0001, 1); b := SHR(BYTE#2#1000_0001, 1); c := ROL(BYTE#2#1000_0001, 1); d := ROR(BYTE#2#1000_0001, 1);
         e := ROL(WORD#16#8001, 4); f := SHL(DWORD#1, 31);",
    );
    assert_eq!(uint(&rt, "a"), 0b0000_0010);
    assert_eq!(uint(&rt, "b"), 0b0100_0000);
    assert_eq!(uint(&rt, "c"), 0b0000_0011);
    assert_eq!(uint(&rt, "d"), 0b1100_0000);
    assert_eq!(uint(&rt, "e"), 0x0018);
    assert_eq!(uint(&rt, "f"), 0x8000_0000);
}

#[test]
fn selection_functions() {
    let rt = eval(
        "a : INT; b : INT; c : INT; d : REAL; e : INT; f : INT; g : TIME; h : INT; i : STRING;",
        "a := SEL(FALSE, 10, 20); b := SEL(TRUE, 10, 20); c := MAX(3, 9, -2); d := MIN(2.5, -1.5);
         e := LIMIT(0, 150, 100); f := LIMIT(0, -5, 100); g := MAX(T#1s, T#2s); h := MUX(2, 10, 20, 30); i := SEL(TRUE, 'no', 'yes');",
    );
    assert_eq!(int(&rt, "a"), 10);
    assert_eq!(int(&rt, "b"), 20);
    assert_eq!(int(&rt, "c"), 9);
    assert_eq!(real(&rt, "d"), -1.5);
    assert_eq!(int(&rt, "e"), 100);
    assert_eq!(int(&rt, "f"), 0);
    assert_eq!(time_ms(&rt, "g"), 2000.0);
    assert_eq!(int(&rt, "h"), 30);
    assert_eq!(string(&rt, "i"), "yes");
}

#[test]
fn formal_arguments_of_standard_functions() {
    let rt = eval(
        "a : INT; b : INT;",
        "a := LIMIT(MN := 0, IN := 500, MX := 100); b := LIMIT(IN := -5, MX := 100, MN := 1);",
    );
    assert_eq!(int(&rt, "a"), 100);
    assert_eq!(int(&rt, "b"), 1);
}

#[test]
fn comparison_functions() {
    let rt = eval(
        "a : BOOL; b : BOOL; c : BOOL; d : BOOL; e : BOOL; f : BOOL;",
        "a := GT(3, 2); b := GE(2, 2); c := EQ(1, 2); d := LE(1, 2); e := LT(2, 1); f := NE(1, 2);",
    );
    assert_eq!(
        [
            boolean(&rt, "a"),
            boolean(&rt, "b"),
            boolean(&rt, "c"),
            boolean(&rt, "d"),
            boolean(&rt, "e"),
            boolean(&rt, "f")
        ],
        [true, true, false, true, false, true]
    );
}

#[test]
fn string_functions() {
    let rt = eval(
        "s : STRING := 'Hello World'; n : INT; l : STRING; r : STRING; m : STRING; c : STRING; i : STRING; d : STRING; p : STRING; f : INT; g : INT; short : STRING[4];",
        "n := LEN(s); l := LEFT(s, 5); r := RIGHT(s, 5); m := MID(s, 3, 2); c := CONCAT('a', 'b', 'c');
         i := INSERT('abef', 'cd', 2); d := DELETE('abcdef', 2, 3); p := REPLACE('abcdef', 'XY', 3, 2);
         f := FIND(s, 'World'); g := FIND(s, 'xyz'); short := s;",
    );
    assert_eq!(int(&rt, "n"), 11);
    assert_eq!(string(&rt, "l"), "Hello");
    assert_eq!(string(&rt, "r"), "World");
    assert_eq!(string(&rt, "m"), "ell");
    assert_eq!(string(&rt, "c"), "abc");
    assert_eq!(string(&rt, "i"), "abcdef");
    // DELETE(IN, L := 2, P := 3) removes 'cd'.
    assert_eq!(string(&rt, "d"), "abef");
    assert_eq!(string(&rt, "p"), "aXYef");
    assert_eq!(f_or(&rt, "f"), 7);
    assert_eq!(int(&rt, "g"), 0);
    // Assignment to a shorter STRING keeps the first characters.
    assert_eq!(string(&rt, "short"), "Hell");
}

fn f_or(rt: &rtcnc_plc::Runtime, n: &str) -> i64 {
    int(rt, n)
}

#[test]
fn string_escapes() {
    let rt = eval("s : STRING; n : INT;", "s := 'it$'s $$5$N'; n := LEN(s);");
    assert_eq!(string(&rt, "s"), "it's $5\n");
    assert_eq!(int(&rt, "n"), 8);
}

#[test]
fn time_literals_and_arithmetic() {
    let rt = eval(
        "a : TIME := T#1d2h3m4s5ms; b : TIME := TIME#1.5s; c : TIME; d : TIME; e : TIME; f : TIME := t#-250ms; g : TIME;",
        "c := b + T#500ms; d := b * 2; e := b / 3; g := T#1s - T#1500ms;",
    );
    let day = 86_400_000.0;
    assert_eq!(
        time_ms(&rt, "a"),
        day + 2.0 * 3_600_000.0 + 3.0 * 60_000.0 + 4_000.0 + 5.0
    );
    assert_eq!(time_ms(&rt, "b"), 1500.0);
    assert_eq!(time_ms(&rt, "c"), 2000.0);
    assert_eq!(time_ms(&rt, "d"), 3000.0);
    assert_eq!(time_ms(&rt, "e"), 500.0);
    assert_eq!(time_ms(&rt, "f"), -250.0);
    assert_eq!(time_ms(&rt, "g"), -500.0);
}

#[test]
fn integer_literals_in_every_radix() {
    let rt = eval(
        "a : DINT; b : DINT; c : DINT; d : DINT; e : LWORD;",
        "a := 16#FF; b := 8#17; c := 2#1010; d := 1_000_000; e := 16#FFFF_FFFF_FFFF_FFFF;",
    );
    assert_eq!(int(&rt, "a"), 255);
    assert_eq!(int(&rt, "b"), 15);
    assert_eq!(int(&rt, "c"), 10);
    assert_eq!(int(&rt, "d"), 1_000_000);
    assert_eq!(uint(&rt, "e"), u64::MAX);
}

#[test]
fn arrays_multi_dimensional_and_initialised() {
    let rt = eval(
        "a : ARRAY[1..5] OF INT := [10, 20, 3(7)]; m : ARRAY[0..1, 1..3] OF DINT; i : INT; j : INT; s : DINT; x : INT;",
        "FOR i := 0 TO 1 DO FOR j := 1 TO 3 DO m[i, j] := i * 10 + j; END_FOR; END_FOR;
         s := m[1, 3] * 100 + m[0, 2]; i := 2; x := a[i] + a[5];",
    );
    assert_eq!(int(&rt, "s"), 1302);
    assert_eq!(int(&rt, "x"), 27);
    assert_eq!(int(&rt, "a[3]"), 7);
    assert_eq!(int(&rt, "m[1,1]"), 11);
}

#[test]
fn structs_nested_with_initial_values_and_whole_assignment() {
    let src = "TYPE Axis : STRUCT pos : LREAL := 1.5; homed : BOOL; limits : ARRAY[0..1] OF LREAL := [-100.0, 100.0]; END_STRUCT;
                Machine : STRUCT x : Axis; y : Axis := (pos := 2.5, homed := TRUE); END_STRUCT; END_TYPE
        PROGRAM P VAR m : Machine; copy : Axis; a : ARRAY[1..3] OF Axis; k : INT := 2; END_VAR
        m.x.homed := TRUE; copy := m.y; a[k].pos := 9.0; a[k].limits[1] := 42.0;
        END_PROGRAM";
    let mut rt = plc(src);
    rt.scan(ms(0)).unwrap();
    assert_eq!(real(&rt, "m.x.pos"), 1.5);
    assert!(boolean(&rt, "m.x.homed"));
    assert_eq!(real(&rt, "copy.pos"), 2.5);
    assert!(boolean(&rt, "copy.homed"));
    assert_eq!(real(&rt, "copy.limits[0]"), -100.0);
    assert_eq!(real(&rt, "a[2].pos"), 9.0);
    assert_eq!(real(&rt, "a[2].limits[1]"), 42.0);
    assert_eq!(real(&rt, "a[1].pos"), 1.5);
}

#[test]
fn enumerations_and_subranges() {
    let src = "TYPE Color : (RED, GREEN := 5, BLUE); Pct : INT (0..100) := 50; Level : (LOW, HIGH); END_TYPE
        PROGRAM P VAR c : Color; d : Color := Color#BLUE; p : Pct; q : INT(10..20); r : SINT(-5..5); same : BOOL; v : DINT; lvl : Level := HIGH; END_VAR
        c := GREEN; same := c = Color#GREEN; v := TO_DINT(d);
        END_PROGRAM";
    let mut rt = plc(src);
    rt.scan(ms(0)).unwrap();
    assert_eq!(rt.format(&rt.resolve("c").unwrap()), "GREEN");
    assert!(boolean(&rt, "same"));
    assert_eq!(int(&rt, "v"), 6);
    assert_eq!(int(&rt, "p"), 50);
    // A subrange starts at its lower limit.
    assert_eq!(int(&rt, "q"), 10);
    assert_eq!(int(&rt, "r"), -5);
    assert_eq!(rt.format(&rt.resolve("lvl").unwrap()), "HIGH");
}

#[test]
fn bit_access_reads_and_writes_single_bits() {
    let rt = eval(
        "w : WORD := 16#0005; a : BOOL; b : BOOL;",
        "a := w.0; b := w.1; w.15 := TRUE; w.0 := FALSE;",
    );
    assert!(boolean(&rt, "a"));
    assert!(!boolean(&rt, "b"));
    assert_eq!(uint(&rt, "w"), 0x8004);
}

#[test]
fn comments_of_all_kinds_and_case_insensitive_names() {
    let rt = eval(
        "Counter : INT; (* block (* nested *) comment *)",
        "// line comment\n counter := COUNTER + 1; /* C comment */ CoUnTeR := counter * 10;",
    );
    assert_eq!(int(&rt, "counter"), 10);
    assert_eq!(int(&rt, "COUNTER"), 10);
}

#[test]
fn user_functions_with_inputs_outputs_and_in_out() {
    let src = "
        FUNCTION Clamp : INT VAR_INPUT x : INT; lo : INT := 0; hi : INT := 100; END_VAR
          IF x < lo THEN Clamp := lo; ELSIF x > hi THEN Clamp := hi; ELSE Clamp := x; END_IF;
        END_FUNCTION
        FUNCTION DivMod : BOOL VAR_INPUT a : DINT; b : DINT; END_VAR VAR_OUTPUT q : DINT; r : DINT; END_VAR
          IF b = 0 THEN DivMod := FALSE; RETURN; END_IF;
          q := a / b; r := a MOD b; DivMod := TRUE;
        END_FUNCTION
        FUNCTION Swap : BOOL VAR_IN_OUT x : INT; y : INT; END_VAR VAR t : INT; END_VAR
          t := x; x := y; y := t; Swap := TRUE;
        END_FUNCTION
        FUNCTION Count : INT VAR n : INT; END_VAR n := n + 1; Count := n; END_FUNCTION
        PROGRAM P VAR a : INT; b : INT; c : INT; q : DINT; r : DINT; ok : BOOL; u : INT := 1; v : INT := 2; nest : INT; k1 : INT; k2 : INT; END_VAR
          a := Clamp(150); b := Clamp(x := -5, lo := -3); c := Clamp(50, 0, 10);
          ok := DivMod(a := 17, b := 5, q => q, r => r);
          Swap(u, v);
          nest := Clamp(Clamp(500, 0, 300), 0, Clamp(250));
          k1 := Count(); k2 := Count();
        END_PROGRAM";
    let mut rt = plc(src);
    rt.scan(ms(0)).unwrap();
    assert_eq!(int(&rt, "a"), 100);
    assert_eq!(int(&rt, "b"), -3);
    assert_eq!(int(&rt, "c"), 10);
    assert!(boolean(&rt, "ok"));
    assert_eq!((int(&rt, "q"), int(&rt, "r")), (3, 2));
    assert_eq!((int(&rt, "u"), int(&rt, "v")), (2, 1));
    assert_eq!(int(&rt, "nest"), 100);
    // Function variables start from their initial values on every call.
    assert_eq!((int(&rt, "k1"), int(&rt, "k2")), (1, 1));
}

#[test]
fn user_function_blocks_keep_state_per_instance() {
    let src = "
        FUNCTION_BLOCK Accumulate
          VAR_INPUT step : INT := 1; reset : BOOL; END_VAR
          VAR_OUTPUT total : INT; calls : INT; END_VAR
          VAR_TEMP scratch : INT := 7; END_VAR
          scratch := scratch + 1;
          IF reset THEN total := 0; ELSE total := total + step; END_IF;
          calls := calls + scratch - 7;
        END_FUNCTION_BLOCK
        FUNCTION_BLOCK Pair VAR_OUTPUT sum : INT; END_VAR VAR a : Accumulate; b : Accumulate; END_VAR
          a(step := 2); b(step := 3); sum := a.total + b.total;
        END_FUNCTION_BLOCK
        PROGRAM P VAR one : Accumulate; two : Accumulate; t : INT; n : INT; pair : Pair; arr : ARRAY[1..3] OF Accumulate; i : INT; END_VAR
          one(); two(step := 10, total => t); one.step := 5; one();
          pair();
          FOR i := 1 TO 3 DO arr[i](step := i); END_FOR;
          n := one.calls;
        END_PROGRAM";
    let mut rt = plc(src);
    rt.scan(ms(0)).unwrap();
    assert_eq!(int(&rt, "one.total"), 6);
    assert_eq!(int(&rt, "t"), 10);
    assert_eq!(int(&rt, "two.total"), 10);
    assert_eq!(int(&rt, "pair.sum"), 5);
    assert_eq!(int(&rt, "arr[3].total"), 3);
    // VAR_TEMP restarts at 7 on every call, so calls counts 1 per call.
    assert_eq!(int(&rt, "n"), 2);
    rt.scan(ms(4)).unwrap();
    // Inputs not given keep their last value: one.step stays 5.
    assert_eq!(int(&rt, "one.total"), 16);
    assert_eq!(int(&rt, "pair.sum"), 10);
}

#[test]
fn negated_output_and_discarded_output() {
    let src = "PROGRAM P VAR t : TON; notq : BOOL; x : BOOL; END_VAR
        t(IN := TRUE, PT := T#0ms, NOT Q => notq, ET => );
        x := t.Q;
        END_PROGRAM";
    let mut rt = plc(src);
    rt.scan(ms(0)).unwrap();
    assert!(boolean(&rt, "x"));
    assert!(!boolean(&rt, "notq"));
}

#[test]
fn globals_external_and_constants() {
    let src = "VAR_GLOBAL CONSTANT N : INT := 4; END_VAR
        VAR_GLOBAL shared : ARRAY[0..N - 1] OF INT; total : INT; END_VAR
        PROGRAM Writer VAR_EXTERNAL shared : ARRAY[0..N - 1] OF INT; END_VAR VAR i : INT; END_VAR
          FOR i := 0 TO N - 1 DO shared[i] := i * i; END_FOR;
        END_PROGRAM
        PROGRAM Reader VAR_EXTERNAL shared : ARRAY[0..N - 1] OF INT; total : INT; END_VAR VAR i : INT; END_VAR
          total := 0; FOR i := 0 TO N - 1 DO total := total + shared[i]; END_FOR;
        END_PROGRAM";
    let mut rt = plc(src);
    rt.scan(ms(0)).unwrap();
    assert_eq!(int(&rt, "total"), 14);
    assert_eq!(int(&rt, "WRITER.i"), 4);
}

#[test]
fn nested_function_call_arguments_do_not_clobber_each_other() {
    let src = "FUNCTION Sub2 : INT VAR_INPUT a : INT; b : INT; END_VAR Sub2 := a - b; END_FUNCTION
        PROGRAM P VAR r : INT; END_VAR r := Sub2(100, Sub2(10, 3)); END_PROGRAM";
    let mut rt = plc(src);
    rt.scan(ms(0)).unwrap();
    assert_eq!(int(&rt, "r"), 93);
}

#[test]
fn string_functions_returning_and_taking_strings() {
    let src = "FUNCTION Greet : STRING[40] VAR_INPUT who : STRING[20]; END_VAR Greet := CONCAT('hi ', who); END_FUNCTION
        PROGRAM P VAR s : STRING; n : INT; END_VAR s := Greet('bob'); n := LEN(Greet(who := 'alice')); END_PROGRAM";
    let mut rt = plc(src);
    rt.scan(ms(0)).unwrap();
    assert_eq!(string(&rt, "s"), "hi bob");
    assert_eq!(int(&rt, "n"), 8);
}

#[test]
fn function_block_in_out_and_struct_returning_function() {
    let src = "TYPE Pt : STRUCT x : INT; y : INT; END_STRUCT; END_TYPE
        FUNCTION Mk : Pt VAR_INPUT x : INT; y : INT; END_VAR Mk.x := x; Mk.y := y; END_FUNCTION
        FUNCTION_BLOCK Bump VAR_IN_OUT target : INT; END_VAR VAR_INPUT step : INT; END_VAR target := target + step; END_FUNCTION_BLOCK
        PROGRAM P VAR p : Pt; b : Bump; v : INT := 10; arr : ARRAY[1..2] OF INT; END_VAR
          p := Mk(3, 4);
          b(target := v, step := 5);
          b(target := arr[2], step := 7);
        END_PROGRAM";
    let mut rt = plc(src);
    rt.scan(ms(0)).unwrap();
    assert_eq!((int(&rt, "p.x"), int(&rt, "p.y")), (3, 4));
    assert_eq!(int(&rt, "v"), 15);
    assert_eq!(int(&rt, "arr[2]"), 7);
}

#[test]
fn numeric_functions_at_run_time_match_the_compile_time_folding() {
    let rt = eval(
        "x : LREAL := 2.0; r : REAL := 0.5; a : LREAL; b : REAL; c : LREAL; d : LREAL; e : LREAL; f : LREAL; i : DINT := -9; g : DINT; h : LREAL;",
        "a := SQRT(x); b := SIN(r); c := EXP(x); d := LN(x); e := EXPT(x, 10); f := ATAN2(x, x); g := ABS(i); h := LOG(x * 50.0);",
    );
    assert_eq!(real(&rt, "a"), 2f64.sqrt());
    assert_eq!(real(&rt, "b"), 0.5f32.sin() as f64);
    assert_eq!(real(&rt, "c"), 2f64.exp());
    assert_eq!(real(&rt, "d"), std::f64::consts::LN_2);
    assert_eq!(real(&rt, "e"), 1024.0);
    assert_eq!(real(&rt, "f"), std::f64::consts::FRAC_PI_4);
    assert_eq!(int(&rt, "g"), 9);
    assert_eq!(real(&rt, "h"), 2.0);
}

#[test]
fn functions_without_a_result_are_statements() {
    let src = "FUNCTION Log2 VAR_IN_OUT acc : INT; END_VAR VAR_INPUT v : INT; END_VAR acc := acc + v; END_FUNCTION
        PROGRAM P VAR total : INT; END_VAR Log2(acc := total, v := 3); Log2(total, 4); END_PROGRAM";
    let mut rt = plc(src);
    rt.scan(ms(0)).unwrap();
    assert_eq!(int(&rt, "total"), 7);
    let bad = "FUNCTION F VAR_INPUT v : INT; END_VAR END_FUNCTION
        PROGRAM P VAR x : BOOL; END_VAR x := F(1); END_PROGRAM";
    assert_eq!(compile_error(bad).2, "type-mismatch");
}

#[test]
fn mixed_operands_meet_at_the_smallest_common_type() {
    let rt = eval(
        "i : INT := -1; u : UINT := 1; b : BOOL; s : DINT; d : DINT := 3; r : REAL := 0.5; x : LREAL;",
        "b := i < u; s := i + u; x := d * r;",
    );
    // INT and UINT meet at DINT: -1 < 1.
    assert!(boolean(&rt, "b"));
    assert_eq!(int(&rt, "s"), 0);
    // DINT and REAL meet at LREAL.
    assert_eq!(real(&rt, "x"), 1.5);
}

#[test]
fn methods_of_function_blocks() {
    let src = "
        FUNCTION_BLOCK Axis
          VAR_INPUT enable : BOOL; END_VAR
          VAR_OUTPUT pos : LREAL; moves : INT; END_VAR
          VAR target : LREAL; END_VAR
          METHOD PUBLIC MoveTo : BOOL
            VAR_INPUT where : LREAL; END_VAR
            VAR scratch : INT; END_VAR
            scratch := scratch + 1;
            IF NOT enable THEN MoveTo := FALSE; RETURN; END_IF;
            target := where; moves := moves + scratch; MoveTo := TRUE;
          END_METHOD
          METHOD PRIVATE Step
            pos := pos + LIMIT(-1.0, target - pos, 1.0);
          END_METHOD
          METHOD Distance : LREAL
            Distance := ABS(target - pos);
          END_METHOD
          Step();
        END_FUNCTION_BLOCK
        PROGRAM P VAR x : Axis; y : Axis; ok1 : BOOL; ok2 : BOOL; d : LREAL; temps_ok : BOOL; END_VAR
          ok1 := x.MoveTo(2.5);
          y.enable := TRUE;
          ok2 := y.MoveTo(where := 3.0);
          y.MoveTo(-1.0);
          y.MoveTo(3.0);
          x(); y();
          d := y.Distance();
        END_PROGRAM";
    let mut rt = plc(src);
    rt.scan(ms(0)).unwrap();
    assert!(!boolean(&rt, "ok1"));
    assert!(boolean(&rt, "ok2"));
    // Method variables restart on every call: each call adds 1 to moves.
    assert_eq!(int(&rt, "y.moves"), 3);
    assert_eq!(int(&rt, "x.moves"), 0);
    assert_eq!(real(&rt, "y.pos"), 1.0);
    assert_eq!(real(&rt, "x.pos"), 0.0);
    assert_eq!(real(&rt, "d"), 2.0);
    rt.scan(ms(4)).unwrap();
    assert_eq!(real(&rt, "y.pos"), 2.0);
}

#[test]
fn method_errors() {
    let fb = "FUNCTION_BLOCK B METHOD PRIVATE Hidden : INT Hidden := 1; END_METHOD METHOD Act Hidden(); END_METHOD END_FUNCTION_BLOCK\n";
    let src = format!("{fb}PROGRAM P VAR b : B; x : INT; END_VAR\n  x := b.Hidden();\nEND_PROGRAM");
    assert_eq!(compile_error(&src).2, "invalid");
    let src = format!("{fb}PROGRAM P VAR b : B; END_VAR\n  b.Nothing();\nEND_PROGRAM");
    assert_eq!(compile_error(&src).2, "undeclared");
    let src = format!("{fb}PROGRAM P VAR b : B; x : INT; END_VAR\n  x := b.Act();\nEND_PROGRAM");
    assert_eq!(compile_error(&src).2, "type-mismatch");
    let src = "FUNCTION_BLOCK R METHOD Again : INT Again := Again(); END_METHOD END_FUNCTION_BLOCK";
    assert_eq!(compile_error(src).2, "invalid");
}

#[test]
fn extensible_comparisons_and_operator_functions() {
    let rt = eval(
        "a : BOOL; b : BOOL; c : BOOL; d : BOOL; w : WORD; x : BOOL; m : INT; t1 : TIME; t2 : TIME; t3 : TIME;",
        "a := GT(3, 2, 1); b := GT(3, 2, 2); c := LE(1, 1, 2, 5); d := EQ(4, 4, 4);
         w := AND(WORD#16#FF0F, WORD#16#0FFF, WORD#16#F0F0); x := XOR(TRUE, TRUE, TRUE); m := MOD(17, 5);
         t1 := STRING_TO_TIME('T#1m2s500ms'); t2 := STRING_TO_TIME('250ms'); t3 := STRING_TO_TIME('nonsense');",
    );
    assert!(boolean(&rt, "a"));
    assert!(!boolean(&rt, "b"));
    assert!(boolean(&rt, "c"));
    assert!(boolean(&rt, "d"));
    assert_eq!(uint(&rt, "w"), 0x0000);
    assert!(boolean(&rt, "x"));
    assert_eq!(int(&rt, "m"), 2);
    assert_eq!(time_ms(&rt, "t1"), 62_500.0);
    assert_eq!(time_ms(&rt, "t2"), 250.0);
    assert_eq!(time_ms(&rt, "t3"), 0.0);
}

#[test]
fn var_temp_between_other_blocks_restarts_alone() {
    let src = "FUNCTION_BLOCK B
          VAR_TEMP t1 : INT := 5; END_VAR
          VAR keep : INT; END_VAR
          VAR_TEMP t2 : INT := 7; END_VAR
          t1 := t1 + 1; t2 := t2 + 1; keep := keep + t1 + t2;
        END_FUNCTION_BLOCK
        PROGRAM P VAR b : B; END_VAR b(); b(); END_PROGRAM";
    let mut rt = plc(src);
    rt.scan(ms(0)).unwrap();
    // Each call: t1 = 6, t2 = 8; keep accumulates across calls.
    assert_eq!(int(&rt, "b.keep"), 28);
}

#[test]
fn remaining_standard_functions_and_operators() {
    let rt = eval(
        "x : LREAL := 0.5; a : DINT; b : DINT; c : DINT; m : INT := 9; d : LREAL; e : LREAL; f : LREAL; g : LREAL; h : LREAL;
         p : BOOL; q : BOOL; r : LREAL; s : REAL := -2.5; t : DINT; u : INT; v : LREAL := 3.0;",
        "a := SUB(10, 3); b := DIV(7, 2); c := MOVE(m);
         d := COS(x); e := TAN(x); f := ASIN(x); g := ACOS(x); h := ATAN(x);
         p := TRUE & FALSE; q := NOT (1 > 2) & TRUE; r := v ** 2.0 - -v; t := TRUNC(s); u := REAL_TRUNC_INT(s);",
    );
    assert_eq!(int(&rt, "a"), 7);
    assert_eq!(int(&rt, "b"), 3);
    assert_eq!(int(&rt, "c"), 9);
    assert_eq!(real(&rt, "d"), 0.5f64.cos());
    assert_eq!(real(&rt, "e"), 0.5f64.tan());
    assert_eq!(real(&rt, "f"), 0.5f64.asin());
    assert_eq!(real(&rt, "g"), 0.5f64.acos());
    assert_eq!(real(&rt, "h"), 0.5f64.atan());
    assert!(!boolean(&rt, "p"));
    assert!(boolean(&rt, "q"));
    // 3 ** 2 - (-3) = 12
    assert_eq!(real(&rt, "r"), 12.0);
    // TRUNC goes toward zero.
    assert_eq!(int(&rt, "t"), -2);
    assert_eq!(int(&rt, "u"), -2);
}

/// IEC 61131-3 leaves a real-to-integer conversion of a value outside the target's range
/// implementation-defined. rtcnc saturates: the nearest end of the range; NaN gives 0.
/// (Before, the 64-bit result was wrapped to the target: LREAL_TO_DINT(1E10) gave
/// 1410065408, of 4294967295.0 gave -1.)
#[test]
fn real_to_integer_conversions_saturate_outside_the_range() {
    let rt = eval(
        "big : LREAL := 1.0E10; huge : LREAL := 1.0E300; neg : LREAL := -1.0E10;
         u32max : LREAL := 4294967295.0; tie : LREAL := 2147483646.5; m : LREAL := -1.0;
         d1, d2, d3, d4, d5, d6, d7 : DINT; i1 : INT; u1 : UINT; ud : UDINT; n : LREAL;",
        "d1 := LREAL_TO_DINT(big); d2 := LREAL_TO_DINT(neg); d3 := LREAL_TO_DINT(u32max);
         d4 := LREAL_TO_DINT(tie); d5 := LREAL_TO_DINT(huge); d6 := TRUNC(neg);
         n := SQRT(m); d7 := LREAL_TO_DINT(n);
         i1 := LREAL_TO_INT(big); u1 := LREAL_TO_UINT(neg); ud := LREAL_TO_UDINT(big);",
    );
    assert_eq!(int(&rt, "d1"), 2_147_483_647);
    assert_eq!(int(&rt, "d2"), -2_147_483_648);
    assert_eq!(int(&rt, "d3"), 2_147_483_647);
    // In range, rounding is to the nearest, ties to even (IEC 60559), as before.
    assert_eq!(int(&rt, "d4"), 2_147_483_646);
    assert_eq!(int(&rt, "d5"), 2_147_483_647);
    assert_eq!(int(&rt, "d6"), -2_147_483_648);
    assert_eq!(int(&rt, "d7"), 0);
    assert_eq!(int(&rt, "i1"), 32_767);
    assert_eq!(int(&rt, "u1"), 0);
    assert_eq!(int(&rt, "ud"), 4_294_967_295);
}

/// Found by the structure-aware fuzz target (fuzz/src/st_generated.rs): a comparison of two
/// constants that the compiler does not fold (the left one is NaN) was refused as a bare
/// "type mismatch".
#[test]
fn constants_left_unfolded_compare_as_lreal() {
    let rt = eval(
        "b1 : BOOL := TRUE; b2 : BOOL;",
        "b1 := SIN(SQRT(1.0E308 + 1.0E308)) > 1.0E308; b2 := SIN(SQRT(1.0E308 + 1.0E308)) <> 1.0;",
    );
    // SIN(+inf) is NaN: NaN > x is false, NaN <> x true (IEC 60559).
    assert_eq!(get(&rt, "b1"), Value::Bool(false));
    assert_eq!(get(&rt, "b2"), Value::Bool(true));
}
