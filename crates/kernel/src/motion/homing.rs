//! Homing, group by group in sequence order (LinuxCNC's order for each joint: search the
//! switch, back off it, latch on the index or the switch edge, move to the home
//! position). The joints of an axis are taken over from the axis' generator while they
//! home and handed back once they stand, so that a gantry's joints square themselves.

use rtcnc_motion::otg::{self, OnlineAxis};

use super::MotionCore;
use super::state::{Event, State};
use crate::config::MAX_JOINTS;
use crate::messages::JointSetpoints;
use crate::shared::Feedback;

/// Where a joint is in its homing sequence.
#[derive(Debug, Clone, Copy, PartialEq)]
enum HomingStep {
    Search,
    SearchStop,
    BackOff,
    BackOffStop,
    Latch,
    LatchStop,
    MoveHome,
}

/// The group of joints homing now.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Homing {
    /// The group's sequence number; `None` for the joints of one axis homed alone (no
    /// group follows them).
    sequence: Option<u8>,
    /// Joints of the current group with their step.
    step: [Option<HomingStep>; MAX_JOINTS],
}

#[cfg(test)]
impl Homing {
    /// A group of no joints, for the state's tests.
    pub(super) fn of_sequence(sequence: u8) -> Homing {
        Homing {
            sequence: Some(sequence),
            step: [None; MAX_JOINTS],
        }
    }
}

impl MotionCore {
    /// Homes every joint with a homing sequence, group by group; joints without one are
    /// homed where they stand.
    pub(super) fn home_all(&mut self) -> bool {
        self.enter_manual();
        self.disarm_homing_latches();
        self.homed = 0;
        let group = self.next_homing_group(None);
        if group.is_none() {
            self.homed = (1u32 << self.machine.joint_count) - 1;
        }
        self.fire(Event::Home(group))
    }

    /// The group of joints that homes after sequence number `after` (the first: none).
    fn next_homing_group(&self, after: Option<u8>) -> Option<Homing> {
        let sequence = (0..self.machine.joint_count)
            .filter_map(|j| self.machine.joints[j].homing.map(|h| h.sequence))
            .filter(|s| after.is_none_or(|a| *s > a))
            .min()?;
        let mut step = [None; MAX_JOINTS];
        for (j, slot) in step.iter_mut().enumerate().take(self.machine.joint_count) {
            if self.machine.joints[j]
                .homing
                .is_some_and(|h| h.sequence == sequence)
            {
                *slot = Some(HomingStep::Search);
            }
        }
        Some(Homing {
            sequence: Some(sequence),
            step,
        })
    }

    /// Homes the joints of axis `i` alone, together (a gantry's joints square themselves
    /// as in their sequence); those without a homing sequence are homed where they stand.
    /// Refused for an axis that no joint drives.
    pub(super) fn home_axis(&mut self, i: usize) -> bool {
        let joints =
            (0..self.machine.joint_count).filter(|&j| self.machine.joints[j].axis == Some(i));
        let mut step = [None; MAX_JOINTS];
        let (mut any, mut searching) = (false, false);
        for j in joints {
            any = true;
            self.homed &= !(1u32 << j);
            if self.machine.joints[j].homing.is_some() {
                step[j] = Some(HomingStep::Search);
                searching = true;
            } else {
                self.homed |= 1 << j;
            }
        }
        if !any {
            return false;
        }
        self.enter_manual();
        self.disarm_homing_latches();
        let group = searching.then_some(Homing {
            sequence: None,
            step,
        });
        if group.is_none() {
            self.requests_mut().homed = self.all_homed();
        }
        self.fire(Event::Home(group))
    }

    /// Takes back every homing latch request (index pulse, home switch). A homing stopped
    /// with its latch armed left the request standing: the drive stayed armed, latched
    /// whatever edge the next jog passed, and the next homing, whose request was the same,
    /// took that old latch as its own (the machine frame one index pulse off). A request
    /// taken back and made again re-arms the drive.
    pub(super) fn disarm_homing_latches(&mut self) {
        self.out.latch.index = 0;
        self.out.latch.switch = 0;
    }

    /// Every joint is homed.
    fn all_homed(&self) -> bool {
        let all = (1u32 << self.machine.joint_count) - 1;
        self.homed & all == all
    }
    /// One period of the homing sequence of the current group.
    pub(super) fn homing_step(&mut self, feedback: &Feedback) {
        let State::Homing(mut homing) = self.state else {
            return;
        };
        let mut all_done = true;
        for j in 0..self.machine.joint_count {
            let Some(step) = homing.step[j] else {
                continue;
            };
            let Some(h) = self.machine.joints[j].homing else {
                continue;
            };
            let bit = 1u32 << j;
            let toward = h.search_velocity.signum();
            let on_switch = feedback.home_switch & bit != 0;
            let joint_otg = &mut self.manual.joint_otg[j];
            let next = match step {
                HomingStep::Search => {
                    if self.manual.joint_manual & bit == 0 {
                        // Take the joint over from its axis, at rest where it stands.
                        let p = self.out.last.joints[j];
                        if let Ok(o) =
                            OnlineAxis::new(otg::State::at_rest(p), self.machine.joints[j].limits)
                        {
                            *joint_otg = o;
                        }
                        self.manual.joint_manual |= bit;
                        let _ = joint_otg.set_velocity(h.search_velocity, 0.0);
                        Some(HomingStep::Search)
                    } else if on_switch {
                        let _ = joint_otg.stop();
                        Some(HomingStep::SearchStop)
                    } else {
                        Some(HomingStep::Search)
                    }
                }
                HomingStep::SearchStop => {
                    if joint_otg.is_finished() {
                        let _ = joint_otg.set_velocity(-toward * h.latch_velocity, 0.0);
                        Some(HomingStep::BackOff)
                    } else {
                        Some(HomingStep::SearchStop)
                    }
                }
                HomingStep::BackOff => {
                    if !on_switch {
                        let _ = joint_otg.stop();
                        Some(HomingStep::BackOffStop)
                    } else {
                        Some(HomingStep::BackOff)
                    }
                }
                HomingStep::BackOffStop => {
                    if joint_otg.is_finished() {
                        if h.use_index {
                            self.out.latch.index |= bit;
                        } else {
                            self.out.latch.switch |= bit;
                        }
                        let _ = joint_otg.set_velocity(toward * h.latch_velocity, 0.0);
                        Some(HomingStep::Latch)
                    } else {
                        Some(HomingStep::BackOffStop)
                    }
                }
                HomingStep::Latch => {
                    if feedback.latched & bit != 0
                        && (self.out.latch.index | self.out.latch.switch) & bit != 0
                    {
                        self.out.latch.index &= !bit;
                        self.out.latch.switch &= !bit;
                        // The latched raw position becomes `latch_position`.
                        let new_offset = h.latch_position - feedback.latch_position[j];
                        let shift = new_offset - self.out.offsets[j];
                        self.out.offsets[j] = new_offset;
                        let s = joint_otg.sample();
                        if let Ok(o) = OnlineAxis::new(
                            otg::State::new(s.p + shift, s.v, s.a),
                            self.machine.joints[j].limits,
                        ) {
                            *joint_otg = o;
                        }
                        let _ = joint_otg.stop();
                        Some(HomingStep::LatchStop)
                    } else {
                        Some(HomingStep::Latch)
                    }
                }
                HomingStep::LatchStop => {
                    if joint_otg.is_finished() {
                        let _ = joint_otg.set_target(otg::State::at_rest(h.home_position));
                        Some(HomingStep::MoveHome)
                    } else {
                        Some(HomingStep::LatchStop)
                    }
                }
                HomingStep::MoveHome => {
                    if joint_otg.is_finished() {
                        self.homed |= bit;
                        None
                    } else {
                        Some(HomingStep::MoveHome)
                    }
                }
            };
            homing.step[j] = next;
            if next.is_some() {
                all_done = false;
            }
        }
        if all_done {
            // The group's axis joints, now squared, go back to their axes at the end of
            // this period (`release_stopped_homing_joints`).
            let next = homing
                .sequence
                .and_then(|s| self.next_homing_group(Some(s)));
            self.fire(Event::GroupHomed(next));
            if next.is_none() {
                if homing.sequence.is_some() {
                    // Joints without a sequence are homed where they stand.
                    for j in 0..self.machine.joint_count {
                        if self.machine.joints[j].homing.is_none() {
                            self.homed |= 1 << j;
                        }
                    }
                }
                self.requests_mut().homed = self.all_homed();
            }
        } else if let State::Homing(group) = &mut self.state {
            *group = homing;
        }
    }
    /// Axis joints that homing took over go back to their axis once they stand outside
    /// the group being homed (their group is done, or homing was stopped), so that the
    /// axis drives them again from there. Runs after the period's set-point `sp` is made,
    /// which it corrects for the axis, so the hand-over has no step.
    pub(super) fn release_stopped_homing_joints(&mut self, sp: &mut JointSetpoints) {
        for j in 0..self.machine.joint_count {
            let bit = 1u32 << j;
            let Some(i) = self.machine.joints[j].axis else {
                continue;
            };
            let in_group = matches!(self.state, State::Homing(h) if h.step[j].is_some());
            if self.manual.joint_manual & bit == 0
                || in_group
                || !self.manual.joint_otg[j].is_finished()
            {
                continue;
            }
            let p = self.manual.joint_otg[j].sample().p;
            if let Ok(o) = OnlineAxis::new(otg::State::at_rest(p), self.machine.axis_limits[i]) {
                self.manual.axis_otg[i] = o;
            }
            self.manual.joint_manual &= !bit;
            sp.axes[i] = p;
            sp.joints[j] = p;
        }
    }
}
