//! The interpreter task: reads the program (or an MDI line) with the G-code interpreter and
//! the cutter-radius compensation stage, and sends plain-data blocks ahead while the channel
//! has room. It is an event task below the real-time ones: it may allocate (the interpreter
//! does), it never blocks, and it yields when the channel is full.

use std::path::PathBuf;
use std::time::Duration;

use rtcnc_gcode::canon::{
    Arc as CanonArc, CanonCommand, FeedMode, Plane, SpindleDirection, Spline as CanonSpline, Units,
};
use rtcnc_gcode::compensation::Compensator;
use rtcnc_gcode::{Canon, Interpreter, Parameters, Settings, ToolTable};
use rtcnc_motion::nurbs::NurbsCurve;
use rtcnc_motion::{Bezier, CurvePart, FiveAxisKinematics, PathMode};
use rtcnc_rt::{Context, Next};

use crate::config::OverSpeed;
use crate::fault::FaultCode;
use crate::messages::{Aux, FixedText, MachineResult, ProgramBlock, WaitCondition};
use crate::shared::{InterpreterRequest, Shared, Tagged};

/// Blocks handled per activation before giving the processor back.
const BLOCKS_PER_ACTIVATION: usize = 64;

/// Declared processor time per canonical command (virtual time charges it).
const COST_PER_COMMAND: Duration = Duration::from_micros(2);

pub(crate) struct InterpreterStage {
    shared: Shared,
    program: Option<PathBuf>,
    settings: Settings,
    tools: ToolTable,
    parameters: Parameters,
    interp: Option<Interpreter>,
    comp: Compensator,
    epoch: u32,
    active: bool,
    mdi: bool,
    /// Blocks converted but not yet sent (the channel was full).
    outbox: std::collections::VecDeque<ProgramBlock>,
    /// Program position, for arcs (program coordinates).
    position: [f64; 9],
    plane: Plane,
    /// Length units of the canonical commands (for the arcs' radius tolerance).
    units: Units,
    selected_tool: i32,
    spindle_rpm: f64,
    spindle_on: Option<SpindleDirection>,
    diameter_mode: bool,
    /// M30/M60 exchange pallets through the machine logic.
    pallet_shuttle: bool,
    parameter_file: Option<PathBuf>,
    /// The G64 P tolerance in force, so that a later Q (naive-CAM merge) can join it.
    blend_tolerance: Option<f64>,
    /// A command the kernel cannot carry out stopped this run: nothing after it converts.
    refused: bool,
    /// G96 in force, with its D word.
    css_max: Option<f64>,
    /// A spindle-synchronised stretch being collected (from its start to its end).
    sync_hold: Option<Vec<Canon>>,
    /// A stretch collected, waiting for the next command: another one chains to it.
    sync_done: Option<Vec<Canon>>,
    /// Sequence number of the last operator message.
    message_seq: u32,
    /// Message texts not yet handed to the look-ahead (its channel was full).
    texts: std::collections::VecDeque<(u32, FixedText)>,
    /// The tool table file (read again on request).
    tool_table_file: Option<PathBuf>,
    /// Where the modal state goes after every activation.
    modal: Option<rtcnc_rt::SeqlockWriter<crate::modal::ModalSnapshot>>,
    /// `tools` was read again: the next interpreter takes it instead of the last one's.
    tools_fresh: bool,
    /// The spindle's highest speed (rpm) and what an S word above it does.
    spindle_limit: Option<(f64, OverSpeed)>,
    /// The machine's five-axis kinematics (a table or a head) (M428 needs one).
    five_axis: Option<FiveAxisKinematics>,
    /// M428 in force.
    tool_centre_point: bool,
}

/// The user M-code number with which a pallet shuttle is asked of the machine logic.
pub const PALLET_SHUTTLE_M_CODE: u16 = 60;

impl InterpreterStage {
    pub(crate) fn new(
        shared: Shared,
        program: Option<PathBuf>,
        settings: Settings,
        tools: ToolTable,
        parameters: Parameters,
        diameter_mode: bool,
    ) -> Self {
        InterpreterStage {
            shared,
            program,
            settings,
            tools,
            parameters,
            interp: None,
            comp: Compensator::new(),
            epoch: 0,
            active: false,
            mdi: false,
            outbox: std::collections::VecDeque::with_capacity(256),
            position: [0.0; 9],
            plane: Plane::XY,
            units: Units::Mm,
            selected_tool: 0,
            spindle_rpm: 0.0,
            spindle_on: None,
            diameter_mode,
            pallet_shuttle: false,
            parameter_file: None,
            blend_tolerance: None,
            refused: false,
            css_max: None,
            sync_hold: None,
            sync_done: None,
            message_seq: 0,
            texts: std::collections::VecDeque::with_capacity(8),
            tool_table_file: None,
            modal: None,
            tools_fresh: false,
            spindle_limit: None,
            five_axis: None,
            tool_centre_point: false,
        }
    }

    /// The machine's five-axis kinematics (`[kinematics]`), for M428 and M429.
    pub(crate) fn with_five_axis_kinematics(
        mut self,
        five_axis: Option<FiveAxisKinematics>,
    ) -> Self {
        self.five_axis = five_axis;
        self
    }

    /// The machine has a pallet shuttle (`machine.pallet_shuttle`).
    pub(crate) fn with_pallet_shuttle(mut self, on: bool) -> Self {
        self.pallet_shuttle = on;
        self
    }

    /// The tool table file, read again on `InterpreterRequest::ReloadToolTable`.
    pub(crate) fn with_tool_table_file(mut self, path: Option<PathBuf>) -> Self {
        self.tool_table_file = path;
        self
    }

    /// Publishes the modal state there after every activation.
    pub(crate) fn with_modal(
        mut self,
        writer: rtcnc_rt::SeqlockWriter<crate::modal::ModalSnapshot>,
    ) -> Self {
        self.modal = Some(writer);
        self
    }

    /// S words above `max_rpm` are refused or clamped (`spindle.over_speed`).
    pub(crate) fn with_spindle_limit(mut self, limit: Option<(f64, OverSpeed)>) -> Self {
        self.spindle_limit = limit;
        self
    }

    /// Where the parameters (work offsets, #5161..) are saved at the end of every program.
    pub(crate) fn with_parameter_file(mut self, path: Option<PathBuf>) -> Self {
        self.parameter_file = path;
        self
    }

    fn fresh_interpreter(&mut self) -> Interpreter {
        let parameters = self
            .interp
            .as_ref()
            .map(|i| i.parameters().clone())
            .unwrap_or_else(|| self.parameters.clone());
        let tools = match &self.interp {
            Some(i) if !self.tools_fresh => i.tool_table().clone(),
            _ => self.tools.clone(),
        };
        self.tools_fresh = false;
        // A new interpreter starts with TCP off, and so does tool compensation.
        if self.tool_centre_point {
            self.tool_centre_point = false;
            self.outbox.push_back(ProgramBlock::ToolCentrePoint(false));
        }
        let mut interp = Interpreter::new(self.settings.clone(), tools, parameters);
        if self.diameter_mode {
            // A lathe in diameter mode: G18 and G7 before the program, as LinuxCNC's
            // RS274NGC_STARTUP_CODE does on such a machine.
            let _ = interp.execute_mdi("G18 G7");
            while let Some(Ok(_)) = interp.next_canon() {}
        }
        interp
    }

    pub(crate) fn body(&mut self, ctx: &mut Context<'_>) -> Next {
        let next = self.run(ctx);
        if let (Some(w), Some(interp)) = (self.modal.as_mut(), self.interp.as_ref()) {
            let m = crate::modal::ModalSnapshot::of(interp.modal_state());
            if w.value() != m {
                w.publish(m);
            }
        }
        next
    }

    fn run(&mut self, ctx: &mut Context<'_>) -> Next {
        while let Some(request) = self.shared.interpreter_requests.try_get() {
            match request {
                InterpreterRequest::Run { epoch } => {
                    self.epoch = epoch;
                    self.refused = false;
                    self.css_max = None;
                    self.sync_hold = None;
                    self.sync_done = None;
                    self.outbox.clear();
                    self.texts.clear();
                    self.comp = Compensator::new();
                    let mut interp = self.fresh_interpreter();
                    let opened = match &self.program {
                        Some(path) => interp.open(path).map_err(|e| (e.line, e.to_string())),
                        None => Err((0, "no program loaded".to_string())),
                    };
                    self.interp = Some(interp);
                    self.mdi = false;
                    match opened {
                        Ok(()) => self.active = true,
                        Err((line, text)) => {
                            *self.shared.error_text.lock() = Some(text);
                            self.outbox.push_back(ProgramBlock::Error {
                                line,
                                code: FaultCode::ProgramError,
                            });
                            self.active = false;
                        }
                    }
                }
                InterpreterRequest::Mdi { epoch, line } => {
                    self.epoch = epoch;
                    self.sync_hold = None;
                    self.sync_done = None;
                    self.refused = false;
                    self.outbox.clear();
                    self.texts.clear();
                    if self.interp.is_none() || self.tools_fresh {
                        self.interp = Some(self.fresh_interpreter());
                    }
                    if let Some(interp) = self.interp.as_mut() {
                        if let Err(e) = interp.execute_mdi(line.as_str()) {
                            *self.shared.error_text.lock() = Some(e.to_string());
                            self.outbox.push_back(ProgramBlock::Error {
                                line: 0,
                                code: FaultCode::ProgramError,
                            });
                        }
                    }
                    self.mdi = true;
                    self.active = true;
                }
                InterpreterRequest::Stop => {
                    self.sync_hold = None;
                    self.sync_done = None;
                    // Also ends a wait for the machine's result.
                    if let Some(interp) = self.interp.as_mut() {
                        interp.abort();
                    }
                    self.active = false;
                    self.outbox.clear();
                    self.texts.clear();
                }
                InterpreterRequest::BlockDelete(on) => self.settings.block_delete = on,
                InterpreterRequest::Open(path) => self.program = Some(path.as_str().into()),
                InterpreterRequest::ReloadToolTable => self.reload_tool_table(),
            }
        }
        for _ in 0..BLOCKS_PER_ACTIVATION {
            // A message's text goes ahead of its block.
            while let Some(&text) = self.texts.front() {
                if self.shared.message_texts.try_put(text).is_err() {
                    break;
                }
                self.texts.pop_front();
            }
            if let Some(block) = self.outbox.front().copied() {
                if let ProgramBlock::Aux {
                    aux: Aux::Message { seq },
                    ..
                } = block
                {
                    if self.texts.iter().any(|t| t.0 == seq) {
                        return Next::WaitFor {
                            trigger: self.shared.message_texts.space_trigger(),
                            timeout: None,
                        };
                    }
                }
                let tagged = Tagged {
                    epoch: self.epoch,
                    block,
                };
                if self.shared.program_blocks.try_put(tagged).is_err() {
                    return Next::WaitFor {
                        trigger: self.shared.program_blocks.space_trigger(),
                        timeout: None,
                    };
                }
                self.outbox.pop_front();
                continue;
            }
            if !self.active {
                return Next::Done;
            }
            ctx.consume(COST_PER_COMMAND);
            if !self.pull_one() {
                return Next::Done;
            }
        }
        Next::Continue
    }

    /// Pulls one canonical command through compensation and converts what comes out.
    /// False when the interpreter waits for the machine's result, which has not come.
    fn pull_one(&mut self) -> bool {
        if let Some(c) = self.comp.pop() {
            self.convert(c);
            return true;
        }
        let Some(interp) = self.interp.as_mut() else {
            self.active = false;
            return true;
        };
        match interp.next_canon() {
            Some(Ok(canon)) => {
                if let Err(e) = self.comp.push(canon) {
                    while let Some(c) = self.comp.pop() {
                        self.convert(c);
                    }
                    self.flush_sync();
                    *self.shared.error_text.lock() = Some(e.to_string());
                    self.outbox.push_back(ProgramBlock::Error {
                        line: e.at.line,
                        code: FaultCode::CompensationError,
                    });
                    self.active = false;
                }
            }
            Some(Err(e)) => {
                self.comp.finish();
                while let Some(c) = self.comp.pop() {
                    self.convert(c);
                }
                self.flush_sync();
                *self.shared.error_text.lock() = Some(e.to_string());
                self.outbox.push_back(ProgramBlock::Error {
                    line: e.line,
                    code: FaultCode::ProgramError,
                });
                self.active = false;
            }
            // After M66 the interpreter reads on only with the machine's result, as
            // LinuxCNC's does: later lines may read #5399. Not the end.
            None if interp.is_waiting() => match self.take_result() {
                Some(MachineResult::Input(value)) => {
                    if let Some(interp) = self.interp.as_mut() {
                        interp.input_result(value);
                    }
                }
                Some(MachineResult::Probe {
                    tripped,
                    at,
                    stopped,
                }) => {
                    if let Some(interp) = self.interp.as_mut() {
                        // Machine millimetres to the interpreter's machine coordinates in
                        // the program's units.
                        let per_unit = match interp.modal_state().units {
                            Units::Mm => 1.0,
                            Units::Inches => 25.4,
                        };
                        let units = |p: [f64; 9]| {
                            let mut p = p;
                            for i in [0, 1, 2, 6, 7, 8] {
                                p[i] /= per_unit;
                            }
                            rtcnc_gcode::canon::Pose::from_array(p)
                        };
                        interp.probe_result(units(at), tripped, units(stopped));
                        self.position = interp.modal_state().position.to_array();
                    }
                }
                None => return false,
            },
            None => {
                self.comp.finish();
                while let Some(c) = self.comp.pop() {
                    self.convert(c);
                }
                self.flush_sync();
                if self.mdi {
                    self.outbox.push_back(ProgramBlock::MdiDone);
                } else {
                    self.outbox.push_back(ProgramBlock::End { line: 0 });
                }
                self.save_parameters();
                self.active = false;
            }
        }
        true
    }

    fn convert(&mut self, canon: Canon) {
        if self.refused {
            return;
        }
        // A spindle-synchronised stretch held for the command after it: another stretch
        // right after it (the next G33 block) chains to it.
        if let Some(mut done) = self.sync_done.take() {
            if matches!(canon.command, CanonCommand::StartSpeedFeedSync { .. }) {
                done.push(canon);
                self.sync_hold = Some(done);
                return;
            }
            self.convert_sync_stretch(done);
            if self.refused {
                return;
            }
        }
        if let Some(what) = not_carried_out(&canon.command) {
            self.refuse(&canon, what);
            return;
        }
        if self.tool_centre_point {
            if let Some(what) = self.not_under_tool_centre_point(&canon.command) {
                self.refuse_because(
                    &canon,
                    &format!("{what} under tool-centre-point control (M428): M429 first"),
                );
                return;
            }
        }
        if let CanonCommand::SetToolCentrePoint(on) = canon.command {
            self.switch_tool_centre_point(&canon, on);
            return;
        }
        if let CanonCommand::NurbsFeed(nurbs) = &canon.command {
            if let Err(e) = self.convert_nurbs(nurbs, canon.source.line) {
                self.refuse_because(&canon, &format!("the NURBS curve (G5.2/G5.3): {e}"));
            }
            return;
        }
        // A spindle-synchronised stretch is held until its end (then until the next
        // command, above): the kernel gets the whole chain before any of it cuts.
        if let Some(held) = self.sync_hold.as_mut() {
            let end = matches!(canon.command, CanonCommand::StopSpeedFeedSync);
            held.push(canon);
            if end {
                self.sync_done = self.sync_hold.take();
            }
            return;
        }
        if matches!(canon.command, CanonCommand::StartSpeedFeedSync { .. }) {
            self.sync_hold = Some(vec![canon]);
            return;
        }
        let Some(canon) = self.spindle_within_limit(canon) else {
            return;
        };
        self.convert_now(canon);
    }

    /// A spindle-synchronised stretch (one or more G33 blocks one after the other, a G76
    /// pass, a G33.1): each feed move that another follows is marked as chained to it.
    /// A chain longer than the kernel takes stops the program before its first move.
    fn convert_sync_stretch(&mut self, held: Vec<Canon>) {
        let is_feed = |c: &Canon| matches!(c.command, CanonCommand::StraightFeed(_));
        let is_move = |c: &Canon| {
            matches!(
                c.command,
                CanonCommand::StraightFeed(_)
                    | CanonCommand::ArcFeed(_)
                    | CanonCommand::RigidTap { .. }
            )
        };
        // Whether each move is a feed another feed follows.
        let moves: Vec<usize> = (0..held.len()).filter(|&i| is_move(&held[i])).collect();
        let mut chained = vec![false; held.len()];
        let mut run = 1;
        for w in moves.windows(2) {
            if is_feed(&held[w[0]]) && is_feed(&held[w[1]]) {
                chained[w[0]] = true;
                run += 1;
                if run > MAX_SYNCED_CHAIN {
                    let first = moves.first().map_or(w[1], |&m| m);
                    let at = held[first].clone();
                    self.refuse_because(
                        &at,
                        &format!(
                            "more than {MAX_SYNCED_CHAIN} consecutive spindle-synchronised moves"
                        ),
                    );
                    return;
                }
            } else {
                run = 1;
            }
        }
        for (c, chained) in held.into_iter().zip(chained) {
            if chained {
                self.outbox.push_back(ProgramBlock::SyncChained);
            }
            self.convert_now(c);
        }
    }

    /// Converts a spindle-synchronised stretch still held (the program's or MDI line's
    /// end, an error after it).
    fn flush_sync(&mut self) {
        if let Some(done) = self.sync_done.take() {
            self.convert_sync_stretch(done);
        }
    }

    /// An S word (in rpm, not a G96 surface speed) above the spindle's highest speed: the
    /// run stops before it, or the speed is clamped with a message to the operator, as
    /// `spindle.over_speed` says. A G96 speed cap (D) above it, or none (D0), becomes it.
    fn spindle_within_limit(&mut self, mut canon: Canon) -> Option<Canon> {
        let Some((max_rpm, policy)) = self.spindle_limit else {
            return Some(canon);
        };
        match &mut canon.command {
            CanonCommand::SetSpindleSpeed { speed, .. }
                if self.css_max.is_none() && speed.abs() > max_rpm =>
            {
                let asked = *speed;
                match policy {
                    OverSpeed::Refuse => {
                        let text = format!(
                            "S{asked} is above the spindle's highest speed, {max_rpm} rpm \
                             (spindle.max_speed_rpm; spindle.over_speed = \"clamp\" runs it \
                             at that speed instead)"
                        );
                        self.refuse_because(&canon, &text);
                        return None;
                    }
                    OverSpeed::Clamp => {
                        *speed = max_rpm.copysign(asked);
                        let note = Canon {
                            command: CanonCommand::Message(
                                format!(
                                    "S{asked} clamped to {max_rpm} rpm (spindle.max_speed_rpm)"
                                )
                                .into(),
                            ),
                            source: canon.source,
                        };
                        self.convert_now(note);
                    }
                }
            }
            CanonCommand::SetSpindleMode {
                constant_surface_speed: true,
                max_rpm: cap,
                ..
            } if *cap <= 0.0 || *cap > max_rpm => *cap = max_rpm,
            _ => {}
        }
        Some(canon)
    }

    /// Turns one canonical command the kernel accepted into program blocks. Each step
    /// below takes one family of commands and hands back any other; a command no step
    /// takes (a comment, a canon call with no effect on motion) leaves no block.
    fn convert_now(&mut self, canon: Canon) {
        let line = canon.source.line;
        let Some(command) = self.convert_modal_setting(canon.command) else {
            return;
        };
        let Some(command) = self.convert_spindle(command, line) else {
            return;
        };
        let Some(command) = self.convert_motion(command, line) else {
            return;
        };
        let Some(command) = self.convert_io_and_operator(command, line) else {
            return;
        };
        if matches!(command, CanonCommand::ProgramEnd | CanonCommand::Finish) {
            // The program's end switches TCP off (the position is the joints again).
            if let (true, Some(kinematics)) = (self.tool_centre_point, self.five_axis) {
                self.apply_tool_centre_point(kinematics, false);
            }
            self.outbox.push_back(ProgramBlock::End { line });
            self.active = false;
            self.save_parameters();
        }
    }

    /// Units, offsets, plane, path mode and feed rate: the modal settings later moves are
    /// read in. Hands back any other command.
    fn convert_modal_setting(&mut self, command: CanonCommand) -> Option<CanonCommand> {
        use CanonCommand as C;
        let out = &mut self.outbox;
        match command {
            C::UseLengthUnits(u) => {
                self.units = u;
                out.push_back(ProgramBlock::Units(match u {
                    Units::Mm => 1.0,
                    Units::Inches => 25.4,
                }))
            }
            C::SetG5xOffset { offset, .. } => {
                out.push_back(ProgramBlock::WorkOffset(offset.to_array()))
            }
            C::SetG92Offset(p) => out.push_back(ProgramBlock::G92Offset(p.to_array())),
            C::SetXyRotation(r) => out.push_back(ProgramBlock::Rotation(r)),
            C::UseToolLengthOffset(p) => out.push_back(ProgramBlock::ToolOffset(p.to_array())),
            C::SelectPlane(p) => self.plane = p,
            C::SetMotionControlMode(mode) => {
                self.blend_tolerance = match mode {
                    rtcnc_gcode::canon::PathMode::Continuous { tolerance } => Some(tolerance),
                    _ => None,
                };
                out.push_back(ProgramBlock::PathMode(match mode {
                    rtcnc_gcode::canon::PathMode::ExactStop => PathMode::ExactStop,
                    rtcnc_gcode::canon::PathMode::ExactPath => PathMode::ExactPath,
                    rtcnc_gcode::canon::PathMode::Continuous { tolerance } => PathMode::Blend {
                        tolerance,
                        merge_tolerance: 0.0,
                    },
                }))
            }
            // G64 Q: rs274 sends it right after the mode it belongs to.
            C::SetNaivecamTolerance(merge_tolerance) => {
                if let Some(tolerance) = self.blend_tolerance {
                    out.push_back(ProgramBlock::PathMode(PathMode::Blend {
                        tolerance,
                        merge_tolerance,
                    }));
                }
            }
            // Nothing to carry: per-revolution feed is read from the modal state at each
            // SET_FEED_RATE below, and the interpreter already turns inverse time (G93) into
            // a feed rate per move, as rs274 does.
            C::SetFeedMode { .. } => {}
            C::SetFeedRate(rate) => {
                let per_revolution = self
                    .interp
                    .as_ref()
                    .is_some_and(|i| i.modal_state().feed_mode == FeedMode::UnitsPerRevolution);
                out.push_back(ProgramBlock::FeedRate {
                    rate,
                    per_revolution,
                })
            }
            other => return Some(other),
        }
        None
    }

    /// Spindle speed, direction, constant surface speed and orientation, and the tool
    /// change. Hands back any other command.
    fn convert_spindle(&mut self, command: CanonCommand, line: u32) -> Option<CanonCommand> {
        use CanonCommand as C;
        let out = &mut self.outbox;
        let aux = |aux| ProgramBlock::Aux { line, aux };
        match command {
            C::SetSpindleMode {
                constant_surface_speed: true,
                max_rpm,
                ..
            } => {
                self.css_max = Some(max_rpm);
                out.push_back(aux(Aux::SurfaceSpeed {
                    surface: self.spindle_rpm,
                    max_rpm,
                }));
            }
            // G97: the S number in force is rpm again (as LinuxCNC's canon takes it), until
            // an S word follows.
            C::SetSpindleMode {
                constant_surface_speed: false,
                ..
            } if self.css_max.is_some() => {
                self.css_max = None;
                out.push_back(aux(Aux::SurfaceSpeedOff));
            }
            C::SetSpindleSpeed { speed, .. } if self.css_max.is_some() => {
                self.spindle_rpm = speed;
                out.push_back(aux(Aux::SurfaceSpeed {
                    surface: speed,
                    max_rpm: self.css_max.unwrap_or(1e30),
                }));
            }
            C::SetSpindleSpeed { speed, .. } => {
                self.spindle_rpm = speed;
                if let Some(d) = self.spindle_on {
                    out.push_back(aux(Aux::SpindleOn {
                        rpm: signed(speed, d),
                    }));
                } else {
                    out.push_back(aux(Aux::SpindleSpeed { rpm: speed }));
                }
            }
            C::StartSpindle { direction, .. } => {
                self.spindle_on = Some(direction);
                out.push_back(aux(Aux::SpindleOn {
                    rpm: signed(self.spindle_rpm, direction),
                }));
            }
            C::StopSpindle { .. } => {
                self.spindle_on = None;
                out.push_back(aux(Aux::SpindleOff));
            }
            C::SelectTool(t) => self.selected_tool = t,
            C::ChangeTool(_) => out.push_back(aux(Aux::ToolChange {
                tool: u32::try_from(self.selected_tool).unwrap_or(0),
            })),
            C::ChangeToolNumber(_) => {}
            C::OrientSpindle { angle, mode, .. } => {
                self.spindle_on = None;
                out.push_back(aux(Aux::SpindleOrient {
                    angle,
                    mode: u8::try_from(mode).unwrap_or(0).min(2),
                }))
            }
            C::WaitOrientComplete { timeout, .. } => {
                out.push_back(aux(Aux::WaitOrient { timeout }))
            }
            C::StartSpeedFeedSync {
                feed_per_revolution,
                ..
            } => out.push_back(ProgramBlock::SpindleSync(Some(feed_per_revolution))),
            C::StopSpeedFeedSync => out.push_back(ProgramBlock::SpindleSync(None)),
            other => return Some(other),
        }
        None
    }

    /// Moves, dwell and probe: the blocks the planner runs as a path. Each one moves the
    /// position the next one starts from. Hands back any other command.
    fn convert_motion(&mut self, command: CanonCommand, line: u32) -> Option<CanonCommand> {
        use CanonCommand as C;
        match command {
            C::Dwell(seconds) => self.outbox.push_back(ProgramBlock::Dwell { line, seconds }),
            C::StraightTraverse(p) => {
                self.position = p.to_array();
                self.outbox.push_back(ProgramBlock::Line {
                    line,
                    end: self.position,
                    rapid: true,
                });
            }
            C::StraightFeed(p) => {
                self.position = p.to_array();
                self.outbox.push_back(ProgramBlock::Line {
                    line,
                    end: self.position,
                    rapid: false,
                });
            }
            C::ArcFeed(arc) => self.convert_arc(&arc, line),
            C::SplineFeed(sp) => self.convert_spline(&sp, line),
            // The tool comes back to where it started: the position stays.
            C::RigidTap { end, scale } => self.outbox.push_back(ProgramBlock::RigidTap {
                line,
                end: end.to_array(),
                scale,
            }),
            C::StraightProbe { end, kind } => {
                self.position = end.to_array();
                self.outbox.push_back(ProgramBlock::Probe {
                    line,
                    end: self.position,
                    kind,
                });
            }
            other => return Some(other),
        }
        None
    }

    fn convert_arc(&mut self, arc: &rtcnc_gcode::canon::Arc, line: u32) {
        let (end, centre, normal, turns) = arc_geometry(arc, self.plane, &self.position);
        // The radius difference the interpreter accepts for this arc: the planner
        // runs it as a spiral (as LinuxCNC does) and refuses no less. Cutter
        // compensation keeps the programmed difference while it changes the radii
        // (the interpreter accepted it for the programmed ones): at least the arc's
        // own difference.
        let radius = |p: &[f64; 9]| {
            let d = [p[0] - centre[0], p[1] - centre[1], p[2] - centre[2]];
            let along = d[0] * normal[0] + d[1] * normal[1] + d[2] * normal[2];
            (d[0] * d[0] + d[1] * d[1] + d[2] * d[2] - along * along)
                .max(0.0)
                .sqrt()
        };
        let (r_start, r_end) = (radius(&self.position), radius(&end));
        let radius_tolerance = self
            .settings
            .arc_radius_tolerance(self.units)
            .largest_difference(r_start.max(r_end))
            .max((r_start - r_end).abs());
        self.position = end;
        self.outbox.push_back(ProgramBlock::Arc {
            line,
            end,
            centre,
            normal,
            turns,
            radius_tolerance,
        });
    }

    fn convert_spline(&mut self, sp: &rtcnc_gcode::canon::Spline, line: u32) {
        let (end, control) = spline_geometry(sp, &self.position);
        self.push_curve(end, control, line);
    }

    /// A G5.2/G5.3 curve as the cubic Bézier curves within `NURBS_ERROR_MM` of it
    /// (`rtcnc_motion::nurbs`; the curve itself where it is a polynomial of order 4 or
    /// less), each run as a G5 spline is. The axes outside XY keep their values.
    fn convert_nurbs(
        &mut self,
        nurbs: &rtcnc_gcode::canon::Nurbs,
        line: u32,
    ) -> Result<(), String> {
        let at = |x: f64, y: f64| {
            let mut p = self.position;
            p[0] = x;
            p[1] = y;
            p
        };
        let points: Vec<[f64; 9]> = nurbs.points.iter().map(|q| at(q.x, q.y)).collect();
        let weights: Vec<f64> = nurbs.points.iter().map(|q| q.weight).collect();
        let tolerance = match self.units {
            Units::Mm => NURBS_ERROR_MM,
            Units::Inches => NURBS_ERROR_MM / 25.4,
        };
        let order = usize::try_from(nurbs.order).unwrap_or(usize::MAX);
        let curve =
            NurbsCurve::clamped_uniform(order, &points, &weights).map_err(|e| e.to_string())?;
        let mut cubics = Vec::new();
        curve
            .to_cubics(tolerance, &mut cubics)
            .map_err(|e| e.to_string())?;
        for [_, c1, c2, end] in cubics {
            self.push_curve(end, Bezier::Cubic([c1, c2]), line);
        }
        Ok(())
    }

    /// A polynomial curve from the current position: the planner follows it exactly.
    fn push_curve(&mut self, end: [f64; 9], control: Bezier, line: u32) {
        if control.is_followable(&self.position, &end) {
            self.outbox
                .push_back(ProgramBlock::Spline { line, end, control });
            self.position = end;
            return;
        }
        let tolerance = match self.units {
            Units::Mm => SPLINE_CHORD_ERROR_MM,
            Units::Inches => SPLINE_CHORD_ERROR_MM / 25.4,
        };
        // A cusp (the curve stops and turns back) or an end without direction: the curve
        // up to just before it, chords within the tolerance into and out of it, where
        // the path comes to rest, and the curve on.
        let mut parts = Vec::new();
        if control.split_at_cusps(&self.position, &end, tolerance, &mut parts) {
            for part in parts {
                self.outbox.push_back(match part {
                    CurvePart::Curve { end, control } => {
                        ProgramBlock::Spline { line, end, control }
                    }
                    CurvePart::Line { end } => ProgramBlock::Line {
                        line,
                        end,
                        rapid: false,
                    },
                });
            }
        } else {
            // What cannot be cut so runs as chords within the tolerance of the curve,
            // blended as lines are, stopping where they reverse (LinuxCNC runs every
            // spline as arcs).
            let mut points = Vec::new();
            control.flatten(&self.position, &end, tolerance, &mut points);
            for end in points {
                self.outbox.push_back(ProgramBlock::Line {
                    line,
                    end,
                    rapid: false,
                });
            }
        }
        self.position = end;
    }

    /// Program I/O, messages, override switches, coolant, user M-codes and program
    /// stops: auxiliary blocks the kernel runs between moves. Hands back any other
    /// command.
    fn convert_io_and_operator(
        &mut self,
        command: CanonCommand,
        line: u32,
    ) -> Option<CanonCommand> {
        use CanonCommand as C;
        let out = &mut self.outbox;
        let aux = |aux| ProgramBlock::Aux { line, aux };
        match command {
            C::SetDigitalOutput {
                index,
                on,
                synchronized,
            } => out.push_back(aux(Aux::DigitalOutput {
                index,
                on,
                synchronized,
            })),
            C::WaitInput {
                digital: true,
                index,
                mode,
                timeout,
            } => {
                use rtcnc_gcode::canon::WaitMode;
                let condition = match mode {
                    WaitMode::Immediate => WaitCondition::Immediate,
                    WaitMode::Rise => WaitCondition::Rise,
                    WaitMode::Fall => WaitCondition::Fall,
                    WaitMode::High => WaitCondition::High,
                    WaitMode::Low => WaitCondition::Low,
                };
                out.push_back(aux(Aux::WaitInput {
                    index,
                    condition,
                    timeout,
                }));
            }
            C::Message(text) => {
                self.message_seq = self.message_seq.wrapping_add(1);
                self.texts
                    .push_back((self.message_seq, FixedText::truncated(&text)));
                out.push_back(aux(Aux::Message {
                    seq: self.message_seq,
                }));
            }
            // The interpreter allows only L0 (read now) on an analogue input, as LinuxCNC.
            C::WaitInput {
                digital: false,
                index,
                ..
            } => out.push_back(aux(Aux::ReadAnalogInput { index })),
            C::SetAnalogOutput {
                index,
                value,
                synchronized,
            } => out.push_back(aux(Aux::AnalogOutput {
                index,
                value,
                synchronized,
            })),
            C::FeedOverride(on) => out.push_back(aux(Aux::FeedOverrideEnable(on))),
            C::SpeedOverride { enable, .. } => {
                out.push_back(aux(Aux::SpindleOverrideEnable(enable)))
            }
            C::FeedHold(on) => out.push_back(aux(Aux::FeedStopEnable(on))),
            C::AdaptiveFeed(on) => out.push_back(aux(Aux::AdaptiveFeed(on))),
            C::MistOn => out.push_back(aux(Aux::Mist(true))),
            C::MistOff => out.push_back(aux(Aux::Mist(false))),
            C::FloodOn => out.push_back(aux(Aux::Flood(true))),
            C::FloodOff => out.push_back(aux(Aux::Flood(false))),
            C::UserMCode { code, p, q } => out.push_back(aux(Aux::UserM {
                code,
                p: p.unwrap_or(f64::NAN),
                q: q.unwrap_or(f64::NAN),
            })),
            C::ProgramStop => out.push_back(aux(Aux::ProgramStop)),
            // LinuxCNC's task does nothing for it; a machine with a shuttle has its logic
            // exchange the pallets (the user M-code hand-shake, code 60).
            C::PalletShuttle if self.pallet_shuttle => out.push_back(aux(Aux::UserM {
                code: PALLET_SHUTTLE_M_CODE,
                p: f64::NAN,
                q: f64::NAN,
            })),
            C::PalletShuttle => {}
            C::OptionalProgramStop => out.push_back(aux(Aux::OptionalStop)),
            other => return Some(other),
        }
        None
    }
}

impl InterpreterStage {
    /// Stops the run before a block the kernel cannot carry out: "error in program" at
    /// that block, like an interpreter error found ahead.
    fn refuse(&mut self, canon: &Canon, what: &str) {
        self.refuse_because(
            canon,
            &format!("{what} is not supported by the motion kernel yet"),
        );
    }

    /// Stops the run before `canon`'s block, for `reason`.
    fn refuse_because(&mut self, canon: &Canon, reason: &str) {
        let line = canon.source.line;
        let file = self
            .interp
            .as_ref()
            .map_or_else(|| "MDI".into(), |i| i.file_name(canon.source.file));
        *self.shared.error_text.lock() = Some(format!(
            "{file}:{line}: {reason}; the program stops before this block"
        ));
        self.outbox.push_back(ProgramBlock::Error {
            line,
            code: FaultCode::ProgramError,
        });
        self.active = false;
        self.refused = true;
    }

    /// What the kernel does not run under TCP: only lines and arcs are cut into
    /// joint-space chords, and the kinematics' tool length stays the one it started with.
    fn not_under_tool_centre_point(&self, command: &CanonCommand) -> Option<&'static str> {
        use CanonCommand as C;
        let per_revolution = self
            .interp
            .as_ref()
            .is_some_and(|i| i.modal_state().feed_mode == FeedMode::UnitsPerRevolution);
        match command {
            C::SplineFeed(_) | C::NurbsFeed(_) => Some("a spline (G5..G5.3)"),
            C::StraightProbe { .. } => Some("a probing move (G38)"),
            C::RigidTap { .. } | C::StartSpeedFeedSync { .. } => {
                Some("spindle-synchronised motion (G33, G76)")
            }
            C::UseToolLengthOffset(_) => Some("a tool length offset change (G43, G49)"),
            C::StartCutterRadiusCompensation { .. } => Some("cutter radius compensation"),
            C::StraightFeed(_) if per_revolution => Some("feed per revolution (G95)"),
            _ => None,
        }
    }

    /// M428/M429: the same joints stand for another position; the interpreter reads on
    /// from it, and tool compensation turns the lines from here on into tool-tip moves
    /// (or back).
    fn switch_tool_centre_point(&mut self, canon: &Canon, on: bool) {
        let Some(kinematics) = self.five_axis else {
            self.refuse_because(
                canon,
                "M428/M429 need a five-axis kinematics (the machine file's [kinematics] kind)",
            );
            return;
        };
        if on != self.tool_centre_point {
            self.apply_tool_centre_point(kinematics, on);
        }
    }

    fn apply_tool_centre_point(&mut self, kinematics: FiveAxisKinematics, on: bool) {
        let Some(interp) = self.interp.as_mut() else {
            return;
        };
        let per_unit = match interp.modal_state().units {
            Units::Mm => 1.0,
            Units::Inches => 25.4,
        };
        let linear = |i: usize| !(3..6).contains(&i);
        let mut m = interp.machine_position_now().to_array();
        for (i, v) in m.iter_mut().enumerate() {
            if linear(i) {
                *v *= per_unit;
            }
        }
        let tool = interp.modal_state().tool_offset.z * per_unit;
        // Off, the position is the joints; on, the pose they put the tool tip at.
        let mut now = if on {
            kinematics.pose(&m, tool)
        } else {
            kinematics.joints(&m, tool)
        };
        for (i, v) in now.iter_mut().enumerate() {
            if linear(i) {
                *v /= per_unit;
            }
        }
        interp.kinematics_switched(rtcnc_gcode::canon::Pose::from_array(now));
        self.position = interp.modal_state().position.to_array();
        self.tool_centre_point = on;
        self.outbox.push_back(ProgramBlock::ToolCentrePoint(on));
    }

    /// The machine's result for the current run, if it has come (older runs' are dropped).
    fn take_result(&mut self) -> Option<MachineResult> {
        while let Some(Tagged { epoch, block }) = self.shared.machine_results.try_get() {
            if epoch == self.epoch {
                return Some(block);
            }
        }
        None
    }

    /// Reads the tool table file again; the next program or MDI line uses it (MDI then
    /// starts with a fresh interpreter; a running program keeps the table it started with). A file that does not read keeps the old table and says
    /// why as the last error.
    fn reload_tool_table(&mut self) {
        let Some(path) = &self.tool_table_file else {
            return;
        };
        match ToolTable::load(path) {
            Ok(table) => {
                self.tools = table;
                self.tools_fresh = true;
            }
            Err(e) => *self.shared.error_text.lock() = Some(e.to_string()),
        }
    }

    /// Writes the parameter file (atomically: the interpreter's `Parameters::save`).
    fn save_parameters(&mut self) {
        if let (Some(path), Some(interp)) = (&self.parameter_file, &self.interp) {
            if let Err(e) = interp.parameters().save(path) {
                *self.shared.error_text.lock() = Some(format!("{}: {e}", path.display()));
            }
        }
    }
}

/// Canonical commands the kernel cannot carry out yet. Running them as something else (a
/// spline as a line, a probing move as a plain feed) would move the
/// machine in a way the program did not mean, so the run stops before them instead.
fn not_carried_out(command: &CanonCommand) -> Option<&'static str> {
    use CanonCommand as C;
    match command {
        C::StartSpeedFeedSync {
            velocity_mode: true,
            ..
        } => Some("velocity-synchronised motion"),
        _ => None,
    }
}

fn signed(rpm: f64, direction: SpindleDirection) -> f64 {
    match direction {
        SpindleDirection::Clockwise => rpm.abs(),
        SpindleDirection::CounterClockwise => -rpm.abs(),
    }
}

/// Most spindle-synchronised moves the kernel runs as one chain.
const MAX_SYNCED_CHAIN: usize = crate::messages::MAX_SYNCED_CHAIN;

/// Largest distance of the chords a spline the planner cannot follow is run as from the
/// curve, mm.
const SPLINE_CHORD_ERROR_MM: f64 = 0.001;

/// Largest distance of the cubic curves a NURBS is run as from the curve, mm (0.1 µm;
/// LinuxCNC's biarcs keep within its naive-CAM tolerance).
const NURBS_ERROR_MM: f64 = 1e-4;

/// The end point and Bézier control points (nine axes) of a canonical spline. The
/// interpreter gives G5/G5.1 in the XY plane only and refuses other axis words on them, so
/// the other axes keep their values (as control points: constant).
fn spline_geometry(sp: &CanonSpline, from: &[f64; 9]) -> ([f64; 9], Bezier) {
    let at = |xy: [f64; 2]| {
        let mut p = *from;
        p[0] = xy[0];
        p[1] = xy[1];
        p
    };
    let control = if sp.order == 3 {
        Bezier::Quadratic(at(sp.p1))
    } else {
        Bezier::Cubic([at(sp.p1), at(sp.p2)])
    };
    (at(sp.end), control)
}

/// The end point (nine axes), centre and plane normal of a canonical arc. The normal points
/// so that a counter-clockwise arc (positive rotation) turns right-handed about it.
fn arc_geometry(
    arc: &CanonArc,
    plane: Plane,
    from: &[f64; 9],
) -> ([f64; 9], [f64; 3], [f64; 3], u32) {
    let mut end = *from;
    end[3] = arc.a;
    end[4] = arc.b;
    end[5] = arc.c;
    end[6] = arc.u;
    end[7] = arc.v;
    end[8] = arc.w;
    // (first, second, normal axis) indices.
    let (f, s, n) = match plane {
        Plane::XY | Plane::UV => (0, 1, 2),
        Plane::XZ | Plane::WU => (2, 0, 1),
        Plane::YZ | Plane::VW => (1, 2, 0),
    };
    end[f] = arc.first_end;
    end[s] = arc.second_end;
    end[n] = arc.axis_end_point;
    let mut centre = [0.0; 3];
    centre[f] = arc.first_axis;
    centre[s] = arc.second_axis;
    centre[n] = from[n];
    let mut normal = [0.0; 3];
    normal[n] = if arc.rotation >= 0 { 1.0 } else { -1.0 };
    let turns = arc.rotation.unsigned_abs().saturating_sub(1);
    (end, centre, normal, turns)
}
