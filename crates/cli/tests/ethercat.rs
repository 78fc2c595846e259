//! The seeds' 12-drive gantry on EtherCAT (configs/ethercat-sim-12.toml: CSP drives on
//! simulated EtherCAT devices in the machine process) through the binary: `rtcnc sim` in
//! virtual time ends at the same cycle time as on the simulated machine
//! (configs/sim-gantry-12.toml), `rtcnc run` runs it in real time, and `rtcnc machine` (the
//! machine process of `rtcnc serve`) runs it on commands from the shared-memory link.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use rtcnc_kernel::link::Client;
use rtcnc_kernel::link::layout::{self, WireCommand, WireEvent, WireText};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn rtcnc() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_rtcnc"));
    c.current_dir(repo());
    c
}

fn line<'a>(text: &'a str, key: &str) -> &'a str {
    text.lines()
        .find(|l| l.starts_with(key))
        .unwrap_or_else(|| panic!("no {key:?} in {text}"))
}

#[test]
fn sim_runs_the_gantry_on_ethercat_drives_in_the_simulated_machines_time() {
    let run = |machine: &str| {
        let out = rtcnc()
            .args(["sim", "examples/gantry-12.ngc", "-q", "--machine", machine])
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
        assert!(
            out.status.success(),
            "{machine}: {stdout}{}",
            String::from_utf8_lossy(&out.stderr)
        );
        stdout
    };
    let reference = run("configs/sim-gantry-12.toml");
    let bus = run("configs/ethercat-sim-12.toml");
    assert!(
        bus.contains("12-drive gantry on simulated EtherCAT drives"),
        "{bus}"
    );
    assert_eq!(line(&bus, "faults"), "faults      none", "{bus}");
    assert_eq!(line(&bus, "limits"), line(&reference, "limits"));
    assert_eq!(line(&bus, "cycle time"), line(&reference, "cycle time"));
}

#[test]
fn run_runs_the_gantry_on_ethercat_drives_in_real_time() {
    let out = rtcnc()
        .args([
            "run",
            "examples/gantry-12.ngc",
            "--machine",
            "configs/ethercat-sim-12.toml",
        ])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    // The shared machine gives no real-time guarantee: a late cycle may fault; the run
    // must bring the bus up, run the program's task graph, report and stop cleanly.
    assert!(stdout.contains("program "), "{stdout}{stderr}");
    assert!(stdout.contains("drive io"), "{stdout}");
    assert!(out.status.code().is_some());
}

struct Machine(Child, String);

impl Drop for Machine {
    fn drop(&mut self) {
        // SAFETY: a signal to our own child.
        unsafe { libc::kill(self.0.id() as i32, libc::SIGTERM) };
        let _ = self.0.wait();
        let _ = std::fs::remove_file(rtcnc_kernel::link::segment_path(&self.1).unwrap());
    }
}

fn wait_events(client: &Client, events: &mut Vec<WireEvent>, done: impl Fn(&[WireEvent]) -> bool) {
    let start = Instant::now();
    while !done(events) {
        client.heartbeat();
        client.drain_events(|e| events.push(e));
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "timed out: {events:?}"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
}

fn acknowledged(serial: u64) -> impl Fn(&[WireEvent]) -> bool {
    move |events| {
        events.iter().any(|e| {
            e.kind == layout::event::ACK
                && e.serial == serial
                && matches!(
                    e.code,
                    layout::ack::DONE | layout::ack::REFUSED | layout::ack::FAILED
                )
        })
    }
}

#[test]
fn the_machine_process_runs_the_gantry_on_ethercat_drives() {
    let segment = format!("rtcnc-clitest-{}-ethercat", std::process::id());
    let child = rtcnc()
        .args([
            "machine",
            "--machine",
            "configs/ethercat-sim-12.toml",
            "--segment",
            &segment,
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let _machine = Machine(child, segment.clone());
    let start = Instant::now();
    let client = loop {
        if let Ok(c) = Client::attach(&segment)
            && c.machine_heartbeat() > 0
        {
            break c;
        }
        assert!(
            start.elapsed() < Duration::from_secs(30),
            "the machine did not start"
        );
        std::thread::sleep(Duration::from_millis(20));
    };
    assert_eq!(
        client.machine_name(),
        "12-drive gantry on simulated EtherCAT drives"
    );
    let mut events = Vec::new();
    let program = repo()
        .join("examples/gantry-12.ngc")
        .canonicalize()
        .unwrap();
    let commands = [
        WireCommand {
            serial: 1,
            kind: layout::command::RESET,
            ..Default::default()
        },
        WireCommand {
            serial: 2,
            kind: layout::command::LOAD_PROGRAM,
            text: WireText::new(&program.to_string_lossy()),
            ..Default::default()
        },
        WireCommand {
            serial: 3,
            kind: layout::command::START,
            ..Default::default()
        },
    ];
    for command in commands {
        let serial = command.serial;
        client.send(command).unwrap();
        wait_events(&client, &mut events, acknowledged(serial));
        let ack = events
            .iter()
            .find(|e| {
                e.kind == layout::event::ACK
                    && e.serial == serial
                    && e.code != layout::ack::ACCEPTED
            })
            .unwrap();
        assert_ne!(
            ack.code,
            layout::ack::REFUSED,
            "command {serial}: {events:?}"
        );
    }
    // The start's acknowledgement comes when the program ended (done) or stopped on a
    // fault (failed: the shared machine may fault a late cycle).
    let status = client.status();
    let done = events
        .iter()
        .any(|e| e.kind == layout::event::ACK && e.serial == 3 && e.code == layout::ack::DONE);
    if done {
        assert_ne!(status.flags & layout::flags::PROGRAM_ENDED, 0);
        assert_eq!(status.fault_count, 0);
        assert!(
            status.axes[..3].iter().all(|a| a.abs() < 1e-9),
            "{:?}",
            status.axes
        );
    } else {
        assert!(status.fault_count > 0, "{events:?}");
        eprintln!("the program stopped on a fault (a late cycle on a loaded machine): {events:?}");
    }
    assert_eq!(client.joint_name(11), "P2");
}
