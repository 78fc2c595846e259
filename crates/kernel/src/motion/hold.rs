//! Feed holds: the operator's (or a deadline miss's), the machine logic's and the feed
//! stop switch's, and the resume that releases them. A hold is latched over whatever the
//! machine does (docs/kernel.md, "Feed hold"): a moving path decelerates along itself, a
//! jog or homing stops, and whatever the program waits for ends without the next block
//! starting, until a resume.

use rtcnc_motion::AXES;

use super::state::{Event, Step};
use super::{MotionCore, Source};
use crate::messages::Aux;

/// The holds in force.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(super) struct Hold {
    /// The path is held (the operator's hold, or the logic's while the path moved): no
    /// move starts until a resume.
    pub(super) held: bool,
    /// The logic's hold rose while a program or MDI line stood between moves (not in its
    /// own spindle hand-shake): the next move waits for a resume, as a held path does.
    pub(super) logic_paused: bool,
    /// A hold came during a thread pass: the path is held at its end.
    pub(super) after_sync: bool,
    /// The machine logic asks for a feed hold (its level as interpolation last read it).
    /// Its rising edge holds a moving path as the operator's feed hold does; while it
    /// stands, a resume is refused and a standing path does not start.
    pub(super) logic_request: bool,
    /// The feed stop switch holds the path now.
    pub(super) feed_stop: bool,
}

impl Hold {
    /// A hold latched until a resume.
    pub(super) fn latched(&self) -> bool {
        self.held || self.logic_paused
    }
}

impl MotionCore {
    /// The operator's feed hold. It is latched in every state, moving or not, until a
    /// resume (or an abort, e-stop or fault): a moving path decelerates along itself, a
    /// jog or homing stops, and whatever the machine waits for (a machine function, a
    /// dwell, an input, a pause, the start of a program, the next MDI line) ends without
    /// the next block starting.
    pub(super) fn hold(&mut self) {
        // An e-stop or fault has already stopped everything and ended the program; a hold
        // latched now would outlive the reset that follows. Homing cannot go on from where
        // a hold stops it: it is given up (and starts again next time).
        if !self.fire(Event::Hold) {
            return;
        }
        match self.source {
            // A thread pass cannot stop in the cut: the hold takes effect at its end (as in
            // LinuxCNC, which holds spindle-synchronised motion only after it).
            Source::Path if self.synced.is_some() => self.hold.after_sync = true,
            Source::Path => {
                self.hold.held = true;
                if self.moving() {
                    self.take_back();
                    self.path.planner.hold();
                }
            }
            Source::Manual => {
                self.hold.held = true;
                self.take_back();
                self.manual.handwheel = None;
                for i in 0..AXES {
                    if self.machine.axis_present[i] {
                        let _ = self.manual.axis_otg[i].stop();
                    }
                }
                // Joints of an axis that homing had taken over; independent joints move
                // beside the program and are not held (as PLCopen axes are not).
                for j in 0..self.machine.joint_count {
                    if self.machine.joints[j].axis.is_some()
                        && self.manual.joint_manual & (1 << j) != 0
                    {
                        let _ = self.manual.joint_otg[j].stop();
                    }
                }
            }
        }
    }

    /// The operator's resume: releases a latched hold, and continues a program paused at
    /// M0/M1 or a single block (the operator's "go on" is the same key on every
    /// controller). Refused while the logic asks for a hold (door open, fault, spindle not
    /// at speed).
    pub(super) fn resume(&mut self) {
        if self.interface.logic.get().feed_hold_request {
            return;
        }
        if self.hold.latched() {
            self.hold.held = false;
            self.hold.logic_paused = false;
            // The feed stop switch keeps holding until it is released.
            if !self.hold.feed_stop {
                self.take_back();
                self.path.planner.resume();
            }
        }
        if matches!(self.step_of_program(), Some(Step::Paused { .. })) {
            self.program.start_count = self.program.start_count.wrapping_add(1);
        }
    }

    /// The machine logic's feed hold request as this period reads it: its rising edge
    /// holds a moving path, or, when a program stands between moves (not in its spindle
    /// hand-shake, which waits for the request to fall by itself), makes the next move
    /// wait for a resume. A run that has not taken its first block yet waits for the
    /// request to fall, as one started while it already stood: whether the logic's scan
    /// saw the door open just before or just after the operator's start is chance, and
    /// the machine logic asks for a hold for a few scans after a reset, when scripts
    /// start their program.
    pub(super) fn follow_logic_hold(&mut self, request: bool) {
        if request && !self.hold.logic_request {
            let step = self.step_of_program();
            let spindle_handshake = matches!(
                step,
                Some(Step::Logic {
                    aux: Aux::SpindleOn { .. }
                        | Aux::SpindleSpeed { .. }
                        | Aux::ConstantSurfaceSpeed { .. }
                        | Aux::SurfaceSpeedOff,
                    ..
                })
            );
            // A rigid tap's own spindle reversals take the spindle out of the logic's
            // at-speed window: as in a spindle hand-shake nothing latches; the tap goes
            // on (it cannot stop in the hole) and the next block waits for the request to
            // fall.
            let in_tap = self.tap_spindle().is_some();
            if self.moving() && !in_tap {
                self.hold();
            } else if !in_tap && step.is_some() && !spindle_handshake && self.program.took_a_block {
                self.hold.logic_paused = true;
            }
        }
        self.hold.logic_request = request;
    }

    /// The feed stop switch (M53): holds a moving path while it is on, and lets it go on
    /// by itself when released (LinuxCNC's feed hold input); no new move starts meanwhile.
    pub(super) fn follow_feed_stop_switch(&mut self, digital_inputs: u64) {
        let stop_now =
            self.overrides.feed_stop_enabled && digital_inputs & self.io.feed_stop_bit != 0;
        if stop_now != self.hold.feed_stop {
            self.hold.feed_stop = stop_now;
            if self.source == Source::Path {
                if stop_now {
                    if self.moving() {
                        self.take_back();
                        self.path.planner.hold();
                    }
                } else if !self.hold.latched() {
                    self.take_back();
                    self.path.planner.resume();
                }
            }
        }
    }
}
