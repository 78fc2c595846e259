//! DATE, TIME_OF_DAY and DATE_AND_TIME: literals, calendar arithmetic, text, and the
//! standard's date and time functions (ADD_TOD_TIME, CONCAT_DATE_TOD, DAY_OF_WEEK, ...).
//!
//! All three count nanoseconds in an i64 slot, as CODESYS's LDATE, LTOD and LDT do: a DATE
//! from 1970-01-01 (midnight of its day), a TIME_OF_DAY from midnight, a DATE_AND_TIME from
//! 1970-01-01-00:00:00, on the proleptic Gregorian calendar without leap seconds. The range
//! is therefore 1970-01-01 to 2262-04-11. Conversions to integers give CODESYS's units:
//! seconds for DATE and DATE_AND_TIME, milliseconds for TIME_OF_DAY.

use crate::ast::{Arg, BinOp, Name};
use crate::compiler::{Compiler, R, Scope, TE, Ty, builtin_expr};
use crate::error::{ErrorKind, Pos};
use crate::types::{Elem, IntKind, Type};
use crate::vm::{self, Bin, Builtin, Conv};

/// Nanoseconds in a day.
pub(crate) const NS_PER_DAY: i64 = 86_400_000_000_000;

/// Which of the three types a literal or a text conversion is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Moment {
    Date,
    Tod,
    Dt,
}

impl Moment {
    pub(crate) fn elem(self) -> Elem {
        match self {
            Moment::Date => Elem::Date,
            Moment::Tod => Elem::Tod,
            Moment::Dt => Elem::Dt,
        }
    }
    pub(crate) fn of(e: Elem) -> Option<Moment> {
        match e {
            Elem::Date => Some(Moment::Date),
            Elem::Tod => Some(Moment::Tod),
            Elem::Dt => Some(Moment::Dt),
            _ => None,
        }
    }
}

/// Days from 1970-01-01 to year-month-day (proleptic Gregorian; H. Hinnant's algorithm).
pub(crate) fn days_from_civil(y: i64, m: i64, d: i64) -> i64 {
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (m + 9) % 12;
    let doy = (153 * mp + 2) / 5 + d - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// Year, month, day of a day count from 1970-01-01.
pub(crate) fn civil_from_days(z: i64) -> (i64, i64, i64) {
    let z = z + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let y = yoe + era * 400;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    (if m <= 2 { y + 1 } else { y }, m, d)
}

fn days_in_month(y: i64, m: i64) -> i64 {
    match m {
        2 if (y % 4 == 0 && y % 100 != 0) || y % 400 == 0 => 29,
        2 => 28,
        4 | 6 | 9 | 11 => 30,
        _ => 31,
    }
}

/// A date at midnight in nanoseconds, if the date exists and fits.
pub(crate) fn date_ns(y: i64, m: i64, d: i64) -> Option<i64> {
    if !(1970..=2262).contains(&y) || !(1..=12).contains(&m) || d < 1 || d > days_in_month(y, m) {
        return None;
    }
    days_from_civil(y, m, d).checked_mul(NS_PER_DAY)
}

/// A time of day in nanoseconds, if valid.
pub(crate) fn tod_ns(h: i64, mi: i64, s: i64, frac_ns: i64) -> Option<i64> {
    if !(0..24).contains(&h) || !(0..60).contains(&mi) || !(0..60).contains(&s) {
        return None;
    }
    Some(((h * 60 + mi) * 60 + s) * 1_000_000_000 + frac_ns)
}

/// Reads an unsigned decimal number; returns it and the rest.
fn number(t: &[u8]) -> Option<(i64, &[u8])> {
    let n = t.iter().take_while(|c| c.is_ascii_digit()).count();
    if n == 0 || n > 9 {
        return None;
    }
    let v = t[..n].iter().fold(0i64, |a, c| a * 10 + (c - b'0') as i64);
    Some((v, &t[n..]))
}

fn expect(t: &[u8], c: u8) -> Option<&[u8]> {
    t.strip_prefix(&[c])
}

fn parse_date(t: &[u8]) -> Option<(i64, &[u8])> {
    let (y, t) = number(t)?;
    let (m, t) = number(expect(t, b'-')?)?;
    let (d, t) = number(expect(t, b'-')?)?;
    Some((date_ns(y, m, d)?, t))
}

fn parse_tod(t: &[u8]) -> Option<(i64, &[u8])> {
    let (h, t) = number(t)?;
    let (mi, t) = number(expect(t, b':')?)?;
    let (s, mut t) = match expect(t, b':') {
        Some(r) => number(r)?,
        None => (0, t),
    };
    let mut frac = 0i64;
    if let Some(r) = expect(t, b'.') {
        let n = r.iter().take_while(|c| c.is_ascii_digit()).count();
        if n == 0 {
            return None;
        }
        let mut scale = 100_000_000i64;
        for c in &r[..n.min(9)] {
            frac += (c - b'0') as i64 * scale;
            scale /= 10;
        }
        t = &r[n..];
    }
    Some((tod_ns(h, mi, s, frac)?, t))
}

/// Parses the text after `D#`, `TOD#` or `DT#` (all of it): `2026-11-27`, `12:30:15.5`,
/// `2026-11-27-12:30:15`.
pub(crate) fn parse(kind: Moment, text: &[u8]) -> Option<i64> {
    let (v, rest) = match kind {
        Moment::Date => parse_date(text)?,
        Moment::Tod => parse_tod(text)?,
        Moment::Dt => {
            let (d, r) = parse_date(text)?;
            let (t, r) = parse_tod(expect(r, b'-')?)?;
            (d.checked_add(t)?, r)
        }
    };
    rest.is_empty().then_some(v)
}

/// Parses a literal with its prefix (`D#...`, `DATE#...`, `TOD#...`, `DT#...`, long forms).
pub(crate) fn parse_prefixed(kind: Moment, text: &[u8]) -> Option<i64> {
    let t = text.trim_ascii();
    let body = match t.iter().position(|c| *c == b'#') {
        Some(k) => &t[k + 1..],
        None => t,
    };
    parse(kind, body)
}

/// The literal prefix words of each kind.
pub(crate) fn literal_kind(prefix: &str) -> Option<Moment> {
    match prefix {
        "D" | "DATE" | "LDATE" | "LD" => Some(Moment::Date),
        "TOD" | "TIME_OF_DAY" | "LTOD" | "LTIME_OF_DAY" => Some(Moment::Tod),
        "DT" | "DATE_AND_TIME" | "LDT" | "LDATE_AND_TIME" => Some(Moment::Dt),
        _ => None,
    }
}

/// Writes `D#2026-11-27`, `TOD#12:30:15.5` or `DT#2026-11-27-12:30:15` into `out`;
/// returns the length. No allocation.
pub(crate) fn format(kind: Moment, ns: i64, out: &mut [u8]) -> usize {
    use std::io::Write;
    let mut w = std::io::Cursor::new(out);
    let day = ns.div_euclid(NS_PER_DAY);
    let in_day = ns.rem_euclid(NS_PER_DAY);
    let (y, m, d) = civil_from_days(day);
    let secs = in_day / 1_000_000_000;
    let frac = in_day % 1_000_000_000;
    let (h, mi, s) = (secs / 3600, secs / 60 % 60, secs % 60);
    let _ = match kind {
        Moment::Date => write!(w, "D#{y:04}-{m:02}-{d:02}"),
        Moment::Tod => write!(w, "TOD#{h:02}:{mi:02}:{s:02}"),
        Moment::Dt => write!(w, "DT#{y:04}-{m:02}-{d:02}-{h:02}:{mi:02}:{s:02}"),
    };
    if kind != Moment::Date && frac != 0 {
        let mut f = frac;
        let mut digits = 9;
        while f % 10 == 0 {
            f /= 10;
            digits -= 1;
        }
        let _ = write!(w, ".{f:0digits$}");
    }
    w.position() as usize
}

/// CONCAT_DATE(year, month, day), CONCAT_TOD(h, m, s, ms), CONCAT_DT(y, mo, d, h, mi, s,
/// ms) at run time: an impossible date or time gives 0 (1970-01-01, midnight).
pub(crate) fn concat(b: Builtin, v: &[u64]) -> u64 {
    let a = |i: usize| v.get(i).copied().unwrap_or(0) as i64;
    let tod = |k: usize| {
        let ms = a(k + 3);
        if !(0..1000).contains(&ms) {
            return None;
        }
        tod_ns(a(k), a(k + 1), a(k + 2), ms * 1_000_000)
    };
    let r = match b {
        Builtin::ConcatDate => date_ns(a(0), a(1), a(2)),
        Builtin::ConcatTod => tod(0),
        Builtin::ConcatDt => date_ns(a(0), a(1), a(2)).and_then(|d| d.checked_add(tod(3)?)),
        Builtin::DayOfWeek => {
            // 1970-01-01 was a Thursday; IEC counts 0 = Sunday.
            Some((a(0).div_euclid(NS_PER_DAY) + 4).rem_euclid(7))
        }
        _ => None,
    };
    r.unwrap_or(0) as u64
}

fn arg_as(c: &Compiler, f: &str, a: (TE, Pos), t: Elem) -> R<vm::Expr> {
    let (te, pos) = a;
    c.coerce_to(te, &Type::Elem(t), pos).map_err(|mut e| {
        e.kind = ErrorKind::WrongArgument;
        e.message = format!("{f}: {}", e.message);
        e
    })
}

/// The standard's date and time functions; `None` when `name` is none of them.
pub(crate) fn call(
    c: &mut Compiler,
    name: &Name,
    args: &[Arg],
    sc: &mut Scope,
    pos: Pos,
) -> R<Option<TE>> {
    use Elem::{DInt, Date, Dt, Time, Tod};
    let f = name.text.as_str();
    // (operator, left type, right type, result type) of the two-argument functions.
    let binary: Option<(BinOp, Elem, Elem, Elem)> = match f {
        "ADD_TIME" => Some((BinOp::Add, Time, Time, Time)),
        "SUB_TIME" => Some((BinOp::Sub, Time, Time, Time)),
        "ADD_TOD_TIME" => Some((BinOp::Add, Tod, Time, Tod)),
        "ADD_DT_TIME" => Some((BinOp::Add, Dt, Time, Dt)),
        "SUB_TOD_TIME" => Some((BinOp::Sub, Tod, Time, Tod)),
        "SUB_DT_TIME" => Some((BinOp::Sub, Dt, Time, Dt)),
        "SUB_DATE_DATE" => Some((BinOp::Sub, Date, Date, Time)),
        "SUB_TOD_TOD" => Some((BinOp::Sub, Tod, Tod, Time)),
        "SUB_DT_DT" => Some((BinOp::Sub, Dt, Dt, Time)),
        "CONCAT_DATE_TOD" => Some((BinOp::Add, Date, Tod, Dt)),
        _ => None,
    };
    let arity = match f {
        "MUL_TIME" | "DIV_TIME" => 2,
        "CONCAT_DATE" => 3,
        "CONCAT_TOD" => 4,
        "CONCAT_DT" => 7,
        "DAY_OF_WEEK" => 1,
        _ if binary.is_some() => 2,
        _ => return Ok(None),
    };
    let mut a = c.b_args(args, sc, f)?;
    if a.len() != arity {
        return Err(c.err_at(
            pos,
            ErrorKind::WrongArgument,
            format!("{f} takes {arity} arguments, {} given", a.len()),
        ));
    }
    if let Some((op, lt, rt, res)) = binary {
        let r = a.remove(1);
        let l = a.remove(0);
        let le = arg_as(c, f, l, lt)?;
        let re = arg_as(c, f, r, rt)?;
        let e = if f == "CONCAT_DATE_TOD" {
            vm::Expr::Bin(Bin::AddI(IntKind::I64), Box::new((le, re)))
        } else {
            let te = c.binary_op(
                op,
                Compiler::te(Ty::T(Type::Elem(lt)), le),
                Compiler::te(Ty::T(Type::Elem(rt)), re),
                pos,
            )?;
            Compiler::te_parts(te).1
        };
        return Ok(Some(Compiler::te(Ty::T(Type::Elem(res)), c.folded(e))));
    }
    match f {
        "MUL_TIME" | "DIV_TIME" => {
            let n = a.remove(1);
            let t = a.remove(0);
            let te = arg_as(c, f, t, Time)?;
            let op = if f == "MUL_TIME" {
                BinOp::Mul
            } else {
                BinOp::Div
            };
            let r = c.binary_op(op, Compiler::te(Ty::T(Type::Elem(Time)), te), n.0, pos)?;
            Ok(Some(r))
        }
        "DAY_OF_WEEK" => {
            let d = arg_as(c, f, a.remove(0), Date)?;
            let e = builtin_expr(Builtin::DayOfWeek, vec![d], 0);
            Ok(Some(Compiler::te(Ty::T(Type::Elem(Elem::Int)), e)))
        }
        _ => {
            let (b, res) = match f {
                "CONCAT_DATE" => (Builtin::ConcatDate, Date),
                "CONCAT_TOD" => (Builtin::ConcatTod, Tod),
                _ => (Builtin::ConcatDt, Dt),
            };
            let mut parts = Vec::with_capacity(arity);
            for x in a {
                parts.push(c.conversion(arg_as(c, f, x, DInt)?, DInt, Elem::LInt));
            }
            Ok(Some(Compiler::te(
                Ty::T(Type::Elem(res)),
                builtin_expr(b, parts, 0),
            )))
        }
    }
}

/// Conversions that involve one of the three types (`DT_TO_DATE`, `DATE_TO_UDINT`, ...);
/// `None` when neither side is one.
pub(crate) fn convert(e: vm::Expr, f: Elem, t: Elem) -> Option<vm::Expr> {
    let c = |cv: Conv, e: vm::Expr| vm::Expr::Conv(cv, Box::new(e));
    let (fm, tm) = (Moment::of(f), Moment::of(t));
    if fm.is_none() && tm.is_none() {
        return None;
    }
    Some(match (fm, tm) {
        (Some(Moment::Dt), Some(Moment::Date)) => c(Conv::DayFloor, e),
        (Some(Moment::Dt), Some(Moment::Tod)) => c(Conv::DayRem, e),
        (Some(_), Some(_)) => e,
        (Some(m), None) => {
            if t == Elem::Time {
                return Some(e);
            }
            let unit = if m == Moment::Tod {
                Conv::NsToMs
            } else {
                Conv::NsToS
            };
            let n = c(unit, e);
            if t.is_real() {
                c(
                    Conv::IntToReal {
                        signed: true,
                        f32: t == Elem::Real,
                    },
                    n,
                )
            } else if t == Elem::Bool {
                c(Conv::IntToBool, n)
            } else {
                c(Conv::Int(t.int_kind().unwrap_or(IntKind::I64)), n)
            }
        }
        (None, Some(m)) => {
            if f == Elem::Time {
                return Some(e);
            }
            let whole = if f.is_real() {
                c(Conv::RealToInt(IntKind::I64), e)
            } else {
                e
            };
            let unit = if m == Moment::Tod {
                Conv::MsToNs
            } else {
                Conv::SToNs
            };
            c(unit, whole)
        }
        (None, None) => return None,
    })
}
