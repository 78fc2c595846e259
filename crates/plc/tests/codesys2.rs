//! The CODESYS 2.3 dialect that libraries written for it (OSCAT BASIC and the like) use.
//! Every program here is written for the test; expected values are worked out by hand.

use crate::common::*;

use std::sync::Arc;

use rtcnc_plc::{CompileOptions, Conversions, Runtime, compile_sources};

#[test]
fn array_initial_values_without_brackets_and_with_repeat_factors() {
    let rt = plc_scanned(
        "TYPE Pt : STRUCT x, y : INT; END_STRUCT END_TYPE
TYPE Table : STRUCT
  steps : ARRAY[1..4] OF BYTE := 1, 3, 7, 15;
END_STRUCT END_TYPE
PROGRAM P
VAR CONSTANT
  K : ARRAY[0..3] OF INT := 1, 3, 7, 15;
END_VAR
VAR
  r : ARRAY[1..7] OF BYTE := 2(7), 3(0), 9;
  pts : ARRAY[1..2] OF Pt := (x := 1, y := 2), (x := 3, y := 4);
  t : Table;
  one : ARRAY[0..2] OF INT := 3(5);
  sum : INT;
  i : INT;
END_VAR
FOR i := 0 TO 3 DO sum := sum + K[i]; END_FOR
END_PROGRAM",
    );
    // 1 + 3 + 7 + 15
    assert_eq!(int(&rt, "sum"), 26);
    // 2(7), 3(0), 9: 7 7 0 0 0 9, and the seventh element keeps its default 0.
    let r: Vec<i64> = (1..=7).map(|i| int(&rt, &format!("r[{i}]"))).collect();
    assert_eq!(r, [7, 7, 0, 0, 0, 9, 0]);
    assert_eq!([int(&rt, "pts[1].y"), int(&rt, "pts[2].x")], [2, 3]);
    assert_eq!(int(&rt, "t.steps[4]"), 15);
    assert_eq!(int(&rt, "one[2]"), 5);
}

#[test]
fn functionblock_on_as_a_name_and_the_library_list_of_an_export() {
    let rt = plc_scanned(
        "FUNCTION Gate : BOOL
VAR_INPUT ON, OFF, HOLD : BOOL; END_VAR
Gate := ON AND NOT (OFF OR HOLD);
END_FUNCTION

FUNCTIONBLOCK Latch
VAR_INPUT S, R : BOOL; END_VAR
VAR_OUTPUT Q : BOOL; END_VAR
Q := NOT R AND (S OR Q);
END_FUNCTION_BLOCK

PROGRAM P
VAR l : Latch; a, b : BOOL; END_VAR
a := Gate(ON := TRUE, OFF := FALSE, HOLD := FALSE);
b := Gate(TRUE, FALSE, TRUE);
l(S := TRUE, R := FALSE);
END_PROGRAM

LIBRARY
Standard.lib 4.10.05 11:14:46
NumOfPOUs: 2
TON: 0
TP: 0
END_LIBRARY
",
    );
    assert!(boolean(&rt, "a"));
    assert!(!boolean(&rt, "b"));
    assert!(boolean(&rt, "l.Q"));
}

#[test]
fn a_constant_declared_below_bounds_an_array_above_it() {
    let rt = plc_scanned(
        "FUNCTION_BLOCK Fifo
VAR_OUTPUT top : DWORD; size : UDINT; END_VAR
VAR buf : ARRAY[0..n] OF DWORD; END_VAR
VAR CONSTANT n : INT := 3; END_VAR
buf[n] := 16#CAFE;
top := buf[3];
size := SIZEOF(buf);
END_FUNCTION_BLOCK

FUNCTION Last : INT
VAR_INPUT k : INT; END_VAR
VAR a : ARRAY[1..m] OF INT; i : INT; END_VAR
VAR CONSTANT m : INT := 4; END_VAR
FOR i := 1 TO m DO a[i] := i * k; END_FOR
Last := a[m];
END_FUNCTION

PROGRAM P
VAR f : Fifo; x : INT; END_VAR
f();
x := Last(5);
END_PROGRAM",
    );
    assert_eq!(uint(&rt, "f.top"), 0xCAFE);
    // a[4] = 4 * 5
    assert_eq!(int(&rt, "x"), 20);
    // Four DWORDs of 4 bytes each, as CODESYS counts them.
    assert_eq!(uint(&rt, "f.size"), 16);
}

fn codesys(src: &str) -> Result<Runtime, rtcnc_plc::CompileErrors> {
    let options = CompileOptions {
        conversions: Conversions::Codesys,
        ..CompileOptions::default()
    };
    let program = compile_sources(&[(src, "codesys.st")], &options)?;
    let mut rt = Runtime::new(Arc::new(program));
    rt.scan(ms(0)).expect("scan");
    Ok(rt)
}

#[test]
fn codesys_conversions_compute_with_bit_strings_and_narrow_implicitly() {
    let src = "PROGRAM P
VAR
  dw1 : DWORD := 1; dw2 : DWORD := 2; diff : DWORD;
  b : BYTE := 200; i : INT := 100; sum : INT;
  big : DINT := 70000; narrow : INT;
  u : UINT := 40000; w : WORD;
  r : REAL; m : DWORD; less : BOOL;
END_VAR
diff := dw1 - dw2;
sum := b + i;
narrow := big;
w := u;
r := b / 4;
m := dw1 + 16#FFFF_FFFF MOD 7;
less := b < i;
END_PROGRAM";
    let rt = codesys(src).unwrap_or_else(|e| panic!("{e}"));
    // 1 - 2 wraps in 32 bits.
    assert_eq!(uint(&rt, "diff"), 0xFFFF_FFFF);
    // BYTE meets INT at INT: 200 + 100.
    assert_eq!(int(&rt, "sum"), 300);
    // 70000 keeps its low 16 bits: 70000 - 65536.
    assert_eq!(int(&rt, "narrow"), 4464);
    assert_eq!(uint(&rt, "w"), 40000);
    // BYTE / 4 is an integer division (50), then a REAL.
    assert_eq!(real(&rt, "r"), 50.0);
    // 4294967295 MOD 7 = 3 (7 * 613566756 = 4294967292), plus 1.
    assert_eq!(uint(&rt, "m"), 4);
    // 200 < 100 compared as INT.
    assert!(!boolean(&rt, "less"));

    // IEC's rules (the default) refuse the same program.
    let err = compile_sources(&[(src, "iec.st")], &CompileOptions::default())
        .err()
        .map(|e| e.to_string());
    assert!(
        err.as_deref()
            .is_some_and(|e| e.contains("operator SUB does not apply to DWORD and DWORD")),
        "{err:?}"
    );
}

#[test]
fn codesys_conversions_shift_integers_in_their_width_by_a_bit_string_count() {
    let rt = codesys(
        "PROGRAM P
VAR
  i : INT := -2; u : UINT := 40000; n : BYTE := 3;
  a, b : INT; c : UINT; d : DINT; e : BYTE;
END_VAR
a := SHR(i, 1);
b := SHL(INT#16384, 1);
c := SHR(u, n);
d := SHL(DINT#1, 31);
e := ROL(BYTE#16#81, n);
END_PROGRAM",
    )
    .unwrap_or_else(|e| panic!("{e}"));
    // A signed integer shifts right arithmetically (CODESYS 2.3's manual): -2 / 2.
    assert_eq!(int(&rt, "a"), -1);
    // 16#4000 << 1 = 16#8000, the INT -32768.
    assert_eq!(int(&rt, "b"), -32768);
    // 40000 / 8
    assert_eq!(uint(&rt, "c"), 5000);
    assert_eq!(int(&rt, "d"), i32::MIN as i64);
    // 2#1000_0001 rotated left by 3: 2#0000_1100.
    assert_eq!(uint(&rt, "e"), 0x0C);
}

#[test]
fn codesys_conversions_shift_signed_integers_right_with_their_sign() {
    let rt = codesys(
        "PROGRAM P
VAR
  month : INT := 3; days : INT;
  i : INT := -32768; s : SINT := -128; d : DINT := -256; l : LINT := -1;
  a : INT; b : SINT; c, c2 : DINT; e : LINT; w : WORD;
END_VAR
days := (month - 1) * 30 + SHR(month - 4, 1);
a := SHR(i, 15);
b := SHR(s, 3);
c := SHR(d, 4);
c2 := SHR(DINT#1000, 3);
e := SHR(l, 70);
w := SHR(WORD#16#8000, 15);
END_PROGRAM",
    )
    .unwrap_or_else(|e| panic!("{e}"));
    // Days of the year before March 1st: 2 * 30 + SHR(-1, 1) = 60 - 1 = 59 (31 + 28).
    assert_eq!(int(&rt, "days"), 59);
    // 16#8000 with the sign bit filled fifteen times: 16#FFFF.
    assert_eq!(int(&rt, "a"), -1);
    // -128 / 8 and -256 / 16, exact, so the floor of an arithmetic shift is the quotient.
    assert_eq!(int(&rt, "b"), -16);
    assert_eq!(int(&rt, "c"), -16);
    // A positive value: 1000 / 8.
    assert_eq!(int(&rt, "c2"), 125);
    // A count past the width leaves only the sign.
    assert_eq!(int(&rt, "e"), -1);
    // A bit string still takes zeros: 16#8000 >> 15 = 1.
    assert_eq!(uint(&rt, "w"), 1);
}

#[test]
fn time_without_arguments_is_the_scans_plc_time() {
    let mut rt = plc("FUNCTION T_MS : DWORD
T_MS := TIME_TO_DWORD(TIME());
END_FUNCTION
PROGRAM P
VAR t : TIME; ms : DWORD; END_VAR
t := TIME();
ms := T_MS();
END_PROGRAM");
    rt.scan(ms(0)).expect("scan");
    assert_eq!(time_ms(&rt, "t"), 0.0);
    rt.scan(ms(1500)).expect("scan");
    assert_eq!(time_ms(&rt, "t"), 1500.0);
    // TIME_TO_DWORD counts milliseconds.
    assert_eq!(uint(&rt, "ms"), 1500);
}

#[test]
fn codesys_conversions_index_negate_type_big_literals_and_treat_addresses_as_words() {
    let rt = codesys(
        "FUNCTION SUM3 : INT
VAR_INPUT pt : POINTER TO ARRAY[1..3] OF INT; END_VAR
SUM3 := pt^[1] + pt^[2] + pt^[3];
END_FUNCTION
PROGRAM P
VAR
  arr : ARRAY[0..3] OF INT := 10, 20, 30, 40; k : BYTE := 2; at_k : INT;
  step : BYTE := 5; neg : INT;
  off : INT := 3; prod : DINT;
  x0 : INT := 77; a : DWORD; p : POINTER TO INT; y : INT;
  p1, p2 : POINTER TO INT; lt, ge : BOOL;
  s : INT;
END_VAR
at_k := arr[k];
neg := -step;
prod := off * 60000;
a := ADR(x0); p := a; y := p^;
p1 := ADR(arr[1]); p2 := ADR(arr[3]); lt := p1 < p2; ge := p1 >= p2;
s := SUM3(ADR(arr));
END_PROGRAM",
    )
    .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(int(&rt, "at_k"), 30);
    assert_eq!(int(&rt, "neg"), -5);
    // 3 * 60000 does not fit an INT: computed in DINT as CODESYS types 60000.
    assert_eq!(int(&rt, "prod"), 180_000);
    assert_eq!(int(&rt, "y"), 77);
    assert!(boolean(&rt, "lt"));
    assert!(!boolean(&rt, "ge"));
    // pt^[1..3] are arr[0..2]: 10 + 20 + 30.
    assert_eq!(int(&rt, "s"), 60);
}

/// As in CODESYS, a POINTER TO BYTE takes the address of anything and steps through its
/// bytes one at a time: a STRING's characters, an array's elements.
#[test]
fn byte_pointers_step_through_strings_and_arrays_a_byte_at_a_time() {
    let mut rt = plc("FUNCTION SECOND : BYTE
VAR_INPUT s : STRING; END_VAR
VAR pt : POINTER TO BYTE; END_VAR
pt := ADR(s);
pt := pt + 1;
SECOND := pt^;
END_FUNCTION
PROGRAM P
VAR arr : ARRAY[0..3] OF BYTE := 5, 6, 7, 8; pt : POINTER TO BYTE; a, b, c : BYTE; END_VAR
pt := ADR(arr);
pt := pt + SIZEOF(arr[0]);
a := pt^;
pt := pt + 1;
b := pt^;
c := SECOND('AZ');
END_PROGRAM");
    rt.scan(ms(0)).expect("scan");
    assert_eq!((uint(&rt, "a"), uint(&rt, "b")), (6, 7));
    // 'Z' is byte 16#5A.
    assert_eq!(uint(&rt, "c"), 0x5A);
}
