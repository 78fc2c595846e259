//! The operator's commands: the urgent ones (read by interpolation first thing every
//! period) and the normal ones (command parsing), each handed to the part that carries it
//! out. A command refused in the present state raises `kernel.command_refused`.

use rtcnc_rt::Context;

use super::state::{Event, State, Step};
use super::{MotionCore, Source};
use crate::fault::{FaultCode, TaskName};
use crate::messages::{Command, Mode, Urgent};
use crate::shared::{InterpreterRequest, Shared};

impl MotionCore {
    /// An urgent command (e-stop, hold, resume, abort, overrides).
    pub(super) fn urgent(&mut self, ctx: &mut Context<'_>, shared: &Shared, command: Urgent) {
        match command {
            Urgent::EStop => {
                shared.raise(ctx, FaultCode::EStop, TaskName::Interpolation, None, 0, 0.0);
            }
            Urgent::FeedHold => self.hold(),
            Urgent::Resume => self.resume(),
            Urgent::Abort => self.abort(shared),
            Urgent::FeedOverride(f) => self.set_feed_override(f),
            Urgent::RapidOverride(f) => self.set_rapid_override(f),
            Urgent::SpindleOverride(f) => self.set_spindle_override(f),
        }
    }

    /// A normal command. Returns false when it was refused in this state.
    pub(crate) fn command(
        &mut self,
        ctx: &mut Context<'_>,
        shared: &Shared,
        command: Command,
    ) -> bool {
        let ok = self.command_inner(shared, command);
        if !ok {
            shared.raise(
                ctx,
                FaultCode::CommandRefused,
                TaskName::CommandParsing,
                None,
                0,
                0.0,
            );
        }
        self.publish_requests();
        ok
    }

    fn command_inner(&mut self, shared: &Shared, command: Command) -> bool {
        // A latched feed hold refuses whatever would start motion (a program, an MDI
        // line, a jog, homing) until the operator resumes.
        let idle = self.state == State::Idle && !self.hold.held && !self.moving();
        match command {
            Command::Reset => self.reset(),
            Command::Start { from_line } => {
                if idle && self.program.loaded {
                    self.begin_run(shared, Mode::Auto, from_line, |epoch| {
                        InterpreterRequest::Run { epoch }
                    })
                } else if matches!(self.step_of_program(), Some(Step::Paused { .. })) {
                    self.program.start_count = self.program.start_count.wrapping_add(1);
                    true
                } else {
                    false
                }
            }
            Command::Mdi(line) => {
                idle && self.begin_run(shared, Mode::Mdi, 0, |epoch| InterpreterRequest::Mdi {
                    epoch,
                    line,
                })
            }
            Command::JogContinuous { axis, velocity } => {
                idle && self.jog_continuous(usize::from(axis), velocity)
            }
            Command::JogIncrement { axis, distance } => {
                idle && self.jog_increment(usize::from(axis), distance)
            }
            Command::JogStop { axis } => self.jog_stop(usize::from(axis)),
            Command::Handwheel { axis: None, .. } => {
                self.manual.handwheel = None;
                true
            }
            Command::Handwheel {
                axis: Some(axis),
                scale,
            } => idle && self.select_handwheel(usize::from(axis), scale),
            Command::HomeAll => idle && self.home_all(),
            Command::HomeAxis { axis } => idle && self.home_axis(usize::from(axis)),
            Command::SetMode(mode) => idle && self.set_mode(mode),
            Command::JointMove { joint, position } => self.joint_move(usize::from(joint), position),
            Command::SingleBlock(on) => {
                self.program.single_block = on;
                true
            }
            Command::OptionalStop(on) => {
                self.program.optional_stop = on;
                true
            }
            Command::BlockDelete(on) => shared
                .interpreter_requests
                .try_put(InterpreterRequest::BlockDelete(on))
                .is_ok(),
        }
    }

    /// Starts a program run or an MDI line once the interpreter has its request (`request`
    /// of the run's epoch). A full request mailbox (a burst of aborts the interpreter has
    /// not read yet) refuses the command: the run would wait for ever for a request that
    /// was dropped.
    fn begin_run(
        &mut self,
        shared: &Shared,
        mode: Mode,
        from_line: u32,
        request: impl FnOnce(u32) -> InterpreterRequest,
    ) -> bool {
        // `begin` opens the run's epoch: the next one.
        let epoch = self.program.epoch.wrapping_add(1);
        if shared.interpreter_requests.try_put(request(epoch)).is_err() {
            return false;
        }
        self.begin(mode, from_line);
        debug_assert_eq!(self.program.epoch, epoch);
        shared.interpreter_wake.signal();
        true
    }

    /// Stops the program, MDI line, homing or jog: the path decelerates along itself, what
    /// is queued is dropped, the interpreter stops reading.
    pub(super) fn abort(&mut self, shared: &Shared) {
        // An e-stop's or fault's quick stop is under way and has stopped the run already:
        // an abort's gentler stop must not replace it (it took back the quick stop's
        // set-points and left the path braking beyond the limits).
        if self.state == State::Stopping {
            return;
        }
        self.probe = None;
        self.out.latch.probe = 0;
        self.disarm_homing_latches();
        // Whatever stops, stops from the next exchange.
        self.take_back();
        self.stop_synced(false);
        // Output changes of motion that will not run are dropped.
        self.outputs.drop_pending();
        // A stopped program leaves no override disabled behind (M49, M50 P0, M53 P0).
        self.reset_enables();
        self.program.epoch = self.program.epoch.wrapping_add(1);
        let _ = shared
            .interpreter_requests
            .try_put(InterpreterRequest::Stop);
        shared.interpreter_wake.signal();
        self.program.pending = None;
        self.program.tcp = None;
        self.synced_chain.clear();
        self.fire(Event::Abort);
        self.hold.held = false;
        self.hold.logic_paused = false;
        match self.source {
            Source::Path => self.path.planner.abort(),
            Source::Manual => self.stop_manual(false),
        }
        let mi = self.requests_mut();
        mi.tool_change_request = false;
        mi.m_code_request = false;
        mi.program_running = false;
    }
}
