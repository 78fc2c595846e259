//! Running programs as LinuxCNC 2.9's `rs274` (through the peer harness `canon.sh`) ran
//! them, and comparing with what it printed: same lines, same words, numbers within 1e-4,
//! and an error exactly where rs274 reported one. Shared by the tests that hold rs274's
//! output as data (`corpus/`, `data/`).

#![allow(dead_code)]

use std::path::{Path, PathBuf};

use rtcnc_gcode::compensation::{CompError, Compensate};
use rtcnc_gcode::{GcodeError, Interpreter, Parameters, Settings, ToolTable};

/// The folder of the corpus: its tool table, parameter file and subroutines serve all runs.
pub fn corpus_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus")
}

/// Our output for one program as rs274 prints it (`ON_RESET()` at the end), and the error
/// that stopped it. With `compensate`, cutter radius compensation runs after the
/// interpreter, as in `rtcnc check` (rs274 compensates inside its interpreter).
pub fn run(program: &Path, compensate: bool) -> (String, Option<String>) {
    let dir = corpus_dir();
    let settings = Settings {
        subroutine_path: vec![dir.join("subs")],
        ..Settings::rs274()
    };
    let tools = ToolTable::load(&dir.join("canon.tbl")).expect("canon.tbl");
    // A program may come with its own parameter file NAME.var.
    let own = program.with_extension("var");
    let var = if own.exists() {
        own
    } else {
        dir.join("canon.var")
    };
    let params = Parameters::load(&var).expect("parameter file");
    let mut interp = Interpreter::new(settings, tools, params);
    interp.open(program).expect("open");
    let mut out = Vec::new();
    let mut error = None;
    let name: std::sync::Arc<str> = program.display().to_string().into();
    let commands: Box<dyn Iterator<Item = Result<_, GcodeError>>> = if compensate {
        Box::new(Compensate::new(&mut interp, move |e: CompError| {
            e.into_gcode_error(name.clone())
        }))
    } else {
        Box::new(&mut interp)
    };
    for c in commands {
        match c {
            Ok(c) => {
                c.write_rs274(&mut out, false);
            }
            Err(e) => {
                error = Some(e.to_string());
                break;
            }
        }
    }
    out.extend_from_slice(b"ON_RESET()\n");
    (String::from_utf8(out).expect("utf8"), error)
}

/// Splits a line into text and numbers.
fn tokens(line: &str) -> Vec<Result<f64, String>> {
    let mut v = Vec::new();
    let mut text = String::new();
    let b = line.as_bytes();
    let mut i = 0;
    while i < b.len() {
        let starts_number =
            b[i].is_ascii_digit() || (b[i] == b'-' && i + 1 < b.len() && b[i + 1].is_ascii_digit());
        if starts_number {
            let start = i;
            i += 1;
            while i < b.len() && (b[i].is_ascii_digit() || b[i] == b'.') {
                i += 1;
            }
            if !text.is_empty() {
                v.push(Err(std::mem::take(&mut text)));
            }
            v.push(Ok(line[start..i].parse().unwrap_or(f64::NAN)));
        } else {
            text.push(b[i] as char);
            i += 1;
        }
    }
    if !text.is_empty() {
        v.push(Err(text));
    }
    v
}

/// Same words, numbers within 1e-4.
pub fn same_line(ours: &str, theirs: &str) -> bool {
    let (a, b) = (tokens(ours), tokens(theirs));
    a.len() == b.len()
        && a.iter().zip(&b).all(|(x, y)| match (x, y) {
            (Ok(x), Ok(y)) => (x - y).abs() <= 1e-4 + 1e-12 * y.abs(),
            (Err(x), Err(y)) => x == y,
            _ => false,
        })
}

/// Compares two outputs line by line; describes the first difference.
pub fn compare_lines(ours: &str, expected: &str) -> Result<(), String> {
    let ours_lines: Vec<&str> = ours.lines().collect();
    let their_lines: Vec<&str> = expected.lines().collect();
    for (n, (a, b)) in ours_lines.iter().zip(&their_lines).enumerate() {
        if !same_line(a, b) {
            return Err(format!("line {}: ours `{a}`, rs274 `{b}`", n + 1));
        }
    }
    if ours_lines.len() != their_lines.len() {
        return Err(format!(
            "{} lines, rs274 {} (first extra: ours `{}`, rs274 `{}`)",
            ours_lines.len(),
            their_lines.len(),
            ours_lines.get(their_lines.len()).unwrap_or(&""),
            their_lines.get(ours_lines.len()).unwrap_or(&""),
        ));
    }
    Ok(())
}

/// Compares one program with rs274's `NAME.canon` and `NAME.err`.
pub fn compare(program: &Path, compensate: bool) -> Result<(), String> {
    let expected =
        std::fs::read_to_string(program.with_extension("canon")).map_err(|e| e.to_string())?;
    let expected_err = std::fs::read_to_string(program.with_extension("err")).unwrap_or_default();
    let (ours, error) = run(program, compensate);
    compare_lines(&ours, &expected).map_err(|e| format!("{e}; our error: {error:?}"))?;
    match (error, expected_err.trim().is_empty()) {
        (Some(e), true) => Err(format!("we report `{e}`, rs274 reports no error")),
        (None, false) => Err(format!(
            "rs274 reports `{}`, we report no error",
            expected_err.lines().next().unwrap_or("")
        )),
        _ => Ok(()),
    }
}

/// The programs (`*.ngc`) of a folder, sorted.
pub fn programs(dir: &Path) -> Vec<PathBuf> {
    let mut programs: Vec<PathBuf> = std::fs::read_dir(dir)
        .expect("folder of programs")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "ngc"))
        .collect();
    programs.sort();
    programs
}

/// Compares every program of `dir` but `except`; panics listing the differences.
pub fn all_match(dir: &Path, compensate: bool, except: &[&str], at_least: usize) -> usize {
    let programs: Vec<PathBuf> = programs(dir)
        .into_iter()
        .filter(|p| {
            let stem = p.file_stem().unwrap_or_default().to_string_lossy();
            !except.contains(&stem.as_ref())
        })
        .collect();
    assert!(
        programs.len() >= at_least,
        "{} has only {} programs",
        dir.display(),
        programs.len()
    );
    let failures: Vec<String> = programs
        .iter()
        .filter_map(|p| {
            compare(p, compensate).err().map(|e| {
                format!(
                    "{}: {e}",
                    p.file_name().unwrap_or_default().to_string_lossy()
                )
            })
        })
        .collect();
    assert!(
        failures.is_empty(),
        "{} of {} programs differ from rs274:\n{}",
        failures.len(),
        programs.len(),
        failures.join("\n")
    );
    programs.len()
}
