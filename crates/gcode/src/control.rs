//! O-word control flow: subroutine definitions, calls and returns (also Fanuc M98/M99),
//! if/elseif/else, while, do-while, repeat, break and continue. Blocks that are not run are
//! skipped by reading lines without executing them; loops and calls jump back by file
//! offset, so nothing of the program is kept in memory.

use std::path::PathBuf;

use crate::block::{self, Block, OKeyword};
use crate::canon::{FileId, Source};
use crate::error::{ErrorKind, GcodeError};
use crate::interp::{Interpreter, ModalState};
use crate::source::{Location, ReadLineError};

/// Deepest subroutine nesting (LinuxCNC: 10 levels).
const MAX_CALL_DEPTH: usize = 10;
/// Deepest loop / if nesting.
const MAX_NESTING: usize = 64;

/// Kind of an open loop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum LoopKind {
    While,
    Do,
    Repeat,
}

#[derive(Clone, Debug)]
pub(crate) struct LoopFrame {
    label: Box<str>,
    kind: LoopKind,
    /// While: the `while` line; Do and Repeat: the line after `do` / `repeat`.
    start: Location,
    remaining: u64,
}

#[derive(Clone, Debug)]
pub(crate) struct CallFrame {
    pub(crate) label: Box<str>,
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
pub(crate) struct SubDef {
    body: Location,
}

impl Interpreter {
    // ----- o-word control flow -----

    pub(crate) fn control(&mut self, b: &mut Block, kw: OKeyword) -> Result<(), GcodeError> {
        let col = usize::from(b.o_col) + 1;
        let label: Box<str> = b.o_label.as_str().into();
        let arg = b.o_args.first().copied();
        match kw {
            OKeyword::Sub => {
                // A definition met in the flow of the program: remember it, skip its body.
                let body = self.next_line_location()?;
                self.subs.insert(label.clone(), SubDef { body });
                self.skip_to(&label, &[OKeyword::EndSub], col)?;
            }
            OKeyword::Fanuc => {
                // A bare O number (a Fanuc program or subprogram number): remembered for M98,
                // otherwise the flow goes on through it, as in LinuxCNC.
                if let Some(body) = self.src.next_location() {
                    self.subs.insert(label.clone(), SubDef { body });
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
                    None => {
                        self.value = 0.0;
                        self.value_returned = false;
                    }
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

    pub(crate) fn end_repeat(&mut self, label: &str, col: usize) -> Result<(), GcodeError> {
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

    pub(crate) fn push_loop(
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

    pub(crate) fn push_if(&mut self, label: &str, col: usize) -> Result<(), GcodeError> {
        if self.ifs.len() >= MAX_NESTING {
            return Err(self.error_at(ErrorKind::Flow, col, "if blocks nested too deeply"));
        }
        self.ifs.push(label.into());
        Ok(())
    }

    pub(crate) fn pop_if(&mut self, label: &str) {
        if let Some(i) = self.ifs.iter().rposition(|l| **l == *label) {
            self.ifs.truncate(i);
        }
    }

    /// The condition of `if` (or of a skipped-to `elseif`) was false: find the branch to
    /// run.
    pub(crate) fn if_false(&mut self, label: &str, col: usize) -> Result<(), GcodeError> {
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
    pub(crate) fn skip_to(
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
                    self.at_eof = true;
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
                    self.source = self.src.line_start.source();
                    break Err(self.error_at(ErrorKind::Syntax, 0, crate::interp::TOO_LONG));
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

    pub(crate) fn next_line_location(&self) -> Result<Location, GcodeError> {
        self.src
            .next_location()
            .ok_or_else(|| self.error_at(ErrorKind::Flow, 0, "o-word control needs a file"))
    }

    pub(crate) fn jump(&mut self, loc: Location) -> Result<(), GcodeError> {
        self.src.jump(loc).map_err(|e| self.io_error(e))
    }

    /// Finds the definition of subroutine `label`: known already, further on in the current
    /// file, or in `label.ngc` on the subroutine path.
    pub(crate) fn find_sub(
        &mut self,
        label: &str,
        fanuc: bool,
        col: usize,
    ) -> Result<SubDef, GcodeError> {
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

    pub(crate) fn call(&mut self, label: &str, args: &[f64], col: usize) -> Result<(), GcodeError> {
        if self.calls.len() >= MAX_CALL_DEPTH {
            return Err(self.error_at(ErrorKind::Flow, col, "subroutines nested too deeply"));
        }
        if args.len() > 30 {
            return Err(self.error_at(ErrorKind::Flow, col, "more than 30 subroutine arguments"));
        }
        // Where to come back to (nowhere for an MDI call), taken before the search moves
        // the reading position.
        let ret = match self.src.next_location() {
            Some(l) => l,
            None => Location {
                file: FileId::MAX,
                offset: 0,
                line: 0,
            },
        };
        let def = self.find_sub(label, false, col)?;
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
    pub(crate) fn m98(&mut self, b: &Block) -> Result<(), GcodeError> {
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
        let ret = self.next_line_location()?;
        let def = self.find_sub(&label, true, col)?;
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

    pub(crate) fn return_from_call(&mut self) -> Result<(), GcodeError> {
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
        self.state.g92_applied = self.params.get(crate::params::sys::G92_APPLIED) != 0.0;
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
}
