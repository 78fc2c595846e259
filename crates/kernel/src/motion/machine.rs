//! What the motion core knows of the machine from its configuration: the axes and joints
//! with their limits, which joints the planner drives, where everything stands at
//! power-up, and the servo period. Read-only once built.

use rtcnc_motion::otg::Limits;
use rtcnc_motion::{AXES, AxisLimits, MachineLimits};

use crate::config::{HomingConfig, JointLimitsConfig, MAX_JOINTS, MachineConfig};

/// One joint.
#[derive(Debug, Clone, Copy)]
pub(super) struct JointInfo {
    /// The axis it follows; `None`: an independent joint.
    pub(super) axis: Option<usize>,
    pub(super) homing: Option<HomingConfig>,
    pub(super) limits: Limits,
    /// Limits of a quick stop (e-stop, fault).
    pub(super) quick: Limits,
    pub(super) min: f64,
    pub(super) max: f64,
}

/// The machine's axes and joints.
pub(super) struct Machine {
    pub(super) joints: [JointInfo; MAX_JOINTS],
    pub(super) joint_count: usize,
    pub(super) axis_present: [bool; AXES],
    pub(super) axis_limits: [Limits; AXES],
    /// Limits of a quick stop (e-stop, fault).
    pub(super) axis_quick: [Limits; AXES],
    pub(super) axis_min: [f64; AXES],
    pub(super) axis_max: [f64; AXES],
    /// Speed of an incremental jog.
    pub(super) jog_velocity: [f64; AXES],
    /// Each axis' first joint (for positions from the feedback).
    pub(super) axis_joint: [Option<usize>; AXES],
    pub(super) period_s: f64,
    pub(super) period_ns: u64,
    /// Handwheel travel per count at ×1.
    pub(super) handwheel_units_per_count: f64,
}

/// The machine at power-up, and the planner's part of it.
pub(super) struct PowerUp {
    /// The planner's limits.
    pub(super) limits: MachineLimits,
    /// Axis positions: where each axis' first joint stands.
    pub(super) axes: [f64; AXES],
    /// Joint positions.
    pub(super) joints: [f64; MAX_JOINTS],
    /// The machine joint of each of the kinematics' joints (the joints axes drive).
    pub(super) planner_joints: [usize; MAX_JOINTS],
    pub(super) planner_joint_count: usize,
}

pub(super) fn limits_of(v: f64, a: f64, j: f64) -> Limits {
    Limits::symmetric(v, a, j)
}

impl Machine {
    /// The machine of a validated configuration.
    pub(super) fn from_config(config: &MachineConfig) -> (Machine, PowerUp) {
        let plan = config.axis_plan();
        let mut limits = MachineLimits { axes: [None; AXES] };
        let mut axis_present = [false; AXES];
        let mut axis_limits = [limits_of(1.0, 1.0, 1.0); AXES];
        let mut axis_quick = axis_limits;
        let mut axis_min = [0.0; AXES];
        let mut axis_max = [0.0; AXES];
        let mut jog_velocity = [0.0; AXES];
        for p in &plan {
            let Some(a) = config.axis(p.axis) else {
                continue;
            };
            let i = p.axis as usize;
            let qa = a.quick_stop_acceleration.unwrap_or(a.max_acceleration);
            let qj = a.quick_stop_jerk.unwrap_or(a.max_jerk);
            limits.axes[i] = Some(AxisLimits {
                max_velocity: a.max_velocity,
                max_acceleration: a.max_acceleration,
                max_jerk: a.max_jerk,
                min_position: a.min_position,
                max_position: a.max_position,
                quick_stop_acceleration: qa,
                quick_stop_jerk: qj,
            });
            axis_present[i] = true;
            axis_limits[i] = limits_of(a.max_velocity, a.max_acceleration, a.max_jerk);
            axis_quick[i] = limits_of(a.max_velocity, qa, qj);
            axis_min[i] = a.min_position;
            axis_max[i] = a.max_position;
            jog_velocity[i] = a.jog_velocity.unwrap_or(a.max_velocity / 10.0);
        }
        let joint_count = config.joints.len().min(MAX_JOINTS);
        let mut joints = [JointInfo {
            axis: None,
            homing: None,
            limits: limits_of(1.0, 1.0, 1.0),
            quick: limits_of(1.0, 1.0, 1.0),
            min: 0.0,
            max: 0.0,
        }; MAX_JOINTS];
        let mut planner_joint_count = 0;
        let mut axis_started = [false; AXES];
        let mut planner_joints = [0usize; MAX_JOINTS];
        let mut start = [0.0; AXES];
        let mut initial = [0.0; MAX_JOINTS];
        for (j, jc) in config.joints.iter().enumerate().take(joint_count) {
            initial[j] = jc.initial_position();
            let axis = plan.iter().find(|p| p.joints.contains(&j)).map(|p| p.axis);
            let info = &mut joints[j];
            info.homing = jc.homing;
            match axis {
                Some(a) => {
                    let i = a as usize;
                    info.axis = Some(i);
                    info.limits = axis_limits[i];
                    info.quick = axis_quick[i];
                    info.min = axis_min[i];
                    info.max = axis_max[i];
                    // The axis starts where its first joint stands; the others are made to
                    // agree through their offsets until homing squares them.
                    if !std::mem::replace(&mut axis_started[i], true) {
                        start[i] = jc.initial_position();
                    }
                    planner_joints[planner_joint_count] = j;
                    planner_joint_count += 1;
                }
                None => {
                    let l = jc.limits.unwrap_or(JointLimitsConfig {
                        min_position: -1.0,
                        max_position: 1.0,
                        max_velocity: 1.0,
                        max_acceleration: 1.0,
                        max_jerk: 1.0,
                    });
                    info.limits = limits_of(l.max_velocity, l.max_acceleration, l.max_jerk);
                    info.quick = info.limits;
                    info.min = l.min_position;
                    info.max = l.max_position;
                }
            }
        }
        let mut axis_joint = [None; AXES];
        for j in (0..joint_count).rev() {
            if let Some(i) = joints[j].axis {
                axis_joint[i] = Some(j);
            }
        }
        let period = config.servo_period();
        let machine = Machine {
            joints,
            joint_count,
            axis_present,
            axis_limits,
            axis_quick,
            axis_min,
            axis_max,
            jog_velocity,
            axis_joint,
            period_s: period.as_secs_f64(),
            period_ns: period.as_nanos() as u64,
            handwheel_units_per_count: config.handwheel.units_per_count,
        };
        let power_up = PowerUp {
            limits,
            axes: start,
            joints: initial,
            planner_joints,
            planner_joint_count,
        };
        (machine, power_up)
    }
}

/// Every joint's quick-stop limits (the limits of its axis' quick stop; an independent
/// joint's own), for a stop position control makes by itself.
pub(crate) fn joint_quick_stop_limits(config: &MachineConfig) -> Vec<Limits> {
    let (machine, _) = Machine::from_config(config);
    machine.joints[..machine.joint_count]
        .iter()
        .map(|j| j.quick)
        .collect()
}
