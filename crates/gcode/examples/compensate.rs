//! Interprets a G-code program, compensates it and prints the canonical commands as
//! LinuxCNC's `rs274` prints them: the interpreter -> compensation -> printer chain that
//! `rtcnc check --canon` and the kernel use.
//!
//! `cargo run --release --example compensate -- PROGRAM.ngc [TOOL.tbl]`
//! (the tool table is read in inches, as rs274 reads it).

use std::io::Write;
use std::process::ExitCode;

use rtcnc_gcode::compensation::Compensator;
use rtcnc_gcode::{Interpreter, Parameters, Settings, ToolTable};

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(program) = args.first() else {
        eprintln!("usage: compensate PROGRAM.ngc [TOOL.tbl]");
        return ExitCode::from(2);
    };
    let tools = match args.get(1).map(|p| ToolTable::load(p.as_ref())) {
        Some(Ok(t)) => t,
        Some(Err(e)) => {
            eprintln!("{e}");
            return ExitCode::from(2);
        }
        None => ToolTable::new(),
    };
    let mut interp = Interpreter::new(Settings::rs274(), tools, Parameters::new());
    if let Err(e) = interp.open(program) {
        eprintln!("{e}");
        return ExitCode::from(1);
    }
    let mut stage = Compensator::new();
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::with_capacity(1 << 16, stdout.lock());
    let mut buf = Vec::with_capacity(1 << 16);
    let mut status = ExitCode::SUCCESS;
    let mut done = false;
    while !done {
        match interp.next_canon() {
            Some(Ok(c)) => {
                if let Err(e) = stage.push(c) {
                    // Errors name the file the block came from.
                    let name = interp.file_name(e.at.file);
                    eprintln!("{}", e.into_gcode_error(name));
                    status = ExitCode::from(1);
                    done = true;
                }
            }
            Some(Err(e)) => {
                // Like rs274: stop at the first error, what is held is dropped.
                eprintln!("{e}");
                status = ExitCode::from(1);
                done = true;
            }
            None => {
                stage.finish();
                done = true;
            }
        }
        while let Some(c) = stage.pop() {
            c.write_rs274(&mut buf, false);
        }
        if buf.len() >= 60 * 1024 || done {
            if out.write_all(&buf).is_err() {
                return ExitCode::from(1);
            }
            buf.clear();
        }
    }
    let _ = out.write_all(b"ON_RESET()\n");
    let _ = out.flush();
    status
}
