//! Tool-centre-point control (M428/M429) on the tilting/rotating spindle head of
//! `configs/sim-5axis-head.toml` (LinuxCNC's `5axiskins`): the tool tip, computed from
//! the joint set-points by LinuxCNC's 5axiskins forward formula (written out below, not
//! the crate's), stays on the programmed lines within the machine file's tolerance with
//! either tool's length, every joint keeps its limits, and the joints equal those
//! LinuxCNC 2.9's simulator commanded with 5axiskins on the same program.

use crate::common::*;
use rtcnc_kernel::Sample;

const DT: f64 = 0.001;
/// The machine file's `kinematics.tolerance` and `pivot_length`.
const TOLERANCE: f64 = 0.001;
const PIVOT: f64 = 100.0;
/// T1's and T2's lengths in `configs/sim-5axis-head.tbl`.
const T1: f64 = 50.0;
const T2: f64 = 80.0;

/// LinuxCNC's 5axiskins forward formula with W 0 and `pivot-length` = pivot + tool:
/// the joints plus `s2r(L, C, 180 − B)` plus L in Z (the pose's Z with the tool length).
fn forward(j: &[f64], tool: f64) -> [f64; 3] {
    let l = PIVOT + tool;
    let (theta, phi) = (j[4].to_radians(), (180.0 - j[3]).to_radians());
    [
        j[0] + l * phi.sin() * theta.cos(),
        j[1] + l * phi.sin() * theta.sin(),
        j[2] + l + l * phi.cos(),
    ]
}

fn run(text: &str, name: &str) -> Machine {
    run_to_the_end(&config("sim-5axis-head.toml"), text, name)
}

/// Every joint within its velocity, acceleration and jerk (X Y Z B C of the machine file).
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

/// The program of a tool: the head tilts and turns about the standing tip (line 7), then
/// the tip runs two sides of a square while C turns, then lifts, in G61.
fn program(tool: u32) -> String {
    format!(
        "G21 G90 G94 G61\nT{tool} M6\nG43 H{tool}\nG0 X0 Y0 Z80 B0 C0\nM428\n\
         G1 X20 Y0 Z5 F1200\n\
         G1 B30 C45 F1800\n\
         G1 Y20 C135 F600\n\
         G1 X-20 C225\n\
         G0 Z40\n\
         M429\nM2\n"
    )
}

/// The tip's worst distance from each TCP line (6..10) with the tool length `tool`.
fn worst_per_line(m: &Machine, tool: f64) -> Vec<(u32, f64)> {
    let pose = |x: f64, y: f64, z: f64| [x, y, z + tool];
    let lines: [(u32, [f64; 3], [f64; 3]); 4] = [
        (7, pose(20.0, 0.0, 5.0), pose(20.0, 0.0, 5.0)),
        (8, pose(20.0, 0.0, 5.0), pose(20.0, 20.0, 5.0)),
        (9, pose(20.0, 20.0, 5.0), pose(-20.0, 20.0, 5.0)),
        (10, pose(-20.0, 20.0, 5.0), pose(-20.0, 20.0, 40.0)),
    ];
    worst_tip_distance_per_line(&m.samples, &lines, |j| forward(j, tool))
}

/// With T1 (50 mm): every set-point's tip within the tolerance of its line, every joint
/// within its limits, the tip at F 600 = 10 mm/s over the middle of line 9, and the
/// joints at the tilted, turned standstill of line 7 those of the hand-worked inverse
/// (L = 150: X 20 − 75·cos 45, Y −75·sin 45, Z 55 − 150 + 150·cos 30).
#[test]
fn the_tip_follows_the_programmed_lines_on_a_head() {
    let m = run(&program(1), "head_t1.ngc");
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    assert!(m.status().program_ended);
    check_limits(&m.samples);
    for (line, worst) in worst_per_line(&m, T1) {
        assert!(worst <= TOLERANCE + 1e-9, "line {line}: tip {worst} mm off");
    }
    let end7 = m.samples.iter().rfind(|s| s.line == 7).unwrap().setpoint;
    let h = 75.0 * std::f64::consts::FRAC_1_SQRT_2;
    let want = [
        20.0 - h,
        -h,
        55.0 - 150.0 + 150.0 * 30f64.to_radians().cos(),
        30.0,
        45.0,
    ];
    for (got, want) in end7.iter().zip(want) {
        assert!((got - want).abs() < 1e-6, "{end7:?} against {want}");
    }
    let speeds = tip_speeds_on_line(&m.samples, 9, DT, |j| forward(j, T1));
    assert_middle_speed(&speeds, 10.0, "line 9");
}

/// G43 H2 (80 mm) lengthens the lever: the tip computed with 80 mm stays on the lines;
/// computed with T1's 50 mm it is far off them while the head is tilted (so the joints
/// did take the new length).
#[test]
fn a_tool_length_change_enters_the_head_kinematics() {
    let m = run(&program(2), "head_t2.ngc");
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    check_limits(&m.samples);
    for (line, worst) in worst_per_line(&m, T2) {
        assert!(worst <= TOLERANCE + 1e-9, "line {line}: tip {worst} mm off");
    }
    // With B 30 the 30 mm difference swings the tip by 30·sin 30 = 15 mm sideways.
    let wrong = worst_per_line(&m, T1);
    assert!(wrong.iter().all(|(_, w)| *w > 10.0), "{wrong:?}");
}

/// LinuxCNC 2.9's joint positions for the same program: `5axiskins` (type 0, TCP) with
/// `pivot-length` 100 plus `motion.tooloffset.z` (T1, 50 mm) through a `sum2`, W a sixth
/// joint standing at 0, run headless in its simulator (`linuxcnc` with a perfect servo
/// loop, `joint.N.pos-cmd` sampled every period): where the joints stood during each
/// dwell (`scripts/linuxcnc-trt-reference.sh head` makes them again where LinuxCNC is
/// installed). The rtcnc program switches TCP on where B and C are 0, where both
/// kinematics agree.
const LINUXCNC_PROGRAM: &str = "G21 G90 G94 G61\nT1 M6\nG43 H1\nG0 X0 Y0 Z80 B0 C0\nG4 P0.3\n\
     G1 X20 Y0 Z5 F1200\nG4 P0.3\nG1 B30 C45 F1800\nG4 P0.3\nG1 Y20 C135 F600\nG4 P0.3\n\
     G1 X-20 C225\nG4 P0.3\nG1 Y-20 C315\nG4 P0.3\nG0 Z40\nG4 P0.3\nM2\n";
const LINUXCNC_JOINTS: [[f64; 5]; 7] = [
    [0.0, 0.0, 130.0, 0.0, 0.0],
    [20.0, 0.0, 55.0, 0.0, 0.0],
    [-33.033008589, -53.033008589, 34.903810568, 30.0, 45.0],
    [73.033008589, -33.033008589, 34.903810568, 30.0, 135.0],
    [33.033008589, 73.033008589, 34.903810568, 30.0, 225.0],
    [-73.033008589, 33.033008589, 34.903810568, 30.0, 315.0],
    [-73.033008589, 33.033008589, 69.903810568, 30.0, 315.0],
];

/// The same program on rtcnc (M428 after the first move): the joints at every dwell equal
/// LinuxCNC's within 1e-6 mm and 1e-6 degree (its figures have nine decimals).
#[test]
fn joint_positions_equal_linuxcnc_5axiskins() {
    let text = LINUXCNC_PROGRAM.replacen("G4 P0.3\n", "G4 P0.3\nM428\n", 1);
    let m = run(&text, "head_linuxcnc.ngc");
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
