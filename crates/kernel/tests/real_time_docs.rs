//! Every public function of the real-time crates says in its doc comment whether it may run
//! on a real-time path: a line `Real-time: yes (...)` or `Real-time: no (...)`, so that the
//! author of a periodic task can tell without reading the code. What the lines say is kept
//! true by the allocation tests (`no_alloc.rs` here, `no_allocation.rs` of the PLC, the
//! executive's and the planner's); this test keeps every public function, and every method
//! of a public trait, saying it.

use std::path::{Path, PathBuf};

/// The real-time crates' sources, relative to `crates/`: the executive, the servo loops and
/// the fieldbus whole; the planner's public API (its geometry helpers are private); the
/// PLC's run time (not its compiler); the kernel's handle, faults and messages (its tasks are
/// private; its configuration and links are set-up and surface).
const SCOPE: &[&str] = &[
    "rt/src",
    "servo/src",
    "fieldbus/src",
    "motion/src/planner.rs",
    "motion/src/input.rs",
    "motion/src/kinematics.rs",
    "motion/src/limits.rs",
    "motion/src/axes.rs",
    "motion/src/error.rs",
    "motion/src/otg",
    "plc/src/runtime",
    "plc/src/value.rs",
    "plc/src/lib.rs",
    "plc/src/program.rs",
    "plc/src/signals.rs",
    "plc/src/error.rs",
    "kernel/src/kernel.rs",
    "kernel/src/fault.rs",
    "kernel/src/messages.rs",
    "kernel/src/kinematics.rs",
    "kernel/src/modal.rs",
    "kernel/src/shared.rs",
    "kernel/src/error.rs",
];

fn rust_files(path: &Path, out: &mut Vec<PathBuf>) {
    if path.is_dir() {
        let mut entries: Vec<PathBuf> = std::fs::read_dir(path)
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
            .map(|entry| entry.expect("a folder entry").path())
            .collect();
        entries.sort();
        for entry in entries {
            rust_files(&entry, out);
        }
    } else if path.extension().is_some_and(|e| e == "rs") {
        out.push(path.to_path_buf());
    }
}

/// The name of the function a line declares when it is a public function, or `fn` inside a
/// public trait (`in_trait`).
fn declared_function(line: &str, in_trait: bool) -> Option<&str> {
    let mut rest = line.trim_start();
    if !in_trait {
        rest = rest.strip_prefix("pub ")?;
    }
    for qualifier in ["const ", "unsafe ", "async "] {
        rest = rest.strip_prefix(qualifier).unwrap_or(rest);
    }
    let rest = rest.strip_prefix("fn ")?;
    let end = rest
        .find(|c: char| !(c.is_alphanumeric() || c == '_'))
        .unwrap_or(rest.len());
    Some(&rest[..end])
}

/// True when the doc comment above line `at` (past its attributes) has a real-time line.
fn says_real_time(lines: &[&str], at: usize) -> bool {
    let mut i = at;
    while i > 0 && lines[i - 1].trim_start().starts_with("#[") {
        i -= 1;
    }
    while i > 0 && lines[i - 1].trim_start().starts_with("///") {
        i -= 1;
        let text = lines[i].trim_start().trim_start_matches("///").trim_start();
        if text.starts_with("Real-time: yes") || text.starts_with("Real-time: no") {
            return true;
        }
    }
    false
}

/// Braces a line opens minus those it closes, outside comments, strings and characters.
fn brace_balance(line: &str) -> i32 {
    let code = line.split("//").next().unwrap_or("");
    let mut balance = 0;
    let mut in_string = false;
    let mut chars = code.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '\\' if in_string => {
                chars.next();
            }
            '"' => in_string = !in_string,
            '\'' if !in_string => {
                // A character literal such as '{' (a lifetime has no closing quote).
                let literal: String = chars.clone().take(3).collect();
                if literal.chars().nth(1) == Some('\'') {
                    chars.next();
                    chars.next();
                }
            }
            '{' if !in_string => balance += 1,
            '}' if !in_string => balance -= 1,
            _ => {}
        }
    }
    balance
}

/// Public functions and public traits' methods of `source` without a real-time line.
fn unmarked(source: &str) -> Vec<(usize, String)> {
    let lines: Vec<&str> = source.lines().collect();
    // A file's unit tests come last, behind `#[cfg(test)] mod ...`.
    let end = (0..lines.len())
        .find(|&i| {
            lines[i].trim() == "#[cfg(test)]"
                && lines
                    .get(i + 1)
                    .is_some_and(|l| l.trim_start().starts_with("mod "))
        })
        .unwrap_or(lines.len());
    let mut missing = Vec::new();
    let mut depth = 0;
    let mut trait_depth: Option<i32> = None;
    for (i, line) in lines[..end].iter().enumerate() {
        let trimmed = line.trim_start();
        let in_trait = trait_depth.is_some_and(|d| depth == d + 1);
        if let Some(name) = declared_function(line, in_trait) {
            if !says_real_time(&lines, i) {
                missing.push((i + 1, name.to_string()));
            }
        }
        if trimmed.starts_with("pub trait ") || trimmed.starts_with("pub unsafe trait ") {
            trait_depth = Some(depth);
        }
        depth += brace_balance(line);
        if trait_depth.is_some_and(|d| depth <= d) && !trimmed.starts_with("pub ") {
            trait_depth = None;
        }
    }
    missing
}

#[test]
fn every_public_function_of_the_real_time_crates_says_whether_it_is_real_time() {
    let crates = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut files = Vec::new();
    for part in SCOPE {
        let path = crates.join(part);
        assert!(path.exists(), "{} is gone: update SCOPE", path.display());
        rust_files(&path, &mut files);
    }
    let mut missing = Vec::new();
    let mut checked = 0;
    for file in &files {
        let source = std::fs::read_to_string(file).expect("a readable source");
        checked += source.matches("Real-time: ").count();
        for (line, name) in unmarked(&source) {
            missing.push(format!("{}:{line}: {name}", file.display()));
        }
    }
    assert!(
        missing.is_empty(),
        "public functions without a \"Real-time: yes/no\" line in their doc:\n{}",
        missing.join("\n")
    );
    // The walk found the crates' functions (a broken path or pattern would find none).
    assert!(checked > 500, "only {checked} real-time lines found");
}

#[test]
fn the_scanner_finds_unmarked_functions() {
    let source = "
/// Documented.
///
/// Real-time: yes (no allocation, no blocking).
pub fn marked() {}

/// Documented only.
#[inline]
pub const fn unmarked_one() {}

pub trait Bus {
    /// Real-time: no (allocates).
    fn marked_method(&self);
    /// Nothing.
    fn unmarked_method(&self) { let _ = '{'; }
}

fn private() {}

#[cfg(test)]
mod tests {
    pub fn in_tests() {}
}
";
    let found: Vec<String> = unmarked(source).into_iter().map(|(_, n)| n).collect();
    assert_eq!(found, ["unmarked_one", "unmarked_method"]);
}
