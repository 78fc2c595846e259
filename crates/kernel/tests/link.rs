//! The shared-memory link in virtual time: a client in this process attached to the segment
//! of a kernel on the virtual-time runner (the real processes are tested by the API's
//! tests). Commands acknowledged by serial, refusals with their reason, an urgent command
//! overtaking a full normal ring, the continuous jog's keep-alive, the loss of the client,
//! the event ring's overflow count, the version check.

use crate::common;
use std::sync::atomic::Ordering;

use rtcnc_kernel::link::layout::{self, WireCommand, WireEvent, WireText, WireUrgent};
use rtcnc_kernel::link::{Client, LinkError, MachineLink, Refusal, state_name};
use rtcnc_kernel::{Kernel, KernelOptions, MachineConfig, Simulation};

struct Rig {
    sim: Simulation,
    client: Client,
    link: MachineLink,
    events: Vec<WireEvent>,
    serial: u64,
}

impl Drop for Rig {
    fn drop(&mut self) {
        self.link.mapping().unlink();
    }
}

fn rig(test: &str, config: &MachineConfig) -> Rig {
    let name = format!("rtcnc-test-{}-{test}", std::process::id());
    let link = MachineLink::create(&name, config).expect("segment");
    let kernel = Kernel::build(
        config,
        KernelOptions {
            link: Some(link.clone()),
            ..KernelOptions::default()
        },
    )
    .expect("kernel");
    let client = Client::attach(&name).expect("attach");
    Rig {
        sim: Simulation::new(kernel),
        client,
        link,
        events: Vec::new(),
        serial: 0,
    }
}

impl Rig {
    fn run_ms(&mut self, ms: u64) {
        for _ in 0..ms {
            self.client.heartbeat();
            self.sim.run_cycles(1, &mut |_| {}).unwrap();
            let events = &mut self.events;
            self.client.drain_events(|e| events.push(e));
        }
    }

    fn send(&mut self, kind: u32, f: impl FnOnce(&mut WireCommand)) -> u64 {
        self.serial += 1;
        let mut c = WireCommand {
            serial: self.serial,
            kind,
            ..WireCommand::default()
        };
        f(&mut c);
        self.client.send(c).expect("room");
        self.serial
    }

    fn urgent(&mut self, kind: u32, value: f64) -> u64 {
        self.serial += 1;
        let u = WireUrgent {
            serial: self.serial,
            kind,
            value,
            ..WireUrgent::default()
        };
        self.client.send_urgent(u).expect("room");
        self.serial
    }

    fn acks(&self, serial: u64) -> Vec<u32> {
        self.events
            .iter()
            .filter(|e| e.kind == layout::event::ACK && e.serial == serial)
            .map(|e| e.code)
            .collect()
    }

    fn state(&self) -> &'static str {
        state_name(self.client.status().state)
    }

    fn reset(&mut self) {
        let s = self.send(layout::command::RESET, |_| {});
        self.run_ms(50);
        assert_eq!(self.acks(s), [layout::ack::ACCEPTED, layout::ack::DONE]);
        assert_eq!(self.state(), "idle");
    }
}

fn mill() -> MachineConfig {
    common::config("sim-mill.toml")
}

#[test]
fn a_command_is_acknowledged_by_serial_and_done_when_its_motion_ends() {
    let mut r = rig("mdi", &mill());
    r.run_ms(20);
    assert_eq!(
        r.state(),
        "estop",
        "the machine starts in e-stop, as LinuxCNC"
    );
    r.reset();
    let s = r.send(layout::command::MDI, |c| {
        c.text = WireText::new("G0 X10 Y-5")
    });
    r.run_ms(5);
    assert_eq!(r.acks(s), [layout::ack::ACCEPTED], "accepted, not yet done");
    r.run_ms(3000);
    assert_eq!(r.acks(s), [layout::ack::ACCEPTED, layout::ack::DONE]);
    let st = r.client.status();
    assert!((st.axes[0] - 10.0).abs() < 1e-9 && (st.axes[1] + 5.0).abs() < 1e-9);
    assert_eq!(state_name(st.state), "idle");
    assert!(
        st.g_codes.contains(&0) && st.g_codes.contains(&540) && st.g_codes.contains(&210),
        "G0, G54, G21 in the modal state: {:?}",
        st.g_codes
    );
    // The serials of the acknowledgements and their order: accepted before done.
    let seqs: Vec<u64> = r.events.iter().map(|e| e.seq).collect();
    assert!(
        seqs.windows(2).all(|w| w[1] == w[0] + 1),
        "no gap: {seqs:?}"
    );
}

#[test]
fn a_refusal_says_why() {
    let mut r = rig("refuse", &mill());
    r.run_ms(20);
    let jog = r.send(layout::command::JOG_CONTINUOUS, |c| c.value = 5.0);
    let start = r.send(layout::command::START, |_| {});
    r.run_ms(10);
    let reason = |serial: u64| {
        r.events
            .iter()
            .find(|e| e.serial == serial && e.code == layout::ack::REFUSED)
            .and_then(|e| Refusal::from_number(e.number))
    };
    assert_eq!(reason(jog), Some(Refusal::NotReady), "in e-stop");
    assert_eq!(reason(start), Some(Refusal::NoProgram));
    r.reset();
    let bad_axis = r.send(layout::command::JOG_INCREMENT, |c| {
        c.axis = 4; // B: not on the mill
        c.value = 1.0;
    });
    r.run_ms(10);
    let reason = r
        .events
        .iter()
        .find(|e| e.serial == bad_axis && e.code == layout::ack::REFUSED)
        .and_then(|e| Refusal::from_number(e.number));
    assert_eq!(reason, Some(Refusal::BadAxis));
}

#[test]
fn an_urgent_command_overtakes_a_full_normal_ring_within_one_period() {
    let mut r = rig("urgent", &mill());
    r.run_ms(20);
    r.reset();
    // Fill the normal ring without letting the machine run.
    let mut queued = 0;
    loop {
        r.serial += 1;
        let c = WireCommand {
            serial: r.serial,
            kind: layout::command::JOG_INCREMENT,
            value: 0.5,
            ..WireCommand::default()
        };
        if r.client.send(c).is_err() {
            break;
        }
        queued += 1;
    }
    assert_eq!(queued, layout::COMMAND_SLOTS);
    let estop = r.urgent(layout::urgent::ESTOP, 0.0);
    r.run_ms(1);
    let ack = r
        .events
        .iter()
        .find(|e| e.serial == estop)
        .copied()
        .expect("the e-stop is acknowledged in the first period");
    assert_eq!(ack.code, layout::ack::DONE);
    assert_eq!(
        ack.cycle - ack.written_cycle,
        1,
        "read in the period after the one it was written in"
    );
    assert!(
        r.client.status().last_fault != 0,
        "the e-stop is in the status after one period"
    );
    r.run_ms(100);
    assert_eq!(r.state(), "estop");
}

#[test]
fn a_continuous_jog_stops_without_its_keep_alive() {
    let mut r = rig("keepalive", &mill());
    r.run_ms(20);
    r.reset();
    let jog = r.send(layout::command::JOG_CONTINUOUS, |c| c.value = 10.0);
    // With keep-alives every 100 ms the jog goes on for a second.
    for _ in 0..10 {
        r.run_ms(100);
        r.send(layout::command::JOG_KEEP_ALIVE, |_| {});
    }
    assert_eq!(r.state(), "running");
    let x = r.client.status().axes[0];
    assert!(x > 8.0, "jogged {x} mm in a second at 10 mm/s");
    // Without them it stops.
    r.run_ms(600);
    assert_eq!(r.state(), "idle");
    assert_eq!(
        r.acks(jog),
        [layout::ack::ACCEPTED, layout::ack::DONE],
        "the jog is done once it stopped"
    );
    let stopped = r.client.status().axes[0];
    // 10 mm/s for at most 200 ms + the deceleration (under 0.5 mm on the mill).
    assert!(stopped - x < 2.0 + 0.5, "went on {} mm", stopped - x);
}

/// A continuous jog stopped by the client's urgent jog stop, then an incremental jog: the
/// keep-alive of the stopped jog must not lapse into the incremental one (it did: the
/// increment stopped short, 200 ms after the last keep-alive).
#[test]
fn an_incremental_jog_after_a_stopped_continuous_one_runs_its_whole_distance() {
    let mut r = rig("keepalive-increment", &mill());
    r.run_ms(20);
    r.reset();
    r.send(layout::command::JOG_CONTINUOUS, |c| c.value = 10.0);
    r.run_ms(100);
    r.urgent(layout::urgent::JOG_STOP, 0.0);
    r.run_ms(100);
    assert_eq!(r.state(), "idle");
    let from = r.client.status().axes[0];
    let step = r.send(layout::command::JOG_INCREMENT, |c| c.value = 5.0);
    // At the mill's X jog speed (10 mm/s) 5 mm take over 500 ms: the increment is still
    // moving when the stopped jog's keep-alive would have lapsed.
    r.run_ms(3000);
    assert_eq!(r.acks(step), [layout::ack::ACCEPTED, layout::ack::DONE]);
    assert_eq!(r.state(), "idle");
    let moved = r.client.status().axes[0] - from;
    assert!((moved - 5.0).abs() < 1e-9, "moved {moved} mm of 5");
}

#[test]
fn the_loss_of_the_client_stops_a_jog_and_holds_a_program_when_configured() {
    let mut config = mill();
    config.hmi.on_loss = rtcnc_kernel::config::OnLoss::Hold;
    let mut r = rig("loss", &config);
    let program = common::program("G1 X200 F600\nM2\n", "loss.ngc");
    r.run_ms(20);
    r.reset();
    let load = r.send(layout::command::LOAD_PROGRAM, |c| {
        c.text = WireText::new(program.to_str().unwrap())
    });
    let start = r.send(layout::command::START, |_| {});
    r.run_ms(500);
    assert_eq!(r.acks(load), [layout::ack::ACCEPTED, layout::ack::DONE]);
    assert_eq!(r.acks(start), [layout::ack::ACCEPTED]);
    assert_eq!(r.state(), "running");
    // The client stops beating.
    for _ in 0..400 {
        r.sim.run_cycles(1, &mut |_| {}).unwrap();
    }
    assert_eq!(r.state(), "held", "[hmi] on_loss = hold");
    let seg = r.link.mapping().segment();
    assert_eq!(seg.client_losses.load(Ordering::Relaxed), 1);
    assert_eq!(seg.client_pid.load(Ordering::Relaxed), 0);
    let events = &mut r.events;
    r.client.drain_events(|e| events.push(e));
    assert!(
        r.events
            .iter()
            .any(|e| e.kind == layout::event::CLIENT_LOST)
    );
}

#[test]
fn events_lost_to_a_full_ring_are_counted_and_leave_a_gap_in_the_numbers() {
    let mut r = rig("overflow", &mill());
    r.run_ms(20);
    for i in 0..700u64 {
        r.send(layout::command::SINGLE_BLOCK, |c| c.number = i % 2);
        r.client.heartbeat();
        // Keep the command ring from filling, but never read the events.
        if r.client.mapping().segment().commands.len() > 32 {
            r.sim.run_cycles(1, &mut |_| {}).unwrap();
        }
    }
    r.sim.run_cycles(50, &mut |_| {}).unwrap();
    let mut seen = Vec::new();
    r.client.drain_events(|e| seen.push(e.seq));
    let dropped = r.client.status().events_dropped;
    assert_eq!(seen.len(), layout::EVENT_SLOTS, "the ring was full");
    // 700 commands, two acknowledgements each (accepted, done), after the events read at
    // start-up; the ring keeps the oldest, the newest are dropped and counted.
    assert_eq!(seen.len() as u64 + dropped, 1400);
    assert_eq!(seen[0], r.events.len() as u64 + 1);
    assert!(seen.windows(2).all(|w| w[1] == w[0] + 1));
}

#[test]
fn a_client_of_another_layout_is_refused_naming_both_versions() {
    let config = mill();
    let name = format!("rtcnc-test-{}-version", std::process::id());
    let link = MachineLink::create(&name, &config).unwrap();
    let path = link.mapping().path().to_path_buf();
    // Another build's segment: same magic, version 99.
    let mut bytes = std::fs::read(&path).unwrap();
    bytes[8..12].copy_from_slice(&99u32.to_le_bytes());
    std::fs::write(&path, &bytes).unwrap();
    let err = Client::attach(&name).err().expect("refused");
    assert!(matches!(
        err,
        LinkError::Version {
            found: 99,
            expected: layout::LAYOUT_VERSION,
            ..
        }
    ));
    let text = err.to_string();
    assert!(text.contains("99") && text.contains(&layout::LAYOUT_VERSION.to_string()));
    std::fs::write(&path, b"not a segment at all, just some bytes........").unwrap();
    assert!(matches!(
        Client::attach(&name),
        Err(LinkError::NotASegment(_))
    ));
    std::fs::remove_file(&path).unwrap();
    assert!(matches!(Client::attach(&name), Err(LinkError::Absent(_))));
}

#[test]
fn a_client_replaced_without_leaving_counts_as_lost_and_a_clean_detach_does_not() {
    let mut r = rig("replaced", &mill());
    r.run_ms(20);
    let map = r.link.mapping().clone();
    let seg = map.segment();
    // Another process takes the place of the attached one, which never left (killed).
    let before = seg.client_losses.load(Ordering::Relaxed);
    seg.client_pid.store(1, Ordering::Release);
    r.run_ms(5);
    assert_eq!(seg.client_losses.load(Ordering::Relaxed), before + 1);
    // That client leaves cleanly (what `Client::detach` does), then another attaches at
    // once: no loss.
    seg.client_pid.store(0, Ordering::Release);
    seg.client_detaches.fetch_add(1, Ordering::AcqRel);
    seg.client_pid.store(std::process::id(), Ordering::Release);
    r.run_ms(5);
    assert_eq!(seg.client_losses.load(Ordering::Relaxed), before + 1);
    assert!(
        r.events
            .iter()
            .filter(|e| e.kind == layout::event::CLIENT_LOST)
            .count()
            == 1
    );
}
