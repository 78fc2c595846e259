//! Five-axis kinematics of a tilting/rotating spindle head on a bridge mill (LinuxCNC's
//! `5axiskins`).
//!
//! The work stands still; the head moves in X Y Z and, about a pivot point in it, C turns
//! the tool about Z and B tilts it away from Z (B 0: the tool points down; B 90 at C 0:
//! the tip is on the +X side of the pivot, LinuxCNC's direction for this module). With
//! `L` the pivot length plus the tool length in force (LinuxCNC's `pivot-length` pin,
//! which its notes say to feed with the mechanical length plus `motion.tooloffset.z`) and
//! `r = L · (sin B cos C, sin B sin C, −cos B)` the pivot-to-tip vector:
//!
//! ```text
//! forward:  p = J + r + (0, 0, L)
//! inverse:  J = p − r − (0, 0, L)
//! ```
//!
//! At B 0 the joints are the pose (`r = (0, 0, −L)`), as on a three-axis mill. As with
//! the tables, the pose's Z carries the tool length offset (the gauge line) and the tool
//! length in `L` takes it out again, so the tilt swings the tip, not the gauge line.
//! LinuxCNC's W (a move along the tool, added to `L`) is not part of it: here W is 0 in
//! the formula and a configured W axis drives its own joint.

use crate::axes::AxisVec;

const X: usize = 0;
const Y: usize = 1;
const Z: usize = 2;
const B: usize = 4;
const C: usize = 5;

/// A tilting (B) and rotating (C) spindle head: LinuxCNC's `5axiskins` with W = 0.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeadKinematics {
    pivot_length: f64,
}

impl HeadKinematics {
    /// `pivot_length`: from the pivot to the spindle's gauge line (mm), LinuxCNC's
    /// `pivot-length` less the tool length (which [`HeadKinematics::joints`] and
    /// [`HeadKinematics::pose`] take as an argument).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn xyzbc_head(pivot_length: f64) -> HeadKinematics {
        HeadKinematics { pivot_length }
    }

    /// The pivot length (mm), without the tool.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn pivot_length(&self) -> f64 {
        self.pivot_length
    }

    /// `L` and the pivot-to-tip vector `r` at B and C (degrees).
    fn lever(&self, b: f64, c: f64, tool_offset: f64) -> (f64, [f64; 3]) {
        let l = self.pivot_length + tool_offset;
        let (sb, cb) = b.to_radians().sin_cos();
        let (sc, cc) = c.to_radians().sin_cos();
        (l, [l * sb * cc, l * sb * sc, -l * cb])
    }

    /// Joint positions of a pose (inverse kinematics); the other axes pass through.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn joints(&self, pose: &AxisVec, tool_offset: f64) -> AxisVec {
        let (l, r) = self.lever(pose[B], pose[C], tool_offset);
        let mut j = *pose;
        j[X] = pose[X] - r[0];
        j[Y] = pose[Y] - r[1];
        j[Z] = pose[Z] - r[2] - l;
        j
    }

    /// The pose of joint positions (forward kinematics).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn pose(&self, joints: &AxisVec, tool_offset: f64) -> AxisVec {
        let (l, r) = self.lever(joints[B], joints[C], tool_offset);
        let mut p = *joints;
        p[X] = joints[X] + r[0];
        p[Y] = joints[Y] + r[1];
        p[Z] = joints[Z] + r[2] + l;
        p
    }

    /// How much a distance in joint space (mm and degrees in one norm) can move the tip
    /// at most, anywhere: √(1 + 2·k²), k = |L| per radian (the tip's movement per radian
    /// of B is |L|, of C |L·sin B|; X Y Z move it one to one).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn joint_to_tip_gain(&self, tool_offset: f64) -> f64 {
        let k = (self.pivot_length + tool_offset).abs().to_radians();
        (1.0 + 2.0 * k * k).sqrt()
    }
}
