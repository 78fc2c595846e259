//! The real-time tasks allocate nothing per cycle: homing, jogging and the handwheel on the
//! 12-drive gantry (no interpreter involved) run thousands of cycles under a counting
//! allocator; so does the mill with its Structured Text logic and simulated devices; and
//! whole programs (lines, arcs, helices, splines, canned cycles, tool changes, spindle-
//! synchronised threading) run through every real-time task, whose allocations are counted
//! apart from the interpreter's and tool compensation's (event tasks, not real-time: they
//! may allocate); so do homing, a jog and thread passes through a stall of interpolation.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::time::Duration;

use rtcnc_kernel::{Command, Kernel, KernelOptions, MachineConfig, MachineState, Simulation};

mod common;

struct Counting;

thread_local! {
    /// Every allocation of this thread (the tests of this file run on parallel threads; a
    /// simulation runs all its tasks on the thread that runs it).
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
    /// The allocations this thread made inside the body of a periodic (real-time) task.
    static IN_PERIODIC: Cell<u64> = const { Cell::new(0) };
}

fn count() {
    // `try_with`: the allocator also runs while thread-locals are torn down.
    let _ = ALLOCATIONS.try_with(|n| n.set(n.get() + 1));
    if rtcnc_rt::in_periodic_body() {
        let _ = IN_PERIODIC.try_with(|n| n.set(n.get() + 1));
    }
}

fn allocated() -> u64 {
    ALLOCATIONS.with(Cell::get)
}

fn in_periodic() -> u64 {
    IN_PERIODIC.with(Cell::get)
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: forwarded unchanged.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: forwarded unchanged.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
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
    let before = allocated();
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
    let allocations = allocated() - before;
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
    let before = allocated();
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
    let allocations = allocated() - before;
    let faults: Vec<_> = handle.take_faults().iter().map(|f| f.code).collect();
    assert_eq!(faults, [rtcnc_kernel::FaultCode::EStop]);
    let status = handle.status();
    assert_eq!(status.axes[0], 5.0);
    assert!(status.ready);
    assert_eq!(allocations, 0, "allocations on the mill");
}

/// Canned cycles (drilling, peck and chip-breaking), a tool change, spindle and coolant.
const DRILLING: &str = "G21 G90 G17 G94
T2 M6
S3000 M3 M8
G0 X10 Y10 Z2
G98 G81 X10 Y10 Z-5 R1 F300
X20
G83 X30 Y10 Z-8 R1 Q2 F300
G99 G73 X40 Z-6 R1 Q1.5
G80
G0 Z4
M9 M5
M2
";

/// Runs `program` (in `examples/`, or "drilling") on `machine` to its end and returns the allocations made
/// in periodic task bodies meanwhile (from the start command to the end).
fn periodic_allocations_of(machine: &str, program: &str) -> u64 {
    let config = common::config(machine);
    let path = match program {
        "drilling" => common::program(DRILLING, "drilling.ngc"),
        _ => common::repo().join("examples").join(program),
    };
    let mut m = common::Machine::new(&config, Some(path));
    m.power_on();
    let before = in_periodic();
    m.command(Command::Start { from_line: 0 });
    let ended = m.until(600.0, |s| s.program_ended && s.state == MachineState::Idle);
    let allocations = in_periodic() - before;
    assert!(
        ended && m.faults.is_empty(),
        "{program}: ended {ended}, {:?} {:?}",
        m.faults,
        m.sim.handle().error_text()
    );
    allocations
}

#[test]
fn whole_programs_allocate_nothing_in_the_real_time_tasks() {
    for (machine, program) in [
        ("sim-mill.toml", "bracket.ngc"),
        ("sim-mill.toml", "gcode/arc_corners.ngc"),
        ("sim-mill.toml", "gcode/splines.ngc"),
        ("sim-mill.toml", "drilling"),
        ("sim-mill.toml", "gcode/pocket.ngc"),
        ("sim-lathe.toml", "lathe-thread.ngc"),
        ("sim-lathe.toml", "gcode/lathe_roughing.ngc"),
        ("sim-lathe.toml", "gcode/rigid_tap.ngc"),
        ("sim-lathe.toml", "gcode/thread.ngc"),
    ] {
        let n = periodic_allocations_of(machine, program);
        assert_eq!(
            n, 0,
            "{program} on {machine}: {n} allocations in real-time tasks"
        );
    }
}

/// Homing, a jog and a thread pass through stalls of interpolation shorter than the lead:
/// the set-points computed ahead are taken back and computed again after each, without
/// allocating in the real-time tasks (the executive's deadline-miss reports are not).
#[test]
fn manual_motions_through_a_stall_allocate_nothing_in_the_real_time_tasks() {
    let stalled = |machine: &str, at: u64, program: Option<std::path::PathBuf>| {
        let config = common::config(machine);
        let options = KernelOptions {
            interpolation_stall: Some((at, Duration::from_millis(15))),
            program,
            record_capacity: 1 << 14,
            ..KernelOptions::default()
        };
        let kernel = Kernel::build(&config, options).unwrap();
        let mut sim = Simulation::new(kernel);
        let mut none = |_: &rtcnc_kernel::Sample| {};
        sim.run_cycles(2, &mut none).unwrap();
        sim.handle().command(Command::Reset);
        sim.run_cycles(20, &mut none).unwrap();
        (sim, none)
    };
    // The gantry homes from activation 22 on, for seconds.
    let (mut sim, mut none) = stalled("sim-gantry-12.toml", 300, None);
    let before = in_periodic();
    sim.handle().command(Command::HomeAll);
    sim.run_cycles(5, &mut none).unwrap();
    let homed = sim
        .run_until(Duration::from_secs(300), &mut none, |s| {
            s.state == MachineState::Idle
        })
        .unwrap();
    assert!(homed && sim.handle().take_faults().is_empty());
    assert_eq!(in_periodic() - before, 0, "homing");
    // A jog on the mill, at speed at activation 300.
    let (mut sim, mut none) = stalled("sim-mill.toml", 300, None);
    let before = in_periodic();
    sim.handle().command(Command::JogIncrement {
        axis: 0,
        distance: 20.0,
    });
    sim.run_cycles(3000, &mut none).unwrap();
    assert!(sim.handle().take_faults().is_empty());
    assert_eq!(sim.handle().status().axes[0], 20.0);
    assert_eq!(in_periodic() - before, 0, "jog");
    // A G33 pass on the lathe, cutting at activation 1400.
    let text = "G18 G21 G90 G7\nG0 X20 Z5\nS600 M3\nG33 Z-20 K1.5\nG0 X30\nM5\nM2\n";
    let thread = common::program(text, "no-alloc-g33.ngc");
    let (mut sim, _) = stalled("sim-lathe.toml", 1400, Some(thread));
    let mut lines = Vec::with_capacity(10_000);
    let mut sink = |s: &rtcnc_kernel::Sample| {
        if lines.len() < lines.capacity() {
            lines.push((s.cycle, s.line));
        }
    };
    let before = in_periodic();
    sim.handle().command(Command::Start { from_line: 0 });
    let ended = sim
        .run_until(Duration::from_secs(60), &mut sink, |s| {
            s.program_ended && s.state == MachineState::Idle
        })
        .unwrap();
    assert!(ended && sim.handle().take_faults().is_empty());
    assert!(lines.contains(&(1400, 4)));
    assert!(sim.handle().setpoint_lead().1 >= 15);
    assert_eq!(in_periodic() - before, 0, "thread");
}

/// The count sees what a periodic body allocates, and only that.
#[test]
fn the_counter_counts_periodic_bodies_only() {
    let mut b = rtcnc_rt::TaskSet::builder();
    let thread = b.periodic_thread("servo", Duration::from_millis(1), 10);
    b.periodic(thread, "allocates", 1, |ctx| {
        std::hint::black_box(vec![ctx.activation(); 4]);
    });
    let mut runner = rtcnc_rt::VirtualRunner::new(b.build().unwrap());
    let before = in_periodic();
    std::hint::black_box(vec![0u8; 16]);
    runner.run_for(Duration::from_millis(3)).unwrap();
    assert_eq!(in_periodic() - before, 3);
}
