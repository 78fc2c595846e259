//! `rtcnc plc`: compile a Structured Text machine-logic program, or run it in virtual time.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, bail};
use clap::Subcommand;
use rtcnc_plc::{
    CompileOptions, Conversions, FmtTime, LoadError, Runtime, SourceEncoding, Value, VarRef,
    compile_files, parse_time,
};

/// How the source files are read and compiled.
#[derive(Debug, clap::Args)]
struct SourceArgs {
    /// A comment ends at the first `*)` (sources that rely on comments not nesting).
    #[arg(long)]
    flat_comments: bool,
    /// The files' encoding: `auto` reads UTF-8 when the file is valid UTF-8, else
    /// Windows-1252 (what CODESYS 2.3 exports).
    #[arg(long, value_enum, default_value = "auto")]
    encoding: Encoding,
    /// Implicit conversions: `iec` (along the widening chains) or `codesys` (bit strings
    /// compute as unsigned integers; any integer or bit string goes to any other).
    #[arg(long, value_enum, default_value = "iec")]
    conversions: ConversionsArg,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum ConversionsArg {
    Iec,
    Codesys,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum Encoding {
    Auto,
    #[value(name = "utf-8")]
    Utf8,
    #[value(name = "windows-1252", alias = "latin-1")]
    Windows1252,
}

/// Soft PLC: check or run a Structured Text program.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    command: PlcCommand,
}

#[derive(Debug, Subcommand)]
enum PlcCommand {
    /// Compile FILE.st (or the files of one program: global variable lists, types, POUs)
    /// and report errors and warnings with file, line and column.
    Check {
        /// The Structured Text sources of one program, in order.
        #[arg(required = true, num_args = 1..)]
        file: Vec<PathBuf>,
        #[command(flatten)]
        source: SourceArgs,
        /// Also list every variable that `run --watch` / `--set` can name.
        #[arg(long)]
        vars: bool,
    },
    /// Run FILE.st in virtual time and print the watched variables after every scan.
    Run {
        /// The Structured Text sources of one program, in order.
        #[arg(required = true, num_args = 1..)]
        file: Vec<PathBuf>,
        #[command(flatten)]
        source: SourceArgs,
        /// PLC configuration (TOML, as examples/plc/mill.toml): `[signals]` and
        /// `[safe_values]`, and `[axes]` for the PLCopen motion blocks' axes.
        #[arg(long)]
        config: Option<PathBuf>,
        /// Number of scans to run.
        #[arg(long)]
        scans: u64,
        /// Scan period (IEC duration: 4ms, T#1ms500us, 0.5s).
        #[arg(long, default_value = "4ms")]
        period: String,
        /// Force a variable: NAME=VALUE from the first scan, or NAME=VALUE@K from scan K on
        /// (repeatable; a later --set of the same name takes over from its scan).
        #[arg(long = "set", value_name = "NAME=VALUE[@SCAN]")]
        set: Vec<String>,
        /// Release a forced variable from scan SCAN on (repeatable): NAME@SCAN.
        #[arg(long = "unset", value_name = "NAME@SCAN")]
        unset: Vec<String>,
        /// Variable to print after every scan (repeatable): `x`, `Inst.timer.ET`, `a[2]`,
        /// `Inst.axis.Position`; a forced one shows `(F)` after its value.
        #[arg(long = "watch", value_name = "NAME")]
        watch: Vec<String>,
        /// Add a column with each scan's execution time on this computer (µs, wall
        /// time; the virtual PLC clock does not advance with it).
        #[arg(long)]
        timing: bool,
    },
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    match args.command {
        PlcCommand::Check { file, vars, source } => check(&file, &source, vars),
        PlcCommand::Run {
            file,
            source,
            config,
            scans,
            period,
            set,
            unset,
            watch,
            timing,
        } => run_scans(
            &file,
            &source,
            config.as_deref(),
            RunOptions {
                scans,
                period: &period,
                sets: &set,
                unsets: &unset,
                watch: &watch,
                timing,
            },
        ),
    }
}

fn shown(files: &[PathBuf]) -> String {
    let names: Vec<String> = files.iter().map(|f| f.display().to_string()).collect();
    names.join(", ")
}

fn load(
    files: &[PathBuf],
    source: &SourceArgs,
) -> anyhow::Result<Result<rtcnc_plc::Program, ExitCode>> {
    let paths: Vec<&Path> = files.iter().map(PathBuf::as_path).collect();
    let options = CompileOptions {
        nested_comments: !source.flat_comments,
        encoding: match source.encoding {
            Encoding::Auto => SourceEncoding::Auto,
            Encoding::Utf8 => SourceEncoding::Utf8,
            Encoding::Windows1252 => SourceEncoding::Windows1252,
        },
        conversions: match source.conversions {
            ConversionsArg::Iec => Conversions::Iec,
            ConversionsArg::Codesys => Conversions::Codesys,
        },
    };
    match compile_files(&paths, &options) {
        Ok(p) => {
            for w in p.warnings() {
                eprintln!("{w}");
            }
            Ok(Ok(p))
        }
        Err(LoadError::Compile(errors)) => {
            for e in &errors.0 {
                eprintln!("{e}");
            }
            eprintln!("{}: {} error(s)", shown(files), errors.0.len());
            Ok(Err(ExitCode::from(1)))
        }
        Err(e) => Err(e.into()),
    }
}

fn check(file: &[PathBuf], source: &SourceArgs, vars: bool) -> anyhow::Result<ExitCode> {
    let program = match load(file, source)? {
        Ok(p) => p,
        Err(code) => return Ok(code),
    };
    println!(
        "{}: ok: {} POUs, {} bytes of memory, images %I {} B, %Q {} B, %M {} B",
        shown(file),
        program.pou_count(),
        program.memory_bytes(),
        program.image_size(rtcnc_plc::Area::Input),
        program.image_size(rtcnc_plc::Area::Output),
        program.image_size(rtcnc_plc::Area::Memory),
    );
    for t in program.tasks() {
        let every = match t.interval {
            Some(d) => format!("every {}", FmtTime(d.as_nanos() as i64)),
            None => "every scan".to_string(),
        };
        println!(
            "task {} ({every}, priority {}): {}",
            t.name,
            t.priority,
            t.programs.join(", ")
        );
    }
    if vars {
        for v in program.variables() {
            let at = v.location.map(|a| format!(" AT {a}")).unwrap_or_default();
            let retain = if v.retain { " RETAIN" } else { "" };
            println!("{}{at} : {}{retain}", v.path, v.type_name);
        }
    }
    Ok(ExitCode::SUCCESS)
}

struct Force {
    var: VarRef,
    name: String,
    /// `None`: release the force.
    value: Option<Value>,
    from_scan: u64,
}

struct RunOptions<'a> {
    scans: u64,
    period: &'a str,
    sets: &'a [String],
    unsets: &'a [String],
    watch: &'a [String],
    timing: bool,
}

fn run_scans(
    file: &[PathBuf],
    source: &SourceArgs,
    config: Option<&Path>,
    options: RunOptions<'_>,
) -> anyhow::Result<ExitCode> {
    let RunOptions {
        scans,
        period,
        sets,
        unsets,
        watch,
        timing,
    } = options;
    let period_ns =
        parse_time(period).with_context(|| format!("--period '{period}' is not a duration"))?;
    if period_ns <= 0 {
        bail!("--period must be positive");
    }
    // The PLC's clock counts nanoseconds in an i64 (about 292 years).
    if scans
        .checked_mul(period_ns as u64)
        .is_none_or(|end| end > i64::MAX as u64)
    {
        bail!("--scans {scans} of {period} go past the PLC clock's range (about 292 years)");
    }
    let program = match load(file, source)? {
        Ok(p) => p,
        Err(code) => return Ok(code),
    };
    let mut plc = Runtime::new(Arc::new(program));
    if let Some(path) = config {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read {}", path.display()))?;
        let cfg: rtcnc_plc::PlcConfig =
            toml::from_str(&text).with_context(|| format!("{}", path.display()))?;
        plc.configure(&cfg)
            .with_context(|| format!("{}", path.display()))?;
    }
    let mut forces = Vec::new();
    for s in sets {
        let (name, rest) = s
            .split_once('=')
            .with_context(|| format!("--set '{s}': expected NAME=VALUE[@SCAN]"))?;
        let (value, from_scan) = match rest.rsplit_once('@') {
            Some((v, k)) => (
                v,
                k.trim()
                    .parse::<u64>()
                    .with_context(|| format!("--set '{s}': bad scan number"))?,
            ),
            None => (rest, 1),
        };
        let var = plc
            .resolve(name.trim())
            .with_context(|| format!("--set '{s}'"))?;
        let value = plc
            .parse_value(&var, value)
            .with_context(|| format!("--set '{s}'"))?;
        forces.push(Force {
            var,
            name: name.trim().to_string(),
            value: Some(value),
            from_scan,
        });
    }
    for u in unsets {
        let (name, k) = u
            .rsplit_once('@')
            .with_context(|| format!("--unset '{u}': expected NAME@SCAN"))?;
        let from_scan = k
            .trim()
            .parse::<u64>()
            .with_context(|| format!("--unset '{u}': bad scan number"))?;
        let var = plc
            .resolve(name.trim())
            .with_context(|| format!("--unset '{u}'"))?;
        forces.push(Force {
            var,
            name: name.trim().to_string(),
            value: None,
            from_scan,
        });
    }
    forces.sort_by_key(|f| f.from_scan);
    let mut watched = Vec::new();
    for w in watch {
        watched.push(plc.resolve(w).with_context(|| format!("--watch '{w}'"))?);
    }
    let mut header = String::from("scan\ttime");
    for w in watch {
        header.push('\t');
        header.push_str(w);
    }
    if timing {
        header.push_str("\tscan_us");
    }
    println!("{header}");
    for k in 1..=scans {
        for f in forces.iter().filter(|f| f.from_scan == k) {
            match &f.value {
                Some(value) => plc
                    .force(&f.var, value)
                    .with_context(|| format!("--set {}", f.name))?,
                None => plc.unforce(&f.var),
            }
        }
        let now = Duration::from_nanos((k - 1) * period_ns as u64);
        let started = std::time::Instant::now();
        let result = plc.scan(now);
        let took = started.elapsed();
        let mut row = format!("{k}\t{}", FmtTime(now.as_nanos() as i64));
        for v in &watched {
            row.push('\t');
            row.push_str(&plc.format(v));
            if plc.forced_slots().any(|s| s == v.slot()) {
                row.push_str(" (F)");
            }
        }
        if timing {
            row.push_str(&format!("\t{:.3}", took.as_secs_f64() * 1e6));
        }
        println!("{row}");
        if let Err(fault) = result {
            eprintln!("{}: {fault}", shown(file));
            return Ok(ExitCode::from(1));
        }
    }
    Ok(ExitCode::SUCCESS)
}
