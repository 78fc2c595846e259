//! Hand-written lexer for Structured Text: keywords and identifiers are case-insensitive,
//! comments `(* *)` (nesting), `/* */` and `//`, pragmas `{ }` are skipped.

use crate::error::{CompileError, ErrorKind, Pos};

/// One token with its source position.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Token {
    pub kind: Tok,
    pub pos: Pos,
}

/// Token kinds. Identifiers are kept in upper case (the language is case-insensitive);
/// `Ident` keeps the spelling of the source for messages in `text`.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Tok {
    Ident(String),
    /// Integer literal (value as u64 bits, so 16#FFFF_FFFF_FFFF_FFFF fits).
    Int(u128),
    Real(f64),
    /// Duration literal in nanoseconds.
    Time(i128),
    /// DATE, TIME_OF_DAY or DATE_AND_TIME literal in nanoseconds.
    Moment(crate::dates::Moment, i64),
    Str(Vec<u8>),
    /// A WSTRING literal `"..."` as UTF-16 code units.
    WStr(Vec<u16>),
    /// `TYPE#` prefix of a typed literal (`INT#5`, `Mode#Idle`).
    TypedPrefix(String),
    /// Directly represented variable: `%IX0.0`, `%QW3`, `%MD10`.
    Direct(DirectAddr),
    Assign,   // :=
    Output,   // =>
    Colon,    // :
    Semi,     // ;
    Comma,    // ,
    Dot,      // .
    DotDot,   // ..
    LParen,   // (
    RParen,   // )
    LBracket, // [
    RBracket, // ]
    Plus,
    Minus,
    Star,
    Power, // **
    Slash,
    Amp, // &
    Eq,
    Ne,
    Lt,
    Le,
    Gt,
    Ge,
    Caret,
    Eof,
}

/// Area of a directly represented variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Area {
    /// `%I`: the input image.
    Input,
    /// `%Q`: the output image.
    Output,
    /// `%M`: the marker (memory) image.
    Memory,
}

/// Size prefix of a directly represented variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum AddrSize {
    /// `X` (or none): one bit, addressed `byte.bit`.
    Bit,
    /// `B`: one byte.
    Byte,
    /// `W`: a 16-bit word at byte offset `2 * n`.
    Word,
    /// `D`: a 32-bit double word at byte offset `4 * n`.
    Double,
    /// `L`: a 64-bit long word at byte offset `8 * n`.
    Long,
}

/// A parsed `%` address.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct DirectAddr {
    /// The image the address lives in.
    pub area: Area,
    /// The width of the addressed item.
    pub size: AddrSize,
    /// Item index (byte index for bits and bytes).
    pub index: u32,
    /// Bit number for `X` addresses.
    pub bit: u8,
}

impl DirectAddr {
    /// Byte offset of the first byte in its image.
    pub fn byte_offset(&self) -> usize {
        let i = self.index as usize;
        match self.size {
            AddrSize::Bit | AddrSize::Byte => i,
            AddrSize::Word => i * 2,
            AddrSize::Double => i * 4,
            AddrSize::Long => i * 8,
        }
    }
    /// Number of bytes the item occupies (1 for a bit).
    pub fn byte_len(&self) -> usize {
        match self.size {
            AddrSize::Bit | AddrSize::Byte => 1,
            AddrSize::Word => 2,
            AddrSize::Double => 4,
            AddrSize::Long => 8,
        }
    }
}

impl std::fmt::Display for DirectAddr {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let a = match self.area {
            Area::Input => 'I',
            Area::Output => 'Q',
            Area::Memory => 'M',
        };
        match self.size {
            AddrSize::Bit => write!(f, "%{a}X{}.{}", self.index, self.bit),
            AddrSize::Byte => write!(f, "%{a}B{}", self.index),
            AddrSize::Word => write!(f, "%{a}W{}", self.index),
            AddrSize::Double => write!(f, "%{a}D{}", self.index),
            AddrSize::Long => write!(f, "%{a}L{}", self.index),
        }
    }
}

pub(crate) struct Lexer<'a> {
    src: &'a [u8],
    i: usize,
    line: u32,
    line_start: usize,
    file: &'a str,
    nested_comments: bool,
}

fn is_ident_start(c: u8) -> bool {
    c.is_ascii_alphabetic() || c == b'_'
}
fn is_ident(c: u8) -> bool {
    c.is_ascii_alphanumeric() || c == b'_'
}

/// Splits the whole source into tokens (ending with `Eof`) or returns the first lexical error.
pub(crate) fn tokenize(src: &str, file: &str) -> Result<Vec<Token>, CompileError> {
    tokenize_with(src, file, true)
}

/// As [`tokenize`]; `nested_comments` says whether `(* (* *) *)` nests (IEC 61131-3 3rd
/// edition, CODESYS) or ends at the first `*)` (older sources that rely on it).
pub(crate) fn tokenize_with(
    src: &str,
    file: &str,
    nested_comments: bool,
) -> Result<Vec<Token>, CompileError> {
    let mut lx = Lexer {
        src: src.as_bytes(),
        i: 0,
        line: 1,
        line_start: 0,
        file,
        nested_comments,
    };
    let mut out = Vec::with_capacity(src.len() / 3 + 1);
    loop {
        let t = lx.next()?;
        let eof = t.kind == Tok::Eof;
        out.push(t);
        if eof {
            return Ok(out);
        }
    }
}

impl Lexer<'_> {
    fn pos(&self) -> Pos {
        Pos {
            line: self.line,
            col: (self.i - self.line_start) as u32 + 1,
        }
    }
    fn err(&self, pos: Pos, msg: impl Into<String>) -> CompileError {
        CompileError::new(self.file, pos, ErrorKind::Syntax, msg)
    }
    fn peek(&self, k: usize) -> u8 {
        self.src.get(self.i + k).copied().unwrap_or(0)
    }
    fn bump(&mut self) -> u8 {
        let c = self.peek(0);
        self.i += 1;
        if c == b'\n' {
            self.line += 1;
            self.line_start = self.i;
        }
        c
    }

    fn skip_trivia(&mut self) -> Result<(), CompileError> {
        loop {
            let c = self.peek(0);
            if c == b' ' || c == b'\t' || c == b'\r' || c == b'\n' || c == 0x0c {
                self.bump();
            } else if c == b'/' && self.peek(1) == b'/' {
                while self.i < self.src.len() && self.peek(0) != b'\n' {
                    self.bump();
                }
            } else if (c == b'(' || c == b'/') && self.peek(1) == b'*' {
                let start = self.pos();
                let (open, close) = if c == b'(' {
                    (b'(', b')')
                } else {
                    (b'/', b'/')
                };
                self.bump();
                self.bump();
                let mut depth = 1u32;
                loop {
                    if self.i >= self.src.len() {
                        let end = if close == b')' { "*)" } else { "*/" };
                        return Err(
                            self.err(start, format!("comment is not closed: '{end}' expected"))
                        );
                    }
                    if self.peek(0) == b'*' && self.peek(1) == close {
                        self.bump();
                        self.bump();
                        depth -= 1;
                        if depth == 0 {
                            break;
                        }
                    } else if self.nested_comments && self.peek(0) == open && self.peek(1) == b'*' {
                        self.bump();
                        self.bump();
                        depth += 1;
                    } else {
                        self.bump();
                    }
                }
            } else if c == b'{' {
                // Pragmas (`{attribute 'qualified_only'}`, `{IF defined (x)}`) mean nothing
                // here; nested braces are skipped whole.
                let start = self.pos();
                let mut depth = 0u32;
                loop {
                    if self.i >= self.src.len() {
                        return Err(self.err(start, "pragma is not closed: '}' expected"));
                    }
                    match self.bump() {
                        b'{' => depth += 1,
                        b'}' => {
                            depth -= 1;
                            if depth == 0 {
                                break;
                            }
                        }
                        _ => {}
                    }
                }
            } else {
                return Ok(());
            }
        }
    }

    fn next(&mut self) -> Result<Token, CompileError> {
        self.skip_trivia()?;
        let pos = self.pos();
        if self.i >= self.src.len() {
            return Ok(Token {
                kind: Tok::Eof,
                pos,
            });
        }
        let c = self.peek(0);
        let kind = if is_ident_start(c) {
            let start = self.i;
            while is_ident(self.peek(0)) {
                self.bump();
            }
            let word = std::str::from_utf8(&self.src[start..self.i])
                .unwrap_or("")
                .to_ascii_uppercase();
            if word.get(2..).is_some_and(|rest| rest.contains("__")) || word == "__" {
                // IEC forbids double underscores: they make names ambiguous.
                return Err(self.err(pos, "identifier may not contain two underscores in a row"));
            }
            if self.peek(0) == b'#' {
                self.bump();
                let kind = self.typed_literal(word, pos)?;
                return Ok(Token { kind, pos });
            }
            // CODESYS 2.3 also spells the block `FUNCTIONBLOCK` (its exports keep it).
            match word.as_str() {
                "FUNCTIONBLOCK" => Tok::Ident("FUNCTION_BLOCK".into()),
                "END_FUNCTIONBLOCK" => Tok::Ident("END_FUNCTION_BLOCK".into()),
                _ => Tok::Ident(word),
            }
        } else if c.is_ascii_digit() {
            self.number(pos)?
        } else if c == b'\'' {
            self.string(pos)?
        } else if c == b'"' {
            self.wide_string(pos)?
        } else if c == b'%' {
            self.direct(pos)?
        } else {
            self.bump();
            match c {
                b':' => {
                    if self.peek(0) == b'=' {
                        self.bump();
                        Tok::Assign
                    } else {
                        Tok::Colon
                    }
                }
                b';' => Tok::Semi,
                b',' => Tok::Comma,
                b'.' => {
                    if self.peek(0) == b'.' {
                        self.bump();
                        Tok::DotDot
                    } else {
                        Tok::Dot
                    }
                }
                b'(' => Tok::LParen,
                b')' => Tok::RParen,
                b'[' => Tok::LBracket,
                b']' => Tok::RBracket,
                b'+' => Tok::Plus,
                b'-' => Tok::Minus,
                b'*' => {
                    if self.peek(0) == b'*' {
                        self.bump();
                        Tok::Power
                    } else {
                        Tok::Star
                    }
                }
                b'/' => Tok::Slash,
                b'&' => Tok::Amp,
                b'^' => Tok::Caret,
                b'=' => {
                    if self.peek(0) == b'>' {
                        self.bump();
                        Tok::Output
                    } else {
                        Tok::Eq
                    }
                }
                b'<' => match self.peek(0) {
                    b'=' => {
                        self.bump();
                        Tok::Le
                    }
                    b'>' => {
                        self.bump();
                        Tok::Ne
                    }
                    _ => Tok::Lt,
                },
                b'>' => {
                    if self.peek(0) == b'=' {
                        self.bump();
                        Tok::Ge
                    } else {
                        Tok::Gt
                    }
                }
                _ => {
                    let shown = if c.is_ascii_graphic() {
                        format!("'{}'", c as char)
                    } else {
                        format!("byte 0x{c:02x}")
                    };
                    return Err(self.err(pos, format!("unexpected character {shown}")));
                }
            }
        };
        Ok(Token { kind, pos })
    }

    fn digits(&mut self, radix: u32, pos: Pos) -> Result<u128, CompileError> {
        let mut v: u128 = 0;
        let mut any = false;
        loop {
            let c = self.peek(0);
            if c == b'_' {
                self.bump();
                continue;
            }
            let Some(d) = (c as char).to_digit(radix) else {
                break;
            };
            self.bump();
            any = true;
            v = v
                .checked_mul(radix as u128)
                .and_then(|v| v.checked_add(d as u128))
                .filter(|v| *v <= u64::MAX as u128)
                .ok_or_else(|| self.err(pos, "integer literal is too large"))?;
        }
        if !any {
            return Err(self.err(pos, "digits expected"));
        }
        Ok(v)
    }

    fn number(&mut self, pos: Pos) -> Result<Tok, CompileError> {
        let start = self.i;
        let v = self.digits(10, pos)?;
        if self.peek(0) == b'#' {
            self.bump();
            let radix = match v {
                2 | 8 | 16 => v as u32,
                _ => return Err(self.err(pos, "radix must be 2, 8 or 16")),
            };
            return Ok(Tok::Int(self.digits(radix, pos)?));
        }
        let is_real = self.peek(0) == b'.' && self.peek(1).is_ascii_digit();
        let has_exp = matches!(self.peek(0), b'e' | b'E')
            && (self.peek(1).is_ascii_digit()
                || (matches!(self.peek(1), b'+' | b'-') && self.peek(2).is_ascii_digit()));
        if !is_real && !has_exp {
            return Ok(Tok::Int(v));
        }
        if is_real {
            self.bump();
            while self.peek(0).is_ascii_digit() || self.peek(0) == b'_' {
                self.bump();
            }
        }
        if matches!(self.peek(0), b'e' | b'E')
            && (self.peek(1).is_ascii_digit()
                || (matches!(self.peek(1), b'+' | b'-') && self.peek(2).is_ascii_digit()))
        {
            self.bump();
            if matches!(self.peek(0), b'+' | b'-') {
                self.bump();
            }
            while self.peek(0).is_ascii_digit() {
                self.bump();
            }
        }
        let text: String = self.src[start..self.i]
            .iter()
            .filter(|c| **c != b'_')
            .map(|c| *c as char)
            .collect();
        text.parse::<f64>()
            .map(Tok::Real)
            .map_err(|_| self.err(pos, "malformed real literal"))
    }

    fn string(&mut self, pos: Pos) -> Result<Tok, CompileError> {
        self.bump();
        let mut out = Vec::new();
        loop {
            if self.i >= self.src.len() || self.peek(0) == b'\n' {
                return Err(self.err(
                    pos,
                    "string literal is not closed: ' expected before the end of the line",
                ));
            }
            let c = self.bump();
            match c {
                b'\'' => break,
                b'$' => {
                    let e = self.bump();
                    let ch = match e.to_ascii_uppercase() {
                        b'$' => b'$',
                        b'\'' => b'\'',
                        b'L' | b'N' => b'\n',
                        b'P' => 0x0c,
                        b'R' => b'\r',
                        b'T' => b'\t',
                        h if h.is_ascii_hexdigit() => {
                            let l = self.bump();
                            let hex = [h, l];
                            let s = std::str::from_utf8(&hex).unwrap_or("");
                            u8::from_str_radix(s, 16)
                                .map_err(|_| self.err(pos, "bad $hh escape in string"))?
                        }
                        _ => return Err(self.err(pos, "unknown $ escape in string")),
                    };
                    out.push(ch);
                }
                c if c < 0x80 => out.push(c),
                lead => {
                    let ch = self.char_from(lead);
                    let byte = crate::charset::encode(ch).ok_or_else(|| {
                        self.err(
                            pos,
                            format!(
                                "'{ch}' is not a STRING character (STRING holds \
                                 Windows-1252): use a WSTRING literal \"...\""
                            ),
                        )
                    })?;
                    out.push(byte);
                }
            }
        }
        if out.len() > crate::types::MAX_STRING_LEN as usize {
            return Err(self.err(
                pos,
                format!(
                    "string literal longer than {} characters",
                    crate::types::MAX_STRING_LEN
                ),
            ));
        }
        Ok(Tok::Str(out))
    }

    /// `"..."`: a WSTRING literal. Escapes as in a STRING with `$"` for the quote and
    /// four hex digits (`$20AC`) for one code unit; other characters are the source's
    /// UTF-8 text in UTF-16.
    fn wide_string(&mut self, pos: Pos) -> Result<Tok, CompileError> {
        self.bump();
        let mut out: Vec<u16> = Vec::new();
        loop {
            if self.i >= self.src.len() || self.peek(0) == b'\n' {
                return Err(self.err(
                    pos,
                    "WSTRING literal is not closed: '\"' expected before the end of the line",
                ));
            }
            let c = self.bump();
            match c {
                b'"' => break,
                b'$' => {
                    let e = self.bump();
                    let unit = match e.to_ascii_uppercase() {
                        b'$' => b'$' as u16,
                        b'"' => b'"' as u16,
                        b'\'' => b'\'' as u16,
                        b'L' | b'N' => b'\n' as u16,
                        b'P' => 0x0c,
                        b'R' => b'\r' as u16,
                        b'T' => b'\t' as u16,
                        h if h.is_ascii_hexdigit() => {
                            let hex = [h, self.bump(), self.bump(), self.bump()];
                            let s = std::str::from_utf8(&hex).unwrap_or("");
                            u16::from_str_radix(s, 16).map_err(|_| {
                                self.err(pos, "bad $hhhh escape in WSTRING: four hex digits")
                            })?
                        }
                        _ => return Err(self.err(pos, "unknown $ escape in WSTRING")),
                    };
                    out.push(unit);
                }
                c if c < 0x80 => out.push(c as u16),
                lead => {
                    let mut pair = [0u16; 2];
                    out.extend_from_slice(self.char_from(lead).encode_utf16(&mut pair));
                }
            }
        }
        if out.len() > crate::types::MAX_STRING_LEN as usize {
            return Err(self.err(
                pos,
                format!(
                    "WSTRING literal longer than {} characters",
                    crate::types::MAX_STRING_LEN
                ),
            ));
        }
        Ok(Tok::WStr(out))
    }

    /// The character whose UTF-8 starts with `lead`, just taken; moves past the rest.
    /// The source is a `str`, so its bytes are UTF-8.
    fn char_from(&mut self, lead: u8) -> char {
        let len = match lead {
            0xc0..=0xdf => 2,
            0xe0..=0xef => 3,
            0xf0..=0xf7 => 4,
            _ => 1,
        };
        let start = self.i - 1;
        let end = (start + len).min(self.src.len());
        self.i = end;
        std::str::from_utf8(&self.src[start..end])
            .ok()
            .and_then(|t| t.chars().next())
            .unwrap_or(char::REPLACEMENT_CHARACTER)
    }

    fn direct(&mut self, pos: Pos) -> Result<Tok, CompileError> {
        self.bump();
        let area = match self.bump().to_ascii_uppercase() {
            b'I' => Area::Input,
            b'Q' => Area::Output,
            b'M' => Area::Memory,
            _ => return Err(self.err(pos, "direct address must start with %I, %Q or %M")),
        };
        let size = match self.peek(0).to_ascii_uppercase() {
            b'X' => Some(AddrSize::Bit),
            b'B' => Some(AddrSize::Byte),
            b'W' => Some(AddrSize::Word),
            b'D' => Some(AddrSize::Double),
            b'L' => Some(AddrSize::Long),
            _ => None,
        };
        if size.is_some() {
            self.bump();
        }
        let size = size.unwrap_or(AddrSize::Bit);
        let index = self.digits(10, pos)?;
        let index = u32::try_from(index)
            .ok()
            .filter(|i| *i < 1 << 20)
            .ok_or_else(|| self.err(pos, "direct address is too large"))?;
        let mut bit = 0u8;
        if size == AddrSize::Bit {
            if self.peek(0) != b'.' || !self.peek(1).is_ascii_digit() {
                return Err(self.err(pos, "bit address needs the form %IX<byte>.<bit>"));
            }
            self.bump();
            let b = self.digits(10, pos)?;
            if b > 7 {
                return Err(self.err(pos, "bit number must be 0..7"));
            }
            bit = b as u8;
        }
        Ok(Tok::Direct(DirectAddr {
            area,
            size,
            index,
            bit,
        }))
    }

    fn typed_literal(&mut self, prefix: String, pos: Pos) -> Result<Tok, CompileError> {
        match prefix.as_str() {
            "T" | "TIME" | "LTIME" | "LT" => self.duration(pos),
            p => match crate::dates::literal_kind(p) {
                Some(kind) => {
                    let start = self.i;
                    while matches!(self.peek(0), b'0'..=b'9' | b'-' | b':' | b'.') {
                        self.bump();
                    }
                    let text = &self.src[start..self.i];
                    let ns = crate::dates::parse(kind, text).ok_or_else(|| {
                        let form = match kind {
                            crate::dates::Moment::Date => "D#yyyy-mm-dd",
                            crate::dates::Moment::Tod => "TOD#hh:mm:ss[.fff]",
                            crate::dates::Moment::Dt => "DT#yyyy-mm-dd-hh:mm:ss[.fff]",
                        };
                        self.err(
                            pos,
                            format!("not a valid {prefix}# literal: write {form} (1970 to 2262)"),
                        )
                    })?;
                    Ok(Tok::Moment(kind, ns))
                }
                None => Ok(Tok::TypedPrefix(prefix)),
            },
        }
    }

    /// `T#1d2h3m4s5ms6us7ns`, `T#1.5s`, `T#-5s`, underscores allowed.
    fn duration(&mut self, pos: Pos) -> Result<Tok, CompileError> {
        let negative = if self.peek(0) == b'-' {
            self.bump();
            true
        } else {
            false
        };
        let mut total: f64 = 0.0;
        let mut exact: i128 = 0;
        let mut any = false;
        let mut last_unit = u32::MAX;
        loop {
            if self.peek(0) == b'_' {
                self.bump();
                continue;
            }
            if !self.peek(0).is_ascii_digit() {
                break;
            }
            let start = self.i;
            while self.peek(0).is_ascii_digit() || self.peek(0) == b'_' {
                self.bump();
            }
            let mut frac = false;
            if self.peek(0) == b'.' && self.peek(1).is_ascii_digit() {
                frac = true;
                self.bump();
                while self.peek(0).is_ascii_digit() {
                    self.bump();
                }
            }
            let text: String = self.src[start..self.i]
                .iter()
                .filter(|c| **c != b'_')
                .map(|c| *c as char)
                .collect();
            let c0 = self.peek(0).to_ascii_lowercase();
            let c1 = self.peek(1).to_ascii_lowercase();
            let (unit_ns, len, rank): (i128, usize, u32) = match (c0, c1) {
                (b'd', _) => (86_400_000_000_000, 1, 6),
                (b'h', _) => (3_600_000_000_000, 1, 5),
                (b'm', b's') => (1_000_000, 2, 2),
                (b'm', _) => (60_000_000_000, 1, 4),
                (b's', _) => (1_000_000_000, 1, 3),
                (b'u', b's') => (1_000, 2, 1),
                (b'n', b's') => (1, 2, 0),
                _ => return Err(self.err(pos, "duration needs a unit: d, h, m, s, ms, us or ns")),
            };
            if rank >= last_unit {
                return Err(self.err(pos, "duration units must go from larger to smaller"));
            }
            last_unit = rank;
            for _ in 0..len {
                self.bump();
            }
            if frac {
                let v: f64 = text
                    .parse()
                    .map_err(|_| self.err(pos, "malformed duration"))?;
                total += v * unit_ns as f64;
            } else {
                let v: i128 = text
                    .parse()
                    .map_err(|_| self.err(pos, "malformed duration"))?;
                exact = v
                    .checked_mul(unit_ns)
                    .and_then(|x| x.checked_add(exact))
                    .filter(|x| *x <= i64::MAX as i128)
                    .ok_or_else(|| self.err(pos, "duration is too large"))?;
            }
            any = true;
        }
        if !any {
            return Err(self.err(pos, "duration literal has no value"));
        }
        // The fractional parts in f64 may be of any size (`T#1.5e300h` is not a thing, but
        // `T#99…9.5h` is): out of the i64 range they are too large, never an overflow.
        if !total.is_finite() || total.abs() > i64::MAX as f64 {
            return Err(self.err(pos, "duration is too large"));
        }
        let ns = exact + total.round() as i128;
        if ns > i64::MAX as i128 {
            return Err(self.err(pos, "duration is too large"));
        }
        Ok(Tok::Time(if negative { -ns } else { ns }))
    }
}
