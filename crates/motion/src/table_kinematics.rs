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
//! [`TcpMove`] (on these or on a head, [`crate::HeadKinematics`]) turns one programmed tip
//! move (X Y Z a straight line or an arc, the rotary axes linear in the same parameter, as
//! LinuxCNC's TCP interpolates them) into joint-space chords: each chord's tip, computed by
//! the forward kinematics at its points, stays within a tolerance of the programmed point at
//! the same fraction of the move, and each chord gets its share of the move's duration, so
//! that the planner (which plans in joint space and keeps every joint's velocity,
//! acceleration and jerk) runs the tip at the programmed feed.

use crate::axes::{AXES, AxisVec};
use crate::error::MotionError;
use crate::five_axis::FiveAxisKinematics;

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

/// The tip's path of a [`TcpMove`] in X Y Z.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TipPath {
    /// A straight line.
    Line,
    /// An arc or helix about `centre`, counter-clockwise seen from the tip of `normal`
    /// (need not be unit length), `turns` extra full turns, as [`crate::MoveKind::Arc`]:
    /// the distance from the axis changes linearly with the angle from the start's to the
    /// end's, the rise along the normal linearly too.
    Arc {
        /// Centre (X Y Z).
        centre: [f64; 3],
        /// Plane normal.
        normal: [f64; 3],
        /// Extra full turns.
        turns: u32,
    },
}

/// An arc's frame: centre, unit normal, the in-plane unit vectors towards the start and a
/// quarter turn on, the start's and the end's radius and height, the swept angle.
#[derive(Debug, Clone, Copy, PartialEq)]
struct ArcFrame {
    centre: [f64; 3],
    n: [f64; 3],
    x: [f64; 3],
    y: [f64; 3],
    r0: f64,
    r1: f64,
    h0: f64,
    h1: f64,
    sweep: f64,
}

fn dot3(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

impl ArcFrame {
    fn new(
        start: &AxisVec,
        end: &AxisVec,
        centre: [f64; 3],
        normal: [f64; 3],
        turns: u32,
        line: u32,
    ) -> Result<ArcFrame, MotionError> {
        let invalid = MotionError::ToolCentrePoint {
            line,
            why: "an arc whose start or normal defines no plane",
        };
        let nn = dot3(&normal, &normal).sqrt();
        if !(nn > 0.0 && nn.is_finite() && centre.iter().all(|v| v.is_finite())) {
            return Err(invalid);
        }
        let n = [normal[0] / nn, normal[1] / nn, normal[2] / nn];
        let rel = |p: &AxisVec| [p[X] - centre[0], p[Y] - centre[1], p[Z] - centre[2]];
        let (s, e) = (rel(start), rel(end));
        let (h0, h1) = (dot3(&s, &n), dot3(&e, &n));
        let a0 = [s[0] - h0 * n[0], s[1] - h0 * n[1], s[2] - h0 * n[2]];
        let a1 = [e[0] - h1 * n[0], e[1] - h1 * n[1], e[2] - h1 * n[2]];
        let (r0, r1) = (dot3(&a0, &a0).sqrt(), dot3(&a1, &a1).sqrt());
        if !(r0 > 1e-9) {
            return Err(invalid);
        }
        let x = [a0[0] / r0, a0[1] / r0, a0[2] / r0];
        let y = [
            n[1] * x[2] - n[2] * x[1],
            n[2] * x[0] - n[0] * x[2],
            n[0] * x[1] - n[1] * x[0],
        ];
        // The end's angle from the start, counter-clockwise in (0, 2π]: an end on the
        // start's angle is a full turn, as G2/G3 take it.
        let mut phi = dot3(&a1, &y).atan2(dot3(&a1, &x));
        if phi <= 1e-12 {
            phi += std::f64::consts::TAU;
        }
        Ok(ArcFrame {
            centre,
            n,
            x,
            y,
            r0,
            r1,
            h0,
            h1,
            sweep: phi + std::f64::consts::TAU * f64::from(turns),
        })
    }

    fn at(&self, u: f64) -> [f64; 3] {
        let (s, c) = (u * self.sweep).sin_cos();
        let r = self.r0 + u * (self.r1 - self.r0);
        let h = self.h0 + u * (self.h1 - self.h0);
        let mut p = [0.0; 3];
        for i in 0..3 {
            p[i] = self.centre[i] + h * self.n[i] + r * (c * self.x[i] + s * self.y[i]);
        }
        p
    }
}

/// One chord of a [`TcpMove`].
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
/// ([`TcpMove::next_chord`]); no allocation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TcpMove {
    kin: FiveAxisKinematics,
    tool_offset: f64,
    start: AxisVec,
    end: AxisVec,
    arc: Option<ArcFrame>,
    tolerance: f64,
    duration: f64,
    /// Fraction of the move done, the joints there, and the last step taken.
    u: f64,
    joints: AxisVec,
    step: f64,
    chords: u32,
    line: u32,
}

impl TcpMove {
    /// The tip move along `path` from where `start_joints` put it to the pose `end`, with
    /// the tool length `tool_offset`, its chords within `tolerance` (mm) of the programmed
    /// points, taking `duration` seconds in all (0 for a rapid: the planner's axis limits
    /// set it). `kin` is a table's or a head's kinematics.
    ///
    /// Real-time: yes (no allocation, no blocking).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        kin: impl Into<FiveAxisKinematics>,
        tool_offset: f64,
        start_joints: &AxisVec,
        end: &AxisVec,
        path: TipPath,
        tolerance: f64,
        duration: f64,
        line: u32,
    ) -> Result<TcpMove, MotionError> {
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
        let kin = kin.into();
        let start = kin.pose(start_joints, tool_offset);
        let arc = match path {
            TipPath::Line => None,
            TipPath::Arc {
                centre,
                normal,
                turns,
            } => Some(ArcFrame::new(&start, end, centre, normal, turns, line)?),
        };
        Ok(TcpMove {
            kin,
            tool_offset,
            start,
            end: *end,
            arc,
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
        if let Some(arc) = &self.arc {
            p[..3].copy_from_slice(&arc.at(u));
        }
        p
    }

    /// The tip's length (X Y Z) and the length in all axes (mm and degrees together, as
    /// the planner measures a move whose tip stands): exact for a line and a helix; a
    /// spiral's by Simpson's rule over 64 intervals of its speed
    /// √(rise² + (r₁ − r₀)² + (r·sweep)²) (smooth: far below 1e-9 of its length).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn lengths(&self) -> (f64, f64) {
        let mut others = 0.0;
        for i in 3..AXES {
            others += (self.end[i] - self.start[i]).powi(2);
        }
        let Some(arc) = &self.arc else {
            let mut xyz = 0.0;
            for i in 0..3 {
                xyz += (self.end[i] - self.start[i]).powi(2);
            }
            return (xyz.sqrt(), (xyz + others).sqrt());
        };
        let fixed = (arc.h1 - arc.h0).powi(2) + (arc.r1 - arc.r0).powi(2);
        let speed = |u: f64, extra: f64| {
            let r = arc.r0 + u * (arc.r1 - arc.r0);
            (fixed + (r * arc.sweep).powi(2) + extra).sqrt()
        };
        const N: u32 = 64;
        let (mut tip, mut all) = (0.0, 0.0);
        for k in 0..=N {
            let u = f64::from(k) / f64::from(N);
            let w = if k == 0 || k == N {
                1.0
            } else if k % 2 == 1 {
                4.0
            } else {
                2.0
            };
            tip += w * speed(u, 0.0);
            all += w * speed(u, others);
        }
        let h = 1.0 / (3.0 * f64::from(N));
        (tip * h, all * h)
    }

    /// The same move taking `duration` seconds.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn with_duration(mut self, duration: f64) -> TcpMove {
        self.duration = duration;
        self
    }

    /// See [`TableKinematics::joint_to_tip_gain`] and
    /// [`crate::HeadKinematics::joint_to_tip_gain`], for this move.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn joint_to_tip_gain(&self) -> f64 {
        let table = match &self.kin {
            FiveAxisKinematics::Table(t) => t,
            FiveAxisKinematics::Head(h) => return h.joint_to_tip_gain(self.tool_offset),
        };
        let Some(arc) = &self.arc else {
            return table.joint_to_tip_gain(&self.start, &self.end, self.tool_offset);
        };
        // An arc's points lie within its radius and rise of its centre: the bound is
        // taken at a point that far from the centre, towards the rot point's far side.
        let c = arc.centre;
        let r = table.rot_point;
        let reach = arc.r0.max(arc.r1) + arc.h0.abs().max(arc.h1.abs());
        let q = [c[0] - r[0], c[1] - r[1], c[2] - r[2]];
        let qn = dot3(&q, &q).sqrt();
        let mut far = self.start;
        let dir = if qn > 0.0 {
            [q[0] / qn, q[1] / qn, q[2] / qn]
        } else {
            [1.0, 0.0, 0.0]
        };
        for i in 0..3 {
            far[i] = c[i] + reach * dir[i];
        }
        table.joint_to_tip_gain(&far, &far, self.tool_offset)
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
