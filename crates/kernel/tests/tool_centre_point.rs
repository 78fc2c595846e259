//! Tool-centre-point control (M428/M429) on the tilting/rotary table of
//! `configs/sim-5axis-trt.toml`: the tool tip, computed from the joint set-points by
//! LinuxCNC's xyzac-trt forward formula (written out below, not the crate's), stays on
//! the programmed lines within the machine file's tolerance, every joint keeps its limits,
//! TCP off moves the joints as programmed, and what cannot run stops at its line.

use crate::common;
use crate::common::*;
use rtcnc_kernel::{Command, FaultCode, MachineState, Sample};

const DT: f64 = 0.001;
/// The machine file's `kinematics.tolerance`, and its offsets.
const TOLERANCE: f64 = 0.001;
const Y_OFFSET: f64 = 20.0;
const Z_OFFSET: f64 = 10.0;
/// T1's length in `configs/sim-5axis-trt.tbl`.
const TOOL: f64 = 50.0;

/// LinuxCNC's `xyzacKinematicsForward` (its manual's 5-axis chapter, rot point at the
/// origin): the tip in the work's frame, the pose's Z with the tool length in it.
fn forward(j: &[f64]) -> [f64; 3] {
    let (x, y, z) = (j[0], j[1], j[2]);
    let (a, c) = (j[3].to_radians(), j[4].to_radians());
    let dz = Z_OFFSET + TOOL;
    [
        c.cos() * x
            + c.sin() * a.cos() * (y - Y_OFFSET)
            + c.sin() * a.sin() * (z - dz)
            + c.sin() * Y_OFFSET,
        -c.sin() * x
            + c.cos() * a.cos() * (y - Y_OFFSET)
            + c.cos() * a.sin() * (z - dz)
            + c.cos() * Y_OFFSET,
        -a.sin() * (y - Y_OFFSET) + a.cos() * (z - dz) + dz,
    ]
}

fn run(text: &str, name: &str) -> Machine {
    run_to_the_end(&config("sim-5axis-trt.toml"), text, name)
}

/// Every joint within its velocity, acceleration and jerk (X Y Z A C of the machine file).
fn check_limits(samples: &[Sample]) {
    assert_joint_limits(
        samples,
        &[
            (100.0, 1000.0, 50000.0),
            (100.0, 1000.0, 50000.0),
            (50.0, 800.0, 40000.0),
            (90.0, 900.0, 45000.0),
            (180.0, 1800.0, 90000.0),
        ],
        DT,
    );
}

/// A square on the tilted, turning table in G61 (every programmed corner stops, so the
/// only deviation is TCP's own): every set-point's tip within the tolerance of its line,
/// every joint within its limits, the tip's speed the programmed 600 mm/min.
#[test]
fn the_tip_follows_the_programmed_lines_and_every_joint_keeps_its_limits() {
    // Tip poses (X Y Z with the tool length) of lines 6.. in order.
    let text = "G21 G90 G94 G61\nT1 M6\nG43 H1\nG0 X0 Y0 Z80 A0 C0\nM428\n\
                G1 X20 Y0 Z5 F1200\n\
                G1 A-30 C45 F1800\n\
                G1 Y20 C135 F600\n\
                G1 X-20 C225\n\
                G1 Y-20 C315\n\
                G0 Z40\n\
                M429\nM2\n";
    let m = run(text, "tcp_square.ngc");
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    assert!(m.status().program_ended);
    check_limits(&m.samples);
    let pose = |x: f64, y: f64, z: f64| [x, y, z + TOOL];
    let lines: [(u32, [f64; 3], [f64; 3]); 5] = [
        (7, pose(20.0, 0.0, 5.0), pose(20.0, 0.0, 5.0)),
        (8, pose(20.0, 0.0, 5.0), pose(20.0, 20.0, 5.0)),
        (9, pose(20.0, 20.0, 5.0), pose(-20.0, 20.0, 5.0)),
        (10, pose(-20.0, 20.0, 5.0), pose(-20.0, -20.0, 5.0)),
        (11, pose(-20.0, -20.0, 5.0), pose(-20.0, -20.0, 40.0)),
    ];
    for (line, worst) in worst_tip_distance_per_line(&m.samples, &lines, forward) {
        assert!(worst <= TOLERANCE + 1e-9, "line {line}: tip {worst} mm off");
    }
    // The tip's speed along the 40 mm sides (lines 9, 10): never above F 600 = 10 mm/s
    // by more than the chords' rounding, and at F over their middle.
    for line in [9, 10] {
        let speeds = tip_speeds_on_line(&m.samples, line, DT, forward);
        let top = speeds.iter().copied().fold(0.0, f64::max);
        assert!(top <= 10.0 * 1.01, "line {line}: tip at {top} mm/s");
        assert_middle_speed(&speeds, 10.0, &format!("line {line}"));
    }
    // The table turned about the standing tip on line 7 (F in degrees/min: 30 deg/s
    // along the 45.6° of A and C together, 1.52 s and more).
    let turning = m.samples.iter().filter(|s| s.line == 7).count();
    assert!(turning >= 1520, "{turning} periods");
}

/// M428 where C stands at 90: the interpreter reads on from the pose the joints stand for,
/// so a Z move keeps the joints' X and Y (hand-worked: with A at 0 the joints' XY are the
/// tip's turned by C about the rot point, which a Z move leaves alone), as LinuxCNC's
/// switchkins demo shows. Without the switch the interpreter's X10 Y0 would be taken as
/// the tip's and the joints would go to X0 Y10.
#[test]
fn switching_on_where_the_table_is_turned_starts_from_the_same_joints() {
    let text = "G21 G90\nG0 X10 Y0 Z2 A0 C90\nM428\nG1 Z0 F600\nM429\nG1 Z1\nM2\n";
    let m = run(text, "tcp_switch.ngc");
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    for s in m.samples.iter().filter(|s| s.line == 4) {
        assert!((s.setpoint[0] - 10.0).abs() < 1e-9, "{:?}", s.setpoint);
        assert!(s.setpoint[1].abs() < 1e-9, "{:?}", s.setpoint);
    }
    let end = m.samples.last().unwrap().setpoint;
    // TCP off: Z1 is the joint's own.
    assert_close(&end[..5], &[10.0, 0.0, 1.0, 0.0, 90.0]);
}

fn assert_close(got: &[f64], want: &[f64]) {
    for (g, w) in got.iter().zip(want) {
        assert!((g - w).abs() < 1e-9, "{got:?} against {want:?}");
    }
}

/// TCP off: the joints follow the program's coordinates one to one, in a straight line
/// of joint space.
#[test]
fn tcp_off_moves_the_joints_as_programmed() {
    let text = "G21 G90\nG0 X0 Y0 Z0 A0 C0\nM429\nG1 X30 Y-10 Z5 A-20 C60 F900\nM2\n";
    let m = run(text, "tcp_off.ngc");
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    let end = [30.0, -10.0, 5.0, -20.0, 60.0];
    for s in m.samples.iter().filter(|s| s.line == 4) {
        let u = s.setpoint[0] / 30.0;
        for (got, e) in s.setpoint.iter().zip(end) {
            assert!((got - u * e).abs() < 1e-9, "{:?}", s.setpoint);
        }
    }
    assert_close(&m.samples.last().unwrap().setpoint[..5], &end);
}

/// A tip pose whose joints leave their range (C 90 turns the tip's X 180 into joint Y
/// 180, beyond Y's 150) stops the program at its line, before it moves.
#[test]
fn a_pose_beyond_a_joint_range_stops_at_its_line() {
    let text = "G21 G90\nG0 X0 Y0 Z0 A0 C0\nM428\nG1 X100 F3000\nG1 X180 C90\nM2\n";
    let m = run(text, "tcp_range.ngc");
    let fault = m
        .faults
        .iter()
        .find(|f| f.code == FaultCode::MotionError)
        .expect("a motion error");
    assert_eq!(fault.line, 5);
    // Nothing of line 5 ran.
    assert!(m.samples.iter().all(|s| s.line != 5));
}

/// A circle of the tip on the table tilted by 30° while C turns a full turn: every
/// set-point's tip within the tolerance of the circle, the tip at F over the middle of it,
/// every joint within its limits.
#[test]
fn a_tip_circle_on_the_tilted_table() {
    let text = "G21 G90 G94 G61\nT1 M6\nG43 H1\nG0 X0 Y0 Z80 A0 C0\nM428\n\
                G1 X10 Y0 Z5 F1200\nG1 A-30 F1800\nG3 X10 Y0 I-10 J0 C360 F600\n\
                G0 Z40\nM429\nM2\n";
    let m = run(text, "tcp_circle.ngc");
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    check_limits(&m.samples);
    let tips: Vec<[f64; 3]> = m
        .samples
        .iter()
        .filter(|s| s.line == 8)
        .map(|s| forward(&s.setpoint[..5]))
        .collect();
    assert!(tips.len() > 6000, "{} set-points", tips.len());
    for t in &tips {
        let off = (t[0].hypot(t[1]) - 10.0).hypot(t[2] - (5.0 + TOOL));
        assert!(off <= TOLERANCE + 1e-9, "tip {off} mm off the circle");
    }
    assert_middle_speed(
        &tip_speeds_on_line(&m.samples, 8, DT, forward),
        10.0,
        "circle",
    );
}

/// What TCP does not run stops the program at its line: a spline under M428, and M428 on
/// a machine without a five-axis kinematics.
#[test]
fn what_tcp_does_not_run_stops_at_its_line() {
    let text = "G21 G90\nG0 X0 Y0 Z0 A0 C0\nM428\nG1 X10 F600\nG5.1 X20 Y0 I5 J5\nM2\n";
    let m = run(text, "tcp_spline.ngc");
    let fault = m.faults.first().expect("a fault");
    assert_eq!((fault.code, fault.line), (FaultCode::ProgramError, 5));

    let cfg = config("sim-mill.toml");
    let mut m = Machine::started(&cfg, "G21\nG0 X1\nM428\nG0 X2\nM2\n", "tcp_mill.ngc");
    m.until(30.0, |s| s.last_fault.is_some());
    let fault = m.faults.first().expect("a fault");
    assert_eq!((fault.code, fault.line), (FaultCode::ProgramError, 3));
    let _ = Command::Reset;
}

/// LinuxCNC 2.9's joint positions for the same program: `xyzac-trt-kins` (type 0, TCP) with
/// `y-offset` 20, `z-offset` 10, the rot point at the origin and `tool-offset` from
/// `motion.tooloffset.z` (T1, 50 mm), run headless in its simulator (`linuxcnc` with a
/// perfect servo loop, `joint.N.pos-cmd` sampled every period): where the joints stood
/// during each dwell (`scripts/linuxcnc-trt-reference.sh ac` makes them again where LinuxCNC
/// is installed). (LinuxCNC's TCP needs no M428 there: its kinematics is always the
/// xyzac one without `sparm=identityfirst`; the rtcnc program switches it on where A and C
/// are 0, where both kinematics agree.)
const LINUXCNC_PROGRAM: &str = "G21 G90 G94 G61\nT1 M6\nG43 H1\nG0 X0 Y0 Z80 A0 C0\nG4 P0.3\n\
     G1 X20 Y0 Z5 F1200\nG4 P0.3\nG1 A-30 C45 F1800\nG4 P0.3\nG1 Y20 C135 F600\nG4 P0.3\n\
     G1 X-20 C225\nG4 P0.3\nG1 Y-20 C315\nG4 P0.3\nG0 Z40\nG4 P0.3\nM2\n";
const LINUXCNC_JOINTS: [[f64; 5]; 7] = [
    [0.0, 0.0, 130.0, 0.0, 0.0],
    [20.0, 0.0, 55.0, 0.0, 0.0],
    [14.142135624, 12.426940638, 58.598805169, -30.0, 45.0],
    [-28.284271247, 0.179491924, 65.669872981, -30.0, 135.0],
    [28.284271247, 0.179491924, 65.669872981, -30.0, 225.0],
    [-28.284271247, 0.179491924, 65.669872981, -30.0, 315.0],
    [-28.284271247, 17.679491924, 95.980762114, -30.0, 315.0],
];

/// The same program on rtcnc (M428 after the first move): the joints at every dwell equal
/// LinuxCNC's within 1e-6 mm and 1e-6 degree (its figures have nine decimals).
#[test]
fn joint_positions_equal_linuxcnc_xyzac_trt_kins() {
    let text = LINUXCNC_PROGRAM.replacen("G4 P0.3\n", "G4 P0.3\nM428\n", 1);
    let m = run(&text, "tcp_linuxcnc.ngc");
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    // The dwells' lines in the rtcnc program: 5, then every other line from 8.
    let dwells = [5, 8, 10, 12, 14, 16, 18];
    for (line, want) in dwells.into_iter().zip(LINUXCNC_JOINTS) {
        let at = m
            .samples
            .iter()
            .rfind(|s| s.line == line)
            .unwrap_or_else(|| panic!("no set-point at line {line}"));
        for (j, (got, want)) in at.setpoint.iter().zip(want).enumerate() {
            assert!(
                (got - want).abs() <= 1e-6,
                "line {line} joint {j}: {got} against LinuxCNC's {want}"
            );
        }
    }
}

/// Run from a line under TCP: the machine goes at rapid to where the skipped moves ended,
/// and the tip then follows the line it starts from.
#[test]
fn running_from_a_tcp_line_follows_it() {
    let text = "G21 G90 G94 G61\nT1 M6\nG43 H1\nG0 X0 Y0 Z80 A0 C0\nM428\n\
                G1 X20 Y0 Z5 F1200\nG1 A-30 C45 F1800\nG1 Y20 C135 F600\n\
                G1 X-20 C225\nM429\nM2\n";
    let cfg = config("sim-5axis-trt.toml");
    let mut m = Machine::new(&cfg, Some(common::program(text, "tcp_from.ngc")));
    m.power_on();
    m.command(Command::Start { from_line: 9 });
    assert!(m.until(60.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    let on: Vec<&Sample> = m.samples.iter().filter(|s| s.line == 9).collect();
    // The side takes 4 s at F 600; the approach comes before it under the same line.
    assert!(on.len() > 4000, "{}", on.len());
    let (a, b) = ([20.0, 20.0, 5.0 + TOOL], [-20.0, 20.0, 5.0 + TOOL]);
    for s in &on[on.len() - 3900..] {
        let off = distance_to_segment(forward(&s.setpoint[..5]), a, b);
        assert!(off <= TOLERANCE + 1e-9, "tip {off} mm off");
    }
}
