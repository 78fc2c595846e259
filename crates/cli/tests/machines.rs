//! The machines built into the binary: `rtcnc machines` lists every machine file of
//! `configs/`, `--machine NAME` runs one from any folder as its file in `configs/` runs from
//! the checkout, a machine's state already written is kept, an unknown name is refused.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A folder of this test's own under the target's temporary folder, empty.
fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("rtcnc-machines-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `rtcnc args` run in `cwd` with `data` as the data folder.
fn rtcnc(cwd: &Path, data: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rtcnc"))
        .current_dir(cwd)
        .env("XDG_DATA_HOME", data)
        .args(args)
        .output()
        .unwrap()
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// The machine files of `configs/`, by name.
fn shipped_files() -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(repo().join("configs"))
        .unwrap()
        .filter_map(|e| {
            let name = e.unwrap().file_name().into_string().unwrap();
            name.strip_suffix(".toml").map(str::to_string)
        })
        .collect();
    names.sort();
    names
}

#[test]
fn every_machine_file_of_configs_is_listed_with_its_name() {
    let dir = scratch("list");
    let out = rtcnc(&dir, &dir, &["machines"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let listed = text(&out.stdout);
    let mut names: Vec<String> = listed
        .lines()
        .map(|l| l.split_whitespace().next().unwrap().to_string())
        .collect();
    names.sort();
    assert_eq!(names, shipped_files());
    assert!(!listed.contains("(invalid"), "{listed}");
    // The name each machine file gives its machine, and the default marked.
    let mill = std::fs::read_to_string(repo().join("configs/sim-mill.toml")).unwrap();
    let title = mill
        .lines()
        .find_map(|l| l.strip_prefix("name = \""))
        .unwrap()
        .trim_end_matches('"');
    assert!(
        listed
            .lines()
            .any(|l| l.starts_with("sim-mill ") && l.contains(title) && l.contains("(default)")),
        "{listed}"
    );
}

/// A program that changes the tool (the mill's PLC sequence and carousel), runs the spindle
/// and moves every axis.
const PROGRAM: &str = "G21 G90 G17 G64 P0.01
T2 M6
S6000 M3
G0 X10 Y10 Z5
G1 Z-1 F600
G1 X40 F1500
G2 X50 Y20 I0 J10
G1 Y40
G0 Z5
M5
M2
";

/// The report without the lines that name the machine's file or the wall time.
fn report(out: &Output) -> String {
    text(&out.stdout)
        .lines()
        .filter(|l| {
            !["program ", "machine ", "simulated ", "wrote "]
                .iter()
                .any(|p| l.starts_with(p))
        })
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn the_default_machine_runs_from_any_folder_as_its_file_runs_from_the_checkout() {
    let dir = scratch("default");
    let data = dir.join("data");
    std::fs::write(dir.join("part.ngc"), PROGRAM).unwrap();
    let out = rtcnc(&dir, &data, &["sim", "part.ngc", "-q", "--out", "built-in"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let stdout = text(&out.stdout);
    assert!(stdout.contains("Simulated 3-axis mill"), "{stdout}");
    assert!(stdout.contains("faults      none"), "{stdout}");
    let written = data.join("rtcnc/machines/sim-mill");
    for file in ["sim-mill.toml", "mill.st", "sim-mill.tbl"] {
        assert!(written.join(file).is_file(), "{file}");
    }
    // The reference: the same program on the machine file of the checkout.
    let program = dir.join("part.ngc");
    let from_checkout = rtcnc(
        &repo(),
        &data,
        &[
            "sim",
            program.to_str().unwrap(),
            "-q",
            "--machine",
            "configs/sim-mill.toml",
            "--out",
            dir.join("checkout").to_str().unwrap(),
        ],
    );
    assert!(from_checkout.status.success());
    assert_eq!(report(&out), report(&from_checkout));
    let setpoints = |d: &str| std::fs::read(dir.join(d).join("setpoints.csv")).unwrap();
    assert_eq!(setpoints("built-in"), setpoints("checkout"));
    // By name, the lathe.
    let out = rtcnc(
        &dir,
        &data,
        &["sim", "part.ngc", "-q", "--machine", "sim-lathe"],
    );
    assert!(text(&out.stdout).contains("Simulated 2-axis lathe"));
}

#[test]
fn a_tool_table_already_written_is_kept_and_the_machine_file_renewed() {
    let dir = scratch("kept");
    let machine = dir.join("rtcnc/machines/sim-mill");
    std::fs::create_dir_all(&machine).unwrap();
    let table = "T2 P2 Z+12.5 D6.0 ;changed by the operator\n";
    std::fs::write(machine.join("sim-mill.tbl"), table).unwrap();
    std::fs::write(machine.join("sim-mill.toml"), "stale").unwrap();
    std::fs::write(dir.join("part.ngc"), "G0 X1\nM2\n").unwrap();
    let out = rtcnc(&dir, &dir, &["sim", "part.ngc", "-q"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert_eq!(
        std::fs::read_to_string(machine.join("sim-mill.tbl")).unwrap(),
        table
    );
    let toml = std::fs::read_to_string(machine.join("sim-mill.toml")).unwrap();
    assert!(toml.contains("program = \"mill.st\""), "{toml}");
}

#[test]
fn write_puts_a_machine_into_a_folder_and_unknown_names_are_refused() {
    let dir = scratch("write");
    let out = rtcnc(&dir, &dir, &["machines", "--write", "sim-lathe", "lathe"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let original = std::fs::read_to_string(repo().join("configs/sim-lathe.toml")).unwrap();
    assert_eq!(
        std::fs::read_to_string(dir.join("lathe/sim-lathe.toml")).unwrap(),
        original
    );
    assert_eq!(
        std::fs::read(dir.join("lathe/sim-lathe.tbl")).unwrap(),
        std::fs::read(repo().join("configs/sim-lathe.tbl")).unwrap()
    );
    let out = rtcnc(&dir, &dir, &["sim", "x.ngc", "--machine", "sim-drill"]);
    assert_eq!(out.status.code(), Some(2));
    let err = text(&out.stderr);
    assert!(
        err.contains("no machine file and no shipped machine named 'sim-drill'")
            && err.contains("sim-mill, sim-lathe"),
        "{err}"
    );
    // A missing machine file: its path and the cause, once each.
    let out = rtcnc(&dir, &dir, &["sim", "x.ngc", "--machine", "none/mill.toml"]);
    let err = text(&out.stderr);
    assert_eq!(err.matches("none/mill.toml").count(), 1, "{err}");
    assert_eq!(err.matches("No such file").count(), 1, "{err}");
}
