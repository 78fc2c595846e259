//! `rtcnc check PROGRAM`: interpret a G-code program without a machine, report every error,
//! or print the canonical command stream in the text form of LinuxCNC's `rs274`.

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use rtcnc_gcode::canon::{CanonCommand, Units};
use rtcnc_gcode::compensation::Compensator;
use rtcnc_gcode::{Interpreter, Parameters, Settings, ToolTable};

/// Arguments of `rtcnc check`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The G-code program.
    program: PathBuf,
    /// Tool table in LinuxCNC `.tbl` format. Without it any tool number is accepted, with
    /// no offsets.
    #[arg(long, value_name = "FILE")]
    tool_table: Option<PathBuf>,
    /// Parameter file in LinuxCNC `.var` format (work offsets, G92, homes); read only.
    #[arg(long, value_name = "FILE")]
    params: Option<PathBuf>,
    /// Print the canonical commands, one per line, as LinuxCNC's rs274 prints them.
    #[arg(long)]
    canon: bool,
    /// Prefix every canonical line with rs274's N-word column.
    #[arg(long, requires = "canon")]
    line_numbers: bool,
    /// Units of the tool table and parameter file (rs274 uses inches).
    #[arg(long, value_name = "mm|inch", default_value = "mm")]
    user_units: String,
    /// Folder searched for subroutine files (repeatable).
    #[arg(long = "subroutine-path", value_name = "DIR")]
    subroutine_path: Vec<PathBuf>,
    /// Skip lines that start with '/'.
    #[arg(long)]
    block_delete: bool,
}

/// Most errors reported before giving up.
const MAX_ERRORS: usize = 100;

/// Writes what is buffered, then the error, so the error follows the output before it.
fn report_error(
    out: &mut impl Write,
    buf: &mut Vec<u8>,
    error: &impl std::fmt::Display,
) -> anyhow::Result<()> {
    out.write_all(buf)?;
    buf.clear();
    out.flush()?;
    eprintln!("{error}");
    Ok(())
}

/// Runs `rtcnc check`.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let user_units = match args.user_units.as_str() {
        "mm" => Units::Mm,
        "inch" | "in" => Units::Inches,
        other => anyhow::bail!("--user-units must be mm or inch, not {other}"),
    };
    let tools = match &args.tool_table {
        Some(p) => ToolTable::load(p)?,
        None => ToolTable::new(),
    };
    let params = match &args.params {
        Some(p) => Parameters::load(p)?,
        None => Parameters::new(),
    };
    let settings = Settings {
        user_units,
        accept_unknown_tools: args.tool_table.is_none(),
        subroutine_path: args.subroutine_path.clone(),
        block_delete: args.block_delete,
        ..Settings::default()
    };
    let mut interp = Interpreter::new(settings, tools, params);
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::with_capacity(1 << 16, stdout.lock());
    let mut buf = Vec::with_capacity(1 << 16);
    let mut commands: u64 = 0;
    let mut errors = 0usize;
    interp
        .open(&args.program)
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    // Cutter radius compensation is a stage of its own after the interpreter; what it
    // emits is what rs274 prints, since LinuxCNC compensates inside its interpreter.
    let mut stage = Compensator::new();
    let mut done = false;
    while !done {
        match interp.next_canon() {
            Some(Ok(c)) => {
                if let CanonCommand::Print(text) = &c.command {
                    eprintln!("{text}");
                }
                if let Err(e) = stage.push(c) {
                    errors += 1;
                    let name = interp.file_name(e.at.file);
                    report_error(&mut out, &mut buf, &e.into_gcode_error(name))?;
                    // The stage cannot go on past a refused move: its geometry is unknown.
                    done = true;
                }
            }
            Some(Err(e)) => {
                errors += 1;
                report_error(&mut out, &mut buf, &e)?;
                // rs274 stops at the first error; without --canon keep looking for more.
                done = args.canon || errors >= MAX_ERRORS || !interp.resume_after_error();
            }
            None => {
                stage.finish();
                done = true;
            }
        }
        while let Some(c) = stage.pop() {
            commands += 1;
            if args.canon {
                c.write_rs274(&mut buf, args.line_numbers);
            }
        }
        if buf.len() >= 60 * 1024 {
            out.write_all(&buf)
                .context("writing the canonical output")?;
            buf.clear();
        }
    }
    if args.canon {
        // rs274 resets the interpreter as it exits.
        if args.line_numbers {
            buf.extend_from_slice(b"N..... ");
        }
        buf.extend_from_slice(b"ON_RESET()\n");
    }
    out.write_all(&buf)?;
    out.flush()?;
    drop(out);
    if !args.canon {
        if errors == 0 {
            println!(
                "{}: no errors, {commands} canonical commands",
                args.program.display()
            );
        } else {
            println!("{}: {errors} error(s)", args.program.display());
        }
    }
    Ok(if errors == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}
