//! One module per subcommand, and the argument types they share.
pub mod api;
pub mod check;
pub mod latency;
pub mod machine;
pub mod machines;
pub mod plc;
pub mod run;
pub mod serve;
pub mod sim;
pub mod user;

use std::time::Duration;

/// Longest time a command-line argument in seconds may give: about 31.7 years, far beyond
/// any run, and well inside what a `Duration` holds.
pub const MAX_SECONDS: f64 = 1e9;

/// A time in seconds that may be 0 (`--resume-after-pause`).
pub fn seconds_or_zero(text: &str) -> Result<Duration, String> {
    if text.trim().parse::<f64>() == Ok(0.0) {
        return Ok(Duration::ZERO);
    }
    seconds(text)
}

/// A time in seconds (`--limit`, `--idle`): a finite number greater than zero and at most
/// [`MAX_SECONDS`].
pub fn seconds(text: &str) -> Result<Duration, String> {
    let value: f64 = text
        .trim()
        .parse()
        .map_err(|_| format!("'{text}' is not a number of seconds"))?;
    if !value.is_finite() || value <= 0.0 || value > MAX_SECONDS {
        return Err(format!(
            "{text} s: give a finite time greater than 0 and at most {MAX_SECONDS:e} s"
        ));
    }
    Ok(Duration::from_secs_f64(value))
}
