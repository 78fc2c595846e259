//! Network namespaces for the tests that put the simulator process and a master on the
//! two ends of a veth pair: no hardware, no privileges beyond an unprivileged user
//! namespace (`unshare -Urn`), nothing touched outside the namespace.
#![allow(dead_code)]

use std::io::{BufRead, BufReader, Write};
use std::path::PathBuf;
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};

/// The environment variable that tells a re-run test binary it is inside the namespace.
pub const INSIDE: &str = "RTCNC_ECAT_INSIDE_NETNS";
/// The master's end and the simulator's end.
pub const MASTER_END: &str = "m0";
pub const SIMULATOR_END: &str = "s0";

/// As root, a network namespace alone keeps the right to real-time scheduling (the
/// simulator then answers at SCHED_FIFO, as hardware would); otherwise an unprivileged
/// user namespace owns it.
fn unshare_flags() -> &'static str {
    if is_root() { "-n" } else { "-Urn" }
}

fn is_root() -> bool {
    // SAFETY: a plain query.
    unsafe { libc::geteuid() == 0 }
}

/// Why namespaces cannot be used here, if they cannot.
pub fn namespaces_refused() -> Option<String> {
    match Command::new("unshare")
        .args([unshare_flags(), "true"])
        .output()
    {
        Ok(output) if output.status.success() => None,
        Ok(output) => Some(format!(
            "unshare {} refused: {}",
            unshare_flags(),
            String::from_utf8_lossy(&output.stderr).trim()
        )),
        Err(e) => Some(format!("unshare not available: {e}")),
    }
}

/// Runs the ignored test `inner` of this test binary inside a new user and network
/// namespace; returns whether it passed (its output goes to ours).
pub fn run_inside(inner: &str) -> bool {
    let exe = std::env::current_exe().expect("test binary");
    let status = Command::new("unshare")
        .arg(unshare_flags())
        .arg(exe)
        .args([
            "--exact",
            inner,
            "--ignored",
            "--nocapture",
            "--test-threads=1",
        ])
        .env(INSIDE, "1")
        .status()
        .expect("unshare runs");
    status.success()
}

/// Whether this process is the one inside the namespace.
pub fn inside() -> bool {
    std::env::var_os(INSIDE).is_some()
}

/// Creates the veth pair and brings both ends up.
pub fn veth() {
    for args in [
        vec![
            "link",
            "add",
            MASTER_END,
            "type",
            "veth",
            "peer",
            "name",
            SIMULATOR_END,
        ],
        vec!["link", "set", MASTER_END, "up"],
        vec!["link", "set", SIMULATOR_END, "up"],
    ] {
        let status = Command::new("ip").args(&args).status().expect("ip runs");
        assert!(status.success(), "ip {args:?}");
    }
}

/// The simulator process on the simulator's end.
pub struct Simulator {
    child: Child,
    stdin: ChildStdin,
    stdout: BufReader<ChildStdout>,
    _dir: PathBuf,
}

impl Simulator {
    /// Starts `ecat-slave-sim` with this segment and waits until it is ready.
    pub fn start(segment_toml: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("rtcnc-ecat-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let config = dir.join("segment.toml");
        std::fs::write(&config, segment_toml).expect("segment file");
        let mut command = Command::new(env!("CARGO_BIN_EXE_ecat-slave-sim"));
        command
            .args(["--interface", SIMULATOR_END, "--config"])
            .arg(&config);
        if is_root() {
            command.args(["--priority", "70"]);
        }
        let mut child = command
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .expect("simulator starts");
        let stdin = child.stdin.take().expect("stdin");
        let mut stdout = BufReader::new(child.stdout.take().expect("stdout"));
        let mut line = String::new();
        stdout.read_line(&mut line).expect("simulator answers");
        assert!(line.starts_with("ready"), "simulator: {line}");
        Self {
            child,
            stdin,
            stdout,
            _dir: dir,
        }
    }

    /// Sends a command line and returns the simulator's answer.
    pub fn command(&mut self, line: &str) -> String {
        writeln!(self.stdin, "{line}").expect("command sent");
        let mut answer = String::new();
        self.stdout.read_line(&mut answer).expect("answer");
        answer.trim().to_owned()
    }
}

impl Drop for Simulator {
    fn drop(&mut self) {
        let _ = writeln!(self.stdin, "quit");
        let _ = self.child.wait();
    }
}
