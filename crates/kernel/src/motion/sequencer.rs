//! The program sequencer (the look-ahead task's part): moves the blocks of a program or
//! MDI line into the planner's window while it has room, flushes the window before what
//! needs the machine standing (a machine function, a spindle-synchronised or probing move,
//! the end, an error), waits for the path to stand, and then starts that.

use rtcnc_motion::{
    AXES, Feed, FiveAxisKinematics, MotionError, Move, MoveKind, PathMode, Preparation,
    PreparedMove, TcpMove, TipPath,
};
use rtcnc_rt::Context;

use super::MotionCore;
use super::state::{Event, State, Step, Then};
use crate::fault::{FaultCode, TaskName};
use crate::messages::{MachineBlock, MachineResult, Mode, OperatorMessage};
use crate::shared::{InterpreterRequest, Shared, Tagged};

/// Steps (blocks taken, program steps passed) of one look-ahead run at most, so a run is
/// bounded.
const LOOK_AHEAD_STEPS: usize = 64;

/// The program run.
#[derive(Debug, Clone, Copy)]
pub(super) struct Program {
    /// The run (program start, MDI line, abort, fault): blocks of an older run still in
    /// the channels are dropped.
    pub(super) epoch: u32,
    /// The block the planner had no room for, or whose move is being built apart.
    pub(super) pending: Option<MachineBlock>,
    /// Blocks taken from the channel so far: the number of the latest, which its move is
    /// built apart under (`PreparedMove`).
    pub(super) blocks_taken: u64,
    /// Starts and resumes so far: a pause ends when it changes.
    pub(super) start_count: u32,
    pub(super) single_block: bool,
    pub(super) optional_stop: bool,
    /// Run from a line: the first line whose motion runs.
    pub(super) run_from_line: u32,
    /// Run from a line: where the skipped motion ended (the machine goes there at rapid).
    pub(super) skipped_to: Option<[f64; AXES]>,
    /// The program reached its end.
    pub(super) ended: bool,
    /// The run has taken its first block: before, the machine logic's hold request holds
    /// it only while it stands (the operator started it as the door opened: it goes on
    /// when the door is closed, whether the request rose just before or just after the
    /// start).
    pub(super) took_a_block: bool,
    /// A program is loaded (auto mode can start).
    pub(super) loaded: bool,
    /// Interpolation cycle in which the last machine function started.
    pub(super) aux_cycle: u64,
    /// Interpolation cycle of the last orientation command.
    pub(super) orient_cycle: u64,
    /// The machine's five-axis kinematics (a table or a head) and its TCP tolerance (mm).
    pub(super) five_axis: Option<(FiveAxisKinematics, f64)>,
    /// The tool-centre-point line being cut into chords.
    pub(super) tcp: Option<TcpRun>,
}

/// The share of the TCP tolerance the chords take; their blending takes the rest.
const CHORD_SHARE: f64 = 0.25;

/// A tool-centre-point line on its way into the planner, chord by chord.
#[derive(Debug, Clone, Copy)]
pub(super) struct TcpRun {
    chords: TcpMove,
    rapid: bool,
    /// Between chords: blended within half the TCP tolerance (in joint space).
    inner: PathMode,
    /// At the line's end: the program's mode, its tolerance in joint space.
    last: PathMode,
    line: u32,
}

impl Program {
    pub(super) fn new() -> Program {
        Program {
            epoch: 0,
            pending: None,
            blocks_taken: 0,
            start_count: 0,
            single_block: false,
            optional_stop: false,
            run_from_line: 0,
            skipped_to: None,
            ended: false,
            took_a_block: false,
            loaded: false,
            aux_cycle: 0,
            orient_cycle: 0,
            five_axis: None,
            tcp: None,
        }
    }

    pub(super) fn with_five_axis_kinematics(
        mut self,
        five_axis: Option<FiveAxisKinematics>,
        tolerance: f64,
    ) -> Program {
        self.five_axis = five_axis.map(|t| (t, tolerance));
        self
    }
}

impl MotionCore {
    /// One run of the look-ahead: moves blocks into the planner's window while it has room,
    /// stops the path before machine functions and errors, and sequences their hand-shakes.
    /// Returns whether another run in the same period may find more to do: only when this
    /// one stopped at its bound of steps. Otherwise it stopped on something only another
    /// task can change (no block, no room, the machine still moving, the logic's answer),
    /// or on a move to build: a move's geometry (blends, smoothing) is built in `staging`
    /// by the caller without the core's lock (`PreparedMove::build`, then
    /// `staging.build_due()` is false), and appended by the next run; interpolation waits
    /// on the lock only for the copy and the append.
    pub(crate) fn look_ahead(
        &mut self,
        ctx: &mut Context<'_>,
        shared: &Shared,
        staging: &mut PreparedMove,
    ) -> bool {
        let more = self.look_ahead_runs(ctx, shared, staging);
        self.publish_requests();
        more
    }

    fn look_ahead_runs(
        &mut self,
        ctx: &mut Context<'_>,
        shared: &Shared,
        staging: &mut PreparedMove,
    ) -> bool {
        for _ in 0..LOOK_AHEAD_STEPS {
            // One handler per step of the program; each returns whether the program moved
            // on (look again) or waits for something only another task can change.
            let State::Program(step) = self.state else {
                return false;
            };
            let moved_on = match step {
                Step::Feeding => self.feeding(shared, staging),
                Step::Draining { then, line } => self.draining(ctx, shared, then, line),
                Step::Logic { aux, released, .. } => self.logic_done(aux, released),
                Step::Paused { start_count } => self.paused(start_count),
                Step::Synced => self.synced_done(),
                Step::Probing { kind, line } => self.probing_done(shared, kind, line),
                Step::WaitOrient { deadline, line } => self.waiting_for_orient(deadline, line),
                Step::WaitInput {
                    bit,
                    condition,
                    deadline,
                    previous,
                } => self.waiting_for_input(shared, bit, condition, deadline, previous),
            };
            if !moved_on {
                return false;
            }
        }
        true
    }

    /// Starts a program (auto) or an MDI line from where the machine stands.
    pub(super) fn begin(&mut self, mode: Mode, from_line: u32) {
        self.enter_path();
        if mode == Mode::Auto {
            self.reset_enables();
            self.spindle.css = None;
        }
        self.mode = mode;
        self.program.epoch = self.program.epoch.wrapping_add(1);
        self.fire(Event::Begin);
        self.hold.logic_paused = false;
        self.program.pending = None;
        self.program.tcp = None;
        self.synced_chain.clear();
        self.program.ended = false;
        self.program.took_a_block = false;
        self.program.run_from_line = from_line;
        self.program.skipped_to = None;
        self.outputs.drop_pending();
        self.requests_mut().program_running = mode == Mode::Auto;
    }

    /// Takes the next block of this run, unless a hold keeps the next move from starting.
    fn feeding(&mut self, shared: &Shared, staging: &mut PreparedMove) -> bool {
        if self.hold.latched()
            || ((self.hold.logic_request || self.hold.feed_stop) && !self.moving())
        {
            return false;
        }
        let block = match self.program.pending.take() {
            Some(b) => b,
            None if self.program.tcp.is_some() => match self.next_chord() {
                Ok(Some(chord)) => {
                    // Each chord is a move of its own for the staging's key.
                    self.program.blocks_taken += 1;
                    MachineBlock::Motion(chord)
                }
                Ok(None) => return true,
                Err(e) => {
                    self.program.tcp = None;
                    self.path.planner.flush();
                    self.fire(Event::Fail {
                        code: FaultCode::MotionError,
                        line: e.line().unwrap_or(0),
                        value: 0.0,
                    });
                    *shared.motion_error.lock() = Some(e);
                    return true;
                }
            },
            None => match shared.machine_blocks.try_get() {
                Some(Tagged { epoch, block }) if epoch == self.program.epoch => {
                    self.program.blocks_taken += 1;
                    block
                }
                // A block of an older run: dropped.
                Some(_) => return true,
                None => return false,
            },
        };
        self.program.took_a_block = true;
        self.feed(shared, block, staging)
    }

    /// Returns false when the block could not be taken now (kept for the next run).
    fn feed(&mut self, shared: &Shared, block: MachineBlock, staging: &mut PreparedMove) -> bool {
        let (then, line) = match block {
            MachineBlock::Motion(mv) => return self.feed_move(shared, block, mv, staging),
            MachineBlock::TcpMove {
                line,
                path,
                end,
                rapid,
                feed,
                mode,
                tool_offset,
            } => match self.start_tcp_move(line, path, &end, rapid, feed, mode, tool_offset) {
                Ok(()) => return true,
                Err(e) => {
                    self.before_new_motion();
                    self.path.planner.flush();
                    *shared.motion_error.lock() = Some(e);
                    (Then::Error(FaultCode::MotionError, 0.0), line)
                }
            },
            // M62/M63/M67: the path goes on; the change waits for the next move.
            MachineBlock::Aux { aux, .. }
                if self
                    .synchronized_change(aux)
                    .is_some_and(|c| self.outputs.stage(c)) =>
            {
                return true;
            }
            MachineBlock::Aux { line, aux } => (Then::Aux(aux), line),
            // A chained line waits in the chain for the last one, which starts them all.
            MachineBlock::Synced {
                line,
                end,
                pitch,
                chained: true,
                ..
            } => {
                if self.chain_synced(end, pitch, line) {
                    return true;
                }
                (Then::Error(FaultCode::SyncFailed, 0.0), line)
            }
            MachineBlock::Synced {
                line,
                end,
                pitch,
                tap,
                chained: false,
            } => (Then::Synced(end, pitch, tap), line),
            MachineBlock::Probe { mv, kind } => (Then::Probe(mv, kind), mv.line),
            MachineBlock::End { line } => (Then::End, line),
            MachineBlock::Error { line, code } => (Then::Error(code, 0.0), line),
            MachineBlock::MdiDone => (Then::MdiDone, 0),
        };
        self.before_new_motion();
        self.path.planner.flush();
        self.fire(Event::Drain { then, line });
        true
    }

    /// A move into the planner's window (`block` is `mv`, kept when there is no room or
    /// while its geometry is built apart, in `staging`).
    fn feed_move(
        &mut self,
        shared: &Shared,
        block: MachineBlock,
        mv: Move,
        staging: &mut PreparedMove,
    ) -> bool {
        if self.program.run_from_line > 1 && mv.line < self.program.run_from_line {
            if let MoveKind::Line { end, .. }
            | MoveKind::Arc { end, .. }
            | MoveKind::Spline { end, .. } = mv.kind
            {
                self.program.skipped_to = Some(end);
            }
            return true;
        }
        if self.stall.refuse_moves {
            self.program.pending = Some(block);
            return false;
        }
        let mut mv = mv;
        let arms_outputs = self.outputs.staged() > 0 && !matches!(mv.kind, MoveKind::Dwell { .. });
        if arms_outputs {
            if !self
                .outputs
                .has_room(self.outputs.staged(), self.outputs_oldest_applied())
            {
                // The log still holds changes set-points ahead may go back over: the
                // move waits until the machine has passed them.
                self.program.pending = Some(block);
                return false;
            }
            // The move's start must stay a start: not merged into the line before (G64
            // Q), as LinuxCNC ends its collinear merging at a synchronised output.
            if let PathMode::Blend {
                merge_tolerance, ..
            } = &mut mv.mode
            {
                *merge_tolerance = 0.0;
            }
        }
        self.before_new_motion();
        if let Some(end) = self.program.skipped_to.take() {
            // Run from a line: go to where the first executed block starts, at rapid.
            let approach = Move::rapid(end, PathMode::ExactStop, mv.line);
            match self.path.planner.push(&approach) {
                // Zero length: the machine already stands there (after an abort on the
                // way, say). Keeping the approach for the next attempt met the same
                // refusal at every attempt, and the program stood in `running` for ever.
                Ok(()) | Err(MotionError::ZeroLength { .. }) => {}
                Err(MotionError::QueueFull) => {
                    self.program.skipped_to = Some(end);
                    self.program.pending = Some(block);
                    return false;
                }
                Err(e) => {
                    self.path.planner.flush();
                    self.fire(Event::Fail {
                        code: FaultCode::MotionError,
                        line: e.line().unwrap_or(mv.line),
                        value: 0.0,
                    });
                    *shared.motion_error.lock() = Some(e);
                    return true;
                }
            }
        }
        let key = self.program.blocks_taken;
        let pushed = match self.path.planner.preparation(staging, key) {
            Preparation::Built => self.path.planner.push_prepared(staging),
            Preparation::Stale | Preparation::Copied => {
                self.path.planner.prepare(&mv, key, staging);
                self.program.pending = Some(block);
                return false;
            }
        };
        match pushed {
            Ok(()) => {
                if arms_outputs {
                    let first_piece = self.path.planner.next_piece_id();
                    self.outputs.arm_staged(first_piece);
                }
                let follows_spindle = match mv.feed {
                    Feed::PerRevolution {
                        spindle_rev_per_s, ..
                    } if self.spindle.css.is_some()
                        && !matches!(mv.kind, MoveKind::Dwell { .. }) =>
                    {
                        Some(spindle_rev_per_s)
                    }
                    _ => None,
                };
                self.mark_feed_per_revolution(follows_spindle);
                if self.program.single_block {
                    self.path.planner.flush();
                    self.fire(Event::Drain {
                        then: Then::SingleBlockPause,
                        line: mv.line,
                    });
                }
                true
            }
            Err(MotionError::QueueFull) => {
                self.program.pending = Some(block);
                false
            }
            // A move to where the machine already is: nothing to do (LinuxCNC drops such
            // moves too).
            Err(MotionError::ZeroLength { .. }) => true,
            Err(e) => {
                self.path.planner.flush();
                self.fire(Event::Fail {
                    code: FaultCode::MotionError,
                    line: e.line().unwrap_or(mv.line),
                    value: 0.0,
                });
                *shared.motion_error.lock() = Some(e);
                true
            }
        }
    }

    /// A tool-centre-point move: from the pose the path's end joints stand for to `end`,
    /// along `path`, cut into chords by [`Self::next_chord`] as the window takes them. Its
    /// duration is the tip's length (the rotary axes' where the tip stands) at the feed, as
    /// the planner takes a feed; a rapid's is the axes'.
    #[allow(clippy::too_many_arguments)]
    fn start_tcp_move(
        &mut self,
        line: u32,
        path: TipPath,
        end: &[f64; AXES],
        rapid: bool,
        feed: Feed,
        mode: PathMode,
        tool_offset: f64,
    ) -> Result<(), MotionError> {
        let Some((kinematics, tolerance)) = self.program.five_axis else {
            return Err(MotionError::ToolCentrePoint {
                line,
                why: "the machine has no five-axis kinematics",
            });
        };
        // The end's joints within their range, before any chord runs (a chord that
        // leaves it on the way is refused by the planner at the same line).
        let end_joints = kinematics.joints(end, tool_offset);
        for i in 0..AXES {
            let v = end_joints[i];
            if self.machine.axis_present[i]
                && (v < self.machine.axis_min[i] || v > self.machine.axis_max[i])
            {
                return Err(MotionError::SoftLimit {
                    line,
                    axis: rtcnc_motion::Axis::ALL[i].letter(),
                    position: v,
                    min: self.machine.axis_min[i],
                    max: self.machine.axis_max[i],
                });
            }
        }
        // Run from a line: the move starts where the skipped motion ended (the approach
        // goes there first).
        let start = self
            .program
            .skipped_to
            .unwrap_or_else(|| self.path.planner.path_end());
        let chords = TcpMove::new(
            kinematics,
            tool_offset,
            &start,
            end,
            path,
            tolerance * CHORD_SHARE,
            0.0,
            line,
        )?;
        let (len_xyz, len) = chords.lengths();
        if len <= 1e-12 {
            // A move to where the tip already is: nothing to do.
            return Ok(());
        }
        let seconds = if rapid {
            0.0
        } else {
            let feed_len = if len_xyz > 1e-12 { len_xyz } else { len };
            let seconds = match feed {
                Feed::UnitsPerSecond(f) => feed_len / f,
                Feed::InverseTime { seconds } => seconds,
                Feed::PerRevolution { .. } => f64::NAN,
            };
            if !(seconds.is_finite() && seconds > 0.0) {
                return Err(MotionError::InvalidFeed {
                    line,
                    feed: feed_len / seconds,
                });
            }
            seconds
        };
        let chords = chords.with_duration(seconds);
        // A distance in joint space moves the tip by up to `gain` times as much.
        let gain = chords.joint_to_tip_gain();
        let inner = PathMode::Blend {
            tolerance: tolerance * (1.0 - CHORD_SHARE) / gain,
            merge_tolerance: 0.0,
        };
        let last = match mode {
            PathMode::Blend { tolerance, .. } => PathMode::Blend {
                tolerance: tolerance / gain,
                merge_tolerance: 0.0,
            },
            other => other,
        };
        self.program.tcp = Some(TcpRun {
            chords,
            rapid,
            inner,
            last,
            line,
        });
        Ok(())
    }

    /// The next chord of the tool-centre-point line as a move; `None` once it is done.
    fn next_chord(&mut self) -> Result<Option<Move>, MotionError> {
        let Some(run) = self.program.tcp.as_mut() else {
            return Ok(None);
        };
        let Some(chord) = run.chords.next_chord()? else {
            self.program.tcp = None;
            return Ok(None);
        };
        let mv = Move {
            kind: MoveKind::Line {
                end: chord.end,
                rapid: run.rapid,
            },
            feed: if run.rapid {
                Feed::UnitsPerSecond(f64::INFINITY)
            } else {
                Feed::InverseTime {
                    seconds: chord.seconds,
                }
            },
            mode: if chord.last { run.last } else { run.inner },
            line: run.line,
        };
        if chord.last {
            self.program.tcp = None;
        }
        Ok(Some(mv))
    }

    /// Once the path stands, does what stopped it. Held: the next block (a machine
    /// function, a probing or threading move, the program's end) waits for the resume; an
    /// error stops the program at once.
    fn draining(&mut self, ctx: &mut Context<'_>, shared: &Shared, then: Then, line: u32) -> bool {
        if self.moving() {
            return false;
        }
        if self.hold.latched() && !matches!(then, Then::Error(..)) {
            return false;
        }
        match then {
            Then::SingleBlockPause => {
                self.fire(Event::Pause {
                    start_count: self.program.start_count,
                });
            }
            Then::End => {
                // Synchronised outputs with no move after them change at the end.
                self.change_output_now(None);
                self.reset_enables();
                self.fire(Event::Finish);
                self.program.ended = true;
                self.requests_mut().program_running = false;
            }
            Then::MdiDone => {
                self.change_output_now(None);
                self.fire(Event::Finish);
            }
            Then::Error(code, value) => {
                self.outputs.drop_pending();
                shared.raise(ctx, code, TaskName::LookAhead, None, line, value);
                self.fire(Event::Finish);
                self.program.epoch = self.program.epoch.wrapping_add(1);
                let _ = shared
                    .interpreter_requests
                    .try_put(InterpreterRequest::Stop);
                self.requests_mut().program_running = false;
            }
            Then::Aux(aux) => self.start_aux(shared, aux, line),
            // The next move is not the planner's: synchronised outputs change as it starts.
            Then::Probe(mv, kind) => {
                self.change_output_now(None);
                self.start_probe(shared, mv, kind);
            }
            Then::Synced(end, pitch, tap) => {
                self.change_output_now(None);
                self.start_synced(end, pitch, tap, line);
            }
        }
        true
    }

    /// M0/M1/single block: the program goes on after a start or resume, unless held.
    fn paused(&mut self, start_count: u32) -> bool {
        if self.program.start_count == start_count || self.hold.latched() {
            return false;
        }
        self.fire(Event::Proceed)
    }

    /// The interpolation cycle at which a wait of `seconds` ends: now for 0 (or a
    /// negative or NaN time, which the interpreter refuses before), never for an infinite
    /// one, and saturating for one longer than the machine will run.
    pub(super) fn deadline_after(&self, seconds: f64) -> u64 {
        if seconds.is_nan() || seconds <= 0.0 {
            return self.now();
        }
        // `as` saturates: infinity and 1e30 s become u64::MAX periods.
        let periods = (seconds / self.machine.period_s).ceil() as u64;
        self.now().saturating_add(periods)
    }

    /// Hands the interpreter the result it waits for (it reads on once it has it).
    pub(super) fn send_result(&self, shared: &Shared, result: MachineResult) {
        let _ = shared.machine_results.try_put(Tagged {
            epoch: self.program.epoch,
            block: result,
        });
        shared.interpreter_wake.signal();
    }

    /// Hands the text of message `seq` to the operator, stamped with the set-point at which
    /// the path stands at its block. Texts of an aborted run still in the channel are
    /// older: they are dropped on the way.
    pub(super) fn show_message(&self, shared: &Shared, seq: u32, line: u32) {
        for _ in 0..shared.message_texts.capacity() {
            let Some((s, text)) = shared.message_texts.try_get() else {
                return;
            };
            if s == seq {
                let cycle = self.now();
                let _ = shared.operator_messages.try_put(OperatorMessage {
                    cycle,
                    time_ns: cycle.saturating_mul(self.machine.period_ns),
                    line,
                    text,
                });
                return;
            }
        }
    }
}
