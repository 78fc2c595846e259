//! The interpreter: its set-up, modal state and public API. It reads a line when the caller
//! pulls a command and nothing is queued, runs o-word control (`control.rs`) or executes the
//! block (`exec.rs` and the modules it calls), and queues the canonical commands.

use std::collections::{HashMap, VecDeque};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::arc_tolerance::ArcRadiusTolerance;
use crate::block::{self, Block, ParamRef, ParamSource};
use crate::canon::{
    Canon, CanonCommand, CompensationSide, FeedMode, FileId, NurbsPoint, PathMode, Plane, Pose,
    Source, SpindleDirection, Units,
};
use crate::control::{CallFrame, LoopFrame, SubDef};
use crate::error::{ErrorKind, GcodeError};
use crate::params::{Parameters, sys};
use crate::source::{Location, ReadLineError, Sources};
use crate::tools::ToolTable;

/// The error of a line longer than [`crate::source::MAX_LINE`] bytes.
pub(crate) const TOO_LONG: &str = "line too long (more than 16 KiB)";

/// How the interpreter is set up for a machine.
#[derive(Clone, Debug)]
pub struct Settings {
    /// Units of the tool table and of the length values in the parameter file (LinuxCNC's
    /// "user units"; rs274 uses inches).
    pub user_units: Units,
    /// Length units at start-up (G21 unless told otherwise).
    pub initial_units: Units,
    /// Folders searched for `NAME.ngc` when `o<NAME> call` finds no definition.
    pub subroutine_path: Vec<PathBuf>,
    /// Skip lines starting with `/`.
    pub block_delete: bool,
    /// Absolute part of the tolerance of the radius difference of centre-format arcs in
    /// millimetre programs (LinuxCNC's `CENTER_ARC_RADIUS_TOLERANCE_MM`; see
    /// [`ArcRadiusTolerance`]).
    pub arc_radius_tolerance_mm: f64,
    /// Accept tool numbers that are not in the tool table, as tools with no offsets and
    /// their number for a pocket (to check a program without the machine's table).
    pub accept_unknown_tools: bool,
    /// After a probing move (G38.x) or an input wait (M66), stop reading the program until
    /// the machine reports the result ([`Interpreter::probe_result`],
    /// [`Interpreter::input_result`]), since later lines may read it (#5061-#5070, #5399).
    /// When false the results are modelled as LinuxCNC's stand-alone interpreter does.
    pub wait_for_machine: bool,
    /// A program that runs this many lines of loops or subroutines without issuing any
    /// command is stopped with an error (an endless o-word loop would otherwise never
    /// return). Lines read straight through the file are not counted: they end.
    pub max_lines_without_output: u64,
    /// The same in inch programs (`CENTER_ARC_RADIUS_TOLERANCE_INCH`), in inches.
    pub arc_radius_tolerance_inch: f64,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            user_units: Units::Mm,
            initial_units: Units::Mm,
            subroutine_path: Vec::new(),
            block_delete: false,
            arc_radius_tolerance_mm: ArcRadiusTolerance::MM.absolute,
            arc_radius_tolerance_inch: ArcRadiusTolerance::INCH.absolute,
            max_lines_without_output: 10_000_000,
            wait_for_machine: false,
            accept_unknown_tools: false,
        }
    }
}

impl Settings {
    /// The tolerance of the radius difference of centre-format arcs in `units`.
    pub fn arc_radius_tolerance(&self, units: Units) -> ArcRadiusTolerance {
        let absolute = match units {
            Units::Mm => self.arc_radius_tolerance_mm,
            Units::Inches => self.arc_radius_tolerance_inch,
        };
        ArcRadiusTolerance {
            absolute,
            ..ArcRadiusTolerance::default_for(units)
        }
    }

    /// Settings as LinuxCNC's stand-alone `rs274` uses them (user units are inches).
    pub fn rs274() -> Settings {
        Settings {
            user_units: Units::Inches,
            ..Settings::default()
        }
    }
}

/// The modal state the program sees (what RS274/NGC calls the machine settings).
#[derive(Clone, Debug, PartialEq)]
pub struct ModalState {
    /// G20 / G21.
    pub units: Units,
    /// G17 .. G19.1.
    pub plane: Plane,
    /// G90 (true) / G91.
    pub absolute: bool,
    /// G90.1 (true) / G91.1.
    pub ijk_absolute: bool,
    /// G93 / G94 / G95.
    pub feed_mode: FeedMode,
    /// F, in current units.
    pub feed_rate: f64,
    /// S.
    pub speed: f64,
    /// M3 / M4, `None` when stopped.
    pub spindle: Option<SpindleDirection>,
    /// G96 (with D in `css_max`) / G97.
    pub css: bool,
    /// D of G96.
    pub css_max: f64,
    /// Active motion mode in tenths (10 = G1, 800 = G80).
    pub motion: i32,
    /// G98 (true: back to the initial level) / G99 (R plane).
    pub retract_old_z: bool,
    /// G61 / G61.1 / G64 P.
    pub path_mode: PathMode,
    /// G64 Q.
    pub naivecam_tolerance: f64,
    /// G40 (None) / G41 / G42.
    pub cutter: Option<CompensationSide>,
    /// The G code of group 7 in tenths (400, 410, 411, 420, 421).
    pub cutter_gcode: i32,
    /// Group 8 in tenths (430, 431, 490).
    pub length_gcode: i32,
    /// Tool length offset in force, current units.
    pub tool_offset: Pose,
    /// Active coordinate system 1..=9 (G54..G59.3).
    pub origin_index: u8,
    /// Its offset, current units.
    pub g5x: Pose,
    /// Its XY rotation, degrees.
    pub rotation: f64,
    /// G92 offset, current units.
    pub g92: Pose,
    /// Current position in the active coordinate system, current units.
    pub position: Pose,
    /// M428 (true) / M429: tool-centre-point control. Positions are those of the tool tip
    /// in the work's frame while it is on (the machine's kinematics turns them into
    /// joints).
    pub tool_centre_point: bool,
    /// G92 offsets applied (#5210).
    pub g92_applied: bool,
    /// G7 (true) / G8.
    pub lathe_diameter: bool,
    /// M7.
    pub mist: bool,
    /// M8.
    pub flood: bool,
    /// M48/M50.
    pub feed_override: bool,
    /// M48/M51.
    pub speed_override: bool,
    /// M52.
    pub adaptive_feed: bool,
    /// M53.
    pub feed_hold: bool,
    /// Tool in the spindle.
    pub current_tool: i32,
    /// Its pocket.
    pub current_pocket: i32,
    /// Tool selected by T (-1: none).
    pub selected_tool: i32,
    /// Its pocket.
    pub selected_pocket: i32,
}

impl ModalState {
    fn new(units: Units) -> ModalState {
        ModalState {
            units,
            plane: Plane::XY,
            absolute: true,
            ijk_absolute: false,
            feed_mode: FeedMode::UnitsPerMinute,
            feed_rate: 0.0,
            speed: 0.0,
            spindle: None,
            css: false,
            css_max: 0.0,
            motion: 800,
            retract_old_z: false,
            path_mode: PathMode::Continuous { tolerance: 0.0 },
            naivecam_tolerance: 0.0,
            cutter: None,
            cutter_gcode: 400,
            length_gcode: 490,
            tool_offset: Pose::ZERO,
            origin_index: 1,
            g5x: Pose::ZERO,
            rotation: 0.0,
            g92: Pose::ZERO,
            position: Pose::ZERO,
            tool_centre_point: false,
            g92_applied: false,
            lathe_diameter: false,
            mist: false,
            flood: false,
            feed_override: true,
            speed_override: true,
            adaptive_feed: false,
            feed_hold: true,
            current_tool: 0,
            current_pocket: 0,
            selected_tool: -1,
            // As in LinuxCNC, M6 with no T changes to pocket 0 (no tool).
            selected_pocket: 0,
        }
    }
}

/// Sticky values of canned cycles.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct CycleMemory {
    pub r: f64,
    pub cc: f64,
    pub p: f64,
    pub q: f64,
    pub i: f64,
    pub j: f64,
    pub k: f64,
    pub initial_level: Option<f64>,
}

/// The RS274/NGC interpreter. Pull canonical commands with [`Interpreter::next_canon`] (or
/// iterate).
pub struct Interpreter {
    pub(crate) settings: Settings,
    pub(crate) tools: ToolTable,
    pub(crate) params: Parameters,
    pub(crate) state: ModalState,
    pub(crate) cycle: CycleMemory,
    pub(crate) out: VecDeque<Canon>,
    pub(crate) source: Source,
    /// Column of the word being executed (for errors).
    pub(crate) src: Sources,
    /// The block being executed; boxed so that taking it out to execute moves a pointer.
    pub(crate) block: Option<Box<Block>>,
    pub(crate) line_label: String,
    pub(crate) subs: HashMap<Box<str>, SubDef>,
    pub(crate) calls: Vec<CallFrame>,
    pub(crate) loops: Vec<LoopFrame>,
    /// Labels of open `if` blocks.
    pub(crate) ifs: Vec<Box<str>>,
    /// Saved state of M70 at the top level.
    pub(crate) top_saved: Option<Box<ModalState>>,
    /// The program is running (a file is open and not ended).
    pub(crate) running: bool,
    pub(crate) percent_seen: bool,
    /// A line other than blanks was read (a % after that closes, not opens).
    pub(crate) started: bool,
    pub(crate) failed: bool,
    /// Waiting for a probe or input result from the machine.
    pub(crate) waiting: bool,
    pub(crate) lines_without_output: u64,
    pub(crate) pending_error: Option<GcodeError>,
    pub(crate) at_eof: bool,
    /// The file could not be read: nothing after the error can be.
    pub(crate) unreadable: bool,
    /// Tool length offset in force at the last move (see `resync_position`).
    pub(crate) tool_at_last_move: Pose,
    pub(crate) value: f64,
    pub(crate) value_returned: bool,
    /// Control points of an open G5.2 block.
    pub(crate) nurbs: Vec<NurbsPoint>,
    /// Its order (L).
    pub(crate) nurbs_order: u32,
}

impl Interpreter {
    /// A new interpreter with this machine set-up, tool table and parameters (work offsets,
    /// G92, homes). The start-up commands (units, work offset, G92 offset, rotation) are
    /// queued at once.
    pub fn new(settings: Settings, tools: ToolTable, params: Parameters) -> Interpreter {
        let units = settings.initial_units;
        let mut it = Interpreter {
            settings,
            tools,
            params,
            state: ModalState::new(units),
            cycle: CycleMemory::default(),
            out: VecDeque::with_capacity(64),
            source: Source::default(),
            src: Sources::new(),
            block: Some(Box::default()),
            line_label: String::new(),
            subs: HashMap::new(),
            calls: Vec::new(),
            loops: Vec::new(),
            ifs: Vec::new(),
            top_saved: None,
            running: false,
            percent_seen: false,
            started: false,
            failed: false,
            waiting: false,
            lines_without_output: 0,
            pending_error: None,
            at_eof: false,
            unreadable: false,
            tool_at_last_move: Pose::ZERO,
            value: 0.0,
            value_returned: false,
            nurbs: Vec::new(),
            nurbs_order: 3,
        };
        // #5599 enables (DEBUG,...) messages.
        it.params.set(5599, 1.0);
        it.startup();
        it
    }

    /// The start-up sequence of LinuxCNC's interpreter: units, the coordinate system of
    /// #5220 with its offset and rotation, the G92 offset (if #5210 says it is applied).
    fn startup(&mut self) {
        self.emit(CanonCommand::UseLengthUnits(self.state.units));
        let index = self.params.get(sys::COORD_SYSTEM).round();
        let index = if (1.0..=9.0).contains(&index) {
            index as u8
        } else {
            1
        };
        self.state.origin_index = index;
        self.state.g5x = self.coord_system_from_params(index);
        self.state.rotation = self.params.get(sys::G54 + 20 * usize::from(index - 1) + 9);
        self.emit(CanonCommand::SetG5xOffset {
            index,
            offset: self.state.g5x,
        });
        if self.params.get(sys::G92_APPLIED) != 0.0 {
            self.state.g92 = self.pose_from_params(sys::G92);
            self.state.g92_applied = true;
        }
        self.emit(CanonCommand::SetG92Offset(self.state.g92));
        self.emit(CanonCommand::SetXyRotation(self.state.rotation));
        self.emit(CanonCommand::SetFeedReference);
        self.emit(CanonCommand::OnReset);
    }

    /// Opens a program file to run. Lines are read as commands are pulled.
    pub fn open(&mut self, path: impl AsRef<Path>) -> Result<(), GcodeError> {
        let path = path.as_ref();
        self.reset_run();
        let name = path.display().to_string();
        let id = self.src.open(path, &name).map_err(|e| GcodeError {
            kind: ErrorKind::Io,
            file: Arc::from(name.as_str()),
            line: 0,
            column: 0,
            message: format!("cannot open the program: {e}"),
        })?;
        self.src
            .jump(Location {
                file: id,
                offset: 0,
                line: 1,
            })
            .map_err(|e| self.io_error(e))?;
        self.running = true;
        Ok(())
    }

    /// Runs a program held in memory; `name` is used in errors.
    pub fn open_text(&mut self, name: &str, text: impl Into<Vec<u8>>) -> Result<(), GcodeError> {
        self.reset_run();
        let id = self
            .src
            .open_text(name, text.into())
            .map_err(|e| self.io_error(e))?;
        self.src
            .jump(Location {
                file: id,
                offset: 0,
                line: 1,
            })
            .map_err(|e| self.io_error(e))?;
        self.running = true;
        Ok(())
    }

    fn reset_run(&mut self) {
        self.src.clear();
        self.subs.clear();
        self.calls.clear();
        self.loops.clear();
        self.ifs.clear();
        self.params.reset_scopes();
        self.failed = false;
        self.pending_error = None;
        self.at_eof = false;
        self.unreadable = false;
        self.percent_seen = false;
        self.started = false;
        self.lines_without_output = 0;
        self.waiting = false;
        self.nurbs.clear();
    }

    /// Executes one line of MDI. Its commands are queued for [`Interpreter::next_canon`].
    /// Subroutines may be called (from files on the subroutine path); other o-word control
    /// is refused.
    pub fn execute_mdi(&mut self, line: &str) -> Result<(), GcodeError> {
        if self.running {
            return Err(self.error_at(ErrorKind::State, 0, "a program is running"));
        }
        self.failed = false;
        self.lines_without_output = 0;
        self.src.set_mdi_line(line);
        self.source = Source {
            file: FileId::MAX,
            line: 1,
            n: None,
        };
        let result = self.run_line();
        if result.is_ok() && self.src.current().is_some() {
            // An MDI call: run the subroutine to its end.
            self.running = true;
        }
        result.map(|_| ())
    }

    /// The next canonical command, reading and executing as many lines as needed. `None`
    /// when the program has ended (or after an error).
    pub fn next_canon(&mut self) -> Option<Result<Canon, GcodeError>> {
        loop {
            if let Some(c) = self.out.pop_front() {
                self.lines_without_output = 0;
                return Some(Ok(c));
            }
            if let Some(e) = self.pending_error.take() {
                return Some(Err(e));
            }
            if !self.running || self.failed || self.waiting {
                return None;
            }
            // Only lines run again can run forever: a loop's or a subroutine's (read
            // straight through, a file of any length ends).
            if !self.loops.is_empty() || !self.calls.is_empty() {
                self.lines_without_output += 1;
            }
            if self.lines_without_output > self.settings.max_lines_without_output {
                self.failed = true;
                self.running = false;
                return Some(Err(self.error_at(
                    ErrorKind::Flow,
                    0,
                    format!(
                        "{} lines ran without producing any command: endless loop?",
                        self.settings.max_lines_without_output
                    ),
                )));
            }
            if let Err(e) = self.step() {
                // What the failing block issued before the error still comes out first,
                // as in rs274.
                self.failed = true;
                self.running = false;
                if self.out.is_empty() {
                    return Some(Err(e));
                }
                self.pending_error = Some(e);
            }
        }
    }

    /// Stops the running program (operator abort): queued commands are dropped, open
    /// subroutine calls and loops are forgotten. The modal state stays as it is.
    pub fn abort(&mut self) {
        self.out.clear();
        self.pending_error = None;
        self.running = false;
        self.waiting = false;
        self.calls.clear();
        self.loops.clear();
        self.ifs.clear();
        self.params.reset_scopes();
        self.nurbs.clear();
    }

    /// True when the interpreter waits for [`Interpreter::probe_result`] or
    /// [`Interpreter::input_result`] before reading on (see [`Settings::wait_for_machine`]).
    pub fn is_waiting(&self) -> bool {
        self.waiting
    }

    /// The result of the last probing move: where the probe tripped (machine coordinates,
    /// current length units) and whether it did. The controlled point is taken to be at
    /// `stopped_at` (machine coordinates) afterwards. Reading resumes.
    pub fn probe_result(&mut self, tripped_at: Pose, tripped: bool, stopped_at: Pose) {
        let p = self.program_from_machine(&tripped_at).to_array();
        for (i, v) in p.iter().enumerate() {
            self.params.set(sys::PROBE + i, *v);
        }
        self.params
            .set(sys::PROBE_OK, if tripped { 1.0 } else { 0.0 });
        self.state.position = self.program_from_machine(&stopped_at);
        self.waiting = false;
    }

    /// The machine's kinematics changed (M428, M429): the same joints now stand for the
    /// machine position `machine` (machine coordinates, current length units); the program
    /// position follows, so that later moves, incremental words and omitted axes start
    /// from there.
    pub fn kinematics_switched(&mut self, machine: Pose) {
        self.state.position = self.program_from_machine(&machine);
    }

    /// The controlled point in machine coordinates (current length units): the program
    /// position with the offsets in force.
    pub fn machine_position_now(&self) -> Pose {
        self.machine_position()
    }

    /// The result of the last M66 wait (the input's value, -1 on time-out): stored in
    /// #5399. Reading resumes.
    pub fn input_result(&mut self, value: f64) {
        self.params.set(sys::INPUT, value);
        self.waiting = false;
    }

    /// After an error from a program file, continue with the line after the one that
    /// failed (to report further errors; the state may be off after a failed line). Returns
    /// false when there is nothing left to read, the file cannot be read, or the error is
    /// inside a loop or subroutine (going on would repeat it).
    pub fn resume_after_error(&mut self) -> bool {
        if !self.failed || self.src.current().is_none() || self.at_eof || self.unreadable {
            return false;
        }
        if !self.loops.is_empty() || !self.calls.is_empty() {
            // Inside a loop or a subroutine the failed line would come round again, and
            // the same error with it, as often as the loop runs (or forever).
            return false;
        }
        self.failed = false;
        self.running = true;
        true
    }

    /// Current modal state.
    pub fn modal_state(&self) -> &ModalState {
        &self.state
    }

    /// The parameters (save them with [`Parameters::save`] to persist offsets).
    pub fn parameters(&self) -> &Parameters {
        &self.params
    }

    /// The tool table, with changes made by G10 L1/L10/L11.
    pub fn tool_table(&self) -> &ToolTable {
        &self.tools
    }

    /// Name of a source file as given when it was opened (`<mdi>` for MDI lines).
    pub fn file_name(&self, id: FileId) -> Arc<str> {
        self.src.name(id)
    }

    /// True while a program (or an MDI subroutine call) has lines left to run.
    pub fn is_running(&self) -> bool {
        self.running && !self.failed
    }

    /// Reads and executes one line.
    fn step(&mut self) -> Result<(), GcodeError> {
        match self.src.read_line() {
            Ok(true) => {}
            Ok(false) => {
                self.at_eof = true;
                return self.end_of_file();
            }
            Err(ReadLineError::TooLong) => {
                self.source = self.src.line_start.source();
                return Err(self.error_at(ErrorKind::Syntax, 0, TOO_LONG));
            }
            Err(ReadLineError::Io(e)) => return Err(self.io_error(e)),
        }
        self.source = self.src.line_start.source();
        self.run_line().map(|_| ())
    }

    fn end_of_file(&mut self) -> Result<(), GcodeError> {
        if !self.calls.is_empty() {
            let label = self
                .calls
                .last()
                .map(|c| c.label.clone())
                .unwrap_or_default();
            return Err(self.error_at(
                ErrorKind::Flow,
                0,
                format!("file ended inside subroutine o<{label}> (missing endsub or M99)"),
            ));
        }
        if self.src.current() == Some(FileId::MAX) || self.src.current().is_none() {
            self.running = false;
            return Ok(());
        }
        Err(self.error_at(
            ErrorKind::Flow,
            0,
            "file ended with no percent sign or program end (M2, M30)",
        ))
    }

    /// Reads the current line into the block and runs it. Returns false if the line was
    /// skipped.
    pub(crate) fn run_line(&mut self) -> Result<bool, GcodeError> {
        let mut block = self.block.take().unwrap_or_default();
        let r = self.run_block(&mut block);
        self.block = Some(block);
        r
    }

    fn run_block(&mut self, b: &mut Block) -> Result<bool, GcodeError> {
        let line = std::mem::take(&mut self.src.line);
        let r = block::read_block(&line, &*self, b);
        self.src.line = line;
        if let Err(e) = r {
            return Err(self.error_at(e.kind, e.column + 1, e.message));
        }
        if b.block_delete && self.settings.block_delete {
            return Ok(false);
        }
        if b.percent {
            if !self.started && self.source.file == 0 {
                // The first line that is not blank may open the program with %.
                self.percent_seen = true;
                self.started = true;
                return Ok(false);
            }
            if self.percent_seen && self.calls.is_empty() && self.src.current() == Some(0) {
                // Closing % ends the program at once.
                self.emit(CanonCommand::Finish);
                self.running = false;
                return Ok(true);
            }
            return Err(self.error_at(
                ErrorKind::Syntax,
                1,
                "'%' only opens and closes a program (the first line must be % too)",
            ));
        }
        if !self.started
            && (b.other_words || b.has_comment || b.o_keyword.is_some() || b.n.is_some())
        {
            self.started = true;
        }
        self.source.n = b.n;
        if let Some(kw) = b.o_keyword {
            self.control(b, kw)?;
            return Ok(true);
        }
        if b.m98 {
            self.m98(b)?;
        }
        // Parameter settings take effect after the whole line is read, before it runs.
        if !b.assigns.is_empty() {
            self.assign(b);
        }
        let more = self.execute(b)?;
        if !more {
            self.program_ended()?;
        }
        Ok(true)
    }

    pub(crate) fn assign(&mut self, b: &mut Block) {
        for (target, value) in b.assigns.drain(..) {
            match target {
                ParamRef::Numbered(i) => self.params.set(i, value),
                ParamRef::Named(name) => self.params.set_named(&name, value),
            }
        }
    }

    /// After M2/M30 (or M99 at the top level): stop, and note a missing closing `%`.
    fn program_ended(&mut self) -> Result<(), GcodeError> {
        if self.percent_seen {
            let mut found = false;
            while let Ok(true) = self.src.read_line() {
                let t = self.src.line.trim_ascii();
                if t == b"%" {
                    found = true;
                    break;
                }
            }
            if !found {
                self.emit(CanonCommand::Comment(
                    "interpreter: percent sign missing from end of file".into(),
                ));
            }
        }
        self.running = false;
        self.calls.clear();
        self.loops.clear();
        self.ifs.clear();
        self.params.reset_scopes();
        self.nurbs.clear();
        Ok(())
    }

    // ----- helpers shared with execution -----

    pub(crate) fn emit(&mut self, command: CanonCommand) {
        if matches!(
            command,
            CanonCommand::StraightTraverse(_)
                | CanonCommand::StraightFeed(_)
                | CanonCommand::ArcFeed(_)
                | CanonCommand::SplineFeed(_)
                | CanonCommand::NurbsFeed(_)
                | CanonCommand::StraightProbe { .. }
                | CanonCommand::RigidTap { .. }
        ) {
            self.tool_at_last_move = self.state.tool_offset;
        }
        self.out.push_back(Canon {
            source: self.source,
            command,
        });
    }

    pub(crate) fn error_at(
        &self,
        kind: ErrorKind,
        column: usize,
        message: impl Into<String>,
    ) -> GcodeError {
        GcodeError {
            kind,
            file: self.src.name(self.source.file),
            line: self.source.line,
            column: column as u32,
            message: message.into(),
        }
    }

    pub(crate) fn io_error(&mut self, e: std::io::Error) -> GcodeError {
        self.unreadable = true;
        self.error_at(ErrorKind::Io, 0, format!("cannot read: {e}"))
    }

    /// Converts a length from user units to program units.
    pub(crate) fn user_to_program(&self, v: f64) -> f64 {
        v * self.settings.user_units.mm_per_unit() / self.state.units.mm_per_unit()
    }

    /// Converts a length from program units to user units.
    pub(crate) fn program_to_user(&self, v: f64) -> f64 {
        v * self.state.units.mm_per_unit() / self.settings.user_units.mm_per_unit()
    }

    /// Nine values from parameters `base..base+9` (user units) as a pose in program
    /// units (A, B, C are angles and not converted).
    pub(crate) fn pose_from_params(&self, base: usize) -> Pose {
        let mut v = [0.0; 9];
        for (i, x) in v.iter_mut().enumerate() {
            let p = self.params.get(base + i);
            *x = if (3..6).contains(&i) {
                p
            } else {
                self.user_to_program(p)
            };
        }
        Pose::from_array(v)
    }

    /// Stores a pose (program units) into parameters `base..base+9` (user units).
    pub(crate) fn pose_to_params(&mut self, base: usize, pose: &Pose) {
        for (i, x) in pose.to_array().iter().enumerate() {
            let v = if (3..6).contains(&i) {
                *x
            } else {
                self.program_to_user(*x)
            };
            self.params.set(base + i, v);
        }
    }

    pub(crate) fn coord_system_from_params(&self, index: u8) -> Pose {
        self.pose_from_params(sys::G54 + 20 * usize::from(index.saturating_sub(1)))
    }

    /// Position in machine coordinates (offsets, rotation and tool offset applied).
    pub(crate) fn machine_position(&self) -> Pose {
        let s = &self.state;
        let p = s.position;
        let (x, y) = rotate(p.x + s.g92.x, p.y + s.g92.y, s.rotation);
        let mut m = p.to_array();
        let g92 = s.g92.to_array();
        let g5x = s.g5x.to_array();
        let tool = s.tool_offset.to_array();
        for i in 0..9 {
            m[i] += g92[i] + g5x[i] + tool[i];
        }
        m[0] = x + s.g5x.x + s.tool_offset.x;
        m[1] = y + s.g5x.y + s.tool_offset.y;
        Pose::from_array(m)
    }

    /// Program position for a machine position, with the current offsets.
    pub(crate) fn program_from_machine(&self, m: &Pose) -> Pose {
        let s = &self.state;
        let mut p = m.to_array();
        let g92 = s.g92.to_array();
        let g5x = s.g5x.to_array();
        let tool = s.tool_offset.to_array();
        for i in 0..9 {
            p[i] -= g92[i] + g5x[i] + tool[i];
        }
        let (x, y) = rotate(
            m.x - s.g5x.x - s.tool_offset.x,
            m.y - s.g5x.y - s.tool_offset.y,
            -s.rotation,
        );
        p[0] = x - s.g92.x;
        p[1] = y - s.g92.y;
        Pose::from_array(p)
    }

    fn predefined(&self, name: &str) -> Option<f64> {
        let s = &self.state;
        let b = |c: bool| if c { 1.0 } else { 0.0 };
        let m = || self.machine_position();
        Some(match name {
            "vmajor" => 2.9,
            "vminor" => 0.0,
            "line" => f64::from(self.source.line),
            "motion_mode" => f64::from(s.motion),
            "plane" => match s.plane {
                Plane::XY => 170.0,
                Plane::XZ => 180.0,
                Plane::YZ => 190.0,
                Plane::UV => 171.0,
                Plane::WU => 181.0,
                Plane::VW => 191.0,
            },
            "ccomp" => f64::from(s.cutter_gcode),
            "metric" => b(s.units == Units::Mm),
            "imperial" => b(s.units == Units::Inches),
            "absolute" => b(s.absolute),
            "incremental" => b(!s.absolute),
            "inverse_time" => b(s.feed_mode == FeedMode::InverseTime),
            "units_per_minute" => b(s.feed_mode == FeedMode::UnitsPerMinute),
            "units_per_rev" => b(s.feed_mode == FeedMode::UnitsPerRevolution),
            "coord_system" => match s.origin_index {
                1..=6 => 530.0 + 10.0 * f64::from(s.origin_index),
                i => 590.0 + f64::from(i - 6),
            },
            "tool_offset" => b(s.length_gcode != 490),
            "retract_r_plane" => b(!s.retract_old_z),
            "retract_old_z" => b(s.retract_old_z),
            "spindle_rpm_mode" => b(!s.css),
            "spindle_css_mode" => b(s.css),
            "ijk_absolute_mode" => b(s.ijk_absolute),
            "lathe_diameter_mode" => b(s.lathe_diameter),
            "lathe_radius_mode" => b(!s.lathe_diameter),
            "spindle_on" => b(s.spindle.is_some()),
            "spindle_cw" => b(s.spindle == Some(SpindleDirection::Clockwise)),
            "mist" => b(s.mist),
            "flood" => b(s.flood),
            "speed_override" => b(s.speed_override),
            "feed_override" => b(s.feed_override),
            "adaptive_feed" => b(s.adaptive_feed),
            "feed_hold" => b(s.feed_hold),
            "feed" => s.feed_rate,
            "rpm" => s.speed,
            "x" => s.position.x,
            "y" => s.position.y,
            "z" => s.position.z,
            "a" => s.position.a,
            "b" => s.position.b,
            "c" => s.position.c,
            "u" => s.position.u,
            "v" => s.position.v,
            "w" => s.position.w,
            "abs_x" => m().x,
            "abs_y" => m().y,
            "abs_z" => m().z,
            "abs_a" => m().a,
            "abs_b" => m().b,
            "abs_c" => m().c,
            "abs_u" => m().u,
            "abs_v" => m().v,
            "abs_w" => m().w,
            "current_tool" => f64::from(s.current_tool),
            "current_pocket" => f64::from(s.current_pocket),
            "selected_tool" => f64::from(s.selected_tool),
            "selected_pocket" => f64::from(s.selected_pocket),
            "value" => self.value,
            "value_returned" => b(self.value_returned),
            "call_level" => self.calls.len() as f64,
            "remap_level" => 0.0,
            "task" => 0.0,
            _ => return None,
        })
    }
}

impl ParamSource for Interpreter {
    fn numbered(&self, index: usize) -> f64 {
        // The current position (#5420..#5428) is computed, not stored.
        if (sys::POSITION..sys::POSITION + 9).contains(&index) {
            return self.state.position.to_array()[index - sys::POSITION];
        }
        self.params.get(index)
    }

    fn named(&self, name: &str) -> Option<f64> {
        if let Some(n) = name.strip_prefix('_') {
            if let Some(v) = self.predefined(n) {
                return Some(v);
            }
        }
        self.params.named(name)
    }
}

impl Iterator for Interpreter {
    type Item = Result<Canon, GcodeError>;

    fn next(&mut self) -> Option<Self::Item> {
        self.next_canon()
    }
}

/// Rotates (x, y) by `degrees` counter-clockwise.
pub(crate) fn rotate(x: f64, y: f64, degrees: f64) -> (f64, f64) {
    if degrees == 0.0 {
        return (x, y);
    }
    let (s, c) = degrees.to_radians().sin_cos();
    (x * c - y * s, x * s + y * c)
}

/// Formats the text of `(DEBUG,...)` / `(PRINT,...)`: `#n` and `#<name>` are replaced by
/// their values (`%f`-style, 6 decimals).
pub(crate) fn substitute(text: &str, params: &dyn ParamSource) -> String {
    let bytes = text.as_bytes();
    let mut out = String::with_capacity(text.len() + 16);
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'#' {
            if bytes.get(i + 1) == Some(&b'<') {
                if let Some(end) = text[i + 2..].find('>') {
                    let name: String = text[i + 2..i + 2 + end]
                        .chars()
                        .filter(|c| !c.is_whitespace())
                        .map(|c| c.to_ascii_lowercase())
                        .collect();
                    match params.named(&name) {
                        Some(v) => out.push_str(&format!("{v:.6}")),
                        None => out.push_str("######"),
                    }
                    i += 2 + end + 1;
                    continue;
                }
            } else {
                let digits = bytes[i + 1..]
                    .iter()
                    .take_while(|c| c.is_ascii_digit())
                    .count();
                if digits > 0 {
                    let index: usize = text[i + 1..i + 1 + digits].parse().unwrap_or(0);
                    if (1..=block::MAX_PARAMETER).contains(&index) {
                        out.push_str(&format!("{:.6}", params.numbered(index)));
                    } else {
                        out.push_str("######");
                    }
                    i += 1 + digits;
                    continue;
                }
            }
        }
        let ch = text[i..].chars().next().unwrap_or(' ');
        out.push(ch);
        i += ch.len_utf8().max(1);
    }
    out
}
