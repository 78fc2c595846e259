//! Checks how much of a CODESYS 2.3 export (`.EXP`/`.TXT`, Windows-1252) compiles with
//! CODESYS's conversions: splits it into its objects, compiles them together, drops every
//! object an error names and compiles the rest again until it compiles; prints the count
//! of each kind kept and the first error of each object dropped.
//!
//! With `--run FILE`, compiles FILE (Structured Text holding one PROGRAM) with the objects
//! that compile, scans it (once, or `--scans N` times 10 ms apart) and prints the
//! PROGRAM's variables: a way to try the library's functions and blocks.
//!
//! Usage: `cargo run -p rtcnc-plc --example export_check -- EXPORT [--keep DIR]
//! [--run FILE [--scans N]]`

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use std::sync::Arc;
use std::time::Duration;

use rtcnc_plc::{CompileOptions, Conversions, LoadError, Runtime, SourceEncoding, compile_files};

struct Object {
    name: String,
    kind: &'static str,
    path: PathBuf,
}

/// An export starts each object with its `(* @NESTEDCOMMENTS := ... *)` pragma.
fn split(bytes: &[u8]) -> Vec<&[u8]> {
    let mut starts = Vec::new();
    let mut line_start = 0;
    for (i, &b) in bytes.iter().enumerate() {
        if i == line_start && bytes[i..].starts_with(b"(* @NESTEDCOMMENTS") {
            starts.push(i);
        }
        if b == b'\n' {
            line_start = i + 1;
        }
    }
    starts.push(bytes.len());
    starts.windows(2).map(|w| &bytes[w[0]..w[1]]).collect()
}

fn kind_and_name(object: &[u8]) -> (&'static str, String) {
    let text = String::from_utf8_lossy(object);
    for line in text.lines() {
        let words: Vec<&str> = line.split_whitespace().collect();
        let name = |i: usize| {
            words
                .get(i)
                .map(|w| w.trim_end_matches(':').to_string())
                .unwrap_or_default()
        };
        match words.first().copied() {
            // CODESYS 2.3 also reads FUNCTIONBLOCK.
            Some("FUNCTION_BLOCK") | Some("FUNCTIONBLOCK") => return ("function block", name(1)),
            Some("FUNCTION") => return ("function", name(1)),
            Some("PROGRAM") => return ("program", name(1)),
            Some("TYPE") => return ("type", name(1)),
            Some("VAR_GLOBAL") | Some("VAR_CONFIG") => return ("global list", String::new()),
            _ => {}
        }
    }
    ("other", String::new())
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(export) = args.first() else {
        eprintln!("usage: export_check EXPORT [--keep DIR] [--run FILE [--scans N]]");
        return ExitCode::from(2);
    };
    let dir = match args.iter().position(|a| a == "--keep") {
        Some(i) => PathBuf::from(args.get(i + 1).cloned().unwrap_or_default()),
        None => std::env::temp_dir().join(format!("export_check.{}", std::process::id())),
    };
    let bytes = match std::fs::read(export) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("{export}: {e}");
            return ExitCode::from(2);
        }
    };
    if let Err(e) = std::fs::create_dir_all(&dir) {
        eprintln!("{}: {e}", dir.display());
        return ExitCode::from(2);
    }
    let mut objects = Vec::new();
    for (i, part) in split(&bytes).into_iter().enumerate() {
        let (kind, mut name) = kind_and_name(part);
        if kind == "other" {
            continue;
        }
        if name.is_empty() {
            name = format!("globals{i}");
        }
        let path = dir.join(format!("{i:04}_{name}.st"));
        if let Err(e) = std::fs::write(&path, part) {
            eprintln!("{}: {e}", path.display());
            return ExitCode::from(2);
        }
        objects.push(Object { name, kind, path });
    }
    let options = CompileOptions {
        encoding: SourceEncoding::Windows1252,
        conversions: Conversions::Codesys,
        ..CompileOptions::default()
    };
    let mut dropped: BTreeMap<String, String> = BTreeMap::new();
    let mut kept: Vec<&Object> = objects.iter().collect();
    loop {
        let paths: Vec<&Path> = kept.iter().map(|o| o.path.as_path()).collect();
        match compile_files(&paths, &options) {
            Ok(program) => {
                println!(
                    "compiled: {} POUs, {} bytes of memory",
                    program.pou_count(),
                    program.memory_bytes()
                );
                break;
            }
            Err(LoadError::Compile(errors)) => {
                let mut failing = BTreeSet::new();
                for e in &errors.0 {
                    if let Some(o) = kept.iter().find(|o| o.path.display().to_string() == e.file) {
                        dropped
                            .entry(o.name.clone())
                            .or_insert_with(|| e.to_string());
                        failing.insert(o.path.clone());
                    }
                }
                if failing.is_empty() {
                    eprintln!("errors name no object: {errors}");
                    return ExitCode::from(1);
                }
                kept.retain(|o| !failing.contains(&o.path));
            }
            Err(e) => {
                eprintln!("{e}");
                return ExitCode::from(2);
            }
        }
    }
    let mut counts: BTreeMap<&str, (usize, usize)> = BTreeMap::new();
    for o in &objects {
        counts.entry(o.kind).or_default().1 += 1;
    }
    for o in &kept {
        counts.entry(o.kind).or_default().0 += 1;
    }
    println!("{} of {} objects compile", kept.len(), objects.len());
    for (kind, (ok, all)) in &counts {
        println!("  {kind}: {ok} of {all}");
    }
    for (name, error) in &dropped {
        println!("dropped {name}: {error}");
    }
    match args.iter().position(|a| a == "--run") {
        Some(i) => {
            let scans = args
                .iter()
                .position(|a| a == "--scans")
                .and_then(|j| args.get(j + 1))
                .and_then(|n| n.parse().ok())
                .unwrap_or(1);
            let driver = args.get(i + 1).map(String::as_str).unwrap_or("");
            run(&kept, driver, scans, &options)
        }
        None => ExitCode::SUCCESS,
    }
}

fn run(kept: &[&Object], driver: &str, scans: u64, options: &CompileOptions) -> ExitCode {
    let program_name = std::fs::read_to_string(driver)
        .ok()
        .and_then(|text| {
            text.lines().find_map(|l| {
                let mut words = l.split_whitespace();
                (words.next() == Some("PROGRAM")).then(|| words.next().map(str::to_uppercase))?
            })
        })
        .unwrap_or_default();
    let mut paths: Vec<&Path> = kept.iter().map(|o| o.path.as_path()).collect();
    paths.push(Path::new(driver));
    let options = CompileOptions {
        encoding: SourceEncoding::Auto,
        ..options.clone()
    };
    let program = match compile_files(&paths, &options) {
        Ok(p) => Arc::new(p),
        Err(e) => {
            eprintln!("{e}");
            return ExitCode::from(1);
        }
    };
    let mut runtime = Runtime::new(program.clone());
    for k in 0..scans {
        if let Err(fault) = runtime.scan(Duration::from_millis(10 * k)) {
            eprintln!("fault at scan {}: {fault}", k + 1);
            return ExitCode::from(1);
        }
    }
    let prefix = format!("{program_name}.");
    for v in program.variables() {
        if v.path.starts_with(&prefix)
            && let Ok(r) = runtime.resolve(&v.path)
        {
            println!("{} = {}", v.path, runtime.format(&r));
        }
    }
    ExitCode::SUCCESS
}
