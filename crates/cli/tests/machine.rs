//! `rtcnc machine` as a real process, with this test as its client on the shared-memory
//! segment: commands acknowledged by serial, and an urgent e-stop that overtakes a full
//! normal ring (acknowledged before the commands queued ahead of it have all been taken).

use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use rtcnc_kernel::link::layout::{self, WireCommand, WireEvent, WireUrgent};
use rtcnc_kernel::link::{Client, state_name};

struct Machine(Child, String);

impl Drop for Machine {
    fn drop(&mut self) {
        // SAFETY: a signal to our own child.
        unsafe { libc::kill(self.0.id() as i32, libc::SIGTERM) };
        let _ = self.0.wait();
        let _ = std::fs::remove_file(rtcnc_kernel::link::segment_path(&self.1).unwrap());
    }
}

fn start_machine(test: &str) -> (Machine, Client) {
    let repo = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    start_machine_on(test, &repo.join("configs/sim-mill.toml"))
}

fn start_machine_on(test: &str, machine_file: &std::path::Path) -> (Machine, Client) {
    let segment = format!("rtcnc-clitest-{}-{test}", std::process::id());
    let child = Command::new(env!("CARGO_BIN_EXE_rtcnc"))
        .args(["machine", "--machine"])
        .arg(machine_file)
        .args(["--segment", &segment])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let machine = Machine(child, segment.clone());
    let start = Instant::now();
    loop {
        if let Ok(c) = Client::attach(&segment) {
            if c.machine_heartbeat() > 0 {
                return (machine, c);
            }
        }
        assert!(
            start.elapsed() < Duration::from_secs(30),
            "the machine did not start"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn collect_until(
    client: &Client,
    events: &mut Vec<WireEvent>,
    done: impl Fn(&[WireEvent]) -> bool,
) {
    let start = Instant::now();
    while !done(events) {
        client.heartbeat();
        client.drain_events(|e| events.push(e));
        assert!(
            start.elapsed() < Duration::from_secs(30),
            "timed out: {events:?}"
        );
        std::thread::sleep(Duration::from_millis(2));
    }
}

#[test]
fn an_urgent_estop_overtakes_a_full_normal_ring_in_the_real_machine_process() {
    let (_machine, client) = start_machine("urgent");
    let mut events = Vec::new();
    let reset = WireCommand {
        serial: 1,
        kind: layout::command::RESET,
        ..Default::default()
    };
    client.send(reset).unwrap();
    collect_until(&client, &mut events, |e| {
        e.iter()
            .any(|e| e.serial == 1 && e.code == layout::ack::DONE)
    });
    // Fill the ring (the machine takes at most four commands per period; this loop writes
    // in microseconds).
    let mut serial = 100;
    while client
        .send(WireCommand {
            serial,
            kind: layout::command::SINGLE_BLOCK,
            number: serial % 2,
            ..Default::default()
        })
        .is_ok()
    {
        serial += 1;
    }
    let queued = serial - 100;
    assert!(
        queued >= layout::COMMAND_SLOTS as u64 - 8,
        "the ring filled ({queued})"
    );
    client
        .send_urgent(WireUrgent {
            serial: 99,
            kind: layout::urgent::ESTOP,
            ..Default::default()
        })
        .unwrap();
    collect_until(&client, &mut events, |e| e.iter().any(|e| e.serial == 99));
    let before: usize = events
        .iter()
        .take_while(|e| e.serial != 99)
        .filter(|e| e.serial >= 100 && e.code == layout::ack::ACCEPTED)
        .count();
    assert!(
        (before as u64) < queued,
        "the e-stop was acknowledged before all {queued} queued commands were taken ({before})"
    );
    let estop = events.iter().find(|e| e.serial == 99).unwrap();
    assert_eq!(estop.code, layout::ack::DONE);
    // And the machine is in e-stop; the queued commands are all taken afterwards.
    collect_until(&client, &mut events, |e| {
        e.iter()
            .filter(|e| e.serial >= 100 && e.code == layout::ack::DONE)
            .count() as u64
            == queued
    });
    let start = Instant::now();
    while state_name(client.status().state) != "estop" {
        assert!(start.elapsed() < Duration::from_secs(10));
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Sends a PLC service request and waits for its reply.
fn plc_service(
    client: &Client,
    serial: u64,
    kind: u32,
    path: &str,
    value: &str,
) -> layout::ServiceReply {
    client
        .request(layout::ServiceRequest {
            serial,
            kind,
            text: layout::WireText::new(path),
            value_text: layout::WireText::new(value),
            ..Default::default()
        })
        .unwrap();
    let start = Instant::now();
    loop {
        client.heartbeat();
        let mut reply = None;
        client.drain_replies(|r| {
            if r.serial == serial {
                reply = Some(r);
            }
        });
        if let Some(r) = reply {
            return r;
        }
        assert!(
            start.elapsed() < Duration::from_secs(30),
            "no reply to {path}"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// mill.st's RETAIN variable, forced to 7 in one machine process, is written to the
/// machine file's `files.plc_retain` (by rename: no temporary file is left) and is 7 again,
/// unforced, in the next machine process started on the same file.
#[test]
fn a_retained_plc_variable_survives_a_restart_of_the_machine_process() {
    let repo = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let dir = std::env::temp_dir().join(format!("rtcnc-clitest-retain-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::copy(repo.join("configs/sim-mill.tbl"), dir.join("sim-mill.tbl")).unwrap();
    let text = std::fs::read_to_string(repo.join("configs/sim-mill.toml"))
        .unwrap()
        .replace(
            "program = \"../examples/plc/mill.st\"",
            &format!("program = {:?}", repo.join("examples/plc/mill.st")),
        )
        .replace(
            "# plc_retain = \"sim-mill.retain\"",
            "plc_retain = \"mill.retain\" #",
        );
    let machine_file = dir.join("mill.toml");
    std::fs::write(&machine_file, text).unwrap();
    let retain = dir.join("mill.retain");
    {
        let (_machine, client) = start_machine_on("retain1", &machine_file);
        let r = plc_service(
            &client,
            1,
            layout::service::PLC_FORCE,
            "Mill.current_tool",
            "7",
        );
        assert_eq!(r.ok, 1, "{}", r.text.as_str());
        let start = Instant::now();
        while !std::fs::read_to_string(&retain)
            .unwrap_or_default()
            .lines()
            .any(|l| l.eq_ignore_ascii_case("MILL.current_tool = 7"))
        {
            client.heartbeat();
            assert!(start.elapsed() < Duration::from_secs(30), "not saved");
            std::thread::sleep(Duration::from_millis(20));
        }
    }
    let mut files: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    files.sort();
    assert_eq!(files, ["mill.retain", "mill.toml", "sim-mill.tbl"]);
    let (_machine, client) = start_machine_on("retain2", &machine_file);
    let r = plc_service(
        &client,
        2,
        layout::service::PLC_READ,
        "Mill.current_tool",
        "",
    );
    assert_eq!((r.ok, r.text.as_str()), (1, "7"));
    let _ = std::fs::remove_dir_all(&dir);
}
