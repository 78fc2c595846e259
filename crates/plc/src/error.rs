//! Compile errors (with file, line and column) and runtime faults.

use std::fmt;
use std::sync::Arc;

/// A position in a source file (1-based line and column, columns count bytes).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Pos {
    /// Line, starting at 1.
    pub line: u32,
    /// Column, starting at 1.
    pub col: u32,
}

/// What kind of compile error it is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorKind {
    /// The text does not follow the grammar.
    Syntax,
    /// A name is used that is not declared.
    Undeclared,
    /// A name is declared twice in one scope.
    Duplicate,
    /// Operand or assigned value has the wrong type.
    TypeMismatch,
    /// A call has a missing, unknown, surplus or ill-typed argument.
    WrongArgument,
    /// Assignment to a CONSTANT.
    AssignToConstant,
    /// Assignment to an input (VAR_INPUT of the POU, an `%I` variable, or an FB output from outside).
    AssignToInput,
    /// A construct that is valid but not supported here, or a semantic rule broken.
    Invalid,
}

impl ErrorKind {
    /// Stable short code of the error kind.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn code(self) -> &'static str {
        match self {
            ErrorKind::Syntax => "syntax",
            ErrorKind::Undeclared => "undeclared",
            ErrorKind::Duplicate => "duplicate",
            ErrorKind::TypeMismatch => "type-mismatch",
            ErrorKind::WrongArgument => "wrong-argument",
            ErrorKind::AssignToConstant => "assign-to-constant",
            ErrorKind::AssignToInput => "assign-to-input",
            ErrorKind::Invalid => "invalid",
        }
    }
}

/// One compile error: where and what.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{file}:{}:{}: error[{}]: {message}", pos.line, pos.col, kind.code())]
pub struct CompileError {
    /// The file name given to the compiler.
    pub file: String,
    /// Line and column.
    pub pos: Pos,
    /// Error class.
    pub kind: ErrorKind,
    /// Plain message.
    pub message: String,
}

impl CompileError {
    pub(crate) fn new(file: &str, pos: Pos, kind: ErrorKind, message: impl Into<String>) -> Self {
        CompileError {
            file: file.to_string(),
            pos,
            kind,
            message: message.into(),
        }
    }
    /// Stable code of the error kind.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn code(&self) -> &'static str {
        self.kind.code()
    }
}

/// A construct the compiler accepts but a reader should look at (CODESYS and TwinCAT
/// accept it too, with the same warning).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{file}:{}:{}: warning[{code}]: {message}", pos.line, pos.col)]
pub struct Warning {
    /// The file name given to the compiler.
    pub file: String,
    /// Line and column.
    pub pos: Pos,
    /// Stable short code (`assign-to-input`).
    pub code: &'static str,
    /// Plain message.
    pub message: String,
}

/// All errors found in one compilation (at least one).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CompileErrors(pub Vec<CompileError>);

impl CompileErrors {
    /// The first error (there is always one).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn first(&self) -> Option<&CompileError> {
        self.0.first()
    }
}

impl fmt::Display for CompileErrors {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, e) in self.0.iter().enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            write!(f, "{e}")?;
        }
        Ok(())
    }
}

impl std::error::Error for CompileErrors {}

impl From<CompileError> for CompileErrors {
    fn from(e: CompileError) -> Self {
        CompileErrors(vec![e])
    }
}

/// Error of [`crate::compile_file`]: the file could not be read or did not compile.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// Reading the file failed.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The path.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// The source has compile errors.
    #[error("{0}")]
    Compile(CompileErrors),
}

impl LoadError {
    /// Stable code.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn code(&self) -> &'static str {
        match self {
            LoadError::Io { .. } => "io",
            LoadError::Compile(_) => "compile",
        }
    }
}

/// What went wrong during a scan.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FaultKind {
    /// Integer or real division (or MOD) by zero.
    DivisionByZero,
    /// An array index outside the declared bounds.
    IndexOutOfRange {
        /// The index used.
        index: i64,
        /// Lower bound.
        low: i64,
        /// Upper bound.
        high: i64,
    },
    /// A value assigned to a subrange variable lies outside it.
    SubrangeViolation {
        /// The value.
        value: i64,
        /// Lower bound.
        low: i64,
        /// Upper bound.
        high: i64,
    },
    /// The scan executed more statements and loop iterations than its budget allows.
    WatchdogExceeded {
        /// The budget that was exceeded.
        budget: u64,
    },
    /// A FOR loop with a step of zero.
    ZeroForStep,
    /// A pointer, reference or interface that points nowhere was used, or an interface
    /// holds an instance of no type that implements the method called.
    NullReference,
    /// A pointer was used whose target (with the bytes read or written there) is not
    /// inside the program's memory.
    PointerOutOfRange {
        /// The address accessed.
        address: u64,
    },
}

/// A runtime fault: the PLC stopped, its outputs went to their safe values.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("PLC fault [{}] in {pou} line {line}: {}", self.code(), self.describe())]
pub struct Fault {
    /// What went wrong.
    pub kind: FaultKind,
    /// Name of the POU (program, function block type or function) that was running.
    pub pou: Arc<str>,
    /// Source line of the statement that faulted.
    pub line: u32,
    /// Number of the scan (1-based since start or restart) that faulted.
    pub scan: u64,
}

impl Fault {
    /// Stable code of the fault kind.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn code(&self) -> &'static str {
        match self.kind {
            FaultKind::DivisionByZero => "division-by-zero",
            FaultKind::IndexOutOfRange { .. } => "index-out-of-range",
            FaultKind::SubrangeViolation { .. } => "subrange-violation",
            FaultKind::WatchdogExceeded { .. } => "watchdog",
            FaultKind::ZeroForStep => "zero-for-step",
            FaultKind::NullReference => "null-reference",
            FaultKind::PointerOutOfRange { .. } => "pointer-out-of-range",
        }
    }
    /// Plain message.
    ///
    /// Real-time: no (allocates).
    pub fn describe(&self) -> String {
        match self.kind {
            FaultKind::DivisionByZero => "division by zero".into(),
            FaultKind::IndexOutOfRange { index, low, high } => {
                format!("array index {index} outside {low}..{high}")
            }
            FaultKind::SubrangeViolation { value, low, high } => {
                format!("value {value} outside subrange {low}..{high}")
            }
            FaultKind::WatchdogExceeded { budget } => {
                format!(
                    "scan exceeded its watchdog budget of {budget} statements and loop iterations"
                )
            }
            FaultKind::ZeroForStep => "FOR loop with step 0".into(),
            FaultKind::NullReference => {
                "a pointer, reference or interface that points to nothing was used".into()
            }
            FaultKind::PointerOutOfRange { address } => {
                format!("pointer access at address {address} outside the PLC's memory")
            }
        }
    }
}
