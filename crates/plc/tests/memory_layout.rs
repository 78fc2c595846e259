//! Memory laid out in bytes as CODESYS 3 and TwinCAT 3 lay it out on x86-64: SIZEOF,
//! structure padding, UNION, pointer arithmetic in bytes, and code written in OSCAT
//! BASIC's style that walks strings and arrays through pointers. Every expected value is
//! worked out by hand from CODESYS's layout rules (each value little-endian at its own
//! size, aligned to it; structures padded to their largest member's alignment; STRING(n)
//! n + 1 bytes ending in 0) or IEEE-754.

use crate::common::*;

use std::sync::Arc;

use rtcnc_plc::{CompileOptions, Conversions, Runtime, compile_sources};

/// Compiled with CODESYS's implicit conversions (as OSCAT BASIC needs) and scanned once.
fn codesys(src: &str) -> Runtime {
    let options = CompileOptions {
        conversions: Conversions::Codesys,
        ..CompileOptions::default()
    };
    let program =
        compile_sources(&[(src, "layout.st")], &options).unwrap_or_else(|e| panic!("{e}"));
    let mut rt = Runtime::new(Arc::new(program));
    rt.scan(ms(0)).expect("scan");
    rt
}

#[test]
fn sizeof_of_elementary_types_is_codesys_s() {
    let rt = plc_scanned(
        "PROGRAM P
VAR
  s : ARRAY[0..15] OF UDINT;
  str : STRING; s10 : STRING(10); w10 : WSTRING(10); p : POINTER TO INT;
END_VAR
s[0] := SIZEOF(BOOL); s[1] := SIZEOF(BYTE); s[2] := SIZEOF(SINT); s[3] := SIZEOF(USINT);
s[4] := SIZEOF(WORD); s[5] := SIZEOF(INT); s[6] := SIZEOF(UINT);
s[7] := SIZEOF(DWORD); s[8] := SIZEOF(DINT); s[9] := SIZEOF(UDINT); s[10] := SIZEOF(REAL);
s[11] := SIZEOF(LWORD); s[12] := SIZEOF(LINT); s[13] := SIZEOF(ULINT); s[14] := SIZEOF(LREAL);
s[15] := SIZEOF(p);
END_PROGRAM",
    );
    let want = [1, 1, 1, 1, 2, 2, 2, 4, 4, 4, 4, 8, 8, 8, 8, 8];
    for (k, w) in want.iter().enumerate() {
        assert_eq!(uint(&rt, &format!("P.s[{k}]")), *w, "s[{k}]");
    }
    let rt = plc_scanned(
        "PROGRAM P
VAR str : STRING; s10 : STRING(10); w10 : WSTRING(10); a, b, c : UDINT; END_VAR
a := SIZEOF(str); b := SIZEOF(s10); c := SIZEOF(w10);
END_PROGRAM",
    );
    // STRING is STRING(80): 80 characters and the terminating zero; a WSTRING 2 bytes a
    // code unit.
    assert_eq!(
        (uint(&rt, "a"), uint(&rt, "b"), uint(&rt, "c")),
        (81, 11, 22)
    );
}

/// The distance in bytes from address `b` to address `a`.
const OFF: &str = "FUNCTION OFF : ULINT
VAR_INPUT a, b : ULINT; END_VAR
OFF := a - b;
END_FUNCTION
";

#[test]
fn structures_are_padded_as_codesys_pads_them() {
    let rt = plc_scanned(&format!(
        "{OFF}TYPE Mixed : STRUCT a : BOOL; b : DINT; c : BYTE; d : LREAL; e : INT; END_STRUCT END_TYPE
TYPE Bytes3 : STRUCT x, y, z : BYTE; END_STRUCT END_TYPE
TYPE ByteWord : STRUCT b : BYTE; w : WORD; END_STRUCT END_TYPE
TYPE DintBool : STRUCT d : DINT; f : BOOL; END_STRUCT END_TYPE
TYPE Outer : STRUCT flag : BOOL; inner : ByteWord; last : BYTE; END_STRUCT END_TYPE
PROGRAM P
VAR
  m : Mixed; o : Outer;
  size_m, size_3, size_bw, size_db, size_arr3, size_arrdb, size_o : UDINT;
  off_b, off_c, off_d, off_e, off_inner, off_w, off_last : ULINT;
  arr3 : ARRAY[1..3] OF Bytes3; arrdb : ARRAY[1..2] OF DintBool;
END_VAR
size_m := SIZEOF(Mixed); size_3 := SIZEOF(Bytes3); size_bw := SIZEOF(ByteWord);
size_db := SIZEOF(DintBool); size_arr3 := SIZEOF(arr3); size_arrdb := SIZEOF(arrdb);
size_o := SIZEOF(o);
off_b := OFF(ADR(m.b), ADR(m)); off_c := OFF(ADR(m.c), ADR(m));
off_d := OFF(ADR(m.d), ADR(m)); off_e := OFF(ADR(m.e), ADR(m));
off_inner := OFF(ADR(o.inner), ADR(o)); off_w := OFF(ADR(o.inner.w), ADR(o));
off_last := OFF(ADR(o.last), ADR(o));
END_PROGRAM"
    ));
    // Mixed: a at 0, b (4-aligned) at 4, c at 8, d (8-aligned) at 16, e at 24; 26 bytes
    // padded to a multiple of 8.
    assert_eq!(
        [
            uint(&rt, "off_b"),
            uint(&rt, "off_c"),
            uint(&rt, "off_d"),
            uint(&rt, "off_e")
        ],
        [4, 8, 16, 24]
    );
    assert_eq!(uint(&rt, "size_m"), 32);
    // Three BYTEs need no padding; BYTE then WORD puts the WORD at 2.
    assert_eq!((uint(&rt, "size_3"), uint(&rt, "size_bw")), (3, 4));
    // DINT then BOOL: 5 bytes padded to 8, so an array of them steps 8.
    assert_eq!((uint(&rt, "size_db"), uint(&rt, "size_arrdb")), (8, 16));
    assert_eq!(uint(&rt, "size_arr3"), 9);
    // Outer: flag at 0, inner (2-aligned) at 2 with its w at 4, last at 6; 7 bytes
    // padded to 8.
    assert_eq!(
        [
            uint(&rt, "off_inner"),
            uint(&rt, "off_w"),
            uint(&rt, "off_last"),
            uint(&rt, "size_o")
        ],
        [2, 4, 6, 8]
    );
}

#[test]
fn arrays_are_contiguous() {
    let rt = plc_scanned(&format!(
        "{OFF}PROGRAM P
VAR
  r : ARRAY[1..4] OF REAL; b : ARRAY[0..9] OF BOOL; m : ARRAY[1..2, 1..3] OF INT;
  s : ARRAY[1..3] OF STRING(9);
  size_r, size_b, size_m, size_s : UDINT;
  step_r, step_m_row, step_s : ULINT;
END_VAR
size_r := SIZEOF(r); size_b := SIZEOF(b); size_m := SIZEOF(m); size_s := SIZEOF(s);
step_r := OFF(ADR(r[2]), ADR(r[1]));
step_m_row := OFF(ADR(m[2, 1]), ADR(m[1, 1]));
step_s := OFF(ADR(s[3]), ADR(s[1]));
END_PROGRAM"
    ));
    assert_eq!(
        [
            uint(&rt, "size_r"),
            uint(&rt, "size_b"),
            uint(&rt, "size_m"),
            uint(&rt, "size_s")
        ],
        [16, 10, 12, 30]
    );
    // Row-major: a row of three INTs is 6 bytes; a STRING(9) 10.
    assert_eq!(
        [
            uint(&rt, "step_r"),
            uint(&rt, "step_m_row"),
            uint(&rt, "step_s")
        ],
        [4, 6, 20]
    );
}

#[test]
fn union_members_share_their_bytes() {
    let mut rt = plc_scanned(
        "TYPE U : UNION d : DWORD; b : ARRAY[0..3] OF BYTE; r : REAL; END_UNION END_TYPE
TYPE Wide : UNION l : LREAL; b : BYTE; END_UNION END_TYPE
PROGRAM P
VAR
  u, v : U; b0, b1, b2, b3 : BYTE; bits, neg : DWORD; back : REAL;
  size_u, size_wide : UDINT;
END_VAR
u.d := 16#11223344;
b0 := u.b[0]; b1 := u.b[1]; b2 := u.b[2]; b3 := u.b[3];
v.r := 1.0;
bits := v.d;
v.r := -2.5;
neg := v.d;
v.d := 16#40490FDB;
back := v.r;
size_u := SIZEOF(U); size_wide := SIZEOF(Wide);
END_PROGRAM",
    );
    // Little-endian: the lowest byte first.
    assert_eq!(
        [
            uint(&rt, "b0"),
            uint(&rt, "b1"),
            uint(&rt, "b2"),
            uint(&rt, "b3")
        ],
        [0x44, 0x33, 0x22, 0x11]
    );
    // IEEE-754 single: 1.0 is 0 01111111 000..., -2.5 is 1 10000000 0100...
    assert_eq!(uint(&rt, "bits"), 0x3F80_0000);
    assert_eq!(uint(&rt, "neg"), 0xC020_0000);
    // 16#40490FDB is the single nearest pi.
    assert_eq!(real(&rt, "back"), std::f32::consts::PI as f64);
    assert_eq!((uint(&rt, "size_u"), uint(&rt, "size_wide")), (4, 8));
    // The monitor sees the members too, and a write to one shows in the others.
    set(&mut rt, "u.b[3]", rtcnc_plc::Value::UInt(0xAA));
    assert_eq!(uint(&rt, "u.d"), 0xAA22_3344);
}

/// OSCAT's string functions walk a STRING byte by byte through a POINTER TO BYTE until
/// the terminating zero.
#[test]
fn oscat_style_pointer_walks_over_strings() {
    let rt = codesys(
        "FUNCTION MY_LEN : INT
VAR_INPUT str : STRING; END_VAR
VAR pt : POINTER TO BYTE; END_VAR
pt := ADR(str);
MY_LEN := 0;
WHILE pt^ <> 0 DO
  MY_LEN := MY_LEN + 1;
  pt := pt + 1;
END_WHILE
END_FUNCTION

FUNCTION MY_UPPER : STRING
VAR_INPUT str : STRING; END_VAR
VAR pt : POINTER TO BYTE; END_VAR
MY_UPPER := str;
pt := ADR(MY_UPPER);
WHILE pt^ > 0 DO
  IF pt^ >= 97 AND pt^ <= 122 THEN
    pt^ := pt^ - 32;
  END_IF
  pt := pt + 1;
END_WHILE
END_FUNCTION

FUNCTION MY_FIND : INT
VAR_INPUT str : STRING; c : BYTE; END_VAR
VAR pt : POINTER TO ARRAY[1..255] OF BYTE; i : INT; END_VAR
pt := ADR(str);
MY_FIND := 0;
FOR i := 1 TO LEN(str) DO
  IF pt^[i] = c THEN
    MY_FIND := i;
    RETURN;
  END_IF
END_FOR
END_FUNCTION

PROGRAM P
VAR
  n, empty, found, missing : INT; up : STRING; s3 : STRING(3) := 'abc'; tail : BYTE;
  p : POINTER TO BYTE;
END_VAR
n := MY_LEN('Hello, PLC');
empty := MY_LEN('');
up := MY_UPPER('spindle 2 on');
found := MY_FIND('M06 T12', 84);
missing := MY_FIND('M06 T12', 88);
p := ADR(s3) + 3;
tail := p^;
END_PROGRAM",
    );
    assert_eq!((int(&rt, "n"), int(&rt, "empty")), (10, 0));
    assert_eq!(string(&rt, "up"), "SPINDLE 2 ON");
    // 'T' (84) is the fifth character; 'X' (88) is not there.
    assert_eq!((int(&rt, "found"), int(&rt, "missing")), (5, 0));
    // A STRING(3) holding 'abc' ends in its zero byte.
    assert_eq!(uint(&rt, "tail"), 0);
}

/// OSCAT's REAL_TO_DW and DW_TO_REAL read a REAL's IEEE-754 bits through a pointer.
#[test]
fn real_bits_through_a_dword_pointer() {
    let rt = codesys(
        "FUNCTION REAL_TO_DW : DWORD
VAR_INPUT X : REAL; END_VAR
VAR pt : POINTER TO DWORD; END_VAR
pt := ADR(X);
REAL_TO_DW := pt^;
END_FUNCTION

FUNCTION DW_TO_REAL : REAL
VAR_INPUT X : DWORD; END_VAR
VAR pt : POINTER TO REAL; END_VAR
pt := ADR(X);
DW_TO_REAL := pt^;
END_FUNCTION

PROGRAM P
VAR one, half, neg : DWORD; r : REAL; w : WORD; pw : POINTER TO WORD; x : REAL := 1.0; END_VAR
one := REAL_TO_DW(1.0);
half := REAL_TO_DW(0.5);
neg := REAL_TO_DW(-2.5);
r := DW_TO_REAL(16#41200000);
pw := ADR(x) + 2;
w := pw^;
END_PROGRAM",
    );
    assert_eq!(uint(&rt, "one"), 0x3F80_0000);
    assert_eq!(uint(&rt, "half"), 0x3F00_0000);
    assert_eq!(uint(&rt, "neg"), 0xC020_0000);
    // 16#41200000: exponent 130, mantissa 1.25: 10.0.
    assert_eq!(real(&rt, "r"), 10.0);
    // The high WORD of 1.0's bits, at byte 2 (little-endian).
    assert_eq!(uint(&rt, "w"), 0x3F80);
}

/// OSCAT's array functions take `ADR(arr)` and `SIZEOF(arr)` and count elements with
/// CODESYS's sizes (`SHR(size, 2)` REALs).
#[test]
fn oscat_style_array_functions_over_adr_and_sizeof() {
    let rt = codesys(
        "FUNCTION ARRAY_AVG : REAL
VAR_INPUT pt : POINTER TO ARRAY[0..32000] OF REAL; size : UINT; END_VAR
VAR i, stop : UINT; END_VAR
stop := SHR(size, 2) - 1;
ARRAY_AVG := pt^[0];
FOR i := 1 TO stop DO
  ARRAY_AVG := ARRAY_AVG + pt^[i];
END_FOR
ARRAY_AVG := ARRAY_AVG / UINT_TO_REAL(stop + 1);
END_FUNCTION

FUNCTION INT_AVG : REAL
VAR_INPUT pt : POINTER TO ARRAY[0..32000] OF INT; size : UINT; END_VAR
VAR i, stop : UINT; sum : DINT; END_VAR
stop := SHR(size, 1) - 1;
sum := 0;
FOR i := 0 TO stop DO
  sum := sum + pt^[i];
END_FOR
INT_AVG := DINT_TO_REAL(sum) / UINT_TO_REAL(stop + 1);
END_FUNCTION

PROGRAM P
VAR
  r : ARRAY[1..4] OF REAL := [1.0, 2.0, 3.0, 4.0];
  i : ARRAY[1..4] OF INT := [1, 2, 3, 4];
  avg_r, avg_i : REAL;
END_VAR
avg_r := ARRAY_AVG(ADR(r), SIZEOF(r));
avg_i := INT_AVG(ADR(i), SIZEOF(i));
END_PROGRAM",
    );
    assert_eq!(real(&rt, "avg_r"), 2.5);
    assert_eq!(real(&rt, "avg_i"), 2.5);
}

#[test]
fn pointers_outside_memory_fault_with_their_code() {
    // A null pointer.
    let mut rt =
        plc("PROGRAM P\nVAR p : POINTER TO DWORD; x : DWORD := 1; END_VAR\nx := p^;\nEND_PROGRAM");
    let f = rt.scan(ms(0)).expect_err("null pointer");
    assert_eq!((f.code(), f.line), ("null-reference", 3));
    assert_eq!(uint(&rt, "x"), 1);

    // Far past the end of the program's memory, for reading and for writing.
    let mut rt = plc("PROGRAM P
VAR p : POINTER TO DWORD; x : DWORD := 1; END_VAR
p := ADR(x);
p := p + 100000000;
x := p^;
END_PROGRAM");
    let f = rt.scan(ms(0)).expect_err("beyond memory");
    assert_eq!((f.code(), f.line), ("pointer-out-of-range", 5));
    assert_eq!(uint(&rt, "x"), 1);
    let mut rt = plc("PROGRAM P
VAR p : POINTER TO LREAL; a : LWORD; END_VAR
a := 4;
p := a;
p^ := 2.0;
END_PROGRAM");
    let f = rt.scan(ms(0)).expect_err("into the first bytes");
    assert_eq!((f.code(), f.line), ("pointer-out-of-range", 5));

    // An index within the declared bounds of an array reached through a pointer, but
    // past the memory's end.
    let mut rt = codesys_unscanned(
        "PROGRAM P
VAR p : POINTER TO ARRAY[0..32000] OF REAL; small : ARRAY[0..1] OF REAL; y : REAL; END_VAR
p := ADR(small);
y := p^[1];
y := p^[32000];
END_PROGRAM",
    );
    let f = rt.scan(ms(0)).expect_err("past the end through an index");
    assert_eq!((f.code(), f.line), ("pointer-out-of-range", 5));
}

fn codesys_unscanned(src: &str) -> Runtime {
    let options = CompileOptions {
        conversions: Conversions::Codesys,
        ..CompileOptions::default()
    };
    let program =
        compile_sources(&[(src, "layout.st")], &options).unwrap_or_else(|e| panic!("{e}"));
    Runtime::new(Arc::new(program))
}

/// A standard block's INT input written at its own width (2 bytes) is read as the INT it
/// is: a negative preset stays negative.
#[test]
fn standard_blocks_read_narrow_inputs_at_their_width() {
    let rt = plc_scanned(
        "PROGRAM P
VAR down : CTD; up : CTU; q_down, q_up : BOOL; cv_down : INT; END_VAR
down(CD := FALSE, LD := TRUE, PV := -2, Q => q_down, CV => cv_down);
up(CU := FALSE, R := FALSE, PV := -1, Q => q_up);
END_PROGRAM",
    );
    // CTD loads CV with PV: -2, and Q is CV <= 0; CTU's Q is CV (0) >= PV (-1).
    assert_eq!(int(&rt, "cv_down"), -2);
    assert!(boolean(&rt, "q_down"));
    assert!(boolean(&rt, "q_up"));
}
