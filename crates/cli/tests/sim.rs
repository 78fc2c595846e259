//! `rtcnc sim` and `rtcnc run` on the built binary.

use std::path::{Path, PathBuf};
use std::process::Command;

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

#[test]
fn sim_runs_experiment_1_and_writes_its_report() {
    let dir = std::env::temp_dir().join(format!("rtcnc-sim-test-{}", std::process::id()));
    let out = rtcnc()
        .args([
            "sim",
            "examples/experiment-1.ngc",
            "--machine",
            "configs/experiment-1.toml",
            "-q",
            "--out",
        ])
        .arg(&dir)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("limits      respected"), "{stdout}");
    assert!(stdout.contains("faults      none"), "{stdout}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["ended"], true);
    assert_eq!(summary["axes"]["X"]["limit_velocity"], 50.0);
    assert_eq!(summary["axes"]["X"]["limit_jerk"], 10000.0);
    let v = summary["axes"]["X"]["max_velocity"].as_f64().unwrap();
    assert!(v > 0.0 && v <= 50.0, "max velocity {v}");
    let fe = summary["joints"]["X"]["max_following_error"]
        .as_f64()
        .unwrap();
    assert!(fe < 0.01, "following error {fe}");
    let t = summary["cycle_time_s"].as_f64().unwrap();
    assert!(t > 0.2678 && t < 0.5, "cycle time {t}");
    // CSV: a header and one row per servo cycle.
    let csv = std::fs::read_to_string(dir.join("setpoints.csv")).unwrap();
    assert!(csv.starts_with("time_s,cycle,line,path_speed,X,X_setpoint\n"));
    let last = csv.lines().last().unwrap();
    assert!(last.ends_with(",6.000000,6.000000"), "{last}");
    let svg = std::fs::read_to_string(dir.join("plot.svg")).unwrap();
    assert!(
        svg.starts_with("<svg")
            && svg.contains("top (X-Y)")
            && svg.contains("path speed over time")
    );
    let trace: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("trace.json")).unwrap()).unwrap();
    assert!(trace.to_string().contains("interpolation"));
}

#[test]
fn a_bad_machine_file_is_refused_naming_the_key() {
    let dir = std::env::temp_dir().join(format!("rtcnc-sim-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("bad.toml");
    let text = std::fs::read_to_string(repo().join("configs/experiment-1.toml"))
        .unwrap()
        .replace("max_jerk = 10000.0", "max_jerk = -1.0");
    std::fs::write(&bad, text).unwrap();
    let out = rtcnc()
        .args(["sim", "examples/experiment-1.ngc", "--machine"])
        .arg(&bad)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("axes.x.max_jerk: must be greater than zero"),
        "{stderr}"
    );
}

#[test]
fn run_executes_experiment_1_in_real_time() {
    let out = rtcnc()
        .args([
            "run",
            "examples/experiment-1.ngc",
            "--machine",
            "configs/experiment-1.toml",
        ])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    // On a loaded machine without real-time guarantees a late cycle may fault the tight
    // following-error limit; the run must still start, report and stop cleanly.
    assert!(stdout.contains("program "), "{stdout}");
    assert!(stdout.contains("interpolation"), "{stdout}");
    assert!(out.status.code().is_some());
}

#[test]
fn ctrl_c_holds_the_feed_and_a_second_one_aborts() {
    // A slow, long move on the ideal-drive machine: nothing but the two Ctrl-C can stop it
    // early, even on a loaded machine without real-time scheduling.
    let dir = std::env::temp_dir().join(format!("rtcnc-run-ctrlc-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let program = dir.join("slow.ngc");
    std::fs::write(&program, "G21 G90 G1 X500 F600\nM2\n").unwrap();
    let mut child = rtcnc()
        .args(["run", "--machine", "configs/bench-xyz.toml"])
        .arg(&program)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let stdout = stdout_once_running(&mut child);
    let pid = child.id() as libc::pid_t;
    // SAFETY: signalling our own child process.
    unsafe { libc::kill(pid, libc::SIGINT) };
    std::thread::sleep(std::time::Duration::from_millis(800));
    // SAFETY: as above.
    unsafe { libc::kill(pid, libc::SIGINT) };
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    let stdout = stdout.join().unwrap();
    let hold = stderr
        .find("feed hold")
        .unwrap_or_else(|| panic!("{stderr}"));
    let abort = stderr
        .find("rtcnc: abort")
        .unwrap_or_else(|| panic!("{stderr}"));
    assert!(hold < abort, "{stderr}");
    assert!(stdout.contains("program stopped"), "{stdout}");
    assert_eq!(out.status.code(), Some(1));
}

/// Writes `text` as a program in a fresh temporary folder.
fn temp_program(name: &str, text: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rtcnc-cli-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("{name}.ngc"));
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn sim_shows_operator_messages_when_the_machine_reaches_them() {
    let program = temp_program(
        "messages",
        "G21 G90\nG1 X10 F600\n(MSG,first cut done)\nG1 X20\n(DEBUG,at X#5420)\nM2\n",
    );
    let dir = program.parent().unwrap().join("out");
    let out = rtcnc()
        .args(["sim"])
        .arg(&program)
        .args(["--machine", "configs/bench-xyz.toml", "-q", "--out"])
        .arg(&dir)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}");
    let lines: Vec<&str> = stdout
        .lines()
        .filter(|l| l.starts_with("message"))
        .collect();
    assert_eq!(lines.len(), 2, "{stdout}");
    assert!(lines[0].ends_with("line 3: first cut done"), "{stdout}");
    assert!(lines[1].ends_with("line 5: at X20.000000"), "{stdout}");
    // Printed before the report, in the order of the motion.
    assert!(stdout.find("message").unwrap() < stdout.find("limits").unwrap());
    // Each 10 mm move at 10 mm/s on this machine is a rest-to-rest S-curve of
    // 1 + 2·sqrt(10/50000) = 1.028 s (see crates/kernel/tests/messages.rs for the exact
    // period counts): the messages come after one and after two of them.
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    let messages = summary["messages"].as_array().unwrap();
    assert_eq!(messages.len(), 2);
    assert_eq!(messages[0]["line"], 3);
    assert_eq!(messages[0]["text"], "first cut done");
    assert_eq!(messages[1]["text"], "at X20.000000");
    let t0 = messages[0]["time_s"].as_f64().unwrap();
    let t1 = messages[1]["time_s"].as_f64().unwrap();
    let move_time = 1.0 + 2.0 * (10.0f64 / 50_000.0).sqrt();
    assert!(t0 > move_time && t0 < move_time + 0.01, "{t0}");
    assert!(
        t1 - t0 > move_time && t1 - t0 < move_time + 0.003,
        "{t0} {t1}"
    );
}

#[test]
fn run_shows_operator_messages() {
    let program = temp_program(
        "run-messages",
        "G21 G90\nG1 X1 F600\n(MSG,halfway)\nG1 X0\nM2\n",
    );
    let out = rtcnc()
        .args(["run"])
        .arg(&program)
        .args(["--machine", "configs/bench-xyz.toml"])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout
            .lines()
            .any(|l| l.starts_with("message") && l.ends_with("line 3: halfway")),
        "{stdout}"
    );
}

/// Runs `rtcnc sim PROGRAM -q` with `extra` arguments and asserts that it ends within every
/// limit with no fault.
fn assert_sim_ends_cleanly(program: &str, extra: &[&str]) {
    let out = rtcnc()
        .args(["sim", program, "-q"])
        .args(extra)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("limits      respected"), "{stdout}");
    assert!(stdout.contains("faults      none"), "{stdout}");
}

#[test]
fn sim_runs_the_spline_example_on_the_mill() {
    assert_sim_ends_cleanly("examples/gcode/splines.ngc", &[]);
}

/// The shipped 5-axis machine (by its name) runs the TCP example to its end within every
/// joint's limits.
#[test]
fn sim_runs_the_tool_centre_point_example_on_the_5_axis_table() {
    assert_sim_ends_cleanly(
        "examples/5axis-trt-tcp.ngc",
        &["--machine", "sim-5axis-trt"],
    );
}

/// The shipped 5-axis head machine (by its name) runs its TCP example to its end within
/// every joint's limits.
#[test]
fn sim_runs_the_tool_centre_point_example_on_the_5_axis_head() {
    assert_sim_ends_cleanly(
        "examples/5axis-head-tcp.ngc",
        &["--machine", "sim-5axis-head"],
    );
}

/// A hard limit at 40 mm hit at 50 mm/s: the quick stop (1000 mm/s², jerk 10 000 mm/s³:
/// a triangular deceleration of 2·√(50/10 000) = 0.141 s over 50 · 0.0707 = 3.5 mm) ends
/// near X43.5. The recording goes on until the load stands, so the CSV shows the whole
/// stop and ends standing (20 ms after the fault, X would still move near X41).
#[test]
fn sim_records_a_fault_until_the_load_stands() {
    let dir = std::env::temp_dir().join(format!("rtcnc-sim-stop-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let machine = dir.join("limit-at-40.toml");
    std::fs::write(
        &machine,
        std::fs::read_to_string(repo().join("configs/experiment-1.toml"))
            .unwrap()
            .replace(
                "sim = { drive = \"velocity\" }",
                "sim = { drive = \"velocity\", positive_limit_switch = 40.0 }",
            ),
    )
    .unwrap();
    let program = temp_program("to-the-limit", "G21 G90 G61\nG1 X90 F3000\nM2\n");
    let out = rtcnc()
        .arg("sim")
        .arg(&program)
        .arg("--machine")
        .arg(&machine)
        .args(["-q", "--out"])
        .arg(dir.join("out"))
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(!out.status.success(), "{stdout}");
    assert!(
        stdout.contains("hard limit") || stdout.contains("hard_limit"),
        "{stdout}"
    );
    let csv = std::fs::read_to_string(dir.join("out/setpoints.csv")).unwrap();
    let x: Vec<f64> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(4).unwrap().parse().unwrap())
        .collect();
    let last = *x.last().unwrap();
    assert!(last > 42.5 && last < 44.5, "the load stopped at X{last}");
    assert!(
        x[x.len() - 20..].iter().all(|v| *v == last),
        "the recording ends before the load stands: {:?}",
        &x[x.len() - 20..]
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// `rtcnc run --out` records every servo period into the files `rtcnc sim --out` writes:
/// the same columns, one row per period, and experiment 1's move from X0 to X6.
#[test]
fn run_records_the_files_sim_writes() {
    let dir = std::env::temp_dir().join(format!("rtcnc-run-out-{}", std::process::id()));
    let out = rtcnc()
        .args([
            "run",
            "examples/experiment-1.ngc",
            "--machine",
            "configs/experiment-1.toml",
            "--out",
        ])
        .arg(&dir)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let line = stdout
        .lines()
        .find(|l| l.starts_with("recording"))
        .unwrap_or_else(|| panic!("{stdout}"));
    let rows: u64 = line.split_whitespace().nth(1).unwrap().parse().unwrap();
    let csv = std::fs::read_to_string(dir.join("setpoints.csv")).unwrap();
    assert!(csv.starts_with("time_s,cycle,line,path_speed,X,X_setpoint\n"));
    assert_eq!(csv.lines().count() as u64, rows + 1, "{line}");
    let feedback = std::fs::read_to_string(dir.join("feedback.csv")).unwrap();
    assert_eq!(feedback.lines().count(), csv.lines().count());
    let x: Vec<f64> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(4).unwrap().parse().unwrap())
        .collect();
    // The cycles are consecutive unless the line says some were missing.
    if line.ends_with("; 0 periods missing") {
        let cycles: Vec<u64> = csv
            .lines()
            .skip(1)
            .map(|l| l.split(',').nth(1).unwrap().parse().unwrap())
            .collect();
        assert!(cycles.windows(2).all(|w| w[1] == w[0] + 1), "{line}");
    }
    if stdout.contains("program ended") {
        assert_eq!(*x.last().unwrap(), 6.0);
        assert!(x.windows(2).all(|w| w[1] >= w[0]), "X only moves forward");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// The cycle time `rtcnc sim` prints ("cycle time  12.345 s").
fn cycle_time(stdout: &str) -> f64 {
    stdout
        .lines()
        .find_map(|l| l.strip_prefix("cycle time"))
        .and_then(|l| l.split_whitespace().next())
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("no cycle time in {stdout}"))
}

/// M0 pauses the program until the operator resumes it: without `--resume-after-pause` the
/// run stays there to its time limit (and says how to go on); with it the program ends, and
/// the wait given adds exactly that much to the cycle time.
#[test]
fn sim_resumes_after_a_program_pause_when_asked() {
    let program = temp_program("pause", "G21 G90\nG1 X10 F600\nM0\nG1 X20\nM2\n");
    let run = |extra: &[&str]| {
        let out = rtcnc()
            .args(["sim"])
            .arg(&program)
            .args(["--machine", "configs/bench-xyz.toml", "-q", "--limit", "8"])
            .args(extra)
            .output()
            .unwrap();
        (
            out.status.success(),
            String::from_utf8_lossy(&out.stdout).to_string(),
        )
    };
    let (ok, stdout) = run(&[]);
    assert!(!ok, "{stdout}");
    assert!(stdout.contains("did not reach the end"), "{stdout}");
    assert!(stdout.contains("(M0/M1); --resume-after-pause"), "{stdout}");
    let (ok, at_once) = run(&["--resume-after-pause"]);
    assert!(ok, "{at_once}");
    assert!(
        at_once.contains("(M0/M1); resumed after 0.000 s"),
        "{at_once}"
    );
    let (ok, after_2s) = run(&["--resume-after-pause", "2"]);
    assert!(ok, "{after_2s}");
    // Two 10 mm rest-to-rest moves at 10 mm/s: 1 + 2·sqrt(10/50000) s each.
    let moves = 2.0 * (1.0 + 2.0 * (10.0f64 / 50_000.0).sqrt());
    let (t0, t2) = (cycle_time(&at_once), cycle_time(&after_2s));
    assert!(t0 > moves && t0 < moves + 0.05, "{t0}");
    assert!((t2 - t0 - 2.0).abs() <= 0.0015, "{t0} {t2}");
    assert!(
        rtcnc()
            .args(["sim"])
            .arg(&program)
            .args(["--resume-after-pause", "-1"])
            .output()
            .unwrap()
            .stderr
            .starts_with(b"error")
    );
}
