//! The kinematics the kernel plans with: any [`Kinematics`] of `rtcnc-motion`, chosen when
//! the kernel is built. The machine file gives trivial kinematics (one joint per axis, or
//! several for a gantry axis); other kinematics are handed to `Kernel::build_with`.

use rtcnc_motion::{AxisVec, JointLimits, Kinematics, MotionError, TrivialKinematics};

use crate::config::MachineConfig;

/// A machine's kinematics, boxed so that the kernel's types do not depend on which one it
/// is. Its joint `k` is the `k`-th joint of the machine file that an axis drives (joints
/// no axis drives are independent joints, outside the kinematics). One call per servo
/// period goes through the box (the planner's `axes_to_joints`); it does not allocate.
pub struct MachineKinematics(Box<dyn Kinematics + Send>);

impl MachineKinematics {
    /// Any kinematics.
    ///
    /// Real-time: no (set-up: allocates).
    pub fn new(kinematics: impl Kinematics + Send + 'static) -> MachineKinematics {
        MachineKinematics(Box::new(kinematics))
    }

    /// The machine file's kinematics: every joint an axis drives follows that axis one to
    /// one (a gantry axis drives several joints), in the order of `[[joints]]`.
    ///
    /// Real-time: no (set-up: allocates).
    pub fn from_config(config: &MachineConfig) -> Result<MachineKinematics, MotionError> {
        let plan = config.axis_plan();
        let joints = (0..config.joints.len())
            .filter_map(|j| {
                let axis = plan.iter().find(|p| p.joints.contains(&j))?.axis;
                Some((axis, None))
            })
            .collect();
        Ok(MachineKinematics::new(TrivialKinematics::new(joints)?))
    }
}

impl Kinematics for MachineKinematics {
    fn joint_count(&self) -> usize {
        self.0.joint_count()
    }

    fn axes_to_joints(&self, axes: &AxisVec, joints: &mut [f64]) {
        self.0.axes_to_joints(axes, joints);
    }

    fn joints_to_axes(&self, joints: &[f64]) -> AxisVec {
        self.0.joints_to_axes(joints)
    }

    fn joint_axis(&self, joint: usize) -> Option<rtcnc_motion::Axis> {
        self.0.joint_axis(joint)
    }

    fn joint_limits(&self, joint: usize) -> Option<JointLimits> {
        self.0.joint_limits(joint)
    }
}
