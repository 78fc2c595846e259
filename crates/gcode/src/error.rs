//! Errors: every one names the file, line and column it was found at and says in plain
//! words what is wrong.

use std::fmt;
use std::sync::Arc;

/// What kind of error: a stable classification with a stable [`ErrorKind::code`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ErrorKind {
    /// The text cannot be read: bad character, bad number, unbalanced brackets or comment.
    Syntax,
    /// A letter or code the dialect does not know.
    UnknownWord,
    /// A word appears twice, or two codes of one modal group are on one block.
    Conflict,
    /// A code needs a word that is missing (axis word for G1, P for G4, ...).
    MissingWord,
    /// A word is present where nothing uses it.
    UnusedWord,
    /// A value is out of its range (negative feed, tool number not in the table, ...).
    BadValue,
    /// Arc geometry: radius mismatch, impossible R format, zero radius.
    Arc,
    /// An expression cannot be evaluated (division by zero, domain error, undefined
    /// parameter).
    Expression,
    /// O-word structure: undefined subroutine, unterminated block, misplaced endsub.
    Flow,
    /// The machine state forbids the command (zero feed, spindle stopped for a cycle,
    /// command not allowed with cutter compensation on, ...).
    State,
    /// A file could not be read or written.
    Io,
}

impl ErrorKind {
    /// Stable machine-readable code, e.g. `G-SYNTAX`.
    pub fn code(self) -> &'static str {
        match self {
            ErrorKind::Syntax => "G-SYNTAX",
            ErrorKind::UnknownWord => "G-UNKNOWN",
            ErrorKind::Conflict => "G-CONFLICT",
            ErrorKind::MissingWord => "G-MISSING",
            ErrorKind::UnusedWord => "G-UNUSED",
            ErrorKind::BadValue => "G-VALUE",
            ErrorKind::Arc => "G-ARC",
            ErrorKind::Expression => "G-EXPR",
            ErrorKind::Flow => "G-FLOW",
            ErrorKind::State => "G-STATE",
            ErrorKind::Io => "G-IO",
        }
    }
}

/// An interpreter error with its place in the program.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub struct GcodeError {
    /// Classification.
    pub kind: ErrorKind,
    /// Name of the file (as given when it was opened; `<mdi>` for MDI lines).
    pub file: Arc<str>,
    /// 1-based line number (0 when no line is concerned, e.g. a missing file).
    pub line: u32,
    /// 1-based column of the offending character or word (0 for the whole line).
    pub column: u32,
    /// What is wrong, in plain words.
    pub message: String,
}

impl GcodeError {
    /// Stable machine-readable code of the error's kind.
    pub fn code(&self) -> &'static str {
        self.kind.code()
    }
}

impl fmt::Display for GcodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}:{}:{}: {}",
            self.file, self.line, self.column, self.message
        )
    }
}
