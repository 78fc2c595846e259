//! The safety chain: e-stop and faults stop whatever moves (a quick stop with the
//! configured deceleration and jerk) and disable the drives once it stands; a reset
//! enables them again from where the machine stands; the machine logic's e-stop chain,
//! once closed after a reset, is an e-stop when it opens.

use rtcnc_motion::AXES;
use rtcnc_motion::otg::{self, OnlineAxis};
use rtcnc_rt::Context;

use super::state::{Event, State, transition};
use super::{DriveEnable, LatchRequest, MotionCore, Source};
use crate::fault::{Fault, FaultCode, TaskName};
use crate::shared::{Feedback, InterpreterRequest, Shared};

/// The safety chain's latches (the states `Off` and `Stopping` are the machine state's).
#[derive(Debug, Clone, Copy)]
pub(super) struct Safety {
    /// An e-stop is latched (until a reset).
    pub(super) estop: bool,
    /// A fault is latched (until a reset).
    pub(super) fault: bool,
    /// Resets so far: position control clears its latched faults at each.
    pub(super) reset_count: u32,
    /// The logic's e-stop chain has been seen closed since the last reset.
    pub(super) chain_closed: bool,
    pub(super) last_fault: Option<Fault>,
}

impl Safety {
    /// At power-up: in e-stop, drives off.
    pub(super) fn new() -> Safety {
        Safety {
            estop: true,
            fault: false,
            reset_count: 0,
            chain_closed: false,
            last_fault: None,
        }
    }
}

impl MotionCore {
    /// The drives are enabled (also during the quick stop).
    pub(super) fn drives_enabled(&self) -> bool {
        matches!(
            self.state,
            State::Stopping | State::Idle | State::Homing(_) | State::Program(_)
        )
    }

    /// What the drives are to be: during a quick stop enabled ones stay enabled and none
    /// is brought up.
    pub(super) fn drive_enable(&self) -> DriveEnable {
        match self.state {
            State::Stopping => DriveEnable::Keep,
            State::Idle | State::Homing(_) | State::Program(_) => DriveEnable::On,
            _ => DriveEnable::Off,
        }
    }

    /// The operator's reset: clears the e-stop and faults and enables the drives. Refused
    /// before the self-test passed, while the e-stop input is pressed, while the fieldbus
    /// exchange fails and while a quick stop runs: the machine does not leave e-stop or
    /// fault while the cause stands. A failed exchange's feedback is the last one
    /// received, not where the load is (it coasts, or its drives stop it); the reset once
    /// the bus works again takes the set-points from fresh feedback.
    pub(super) fn reset(&mut self) -> bool {
        let feedback = *self.interface.feedback.get();
        if feedback.estop
            || feedback.exchange_failed
            || transition(&self.state, Event::Reset).is_none()
        {
            return false;
        }
        if self.state == State::Off && self.out.offsets_known && !self.drives_still_on(&feedback) {
            // The drives were off (the load may have coasted): the set-points start again
            // from where the machine stands.
            self.resync_to_feedback(&feedback);
        }
        self.safety.estop = false;
        self.safety.fault = false;
        self.fire(Event::Reset);
        // The drives enable from the next exchange, not from the set-points a lead ahead.
        self.out.set_enable_ahead(self.drive_enable());
        self.apply_feed_overrides();
        self.safety.chain_closed = false;
        self.safety.reset_count = self.safety.reset_count.wrapping_add(1);
        let mi = self.requests_mut();
        mi.reset_count = mi.reset_count.wrapping_add(1);
        mi.machine_on_request = true;
        true
    }

    /// A fault that stops the machine (read by interpolation before the period's
    /// set-point): the quick stop of whatever moves, with the configured deceleration and
    /// jerk; the drives are disabled once it stands ([`MotionCore::finish_quick_stop`]).
    pub(super) fn on_fault(&mut self, shared: &Shared, fault: Fault) {
        self.safety.last_fault = Some(fault);
        self.requests_mut().machine_on_request = false;
        if fault.code == FaultCode::EStop {
            self.safety.estop = true;
        } else {
            self.safety.fault = true;
        }
        // With the drives off already (power-up, or after an earlier fault) only the
        // latches change.
        if !self.fire(Event::Fault) {
            return;
        }
        self.probe = None;
        // Whatever stops, stops from the next exchange.
        self.take_back();
        self.stop_synced(true);
        // Output changes of motion that will not run are dropped.
        self.outputs.drop_pending();
        self.program.epoch = self.program.epoch.wrapping_add(1);
        let _ = shared
            .interpreter_requests
            .try_put(InterpreterRequest::Stop);
        self.program.pending = None;
        self.program.tcp = None;
        self.synced_chain.clear();
        self.hold.held = false;
        self.hold.logic_paused = false;
        self.out.latch = LatchRequest::default();
        match self.source {
            Source::Path => self.path.planner.quick_stop(),
            Source::Manual => {
                self.manual.handwheel = None;
                self.stop_manual(true);
            }
        }
        let mi = self.requests_mut();
        mi.tool_change_request = false;
        mi.m_code_request = false;
        mi.program_running = false;
        mi.spindle_on = false;
        mi.spindle_orient = false;
        self.spindle.on = false;
        // A stopped program leaves no override disabled behind; the planner takes them at
        // the reset.
        self.overrides.enable_all();
    }

    /// Every drive still holds its load under control: a reset came as a quick stop stood,
    /// before the drives heard they were to go off. They follow the last set-points, so
    /// the set-points go on from there: starting them from the measured positions would
    /// step each by its following error while the drive follows it.
    fn drives_still_on(&self, feedback: &Feedback) -> bool {
        let all = if self.machine.joint_count >= 32 {
            u32::MAX
        } else {
            (1u32 << self.machine.joint_count) - 1
        };
        feedback.enabled & all == all
    }

    /// The quick stop stands: the drives go off, from the next exchange. The set-points
    /// computed ahead while it stopped (standing) still enabled them: a drive whose power
    /// came back (the e-stop button released) was enabled by them while the machine was in
    /// e-stop.
    pub(super) fn finish_quick_stop(&mut self) {
        if self.state == State::Stopping && !self.moving() {
            self.fire(Event::Stood);
            self.out.set_enable_ahead(self.drive_enable());
        }
    }

    /// The machine logic's e-stop chain: once closed after a reset, its opening is an
    /// e-stop (the chain closes a scan or two after the reset).
    pub(super) fn watch_estop_chain(
        &mut self,
        ctx: &mut Context<'_>,
        shared: &Shared,
        chain_ok: bool,
    ) {
        if self.drives_enabled() && !self.safety.estop {
            if chain_ok {
                self.safety.chain_closed = true;
            } else if self.safety.chain_closed {
                self.safety.chain_closed = false;
                shared.raise(ctx, FaultCode::EStop, TaskName::MachineLogic, None, 0, 0.0);
            }
        }
    }

    /// Puts every set-point generator at rest on the measured positions. Joints of a
    /// gantry axis that no longer agree lose their homed state (their offsets absorb the
    /// difference; homing squares them again).
    fn resync_to_feedback(&mut self, feedback: &Feedback) {
        self.discard_ahead();
        let mut axes = self.out.last.axes;
        let mut axis_set = [false; AXES];
        for j in 0..self.machine.joint_count {
            let machine = feedback.position[j] + self.out.offsets[j];
            match self.machine.joints[j].axis {
                Some(i) if !axis_set[i] => {
                    axis_set[i] = true;
                    axes[i] = machine;
                    self.out.last.joints[j] = machine;
                }
                Some(i) => {
                    if (machine - axes[i]).abs() > 1e-3 {
                        self.homed &= !(1 << j);
                    }
                    self.out.offsets[j] = axes[i] - feedback.position[j];
                    self.out.last.joints[j] = axes[i];
                }
                None => {
                    self.out.last.joints[j] = machine;
                    let limits = self.machine.joints[j].limits;
                    if let Ok(o) = OnlineAxis::new(otg::State::at_rest(machine), limits) {
                        self.manual.joint_otg[j] = o;
                    }
                }
            }
        }
        self.out.last.axes = axes;
        for i in 0..AXES {
            if self.machine.axis_present[i] {
                let limits = self.machine.axis_limits[i];
                if let Ok(o) = OnlineAxis::new(otg::State::at_rest(axes[i]), limits) {
                    self.manual.axis_otg[i] = o;
                }
            }
        }
        for j in 0..self.machine.joint_count {
            if self.machine.joints[j].axis.is_some() && self.manual.joint_manual & (1 << j) != 0 {
                let at = otg::State::at_rest(self.out.last.joints[j]);
                if let Ok(o) = OnlineAxis::new(at, self.machine.joints[j].limits) {
                    self.manual.joint_otg[j] = o;
                }
            }
        }
        let _ = self.path.planner.reset_at(axes);
    }
}
