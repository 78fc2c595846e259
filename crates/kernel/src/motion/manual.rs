//! Manual motion on the on-line generators: jog (continuous, incremental), the handwheel,
//! independent joints (which move beside whatever the axes do), and the hand-over of the
//! axes between the planner and these generators.

use rtcnc_motion::AXES;
use rtcnc_motion::otg::{self, Limits, OnlineAxis};

use super::state::State;
use super::{MotionCore, Source};
use crate::config::MAX_JOINTS;
use crate::messages::{JointSetpoints, Mode};
use crate::shared::Feedback;

/// The on-line generators.
pub(super) struct Manual {
    /// One per axis: jog, handwheel.
    pub(super) axis_otg: [OnlineAxis; AXES],
    /// One per joint: homing, independent joints.
    pub(super) joint_otg: [OnlineAxis; MAX_JOINTS],
    /// Bit n: joint n follows its own generator (homing, independent joint).
    pub(super) joint_manual: u32,
    /// The handwheel's axis and travel per count.
    pub(super) handwheel: Option<(usize, f64)>,
    /// The handwheel's counter when last read.
    pub(super) handwheel_counts: Option<i64>,
}

impl Manual {
    pub(super) fn new(
        axis_otg: [OnlineAxis; AXES],
        joint_otg: [OnlineAxis; MAX_JOINTS],
        joint_manual: u32,
    ) -> Manual {
        Manual {
            axis_otg,
            joint_otg,
            joint_manual,
            handwheel: None,
            handwheel_counts: None,
        }
    }
}

impl MotionCore {
    /// Continuous jog of axis `i` at `velocity` (signed), towards its soft limit.
    pub(super) fn jog_continuous(&mut self, i: usize, velocity: f64) -> bool {
        if !(i < AXES && self.machine.axis_present[i] && velocity.is_finite() && velocity != 0.0) {
            return false;
        }
        self.enter_manual();
        let axis = self.machine.axis_limits[i];
        let speed = velocity.abs().min(axis.max_velocity);
        let target = if velocity > 0.0 {
            self.machine.axis_max[i]
        } else {
            self.machine.axis_min[i]
        };
        let limits = Limits::symmetric(speed, axis.max_acceleration, axis.max_jerk);
        let otg = &mut self.manual.axis_otg[i];
        otg.set_limits(limits).is_ok() && otg.set_target(otg::State::at_rest(target)).is_ok()
    }

    /// Incremental jog of axis `i` by `distance`, at its jog speed, within its soft limits.
    pub(super) fn jog_increment(&mut self, i: usize, distance: f64) -> bool {
        if !(i < AXES && self.machine.axis_present[i] && distance.is_finite()) {
            return false;
        }
        self.enter_manual();
        let from = self.manual.axis_otg[i].sample().p;
        let target = (from + distance).clamp(self.machine.axis_min[i], self.machine.axis_max[i]);
        let axis = self.machine.axis_limits[i];
        let limits = Limits::symmetric(
            self.machine.jog_velocity[i],
            axis.max_acceleration,
            axis.max_jerk,
        );
        let otg = &mut self.manual.axis_otg[i];
        otg.set_limits(limits).is_ok() && otg.set_target(otg::State::at_rest(target)).is_ok()
    }

    /// Stops a jog of axis `i`.
    pub(super) fn jog_stop(&mut self, i: usize) -> bool {
        if !(self.source == Source::Manual && i < AXES && self.machine.axis_present[i]) {
            return false;
        }
        self.take_back();
        self.manual.axis_otg[i].stop().is_ok()
    }

    /// The handwheel on axis `i`, `scale` times `handwheel.units_per_count` per count.
    pub(super) fn select_handwheel(&mut self, i: usize, scale: f64) -> bool {
        if !(i < AXES && self.machine.axis_present[i] && scale.is_finite() && scale > 0.0) {
            return false;
        }
        self.enter_manual();
        let _ = self.manual.axis_otg[i].set_limits(self.machine.axis_limits[i]);
        self.manual.handwheel = Some((i, scale * self.machine.handwheel_units_per_count));
        self.manual.handwheel_counts = None;
        true
    }

    /// Moves independent joint `j` to `position` (within its limits). Independent joints
    /// move beside whatever the axes do (the seeds' 12-drive test: independent moves
    /// during three-axis interpolation), but not while homing.
    pub(super) fn joint_move(&mut self, j: usize, position: f64) -> bool {
        if !(matches!(self.state, State::Idle | State::Program(_))
            && j < self.machine.joint_count
            && self.machine.joints[j].axis.is_none()
            && position.is_finite())
        {
            return false;
        }
        self.take_back();
        let info = self.machine.joints[j];
        let target = position.clamp(info.min, info.max);
        let otg = &mut self.manual.joint_otg[j];
        let _ = otg.set_limits(info.limits);
        otg.set_target(otg::State::at_rest(target)).is_ok()
    }

    /// Hands motion to the on-line generators, from where the path stands.
    /// The operator's mode switch (idle only): manual hands the axes to the jog generators
    /// at once; auto and MDI take the path when their command comes.
    pub(super) fn set_mode(&mut self, mode: Mode) -> bool {
        match mode {
            Mode::Manual => self.enter_manual(),
            Mode::Auto | Mode::Mdi => self.mode = mode,
        }
        true
    }

    pub(super) fn enter_manual(&mut self) {
        self.mode = Mode::Manual;
        if self.source == Source::Manual {
            // What follows changes the generators from the next exchange on.
            self.take_back();
            return;
        }
        // The jog starts from where the machine is, not after the path's set-points
        // produced ahead.
        self.discard_ahead();
        let axes = self.out.last.axes;
        for i in 0..AXES {
            if self.machine.axis_present[i] {
                let limits = self.machine.axis_limits[i];
                if let Ok(o) = OnlineAxis::new(otg::State::at_rest(axes[i]), limits) {
                    self.manual.axis_otg[i] = o;
                }
            }
        }
        self.source = Source::Manual;
    }

    /// Hands motion to the planner, from where the generators stand.
    pub(super) fn enter_path(&mut self) {
        if self.source == Source::Path {
            return;
        }
        // From the set-point position control takes next, not after the generators' lead.
        self.discard_ahead();
        let _ = self.path.planner.reset_at(self.out.last.axes);
        self.manual.handwheel = None;
        self.source = Source::Path;
    }

    /// Stops every generator, with the quick-stop limits when `quick`.
    pub(super) fn stop_manual(&mut self, quick: bool) {
        for i in 0..AXES {
            if self.machine.axis_present[i] {
                if quick {
                    let _ = self.manual.axis_otg[i].set_limits(self.machine.axis_quick[i]);
                }
                let _ = self.manual.axis_otg[i].stop();
            }
        }
        for j in 0..self.machine.joint_count {
            if quick {
                let _ = self.manual.joint_otg[j].set_limits(self.machine.joints[j].quick);
            }
            let _ = self.manual.joint_otg[j].stop();
        }
    }

    /// Whether an axis or joint generator still moves.
    pub(super) fn manual_moving(&self) -> bool {
        (0..AXES).any(|i| self.machine.axis_present[i] && !self.manual.axis_otg[i].is_finished())
            || (0..self.machine.joint_count).any(|j| !self.manual.joint_otg[j].is_finished())
    }

    /// One period of the axis generators: every axis steps, the axis joints follow their
    /// axis.
    pub(super) fn manual_step(&mut self, sp: &mut JointSetpoints) {
        let mut speed2 = 0.0;
        for i in 0..AXES {
            if self.machine.axis_present[i] {
                let s = self.manual.axis_otg[i].step(self.machine.period_s);
                sp.axes[i] = s.p;
                speed2 += s.v * s.v;
            }
        }
        sp.path_speed = speed2.sqrt();
        for j in 0..self.machine.joint_count {
            if let Some(i) = self.machine.joints[j].axis {
                sp.joints[j] = sp.axes[i];
            }
        }
    }

    /// The handwheel's counts since it was last read move its axis' target.
    pub(super) fn handwheel_step(&mut self, feedback: &Feedback) {
        let Some((i, per_count)) = self.manual.handwheel else {
            self.manual.handwheel_counts = None;
            return;
        };
        let counts = feedback.handwheel_counts;
        let previous = self
            .manual
            .handwheel_counts
            .replace(counts)
            .unwrap_or(counts);
        let delta = counts.wrapping_sub(previous);
        if delta != 0 {
            let target = self.handwheel_target(i) + delta as f64 * per_count;
            let target = target.clamp(self.machine.axis_min[i], self.machine.axis_max[i]);
            let _ = self.manual.axis_otg[i].set_target(otg::State::at_rest(target));
        }
    }

    /// Where the axis generator is heading (its profile's end).
    fn handwheel_target(&self, i: usize) -> f64 {
        let (profile, _) = self.manual.axis_otg[i].profile();
        profile.at(profile.duration()).p
    }
}
