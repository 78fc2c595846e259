//! The interpreter: reads blocks on demand, runs o-word control flow, and executes blocks
//! into canonical commands that the caller pulls one at a time.

use std::collections::{HashMap, VecDeque};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::block::{self, Block, OKeyword, ParamRef, ParamSource};
use crate::canon::{
    Canon, CanonCommand, CompensationSide, FeedMode, FileId, PathMode, Plane, Pose, Source,
    SpindleDirection, Units,
};
use crate::error::{ErrorKind, GcodeError};
use crate::params::{Parameters, sys};
use crate::source::{Location, ReadLineError, Sources};
use crate::tools::ToolTable;

/// Deepest subroutine nesting (LinuxCNC: 10 levels).
const MAX_CALL_DEPTH: usize = 10;
/// Deepest loop / if nesting.
const MAX_NESTING: usize = 64;

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
    /// Tolerance of the radius difference of centre-format arcs (mm).
    pub arc_radius_tolerance_mm: f64,
    /// The same in inches.
    pub arc_radius_tolerance_inch: f64,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            user_units: Units::Mm,
            initial_units: Units::Mm,
            subroutine_path: Vec::new(),
            block_delete: false,
            arc_radius_tolerance_mm: 2.0 * 0.01 * std::f64::consts::SQRT_2,
            arc_radius_tolerance_inch: 2.0 * 0.001 * std::f64::consts::SQRT_2,
        }
    }
}

impl Settings {
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

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum LoopKind {
    While,
    Do,
    Repeat,
}

#[derive(Clone, Debug)]
struct LoopFrame {
    label: Box<str>,
    kind: LoopKind,
    /// While: the `while` line; Do and Repeat: the line after `do` / `repeat`.
    start: Location,
    remaining: u64,
}

#[derive(Clone, Debug)]
struct CallFrame {
    label: Box<str>,
    ret: Location,
    saved: [f64; 30],
    loops: usize,
    ifs: usize,
    /// Fanuc M98: remaining repetitions and where the subprogram body starts.
    m98_remaining: u64,
    body: Location,
    fanuc: bool,
    saved_state: Option<Box<ModalState>>,
    restore_on_return: bool,
}

/// Where a definition lives: the line after `o<name> sub` (or after `O1000`).
#[derive(Clone, Copy, Debug)]
struct SubDef {
    body: Location,
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
    block: Option<Box<Block>>,
    line_label: String,
    subs: HashMap<Box<str>, SubDef>,
    calls: Vec<CallFrame>,
    loops: Vec<LoopFrame>,
    /// Labels of open `if` blocks.
    ifs: Vec<Box<str>>,
    /// Saved state of M70 at the top level.
    top_saved: Option<Box<ModalState>>,
    /// The program is running (a file is open and not ended).
    running: bool,
    percent_seen: bool,
    failed: bool,
    pending_error: Option<GcodeError>,
    at_eof: bool,
    pub(crate) value: f64,
    pub(crate) value_returned: bool,
    pub(crate) probe_pending: bool,
    pub(crate) spline_last_pq: Option<[f64; 2]>,
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
            failed: false,
            pending_error: None,
            at_eof: false,
            value: 0.0,
            value_returned: false,
            probe_pending: false,
            spline_last_pq: None,
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
        }
        self.emit(CanonCommand::SetG92Offset(self.state.g92));
        self.emit(CanonCommand::SetXyRotation(self.state.rotation));
        self.emit(CanonCommand::SetFeedReference);
        self.emit(CanonCommand::OnReset);
    }

    /// Opens a program file to run. Lines are read as commands are pulled.
    pub fn open(&mut self, path: impl AsRef<Path>) -> Result<(), GcodeError> {
        let path = path.as_ref();
        self.src.clear();
        self.subs.clear();
        self.calls.clear();
        self.loops.clear();
        self.ifs.clear();
        self.params.reset_scopes();
        self.failed = false;
        self.at_eof = false;
        self.percent_seen = false;
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

    /// Executes one line of MDI. Its commands are queued for [`Interpreter::next_canon`].
    /// Subroutines may be called (from files on the subroutine path); other o-word control
    /// is refused.
    pub fn execute_mdi(&mut self, line: &str) -> Result<(), GcodeError> {
        if self.running {
            return Err(self.error_at(ErrorKind::State, 0, "a program is running"));
        }
        self.failed = false;
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
                return Some(Ok(c));
            }
            if let Some(e) = self.pending_error.take() {
                return Some(Err(e));
            }
            if !self.running || self.failed {
                return None;
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

    /// After an error from a program file, continue with the line after the one that
    /// failed (to report further errors; the state may be off after a failed line). Returns
    /// false when there is nothing left to read.
    pub fn resume_after_error(&mut self) -> bool {
        if !self.failed || self.src.current().is_none() || self.at_eof {
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
                return Err(self.error_at(ErrorKind::Syntax, 0, "line too long"));
            }
            Err(ReadLineError::Io(e)) => return Err(self.io_error(e)),
        }
        let loc = self.src.line_start;
        self.source = Source {
            file: loc.file,
            line: loc.line,
            n: None,
        };
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
    fn run_line(&mut self) -> Result<bool, GcodeError> {
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
            if !self.percent_seen && self.source.line == 1 && self.source.file == 0 {
                self.percent_seen = true;
                return Ok(false);
            }
            if self.calls.is_empty() && self.src.current() == Some(0) {
                // Closing % ends the program at once.
                self.emit(CanonCommand::Finish);
                self.running = false;
                return Ok(true);
            }
            return Ok(false);
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

    fn assign(&mut self, b: &mut Block) {
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
        Ok(())
    }

    // ----- o-word control flow -----

    fn control(&mut self, b: &mut Block, kw: OKeyword) -> Result<(), GcodeError> {
        let col = usize::from(b.o_col) + 1;
        let label: Box<str> = b.o_label.as_str().into();
        let arg = b.o_args.first().copied();
        match kw {
            OKeyword::Sub | OKeyword::Fanuc => {
                // A definition met in the flow of the program: remember it, skip its body.
                let body = self.next_line_location()?;
                self.subs.insert(label.clone(), SubDef { body });
                if kw == OKeyword::Fanuc {
                    self.skip_fanuc_body(&label, col)?;
                } else {
                    self.skip_to(&label, &[OKeyword::EndSub], col)?;
                }
            }
            OKeyword::EndSub | OKeyword::Return => {
                if kw == OKeyword::Return && self.calls.is_empty() {
                    return Err(self.error_at(
                        ErrorKind::Flow,
                        col,
                        format!("o{label} return outside a subroutine"),
                    ));
                }
                match arg {
                    Some(v) => {
                        self.value = v;
                        self.value_returned = true;
                    }
                    None => self.value_returned = false,
                }
                if self.calls.is_empty() {
                    return Err(self.error_at(
                        ErrorKind::Flow,
                        col,
                        format!("o{label} endsub without a call"),
                    ));
                }
                self.return_from_call()?;
            }
            OKeyword::Call => self.call(&label, &b.o_args, col)?,
            OKeyword::If => {
                self.push_if(&label, col)?;
                if arg.unwrap_or(0.0) == 0.0 {
                    self.if_false(&label, col)?;
                }
            }
            OKeyword::ElseIf | OKeyword::Else => {
                // Reached by executing a taken branch: skip to the end.
                self.skip_to(&label, &[OKeyword::EndIf], col)?;
                self.pop_if(&label);
            }
            OKeyword::EndIf => self.pop_if(&label),
            OKeyword::Do => {
                let start = self.next_line_location()?;
                self.push_loop(label, LoopKind::Do, start, 0, col)?;
            }
            OKeyword::While => {
                let is_do_tail = self
                    .loops
                    .last()
                    .is_some_and(|l| l.kind == LoopKind::Do && *l.label == *label);
                if is_do_tail {
                    if arg.unwrap_or(0.0) != 0.0 {
                        let start = self.loops.last().map(|l| l.start);
                        if let Some(start) = start {
                            self.jump(start)?;
                        }
                    } else {
                        self.loops.pop();
                    }
                } else {
                    let here = self.src.line_start;
                    let active = self
                        .loops
                        .last()
                        .is_some_and(|l| l.kind == LoopKind::While && l.start == here);
                    if arg.unwrap_or(0.0) != 0.0 {
                        if !active {
                            self.push_loop(label, LoopKind::While, here, 0, col)?;
                        }
                    } else {
                        if active {
                            self.loops.pop();
                        }
                        self.skip_to(&label, &[OKeyword::EndWhile], col)?;
                    }
                }
            }
            OKeyword::EndWhile => match self.loops.last() {
                Some(l) if l.kind == LoopKind::While && *l.label == *label => {
                    let start = l.start;
                    self.jump(start)?;
                }
                _ => {
                    return Err(self.error_at(
                        ErrorKind::Flow,
                        col,
                        format!("o{label} endwhile without a matching while"),
                    ));
                }
            },
            OKeyword::Repeat => {
                let n = arg.unwrap_or(0.0).round();
                if n >= 1.0 {
                    let start = self.next_line_location()?;
                    self.push_loop(label, LoopKind::Repeat, start, n as u64, col)?;
                } else {
                    self.skip_to(&label, &[OKeyword::EndRepeat], col)?;
                }
            }
            OKeyword::EndRepeat => self.end_repeat(&label, col)?,
            OKeyword::Break => {
                let Some(l) = self.loops.pop() else {
                    return Err(self.error_at(ErrorKind::Flow, col, "break outside a loop"));
                };
                let end = match l.kind {
                    LoopKind::While => OKeyword::EndWhile,
                    LoopKind::Repeat => OKeyword::EndRepeat,
                    LoopKind::Do => OKeyword::While,
                };
                self.skip_to(&l.label, &[end], col)?;
            }
            OKeyword::Continue => {
                let Some(l) = self.loops.last().cloned() else {
                    return Err(self.error_at(ErrorKind::Flow, col, "continue outside a loop"));
                };
                match l.kind {
                    LoopKind::While => self.jump(l.start)?,
                    LoopKind::Repeat => {
                        self.skip_to(&l.label, &[OKeyword::EndRepeat], col)?;
                        self.end_repeat(&l.label, col)?;
                    }
                    LoopKind::Do => {
                        // Evaluate the tail `while` as if reached normally.
                        self.skip_to(&l.label, &[OKeyword::While], col)?;
                        self.source.line = self.src.line_start.line;
                        self.run_line()?;
                    }
                }
            }
        }
        Ok(())
    }

    fn end_repeat(&mut self, label: &str, col: usize) -> Result<(), GcodeError> {
        match self.loops.last_mut() {
            Some(l) if l.kind == LoopKind::Repeat && *l.label == *label => {
                l.remaining = l.remaining.saturating_sub(1);
                if l.remaining > 0 {
                    let start = l.start;
                    self.jump(start)?;
                } else {
                    self.loops.pop();
                }
                Ok(())
            }
            _ => Err(self.error_at(
                ErrorKind::Flow,
                col,
                format!("o{label} endrepeat without a matching repeat"),
            )),
        }
    }

    fn push_loop(
        &mut self,
        label: Box<str>,
        kind: LoopKind,
        start: Location,
        remaining: u64,
        col: usize,
    ) -> Result<(), GcodeError> {
        if self.loops.len() >= MAX_NESTING {
            return Err(self.error_at(ErrorKind::Flow, col, "loops nested too deeply"));
        }
        self.loops.push(LoopFrame {
            label,
            kind,
            start,
            remaining,
        });
        Ok(())
    }

    fn push_if(&mut self, label: &str, col: usize) -> Result<(), GcodeError> {
        if self.ifs.len() >= MAX_NESTING {
            return Err(self.error_at(ErrorKind::Flow, col, "if blocks nested too deeply"));
        }
        self.ifs.push(label.into());
        Ok(())
    }

    fn pop_if(&mut self, label: &str) {
        if let Some(i) = self.ifs.iter().rposition(|l| **l == *label) {
            self.ifs.truncate(i);
        }
    }

    /// The condition of `if` (or of a skipped-to `elseif`) was false: find the branch to
    /// run.
    fn if_false(&mut self, label: &str, col: usize) -> Result<(), GcodeError> {
        loop {
            let kw = self.skip_to(
                label,
                &[OKeyword::ElseIf, OKeyword::Else, OKeyword::EndIf],
                col,
            )?;
            match kw {
                OKeyword::ElseIf => {
                    // Evaluate its condition.
                    let loc = self.src.line_start;
                    self.source = Source {
                        file: loc.file,
                        line: loc.line,
                        n: None,
                    };
                    let mut b = self.block.take().unwrap_or_default();
                    let line = std::mem::take(&mut self.src.line);
                    let r = block::read_block(&line, &*self, &mut b);
                    self.src.line = line;
                    let cond = b.o_args.first().copied().unwrap_or(0.0);
                    self.block = Some(b);
                    if let Err(e) = r {
                        return Err(self.error_at(e.kind, e.column + 1, e.message));
                    }
                    if cond != 0.0 {
                        return Ok(());
                    }
                }
                OKeyword::EndIf => {
                    self.pop_if(label);
                    return Ok(());
                }
                _ => return Ok(()),
            }
        }
    }

    /// Reads lines without executing them until an o-word with `label` and one of
    /// `targets`; that line is left in `self.src.line`. Nested definitions are skipped.
    fn skip_to(
        &mut self,
        label: &str,
        targets: &[OKeyword],
        col: usize,
    ) -> Result<OKeyword, GcodeError> {
        let opened = self.src.line_start;
        let mut l = std::mem::take(&mut self.line_label);
        let r = loop {
            match self.src.read_line() {
                Ok(true) => {}
                Ok(false) => {
                    break Err(GcodeError {
                        kind: ErrorKind::Flow,
                        file: self.src.name(opened.file),
                        line: opened.line,
                        column: col as u32,
                        message: format!(
                            "o{label} block is never closed (expected {})",
                            targets
                                .iter()
                                .map(|k| format!("{k:?}").to_lowercase())
                                .collect::<Vec<_>>()
                                .join(" or ")
                        ),
                    });
                }
                Err(ReadLineError::TooLong) => {
                    break Err(self.error_at(ErrorKind::Syntax, 0, "line too long"));
                }
                Err(ReadLineError::Io(e)) => break Err(self.io_error(e)),
            }
            if let Some(kw) = block::peek_oword(&self.src.line, &mut l) {
                if kw == OKeyword::Sub && l != label {
                    // Remember definitions we pass.
                    if let Some(body) = self.src.next_location() {
                        self.subs.insert(l.as_str().into(), SubDef { body });
                    }
                }
                if l == label && targets.contains(&kw) {
                    break Ok(kw);
                }
            }
        };
        self.line_label = l;
        r
    }

    /// Skips a Fanuc subprogram body (up to and including its M99 line).
    fn skip_fanuc_body(&mut self, label: &str, col: usize) -> Result<(), GcodeError> {
        let opened = self.src.line_start;
        loop {
            match self.src.read_line() {
                Ok(true) => {}
                Ok(false) => {
                    return Err(GcodeError {
                        kind: ErrorKind::Flow,
                        file: self.src.name(opened.file),
                        line: opened.line,
                        column: col as u32,
                        message: format!("subprogram O{label} has no M99"),
                    });
                }
                Err(ReadLineError::TooLong) => {
                    return Err(self.error_at(ErrorKind::Syntax, 0, "line too long"));
                }
                Err(ReadLineError::Io(e)) => return Err(self.io_error(e)),
            }
            if has_m99(&self.src.line) {
                return Ok(());
            }
        }
    }

    fn next_line_location(&self) -> Result<Location, GcodeError> {
        self.src
            .next_location()
            .ok_or_else(|| self.error_at(ErrorKind::Flow, 0, "o-word control needs a file"))
    }

    fn jump(&mut self, loc: Location) -> Result<(), GcodeError> {
        self.src.jump(loc).map_err(|e| self.io_error(e))
    }

    /// Finds the definition of subroutine `label`: known already, further on in the current
    /// file, or in `label.ngc` on the subroutine path.
    fn find_sub(&mut self, label: &str, fanuc: bool, col: usize) -> Result<SubDef, GcodeError> {
        if let Some(d) = self.subs.get(label) {
            return Ok(*d);
        }
        // Search forward in the current file, then come back.
        if let Some(resume) = self.src.next_location() {
            let mut l = std::mem::take(&mut self.line_label);
            let mut found = None;
            while let Ok(true) = self.src.read_line() {
                if let Some(kw) = block::peek_oword(&self.src.line, &mut l) {
                    if kw == OKeyword::Sub || kw == OKeyword::Fanuc {
                        if let Some(body) = self.src.next_location() {
                            let def = SubDef { body };
                            self.subs.insert(l.as_str().into(), def);
                            if l == label && (kw == OKeyword::Fanuc) == fanuc {
                                found = Some(def);
                                break;
                            }
                        }
                    }
                }
            }
            self.line_label = l;
            self.jump(resume)?;
            if let Some(d) = found {
                return Ok(d);
            }
        }
        // A file of its own on the subroutine path (or next to the program).
        let mut dirs: Vec<PathBuf> = self.settings.subroutine_path.clone();
        if let Some(dir) = self.src.path(0).and_then(|p| p.parent()) {
            dirs.push(dir.to_path_buf());
        }
        for dir in dirs {
            let path = dir.join(format!("{label}.ngc"));
            if !path.is_file() {
                continue;
            }
            let resume = self.src.next_location();
            let id = self
                .src
                .open(&path, &path.display().to_string())
                .map_err(|e| self.io_error(e))?;
            self.jump(Location {
                file: id,
                offset: 0,
                line: 1,
            })?;
            let mut l = std::mem::take(&mut self.line_label);
            let mut found = None;
            while let Ok(true) = self.src.read_line() {
                if let Some(OKeyword::Sub) = block::peek_oword(&self.src.line, &mut l) {
                    if l == label {
                        found = self.src.next_location();
                        break;
                    }
                }
            }
            self.line_label = l;
            if let Some(r) = resume {
                self.jump(r)?;
            }
            if let Some(body) = found {
                let def = SubDef { body };
                self.subs.insert(label.into(), def);
                return Ok(def);
            }
            return Err(self.error_at(
                ErrorKind::Flow,
                col,
                format!("{} does not define o<{label}> sub", path.display()),
            ));
        }
        Err(self.error_at(
            ErrorKind::Flow,
            col,
            format!("subroutine o<{label}> is not defined"),
        ))
    }

    fn call(&mut self, label: &str, args: &[f64], col: usize) -> Result<(), GcodeError> {
        if self.calls.len() >= MAX_CALL_DEPTH {
            return Err(self.error_at(ErrorKind::Flow, col, "subroutines nested too deeply"));
        }
        if args.len() > 30 {
            return Err(self.error_at(ErrorKind::Flow, col, "more than 30 subroutine arguments"));
        }
        let def = self.find_sub(label, false, col)?;
        let ret = match self.src.next_location() {
            Some(l) => l,
            None => Location {
                file: FileId::MAX,
                offset: 0,
                line: 0,
            },
        };
        let mut saved = [0.0; 30];
        for (i, s) in saved.iter_mut().enumerate() {
            *s = self.params.get(i + 1);
            self.params.set(i + 1, args.get(i).copied().unwrap_or(0.0));
        }
        self.calls.push(CallFrame {
            label: label.into(),
            ret,
            saved,
            loops: self.loops.len(),
            ifs: self.ifs.len(),
            m98_remaining: 0,
            body: def.body,
            fanuc: false,
            saved_state: None,
            restore_on_return: false,
        });
        self.params.push_scope();
        self.jump(def.body)
    }

    /// M98 P<n> L<count>: Fanuc-style call of subprogram O<n>; #1..#30 are shared.
    fn m98(&mut self, b: &Block) -> Result<(), GcodeError> {
        let col = usize::from(b.m_col[block::mg::USER]) + 1;
        let Some(p) = b.get(b'p') else {
            return Err(self.error_at(ErrorKind::MissingWord, col, "M98 needs a P word"));
        };
        let label = format!("{}", p.round() as i64);
        let count = b.get(b'l').map_or(1.0, f64::round);
        if count < 1.0 {
            return Ok(());
        }
        if self.calls.len() >= MAX_CALL_DEPTH {
            return Err(self.error_at(ErrorKind::Flow, col, "subroutines nested too deeply"));
        }
        let def = self.find_sub(&label, true, col)?;
        let ret = self.next_line_location()?;
        self.calls.push(CallFrame {
            label: label.into(),
            ret,
            saved: [0.0; 30],
            loops: self.loops.len(),
            ifs: self.ifs.len(),
            m98_remaining: count as u64,
            body: def.body,
            fanuc: true,
            saved_state: None,
            restore_on_return: false,
        });
        self.jump(def.body)
    }

    /// M99: end of a Fanuc subprogram (repeat or return); at the top level it ends the
    /// program.
    pub(crate) fn m99(&mut self) -> Result<bool, GcodeError> {
        match self.calls.last_mut() {
            Some(f) if f.fanuc => {
                f.m98_remaining = f.m98_remaining.saturating_sub(1);
                if f.m98_remaining > 0 {
                    let body = f.body;
                    self.jump(body)?;
                } else {
                    self.return_from_call()?;
                }
                Ok(true)
            }
            Some(_) => {
                self.return_from_call()?;
                Ok(true)
            }
            None => Ok(false),
        }
    }

    fn return_from_call(&mut self) -> Result<(), GcodeError> {
        let Some(frame) = self.calls.pop() else {
            return Ok(());
        };
        self.loops.truncate(frame.loops);
        self.ifs.truncate(frame.ifs);
        if !frame.fanuc {
            for (i, v) in frame.saved.iter().enumerate() {
                self.params.set(i + 1, *v);
            }
            self.params.pop_scope();
        }
        if frame.restore_on_return {
            if let Some(saved) = frame.saved_state {
                self.restore_state(&saved)?;
            }
        }
        if frame.ret.file == FileId::MAX {
            // Called from MDI: done.
            self.running = false;
            return Ok(());
        }
        self.jump(frame.ret)
    }

    /// M70 / M73: save the modal state in the current call level.
    pub(crate) fn save_state(&mut self, auto_restore: bool) {
        let s = Box::new(self.state.clone());
        match self.calls.last_mut() {
            Some(f) => {
                f.saved_state = Some(s);
                f.restore_on_return |= auto_restore;
            }
            None => self.top_saved = Some(s),
        }
    }

    /// M71: forget the saved state of this call level.
    pub(crate) fn invalidate_state(&mut self) {
        match self.calls.last_mut() {
            Some(f) => {
                f.saved_state = None;
                f.restore_on_return = false;
            }
            None => self.top_saved = None,
        }
    }

    /// The state M72 would restore.
    pub(crate) fn saved_state(&self) -> Option<ModalState> {
        match self.calls.last() {
            Some(f) => f.saved_state.as_deref().cloned(),
            None => self.top_saved.as_deref().cloned(),
        }
    }

    // ----- helpers shared with execution -----

    pub(crate) fn emit(&mut self, command: CanonCommand) {
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

    pub(crate) fn io_error(&self, e: std::io::Error) -> GcodeError {
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

/// True if the line holds an M99 word outside comments.
fn has_m99(line: &[u8]) -> bool {
    let mut compact = [0u8; 3];
    let mut n = 0;
    let mut in_comment = false;
    for &c in line {
        match c {
            b'(' => in_comment = true,
            b')' => in_comment = false,
            b';' if !in_comment => return false,
            b' ' | b'\t' => {}
            _ if in_comment => {}
            _ => {
                compact = [compact[1], compact[2], c.to_ascii_lowercase()];
                n += 1;
                if n >= 3 && &compact == b"m99" {
                    return true;
                }
            }
        }
    }
    false
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
