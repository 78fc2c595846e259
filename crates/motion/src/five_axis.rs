//! The five-axis kinematics a tool-centre-point move runs through: a table
//! ([`TableKinematics`]) or a spindle head ([`HeadKinematics`]).

use crate::axes::AxisVec;
use crate::head_kinematics::HeadKinematics;
use crate::table_kinematics::TableKinematics;

/// A machine's five-axis kinematics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FiveAxisKinematics {
    /// A tilting table carrying a rotary table (`xyzac-trt`, `xyzbc-trt`).
    Table(TableKinematics),
    /// A tilting/rotating spindle head (`xyzbc-head`).
    Head(HeadKinematics),
}

impl From<TableKinematics> for FiveAxisKinematics {
    fn from(k: TableKinematics) -> Self {
        FiveAxisKinematics::Table(k)
    }
}

impl From<HeadKinematics> for FiveAxisKinematics {
    fn from(k: HeadKinematics) -> Self {
        FiveAxisKinematics::Head(k)
    }
}

impl FiveAxisKinematics {
    /// Joint positions of a pose, `tool_offset` the tool length in force (mm).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn joints(&self, pose: &AxisVec, tool_offset: f64) -> AxisVec {
        match self {
            FiveAxisKinematics::Table(k) => k.joints(pose, tool_offset),
            FiveAxisKinematics::Head(k) => k.joints(pose, tool_offset),
        }
    }

    /// The pose of joint positions, `tool_offset` the tool length in force (mm).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn pose(&self, joints: &AxisVec, tool_offset: f64) -> AxisVec {
        match self {
            FiveAxisKinematics::Table(k) => k.pose(joints, tool_offset),
            FiveAxisKinematics::Head(k) => k.pose(joints, tool_offset),
        }
    }
}
