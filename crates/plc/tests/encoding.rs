//! Source files in Windows-1252 (what CODESYS 2.3 exports) and STRING as one byte a
//! character. Expected values by hand: "Grüße" is five characters; in Windows-1252 ü is
//! 0xFC and ß 0xDF, in UTF-8 each takes two bytes.

use crate::common::*;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use rtcnc_plc::{CompileOptions, LoadError, Runtime, SourceEncoding, compile_files};

const PROGRAM_HEAD: &str = "PROGRAM P\nVAR s : STRING := '";
const PROGRAM_TAIL: &str = "'; n, f : INT; m : STRING; END_VAR\n\
n := LEN(s); f := FIND(s, 'e'); m := MID(s, 2, 3);\nEND_PROGRAM\n";

/// A file of the program with the literal's characters written as `text` bytes.
fn source_file(name: &str, text: &[u8]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rtcnc-plc-encoding-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join(name);
    let mut bytes = PROGRAM_HEAD.as_bytes().to_vec();
    bytes.extend_from_slice(text);
    bytes.extend_from_slice(PROGRAM_TAIL.as_bytes());
    std::fs::write(&path, bytes).expect("write source");
    path
}

fn run(path: &Path, encoding: SourceEncoding) -> Result<Runtime, LoadError> {
    let options = CompileOptions {
        encoding,
        ..CompileOptions::default()
    };
    let program = compile_files(&[path], &options)?;
    let mut rt = Runtime::new(Arc::new(program));
    rt.scan(ms(0)).expect("scan");
    Ok(rt)
}

#[test]
fn a_windows_1252_file_is_read_as_such_and_len_counts_characters_as_codesys() {
    let path = source_file("latin.st", b"Gr\xfc\xdfe");
    let rt = run(&path, SourceEncoding::Auto).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(string(&rt, "s"), "Grüße");
    // CODESYS: LEN('Grüße') = 5, 'e' is the fifth character, MID(s, 2, 3) = 'üß'.
    assert_eq!(int(&rt, "n"), 5);
    assert_eq!(int(&rt, "f"), 5);
    assert_eq!(string(&rt, "m"), "üß");
    let forced = run(&path, SourceEncoding::Windows1252).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(int(&forced, "n"), 5);

    let Err(err) = run(&path, SourceEncoding::Utf8) else {
        panic!("UTF-8 forced: refused")
    };
    assert!(err.to_string().contains("not valid UTF-8"), "{err}");
    std::fs::remove_file(path).expect("remove");
}

#[test]
fn a_utf8_file_of_the_same_text_gives_the_same_string() {
    let path = source_file("utf8.st", "Grüße".as_bytes());
    let rt = run(&path, SourceEncoding::Auto).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(string(&rt, "s"), "Grüße");
    assert_eq!(int(&rt, "n"), 5);
    assert_eq!(string(&rt, "m"), "üß");
    // Read as Windows-1252, the UTF-8 bytes of ü and ß are two characters each.
    let rt = run(&path, SourceEncoding::Windows1252).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(int(&rt, "n"), 7);
    assert_eq!(string(&rt, "s"), "GrÃ¼ÃŸe");
    std::fs::remove_file(path).expect("remove");
}

#[test]
fn a_string_holds_windows_1252_and_refuses_or_replaces_what_it_lacks() {
    // € is 0x80 in Windows-1252: one character. Comparison orders by byte: ä (0xE4) > z.
    let rt = eval(
        "e : STRING := '5 €'; w : WSTRING := \"Ω=1\"; s : STRING; n, ns : INT; gt : BOOL;",
        "n := LEN(e); s := WSTRING_TO_STRING(w); ns := LEN(s); gt := 'ä' > 'z';",
    );
    assert_eq!(int(&rt, "n"), 3);
    assert_eq!(string(&rt, "e"), "5 €");
    // Ω is not in Windows-1252: '?' as CODESYS converts.
    assert_eq!(string(&rt, "s"), "?=1");
    assert_eq!(int(&rt, "ns"), 3);
    assert!(boolean(&rt, "gt"));

    let (line, col, code, msg) =
        compile_error("PROGRAM P\nVAR s : STRING; END_VAR\ns := 'Ω';\nEND_PROGRAM\n");
    assert_eq!((line, col, code), (3, 6, "syntax"), "{msg}");
    assert!(msg.contains("use a WSTRING"), "{msg}");
}
