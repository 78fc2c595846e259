//! The link's real-time tasks allocate nothing: commands acknowledged by serial, refusals,
//! urgent commands, a continuous jog and its keep-alive, the status, events and trace
//! published every period, the loss of the client, all under a counting allocator, on the
//! mill with its Structured Text logic.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicU64, Ordering};

use rtcnc_kernel::link::layout::{self, WireCommand, WireEvent, WireUrgent};
use rtcnc_kernel::link::{Client, MachineLink};
use rtcnc_kernel::{Kernel, KernelOptions, MachineConfig, Simulation};

struct Counting;
static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        // SAFETY: forwarded unchanged.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: forwarded unchanged.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        // SAFETY: forwarded unchanged.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn the_links_tasks_allocate_nothing() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs/sim-mill.toml");
    let config = MachineConfig::load(&path).unwrap();
    let name = format!("rtcnc-test-{}-noalloc", std::process::id());
    let link = MachineLink::create(&name, &config).unwrap();
    let kernel = Kernel::build(
        &config,
        KernelOptions {
            link: Some(link.clone()),
            ..KernelOptions::default()
        },
    )
    .unwrap();
    let client = Client::attach(&name).unwrap();
    let mut sim = Simulation::new(kernel);
    let mut events: Vec<WireEvent> = Vec::with_capacity(100_000);
    let mut none = |_: &rtcnc_kernel::Sample| {};
    let mut run = |sim: &mut Simulation, events: &mut Vec<WireEvent>, cycles: u32, beat: bool| {
        for _ in 0..cycles {
            if beat {
                client.heartbeat();
            }
            sim.run_cycles(1, &mut none).unwrap();
            client.drain_events(|e| events.push(e));
            client.drain_trace(|_| {});
        }
    };
    let cmd = |serial: u64, kind: u32, axis: u32, value: f64| WireCommand {
        serial,
        kind,
        axis,
        value,
        ..WireCommand::default()
    };
    run(&mut sim, &mut events, 20, true);
    client.send(cmd(1, layout::command::RESET, 0, 0.0)).unwrap();
    run(&mut sim, &mut events, 100, true);
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    client
        .send(cmd(2, layout::command::JOG_INCREMENT, 0, 1.0))
        .unwrap();
    run(&mut sim, &mut events, 2000, true);
    client
        .send(cmd(3, layout::command::JOG_CONTINUOUS, 1, 10.0))
        .unwrap();
    for _ in 0..5 {
        run(&mut sim, &mut events, 100, true);
        client
            .send(cmd(4, layout::command::JOG_KEEP_ALIVE, 1, 0.0))
            .unwrap();
    }
    client
        .send_urgent(WireUrgent {
            serial: 5,
            kind: layout::urgent::FEED_OVERRIDE,
            value: 0.5,
            ..WireUrgent::default()
        })
        .unwrap();
    client
        .send_urgent(WireUrgent {
            serial: 6,
            kind: layout::urgent::JOG_STOP,
            axis: 1,
            ..WireUrgent::default()
        })
        .unwrap();
    // Refused: no axis B on the mill; a start without a program.
    client
        .send(cmd(7, layout::command::JOG_INCREMENT, 4, 1.0))
        .unwrap();
    client.send(cmd(8, layout::command::START, 0, 0.0)).unwrap();
    run(&mut sim, &mut events, 300, true);
    // A jog, then the client stops beating: lost, the jog stops.
    client
        .send(cmd(9, layout::command::JOG_CONTINUOUS, 0, -10.0))
        .unwrap();
    run(&mut sim, &mut events, 10, true);
    run(&mut sim, &mut events, 600, false);
    let after = ALLOCATIONS.load(Ordering::SeqCst);
    let status = client.status();
    link.mapping().unlink();
    assert_eq!(after - before, 0, "allocations in the link's tasks");
    // What ran is what the test meant to run.
    let acked =
        |serial: u64, code: u32| events.iter().any(|e| e.serial == serial && e.code == code);
    assert!(acked(2, layout::ack::DONE), "jog increment");
    assert!(acked(3, layout::ack::DONE), "continuous jog");
    assert!(acked(6, layout::ack::DONE), "jog stop");
    assert!(acked(7, layout::ack::REFUSED) && acked(8, layout::ack::REFUSED));
    assert!(events.iter().any(|e| e.kind == layout::event::CLIENT_LOST));
    assert_eq!(rtcnc_kernel::link::state_name(status.state), "idle");
    assert!(status.trace_dropped == 0 && status.events_dropped == 0);
}
