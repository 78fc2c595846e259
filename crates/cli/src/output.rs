//! What the command line does when its output goes away, and how it words an error.
//!
//! A closed standard output (`rtcnc check F | head -1`) ends `check`, `sim`, `plc` and
//! `latency` the way it ends other Unix filters: the default action of SIGPIPE, no message,
//! shell status 141 ([`EXIT_CLOSED_OUTPUT`]). `run` drives a machine and must not die with
//! its output: it ignores SIGPIPE and drops what it can no longer print ([`say`]).

use std::io::Write as _;
use std::sync::atomic::{AtomicBool, Ordering};

/// The shell's status of a command whose output was closed (128 + SIGPIPE).
pub const EXIT_CLOSED_OUTPUT: u8 = 141;

/// Lets a write to a closed pipe end the process quietly (SIGPIPE's default action), as
/// other Unix filters do. The Rust run time ignores SIGPIPE, which turns such a write into an
/// error and `println!` into a panic.
pub fn end_quietly_when_output_closes() {
    // SAFETY: resetting a signal's disposition to its default has no memory effects.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

/// Whether an error comes from writing into a closed pipe.
pub fn is_broken_pipe(error: &anyhow::Error) -> bool {
    error.chain().any(|cause| {
        cause
            .downcast_ref::<std::io::Error>()
            .is_some_and(|e| e.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

/// Ends the process quietly after its output was closed.
pub fn exit_on_closed_output() -> ! {
    std::process::exit(i32::from(EXIT_CLOSED_OUTPUT))
}

/// An error and its causes on one line, each cause once: a cause whose text the message
/// before it already contains (an error that prints its source and also returns it) is
/// left out.
pub fn error_chain(error: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in error.chain() {
        let part = cause.to_string();
        if part.is_empty() || text.contains(&part) {
            continue;
        }
        if !text.is_empty() {
            text.push_str(": ");
        }
        text.push_str(&part);
    }
    text
}

static STDOUT_CLOSED: AtomicBool = AtomicBool::new(false);

/// Prints a line on standard output; once the output is closed, drops it and every line
/// after it (used by `run`, which goes on driving the machine).
pub fn say(line: std::fmt::Arguments<'_>) {
    if STDOUT_CLOSED.load(Ordering::Relaxed) {
        return;
    }
    let mut out = std::io::stdout().lock();
    if out
        .write_fmt(line)
        .and_then(|()| out.write_all(b"\n"))
        .is_err()
    {
        STDOUT_CLOSED.store(true, Ordering::Relaxed);
    }
}

/// `println!` that never fails: see [`say`].
#[macro_export]
macro_rules! say {
    ($($arg:tt)*) => {
        $crate::output::say(format_args!($($arg)*))
    };
}
