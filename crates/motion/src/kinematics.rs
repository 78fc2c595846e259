//! Kinematics: the map from axis space (X Y Z A B C U V W) to joints.
//!
//! The planner plans in axis space and checks limits there; [`Kinematics`] turns each
//! set-point into joint positions. Trivial kinematics (every joint follows one axis, possibly
//! several joints the same axis, as in a gantry) is implemented; its joint limits are folded
//! into the axis limits. A non-trivial kinematics (5-axis heads, hexapods) implements the
//! same trait; the planner then needs joint limits projected through the Jacobian, which is
//! not implemented yet: such kinematics is refused by the planner.

use crate::axes::{AXES, Axis, AxisVec};
use crate::error::MotionError;

/// Limits of one joint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointLimits {
    /// Maximum |velocity|.
    pub max_velocity: f64,
    /// Lower position limit.
    pub min_position: f64,
    /// Upper position limit.
    pub max_position: f64,
}

/// Axis-space to joint-space map.
pub trait Kinematics {
    /// Number of joints.
    ///
    /// Real-time: yes (implementations allocate nothing and do not block).
    fn joint_count(&self) -> usize;
    /// Joint positions of an axis position (inverse kinematics). `joints.len()` is
    /// `joint_count()`.
    ///
    /// Real-time: yes (implementations allocate nothing and do not block: it runs every
    /// servo period).
    fn axes_to_joints(&self, axes: &AxisVec, joints: &mut [f64]);
    /// Axis position of joint positions (forward kinematics).
    ///
    /// Real-time: yes (implementations allocate nothing and do not block).
    fn joints_to_axes(&self, joints: &[f64]) -> AxisVec;
    /// For trivial kinematics: the axis that joint `joint` follows one to one. `None` means
    /// the kinematics is not trivial.
    ///
    /// Real-time: yes (implementations allocate nothing and do not block).
    fn joint_axis(&self, joint: usize) -> Option<Axis>;
    /// Limits of joint `joint`, if any beyond the axis limits.
    ///
    /// Real-time: yes (implementations allocate nothing and do not block).
    fn joint_limits(&self, joint: usize) -> Option<JointLimits>;
}

/// Every joint follows one axis; an axis may drive several joints (gantry: X → X0..X3).
#[derive(Debug, Clone, PartialEq)]
pub struct TrivialKinematics {
    joints: Vec<(Axis, Option<JointLimits>)>,
}

impl TrivialKinematics {
    /// One joint per listed axis, in order (the usual XYZ mill: `&[X, Y, Z]`).
    ///
    /// Real-time: no (set-up: allocates).
    pub fn identity(axes: &[Axis]) -> Self {
        TrivialKinematics {
            joints: axes.iter().map(|a| (*a, None)).collect(),
        }
    }

    /// Joints given as (axis they follow, their own limits). A gantry X with four drives
    /// lists X four times.
    ///
    /// Real-time: no (set-up: allocates).
    pub fn new(joints: Vec<(Axis, Option<JointLimits>)>) -> Result<Self, MotionError> {
        if joints.is_empty() {
            return Err(MotionError::Kinematics("no joints".into()));
        }
        for (i, (_, l)) in joints.iter().enumerate() {
            if let Some(l) = l {
                if !(l.max_velocity.is_finite() && l.max_velocity > 0.0) {
                    return Err(MotionError::InvalidLimit {
                        what: format!("joint {i} velocity"),
                        value: l.max_velocity,
                    });
                }
                if !(l.min_position.is_finite()
                    && l.max_position.is_finite()
                    && l.min_position <= l.max_position)
                {
                    return Err(MotionError::InvalidLimit {
                        what: format!("joint {i} position range"),
                        value: l.min_position,
                    });
                }
            }
        }
        Ok(TrivialKinematics { joints })
    }
}

impl Kinematics for TrivialKinematics {
    fn joint_count(&self) -> usize {
        self.joints.len()
    }

    fn axes_to_joints(&self, axes: &AxisVec, joints: &mut [f64]) {
        for (out, (axis, _)) in joints.iter_mut().zip(self.joints.iter()) {
            *out = axes[*axis as usize];
        }
    }

    fn joints_to_axes(&self, joints: &[f64]) -> AxisVec {
        let mut a = [0.0; AXES];
        // The first joint of an axis defines it (gantry joints are equal by construction).
        for (i, (axis, _)) in self.joints.iter().enumerate().rev() {
            if let Some(j) = joints.get(i) {
                a[*axis as usize] = *j;
            }
        }
        a
    }

    fn joint_axis(&self, joint: usize) -> Option<Axis> {
        self.joints.get(joint).map(|j| j.0)
    }

    fn joint_limits(&self, joint: usize) -> Option<JointLimits> {
        self.joints.get(joint).and_then(|j| j.1)
    }
}
