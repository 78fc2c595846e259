//! Values as the outside world sees them (monitoring, forcing, signals, retain files).

use std::fmt;

use crate::types::Elem;

/// A PLC value.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// BOOL.
    Bool(bool),
    /// Signed integer types and enumerations.
    Int(i64),
    /// Unsigned integer and bit-string types.
    UInt(u64),
    /// REAL and LREAL.
    Real(f64),
    /// TIME in nanoseconds.
    Time(i64),
    /// STRING.
    String(String),
}

/// Formats nanoseconds as an IEC duration literal (`T#1s500ms`).
pub struct FmtTime(pub i64);

impl fmt::Display for FmtTime {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut ns = self.0;
        f.write_str("T#")?;
        if ns < 0 {
            f.write_str("-")?;
            ns = ns.checked_neg().unwrap_or(i64::MAX);
        }
        if ns == 0 {
            return f.write_str("0s");
        }
        const UNITS: [(i64, &str); 7] = [
            (86_400_000_000_000, "d"),
            (3_600_000_000_000, "h"),
            (60_000_000_000, "m"),
            (1_000_000_000, "s"),
            (1_000_000, "ms"),
            (1_000, "us"),
            (1, "ns"),
        ];
        for (unit, name) in UNITS {
            if ns >= unit {
                write!(f, "{}{name}", ns / unit)?;
                ns %= unit;
            }
        }
        Ok(())
    }
}

impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::Bool(b) => f.write_str(if *b { "TRUE" } else { "FALSE" }),
            Value::Int(v) => write!(f, "{v}"),
            Value::UInt(v) => write!(f, "{v}"),
            Value::Real(v) => {
                if v.is_finite() && v.fract() == 0.0 && v.abs() < 1e15 {
                    write!(f, "{v:.1}")
                } else {
                    write!(f, "{v}")
                }
            }
            Value::Time(ns) => write!(f, "{}", FmtTime(*ns)),
            Value::String(s) => write!(f, "'{s}'"),
        }
    }
}

/// Why a value does not fit a variable.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ValueError {
    /// The value's kind does not match the variable's type.
    #[error("a {given} value does not fit a {ty} variable")]
    Kind {
        /// Kind of value given.
        given: &'static str,
        /// Variable type.
        ty: String,
    },
    /// The value is outside the type's range.
    #[error("{value} is outside the range of {ty}")]
    Range {
        /// The value.
        value: String,
        /// Variable type.
        ty: String,
    },
    /// Text that is not a value of the type.
    #[error("'{text}' is not a {ty} value")]
    Parse {
        /// The text.
        text: String,
        /// Variable type.
        ty: String,
    },
}

impl ValueError {
    /// Stable code.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn code(&self) -> &'static str {
        match self {
            ValueError::Kind { .. } => "value-kind",
            ValueError::Range { .. } => "value-range",
            ValueError::Parse { .. } => "value-parse",
        }
    }
}

impl Value {
    fn kind_name(&self) -> &'static str {
        match self {
            Value::Bool(_) => "BOOL",
            Value::Int(_) | Value::UInt(_) => "integer",
            Value::Real(_) => "real",
            Value::Time(_) => "TIME",
            Value::String(_) => "STRING",
        }
    }

    /// Decodes a slot of elementary type `e`.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn from_slot(e: Elem, v: u64) -> Value {
        match e {
            Elem::Bool => Value::Bool(v & 1 != 0),
            Elem::Real | Elem::LReal => Value::Real(f64::from_bits(v)),
            Elem::Time => Value::Time(v as i64),
            e if e.int_kind().is_some_and(|k| k.signed()) => Value::Int(v as i64),
            _ => Value::UInt(v),
        }
    }

    /// Encodes into a slot of elementary type `e`, checking the range (`lo..=hi` narrows
    /// it further for subranges).
    ///
    /// Real-time: yes for elementary types (no allocation, no blocking); a `STRING` value
    /// or a refusal's message allocates.
    pub fn to_slot(&self, e: Elem, range: Option<(i64, i64)>) -> Result<u64, ValueError> {
        let ty = || e.name().to_string();
        let int = |v: i128| -> Result<u64, ValueError> {
            let (lo, hi) = match range {
                Some((l, h)) => (l as i128, h as i128),
                None => e.int_range().unwrap_or((0, 1)),
            };
            if v < lo || v > hi {
                return Err(ValueError::Range {
                    value: v.to_string(),
                    ty: ty(),
                });
            }
            Ok(v as i64 as u64)
        };
        match (self, e) {
            (Value::Bool(b), Elem::Bool) => Ok(*b as u64),
            (Value::Int(v), Elem::Bool) if *v == 0 || *v == 1 => Ok(*v as u64),
            (Value::UInt(v), Elem::Bool) if *v <= 1 => Ok(*v),
            (Value::Real(x), Elem::Real) => Ok(((*x as f32) as f64).to_bits()),
            (Value::Real(x), Elem::LReal) => Ok(x.to_bits()),
            (Value::Int(v), Elem::Real) => Ok(((*v as f32) as f64).to_bits()),
            (Value::UInt(v), Elem::Real) => Ok(((*v as f32) as f64).to_bits()),
            (Value::Int(v), Elem::LReal) => Ok((*v as f64).to_bits()),
            (Value::UInt(v), Elem::LReal) => Ok((*v as f64).to_bits()),
            (Value::Time(ns), Elem::Time) => Ok(*ns as u64),
            (Value::Int(v), e) if e.int_kind().is_some() && e != Elem::Time && e != Elem::Bool => {
                int(*v as i128)
            }
            (Value::UInt(v), e) if e.int_kind().is_some() && e != Elem::Time && e != Elem::Bool => {
                int(*v as i128)
            }
            _ => Err(ValueError::Kind {
                given: self.kind_name(),
                ty: ty(),
            }),
        }
    }

    /// Parses IEC-style text for a variable of elementary type `e`: `TRUE`, `FALSE`, `1`,
    /// `-5`, `16#FF`, `2.5`, `T#20ms`, or with a type prefix (`INT#5`).
    ///
    /// Real-time: no (allocates).
    pub fn parse(text: &str, e: Elem) -> Result<Value, ValueError> {
        let bad = || ValueError::Parse {
            text: text.to_string(),
            ty: e.name().to_string(),
        };
        let t = text.trim();
        let upper = t.to_ascii_uppercase();
        // Strip a type prefix such as INT# but keep T#/TIME# for durations.
        let body = match upper.split_once('#') {
            Some((p, rest)) if Elem::from_name(p).is_some() && !matches!(p, "TIME" | "LTIME") => {
                rest.to_string()
            }
            _ => upper.clone(),
        };
        match e {
            Elem::Bool => match body.as_str() {
                "TRUE" | "1" => Ok(Value::Bool(true)),
                "FALSE" | "0" => Ok(Value::Bool(false)),
                _ => Err(bad()),
            },
            Elem::Real | Elem::LReal => body.parse::<f64>().map(Value::Real).map_err(|_| bad()),
            Elem::Time => parse_time(&body).map(Value::Time).ok_or_else(bad),
            Elem::Date | Elem::Tod | Elem::Dt => crate::dates::Moment::of(e)
                .and_then(|m| crate::dates::parse_prefixed(m, upper.as_bytes()))
                .map(Value::Int)
                .ok_or_else(bad),
            _ => {
                let (neg, digits) = match body.strip_prefix('-') {
                    Some(d) => (true, d),
                    None => (false, body.as_str()),
                };
                let digits = digits.replace('_', "");
                let mag = match digits.split_once('#') {
                    Some((r, d)) => {
                        let radix: u32 = r.parse().map_err(|_| bad())?;
                        if ![2, 8, 16].contains(&radix) {
                            return Err(bad());
                        }
                        u64::from_str_radix(d, radix).map_err(|_| bad())?
                    }
                    None => digits.parse::<u64>().map_err(|_| bad())?,
                };
                let signed = e.int_kind().is_some_and(|k| k.signed());
                if neg {
                    let v = -(mag as i128);
                    if v < i64::MIN as i128 {
                        return Err(bad());
                    }
                    Ok(Value::Int(v as i64))
                } else if signed {
                    i64::try_from(mag).map(Value::Int).map_err(|_| bad())
                } else {
                    Ok(Value::UInt(mag))
                }
            }
        }
    }
}

/// Parses `T#1s500ms`, `TIME#20ms`, `20ms` or a plain number of milliseconds.
///
/// Real-time: no (allocates).
pub fn parse_time(text: &str) -> Option<i64> {
    let t = text.trim().to_ascii_uppercase();
    let body = t
        .strip_prefix("LTIME#")
        .or_else(|| t.strip_prefix("TIME#"))
        .or_else(|| t.strip_prefix("LT#"))
        .or_else(|| t.strip_prefix("T#"))
        .unwrap_or(&t);
    let src = format!("T#{body}");
    match crate::lexer::tokenize(&src, "") {
        Ok(toks) if toks.len() == 2 => match toks[0].kind {
            crate::lexer::Tok::Time(ns) => i64::try_from(ns).ok(),
            _ => None,
        },
        _ => body.parse::<f64>().ok().map(|ms| (ms * 1e6).round() as i64),
    }
}
