//! The stall watchdog: a program's path that stands still while it should move (the
//! planner moving or with moves queued, speed zero, no hold, no dwell, overrides above
//! zero), or a program whose next block cannot be handed on while the planner stands
//! empty and nothing holds it, for longer than `safety.stall_timeout` stops the program
//! with `kernel.motion_stalled` at its line, instead of waiting for ever. The machine
//! stands, so the planner is put at rest where it is.

use rtcnc_motion::MotionState;
use rtcnc_rt::Context;

use super::state::State;
use super::{MotionCore, Source};
use crate::fault::{FaultCode, TaskName};
use crate::shared::Shared;

/// The watchdog's count and limit.
#[derive(Debug, Clone, Copy)]
pub(super) struct StallWatch {
    /// Periods a stall is allowed.
    pub(super) limit: u64,
    /// Periods the path has stood still while it should move.
    pub(super) still: u64,
    /// Fault injection: the planner makes no progress from this set-point number on.
    pub(super) freeze_from: Option<u64>,
    /// Fault injection: the planner takes no move of a program.
    pub(super) refuse_moves: bool,
}

impl StallWatch {
    pub(super) fn new(limit: u64) -> StallWatch {
        StallWatch {
            limit,
            still: 0,
            freeze_from: None,
            refuse_moves: false,
        }
    }
}

impl MotionCore {
    /// Whether the path should be moving now (at the set-point position control applies
    /// next): a program runs on the planner, nothing holds it, it is neither dwelling nor
    /// holding, and the overrides in force let it move.
    fn path_should_move(&self) -> bool {
        let now = self.out.now();
        let running = self.source == Source::Path
            && self.synced.is_none()
            && matches!(self.state, State::Program(_));
        let held = self.hold.latched() || self.hold.feed_stop || self.hold.logic_request;
        let (feed, rapid) = self.effective_feed_overrides();
        let planner_wants = now.state == MotionState::Moving
            || (now.state == MotionState::Idle && self.path.planner.pieces_ahead() > 0);
        running && !held && feed > 0.0 && rapid > 0.0 && planner_wants
    }

    /// The line of a program's block that waits to be handed on while the planner stands
    /// empty at rest and nothing holds it (the sequencer cannot go on: a run from a line
    /// whose approach the planner kept refusing stood so for ever).
    fn block_stuck(&self) -> Option<u32> {
        let now = self.out.now();
        let running = self.source == Source::Path
            && self.synced.is_none()
            && matches!(self.state, State::Program(_));
        let held = self.hold.latched() || self.hold.feed_stop || self.hold.logic_request;
        let planner_empty = now.state == MotionState::Idle && self.path.planner.pieces_ahead() == 0;
        match &self.program.pending {
            Some(block) if running && !held && planner_empty => Some(block.line()),
            _ => None,
        }
    }

    /// Once a period (interpolation): counts the periods the path stands still while it
    /// should move, or a block waits that nothing keeps from going on, and stops the
    /// program when they exceed the limit.
    pub(super) fn watch_for_stall(&mut self, ctx: &mut Context<'_>, shared: &Shared) {
        let now = *self.out.now();
        let stuck = self.block_stuck();
        if (self.path_should_move() || stuck.is_some()) && now.target.setpoints.path_speed == 0.0 {
            self.stall.still += 1;
        } else {
            self.stall.still = 0;
        }
        if self.stall.still <= self.stall.limit {
            return;
        }
        self.stall.still = 0;
        let line = stuck.unwrap_or(now.target.setpoints.line);
        let seconds = self.stall.limit as f64 * self.machine.period_s;
        shared.raise(
            ctx,
            FaultCode::MotionStalled,
            TaskName::Interpolation,
            None,
            line,
            seconds,
        );
        *shared.error_text.lock() = Some(format!(
            "line {line}: the path stood still for {seconds} s while it should move (the stall watchdog, safety.stall_timeout)"
        ));
        self.abort(shared);
        // The planner does not move on by itself: at rest where the machine stands.
        self.discard_ahead();
        let _ = self.path.planner.reset_at(self.out.last.axes);
        self.path.state = MotionState::Idle;
        self.stall.freeze_from = None;
    }

    /// Fault injection for the watchdog's test: the planner is frozen from this set-point
    /// number on.
    pub(crate) fn freeze_path_from(&mut self, number: Option<u64>) {
        self.stall.freeze_from = number;
    }

    /// Fault injection for the watchdog's test: the planner takes no move of a program.
    pub(crate) fn refuse_moves(&mut self, refuse: bool) {
        self.stall.refuse_moves = refuse;
    }

    /// The injected freeze is in force for the set-point being produced.
    pub(super) fn path_frozen(&self) -> bool {
        self.stall
            .freeze_from
            .is_some_and(|from| self.out.cycle >= from)
    }
}
