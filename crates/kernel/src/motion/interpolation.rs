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
//! next exchange as if every set-point had been computed just in time.
//!
//! Jog, handwheel, homing and spindle-synchronised moves (the on-line generators) have the
//! same lead. What they decide on the feedback (a home switch, a latch, the handwheel's
//! counts, the spindle's angle) is decided in the set-point for the next exchange only:
//! in every period that brings such a decision, the set-points after it are taken back
//! and computed again from the new feedback. The set-points beyond it go on with what the
//! generators do by themselves (a jog, a search, a homing stop, a thread pass with the
//! spindle turning on at the speed it had), so that a stall is ridden through; a decision
//! due meanwhile waits for the next run (a homing phase that ended stands until then).
//! A decision or a command changes the generators from one set-point on (the floor): no
//! take-back goes back before it, so that what is taken back is only the generators'
//! clocks (and a synchronised move's state), saved with every set-point.

use rtcnc_motion::otg::OnlineAxis;
use rtcnc_motion::{AXES, MotionState};
use rtcnc_rt::{Context, LeadProducer};

use super::state::State;
use super::synced::SyncedMove;
use super::{DriveEnable, LatchRequest, MotionCore, ServoTarget, Source};
use crate::config::MAX_JOINTS;
use crate::messages::JointSetpoints;
use crate::shared::{Feedback, Shared};

/// One set-point as produced, kept until position control has surely taken it: what a
/// take-back goes back to, and what the status and the sequencer read as the machine now.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Produced {
    pub(super) target: ServoTarget,
    /// The planner's state after this set-point; with the on-line generators, `Moving`
    /// while one of them still moves after it.
    pub(super) state: MotionState,
    /// Program output changes applied up to this set-point (its `target.outputs`).
    pub(super) outputs_applied: u64,
}

/// The on-line generators as after one set-point, to go back to: with the floor, no
/// target of theirs changes after it, so their clocks are all that differs.
#[derive(Debug, Clone, Copy)]
struct Generators {
    axes: [f64; AXES],
    joints: [f64; MAX_JOINTS],
    synced: Option<SyncedMove>,
}

/// Everything the on-line generators' decisions may change, with the last set-point: kept
/// while a decision is computed again over set-points already produced, so that when it
/// changes nothing (homing between its switches, a thread pass on a steady spindle) those
/// set-points stand instead of being computed again.
#[derive(Clone, Copy)]
struct Decisions {
    state: State,
    hold: super::hold::Hold,
    axis_otg: [OnlineAxis; AXES],
    joint_otg: [OnlineAxis; MAX_JOINTS],
    joint_manual: u32,
    handwheel: Option<(usize, f64)>,
    handwheel_counts: Option<i64>,
    synced: Option<SyncedMove>,
    latch: LatchRequest,
    offsets: [f64; MAX_JOINTS],
    homed: u32,
    last: JointSetpoints,
    cycle: u64,
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
    /// The on-line generators after each set-point they produced, by number modulo the
    /// length (saved before the next one is produced, so with the changes made between).
    generators: Box<[Generators]>,
    /// The on-line generators' decisions and the commands that change them act from the
    /// set-point after this one on: no take-back goes before it.
    pub(super) floor: u64,
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
                enable: DriveEnable::Off,
                reset_count: 0,
                latch: LatchRequest::default(),
                outputs: super::ProgramOutputs::default(),
            },
            state: MotionState::Idle,
            outputs_applied: 0,
        };
        let independent = if independent_joints {
            vec![*joint_otg; len]
        } else {
            Vec::new()
        };
        let generators = Generators {
            axes: [0.0; AXES],
            joints: [0.0; MAX_JOINTS],
            synced: None,
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
            generators: vec![generators; len].into_boxed_slice(),
            floor: 0,
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

    /// Sets the drives' enable of the set-points produced ahead that position control has
    /// not taken (from the one it takes next while interpolation runs, else the one after
    /// it): a change of the drives' state acts from the next exchange, not a lead later.
    pub(super) fn set_enable_ahead(&mut self, enable: DriveEnable) {
        let from = self.consumer_next() + u64::from(!self.interpolating);
        if self.cycle < from {
            return;
        }
        let first_free = self.queue.rewind(from);
        for number in first_free..=self.cycle {
            let slot = self.slot(number);
            self.produced[slot].target.enable = enable;
            let _ = self.queue.push(self.produced[slot].target);
        }
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
        let (feed_hold_request, estop_chain_ok) = {
            let answers = self.interface.logic.get();
            (answers.feed_hold_request, answers.estop_chain_ok)
        };
        self.follow_logic_hold(feed_hold_request);
        self.follow_feed_stop_switch(feedback.digital_inputs);
        self.watch_estop_chain(ctx, shared, estop_chain_ok);
        self.probe_step(&feedback);
        self.adaptive_feed_step();
        self.spindle_feed_step(false);
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

    /// Whether the set-points are the on-line generators' (jog, handwheel, homing, a
    /// spindle-synchronised move) rather than the planner's.
    fn generators_lead(&self) -> bool {
        self.source == Source::Manual || self.synced.is_some()
    }

    /// Whether the on-line generators may decide something on this period's feedback: a
    /// homing sequence, a handwheel whose counter moved, homing joints still to hand back
    /// to their axis, a synchronised move (it follows the spindle's angle).
    fn decisions_due(&self, feedback: &Feedback) -> bool {
        match self.source {
            Source::Path => self.synced.is_some(),
            Source::Manual => {
                let axis_joints_taken = (0..self.machine.joint_count).any(|j| {
                    self.machine.joints[j].axis.is_some()
                        && self.manual.joint_manual & (1 << j) != 0
                });
                matches!(self.state, State::Homing(_))
                    || axis_joints_taken
                    || (self.manual.handwheel.is_some()
                        && self.manual.handwheel_counts != Some(feedback.handwheel_counts))
            }
        }
    }

    /// Produces the set-points up to the lead ahead of position control, a bounded number
    /// per run (a run after a stall catches up over the next ones). When the on-line
    /// generators have something to decide, the first produced decides, in place of the
    /// one position control takes next and those after it.
    fn produce(&mut self, ctx: &mut Context<'_>, shared: &Shared, feedback: &Feedback) {
        let mut decide = self.decisions_due(feedback);
        let mut replace_from = None;
        let mut before_decision = None;
        if decide {
            let from = self.out.consumer_next().max(self.out.floor + 1);
            if self.out.cycle >= from {
                // The generators go back now; the queue only once the set-point that
                // replaces the first is computed, so that position control, taking it on
                // another processor meanwhile, still finds one.
                replace_from = Some((from, self.out.cycle));
                if from < self.out.cycle {
                    before_decision = Some(self.decisions());
                }
                self.restore(from - 1);
            }
        }
        let target = self.out.consumer_next() + self.out.lead - 1;
        let most = self.out.lead + 8;
        let mut steps = 0;
        while self.out.cycle < target && steps < most {
            let generators = self.generators_lead();
            if generators {
                self.save_generators();
            }
            self.step(feedback, decide);
            if decide {
                self.out.floor = self.out.cycle;
                decide = false;
            }
            let state = if generators && self.source == Source::Manual {
                if self.manual_moving() {
                    MotionState::Moving
                } else {
                    MotionState::Idle
                }
            } else {
                self.path.state
            };
            let produced = Produced {
                target: ServoTarget {
                    setpoints: self.out.last,
                    offsets: self.out.offsets,
                    enable: self.drive_enable(),
                    reset_count: self.safety.reset_count,
                    latch: self.out.latch,
                    outputs: self.outputs.state,
                },
                state,
                outputs_applied: self.outputs.applied,
            };
            let mut taken_meanwhile = false;
            if let Some((from, latest)) = replace_from.take() {
                if let Some(latest_decisions) = before_decision.take()
                    && self.decided_as_before(&latest_decisions, from, &produced)
                {
                    // The set-points after it are those already queued: they stand.
                    self.put_back(&latest_decisions);
                    steps += 1;
                    continue;
                }
                let first_free = self.out.queue.rewind(from);
                self.out.taken_back += (latest + 1).saturating_sub(first_free);
                // Position control took the one computed before: the decision acts from
                // the next exchange (off by what it changed in one period).
                taken_meanwhile = first_free > from;
            }
            let slot = self.out.slot(self.out.cycle);
            self.out.produced[slot] = produced;
            if !self.out.independent.is_empty() {
                self.out.independent[slot] = self.manual.joint_otg;
            }
            if taken_meanwhile {
                steps += 1;
                continue;
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

    /// What the on-line generators' decisions may change, as it is now.
    fn decisions(&self) -> Decisions {
        Decisions {
            state: self.state,
            hold: self.hold,
            axis_otg: self.manual.axis_otg,
            joint_otg: self.manual.joint_otg,
            joint_manual: self.manual.joint_manual,
            handwheel: self.manual.handwheel,
            handwheel_counts: self.manual.handwheel_counts,
            synced: self.synced,
            latch: self.out.latch,
            offsets: self.out.offsets,
            homed: self.homed,
            last: self.out.last,
            cycle: self.out.cycle,
        }
    }

    /// Whether the decision just computed again for set-point `from` (giving `produced`)
    /// left everything as the set-points after it were computed with (`latest`: as after
    /// the last of them): then computing them again would give them again. Between `from`
    /// and the latest no target changed (the floor), so the generators' clocks and a
    /// synchronised move's state are all that differs, saved with `from`.
    fn decided_as_before(&self, latest: &Decisions, from: u64, produced: &Produced) -> bool {
        if *produced != *self.out.at(from) {
            return false;
        }
        let saved = &self.out.generators[self.out.slot(from)];
        let same_generator = |then: &OnlineAxis, time: f64, now: &OnlineAxis| {
            let mut then = *then;
            then.set_time(time);
            then == *now
        };
        let joints = self.machine.joint_count;
        (0..AXES)
            .all(|i| same_generator(&latest.axis_otg[i], saved.axes[i], &self.manual.axis_otg[i]))
            && (0..joints).all(|j| {
                same_generator(
                    &latest.joint_otg[j],
                    saved.joints[j],
                    &self.manual.joint_otg[j],
                )
            })
            && latest.joint_otg[joints..] == self.manual.joint_otg[joints..]
            && (latest.synced.is_none() || saved.synced == self.synced)
            && latest.synced.is_some() == self.synced.is_some()
            && latest.state == self.state
            && latest.hold == self.hold
            && latest.joint_manual == self.manual.joint_manual
            && latest.handwheel == self.manual.handwheel
            && latest.handwheel_counts == self.manual.handwheel_counts
            && latest.latch == self.out.latch
            && latest.offsets == self.out.offsets
            && latest.homed == self.homed
    }

    /// Puts the on-line generators back as after the latest set-point produced.
    fn put_back(&mut self, latest: &Decisions) {
        self.manual.axis_otg = latest.axis_otg;
        self.manual.joint_otg = latest.joint_otg;
        self.synced = latest.synced;
        self.out.last = latest.last;
        self.out.cycle = latest.cycle;
    }

    /// Saves the on-line generators as after the last produced set-point.
    fn save_generators(&mut self) {
        let slot = self.out.slot(self.out.cycle);
        let g = &mut self.out.generators[slot];
        for i in 0..AXES {
            g.axes[i] = self.manual.axis_otg[i].time();
        }
        for j in 0..self.machine.joint_count {
            g.joints[j] = self.manual.joint_otg[j].time();
        }
        g.synced = self.synced;
    }

    /// Before a change of the path or of the on-line generators: takes back the
    /// set-points position control has not taken, from the next one (in interpolation's
    /// own run) or the one after it (from another task), so that the change acts from
    /// there. The planner goes back over them; where it cannot (its history does not
    /// reach), the same set-points are queued again and the change acts after them. The
    /// on-line generators go back to their saved state, never before their floor.
    pub(super) fn take_back(&mut self) {
        let from = self.out.consumer_next() + u64::from(!self.out.interpolating);
        if self.generators_lead() {
            self.take_back_generators(from);
            return;
        }
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

    /// Takes back the on-line generators' set-points from `from` (not before the floor)
    /// and puts the generators as after the last one kept; a change made now acts from
    /// the next one produced, which becomes the floor.
    fn take_back_generators(&mut self, from: u64) {
        let from = from.max(self.out.floor + 1);
        if self.out.cycle < from {
            self.out.floor = self.out.floor.max(self.out.cycle);
            return;
        }
        let first_free = self.out.queue.rewind(from);
        self.out.taken_back += (self.out.cycle + 1).saturating_sub(first_free);
        self.restore(first_free - 1);
    }

    /// Drops the set-points position control has not taken, from the one after its next,
    /// for a caller that puts every generator somewhere new (a reset after the drives were
    /// off): the next produced set-point follows the one position control takes next.
    pub(super) fn discard_ahead(&mut self) {
        let from = self.out.consumer_next() + 1;
        if self.generators_lead() {
            self.take_back_generators(from);
            return;
        }
        if self.out.cycle < from {
            self.out.floor = self.out.floor.max(self.out.cycle);
            return;
        }
        let first_free = self.out.queue.rewind(from);
        self.restore(first_free - 1);
    }

    /// The generators' output and the independent joints as after set-point `number`.
    fn restore(&mut self, number: u64) {
        let p = *self.out.at(number);
        let latest = std::mem::replace(&mut self.out.cycle, number);
        self.out.last = p.target.setpoints;
        self.outputs.restore(p.target.outputs, p.outputs_applied);
        self.out.floor = self.out.floor.max(number);
        if self.generators_lead() {
            if number < latest {
                let saved = self.out.generators[self.out.slot(number)];
                for i in 0..AXES {
                    self.manual.axis_otg[i].set_time(saved.axes[i]);
                }
                for j in 0..self.machine.joint_count {
                    self.manual.joint_otg[j].set_time(saved.joints[j]);
                }
                if self.synced.is_some() {
                    self.synced = saved.synced;
                }
            }
            return;
        }
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

    /// One servo period of the set-point generators; `decide`: the on-line generators
    /// decide on the feedback (only in the set-point for the next exchange).
    fn step(&mut self, feedback: &Feedback, decide: bool) {
        self.out.cycle += 1;
        let mut sp = self.out.last;
        sp.cycle = self.out.cycle;
        let mut on_piece = None;
        match self.source {
            Source::Path if self.synced.is_some() => self.synced_step(feedback, &mut sp, decide),
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
                on_piece = self.path.planner.emitted_piece();
            }
            Source::Manual => {
                if decide {
                    self.handwheel_step(feedback);
                }
                self.manual_step(&mut sp);
                if decide {
                    self.homing_step(feedback);
                }
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
        if self.source == Source::Manual && decide {
            self.release_stopped_homing_joints(&mut sp);
        }
        // The output changes due at this set-point: on the planner's path those armed on
        // its piece too, elsewhere the immediate ones only.
        self.outputs.advance(sp.cycle, on_piece);
        self.out.last = sp;
    }
}
