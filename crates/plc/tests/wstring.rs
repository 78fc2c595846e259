//! WSTRING: UTF-16 strings as in CODESYS and TwinCAT (`"..."` literals, `$"`, `$hhhh`),
//! the string functions on them and the conversions to and from STRING and numbers.
//! Expected values are worked out by hand: "Grüße" is G r ü ß e, five UTF-16 code units
//! (ü U+00FC, ß U+00DF) and five Windows-1252 bytes in a STRING (0xFC, 0xDF); `€` is
//! U+20AC, byte 0x80 in Windows-1252.

use crate::common::*;

#[test]
fn literals_escapes_and_length_count_code_units() {
    let rt = eval(
        "a : WSTRING := \"Grüße\"; b : WSTRING(10) := \"a$\"b$$c\"; euro : WSTRING := \"$20AC\";
         nl : WSTRING := \"x$Ny\"; s : STRING := 'Grüße';
         la, lb, le, ls : INT; same_euro : BOOL;",
        "la := LEN(a); lb := LEN(b); le := LEN(euro); ls := LEN(s);
         same_euro := euro = \"€\";",
    );
    assert_eq!(string(&rt, "a"), "Grüße");
    assert_eq!(int(&rt, "la"), 5);
    assert_eq!(string(&rt, "b"), "a\"b$c");
    assert_eq!(int(&rt, "lb"), 5);
    assert_eq!(string(&rt, "euro"), "€");
    assert_eq!(int(&rt, "le"), 1);
    assert!(boolean(&rt, "same_euro"));
    assert_eq!(string(&rt, "nl"), "x\ny");
    // The STRING of the same text holds one Windows-1252 byte a character, as CODESYS.
    assert_eq!(int(&rt, "ls"), 5);
}

#[test]
fn assignment_cuts_to_the_declared_length_and_comparison_orders_by_code_unit() {
    let rt = eval(
        "short : WSTRING(3); w : WSTRING(80); lt, gt, eq, ne : BOOL; n : INT;",
        "short := \"Grüße\"; n := LEN(short); w := short;
         lt := \"abc\" < \"abd\"; gt := \"é\" > \"z\"; eq := w = \"Grü\"; ne := w <> \"Gru\";",
    );
    assert_eq!(string(&rt, "short"), "Grü");
    assert_eq!(int(&rt, "n"), 3);
    assert_eq!(string(&rt, "w"), "Grü");
    assert!(boolean(&rt, "lt"));
    // é is U+00E9, above z (U+007A).
    assert!(boolean(&rt, "gt"));
    assert!(boolean(&rt, "eq"));
    assert!(boolean(&rt, "ne"));
}

#[test]
fn string_functions_work_on_code_units() {
    let rt = eval(
        "a : WSTRING := \"Grüße\";
         l, r, m, c, i, d, rep : WSTRING; f, f0 : INT;",
        "l := LEFT(a, 3); r := RIGHT(a, 2); m := MID(a, 2, 3);
         c := CONCAT(a, \" \", \"€\"); i := INSERT(\"Gre\", \"ü\", 2);
         d := DELETE(a, 2, 2); rep := REPLACE(a, \"u\", 1, 3);
         f := FIND(a, \"ße\"); f0 := FIND(a, \"x\");",
    );
    assert_eq!(string(&rt, "l"), "Grü");
    assert_eq!(string(&rt, "r"), "ße");
    // MID(IN, L := 2, P := 3): two characters from the third.
    assert_eq!(string(&rt, "m"), "üß");
    assert_eq!(string(&rt, "c"), "Grüße €");
    // INSERT after position 2.
    assert_eq!(string(&rt, "i"), "Grüe");
    // DELETE two characters from position 2: r and ü go.
    assert_eq!(string(&rt, "d"), "Gße");
    assert_eq!(string(&rt, "rep"), "Gruße");
    assert_eq!(int(&rt, "f"), 4);
    assert_eq!(int(&rt, "f0"), 0);
}

#[test]
fn conversions_keep_non_ascii_text_and_numbers() {
    let rt = eval(
        "a : WSTRING := \"Grüße €\"; s : STRING; back : WSTRING; ls, lb : INT;
         wi, wr, wb, wt, ws : WSTRING; i : INT; r : REAL; t : TIME; s2 : STRING;",
        "s := WSTRING_TO_STRING(a); ls := LEN(s); back := STRING_TO_WSTRING(s); lb := LEN(back);
         wi := INT_TO_WSTRING(-42); wr := TO_WSTRING(REAL#2.5); wb := TO_WSTRING(TRUE);
         wt := TIME_TO_WSTRING(T#1s500ms); ws := TO_WSTRING('abc');
         i := WSTRING_TO_INT(\" 123\"); r := WSTRING_TO_REAL(\"1.25\"); t := WSTRING_TO_TIME(\"T#2s\");
         s2 := TO_STRING(\"xyz\");",
    );
    // Windows-1252: one byte for each of the 7 characters (€ is 0x80).
    assert_eq!(string(&rt, "s"), "Grüße €");
    assert_eq!(int(&rt, "ls"), 7);
    assert_eq!(string(&rt, "back"), "Grüße €");
    assert_eq!(int(&rt, "lb"), 7);
    assert_eq!(string(&rt, "wi"), "-42");
    assert_eq!(string(&rt, "wr"), "2.5");
    assert_eq!(string(&rt, "wb"), "TRUE");
    assert_eq!(string(&rt, "ws"), "abc");
    assert_eq!(int(&rt, "i"), 123);
    assert_eq!(real(&rt, "r"), 1.25);
    assert_eq!(time_ms(&rt, "t"), 2000.0);
    assert_eq!(string(&rt, "s2"), "xyz");
    // TIME_TO_STRING's form, widened.
    let text = string(&rt, "wt");
    let narrow = eval("s : STRING;", "s := TIME_TO_STRING(T#1s500ms);");
    assert_eq!(text, string(&narrow, "s"));
}

#[test]
fn wstrings_pass_through_blocks_functions_and_structures() {
    let mut rt = plc("TYPE Label : STRUCT text : WSTRING(20); END_STRUCT END_TYPE
FUNCTION Greet : WSTRING
VAR_INPUT name : WSTRING; END_VAR
Greet := CONCAT(\"Grüß \", name);
END_FUNCTION
FUNCTION_BLOCK Tag
VAR_INPUT IN : WSTRING(10); END_VAR
VAR_OUTPUT OUT : WSTRING(12); END_VAR
OUT := CONCAT(\"[\", IN, \"]\");
END_FUNCTION_BLOCK
PROGRAM P
VAR g : WSTRING; t : Tag; o : WSTRING; l : Label; size : UDINT; END_VAR
g := Greet(\"Jörg\");
t(IN := \"ÄÖÜ\", OUT => o);
l.text := o;
size := SIZEOF(l);
END_PROGRAM");
    rt.scan(ms(0)).expect("scan");
    assert_eq!(string(&rt, "g"), "Grüß Jörg");
    assert_eq!(string(&rt, "o"), "[ÄÖÜ]");
    assert_eq!(string(&rt, "l.text"), "[ÄÖÜ]");
    // A WSTRING(20) in CODESYS: 20 code units and the terminating zero, 2 bytes each.
    assert_eq!(uint(&rt, "size"), 42);
}

#[test]
fn mixing_string_and_wstring_needs_a_conversion() {
    let (line, _, code, msg) = compile_error(
        "PROGRAM P VAR w : WSTRING; END_VAR
w := 'abc';
END_PROGRAM",
    );
    assert_eq!((line, code), (2, "type-mismatch"), "{msg}");
    let (line, _, code, msg) = compile_error(
        "PROGRAM P VAR w : WSTRING; END_VAR
w := CONCAT(w, 'x');
END_PROGRAM",
    );
    assert_eq!((line, code), (2, "wrong-argument"), "{msg}");
    let (line, _, code, msg) = compile_error(
        "PROGRAM P VAR w : WSTRING; n : INT; END_VAR
n := FIND(w, 'x');
END_PROGRAM",
    );
    assert_eq!((line, code), (2, "wrong-argument"), "{msg}");
    let (line, _, code, msg) = compile_error(
        "PROGRAM P VAR w : WSTRING; END_VAR
w := \"abc;
END_PROGRAM",
    );
    assert_eq!((line, code), (2, "syntax"), "{msg}");
    assert!(msg.contains("'\"' expected"), "{msg}");
}

#[test]
fn a_wstring_can_be_watched_and_forced_like_a_string() {
    let mut rt = plc("PROGRAM P VAR w : WSTRING(8); n : INT; END_VAR n := LEN(w); END_PROGRAM");
    let w = rt.resolve("w").unwrap();
    let value = rt.parse_value(&w, "\"ÅÉ€\"").unwrap();
    assert_eq!(value, rtcnc_plc::Value::String("ÅÉ€".into()));
    set(&mut rt, "w", value);
    rt.scan(ms(0)).expect("scan");
    assert_eq!(string(&rt, "w"), "ÅÉ€");
    assert_eq!(int(&rt, "n"), 3);
}

#[test]
fn a_retained_wstring_survives_a_restart_through_the_file() {
    let dir = std::env::temp_dir().join(format!("rtcnc-plc-wretain-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("retain.txt");
    let src = "PROGRAM P VAR RETAIN label : WSTRING(12); END_VAR
IF LEN(label) = 0 THEN label := \"Grüße $\"€$\" $$\"; END_IF
END_PROGRAM";
    let mut a = plc(src);
    a.scan(ms(0)).unwrap();
    a.save_retain(&path).unwrap();
    let mut b = plc(src);
    let report = b.load_retain(&path).unwrap();
    assert_eq!((report.restored, report.skipped), (1, 0));
    assert_eq!(string(&b, "label"), "Grüße \"€\" $");
    let n = eval(
        "n : INT; w : WSTRING := \"Grüße $\"€$\" $$\";",
        "n := LEN(w);",
    );
    // G r ü ß e, space, quote, €, quote, space, $: eleven code units.
    assert_eq!(int(&n, "n"), 11);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn arrays_of_wstring_start_empty_and_wide() {
    // An element never written is an empty WSTRING: CONCAT of it keeps the result wide,
    // so "ä" (U+00E4, one code unit) stays one character.
    let rt = eval(
        "names : ARRAY[1..3] OF WSTRING(4); n, k : INT;",
        "names[2] := CONCAT(names[1], \"ä\"); n := LEN(names[2]);
         FOR k := 1 TO 3 DO names[3] := CONCAT(names[3], \"€\"); END_FOR;",
    );
    assert_eq!(string(&rt, "names[1]"), "");
    assert_eq!(string(&rt, "names[2]"), "ä");
    assert_eq!(int(&rt, "n"), 1);
    assert_eq!(string(&rt, "names[3]"), "€€€");
}
