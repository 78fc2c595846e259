//! The real-time tasks allocate nothing per cycle: homing, jogging and the handwheel on the
//! 12-drive gantry (no interpreter involved; the interpreter task may allocate, it is not
//! real-time) run thousands of cycles under a counting allocator; so does the mill with
//! its Structured Text logic and simulated devices.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use rtcnc_kernel::{Command, Kernel, KernelOptions, MachineConfig, MachineState, Simulation};

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
fn gantry_homing_jog_handwheel_and_the_plc_mill_allocate_nothing() {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs/sim-gantry-12.toml");
    let config = MachineConfig::load(&path).unwrap();
    let kernel = Kernel::build(&config, KernelOptions::default()).unwrap();
    let mut sim = Simulation::new(kernel);
    let handle = sim.handle().clone();
    let mut none = |_: &rtcnc_kernel::Sample| {};
    sim.run_cycles(2, &mut none).unwrap();
    handle.command(Command::Reset);
    sim.run_cycles(20, &mut none).unwrap();
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    handle.command(Command::HomeAll);
    sim.run_cycles(5, &mut none).unwrap();
    let homed = sim
        .run_until(Duration::from_secs(300), &mut none, |s| {
            s.state == MachineState::Idle
        })
        .unwrap();
    handle.command(Command::JogIncrement {
        axis: 0,
        distance: 25.0,
    });
    handle.command(Command::JointMove {
        joint: 10,
        position: 30.0,
    });
    // The jog runs at the axis' jog velocity, 10 mm/s: 2.5 s and the ramps.
    sim.run_cycles(3000, &mut none).unwrap();
    handle.command(Command::Handwheel {
        axis: Some(1),
        scale: 100.0,
    });
    sim.run_cycles(5, &mut none).unwrap();
    handle
        .simulated_machine()
        .unwrap()
        .with(|m| m.turn_handwheel(100));
    sim.run_cycles(2000, &mut none).unwrap();
    let allocations = ALLOCATIONS.load(Ordering::SeqCst) - before;
    assert!(handle.take_faults().is_empty());
    assert!(homed);
    let status = handle.status();
    assert_eq!(status.axes[0], 25.0);
    assert_eq!(status.axes[1], 10.0);
    assert_eq!(allocations, 0, "allocations during {} cycles", status.cycle);

    // The mill with its Structured Text logic and devices: the lubrication pulse with its
    // pressure switch, a jog, the door opened and closed, the e-stop pressed and reset.
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs/sim-mill.toml");
    let config = MachineConfig::load(&path).unwrap();
    let kernel = Kernel::build(&config, KernelOptions::default()).unwrap();
    let mut sim = Simulation::new(kernel);
    let handle = sim.handle().clone();
    sim.run_cycles(2, &mut none).unwrap();
    handle.command(Command::Reset);
    sim.run_cycles(20, &mut none).unwrap();
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    handle.command(Command::JogIncrement {
        axis: 0,
        distance: 5.0,
    });
    sim.run_cycles(3000, &mut none).unwrap();
    handle
        .simulated_machine()
        .unwrap()
        .with(|m| m.set_door_open(true))
        .unwrap();
    sim.run_cycles(100, &mut none).unwrap();
    handle
        .simulated_machine()
        .unwrap()
        .with(|m| m.set_door_open(false))
        .unwrap();
    sim.run_cycles(3000, &mut none).unwrap();
    handle
        .simulated_machine()
        .unwrap()
        .with(|m| m.set_estop(true));
    sim.run_cycles(100, &mut none).unwrap();
    handle
        .simulated_machine()
        .unwrap()
        .with(|m| m.set_estop(false));
    sim.run_cycles(10, &mut none).unwrap();
    handle.command(Command::Reset);
    sim.run_cycles(100, &mut none).unwrap();
    let allocations = ALLOCATIONS.load(Ordering::SeqCst) - before;
    let faults: Vec<_> = handle.take_faults().iter().map(|f| f.code).collect();
    assert_eq!(faults, [rtcnc_kernel::FaultCode::EStop]);
    let status = handle.status();
    assert_eq!(status.axes[0], 5.0);
    assert!(status.ready);
    assert_eq!(allocations, 0, "allocations on the mill");
}
