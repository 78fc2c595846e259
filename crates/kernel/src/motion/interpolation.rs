//! Interpolation, once per servo period: the urgent channel and the stop requests first,
//! then what this period's feedback and machine-logic answers change (holds, the e-stop
//! chain, a probe), then the set-point of every joint from the planner or the on-line
//! generators, sent to position control ([`MotionCore::emit`]).

use rtcnc_motion::MotionState;
use rtcnc_rt::{Context, RingProducer};

use super::{LatchRequest, MotionCore, ServoTarget, Source};
use crate::config::MAX_JOINTS;
use crate::messages::JointSetpoints;
use crate::shared::{Feedback, Shared};

/// The set-point of the last period and what goes with it to position control.
#[derive(Debug, Clone, Copy)]
pub(super) struct Output {
    /// Servo periods interpolated so far (the set-point's number).
    pub(super) cycle: u64,
    /// The last set-point.
    pub(super) last: JointSetpoints,
    /// Homing offsets: raw joint position = machine position − offset.
    pub(super) offsets: [f64; MAX_JOINTS],
    /// The offsets have been set from the first feedback.
    pub(super) offsets_known: bool,
    /// Latches to arm (homing).
    pub(super) latch: LatchRequest,
}

impl Output {
    pub(super) fn new(last: JointSetpoints) -> Output {
        Output {
            cycle: 0,
            last,
            offsets: [0.0; MAX_JOINTS],
            offsets_known: false,
            latch: LatchRequest::default(),
        }
    }
}

impl MotionCore {
    /// One servo period: reacts to stop requests first, then computes the set-point of
    /// every joint and sends it to position control.
    pub(crate) fn interpolate(
        &mut self,
        ctx: &mut Context<'_>,
        shared: &Shared,
        out: &mut RingProducer<ServoTarget>,
    ) {
        // The urgent channel first, all of it, every servo cycle: an e-stop read here stops
        // the set-points computed in this very cycle.
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
        // One set-point per exchange with the drives, numbered by the exchange it is for:
        // the one made in period p is applied by position control in period p + 1, after
        // the exchanges of periods up to p, i.e. p + 1 less the periods the fieldbus thread
        // skipped. The number does not depend on whether drive I/O has already done this
        // period's exchange, which on several processors it may or may not have (reading
        // the feedback's exchange count instead made the set-points one period late about
        // every other period at 10 kHz). After a late activation (a real-time overrun) the
        // missed set-points are computed now, at most four; none when interpolation is
        // ahead. It never runs more than one exchange ahead of the feedback: while the
        // fieldbus thread stalls (it woke late on another processor) the machine does not
        // move on, so neither do its set-points.
        let skipped = shared
            .fieldbus_skipped
            .load(std::sync::atomic::Ordering::Relaxed);
        let target = (ctx.activation() + 1)
            .saturating_sub(skipped)
            .min(feedback.cycle + 1);
        let steps = target.saturating_sub(self.out.cycle).min(4);
        let line = self.out.last.line;
        for _ in 0..steps {
            self.step(&feedback);
        }
        if self.out.last.line != line {
            // The program line in the trace, so a timeline shows which block ran when.
            ctx.mark("line", u64::from(self.out.last.line));
        }
        self.follow_surface_speed();
        self.finish_quick_stop();
        self.publish_requests();
        if steps > 0 {
            self.emit(out);
        }
    }

    /// The set-point output: this period's set-point into the set-point channel to
    /// position control.
    fn emit(&self, out: &mut RingProducer<ServoTarget>) {
        let _ = out.push(ServoTarget {
            setpoints: self.out.last,
            offsets: self.out.offsets,
            enable: self.drives_enabled(),
            reset_count: self.safety.reset_count,
            latch: self.out.latch,
        });
    }

    /// One servo period of the set-point generators.
    fn step(&mut self, feedback: &Feedback) {
        self.out.cycle += 1;
        let mut sp = self.out.last;
        sp.cycle = self.out.cycle;
        match self.source {
            Source::Path if self.synced.is_some() => self.synced_step(feedback, &mut sp),
            Source::Path => {
                let n = self.path.joint_count;
                let status = self.path.planner.next(&mut self.path.buf[..n]);
                for k in 0..n {
                    sp.joints[self.path.joints[k]] = self.path.buf[k];
                }
                sp.axes = status.axes;
                sp.line = status.line;
                sp.path_speed = status.path_speed;
                self.path.state = status.state;
                if status.state == MotionState::Idle && self.step_of_program().is_none() {
                    sp.line = 0;
                }
            }
            Source::Manual => {
                self.manual_step(feedback, &mut sp);
                self.homing_step(feedback);
            }
        }
        // Joints on their own generator (homing, independent joints).
        for j in 0..self.machine.joint_count {
            if self.manual.joint_manual & (1 << j) != 0 {
                sp.joints[j] = self.manual.joint_otg[j].step(self.machine.period_s).p;
            }
        }
        if self.source == Source::Manual {
            self.release_stopped_homing_joints(&mut sp);
        }
        self.out.last = sp;
    }
}
