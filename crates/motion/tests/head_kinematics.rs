//! The spindle head kinematics (`xyzbc-head`, LinuxCNC's `5axiskins`) against hand-worked
//! poses and LinuxCNC's formula, and the chords of a tool-centre-point line on a head.
//!
//! LinuxCNC's formula, computed independently (pivot-length `L` = pivot + tool length):
//!
//! ```python
//! from math import *
//! def s2r(r, t, p):   # 5axiskins' spherical to cartesian, degrees
//!     t, p = radians(t), radians(p)
//!     return (r*sin(p)*cos(t), r*sin(p)*sin(t), r*cos(p))
//! def inverse(p, b, c, L):
//!     r = s2r(L, c, 180 - b)
//!     return (p[0] - r[0], p[1] - r[1], p[2] - L - r[2])
//! print(inverse((10, 20, 30), 30, 45, 150))       # -43.033008588991 -33.033008588991 9.903810567666
//! print(inverse((-12.5, 7, -40), -65, 200, 120))  # -114.698088756698 -30.197062306333 -109.285808591116
//! ```

use rtcnc_motion::{AXES, AxisVec, HeadKinematics, TcpMove, TipPath};

fn pose(x: f64, y: f64, z: f64, b: f64, c: f64) -> AxisVec {
    let mut p = [0.0; AXES];
    p[..6].copy_from_slice(&[x, y, z, 0.0, b, c]);
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

/// The tip (with the tool length in Z, as the pose carries it) written out independently:
/// the pivot stands `pivot` above the joints' gauge line, the tool of length `L` hangs
/// from it along (sin B cos C, sin B sin C, −cos B).
fn tip(j: &AxisVec, pivot: f64, tool: f64) -> [f64; 3] {
    let l = pivot + tool;
    let (b, c) = (j[4].to_radians(), j[5].to_radians());
    [
        j[0] + l * b.sin() * c.cos(),
        j[1] + l * b.sin() * c.sin(),
        j[2] + pivot - l * b.cos() + tool,
    ]
}

/// Worked by hand: pivot 100 mm, tool 50 mm (L = 150). B 0: the joints are the pose,
/// whatever C. B 90 at C 0: the tip is 150 mm on +X of the pivot, which is 150 mm above
/// the tip's Z plus the tool length: X −150, Z −150. B −90 at C 90: the tip is on −Y.
#[test]
fn hand_worked_poses() {
    let k = HeadKinematics::xyzbc_head(100.0);
    let cases = [
        (pose(10.0, 20.0, 30.0, 0.0, 37.0), [10.0, 20.0, 30.0]),
        (pose(10.0, 20.0, 30.0, 90.0, 0.0), [-140.0, 20.0, -120.0]),
        (pose(10.0, 20.0, 30.0, -90.0, 90.0), [10.0, 170.0, -120.0]),
        // The Python snippet above.
        (
            pose(10.0, 20.0, 30.0, 30.0, 45.0),
            [-43.033008588991, -33.033008588991, 9.903810567666],
        ),
    ];
    for (p, xyz) in cases {
        let mut want = p;
        want[..3].copy_from_slice(&xyz);
        assert_close(&k.joints(&p, 50.0), &want, 1e-9);
        assert_close(&k.pose(&want, 50.0), &p, 1e-9);
    }
    let k = HeadKinematics::xyzbc_head(70.0);
    let p = pose(-12.5, 7.0, -40.0, -65.0, 200.0);
    let mut want = p;
    want[..3].copy_from_slice(&[-114.698088756698, -30.197062306333, -109.285808591116]);
    assert_close(&k.joints(&p, 50.0), &want, 1e-9);
}

/// A tool length change (G43 H) enters the kinematics: at B 90, C 0 a 20 mm longer tool
/// puts X 20 mm further back and Z 20 mm lower (the pose's Z carries the 20 mm too); at
/// B 0 the joints stay the pose's.
#[test]
fn tool_length_enters_the_lever() {
    let k = HeadKinematics::xyzbc_head(100.0);
    let p = pose(0.0, 0.0, 0.0, 90.0, 0.0);
    let short = k.joints(&p, 30.0);
    let long = k.joints(&p, 50.0);
    assert!((short[0] - long[0] - 20.0).abs() < 1e-12);
    assert!((short[2] - long[2] - 20.0).abs() < 1e-12);
    let level = pose(4.0, 5.0, 6.0, 0.0, 10.0);
    assert_close(&k.joints(&level, 30.0), &level, 1e-12);
    assert_close(&k.joints(&level, 50.0), &level, 1e-12);
}

/// Forward of inverse is the identity over a grid, and the forward kinematics is the
/// independent formula of the tip.
#[test]
fn forward_undoes_inverse() {
    let k = HeadKinematics::xyzbc_head(120.0);
    for i in 0..9 {
        for j in 0..9 {
            let mut p = pose(
                3.0 * i as f64 - 8.0,
                12.0 - 2.0 * j as f64,
                20.0 + i as f64,
                -120.0 + 30.0 * i as f64,
                -400.0 + 97.0 * j as f64,
            );
            p[6] = 1.5; // U passes through.
            p[8] = -2.0; // W too (not part of the kinematics).
            let joints = k.joints(&p, 33.0);
            assert_close(&k.pose(&joints, 33.0), &p, 1e-9);
            let t = tip(&joints, 120.0, 33.0);
            for a in 0..3 {
                assert!((t[a] - p[a]).abs() < 1e-9, "{t:?} {p:?}");
            }
            assert_eq!((joints[6], joints[8]), (1.5, -2.0));
        }
    }
}

/// The joint-to-tip gain bounds the tip's movement: small joint steps in every direction
/// at several poses move the tip at most gain × the step's length.
#[test]
fn joint_to_tip_gain_bounds_the_tip() {
    let k = HeadKinematics::xyzbc_head(100.0);
    let gain = k.joint_to_tip_gain(50.0);
    for i in 0..6 {
        let j0 = pose(1.0, 2.0, 3.0, -90.0 + 36.0 * i as f64, 50.0 * i as f64);
        for d in 0..64u32 {
            let dir = [
                f64::from(d & 1) - 0.5,
                f64::from((d >> 1) & 1) - 0.5,
                f64::from((d >> 2) & 1) - 0.5,
                f64::from((d >> 3) & 1) * 2.0 - 1.0,
                f64::from((d >> 4) & 1) * 2.0 - 1.0,
            ];
            let mut j1 = j0;
            let step = 1e-3;
            let idx = [0, 1, 2, 4, 5];
            let n: f64 = dir.iter().map(|v| v * v).sum::<f64>().sqrt();
            for (slot, v) in idx.iter().zip(dir) {
                j1[*slot] += step * v / n;
            }
            let (a, b) = (tip(&j0, 100.0, 50.0), tip(&j1, 100.0, 50.0));
            let moved =
                ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
            assert!(
                moved <= gain * step * (1.0 + 1e-6),
                "{moved} > {gain} × {step}"
            );
        }
    }
}

/// Every chord of a TCP line on a head keeps the tip (the independent formula) within the
/// tolerance of the programmed line, checked at 200 points of each chord, and the last
/// chord ends on the inverse of the programmed end.
#[test]
fn chords_keep_the_tip_on_the_programmed_line() {
    let (pivot, tool) = (150.0, 40.0);
    let k = HeadKinematics::xyzbc_head(pivot);
    let start_pose = pose(30.0, 0.0, 20.0, 0.0, 0.0);
    let start = k.joints(&start_pose, tool);
    let end = pose(-10.0, 25.0, 12.0, -40.0, 120.0);
    let tol = 0.001;
    let mut line = TcpMove::new(k, tool, &start, &end, TipPath::Line, tol, 9.0, 3).unwrap();
    assert_close(&line.start_pose(), &start_pose, 1e-9);
    // Points of the programmed line (X Y Z linear in the fraction u).
    let on_line = |u: f64| -> [f64; 3] { [30.0 + u * -40.0, 0.0 + u * 25.0, 20.0 + u * -8.0] };
    let mut j0 = start;
    let (mut chords, mut seconds) = (0, 0.0);
    while let Some(ch) = line.next_chord().unwrap() {
        chords += 1;
        for s in 0..=200 {
            let s = f64::from(s) / 200.0;
            let mut j = [0.0; AXES];
            for i in 0..AXES {
                j[i] = j0[i] + s * (ch.end[i] - j0[i]);
            }
            // The fraction of the move, from B (linear in it from 0 to −40).
            let u = j[4] / -40.0;
            let (t, w) = (tip(&j, pivot, tool), on_line(u));
            let e = ((t[0] - w[0]).powi(2) + (t[1] - w[1]).powi(2) + (t[2] - w[2]).powi(2)).sqrt();
            assert!(e <= tol * 1.05, "chord {chords} at {s}: {e} mm");
        }
        seconds += ch.seconds;
        j0 = ch.end;
        if ch.last {
            assert_close(&ch.end, &k.joints(&end, tool), 1e-12);
        }
    }
    assert!((seconds - 9.0).abs() < 1e-9);
    assert!(chords > 10, "{chords} chords");
}
