//! Interpolation, once per servo period: the urgent channel and the stop requests first,
//! then what this period's feedback and machine-logic answers change (holds, the e-stop
//! chain, a probe), then the set-points of every joint from the planner or the on-line
//! generators, into the lead queue to position control.
//!
//! Set-points are numbered by the exchange with the drives they are for. Along the path
//! (programs, MDI) interpolation computes them `tasks.setpoint_lead` periods ahead of
//! position control, so that a stall of its thread up to that long leaves position control
//! with set-points to apply. Whatever changes the path (an urgent command, a fault, a
//! hold of the machine logic, a probe, new moves into a planner at rest) first takes back
//! the set-points position control has not taken ([`MotionCore::take_back`]): the planner
//! goes back over them and computes them again with the change, so that it acts from the
//! next exchange as if every set-point had been computed just in time. Jog, handwheel,
//! homing and spindle-synchronised moves follow the feedback period by period and are
//! computed one period ahead.

use rtcnc_motion::MotionState;
use rtcnc_motion::otg::OnlineAxis;
use rtcnc_rt::{Context, LeadProducer};

use super::{LatchRequest, MotionCore, ServoTarget, Source};
use crate::config::MAX_JOINTS;
use crate::messages::JointSetpoints;
use crate::shared::{Feedback, Shared};

/// One set-point as produced, kept until position control has surely taken it: what a
/// take-back goes back to, and what the status and the sequencer read as the machine now.
#[derive(Debug, Clone, Copy)]
pub(super) struct Produced {
    pub(super) target: ServoTarget,
    /// The planner's state after this set-point.
    pub(super) state: MotionState,
}

/// The set-points produced ahead and what goes with them to position control.
pub(super) struct Output {
    /// The number of the last set-point produced (the exchange it is for).
    pub(super) cycle: u64,
    /// The last set-point produced.
    pub(super) last: JointSetpoints,
    /// Homing offsets: raw joint position = machine position − offset.
    pub(super) offsets: [f64; MAX_JOINTS],
    /// The offsets have been set from the first feedback.
    pub(super) offsets_known: bool,
    /// Latches to arm (homing).
    pub(super) latch: LatchRequest,
    /// To position control.
    queue: LeadProducer<ServoTarget>,
    /// Periods to produce ahead along the path.
    pub(super) lead: u64,
    /// The last produced set-points, by number modulo the length.
    produced: Box<[Produced]>,
    /// The generators of the independent joints after each produced set-point (only when
    /// the machine has such joints), by number modulo the length.
    independent: Box<[[OnlineAxis; MAX_JOINTS]]>,
    /// Interpolation's own run is under way: a change made now acts from the set-point
    /// position control takes next; from another task, from the one after it (as when
    /// every set-point was computed in the period before its exchange).
    pub(super) interpolating: bool,
    /// Set-points taken back and computed again (urgent changes and faults).
    pub(super) taken_back: u64,
    /// The number position control was to take next when interpolation last ran.
    last_consumer: u64,
}

impl Output {
    pub(super) fn new(
        last: JointSetpoints,
        queue: LeadProducer<ServoTarget>,
        lead: u64,
        independent_joints: bool,
        joint_otg: &[OnlineAxis; MAX_JOINTS],
    ) -> Output {
        // Room for the lead, the periods a late run catches up on, and the one position
        // control may be taking while a take-back runs.
        let len = usize::try_from(lead)
            .unwrap_or(usize::MAX)
            .saturating_add(16);
        let first = Produced {
            target: ServoTarget {
                setpoints: last,
                offsets: [0.0; MAX_JOINTS],
                enable: false,
                reset_count: 0,
                latch: LatchRequest::default(),
            },
            state: MotionState::Idle,
        };
        let independent = if independent_joints {
            vec![*joint_otg; len]
        } else {
            Vec::new()
        };
        Output {
            cycle: 0,
            last,
            offsets: [0.0; MAX_JOINTS],
            offsets_known: false,
            latch: LatchRequest::default(),
            queue,
            lead,
            produced: vec![first; len].into_boxed_slice(),
            independent: independent.into_boxed_slice(),
            interpolating: false,
            taken_back: 0,
            last_consumer: 1,
        }
    }

    /// The number of the set-point position control takes next.
    pub(super) fn consumer_next(&self) -> u64 {
        self.queue.consumer_next()
    }

    fn slot(&self, number: u64) -> usize {
        (number % self.produced.len() as u64) as usize
    }

    /// The produced set-point `number` (the last one when it is not produced yet, or no
    /// longer kept).
    pub(super) fn at(&self, number: u64) -> &Produced {
        let number = number.min(self.cycle);
        let oldest = self.cycle.saturating_sub(self.produced.len() as u64 - 1);
        &self.produced[self.slot(number.max(oldest))]
    }

    /// The set-point the machine is at: the one position control applies next.
    pub(super) fn now(&self) -> &Produced {
        self.at(self.consumer_next())
    }
}

impl MotionCore {
    /// One servo period: reacts to stop requests first, then computes the set-points up to
    /// the lead and queues them for position control.
    pub(crate) fn interpolate(&mut self, ctx: &mut Context<'_>, shared: &Shared) {
        self.out.interpolating = true;
        // Exchanges since interpolation's last run: 1, or more after a stall of its thread
        // (the longest is reported; up to the lead it is ridden through).
        let consumer = self.out.consumer_next();
        let gap = consumer.saturating_sub(std::mem::replace(&mut self.out.last_consumer, consumer));
        shared
            .interpolation_gap
            .fetch_max(gap, std::sync::atomic::Ordering::Relaxed);
        // The urgent channel first, all of it, every servo cycle: an e-stop read here stops
        // the set-points from the next exchange on.
        while let Some(u) = shared.urgent.try_get() {
            self.urgent(ctx, shared, u);
        }
        while let Some(fault) = shared.stop_requests.try_get() {
            self.on_fault(shared, fault);
        }
        let feedback = *self.interface.feedback.get();
        if !self.out.offsets_known && feedback.cycle > 0 {
            // Before homing, a joint's machine position is where the kernel believed it
            // was at power-up: the offsets make feedback and set-points agree.
            self.out.offsets_known = true;
            for j in 0..self.machine.joint_count {
                self.out.offsets[j] = self.out.last.joints[j] - feedback.position[j];
            }
        }
        let answers = *self.interface.logic.get();
        self.follow_logic_hold(answers.feed_hold_request);
        self.follow_feed_stop_switch(feedback.digital_inputs);
        self.watch_estop_chain(ctx, shared, answers.estop_chain_ok);
        self.probe_step(&feedback);
        let line = self.out.now().target.setpoints.line;
        self.produce(ctx, shared, &feedback);
        let now_line = self.out.now().target.setpoints.line;
        if now_line != line {
            // The program line in the trace, so a timeline shows which block ran when.
            ctx.mark("line", u64::from(now_line));
        }
        self.follow_surface_speed();
        self.watch_for_stall(ctx, shared);
        self.finish_quick_stop();
        self.publish_requests();
        self.out.interpolating = false;
    }

    /// How far ahead to produce: the lead along the path; one period for the generators
    /// that follow the feedback every period.
    fn production_lead(&self) -> u64 {
        if self.source == Source::Path && self.synced.is_none() {
            self.out.lead
        } else {
            1
        }
    }

    /// Produces the set-points up to the lead ahead of position control, a bounded number
    /// per run (a run after a stall catches up over the next ones).
    fn produce(&mut self, ctx: &mut Context<'_>, shared: &Shared, feedback: &Feedback) {
        let target = self.out.consumer_next() + self.production_lead() - 1;
        let most = self.out.lead + 8;
        let mut steps = 0;
        while self.out.cycle < target && steps < most {
            self.step(feedback);
            let produced = Produced {
                target: ServoTarget {
                    setpoints: self.out.last,
                    offsets: self.out.offsets,
                    enable: self.drives_enabled(),
                    reset_count: self.safety.reset_count,
                    latch: self.out.latch,
                },
                state: self.path.state,
            };
            let slot = self.out.slot(self.out.cycle);
            self.out.produced[slot] = produced;
            if !self.out.independent.is_empty() {
                self.out.independent[slot] = self.manual.joint_otg;
            }
            if self.out.queue.push(produced.target).is_err() {
                // The queue holds the lead and more: full only if position control stopped
                // taking for longer than it is long. The set-point is lost; say so.
                shared.raise(
                    ctx,
                    crate::fault::FaultCode::SetpointsLost,
                    crate::fault::TaskName::Interpolation,
                    None,
                    0,
                    self.out.cycle as f64,
                );
                break;
            }
            steps += 1;
        }
    }

    /// Before a change of the path: takes back the set-points position control has not
    /// taken, from the next one (in interpolation's own run) or the one after it (from
    /// another task), and has the planner go back over them, so that the change acts from
    /// there. Where the planner cannot go back (its history does not reach), the same
    /// set-points are queued again and the change acts after them. Only along the path:
    /// the other generators produce one period ahead.
    pub(super) fn take_back(&mut self) {
        if self.source != Source::Path || self.synced.is_some() {
            return;
        }
        let from = self.out.consumer_next() + u64::from(!self.out.interpolating);
        if self.out.cycle < from {
            return;
        }
        let first_free = self.out.queue.rewind(from);
        let n = (self.out.cycle + 1).saturating_sub(first_free);
        if n == 0 {
            return;
        }
        let back_to = first_free - 1;
        let went_back = usize::try_from(n)
            .ok()
            .is_some_and(|n| self.path.planner.unemit(n).is_ok());
        if went_back {
            self.restore(back_to);
            self.out.taken_back += n;
        } else {
            for number in first_free..=self.out.cycle {
                let target = self.out.at(number).target;
                let _ = self.out.queue.push(target);
            }
        }
    }

    /// Drops the set-points position control has not taken, from the one after its next,
    /// for a caller that puts every generator somewhere new (a reset after the drives were
    /// off): the next produced set-point follows the one position control takes next.
    pub(super) fn discard_ahead(&mut self) {
        let from = self.out.consumer_next() + 1;
        if self.out.cycle < from {
            return;
        }
        let first_free = self.out.queue.rewind(from);
        self.restore(first_free - 1);
    }

    /// The generators' output and the independent joints as after set-point `number`.
    fn restore(&mut self, number: u64) {
        let p = *self.out.at(number);
        self.out.cycle = number;
        self.out.last = p.target.setpoints;
        self.path.state = p.state;
        if !self.out.independent.is_empty() {
            let saved = self.out.independent[self.out.slot(number)];
            for j in 0..self.machine.joint_count {
                if self.machine.joints[j].axis.is_none() {
                    self.manual.joint_otg[j] = saved[j];
                }
            }
        }
    }

    /// Before new moves or a flush go into the planner: when the path stands at its end,
    /// the set-points produced ahead there are taken back, so that the new motion starts
    /// at the next exchange instead of after the lead.
    pub(super) fn before_new_motion(&mut self) {
        if self.path.state == MotionState::Idle && self.path.planner.pieces_ahead() == 0 {
            self.take_back();
        }
    }

    /// One servo period of the set-point generators.
    fn step(&mut self, feedback: &Feedback) {
        self.out.cycle += 1;
        let mut sp = self.out.last;
        sp.cycle = self.out.cycle;
        match self.source {
            Source::Path if self.synced.is_some() => self.synced_step(feedback, &mut sp),
            Source::Path if self.path_frozen() => {
                // Injected: the planner makes no progress, its set-point stands.
                sp.path_speed = 0.0;
                self.path.state = MotionState::Moving;
            }
            Source::Path => {
                let n = self.path.joint_count;
                let status = self.path.planner.next(&mut self.path.buf[..n]);
                for k in 0..n {
                    sp.joints[self.path.joints[k]] = self.path.buf[k];
                }
                sp.axes = status.axes;
                sp.line = status.line;
                sp.path_speed = status.path_speed;
                sp.move_end = self.path.planner.move_end().unwrap_or(status.axes);
                self.path.state = status.state;
                if status.state == MotionState::Idle && self.step_of_program().is_none() {
                    sp.line = 0;
                    sp.move_end = status.axes;
                }
            }
            Source::Manual => {
                self.manual_step(feedback, &mut sp);
                self.homing_step(feedback);
                sp.move_end = sp.axes;
            }
        }
        // Joints on their own generator (homing, independent joints). The axis a homing
        // joint belongs to is where its joint is (the status and the recording show the
        // joint moving, and the hand-over back to the axis has no step).
        for j in 0..self.machine.joint_count {
            if self.manual.joint_manual & (1 << j) != 0 {
                sp.joints[j] = self.manual.joint_otg[j].step(self.machine.period_s).p;
                if let Some(i) = self.machine.joints[j].axis {
                    sp.axes[i] = sp.joints[j];
                }
            }
        }
        if self.source == Source::Manual {
            self.release_stopped_homing_joints(&mut sp);
        }
        self.out.last = sp;
    }
}
