//! The command line on the inputs and situations that used to panic, hang or fail
//! silently: a closed output, out-of-range arguments, a refused block, SIGTERM.

use std::io::Read as _;
use std::os::unix::process::ExitStatusExt as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use crate::common::stdout_once_running;

fn rtcnc() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_rtcnc"));
    c.current_dir(repo());
    // The shipped machines are written under the data folder: not the user's.
    c.env("XDG_DATA_HOME", env!("CARGO_TARGET_TMPDIR"));
    c
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rtcnc-robust-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Runs `args` with its standard output a pipe whose reading end is closed after the first
/// bytes, as `| head -c 1` does; returns the status and stderr.
fn with_closed_output(args: &[&str]) -> (std::process::ExitStatus, String) {
    let mut child = rtcnc()
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdout = child.stdout.take().unwrap();
    let mut first = [0u8; 1];
    let _ = stdout.read(&mut first);
    drop(stdout);
    let mut stderr = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut stderr)
        .unwrap();
    (child.wait().unwrap(), stderr)
}

/// Ended by SIGPIPE's default action (shell status 141), with nothing on stderr.
fn assert_ended_quietly(status: std::process::ExitStatus, stderr: &str) {
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(!stderr.contains("Broken pipe"), "{stderr}");
    assert!(
        status.signal() == Some(libc::SIGPIPE) || status.code() == Some(141),
        "{status:?} {stderr}"
    );
}

/// A program whose canonical text is far longer than a pipe's buffer.
fn long_program() -> PathBuf {
    let dir = scratch("long");
    let path = dir.join("long.ngc");
    let mut text = String::from("G21 G90\n");
    for i in 0..20_000 {
        text.push_str(&format!("G1 X{} Y{} F1000\n", i % 100, i % 37));
    }
    text.push_str("M2\n");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn check_ends_quietly_when_its_output_is_closed() {
    let program = long_program();
    let (status, stderr) = with_closed_output(&["check", program.to_str().unwrap(), "--canon"]);
    assert_ended_quietly(status, &stderr);
}

#[test]
fn plc_run_ends_quietly_when_its_output_is_closed() {
    let (status, stderr) = with_closed_output(&[
        "plc",
        "run",
        "examples/plc/mill.st",
        "--scans",
        "200000",
        "--watch",
        "spindle_on",
    ]);
    assert_ended_quietly(status, &stderr);
}

#[test]
fn sim_ends_quietly_when_its_output_is_closed() {
    // The report is printed at the end, line by line: the first line read, the pipe
    // closed, the next write ends the process.
    let (status, stderr) = with_closed_output(&[
        "sim",
        "examples/experiment-1.ngc",
        "--machine",
        "configs/experiment-1.toml",
        "-q",
    ]);
    assert!(!stderr.contains("panicked"), "{stderr}");
    // The whole report may fit the pipe before it is closed: then the run ends normally.
    assert!(
        status.success() || status.signal() == Some(libc::SIGPIPE),
        "{status:?} {stderr}"
    );
}

fn refused(args: &[&str], key: &str) {
    let out = rtcnc().args(args).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(stderr.contains(key), "{args:?}: {stderr}");
}

#[test]
fn times_beyond_any_run_are_refused_with_the_argument_named() {
    for limit in ["inf", "1e30", "-1", "0", "nan"] {
        refused(
            &[
                "sim",
                "examples/experiment-1.ngc",
                &format!("--limit={limit}"),
            ],
            "--limit",
        );
    }
    refused(&["run", "--idle", "inf"], "--idle");
    refused(&["run", "--idle", "1e30"], "--idle");
    refused(
        &["run", "examples/bracket.ngc", "--limit", "inf"],
        "--limit",
    );
}

#[test]
fn latency_refuses_a_cpu_the_process_cannot_use() {
    let beyond = rtcnc_rt::allowed_cpus().last().copied().unwrap_or(0) + 1;
    let out = rtcnc()
        .args(["latency", "--duration", "1s", "-q", "--cpu"])
        .arg(beyond.to_string())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains(&format!("CPU {beyond} is not available")),
        "{stderr}"
    );
}

#[test]
fn plc_run_refuses_scans_beyond_the_plc_clock() {
    let out = rtcnc()
        .args([
            "plc",
            "run",
            "examples/plc/mill.st",
            "--scans",
            "18446744073709551615",
            "--period",
            "1s",
        ])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("--scans"), "{stderr}");
}

/// The cycle time `sim` printed, in seconds.
fn cycle_time(stdout: &str) -> f64 {
    let line = stdout
        .lines()
        .find(|l| l.starts_with("cycle time"))
        .unwrap_or_else(|| panic!("{stdout}"));
    line.split_whitespace().nth(2).unwrap().parse().unwrap()
}

#[test]
fn sim_ends_at_a_block_the_kernel_refuses() {
    let dir = scratch("refused");
    for (name, text, fault) in [
        (
            "m68.ngc",
            "G21 G90\nG1 X10 F1000\nM68 E9 Q1\nG1 X20\nM2\n",
            "kernel.aux_refused",
        ),
        (
            "g33.ngc",
            "G21 G90\nS500 M3\nG33 Z-10 K0\nM2\n",
            "kernel.sync_failed",
        ),
    ] {
        let program = dir.join(name);
        std::fs::write(&program, text).unwrap();
        let out = rtcnc()
            .arg("sim")
            .arg(&program)
            .args(["--machine", "configs/sim-mill.toml", "-q", "--limit", "600"])
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert_eq!(out.status.code(), Some(1), "{stdout}");
        assert!(stdout.contains(fault), "{stdout}");
        assert!(stdout.contains("did not reach the end"), "{stdout}");
        // Machine time, not wall time: the refusal comes within the first second of the
        // program; before, the run went on to its limit.
        assert!(cycle_time(&stdout) < 5.0, "{stdout}");
    }
}

#[test]
fn sigterm_makes_a_controlled_stop_and_prints_the_summary() {
    let dir = scratch("sigterm");
    let program = dir.join("slow.ngc");
    std::fs::write(&program, "G21 G90 G1 X500 F600\nM2\n").unwrap();
    let mut child = rtcnc()
        .args(["run", "--machine", "configs/bench-xyz.toml"])
        .arg(&program)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stdout = stdout_once_running(&mut child);
    // SAFETY: signalling our own child process.
    unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGTERM) };
    let out = child.wait_with_output().unwrap();
    let stdout = stdout.join().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(143), "{stdout}\n{stderr}");
    assert!(stdout.contains("terminated (SIGTERM)"), "{stdout}");
    // The summary of the timing monitor follows.
    assert!(stdout.contains("position control"), "{stdout}");
    assert!(stderr.contains("feed hold, abort, drives off"), "{stderr}");
}

#[test]
fn an_error_names_its_cause_once() {
    let count = |text: &str, what: &str| text.matches(what).count();
    let out = rtcnc()
        .args([
            "sim",
            "examples/bracket.ngc",
            "--machine",
            "configs/no-such-machine.toml",
        ])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert_eq!(count(&stderr, "no-such-machine.toml"), 1, "{stderr}");
    assert_eq!(count(&stderr, "No such file or directory"), 1, "{stderr}");

    // A machine file whose tool table is missing: the self-test names the file once.
    let dir = scratch("cause-once");
    let text = std::fs::read_to_string(repo().join("configs/sim-mill.toml"))
        .unwrap()
        .replace(
            "\"../examples/plc/mill.st\"",
            &format!("{:?}", repo().join("examples/plc/mill.st")),
        );
    assert!(text.contains("sim-mill.tbl"));
    std::fs::write(dir.join("mill.toml"), text).unwrap();
    let out = rtcnc()
        .args(["sim", "examples/bracket.ngc", "--machine"])
        .arg(dir.join("mill.toml"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert_eq!(count(&stderr, "sim-mill.tbl"), 1, "{stderr}");
    assert_eq!(count(&stderr, "No such file or directory"), 1, "{stderr}");
}
