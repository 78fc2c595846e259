//! `rtcnc plc check` and `rtcnc plc run` as a user calls them.

use std::path::PathBuf;
use std::process::{Command, Output};

fn rtcnc(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rtcnc"))
        .args(args)
        .output()
        .expect("rtcnc runs")
}

fn repo(path: &str) -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(path)
        .display()
        .to_string()
}

fn temp_st(name: &str, text: &str) -> String {
    let dir = std::env::temp_dir().join(format!("rtcnc-cli-plc-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.display().to_string()
}

#[test]
fn check_accepts_the_mill_logic_and_lists_its_task() {
    let out = rtcnc(&["plc", "check", &repo("examples/plc/mill.st")]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains(": ok: "), "{stdout}");
    assert!(
        stdout.contains("task LOGIC (every T#4ms, priority 1): MILL"),
        "{stdout}"
    );
}

#[test]
fn check_reports_errors_with_file_line_and_column() {
    let file = temp_st(
        "bad.st",
        "PROGRAM P\nVAR x : INT; END_VAR\n  x := TRUE;\nEND_PROGRAM\n",
    );
    let out = rtcnc(&["plc", "check", &file]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains(&format!("{file}:3:8: error[type-mismatch]")),
        "{stderr}"
    );
}

#[test]
fn run_prints_watched_variables_per_scan() {
    let file = temp_st(
        "ton.st",
        "PROGRAM P VAR go : BOOL; t : TON; END_VAR t(IN := go, PT := T#20ms); END_PROGRAM\n",
    );
    let out = rtcnc(&[
        "plc",
        "run",
        &file,
        "--scans",
        "7",
        "--period",
        "4ms",
        "--set",
        "go=TRUE@2",
        "--watch",
        "t.Q",
        "--watch",
        "t.ET",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    let rows: Vec<&str> = stdout.lines().collect();
    // IN rises on scan 2 (t = 4 ms): ET reaches 20 ms and Q rises on scan 7 (t = 24 ms).
    assert_eq!(
        rows,
        [
            "scan\ttime\tt.Q\tt.ET",
            "1\tT#0s\tFALSE\tT#0s",
            "2\tT#4ms\tFALSE\tT#0s",
            "3\tT#8ms\tFALSE\tT#4ms",
            "4\tT#12ms\tFALSE\tT#8ms",
            "5\tT#16ms\tFALSE\tT#12ms",
            "6\tT#20ms\tFALSE\tT#16ms",
            "7\tT#24ms\tTRUE\tT#20ms",
        ]
    );
}

#[test]
fn run_stops_on_a_runtime_fault_with_its_location() {
    let file = temp_st(
        "div.st",
        "PROGRAM P\nVAR a : INT := 1; b : INT := 3; END_VAR\n  b := b - 1;\n  a := a / b;\nEND_PROGRAM\n",
    );
    let out = rtcnc(&["plc", "run", &file, "--scans", "10", "--watch", "b"]);
    assert_eq!(out.status.code(), Some(1));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(stdout.lines().count(), 1 + 3, "{stdout}");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("PLC fault [division-by-zero] in P line 4"),
        "{stderr}"
    );
}

#[test]
fn run_rejects_unknown_watch_names() {
    let out = rtcnc(&[
        "plc",
        "run",
        &repo("examples/plc/mill.st"),
        "--scans",
        "1",
        "--watch",
        "no_such_var",
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("no variable 'no_such_var'"));
}

#[test]
fn check_lists_variables_on_request() {
    let out = rtcnc(&["plc", "check", "--vars", &repo("examples/plc/mill.st")]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success());
    assert!(
        stdout
            .lines()
            .any(|l| l == "MILL.ESTOP_BUTTON_OK AT %IX0.0 : BOOL"),
        "{stdout}"
    );
    assert!(
        stdout.lines().any(|l| l == "MILL.SPINDLE_TIMER.ET : TIME"),
        "{stdout}"
    );
    assert!(
        stdout
            .lines()
            .any(|l| l == "MILL.CURRENT_TOOL : INT RETAIN"),
        "{stdout}"
    );
}

#[test]
fn a_program_of_several_files_runs_and_its_warnings_are_shown() {
    let gvl = temp_st(
        "gvl.st",
        "VAR_GLOBAL CONSTANT\n  N : INT := 3;\nEND_VAR\nVAR_GLOBAL\n  total : INT;\nEND_VAR\n",
    );
    let fb = temp_st(
        "fb_add.st",
        "FUNCTION_BLOCK FB_Add\nVAR_INPUT k : INT; END_VAR\nVAR a : ARRAY[1..N] OF INT; END_VAR\nk := k + 1;\ntotal := total + k;\nEND_FUNCTION_BLOCK\n",
    );
    let main = temp_st(
        "main.st",
        "PROGRAM Main\nVAR add : FB_Add; END_VAR\nadd(k := 1);\nEND_PROGRAM\n",
    );
    let out = rtcnc(&[
        "plc", "run", &gvl, &fb, &main, "--scans", "2", "--watch", "total",
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stdout}{stderr}");
    // k arrives as 1 and the block adds k + 1 = 2 per scan.
    assert!(stdout.contains("1\tT#0s\t2\n2\tT#4ms\t4"), "{stdout}");
    assert!(
        stderr.contains(&format!(
            "{fb}:4:1: warning[assign-to-input]: 'k' is a VAR_INPUT"
        )),
        "{stderr}"
    );
}

#[test]
fn run_takes_a_configuration_with_plcopen_axes() {
    let out = rtcnc(&[
        "plc",
        "run",
        &repo("examples/plc/carousel.st"),
        "--config",
        &repo("examples/plc/carousel.toml"),
        "--scans",
        "265",
        "--set",
        "Carousel.machine_on=TRUE",
        "--set",
        "Carousel.tool_number=4",
        "--set",
        "Carousel.tool_change_request=TRUE@11",
        "--watch",
        "Carousel.angle.Position",
        "--watch",
        "Carousel.tool_change_done",
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // The 90 degree turn starts at 44 ms and takes 1.01 s (see the plc crate's tests).
    assert!(stdout.contains("\n264\tT#1s52ms\t"), "{stdout}");
    assert!(stdout.ends_with("265\tT#1s56ms\t90.0\tTRUE\n"), "{stdout}");
}

/// Monitoring as at commissioning: FB instance members and array elements watched, a
/// variable forced (shown with `(F)`) and released, each scan's execution time.
#[test]
fn run_watches_members_and_elements_marks_forces_and_times_scans() {
    let file = temp_st(
        "monitor.st",
        "PROGRAM P\nVAR go : BOOL; c : CTU; log : ARRAY[1..3] OF INT; END_VAR\n\
         c(CU := go, PV := 10);\nlog[2] := c.CV * 10;\nEND_PROGRAM\n",
    );
    let out = rtcnc(&[
        "plc",
        "run",
        &file,
        "--scans",
        "6",
        "--set",
        "go=TRUE@2",
        "--unset",
        "go@3",
        "--set",
        "go=TRUE@5",
        "--watch",
        "go",
        "--watch",
        "c.CV",
        "--watch",
        "log[2]",
        "--timing",
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rows: Vec<Vec<&str>> = stdout.lines().map(|l| l.split('\t').collect()).collect();
    assert_eq!(rows[0], ["scan", "time", "go", "c.CV", "log[2]", "scan_us"]);
    // go is forced TRUE on scan 2 (a rising edge: CV 1), released on scan 3 (the program
    // keeps the last value, TRUE, no edge), forced again on 5 (still TRUE, no edge).
    let values: Vec<[&str; 3]> = rows[1..].iter().map(|r| [r[2], r[3], r[4]]).collect();
    assert_eq!(
        values,
        [
            ["FALSE", "0", "0"],
            ["TRUE (F)", "1", "10"],
            ["TRUE", "1", "10"],
            ["TRUE", "1", "10"],
            ["TRUE (F)", "1", "10"],
            ["TRUE (F)", "1", "10"],
        ]
    );
    for r in &rows[1..] {
        let us: f64 = r[5].parse().expect("a number of microseconds");
        assert!(us >= 0.0);
    }
}

#[test]
fn a_windows_1252_file_runs_and_its_encoding_can_be_forced() {
    let dir = std::env::temp_dir().join(format!("rtcnc-cli-plc-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("latin.st");
    // 'Grüße' written by a Windows-1252 editor: ü is 0xFC, ß 0xDF.
    std::fs::write(
        &path,
        b"PROGRAM P VAR s : STRING := 'Gr\xfc\xdfe'; n : INT; END_VAR n := LEN(s); END_PROGRAM\n",
    )
    .unwrap();
    let file = path.display().to_string();
    let run = |encoding: &str| {
        rtcnc(&[
            "plc",
            "run",
            &file,
            "--encoding",
            encoding,
            "--scans",
            "1",
            "--watch",
            "n",
        ])
    };
    for encoding in ["auto", "windows-1252"] {
        let out = run(encoding);
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success(), "{encoding}: {stdout}");
        // Five characters, as CODESYS counts them.
        assert_eq!(stdout.lines().nth(1), Some("1\tT#0s\t5"), "{encoding}");
    }
    let out = run("utf-8");
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("not valid UTF-8"), "{stderr}");
}

#[test]
fn codesys_conversions_are_chosen_on_the_command_line() {
    let file = temp_st(
        "dword_sub.st",
        "PROGRAM P VAR a : DWORD := 1; b : DWORD := 2; d : DWORD; END_VAR d := a - b; END_PROGRAM\n",
    );
    let iec = rtcnc(&["plc", "check", &file]);
    assert!(!iec.status.success());
    let stderr = String::from_utf8_lossy(&iec.stderr);
    assert!(
        stderr.contains("operator SUB does not apply to DWORD and DWORD"),
        "{stderr}"
    );
    let out = rtcnc(&[
        "plc",
        "run",
        &file,
        "--conversions",
        "codesys",
        "--scans",
        "1",
        "--watch",
        "d",
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}");
    // 1 - 2 wraps in 32 bits.
    assert_eq!(stdout.lines().nth(1), Some("1\tT#0s\t4294967295"));
}
