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
    let segment = format!("rtcnc-clitest-{}-{test}", std::process::id());
    let child = Command::new(env!("CARGO_BIN_EXE_rtcnc"))
        .args(["machine", "--machine"])
        .arg(repo.join("configs/sim-mill.toml"))
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
