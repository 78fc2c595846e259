//! STRING and WSTRING values in the PLC's byte memory and the standard string functions,
//! without heap allocation. A STRING at address `a` is its Windows-1252 bytes ending in a
//! zero byte, a WSTRING its UTF-16 code units (little-endian) ending in a zero unit, as
//! CODESYS and TwinCAT keep them; the compiler tells each function which of the two it
//! reads. Work buffers live on the stack.

use std::cmp::Ordering;
use std::io::Write as _;

use crate::types::{IntKind, MAX_STRING_LEN};
use crate::vm::Builtin;

const BUF: usize = MAX_STRING_LEN as usize + 1;

/// Characters of a string: bytes of a STRING, code units of a WSTRING.
type Units = [u16; BUF];

/// Copies the string at `a` (a WSTRING if `wide`) into `buf`: the characters up to its
/// terminating zero, at most [`MAX_STRING_LEN`] and none past the memory's end; returns
/// how many.
pub(crate) fn read_units(mem: &[u8], a: usize, wide: bool, buf: &mut Units) -> usize {
    let mut n = 0;
    for u in buf.iter_mut().take(MAX_STRING_LEN as usize) {
        let c = if wide {
            match a
                .checked_add(2 * n)
                .and_then(|i| mem.get(i..i.checked_add(2)?))
            {
                Some(b) => u16::from_le_bytes([b[0], b[1]]),
                None => 0,
            }
        } else {
            a.checked_add(n)
                .and_then(|i| mem.get(i))
                .map_or(0, |b| *b as u16)
        };
        if c == 0 {
            break;
        }
        *u = c;
        n += 1;
    }
    n
}

/// Copies the string at `a` into `buf` as STRING bytes (a WSTRING's code units that
/// Windows-1252 lacks become `?`, as CODESYS converts them); returns its length.
pub(crate) fn read(mem: &[u8], a: usize, wide: bool, buf: &mut [u8; BUF]) -> usize {
    let mut units = [0u16; BUF];
    let len = read_units(mem, a, wide, &mut units);
    for (b, u) in buf.iter_mut().zip(units.iter()).take(len) {
        *b = if wide { narrow(*u) } else { *u as u8 };
    }
    len
}

/// The STRING byte of a UTF-16 code unit, `?` when Windows-1252 has no such character.
fn narrow(unit: u16) -> u8 {
    char::from_u32(unit as u32)
        .and_then(crate::charset::encode)
        .unwrap_or(b'?')
}

/// Writes `units` (cut to `cap`, and at a zero unit) and the terminating zero as the
/// string at `a`, a WSTRING if `wide`; nothing when that does not fit in memory.
pub(crate) fn write_units(mem: &mut [u8], a: usize, cap: u16, wide: bool, units: &[u16]) {
    let n = units.len().min(cap as usize).min(MAX_STRING_LEN as usize);
    let n = units[..n].iter().position(|u| *u == 0).unwrap_or(n);
    let w = if wide { 2 } else { 1 };
    let Some(dst) = a
        .checked_add((n + 1) * w)
        .and_then(|end| mem.get_mut(a..end))
    else {
        return;
    };
    if wide {
        for (d, u) in dst.chunks_exact_mut(2).zip(units[..n].iter().chain([&0])) {
            d.copy_from_slice(&u.to_le_bytes());
        }
    } else {
        for (d, u) in dst.iter_mut().zip(units[..n].iter().chain([&0])) {
            *d = *u as u8;
        }
    }
}

/// Writes `bytes` (cut to `cap`) as the STRING at `a`.
pub(crate) fn write(mem: &mut [u8], a: usize, cap: u16, bytes: &[u8]) {
    let mut units = [0u16; BUF];
    let n = bytes.len().min(BUF);
    for (u, b) in units.iter_mut().zip(bytes.iter()) {
        *u = *b as u16;
    }
    write_units(mem, a, cap, false, &units[..n]);
}

/// UTF-16 code units of `text` into `buf` (cut to its length); returns how many.
pub(crate) fn utf16_units(text: &str, buf: &mut Units) -> usize {
    let mut n = 0;
    for (slot, u) in buf.iter_mut().zip(text.encode_utf16()) {
        *slot = u;
        n += 1;
    }
    n
}

/// STRING bytes of `text` into `buf` (cut to its length; a character Windows-1252 lacks
/// becomes `?`); returns how many.
pub(crate) fn windows_1252(text: &str, buf: &mut [u8; BUF]) -> usize {
    let mut n = 0;
    for (slot, ch) in buf.iter_mut().zip(text.chars()) {
        *slot = crate::charset::encode(ch).unwrap_or(b'?');
        n += 1;
    }
    n
}

/// Copies the string at `src` to `dst` (capacity `cap`), both WSTRINGs if `wide`.
pub(crate) fn copy(mem: &mut [u8], dst: usize, src: usize, cap: u16, wide: bool) {
    if dst == src {
        return;
    }
    let mut b = [0u16; BUF];
    let n = read_units(mem, src, wide, &mut b);
    write_units(mem, dst, cap, wide, &b[..n]);
}

/// Copies the string at `src` to `dst` (capacity `cap`) as a WSTRING if `wide`, else as
/// a STRING: STRING_TO_WSTRING and WSTRING_TO_STRING. A STRING holds Windows-1252, one
/// byte a character, so each byte becomes one code unit and back; a code unit Windows-1252
/// lacks (and half of a surrogate pair) becomes `?`, as CODESYS converts.
pub(crate) fn convert(mem: &mut [u8], dst: usize, src: usize, cap: u16, wide: bool) {
    let mut units = [0u16; BUF];
    let n = read_units(mem, src, !wide, &mut units);
    for u in units.iter_mut().take(n) {
        *u = if wide {
            let mut one = [0u16; 2];
            crate::charset::decode(*u as u8).encode_utf16(&mut one);
            one[0]
        } else {
            narrow(*u) as u16
        };
    }
    write_units(mem, dst, cap, wide, &units[..n]);
}

/// Appends the string at `src` to the (maximum-capacity) string at `dst`.
pub(crate) fn append(mem: &mut [u8], dst: usize, src: usize, wide: bool) {
    let mut a = [0u16; BUF];
    let mut b = [0u16; BUF];
    let n = read_units(mem, dst, wide, &mut a);
    let m = read_units(mem, src, wide, &mut b);
    let total = (n + m).min(MAX_STRING_LEN as usize);
    a[n..total].copy_from_slice(&b[..total - n]);
    write_units(mem, dst, MAX_STRING_LEN, wide, &a[..total]);
}

/// Compares two strings character by character (code units for WSTRING).
pub(crate) fn compare(mem: &[u8], x: usize, y: usize, wide: bool) -> Ordering {
    let mut a = [0u16; BUF];
    let mut b = [0u16; BUF];
    let n = read_units(mem, x, wide, &mut a);
    let m = read_units(mem, y, wide, &mut b);
    a[..n].cmp(&b[..m])
}

fn clamp_pos(v: u64, max: usize) -> usize {
    (v as i64).clamp(0, max as i64) as usize
}

/// Runs a string built-in; string results go to `dest`, whose address is returned.
/// Positions are 1-based as in IEC; out-of-range positions and lengths are clamped. `wide`:
/// the strings read and written are WSTRINGs (a conversion's source is the other kind).
pub(crate) fn builtin(mem: &mut [u8], b: Builtin, v: &[u64], dest: usize, wide: bool) -> u64 {
    match b {
        Builtin::Len
        | Builtin::Left
        | Builtin::Right
        | Builtin::Mid
        | Builtin::Insert
        | Builtin::Delete
        | Builtin::Replace
        | Builtin::Find => edit(mem, b, v, dest, wide),
        Builtin::StrToStr(_)
        | Builtin::IntToStr(_)
        | Builtin::RealToStr(_)
        | Builtin::TimeToStr
        | Builtin::MomentToStr(_)
        | Builtin::BoolToStr => to_text(mem, b, v, dest),
        Builtin::StrToMoment(_)
        | Builtin::StrToInt(_)
        | Builtin::StrToReal(_)
        | Builtin::StrToTime
        | Builtin::StrToBool => from_text(mem, b, v, wide),
        _ => 0,
    }
}

/// LEN, LEFT, RIGHT, MID, INSERT, DELETE, REPLACE and FIND.
fn edit(mem: &mut [u8], b: Builtin, v: &[u64], dest: usize, wide: bool) -> u64 {
    let arg = |i: usize| v.get(i).copied().unwrap_or(0);
    let mut s = [0u16; BUF];
    let mut t = [0u16; BUF];
    let mut out = [0u16; BUF];
    let cap = MAX_STRING_LEN;
    match b {
        Builtin::Len => read_units(mem, arg(0) as usize, wide, &mut s) as u64,
        Builtin::Left | Builtin::Right => {
            let n = read_units(mem, arg(0) as usize, wide, &mut s);
            let l = clamp_pos(arg(1), n);
            let part = if matches!(b, Builtin::Left) {
                &s[..l]
            } else {
                &s[n - l..n]
            };
            out[..l].copy_from_slice(part);
            write_units(mem, dest, cap, wide, &out[..l]);
            dest as u64
        }
        Builtin::Mid => {
            let n = read_units(mem, arg(0) as usize, wide, &mut s);
            let start = clamp_pos(arg(2), n + 1).max(1) - 1;
            let l = clamp_pos(arg(1), n - start);
            out[..l].copy_from_slice(&s[start..start + l]);
            write_units(mem, dest, cap, wide, &out[..l]);
            dest as u64
        }
        Builtin::Insert => {
            // INSERT(IN1, IN2, P): IN2 inserted after position P of IN1.
            let n = read_units(mem, arg(0) as usize, wide, &mut s);
            let m = read_units(mem, arg(1) as usize, wide, &mut t);
            let p = clamp_pos(arg(2), n);
            let mut k = 0;
            for &c in s[..p].iter().chain(t[..m].iter()).chain(s[p..n].iter()) {
                if k < out.len() {
                    out[k] = c;
                    k += 1;
                }
            }
            write_units(mem, dest, cap, wide, &out[..k.min(cap as usize)]);
            dest as u64
        }
        Builtin::Delete => {
            // DELETE(IN, L, P): L characters deleted from position P.
            let n = read_units(mem, arg(0) as usize, wide, &mut s);
            let p = clamp_pos(arg(2), n + 1).max(1) - 1;
            let l = clamp_pos(arg(1), n - p);
            let mut k = 0;
            for &c in s[..p].iter().chain(s[p + l..n].iter()) {
                out[k] = c;
                k += 1;
            }
            write_units(mem, dest, cap, wide, &out[..k]);
            dest as u64
        }
        Builtin::Replace => {
            // REPLACE(IN1, IN2, L, P): L characters of IN1 from position P replaced by IN2.
            let n = read_units(mem, arg(0) as usize, wide, &mut s);
            let m = read_units(mem, arg(1) as usize, wide, &mut t);
            let p = clamp_pos(arg(3), n + 1).max(1) - 1;
            let l = clamp_pos(arg(2), n - p);
            let mut k = 0;
            for &c in s[..p].iter().chain(t[..m].iter()).chain(s[p + l..n].iter()) {
                if k < out.len() {
                    out[k] = c;
                    k += 1;
                }
            }
            write_units(mem, dest, cap, wide, &out[..k.min(cap as usize)]);
            dest as u64
        }
        Builtin::Find => {
            // FIND(IN1, IN2): 1-based position of the first IN2 in IN1, 0 if absent.
            let n = read_units(mem, arg(0) as usize, wide, &mut s);
            let m = read_units(mem, arg(1) as usize, wide, &mut t);
            if m == 0 || m > n {
                return 0;
            }
            (0..=n - m)
                .find(|&i| s[i..i + m] == t[..m])
                .map_or(0, |i| i as u64 + 1)
        }
        _ => 0,
    }
}

/// A value written as text: STRING_TO_WSTRING and back, *_TO_STRING.
fn to_text(mem: &mut [u8], b: Builtin, v: &[u64], dest: usize) -> u64 {
    let arg = |i: usize| v.get(i).copied().unwrap_or(0);
    let mut bytes = [0u8; BUF];
    let cap = MAX_STRING_LEN;
    match b {
        Builtin::StrToStr(to_wide) => {
            convert(mem, dest, arg(0) as usize, cap, to_wide);
            dest as u64
        }
        Builtin::IntToStr(signed) => {
            let x = arg(0);
            let mut w = std::io::Cursor::new(&mut bytes[..]);
            let _ = if signed {
                write!(w, "{}", x as i64)
            } else {
                write!(w, "{x}")
            };
            let k = w.position() as usize;
            write(mem, dest, cap, &bytes[..k]);
            dest as u64
        }
        Builtin::RealToStr(f32) => {
            let x = f64::from_bits(arg(0));
            let mut w = std::io::Cursor::new(&mut bytes[..]);
            let _ = if f32 {
                write!(w, "{}", x as f32)
            } else {
                write!(w, "{x}")
            };
            let k = w.position() as usize;
            write(mem, dest, cap, &bytes[..k]);
            dest as u64
        }
        Builtin::TimeToStr => {
            let mut w = std::io::Cursor::new(&mut bytes[..]);
            let _ = write!(w, "{}", crate::value::FmtTime(arg(0) as i64));
            let k = w.position() as usize;
            write(mem, dest, cap, &bytes[..k]);
            dest as u64
        }
        Builtin::MomentToStr(kind) => {
            let k = crate::dates::format(kind, arg(0) as i64, &mut bytes);
            write(mem, dest, cap, &bytes[..k]);
            dest as u64
        }
        Builtin::BoolToStr => {
            let text: &[u8] = if arg(0) & 1 != 0 { b"TRUE" } else { b"FALSE" };
            write(mem, dest, cap, text);
            dest as u64
        }
        _ => 0,
    }
}

/// A value read from text: STRING_TO_*.
fn from_text(mem: &mut [u8], b: Builtin, v: &[u64], wide: bool) -> u64 {
    let arg = |i: usize| v.get(i).copied().unwrap_or(0);
    let mut text_in = [0u8; BUF];
    match b {
        Builtin::StrToMoment(kind) => {
            let n = read(mem, arg(0) as usize, wide, &mut text_in);
            crate::dates::parse_prefixed(kind, &text_in[..n]).unwrap_or(0) as u64
        }
        Builtin::StrToInt(k) => {
            let n = read(mem, arg(0) as usize, wide, &mut text_in);
            let text = std::str::from_utf8(&text_in[..n]).unwrap_or("").trim();
            let v = if k.signed() {
                text.parse::<i64>().map(|x| x as u64).unwrap_or(0)
            } else {
                text.parse::<u64>().unwrap_or(0)
            };
            wrap_checked(k, v)
        }
        Builtin::StrToReal(f32) => {
            let n = read(mem, arg(0) as usize, wide, &mut text_in);
            let text = std::str::from_utf8(&text_in[..n]).unwrap_or("").trim();
            let x = text.parse::<f64>().unwrap_or(0.0);
            if f32 {
                ((x as f32) as f64).to_bits()
            } else {
                x.to_bits()
            }
        }
        Builtin::StrToTime => {
            let n = read(mem, arg(0) as usize, wide, &mut text_in);
            parse_duration(&text_in[..n]).unwrap_or(0) as u64
        }
        Builtin::StrToBool => {
            let n = read(mem, arg(0) as usize, wide, &mut text_in);
            let text = &text_in[..n];
            (text.eq_ignore_ascii_case(b"TRUE") || text == b"1") as u64
        }
        _ => 0,
    }
}

fn wrap_checked(k: IntKind, v: u64) -> u64 {
    k.wrap(v)
}

/// Parses `T#1h2m3.5s`, `TIME#20ms`, `-5s` or `1d2h` from bytes, without allocating.
fn parse_duration(text: &[u8]) -> Option<i64> {
    let mut t = text.trim_ascii();
    for prefix in [&b"LTIME#"[..], b"TIME#", b"LT#", b"T#"] {
        if t.len() >= prefix.len() && t[..prefix.len()].eq_ignore_ascii_case(prefix) {
            t = &t[prefix.len()..];
            break;
        }
    }
    let negative = t.first() == Some(&b'-');
    if negative {
        t = &t[1..];
    }
    let mut total: f64 = 0.0;
    let mut any = false;
    let mut i = 0;
    while i < t.len() {
        if t[i] == b'_' {
            i += 1;
            continue;
        }
        let start = i;
        while i < t.len() && (t[i].is_ascii_digit() || t[i] == b'.') {
            i += 1;
        }
        let number = std::str::from_utf8(&t[start..i])
            .ok()?
            .parse::<f64>()
            .ok()?;
        let rest = &t[i..];
        let unit = |u: &[u8]| rest.len() >= u.len() && rest[..u.len()].eq_ignore_ascii_case(u);
        let (scale, len) = if unit(b"ms") {
            (1e6, 2)
        } else if unit(b"us") {
            (1e3, 2)
        } else if unit(b"ns") {
            (1.0, 2)
        } else if unit(b"d") {
            (86_400e9, 1)
        } else if unit(b"h") {
            (3_600e9, 1)
        } else if unit(b"m") {
            (60e9, 1)
        } else if unit(b"s") {
            (1e9, 1)
        } else {
            return None;
        };
        total += number * scale;
        i += len;
        any = true;
    }
    if !any || total > i64::MAX as f64 {
        return None;
    }
    let ns = total.round() as i64;
    Some(if negative { -ns } else { ns })
}
