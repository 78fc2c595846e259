//! Executive time: nanoseconds since the executive's epoch (the start of a run), the same
//! type under the real-time and the virtual-time scheduler.

use std::fmt;
use std::time::Duration;

use thiserror::Error;

/// A point in executive time: nanoseconds since the start of the run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Time(u64);

impl Time {
    /// The start of the run.
    pub const ZERO: Time = Time(0);

    /// A time `ns` nanoseconds after the start of the run.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub const fn from_nanos(ns: u64) -> Time {
        Time(ns)
    }

    /// A time `us` microseconds after the start of the run.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub const fn from_micros(us: u64) -> Time {
        Time(us * 1_000)
    }

    /// A time `ms` milliseconds after the start of the run.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub const fn from_millis(ms: u64) -> Time {
        Time(ms * 1_000_000)
    }

    /// Nanoseconds since the start of the run.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub const fn as_nanos(self) -> u64 {
        self.0
    }

    /// The time elapsed since the start of the run.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub const fn since_start(self) -> Duration {
        Duration::from_nanos(self.0)
    }

    /// `self - earlier`, or zero when `earlier` is later.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn saturating_since(self, earlier: Time) -> Duration {
        Duration::from_nanos(self.0.saturating_sub(earlier.0))
    }
}

impl std::ops::Add<Duration> for Time {
    type Output = Time;
    fn add(self, d: Duration) -> Time {
        Time(self.0.saturating_add(duration_ns(d)))
    }
}

impl fmt::Display for Time {
    /// Seconds with nanosecond digits, e.g. `0.000500000 s`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}.{:09} s",
            self.0 / 1_000_000_000,
            self.0 % 1_000_000_000
        )
    }
}

/// Nanoseconds of a duration, saturating at `u64::MAX` (585 years).
pub(crate) fn duration_ns(d: Duration) -> u64 {
    u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)
}

/// A duration given as text could not be read.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum DurationError {
    /// The text is not a number followed by a unit.
    #[error("'{0}' is not a duration: write a number and a unit, e.g. 500us, 1ms, 10s")]
    Syntax(String),
    /// The value is zero or negative.
    #[error("'{0}' must be greater than zero")]
    NotPositive(String),
}

impl DurationError {
    /// Stable error code.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn code(&self) -> &'static str {
        match self {
            DurationError::Syntax(_) => "duration_syntax",
            DurationError::NotPositive(_) => "duration_not_positive",
        }
    }
}

/// Reads a positive duration such as `100us`, `0.5ms`, `1ms`, `10s`, `2min` (units: ns, us,
/// µs, ms, s, min). Zero and negative values are refused.
///
/// Real-time: no (a refusal allocates its message).
pub fn parse_duration(text: &str) -> Result<Duration, DurationError> {
    let t = text.trim();
    let Some(split) = t.find(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-' || c == '+'))
    else {
        // A bare number: zero or negative is refused as such, anything else lacks a unit.
        return match t.parse::<f64>() {
            Ok(v) if v <= 0.0 => Err(DurationError::NotPositive(text.to_string())),
            _ => Err(DurationError::Syntax(text.to_string())),
        };
    };
    let (number, unit) = t.split_at(split);
    let value: f64 = number
        .parse()
        .map_err(|_| DurationError::Syntax(text.to_string()))?;
    let scale = match unit.trim() {
        "ns" => 1e-9,
        "us" | "µs" => 1e-6,
        "ms" => 1e-3,
        "s" => 1.0,
        "min" => 60.0,
        _ => return Err(DurationError::Syntax(text.to_string())),
    };
    let seconds = value * scale;
    if !seconds.is_finite() {
        return Err(DurationError::Syntax(text.to_string()));
    }
    if seconds <= 0.0 {
        return Err(DurationError::NotPositive(text.to_string()));
    }
    let d = Duration::try_from_secs_f64(seconds)
        .map_err(|_| DurationError::Syntax(text.to_string()))?;
    if d.is_zero() {
        return Err(DurationError::NotPositive(text.to_string()));
    }
    Ok(d)
}

/// Converts a period given in seconds (as configuration files hold it) into a duration,
/// refusing zero, negative and non-finite values.
///
/// Real-time: no (a refusal allocates its message).
pub fn duration_from_secs(seconds: f64) -> Result<Duration, DurationError> {
    if !seconds.is_finite() {
        return Err(DurationError::Syntax(format!("{seconds} s")));
    }
    if seconds <= 0.0 {
        return Err(DurationError::NotPositive(format!("{seconds} s")));
    }
    Duration::try_from_secs_f64(seconds).map_err(|_| DurationError::Syntax(format!("{seconds} s")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_units() {
        assert_eq!(parse_duration("1ms"), Ok(Duration::from_millis(1)));
        assert_eq!(parse_duration("500us"), Ok(Duration::from_micros(500)));
        assert_eq!(parse_duration("0.5ms"), Ok(Duration::from_micros(500)));
        assert_eq!(parse_duration("10s"), Ok(Duration::from_secs(10)));
        assert_eq!(parse_duration("2min"), Ok(Duration::from_secs(120)));
        assert_eq!(parse_duration("250ns"), Ok(Duration::from_nanos(250)));
    }

    #[test]
    fn refuses_zero_negative_and_garbage() {
        assert_eq!(
            parse_duration("0"),
            Err(DurationError::NotPositive("0".into()))
        );
        assert_eq!(parse_duration("5"), Err(DurationError::Syntax("5".into())));
        assert_eq!(
            parse_duration("0ms"),
            Err(DurationError::NotPositive("0ms".into()))
        );
        assert_eq!(
            parse_duration("-1ms"),
            Err(DurationError::NotPositive("-1ms".into()))
        );
        assert_eq!(
            parse_duration("1 parsec"),
            Err(DurationError::Syntax("1 parsec".into()))
        );
        assert!(duration_from_secs(-0.001).is_err());
        assert!(duration_from_secs(f64::NAN).is_err());
    }

    #[test]
    fn time_display_is_exact() {
        assert_eq!(Time::from_micros(500).to_string(), "0.000500000 s");
    }
}
