//! Five-axis kinematics of a rotary/tilting table (LinuxCNC's `xyzac-trt-kins` and
//! `xyzbc-trt-kins`) and the joint-space chords that carry a tool-centre-point (TCP) line.
//!
//! The machine: a tilting table (A about X, or B about Y) carrying a rotary table (C about
//! Z) that holds the work; the spindle moves in X Y Z. A *pose* is the tool tip in the
//! work's frame (X Y Z, mm) with the rotary angles (degrees); *joints* are the machine's
//! X Y Z A/B C. The rotary angles are the same in both. With the parameters of LinuxCNC's
//! HAL pins (`x-rot-point` .. `z-rot-point`: where the C axis meets the pivot plane in
//! machine coordinates; `y-offset` (A) or `x-offset` (B) and `z-offset`: the tilting axis
//! relative to the C axis; `tool-offset`: the tool length in force), with
//! `r = (x, y, z rot-point)`, `d = (x-offset | 0, y-offset | 0, z-offset + tool-offset)`,
//! `Rz(c)` the rotation by C about Z and `T` the tilt (`Rx(a)` or `Ry(b)`):
//!
//! ```text
//! inverse:  J = r + d + T · (Rz(c) · (p − r) − d)
//! forward:  p = r + Rz(c)ᵀ · (Tᵀ · (J − r − d) + d)
//! ```
//!
//! which is the transformation LinuxCNC's documentation derives (its "5-Axis Kinematics"
//! chapter, table rotary/tilting with rotary axis offsets) and its modules compute. The
//! tool length enters as LinuxCNC's does: the pose's Z carries the tool length offset (the
//! gauge line, as every other axis position does) and `tool-offset` takes it out again
//! before the rotation, so the tilt turns the tool tip, not the gauge line.
//!
//! [`TcpLine`] turns one programmed tip move (X Y Z a straight line, the rotary axes
//! linear in the same parameter, as LinuxCNC's TCP interpolates them) into joint-space
//! chords: each chord's tip, computed by the forward kinematics at its points, stays
//! within a tolerance of the programmed point at the same fraction of the move, and each
//! chord gets its share of the move's duration, so that the planner (which plans in joint
//! space and keeps every joint's velocity, acceleration and jerk) runs the tip at the
//! programmed feed.

use crate::axes::{AXES, AxisVec};
use crate::error::MotionError;

/// The table's tilting axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TiltAxis {
    /// A, about X (`xyzac-trt`).
    A,
    /// B, about Y (`xyzbc-trt`).
    B,
}

/// A tilting table with a rotary table on it: `xyzac-trt` or `xyzbc-trt`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TableKinematics {
    tilt: TiltAxis,
    rot_point: [f64; 3],
    offset: [f64; 3],
}

const X: usize = 0;
const Y: usize = 1;
const Z: usize = 2;
const A: usize = 3;
const B: usize = 4;
const C: usize = 5;

impl TableKinematics {
    /// LinuxCNC's `xyzac-trt-kins`: `rot_point` its `x/y/z-rot-point`, `y_offset` and
    /// `z_offset` its pins of those names (mm).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn xyzac_trt(rot_point: [f64; 3], y_offset: f64, z_offset: f64) -> TableKinematics {
        TableKinematics {
            tilt: TiltAxis::A,
            rot_point,
            offset: [0.0, y_offset, z_offset],
        }
    }

    /// LinuxCNC's `xyzbc-trt-kins`: `rot_point` its `x/y/z-rot-point`, `x_offset` and
    /// `z_offset` its pins of those names (mm).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn xyzbc_trt(rot_point: [f64; 3], x_offset: f64, z_offset: f64) -> TableKinematics {
        TableKinematics {
            tilt: TiltAxis::B,
            rot_point,
            offset: [x_offset, 0.0, z_offset],
        }
    }

    /// The tilting axis.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn tilt(&self) -> TiltAxis {
        self.tilt
    }

    /// Index of the tilting axis in an [`AxisVec`] (A = 3, B = 4).
    fn tilt_index(&self) -> usize {
        match self.tilt {
            TiltAxis::A => A,
            TiltAxis::B => B,
        }
    }

    fn d(&self, tool_offset: f64) -> [f64; 3] {
        [self.offset[0], self.offset[1], self.offset[2] + tool_offset]
    }

    /// The tilt `T` (or its transpose, `sign` −1) applied to `v`, angle in degrees.
    fn tilt_by(&self, angle_deg: f64, v: [f64; 3], sign: f64) -> [f64; 3] {
        let (s, c) = angle_deg.to_radians().sin_cos();
        let s = s * sign;
        match self.tilt {
            TiltAxis::A => [v[0], c * v[1] - s * v[2], s * v[1] + c * v[2]],
            TiltAxis::B => [c * v[0] + s * v[2], v[1], -s * v[0] + c * v[2]],
        }
    }

    /// Joint positions of a pose (inverse kinematics); axes the kinematics does not
    /// involve (the other rotary axis, U V W) pass through.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn joints(&self, pose: &AxisVec, tool_offset: f64) -> AxisVec {
        let r = self.rot_point;
        let d = self.d(tool_offset);
        let (sc, cc) = pose[C].to_radians().sin_cos();
        let q = [pose[X] - r[0], pose[Y] - r[1], pose[Z] - r[2]];
        let turned = [cc * q[0] - sc * q[1], sc * q[0] + cc * q[1], q[2]];
        let tilted = self.tilt_by(
            pose[self.tilt_index()],
            [turned[0] - d[0], turned[1] - d[1], turned[2] - d[2]],
            1.0,
        );
        let mut j = *pose;
        for i in 0..3 {
            j[i] = r[i] + d[i] + tilted[i];
        }
        j
    }

    /// The pose of joint positions (forward kinematics).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn pose(&self, joints: &AxisVec, tool_offset: f64) -> AxisVec {
        let r = self.rot_point;
        let d = self.d(tool_offset);
        let v = [
            joints[X] - r[0] - d[0],
            joints[Y] - r[1] - d[1],
            joints[Z] - r[2] - d[2],
        ];
        let untilted = self.tilt_by(joints[self.tilt_index()], v, -1.0);
        let w = [untilted[0] + d[0], untilted[1] + d[1], untilted[2] + d[2]];
        let (sc, cc) = joints[C].to_radians().sin_cos();
        let mut p = *joints;
        p[X] = r[0] + cc * w[0] + sc * w[1];
        p[Y] = r[1] - sc * w[0] + cc * w[1];
        p[Z] = r[2] + w[2];
        p
    }

    /// A bound of how far the tip moves per radian of either rotary joint, anywhere on
    /// the straight tip move from `a` to `b`: |p − r| + |d| at its farther end (the
    /// distance is convex along a line).
    fn lever(&self, a: &AxisVec, b: &AxisVec, tool_offset: f64) -> f64 {
        let d = self.d(tool_offset);
        let dn = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let dist = |p: &AxisVec| {
            let q = [
                p[X] - self.rot_point[0],
                p[Y] - self.rot_point[1],
                p[Z] - self.rot_point[2],
            ];
            (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt()
        };
        dist(a).max(dist(b)) + dn
    }

    /// How much a distance in joint space (the planner's: mm and degrees in one norm) can
    /// move the tip at most on the move from `a` to `b`: √(1 + 2·k²), k the tip's
    /// movement per degree of a rotary joint (|∂p/∂J_xyz| = 1: a rotation).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn joint_to_tip_gain(&self, a: &AxisVec, b: &AxisVec, tool_offset: f64) -> f64 {
        let k = self.lever(a, b, tool_offset).to_radians();
        (1.0 + 2.0 * k * k).sqrt()
    }
}

/// One chord of a [`TcpLine`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Chord {
    /// Joint positions at its end.
    pub end: AxisVec,
    /// Its share of the move's duration (seconds; 0 for a rapid).
    pub seconds: f64,
    /// The move's last chord.
    pub last: bool,
}

/// Samples per chord at which the tip's distance from the programmed point is measured.
const CHORD_SAMPLES: usize = 16;

/// Chords of one move are at most this many (a bound on the work of a move).
pub const MAX_CHORDS: u32 = 1_000_000;

/// A programmed tool-tip move cut into joint-space chords, one at a time
/// ([`TcpLine::next_chord`]); no allocation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TcpLine {
    kin: TableKinematics,
    tool_offset: f64,
    start: AxisVec,
    end: AxisVec,
    tolerance: f64,
    duration: f64,
    /// Fraction of the move done, the joints there, and the last step taken.
    u: f64,
    joints: AxisVec,
    step: f64,
    chords: u32,
    line: u32,
}

impl TcpLine {
    /// The tip move from where `start_joints` put it to the pose `end`, with the tool
    /// length `tool_offset`, its chords within `tolerance` (mm) of the programmed points,
    /// taking `duration` seconds in all (0 for a rapid: the planner's axis limits set it).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn new(
        kin: TableKinematics,
        tool_offset: f64,
        start_joints: &AxisVec,
        end: &AxisVec,
        tolerance: f64,
        duration: f64,
        line: u32,
    ) -> Result<TcpLine, MotionError> {
        if !(tolerance.is_finite() && tolerance > 0.0) {
            return Err(MotionError::InvalidTolerance {
                line,
                value: tolerance,
            });
        }
        if !(end.iter().all(|v| v.is_finite())
            && start_joints.iter().all(|v| v.is_finite())
            && tool_offset.is_finite()
            && duration.is_finite()
            && duration >= 0.0)
        {
            return Err(MotionError::NotFinite {
                line,
                what: "tool-centre-point move",
            });
        }
        Ok(TcpLine {
            kin,
            tool_offset,
            start: kin.pose(start_joints, tool_offset),
            end: *end,
            tolerance,
            duration,
            u: 0.0,
            joints: *start_joints,
            step: 1.0,
            chords: 0,
            line,
        })
    }

    /// The pose the move starts from (the forward kinematics of the start joints).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn start_pose(&self) -> AxisVec {
        self.start
    }

    /// The programmed pose at fraction `u` of the move.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn pose_at(&self, u: f64) -> AxisVec {
        let mut p = [0.0; AXES];
        for i in 0..AXES {
            p[i] = self.start[i] + u * (self.end[i] - self.start[i]);
        }
        p
    }

    /// See [`TableKinematics::joint_to_tip_gain`], for this move.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn joint_to_tip_gain(&self) -> f64 {
        self.kin
            .joint_to_tip_gain(&self.start, &self.end, self.tool_offset)
    }

    /// Largest distance of the tip on the chord from `j0` (at `u0`) to `j1` (at `u1`)
    /// from the programmed point at the same fraction.
    fn chord_error(&self, u0: f64, j0: &AxisVec, u1: f64, j1: &AxisVec) -> f64 {
        let mut worst: f64 = 0.0;
        for k in 1..CHORD_SAMPLES {
            let s = k as f64 / CHORD_SAMPLES as f64;
            let mut j = [0.0; AXES];
            for i in 0..AXES {
                j[i] = j0[i] + s * (j1[i] - j0[i]);
            }
            let tip = self.kin.pose(&j, self.tool_offset);
            let want = self.pose_at(u0 + s * (u1 - u0));
            let e = ((tip[X] - want[X]).powi(2)
                + (tip[Y] - want[Y]).powi(2)
                + (tip[Z] - want[Z]).powi(2))
            .sqrt();
            // NaN counts as too far.
            if !(e <= worst) {
                worst = if e.is_nan() { f64::INFINITY } else { e };
            }
        }
        worst
    }

    /// The next chord, `None` once the move is done. The chords' joint path stays within
    /// the tolerance at 16 points of each chord (the deviation of a chord is smooth, about
    /// quadratic in its length: the step is shrunk by √(tolerance / error) until it fits).
    ///
    /// Real-time: yes (no allocation, no blocking; at most 64 trials of 16 evaluations).
    pub fn next_chord(&mut self) -> Result<Option<Chord>, MotionError> {
        if self.u >= 1.0 {
            return Ok(None);
        }
        if self.chords >= MAX_CHORDS {
            return Err(MotionError::ToolCentrePoint {
                line: self.line,
                why: "it needs more than a million chords",
            });
        }
        let mut step = (self.step * 2.0).min(1.0 - self.u);
        for _ in 0..64 {
            let u1 = if step >= 1.0 - self.u {
                1.0
            } else {
                self.u + step
            };
            let j1 = if u1 >= 1.0 {
                self.kin.joints(&self.end, self.tool_offset)
            } else {
                self.kin.joints(&self.pose_at(u1), self.tool_offset)
            };
            let e = self.chord_error(self.u, &self.joints, u1, &j1);
            if e <= self.tolerance {
                let chord = Chord {
                    end: j1,
                    seconds: self.duration * (u1 - self.u),
                    last: u1 >= 1.0,
                };
                self.step = u1 - self.u;
                self.u = u1;
                self.joints = j1;
                self.chords += 1;
                return Ok(Some(chord));
            }
            let shrink = if e.is_finite() {
                (0.9 * (self.tolerance / e).sqrt()).clamp(0.05, 0.7)
            } else {
                0.05
            };
            step *= shrink;
        }
        Err(MotionError::ToolCentrePoint {
            line: self.line,
            why: "no chord keeps the tolerance",
        })
    }
}
