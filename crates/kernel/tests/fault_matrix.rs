//! The fault matrix of docs/safety.md: every fault injected while the simulated mill's X
//! axis runs at 100 mm/s, and the travel and time of the load (the simulated machine's
//! true state, not the set-point) from the fault to standstill, asserted against the bounds
//! the document states. The table is read from docs/safety.md itself, so the document
//! and the test cannot drift apart.

use crate::common::*;
use std::time::Duration;

use rtcnc_ecat_slave_sim::Fault as SegmentFault;
use rtcnc_fieldbus::Cia402State;
use rtcnc_fieldbus::sim::InjectedFault;
use rtcnc_kernel::{
    FaultCode, Kernel, KernelOptions, MachineConfig, MachineState, Simulation, Urgent,
};

/// X from 0 to 280 at 100 mm/s (the axis' limit).
const PROGRAM: &str = "G21 G90 G61\nG1 X280 F6000\nM2\n";
/// Where the fault comes: X at speed, well before the end.
const AT_X: f64 = 120.0;

/// What stopped the load, measured.
#[derive(Debug)]
struct Stop {
    travel_mm: f64,
    time_ms: f64,
    faults: Vec<FaultCode>,
    state: MachineState,
    /// Joints whose drive still holds torque (operation enabled or quick stop active) at
    /// the end, as the drives know it; `None` where not measured.
    drives_holding: Option<Vec<usize>>,
}

/// One way to cause a fault, done when X passes `AT_X` (or, for the faults the machine
/// raises by itself, prepared in the configuration).
#[derive(Debug, Clone, Copy)]
enum Cause {
    EStopCommand,
    EStopButton,
    HardLimit,
    FollowingError,
    DriveFault,
    CommunicationLoss,
    DeadlineMiss,
    LogicFault,
    SetpointsRanDry,
}

impl Cause {
    fn from_row(name: &str) -> Cause {
        match name {
            "e-stop (command)" => Cause::EStopCommand,
            "e-stop (button)" => Cause::EStopButton,
            "hard limit" => Cause::HardLimit,
            "following error" => Cause::FollowingError,
            "drive fault" => Cause::DriveFault,
            "fieldbus loss" => Cause::CommunicationLoss,
            "deadline overrun" => Cause::DeadlineMiss,
            "PLC fault" => Cause::LogicFault,
            "set-point underrun" => Cause::SetpointsRanDry,
            other => panic!("docs/safety.md names a fault this test does not know: {other}"),
        }
    }
}

fn mill_with(edit: impl FnOnce(&str) -> String) -> MachineConfig {
    let text = edit(&std::fs::read_to_string(repo().join("configs/sim-mill.toml")).unwrap());
    let mut cfg = MachineConfig::parse(&text, "sim-mill.toml").unwrap();
    cfg.base_dir = repo().join("configs");
    cfg
}

/// The load's X position and whether any axis moves, every period from the start.
struct Trace {
    x: Vec<f64>,
}

/// The load's true state (position, velocity) of a joint: the simulated machine's, or the
/// simulated EtherCAT drive's.
fn true_state(m: &Machine, joint: usize) -> (f64, f64) {
    let handle = m.sim.handle();
    match handle.simulated_machine() {
        Ok(machine) => machine.with(|machine| machine.true_state(joint).unwrap()),
        Err(_) => handle
            .simulated_ethercat()
            .unwrap()
            .true_state(joint)
            .unwrap(),
    }
}

fn true_x(m: &Machine) -> f64 {
    true_state(m, 0).0
}

fn any_axis_moves(m: &Machine) -> bool {
    let joints = m.sim.handle().config().joints.len();
    (0..joints).any(|j| true_state(m, j).1.abs() > 1e-6)
}

/// The machine (as configured for `cause`) running the program from power-on, stepped one
/// period at a time; `act` is called before every period with the period's number.
fn run_mill(
    cfg: &MachineConfig,
    options: KernelOptions,
    mut act: impl FnMut(u64, &Machine) -> bool,
) -> (Machine, Trace) {
    let kernel = Kernel::build(cfg, options).expect("kernel builds");
    let mut m = Machine {
        sim: Simulation::new(kernel),
        samples: Vec::new(),
        faults: Vec::new(),
    };
    let mut trace = Trace { x: Vec::new() };
    m.cycles(2);
    m.command(rtcnc_kernel::Command::Reset);
    m.cycles(10);
    m.command(rtcnc_kernel::Command::Start { from_line: 0 });
    let mut still = 0;
    for period in 0..10_000u64 {
        if !act(period, &m) {
            break;
        }
        m.cycles(1);
        trace.x.push(true_x(&m));
        let faulted = !m.faults.is_empty();
        still = if faulted && !any_axis_moves(&m) {
            still + 1
        } else {
            0
        };
        if still == 50 {
            break;
        }
    }
    (m, trace)
}

fn measure(cause: Cause) -> Stop {
    let options = || KernelOptions {
        program: Some(program(PROGRAM, &format!("matrix-{cause:?}.ngc"))),
        record_capacity: 1 << 14,
        ..KernelOptions::default()
    };
    let cfg = match cause {
        // The switch where X runs at speed.
        Cause::HardLimit => mill_with(|t| {
            t.replacen(
                "positive_limit_switch = 312.0",
                &format!("positive_limit_switch = {AT_X}"),
                1,
            )
        }),
        Cause::DeadlineMiss => {
            let mut cfg = config("sim-mill.toml");
            cfg.safety.deadline_miss = rtcnc_kernel::config::MissReactionConfig::Estop;
            cfg
        }
        _ => config("sim-mill.toml"),
    };
    // The faults made inside the executive (an overrun, a stall of interpolation) are
    // placed at the interpolation activation in which X passes AT_X, found on a run
    // without them (the runs are deterministic).
    let mut opts = options();
    if let Cause::DeadlineMiss | Cause::SetpointsRanDry = cause {
        let mut reached = None;
        run_mill(&cfg, options(), |period, m| {
            if reached.is_none() && true_x(m) >= AT_X {
                reached = Some(m.sim.now().as_millis() as u64);
            }
            reached.is_none() && period < 5000
        });
        let at = reached.expect("X reaches AT_X");
        opts.interpolation_stall = Some((
            at,
            match cause {
                // An overrun of 3 periods: a deadline miss.
                Cause::DeadlineMiss => Duration::from_millis(3),
                // Longer than the set-point lead (50 ms).
                _ => Duration::from_millis(100),
            },
        ));
    }
    let mut injected = false;
    let (m, trace) = run_mill(&cfg, opts, |period, m| {
        // The lubrication pressure switch fails before the pump's first pressure: mill.st
        // reports its machine fault 2 s after machine-on, with X at speed.
        if period == 0 && matches!(cause, Cause::LogicFault) {
            m.sim.handle().simulated_machine().unwrap().with(|machine| {
                machine
                    .inject(InjectedFault::StuckInput {
                        input: 2,
                        value: false,
                    })
                    .unwrap()
            });
        }
        if !injected && true_x(m) >= AT_X {
            injected = true;
            let inject = |fault| {
                m.sim
                    .handle()
                    .simulated_machine()
                    .unwrap()
                    .with(|machine| machine.inject(fault).unwrap())
            };
            match cause {
                Cause::EStopCommand => assert!(m.sim.handle().urgent(Urgent::EStop)),
                Cause::EStopButton => m
                    .sim
                    .handle()
                    .simulated_machine()
                    .unwrap()
                    .with(|machine| machine.set_estop(true)),
                Cause::FollowingError => inject(InjectedFault::EncoderLoss { joint: 0 }),
                Cause::DriveFault => inject(InjectedFault::DriveFault {
                    joint: 0,
                    error_code: 0x2310,
                }),
                Cause::CommunicationLoss => inject(InjectedFault::CommunicationLoss),
                _ => {}
            }
        }
        true
    });
    let first = m.faults.first().expect("a fault");
    // From the period the first fault was raised in (the machine's reaction starts there)
    // to the first of the periods it stood in.
    let t0 = (first.time_ns / 1_000_000) as usize;
    let start = m.sim.now().as_millis() as usize - trace.x.len();
    let i0 = t0.saturating_sub(start).min(trace.x.len() - 1);
    let stood = trace.x.len() - 50;
    let drives_holding = m.handle_machine(|machine| {
        (0..3)
            .filter(|&j| {
                matches!(
                    machine.drive_state(j),
                    Some(Cia402State::OperationEnabled | Cia402State::QuickStopActive)
                )
            })
            .collect()
    });
    Stop {
        travel_mm: trace.x[stood] - trace.x[i0],
        time_ms: (stood - i0) as f64,
        faults: m.faults.iter().map(|f| f.code).collect(),
        state: m.status().state,
        drives_holding: Some(drives_holding),
    }
}

/// One row of docs/safety.md's matrix.
struct Row {
    fault: String,
    code: String,
    /// What the fault's text names (the EtherCAT table).
    says: String,
    category: u8,
    travel_mm: f64,
    time_ms: f64,
}

fn documented_matrix() -> Vec<Row> {
    documented_table("| fault | code |")
}

/// The table of docs/safety.md whose header starts with `header`; the EtherCAT table has a
/// column of what the fault's text says after its code.
fn documented_table(header: &str) -> Vec<Row> {
    let text = std::fs::read_to_string(repo().join("docs/safety.md")).unwrap();
    let says = header.starts_with("| EtherCAT");
    let table = text
        .split(header)
        .nth(1)
        .expect("docs/safety.md has the table");
    table
        .lines()
        .skip(2)
        .take_while(|l| l.starts_with('|'))
        .map(|l| {
            let cells: Vec<&str> = l.split('|').map(str::trim).collect();
            // The EtherCAT table has "says" after the code.
            let k = usize::from(says);
            Row {
                fault: cells[1].to_string(),
                code: cells[2].trim_matches('`').to_string(),
                says: if says {
                    cells[3].trim_matches('`').to_string()
                } else {
                    String::new()
                },
                category: cells[5 + k].parse().unwrap(),
                travel_mm: cells[6 + k].parse().unwrap(),
                time_ms: cells[7 + k].parse().unwrap(),
            }
        })
        .collect()
}

/// The stop keeps the row's travel and time, and ends in the safe state: categories 0 and 1
/// both end with the drives off, the machine waiting for a reset.
fn assert_within_row(row: &Row, stop: &Stop) {
    assert!(
        stop.travel_mm <= row.travel_mm,
        "{}: {:.2} mm > {} mm",
        row.fault,
        stop.travel_mm,
        row.travel_mm
    );
    assert!(
        stop.time_ms <= row.time_ms,
        "{}: {} ms > {} ms",
        row.fault,
        stop.time_ms,
        row.time_ms
    );
    assert!(matches!(row.category, 0 | 1), "{}", row.fault);
    assert!(
        matches!(stop.state, MachineState::EStop | MachineState::Fault),
        "{}: {:?}",
        row.fault,
        stop.state
    );
    // 50 periods after the load stood, no drive holds torque (a following error left the
    // drives in their quick stop, powered, for ever: category 2, not 1).
    if let Some(holding) = &stop.drives_holding {
        assert!(
            holding.is_empty(),
            "{}: drives of joints {holding:?} still hold torque",
            row.fault
        );
    }
}

#[test]
fn every_fault_stops_the_load_within_its_documented_travel_and_time() {
    let rows = documented_matrix();
    assert_eq!(rows.len(), 9, "the matrix has a row per fault of issue 11");
    for row in rows {
        let stop = measure(Cause::from_row(&row.fault));
        assert_eq!(
            stop.faults[0].as_str(),
            row.code,
            "{}: {:?}",
            row.fault,
            stop.faults
        );
        // Stopped at speed: the bound is not met by stopping early or by standing still.
        assert!(stop.travel_mm > 1.0, "{}: {stop:?}", row.fault);
        assert_within_row(&row, &stop);
    }
}

/// A fault of the EtherCAT bus, injected into the simulated devices when X passes `AT_X`.
#[derive(Debug, Clone, Copy)]
enum BusCause {
    FrameLoss,
    ProcessDataLoss,
    SafeOp,
    DriveFault,
    LinkDown,
}

impl BusCause {
    fn from_row(name: &str) -> BusCause {
        match name {
            "frame loss" => BusCause::FrameLoss,
            "process data missing" => BusCause::ProcessDataLoss,
            "device leaves OP" => BusCause::SafeOp,
            "drive fault (0x603F)" => BusCause::DriveFault,
            "link down" => BusCause::LinkDown,
            other => {
                panic!("docs/safety.md names an EtherCAT fault this test does not know: {other}")
            }
        }
    }

    fn fault(self, drive: usize) -> SegmentFault {
        match self {
            BusCause::FrameLoss => SegmentFault::FrameLoss { rate: 0.5 },
            BusCause::ProcessDataLoss => SegmentFault::ProcessDataLoss { slave: drive },
            BusCause::SafeOp => SegmentFault::FallToSafeOp {
                slave: drive,
                code: 0x001A,
            },
            BusCause::DriveFault => SegmentFault::DriveFault {
                slave: drive,
                error_code: 0x2310,
            },
            BusCause::LinkDown => SegmentFault::LinkDown,
        }
    }
}

fn measure_bus(cause: BusCause) -> (Stop, String) {
    let cfg = config("ethercat-sim-12.toml");
    let options = KernelOptions {
        program: Some(program(PROGRAM, &format!("matrix-{cause:?}.ngc"))),
        record_capacity: 1 << 14,
        ..KernelOptions::default()
    };
    let mut injected = false;
    let (m, trace) = run_mill(&cfg, options, |_, m| {
        if !injected && true_x(m) >= AT_X {
            injected = true;
            let bus = m.sim.handle().simulated_ethercat().unwrap();
            // X0's drive.
            let drive = bus.drive_position(0).unwrap();
            bus.inject(cause.fault(drive)).unwrap();
        }
        true
    });
    let first = m.faults.first().expect("a fault");
    let text = m.sim.handle().describe(first);
    let t0 = (first.time_ns / 1_000_000) as usize;
    let start = m.sim.now().as_millis() as usize - trace.x.len();
    let i0 = t0.saturating_sub(start).min(trace.x.len() - 1);
    let stood = trace.x.len() - 50;
    let stop = Stop {
        travel_mm: trace.x[stood] - trace.x[i0],
        time_ms: (stood - i0) as f64,
        faults: m.faults.iter().map(|f| f.code).collect(),
        state: m.status().state,
        // The simulated EtherCAT devices' drive states are not read here.
        drives_holding: None,
    };
    (stop, text)
}

/// The EtherCAT table of docs/safety.md: each fault of the bus, injected into the simulated
/// devices of configs/ethercat-sim-12.toml while X runs at 100 mm/s, raises its code with
/// the bus's reason in words and stops X0's load within the stated travel and time, the
/// machine in its safe state.
#[test]
fn every_ethercat_fault_stops_the_load_within_its_documented_travel_and_time() {
    let rows = documented_table("| EtherCAT fault | code |");
    assert_eq!(rows.len(), 5, "a row per fault of the bus");
    for row in rows {
        let (stop, text) = measure_bus(BusCause::from_row(&row.fault));
        eprintln!("{}: {stop:?}\n  {text}", row.fault);
        assert_eq!(stop.faults[0].as_str(), row.code, "{}: {stop:?}", row.fault);
        assert!(
            text.contains(&row.says),
            "{}: {text:?} lacks {:?}",
            row.fault,
            row.says
        );
        assert!(stop.travel_mm > 0.1, "{}: {stop:?}", row.fault);
        assert_within_row(&row, &stop);
    }
}
