//! The table rotary/tilting kinematics (`xyzac-trt`, `xyzbc-trt`) against hand-worked poses
//! and LinuxCNC's formulas, and the chords of a tool-centre-point line against the
//! programmed line.

use rtcnc_motion::{AXES, AxisVec, TableKinematics, TcpMove, TipPath};

fn pose(x: f64, y: f64, z: f64, a: f64, b: f64, c: f64) -> AxisVec {
    let mut p = [0.0; AXES];
    p[..6].copy_from_slice(&[x, y, z, a, b, c]);
    p
}

fn assert_close(got: &AxisVec, want: &AxisVec, tol: f64) {
    for i in 0..AXES {
        assert!(
            (got[i] - want[i]).abs() <= tol,
            "axis {i}: got {got:?}, want {want:?}"
        );
    }
}

/// Worked by hand: xyzac-trt, pivot at the origin, A axis 20 mm along Y and 10 mm up from
/// the C axis (LinuxCNC's sim values).
#[test]
fn xyzac_hand_worked_poses() {
    let k = TableKinematics::xyzac_trt([0.0; 3], 20.0, 10.0);
    // A 90: q = (10, 0, 0); Rz(0)q − d = (10, −20, −10); Rx(90) of it = (10, 10, −20);
    // plus r + d = (10, 30, −10).
    let j = k.joints(&pose(10.0, 0.0, 0.0, 90.0, 0.0, 0.0), 0.0);
    assert_close(&j, &pose(10.0, 30.0, -10.0, 90.0, 0.0, 0.0), 1e-12);
    // C 90 alone: Rz(90)(10, 0, 5) = (0, 10, 5); the offsets cancel with A = 0.
    let j = k.joints(&pose(10.0, 0.0, 5.0, 0.0, 0.0, 90.0), 0.0);
    assert_close(&j, &pose(0.0, 10.0, 5.0, 0.0, 0.0, 90.0), 1e-12);
    // With both rotary axes at 0 the kinematics is the identity, whatever the offsets.
    let p = pose(-3.0, 7.0, 11.0, 0.0, 0.0, 0.0);
    assert_close(&k.joints(&p, 42.0), &p, 1e-12);
}

/// The tool length: a tip 10 mm along Y from the pivot (the pose's Z is the gauge line,
/// 100 mm above the tip) tilted by A 90 rises to 10 mm above the pivot, and the spindle
/// with it: joint Z 110.
#[test]
fn the_tool_length_moves_the_spindle_not_the_tip() {
    let k = TableKinematics::xyzac_trt([0.0; 3], 0.0, 0.0);
    let j = k.joints(&pose(0.0, 10.0, 100.0, 90.0, 0.0, 0.0), 100.0);
    assert_close(&j, &pose(0.0, 0.0, 110.0, 90.0, 0.0, 0.0), 1e-12);
    // A tip at the pivot stays there whatever the tilt.
    let j = k.joints(&pose(0.0, 0.0, 100.0, 37.0, 0.0, 0.0), 100.0);
    assert_close(&j, &pose(0.0, 0.0, 100.0, 37.0, 0.0, 0.0), 1e-12);
}

/// Worked by hand: xyzbc-trt, B axis 5 mm along X and 10 mm up from the C axis. B 90:
/// Rz(0)·0 − d = (−5, 0, −10); Ry(90) of it = (−10, 0, 5); plus d = (−5, 0, 15).
#[test]
fn xyzbc_hand_worked_pose() {
    let k = TableKinematics::xyzbc_trt([0.0; 3], 5.0, 10.0);
    let j = k.joints(&pose(0.0, 0.0, 0.0, 0.0, 90.0, 0.0), 0.0);
    assert_close(&j, &pose(-5.0, 0.0, 15.0, 0.0, 90.0, 0.0), 1e-12);
}

/// Against LinuxCNC's `xyzacKinematicsInverse` and `xyzbcKinematicsInverse` formulas
/// (trtfuncs.c, as its manual's 5-axis chapter derives them), evaluated in Python:
///
/// ```python
/// from math import *
/// def inv_ac(p, r, dy, dz, t):
///   x, y, z, a, c = p; a = radians(a); c = radians(c); dz = dz + t
///   X = cos(c)*(x-r[0]) - sin(c)*(y-r[1]) + r[0]
///   Y = sin(c)*cos(a)*(x-r[0]) + cos(c)*cos(a)*(y-r[1]) - sin(a)*(z-r[2]) \
///       - cos(a)*dy + sin(a)*dz + dy + r[1]
///   Z = sin(c)*sin(a)*(x-r[0]) + cos(c)*sin(a)*(y-r[1]) + cos(a)*(z-r[2]) \
///       - sin(a)*dy - cos(a)*dz + dz + r[2]
///   return X, Y, Z
/// def inv_bc(p, r, dx, dz, t):
///   x, y, z, b, c = p; b = radians(b); c = radians(c); dz = dz + t
///   dpx = -cos(b)*dx - sin(b)*dz + dx; dpz = sin(b)*dx - cos(b)*dz + dz
///   X = cos(c)*cos(b)*(x-r[0]) - sin(c)*cos(b)*(y-r[1]) + sin(b)*(z-r[2]) + dpx + r[0]
///   Y = sin(c)*(x-r[0]) + cos(c)*(y-r[1]) + r[1]
///   Z = -cos(c)*sin(b)*(x-r[0]) + sin(c)*sin(b)*(y-r[1]) + cos(b)*(z-r[2]) + dpz + r[2]
///   return X, Y, Z
/// inv_ac((12.5, -7.25, 33.0, -37.5, 123.0), (5, -3, -40), 20, 10, 55.5)
/// inv_bc((12.5, -7.25, 33.0, 28.0, -211.0), (5, -3, -40), -15, 10, 55.5)
/// ```
#[test]
fn linuxcnc_formulas_with_every_parameter() {
    let r = [5.0, -3.0, -40.0];
    let ac = TableKinematics::xyzac_trt(r, 20.0, 10.0);
    let j = ac.joints(&pose(12.5, -7.25, 33.0, -37.5, 0.0, 123.0), 55.5);
    assert_close(
        &j,
        &pose(
            4.479557151155,
            12.525247225516,
            38.387141673472,
            -37.5,
            0.0,
            123.0,
        ),
        1e-9,
    );
    let bc = TableKinematics::xyzbc_trt(r, -15.0, 10.0);
    let j = bc.joints(&pose(12.5, -7.25, 33.0, 0.0, 28.0, -211.0), 55.5);
    assert_close(
        &j,
        &pose(
            3.021691498544,
            4.505746589809,
            27.070519194206,
            0.0,
            28.0,
            -211.0,
        ),
        1e-9,
    );
}

/// Forward of inverse is the identity, over a grid of poses and both machines.
#[test]
fn forward_undoes_inverse() {
    let r = [5.0, -3.0, -40.0];
    let machines = [
        TableKinematics::xyzac_trt(r, 20.0, 10.0),
        TableKinematics::xyzbc_trt(r, -15.0, 10.0),
    ];
    for k in machines {
        for i in 0..7 {
            for j in 0..9 {
                let tilt = -100.0 + 25.0 * i as f64;
                let c = -400.0 + 97.0 * j as f64;
                let mut p = pose(
                    3.0 * i as f64 - 8.0,
                    12.0 - 2.0 * j as f64,
                    20.0 + i as f64,
                    0.0,
                    0.0,
                    c,
                );
                p[3] = tilt;
                p[4] = tilt;
                p[6] = 1.5; // U passes through.
                let joints = k.joints(&p, 33.0);
                assert_close(&k.pose(&joints, 33.0), &p, 1e-9);
                assert_eq!(joints[6], 1.5);
            }
        }
    }
}

/// Every chord of a TCP line keeps the tip within the tolerance of the programmed point
/// (checked at 200 points of each chord, more than the generator's 16), the chords end
/// on the programmed end, and their durations add up to the move's.
#[test]
fn chords_keep_the_tip_on_the_programmed_line() {
    let k = TableKinematics::xyzac_trt([0.0; 3], 20.0, 10.0);
    let tool = 50.0;
    let start_pose = pose(30.0, 0.0, 60.0, 0.0, 0.0, 0.0);
    let start = k.joints(&start_pose, tool);
    let end = pose(-10.0, 25.0, 52.0, -45.0, 0.0, 120.0);
    let tol = 0.001;
    let mut line = TcpMove::new(k, tool, &start, &end, TipPath::Line, tol, 12.0, 7).unwrap();
    assert_close(&line.start_pose(), &start_pose, 1e-9);
    let mut u0 = 0.0;
    let mut j0 = start;
    let mut seconds = 0.0;
    let mut chords = 0;
    let span = |p: &AxisVec, q: &AxisVec| -> f64 {
        ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
    };
    let total_tip = span(&start_pose, &end);
    while let Some(ch) = line.next_chord().unwrap() {
        chords += 1;
        // The chord's fraction of the move, from its end's programmed pose.
        let tip_end = k.pose(&ch.end, tool);
        let u1 = span(&start_pose, &tip_end) / total_tip;
        for s in 0..=200 {
            let s = f64::from(s) / 200.0;
            let mut j = [0.0; AXES];
            for i in 0..AXES {
                j[i] = j0[i] + s * (ch.end[i] - j0[i]);
            }
            let tip = k.pose(&j, tool);
            let want = line.pose_at(u0 + s * (u1 - u0));
            assert!(
                span(&tip, &want) <= tol * 1.05,
                "chord {chords} at {s}: {} mm",
                span(&tip, &want)
            );
        }
        seconds += ch.seconds;
        u0 = u1;
        j0 = ch.end;
        if ch.last {
            assert_close(&ch.end, &k.joints(&end, tool), 1e-12);
        }
    }
    assert!((seconds - 12.0).abs() < 1e-9);
    assert!(chords > 10, "{chords} chords");
}

/// Poses (tool tip with the 50 mm tool length in Z) of a program run in LinuxCNC 2.9's
/// simulator, and the joint positions its `xyzac-trt-kins` and `xyzbc-trt-kins` commanded
/// there (`joint.N.pos-cmd` while the program dwelt at each pose, nine decimals; made by
/// `scripts/linuxcnc-trt-reference.sh ac` and `bc`, which holds the program and the
/// configuration).
/// xyzac: `y-offset` 20, `z-offset` 10, rot point at the origin.
const LINUXCNC_AC: [([f64; 5], [f64; 5]); 7] = [
    ([0.0, 0.0, 130.0, 0.0, 0.0], [0.0, 0.0, 130.0, 0.0, 0.0]),
    ([20.0, 0.0, 55.0, 0.0, 0.0], [20.0, 0.0, 55.0, 0.0, 0.0]),
    (
        [20.0, 0.0, 55.0, -30.0, 45.0],
        [14.142135624, 12.426940638, 58.598805169, -30.0, 45.0],
    ),
    (
        [20.0, 20.0, 55.0, -30.0, 135.0],
        [-28.284271247, 0.179491924, 65.669872981, -30.0, 135.0],
    ),
    (
        [-20.0, 20.0, 55.0, -30.0, 225.0],
        [28.284271247, 0.179491924, 65.669872981, -30.0, 225.0],
    ),
    (
        [-20.0, -20.0, 55.0, -30.0, 315.0],
        [-28.284271247, 0.179491924, 65.669872981, -30.0, 315.0],
    ),
    (
        [-20.0, -20.0, 90.0, -30.0, 315.0],
        [-28.284271247, 17.679491924, 95.980762114, -30.0, 315.0],
    ),
];

/// xyzbc: `x-offset` −15, `z-offset` 10, rot point (5, −3, −40); the same program with B
/// 28 and C −211, −121, −31, 59.
const LINUXCNC_BC: [([f64; 5], [f64; 5]); 7] = [
    ([0.0, 0.0, 130.0, 0.0, 0.0], [0.0, 0.0, 130.0, 0.0, 0.0]),
    ([20.0, 0.0, 55.0, 0.0, 0.0], [20.0, 0.0, 55.0, 0.0, 0.0]),
    (
        [20.0, 0.0, 55.0, 28.0, -211.0],
        [6.958956632, 2.154069222, 50.622714581, 28.0, -211.0],
    ),
    (
        [20.0, 20.0, 55.0, 28.0, -121.0],
        [30.261621674, -27.703385233, 38.232467796, 28.0, -121.0],
    ),
    (
        [-20.0, 20.0, 55.0, 28.0, -31.0],
        [11.214160924, 29.590799789, 48.360182326, 28.0, -31.0],
    ),
    (
        [-20.0, -20.0, 55.0, 28.0, 59.0],
        [21.173102561, -33.184829791, 43.064919128, 28.0, 59.0],
    ),
    (
        [-20.0, -20.0, 90.0, 28.0, 59.0],
        [37.604607258, -33.184829791, 73.968084878, 28.0, 59.0],
    ),
];

/// Inverse and forward against LinuxCNC's own transforms, within 1e-6 mm and 1e-6 degree.
#[test]
fn inverse_and_forward_equal_linuxcnc_trt_kins() {
    let ac = TableKinematics::xyzac_trt([0.0; 3], 20.0, 10.0);
    let bc = TableKinematics::xyzbc_trt([5.0, -3.0, -40.0], -15.0, 10.0);
    for (k, tilt, data) in [(ac, 3, LINUXCNC_AC), (bc, 4, LINUXCNC_BC)] {
        for (p, j) in data {
            let as_vec = |v: [f64; 5]| {
                let mut a = pose(v[0], v[1], v[2], 0.0, 0.0, v[4]);
                a[tilt] = v[3];
                a
            };
            let (p, j) = (as_vec(p), as_vec(j));
            assert_close(&k.joints(&p, 50.0), &j, 1e-6);
            assert_close(&k.pose(&j, 50.0), &p, 1e-6);
        }
    }
}

/// An arc: the programmed points lie on the circle, counter-clockwise about the normal
/// (a quarter of a full turn about +Z from (10, 0) is (0, 10); about −Z, a G2, (0, −10)),
/// the rotary axes linear along it; the chords keep the tip within the tolerance of them.
#[test]
fn an_arc_is_followed_along_its_circle() {
    let k = TableKinematics::xyzac_trt([0.0; 3], 20.0, 10.0);
    let tool = 50.0;
    let start_pose = pose(10.0, 0.0, 55.0, -30.0, 0.0, 0.0);
    let start = k.joints(&start_pose, tool);
    let end = pose(10.0, 0.0, 55.0, -30.0, 0.0, 360.0);
    let arc = |normal: [f64; 3]| TipPath::Arc {
        centre: [0.0, 0.0, 55.0],
        normal,
        turns: 0,
    };
    let ccw = TcpMove::new(k, tool, &start, &end, arc([0.0, 0.0, 1.0]), 0.001, 6.0, 1).unwrap();
    assert_close(
        &ccw.pose_at(0.25),
        &pose(0.0, 10.0, 55.0, -30.0, 0.0, 90.0),
        1e-9,
    );
    let cw = TcpMove::new(k, tool, &start, &end, arc([0.0, 0.0, -1.0]), 0.001, 6.0, 1).unwrap();
    assert_close(
        &cw.pose_at(0.25),
        &pose(0.0, -10.0, 55.0, -30.0, 0.0, 90.0),
        1e-9,
    );
    // 2π·10 mm; with C's 360° besides, √((2π·10)² + 360²).
    let (tip, all) = ccw.lengths();
    let circle = 20.0 * std::f64::consts::PI;
    assert!((tip - circle).abs() < 1e-9, "{tip}");
    assert!((all - circle.hypot(360.0)).abs() < 1e-9, "{all}");
    let mut m = ccw;
    let mut j0 = start;
    let mut chords = 0;
    while let Some(ch) = m.next_chord().unwrap() {
        chords += 1;
        for s in 0..=50 {
            let s = f64::from(s) / 50.0;
            let mut j = [0.0; AXES];
            for i in 0..AXES {
                j[i] = j0[i] + s * (ch.end[i] - j0[i]);
            }
            let tip = k.pose(&j, tool);
            let off_circle = (tip[0].hypot(tip[1]) - 10.0).hypot(tip[2] - 55.0);
            assert!(off_circle <= 0.001, "chord {chords}: {off_circle} mm");
        }
        j0 = ch.end;
    }
    assert_close(&j0, &k.joints(&end, tool), 1e-9);
}
