//! `rtcnc-plc`: an IEC 61131-3 Structured Text soft PLC for machine logic.
//!
//! Source is compiled once ([`compile`], [`compile_file`]) into a [`Program`]: a tree of
//! typed operations over a flat slot memory, with every name resolved. A [`Runtime`] is
//! one instance of a program; the caller (the motion kernel's PLC task, a test, the CLI)
//! calls [`Runtime::scan`] every period with the current PLC time. A scan reads the input
//! image, runs the programs of the due tasks, writes the output image; it allocates
//! nothing, takes no locks and never reads the OS clock, so it runs the same in virtual
//! and in real time. Runtime faults (division by zero, index out of range, subrange
//! violation, watchdog budget) stop the PLC, drive outputs to their safe values and come
//! back as a [`Fault`] value.
//!
//! On a real-time path: [`Runtime::scan`], [`Runtime::is_due`] and the reads and writes of
//! resolved variables of elementary types ([`Runtime::read`], [`Runtime::write`]; a refused
//! write's error names the type, which allocates). Set-up and tools only (they allocate):
//! [`compile`], [`compile_file`], [`Runtime::new`], [`Runtime::resolve`],
//! [`Runtime::read_name`] and every value of a `STRING` type. Each public function's doc
//! says it in a line of its own, `Real-time: yes (...)` or `Real-time: no (why)`;
//! `crates/kernel/tests/real_time_docs.rs` checks that every one has it.
//!
//! ```
//! use std::{sync::Arc, time::Duration};
//! let src = "PROGRAM Main
//!   VAR start : BOOL; t : TON; lamp : BOOL; END_VAR
//!   t(IN := start, PT := T#20ms);
//!   lamp := t.Q;
//! END_PROGRAM";
//! let program = Arc::new(rtcnc_plc::compile(src, "main.st").unwrap());
//! let mut plc = rtcnc_plc::Runtime::new(program);
//! let start = plc.resolve("start").unwrap();
//! plc.write(&start, &rtcnc_plc::Value::Bool(true)).unwrap();
//! for k in 0..6 {
//!     plc.scan(Duration::from_millis(4 * k)).unwrap();
//! }
//! assert_eq!(plc.read_name("lamp").unwrap(), rtcnc_plc::Value::Bool(true));
//! assert_eq!(plc.read_name("t.ET").unwrap(), rtcnc_plc::Value::Time(20_000_000));
//! ```

#![forbid(unsafe_code)]

mod ast;
mod builtins;
mod charset;
mod compiler;
mod dates;
mod error;
mod lexer;
mod parser;
mod plcopen;
mod program;
mod runtime;
mod signals;
mod stdfb;
mod strings;
pub mod types;
mod value;
mod vm;

use std::path::Path;

pub use charset::SourceEncoding;

/// Which implicit conversions the compiler makes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Conversions {
    /// IEC 61131-3's: along the widening chains only (the default).
    #[default]
    Iec,
    /// CODESYS's, which libraries written for it rely on: bit strings (BYTE, WORD, DWORD,
    /// LWORD) take arithmetic as the unsigned integers of their width and mix with
    /// integers, and any integer or bit string is assigned or passed to any other (the
    /// low bits kept, as `*_TO_*` does) or to a real.
    Codesys,
}
pub use error::{
    CompileError, CompileErrors, ErrorKind, Fault, FaultKind, LoadError, Pos, Warning,
};
pub use lexer::{AddrSize, Area, DirectAddr};
pub use plcopen::{AxisConfig, AxisState, AxisStatus, DriveFeedback, error_id as motion_error_id};
pub use program::{Program, TaskDesc, VariableInfo};
pub use runtime::{
    MonitorError, Restart, RetainReport, RetainSnapshot, Runtime, RuntimeOptions, VarRef,
};
pub use signals::{ConfigError, Direction, PlcConfig, Signal, SignalKind};
pub use stdfb::StdFb;
pub use value::{FmtTime, Value, ValueError, parse_time};

/// Choices of dialect the source needs.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CompileOptions {
    /// `(* (* *) *)` nests (IEC 61131-3 3rd edition, CODESYS, TwinCAT; the default).
    /// Sources written for tools where a comment ends at the first `*)` need `false`.
    pub nested_comments: bool,
    /// How [`compile_files`] reads a file's bytes (the default: UTF-8 when valid, else
    /// Windows-1252 as CODESYS 2.3 writes).
    pub encoding: SourceEncoding,
    /// Implicit conversions: IEC's (the default) or CODESYS's.
    pub conversions: Conversions,
}

impl Default for CompileOptions {
    fn default() -> Self {
        CompileOptions {
            nested_comments: true,
            encoding: SourceEncoding::Auto,
            conversions: Conversions::Iec,
        }
    }
}

/// Compiles Structured Text source; `file` names the source in error messages.
///
/// Real-time: no (allocates).
pub fn compile(source: &str, file: &str) -> Result<Program, CompileErrors> {
    compiler::compile(&[(source, file)], &CompileOptions::default())
}

/// Compiles one program from several sources (`(text, file name)`: global variable
/// lists, type declarations, POUs), as CODESYS and TwinCAT projects keep them. Errors and
/// faults name the file and the line in it.
///
/// Real-time: no (allocates).
pub fn compile_sources(
    sources: &[(&str, &str)],
    options: &CompileOptions,
) -> Result<Program, CompileErrors> {
    compiler::compile(sources, options)
}

/// Reads and compiles a Structured Text file.
///
/// Real-time: no (allocates, reads a file).
pub fn compile_file(path: &Path) -> Result<Program, LoadError> {
    compile_files(&[path], &CompileOptions::default())
}

/// Reads and compiles the files of one program, in the order given, each read as
/// `options.encoding` says.
///
/// Real-time: no (allocates, reads the files).
pub fn compile_files(paths: &[&Path], options: &CompileOptions) -> Result<Program, LoadError> {
    let mut texts = Vec::with_capacity(paths.len());
    for path in paths {
        let io_error = |source| LoadError::Io {
            path: path.display().to_string(),
            source,
        };
        let bytes = std::fs::read(path).map_err(io_error)?;
        let text = charset::decode_source(&bytes, options.encoding)
            .ok_or_else(|| {
                io_error(std::io::Error::new(
                    std::io::ErrorKind::InvalidData,
                    "not valid UTF-8 (read it as Windows-1252 with the encoding option)",
                ))
            })?
            .into_owned();
        texts.push((text, path.display().to_string()));
    }
    let sources: Vec<(&str, &str)> = texts
        .iter()
        .map(|(t, f)| (t.as_str(), f.as_str()))
        .collect();
    compile_sources(&sources, options).map_err(LoadError::Compile)
}
