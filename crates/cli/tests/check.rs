//! `rtcnc check` end to end: the canonical text equals rs274's for a corpus program, errors
//! name file, line and column and set the exit status.

use std::path::{Path, PathBuf};
use std::process::Command;

fn corpus(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../gcode/tests/corpus")
        .join(name)
}

#[test]
fn canon_output_equals_rs274_text() {
    let out = Command::new(env!("CARGO_BIN_EXE_rtcnc"))
        .args(["check", "--canon", "--user-units", "inch", "--tool-table"])
        .arg(corpus("canon.tbl"))
        .arg(corpus("090_full_program.ngc"))
        .output()
        .unwrap();
    assert!(out.status.success());
    let expected = std::fs::read_to_string(corpus("090_full_program.canon")).unwrap();
    assert_eq!(String::from_utf8(out.stdout).unwrap(), expected);
}

#[test]
fn errors_are_reported_with_their_place_and_fail_the_check() {
    let dir = std::env::temp_dir().join(format!("rtcnc-check-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let program = dir.join("bad.ngc");
    std::fs::write(&program, "G0 X1\nG1 X2 F100 Q3\nG0 X[1/0]\nM2\n").unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_rtcnc"))
        .arg("check")
        .arg(&program)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8(out.stderr).unwrap();
    let lines: Vec<&str> = stderr.lines().collect();
    let file = program.display().to_string();
    assert!(
        lines[0].starts_with(&format!("{file}:2:12: Q word")),
        "{stderr}"
    );
    assert!(
        lines[1].starts_with(&format!("{file}:3:7: division by zero")),
        "{stderr}"
    );
    assert!(
        String::from_utf8(out.stdout)
            .unwrap()
            .contains("2 error(s)")
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

fn comp_corpus(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../gcode/tests/comp_corpus")
        .join(name)
}

#[test]
fn canon_output_is_cutter_compensated_like_rs274() {
    // rs274 compensates inside its interpreter, so its text for a G41 program is the path of
    // the tool's centre: offset lines, arcs around the convex corners.
    // The expected text is rs274's with its 7-character N column, which for a held move
    // names the block that released it; rtcnc keeps the move's own block there, so the
    // commands are compared without that column.
    let out = Command::new(env!("CARGO_BIN_EXE_rtcnc"))
        .args(["check", "--canon"])
        .arg(comp_corpus("square_outside_g41.ngc"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let expected: String = std::fs::read_to_string(comp_corpus("square_outside_g41.expected"))
        .unwrap()
        .lines()
        .map(|line| format!("{}\n", &line[7..]))
        .collect();
    assert_eq!(String::from_utf8(out.stdout).unwrap(), expected);
}

#[test]
fn a_compensation_error_names_its_block_and_fails_the_check() {
    let out = Command::new(env!("CARGO_BIN_EXE_rtcnc"))
        .args(["check", "--canon"])
        .arg(comp_corpus("err_entry_too_short.ngc"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(
        stderr.trim_end().ends_with(
            "err_entry_too_short.ngc:4:0: Length of cutter compensation entry move is not \
             greater than the tool radius"
        ),
        "{stderr}"
    );
}
