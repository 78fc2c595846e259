//! Reading one line of RS274/NGC into a [`Block`]: words, parameter settings, comments,
//! o-word control, with expressions evaluated as the line is read (parameter values are the
//! ones from before the line, as RS274/NGC requires).
//!
//! Spaces and tabs are ignored anywhere outside comments, letters are case-insensitive.

use crate::error::ErrorKind;

/// Axis word letters in pose order (X Y Z A B C U V W).
pub(crate) const AXES: [u8; 9] = [b'x', b'y', b'z', b'a', b'b', b'c', b'u', b'v', b'w'];

/// Highest numbered parameter.
pub const MAX_PARAMETER: usize = 5602;

/// Reads parameter values while a line is evaluated.
pub(crate) trait ParamSource {
    /// Numbered parameter `#index` (1..=5602).
    fn numbered(&self, index: usize) -> f64;
    /// Named parameter, `None` if it does not exist. `name` is lower case without spaces.
    fn named(&self, name: &str) -> Option<f64>;
}

/// A reading error: kind, 0-based byte column, message.
#[derive(Debug)]
pub(crate) struct ReadError {
    pub kind: ErrorKind,
    pub column: usize,
    pub message: String,
}

type Res<T> = Result<T, ReadError>;

fn err<T>(kind: ErrorKind, column: usize, message: impl Into<String>) -> Res<T> {
    Err(ReadError {
        kind,
        column,
        message: message.into(),
    })
}

/// G-code modal groups, as indexes into [`Block::g`].
pub(crate) mod gg {
    pub const NON_MODAL: usize = 0;
    pub const MOTION: usize = 1;
    pub const PLANE: usize = 2;
    pub const DISTANCE: usize = 3;
    pub const IJK: usize = 4;
    pub const FEED_MODE: usize = 5;
    pub const UNITS: usize = 6;
    pub const CUTTER: usize = 7;
    pub const LENGTH: usize = 8;
    pub const RETRACT: usize = 9;
    pub const COORD: usize = 10;
    pub const CONTROL: usize = 11;
    pub const SPINDLE: usize = 12;
    pub const LATHE: usize = 13;
    pub const COUNT: usize = 14;
}

/// M-code modal groups, as indexes into [`Block::m`].
pub(crate) mod mg {
    pub const STOP: usize = 0;
    pub const IO: usize = 1;
    pub const TOOL: usize = 2;
    pub const SPINDLE: usize = 3;
    pub const COOLANT: usize = 4;
    pub const OVERRIDE: usize = 5;
    pub const USER: usize = 6;
    pub const COUNT: usize = 7;
}

/// Modal group of a G code given in tenths (G38.2 = 382), `None` if unknown.
pub(crate) fn g_group(code: i32) -> Option<usize> {
    use gg::*;
    Some(match code {
        40 | 53 | 100 | 280 | 281 | 300 | 301 | 520 | 530 | 920 | 921 | 922 | 923 => NON_MODAL,
        0 | 10 | 20 | 30 | 50 | 51 | 52 | 330 | 331 | 382 | 383 | 384 | 385 | 700 | 710 | 711
        | 712 | 720 | 721 | 722 | 730 | 740 | 760 | 800 | 810 | 820 | 830 | 840 | 850 | 860
        | 870 | 880 | 890 => MOTION,
        170 | 180 | 190 | 171 | 181 | 191 => PLANE,
        900 | 910 => DISTANCE,
        901 | 911 => IJK,
        930 | 940 | 950 => FEED_MODE,
        200 | 210 => UNITS,
        400 | 410 | 420 | 411 | 421 => CUTTER,
        430 | 431 | 432 | 490 => LENGTH,
        980 | 990 => RETRACT,
        540 | 550 | 560 | 570 | 580 | 590 | 591 | 592 | 593 => COORD,
        610 | 611 | 640 => CONTROL,
        960 | 970 => SPINDLE,
        70 | 80 => LATHE,
        _ => return None,
    })
}

/// Modal group of an M code, `None` if unknown.
pub(crate) fn m_group(code: i32) -> Option<usize> {
    use mg::*;
    Some(match code {
        0 | 1 | 2 | 30 | 60 | 99 => STOP,
        62..=68 => IO,
        6 | 61 => TOOL,
        3 | 4 | 5 | 19 | 70..=73 => SPINDLE,
        7..=9 => COOLANT,
        48..=53 => OVERRIDE,
        100..=199 | 428 | 429 => USER,
        98 => TOOL_CALL,
        _ => return None,
    })
}

/// M98 lives in a group of its own (it cannot be combined with M6 etc. anyway).
const TOOL_CALL: usize = mg::USER;

/// Kind of comment that does something.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum CommentKind {
    Plain,
    Msg,
    Debug,
    Print,
    Log,
    LogOpen,
    LogAppend,
    LogClose,
    Abort,
}

/// An o-word control keyword.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum OKeyword {
    Sub,
    EndSub,
    Call,
    Do,
    While,
    EndWhile,
    If,
    ElseIf,
    Else,
    EndIf,
    Break,
    Continue,
    Return,
    Repeat,
    EndRepeat,
    /// A bare `O1000` line: start of a Fanuc-style subprogram.
    Fanuc,
}

/// Reference to a parameter being set.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum ParamRef {
    Numbered(usize),
    Named(String),
}

/// One block (line) as read.
#[derive(Debug)]
pub(crate) struct Block {
    /// Line starts with `/`.
    pub block_delete: bool,
    /// Line is a `%` delimiter.
    pub percent: bool,
    pub n: Option<u32>,
    /// Values of letter words a..z (index = letter - 'a').
    pub words: [f64; 26],
    /// Bit i set when letter i is present.
    pub has: u32,
    /// 0-based column of each letter word.
    pub col: [u16; 26],
    /// G code (tenths) per modal group, -1 if none.
    pub g: [i32; gg::COUNT],
    pub g_col: [u16; gg::COUNT],
    /// M code per modal group, -1 if none.
    pub m: [i32; mg::COUNT],
    pub m_col: [u16; mg::COUNT],
    pub m98: bool,
    pub dollar: Option<f64>,
    /// Polar coordinates: `@` radius and `^` angle (degrees), with their columns.
    pub polar_radius: Option<f64>,
    pub polar_angle: Option<f64>,
    pub polar_col: u16,
    pub assigns: Vec<(ParamRef, f64)>,
    pub comment_kind: CommentKind,
    pub has_comment: bool,
    /// Text of the last comment (for MSG/DEBUG/PRINT the part after the comma).
    pub comment: String,
    pub o_label: String,
    pub o_keyword: Option<OKeyword>,
    pub o_col: u16,
    /// Call arguments, or the single condition / return value / repeat count.
    pub o_args: Vec<f64>,
    /// Words of the line other than N and comments (to reject them on o-word lines).
    pub other_words: bool,
}

impl Default for Block {
    fn default() -> Self {
        Block {
            block_delete: false,
            percent: false,
            n: None,
            words: [0.0; 26],
            has: 0,
            col: [0; 26],
            g: [-1; gg::COUNT],
            g_col: [0; gg::COUNT],
            m: [-1; mg::COUNT],
            m_col: [0; mg::COUNT],
            m98: false,
            dollar: None,
            polar_radius: None,
            polar_angle: None,
            polar_col: 0,
            assigns: Vec::new(),
            comment_kind: CommentKind::Plain,
            has_comment: false,
            comment: String::new(),
            o_label: String::new(),
            o_keyword: None,
            o_col: 0,
            o_args: Vec::new(),
            other_words: false,
        }
    }
}

impl Block {
    fn clear(&mut self) {
        self.block_delete = false;
        self.percent = false;
        self.n = None;
        self.has = 0;
        self.g = [-1; gg::COUNT];
        self.m = [-1; mg::COUNT];
        self.m98 = false;
        self.dollar = None;
        self.polar_radius = None;
        self.polar_angle = None;
        self.assigns.clear();
        self.comment_kind = CommentKind::Plain;
        self.has_comment = false;
        self.comment.clear();
        self.o_label.clear();
        self.o_keyword = None;
        self.o_args.clear();
        self.other_words = false;
    }

    /// Value of letter word `c` (lower case) if present.
    #[inline]
    pub fn get(&self, c: u8) -> Option<f64> {
        let i = (c - b'a') as usize;
        if self.has & (1 << i) != 0 {
            Some(self.words[i])
        } else {
            None
        }
    }

    #[inline]
    pub fn has(&self, c: u8) -> bool {
        self.has & (1 << (c - b'a')) != 0
    }

    /// 0-based column of letter word `c`.
    pub fn column(&self, c: u8) -> usize {
        self.col[(c - b'a') as usize] as usize
    }

    /// True if a polar coordinate (`@` or `^`) is present.
    pub fn has_polar(&self) -> bool {
        self.polar_radius.is_some() || self.polar_angle.is_some()
    }

    /// True if any axis word X Y Z A B C U V W is present.
    pub fn has_axis(&self) -> bool {
        const AXES: u32 = (1 << (b'x' - b'a'))
            | (1 << (b'y' - b'a'))
            | (1 << (b'z' - b'a'))
            | 1
            | (1 << 1)
            | (1 << 2)
            | (1 << (b'u' - b'a'))
            | (1 << (b'v' - b'a'))
            | (1 << (b'w' - b'a'));
        self.has & AXES != 0
    }
}

/// The line reader. Holds the line's bytes and a cursor.
pub(crate) struct Reader<'a, P: ParamSource + ?Sized> {
    s: &'a [u8],
    i: usize,
    params: &'a P,
    /// Nesting of values being read (brackets, indirect parameters, functions).
    depth: u32,
}

/// Deepest nesting of brackets, functions and indirect parameters in one value.
const MAX_DEPTH: u32 = 64;

/// Reads `line` into `block` (cleared first).
pub(crate) fn read_block<P: ParamSource + ?Sized>(
    line: &[u8],
    params: &P,
    block: &mut Block,
) -> Res<()> {
    block.clear();
    let mut r = Reader {
        s: line,
        i: 0,
        params,
        depth: 0,
    };
    r.block(block)
}

/// Reads a bare o-word head of a line (for skipping over blocks without evaluating them):
/// returns the label and keyword if the line starts (after `/` and an N word) with one.
pub(crate) fn peek_oword(line: &[u8], label: &mut String) -> Option<OKeyword> {
    let mut i = 0;
    let skip = |i: &mut usize| {
        while *i < line.len() && (line[*i] == b' ' || line[*i] == b'\t') {
            *i += 1;
        }
    };
    skip(&mut i);
    if i < line.len() && line[i] == b'/' {
        i += 1;
        skip(&mut i);
    }
    if i < line.len() && (line[i] | 0x20) == b'n' {
        i += 1;
        skip(&mut i);
        while i < line.len() && (line[i].is_ascii_digit() || line[i] == b' ' || line[i] == b'\t') {
            i += 1;
        }
    }
    if i >= line.len() || (line[i] | 0x20) != b'o' {
        return None;
    }
    i += 1;
    label.clear();
    skip(&mut i);
    if i < line.len() && line[i] == b'<' {
        i += 1;
        while i < line.len() && line[i] != b'>' {
            if line[i] != b' ' && line[i] != b'\t' {
                label.push((line[i] as char).to_ascii_lowercase());
            }
            i += 1;
        }
        if i >= line.len() {
            return None;
        }
        i += 1;
    } else {
        while i < line.len() && (line[i].is_ascii_digit() || line[i] == b' ' || line[i] == b'\t') {
            if line[i].is_ascii_digit() {
                label.push(line[i] as char);
            }
            i += 1;
        }
        // Leading zeros do not make a different label.
        let trimmed = label.trim_start_matches('0');
        if trimmed.len() != label.len() {
            *label = if trimmed.is_empty() {
                "0".to_string()
            } else {
                trimmed.to_string()
            };
        }
        if label.is_empty() {
            return None;
        }
    }
    let mut word = [0u8; 10];
    let mut n = 0;
    while i < line.len() {
        let c = line[i];
        if c == b' ' || c == b'\t' {
            i += 1;
            continue;
        }
        if c.is_ascii_alphabetic() && n < word.len() {
            word[n] = c.to_ascii_lowercase();
            n += 1;
            i += 1;
        } else {
            break;
        }
    }
    keyword(&word[..n]).or(if n == 0 { Some(OKeyword::Fanuc) } else { None })
}

fn keyword(w: &[u8]) -> Option<OKeyword> {
    Some(match w {
        b"sub" => OKeyword::Sub,
        b"endsub" => OKeyword::EndSub,
        b"call" => OKeyword::Call,
        b"do" => OKeyword::Do,
        b"while" => OKeyword::While,
        b"endwhile" => OKeyword::EndWhile,
        b"if" => OKeyword::If,
        b"elseif" => OKeyword::ElseIf,
        b"else" => OKeyword::Else,
        b"endif" => OKeyword::EndIf,
        b"break" => OKeyword::Break,
        b"continue" => OKeyword::Continue,
        b"return" => OKeyword::Return,
        b"repeat" => OKeyword::Repeat,
        b"endrepeat" => OKeyword::EndRepeat,
        _ => return None,
    })
}

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum BinOp {
    Pow,
    Mul,
    Div,
    Mod,
    Add,
    Sub,
    Eq,
    Ne,
    Gt,
    Ge,
    Lt,
    Le,
    And,
    Or,
    Xor,
}

impl BinOp {
    fn precedence(self) -> u8 {
        match self {
            BinOp::Pow => 6,
            BinOp::Mul | BinOp::Div | BinOp::Mod => 5,
            BinOp::Add | BinOp::Sub => 4,
            BinOp::Eq | BinOp::Ne | BinOp::Gt | BinOp::Ge | BinOp::Lt | BinOp::Le => 3,
            BinOp::And | BinOp::Or | BinOp::Xor => 2,
        }
    }
}

/// Tolerance of EQ and NE, as in LinuxCNC.
const TOLERANCE_EQUAL: f64 = 0.0001;

impl<'a, P: ParamSource + ?Sized> Reader<'a, P> {
    /// Current byte, skipping spaces and tabs.
    #[inline]
    fn peek(&mut self) -> Option<u8> {
        while self.i < self.s.len() {
            let c = self.s[self.i];
            if c == b' ' || c == b'\t' || c == b'\r' {
                self.i += 1;
            } else {
                return Some(c);
            }
        }
        None
    }

    #[inline]
    fn peek_lower(&mut self) -> Option<u8> {
        self.peek().map(|c| c.to_ascii_lowercase())
    }

    fn block(&mut self, b: &mut Block) -> Res<()> {
        if self.peek() == Some(b'/') {
            b.block_delete = true;
            self.i += 1;
        }
        if self.peek() == Some(b'%') {
            return self.percent_line(b);
        }
        if self.peek_lower() == Some(b'n') {
            self.line_number(b)?;
        }
        if self.peek_lower() == Some(b'o') {
            return self.oword(b);
        }
        while let Some(c) = self.peek() {
            self.word(b, c)?;
        }
        Ok(())
    }

    fn percent_line(&mut self, b: &mut Block) -> Res<()> {
        let col = self.i;
        self.i += 1;
        if self.peek().is_some_and(|c| c != b'(' && c != b';') {
            return err(
                ErrorKind::Syntax,
                col,
                "a % line may hold nothing but a comment",
            );
        }
        b.percent = true;
        Ok(())
    }

    fn line_number(&mut self, b: &mut Block) -> Res<()> {
        self.i += 1;
        let col = self.i;
        let v = self.unsigned_integer()?;
        b.n = Some(u32::try_from(v).map_err(|_| ReadError {
            kind: ErrorKind::BadValue,
            column: col,
            message: "line number too large".into(),
        })?);
        Ok(())
    }

    /// One word (or comment, or parameter assignment) starting with `c`.
    fn word(&mut self, b: &mut Block, c: u8) -> Res<()> {
        let col = self.i;
        match c.to_ascii_lowercase() {
            b'(' => self.comment(b)?,
            b';' => {
                // The rest of the line is a comment that does nothing.
                self.i = self.s.len();
            }
            b'#' => {
                self.i += 1;
                self.assignment(b, col)?;
                b.other_words = true;
            }
            b'g' => self.g_word(b, col)?,
            b'm' => self.m_word(b, col)?,
            b'@' | b'^' => self.polar_word(b, c, col)?,
            b'$' => {
                self.i += 1;
                if b.dollar.is_some() {
                    return err(ErrorKind::Conflict, col, "two $ words on one line");
                }
                b.dollar = Some(self.real_value()?);
                b.other_words = true;
            }
            l @ (b'a'..=b'f' | b'h'..=b'l' | b'p'..=b'z') => self.letter_word(b, l, col)?,
            b'n' => {
                return err(ErrorKind::Syntax, col, "an N word may only begin a line");
            }
            b'o' => {
                return err(ErrorKind::Syntax, col, "an O word must begin the line");
            }
            _ => {
                return err(
                    ErrorKind::Syntax,
                    col,
                    format!("bad character '{}'", printable(c)),
                );
            }
        }
        Ok(())
    }

    fn g_word(&mut self, b: &mut Block, col: usize) -> Res<()> {
        self.i += 1;
        let code = self.code(col, b'g')?;
        let Some(group) = g_group(code) else {
            return err(
                ErrorKind::UnknownWord,
                col,
                format!("unknown G code G{}", fmt_code(code)),
            );
        };
        // As in LinuxCNC, G80 gives way to another motion code on the line.
        if group == gg::MOTION && (code == 800 || b.g[group] == 800) && b.g[group] != -1 {
            if code != 800 {
                b.g[group] = code;
                b.g_col[group] = col as u16;
            }
            b.other_words = true;
            return Ok(());
        }
        if b.g[group] != -1 {
            let message = if b.g[group] == code {
                format!("G{} appears twice on the line", fmt_code(code))
            } else {
                format!(
                    "G{} and G{} are in the same modal group",
                    fmt_code(b.g[group]),
                    fmt_code(code)
                )
            };
            return err(ErrorKind::Conflict, col, message);
        }
        b.g[group] = code;
        b.g_col[group] = col as u16;
        b.other_words = true;
        Ok(())
    }

    fn m_word(&mut self, b: &mut Block, col: usize) -> Res<()> {
        self.i += 1;
        let code = self.code(col, b'm')?;
        if code % 10 != 0 {
            return err(
                ErrorKind::UnknownWord,
                col,
                format!("unknown M code M{}", fmt_code(code)),
            );
        }
        let code = code / 10;
        if code == 98 {
            if b.m98 {
                return err(ErrorKind::Conflict, col, "two M98 on one line");
            }
            b.m98 = true;
            b.m_col[mg::USER] = col as u16;
            b.other_words = true;
            return Ok(());
        }
        let Some(group) = m_group(code) else {
            return err(
                ErrorKind::UnknownWord,
                col,
                format!("unknown M code M{code}"),
            );
        };
        if b.m[group] != -1 {
            let message = if b.m[group] == code {
                format!("M{code} appears twice on the line")
            } else {
                format!("M{} and M{code} are in the same modal group", b.m[group])
            };
            return err(ErrorKind::Conflict, col, message);
        }
        b.m[group] = code;
        b.m_col[group] = col as u16;
        b.other_words = true;
        Ok(())
    }

    /// `@` (polar radius) or `^` (polar angle).
    fn polar_word(&mut self, b: &mut Block, c: u8, col: usize) -> Res<()> {
        self.i += 1;
        let slot = if c == b'@' {
            &mut b.polar_radius
        } else {
            &mut b.polar_angle
        };
        if slot.is_some() {
            return err(
                ErrorKind::Conflict,
                col,
                format!("two {} words on one line", c as char),
            );
        }
        let v = self.real_value()?;
        let slot = if c == b'@' {
            &mut b.polar_radius
        } else {
            &mut b.polar_angle
        };
        *slot = Some(v);
        b.polar_col = col as u16;
        b.other_words = true;
        Ok(())
    }

    /// A word of a letter and a number: an axis, F, S, T, P and the like.
    fn letter_word(&mut self, b: &mut Block, l: u8, col: usize) -> Res<()> {
        self.i += 1;
        let idx = (l - b'a') as usize;
        if b.has & (1 << idx) != 0 {
            return err(
                ErrorKind::Conflict,
                col,
                format!("two {} words on one line", l.to_ascii_uppercase() as char),
            );
        }
        let v = self.real_value()?;
        b.words[idx] = v;
        b.has |= 1 << idx;
        b.col[idx] = col as u16;
        b.other_words = true;
        Ok(())
    }

    fn code_tenths(&self, v: f64, col: usize, letter: u8) -> Res<i32> {
        if !v.is_finite() {
            return err(
                ErrorKind::BadValue,
                col,
                format!(
                    "{} code is not a finite number",
                    letter.to_ascii_uppercase() as char
                ),
            );
        }
        if v < 0.0 {
            return err(
                ErrorKind::BadValue,
                col,
                format!("negative {} code", letter.to_ascii_uppercase() as char),
            );
        }
        let t = v * 10.0;
        let r = t.round();
        if (t - r).abs() > 0.0001 || r > 100_000.0 {
            return err(
                ErrorKind::UnknownWord,
                col,
                format!("{}{} is not a code", letter.to_ascii_uppercase() as char, v),
            );
        }
        Ok(r as i32)
    }

    fn comment(&mut self, b: &mut Block) -> Res<()> {
        let start_col = self.i;
        self.i += 1; // '('
        let start = self.i;
        let mut end = None;
        while self.i < self.s.len() {
            match self.s[self.i] {
                b')' => {
                    end = Some(self.i);
                    break;
                }
                b'(' => return err(ErrorKind::Syntax, self.i, "nested comment"),
                _ => self.i += 1,
            }
        }
        let Some(end) = end else {
            return err(ErrorKind::Syntax, start_col, "comment not closed with ')'");
        };
        self.i = end + 1;
        let text = &self.s[start..end];
        let t = text
            .iter()
            .position(|c| *c != b' ' && *c != b'\t')
            .unwrap_or(text.len());
        let body = &text[t..];
        let starts = |p: &[u8]| body.len() >= p.len() && body[..p.len()].eq_ignore_ascii_case(p);
        b.has_comment = true;
        b.comment.clear();
        let (kind, rest) = if starts(b"msg,") {
            (CommentKind::Msg, &body[4..])
        } else if starts(b"debug,") {
            (CommentKind::Debug, &body[6..])
        } else if starts(b"print,") {
            (CommentKind::Print, &body[6..])
        } else if starts(b"log,") {
            (CommentKind::Log, &body[4..])
        } else if starts(b"logopen,") {
            (CommentKind::LogOpen, &body[8..])
        } else if starts(b"logappend,") {
            (CommentKind::LogAppend, &body[10..])
        } else if body.eq_ignore_ascii_case(b"logclose") {
            (CommentKind::LogClose, &body[8..])
        } else if starts(b"abort,") {
            (CommentKind::Abort, &body[6..])
        } else {
            (CommentKind::Plain, text)
        };
        b.comment_kind = kind;
        b.comment.push_str(&String::from_utf8_lossy(rest));
        Ok(())
    }

    fn assignment(&mut self, b: &mut Block, col: usize) -> Res<()> {
        let target = if self.peek() == Some(b'<') {
            let name = self.param_name()?;
            if name.starts_with('_') && crate::params::is_predefined(&name) {
                return err(
                    ErrorKind::BadValue,
                    col,
                    format!("parameter #<{name}> is read-only"),
                );
            }
            ParamRef::Named(name)
        } else {
            let idx = self.param_index(col)?;
            ParamRef::Numbered(idx)
        };
        if self.peek() != Some(b'=') {
            return err(
                ErrorKind::Syntax,
                self.i,
                "'=' missing in parameter setting",
            );
        }
        self.i += 1;
        let v = self.real_value()?;
        b.assigns.push((target, v));
        Ok(())
    }

    /// Reads `<name>` (cursor at '<'), returns the lower-case name without spaces.
    fn param_name(&mut self) -> Res<String> {
        let col = self.i;
        self.i += 1;
        let mut name = String::new();
        while self.i < self.s.len() {
            let c = self.s[self.i];
            self.i += 1;
            match c {
                b'>' => {
                    if name.is_empty() {
                        return err(ErrorKind::Syntax, col, "empty parameter name");
                    }
                    return Ok(name);
                }
                b' ' | b'\t' => {}
                _ => name.push((c as char).to_ascii_lowercase()),
            }
        }
        err(
            ErrorKind::Syntax,
            col,
            "named parameter not terminated with '>'",
        )
    }

    fn param_index(&mut self, col: usize) -> Res<usize> {
        let v = self.real_value()?;
        let r = v.round();
        if (v - r).abs() > 0.0001 {
            return err(
                ErrorKind::BadValue,
                col,
                format!("parameter number {v} is not an integer"),
            );
        }
        if !(1.0..=MAX_PARAMETER as f64).contains(&r) {
            return err(
                ErrorKind::BadValue,
                col,
                format!("parameter number {r} out of range 1..{MAX_PARAMETER}"),
            );
        }
        Ok(r as usize)
    }

    fn unsigned_integer(&mut self) -> Res<u64> {
        let col = self.i;
        let mut v: u64 = 0;
        let mut any = false;
        while let Some(c) = self.peek() {
            if c.is_ascii_digit() {
                v = v.saturating_mul(10).saturating_add(u64::from(c - b'0'));
                any = true;
                self.i += 1;
            } else {
                break;
            }
        }
        if !any {
            return err(ErrorKind::Syntax, col, "digits expected");
        }
        Ok(v)
    }

    /// A real value: number, `[expression]`, `#parameter`, or a function call.
    fn real_value(&mut self) -> Res<f64> {
        self.peek();
        let col = self.i;
        if self
            .s
            .get(self.i)
            .is_some_and(|c| c.is_ascii_digit() || *c == b'.')
        {
            return self.number(col);
        }
        if self.depth >= MAX_DEPTH {
            return err(ErrorKind::Syntax, col, "expression nested too deeply");
        }
        self.depth += 1;
        let v = self.nested_value(col);
        self.depth -= 1;
        v
    }

    fn nested_value(&mut self, col: usize) -> Res<f64> {
        match self.peek() {
            None => err(ErrorKind::Syntax, col, "value expected at end of line"),
            Some(b'[') => {
                self.i += 1;
                self.expression()
            }
            Some(b'#') => {
                self.i += 1;
                self.param_value(col)
            }
            Some(c) if c.is_ascii_alphabetic() => self.function(),
            Some(b'-') => {
                self.i += 1;
                if matches!(self.peek(), Some(b'[' | b'#')) || self.peek_is_function() {
                    Ok(-self.real_value()?)
                } else {
                    Ok(-self.number(col)?)
                }
            }
            Some(b'+') => {
                self.i += 1;
                if matches!(self.peek(), Some(b'[' | b'#')) || self.peek_is_function() {
                    self.real_value()
                } else {
                    self.number(col)
                }
            }
            Some(_) => self.number(col),
        }
    }

    fn peek_is_function(&mut self) -> bool {
        self.peek().is_some_and(|c| c.is_ascii_alphabetic())
    }

    fn param_value(&mut self, col: usize) -> Res<f64> {
        if self.peek() == Some(b'<') {
            let name = self.param_name()?;
            match self.params.named(&name) {
                Some(v) => Ok(v),
                None => err(
                    ErrorKind::Expression,
                    col,
                    format!("named parameter #<{name}> is not defined"),
                ),
            }
        } else {
            let idx = self.param_index(col)?;
            Ok(self.params.numbered(idx))
        }
    }

    /// Unsigned decimal number (the sign was read by the caller). Spaces may appear
    /// anywhere inside it. The value is exact-rounded for up to 15 significant digits.
    fn number(&mut self, col: usize) -> Res<f64> {
        if let Some(v) = self.plain_number() {
            return Ok(v);
        }
        let s = self.s;
        let mut i = self.i;
        let mut mant: u64 = 0;
        let mut significant = 0u32;
        // Digit counts saturate: a number of more than 2^31 digits is out of any range anyway.
        let mut frac = 0i32;
        let mut dropped = 0i32;
        let mut seen_point = false;
        let mut any = false;
        while i < s.len() {
            let c = s[i];
            let d = c.wrapping_sub(b'0');
            if d < 10 {
                any = true;
                if significant < 18 {
                    mant = mant * 10 + u64::from(d);
                    if mant != 0 {
                        significant += 1;
                    }
                    if seen_point {
                        frac = frac.saturating_add(1);
                    }
                } else if !seen_point {
                    dropped = dropped.saturating_add(1);
                }
            } else if c == b'.' && !seen_point {
                seen_point = true;
            } else if c != b' ' && c != b'\t' && c != b'\r' {
                break;
            }
            i += 1;
        }
        self.i = i;
        if !any {
            return err(ErrorKind::Syntax, col, "number expected");
        }
        const POW10: [f64; 23] = [
            1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
            1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
        ];
        let m = mant as f64;
        let exp = dropped.saturating_sub(frac);
        // Exact when the mantissa fits 53 bits and the power of ten is exact.
        Ok(if exp <= 0 && ((-exp) as usize) < POW10.len() {
            m / POW10[(-exp) as usize]
        } else if exp > 0 && (exp as usize) < POW10.len() {
            m * POW10[exp as usize]
        } else {
            m * 10f64.powi(exp)
        })
    }

    /// Fast path of [`Reader::number`] for the common `123.456` form (no spaces, at most 15
    /// digits); `None` (cursor unchanged) for anything else.
    #[inline]
    fn plain_number(&mut self) -> Option<f64> {
        const POW10: [f64; 16] = [
            1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
        ];
        let s = self.s;
        let mut i = self.i;
        // At most 15 digits are read here (the mantissa then stays below 10^15 and exact);
        // a longer number is left to `number`.
        let mut mant: u64 = 0;
        let mut digits = 0usize;
        while i < s.len() {
            let d = s[i].wrapping_sub(b'0');
            if d >= 10 {
                break;
            }
            if digits == 15 {
                return None;
            }
            mant = mant * 10 + u64::from(d);
            digits += 1;
            i += 1;
        }
        let mut frac = 0;
        if i < s.len() && s[i] == b'.' {
            i += 1;
            while i < s.len() {
                let d = s[i].wrapping_sub(b'0');
                if d >= 10 {
                    break;
                }
                if digits == 15 {
                    return None;
                }
                mant = mant * 10 + u64::from(d);
                digits += 1;
                frac += 1;
                i += 1;
            }
        }
        if digits == 0 {
            return None;
        }
        // A space may continue the number ("1 2.5" is 12.5): look past blanks.
        let mut j = i;
        while j < s.len() && matches!(s[j], b' ' | b'\t' | b'\r') {
            j += 1;
        }
        if j < s.len() && (s[j].is_ascii_digit() || s[j] == b'.') {
            return None;
        }
        self.i = j;
        Some(mant as f64 / POW10[frac])
    }

    /// The value of a G or M word in tenths. Plain codes (`1`, `38.2`) are read directly;
    /// anything else (expressions, parameters, spaces) goes through [`Reader::real_value`].
    fn code(&mut self, col: usize, letter: u8) -> Res<i32> {
        let s = self.s;
        let mut i = self.i;
        let mut v: i32 = 0;
        let mut n = 0;
        while i < s.len() && s[i].is_ascii_digit() && n < 5 {
            v = v * 10 + i32::from(s[i] - b'0');
            i += 1;
            n += 1;
        }
        let mut fast = n > 0;
        let mut tenths = v * 10;
        if fast && i < s.len() && s[i] == b'.' {
            i += 1;
            if i < s.len() && s[i].is_ascii_digit() {
                tenths += i32::from(s[i] - b'0');
                i += 1;
            }
        }
        if fast && i < s.len() && matches!(s[i], b'0'..=b'9' | b'.') {
            fast = false;
        }
        if fast {
            // A space may continue the number ("G 1 7" is G17): look past blanks.
            let mut j = i;
            while j < s.len() && matches!(s[j], b' ' | b'\t' | b'\r') {
                j += 1;
            }
            if j >= s.len() || !(s[j].is_ascii_digit() || s[j] == b'.') {
                self.i = j;
                return Ok(tenths);
            }
        }
        let v = self.real_value()?;
        self.code_tenths(v, col, letter)
    }

    fn function(&mut self) -> Res<f64> {
        let col = self.i;
        let mut name = [0u8; 8];
        let mut n = 0;
        while let Some(c) = self.peek() {
            if c.is_ascii_alphabetic() && n < name.len() {
                name[n] = c.to_ascii_lowercase();
                n += 1;
                self.i += 1;
            } else {
                break;
            }
        }
        let name = &name[..n];
        if name == b"exists" {
            if self.peek() != Some(b'[') {
                return err(ErrorKind::Syntax, self.i, "'[' expected after EXISTS");
            }
            self.i += 1;
            if self.peek() != Some(b'#') {
                return err(ErrorKind::Syntax, self.i, "EXISTS needs a named parameter");
            }
            self.i += 1;
            if self.peek() != Some(b'<') {
                return err(ErrorKind::Syntax, self.i, "EXISTS needs a named parameter");
            }
            let pname = self.param_name()?;
            if self.peek() != Some(b']') {
                return err(ErrorKind::Syntax, self.i, "']' expected");
            }
            self.i += 1;
            return Ok(if self.params.named(&pname).is_some() {
                1.0
            } else {
                0.0
            });
        }
        let known = matches!(
            name,
            b"abs"
                | b"acos"
                | b"asin"
                | b"atan"
                | b"cos"
                | b"exp"
                | b"fix"
                | b"fup"
                | b"round"
                | b"ln"
                | b"sin"
                | b"sqrt"
                | b"tan"
        );
        if !known {
            return err(
                ErrorKind::Syntax,
                col,
                format!(
                    "unknown word '{}' where a value or function was expected",
                    String::from_utf8_lossy(name).to_ascii_uppercase()
                ),
            );
        }
        if self.peek() != Some(b'[') {
            return err(
                ErrorKind::Syntax,
                self.i,
                format!(
                    "'[' missing after {}",
                    String::from_utf8_lossy(name).to_ascii_uppercase()
                ),
            );
        }
        self.i += 1;
        let v = self.expression()?;
        let deg = std::f64::consts::PI / 180.0;
        Ok(match name {
            b"abs" => v.abs(),
            b"acos" => {
                if !(-1.0..=1.0).contains(&v) {
                    return err(ErrorKind::Expression, col, "argument to ACOS out of range");
                }
                v.acos() / deg
            }
            b"asin" => {
                if !(-1.0..=1.0).contains(&v) {
                    return err(ErrorKind::Expression, col, "argument to ASIN out of range");
                }
                v.asin() / deg
            }
            b"atan" => {
                if self.peek() != Some(b'/') {
                    return err(
                        ErrorKind::Syntax,
                        self.i,
                        "'/' missing after first ATAN argument",
                    );
                }
                self.i += 1;
                if self.peek() != Some(b'[') {
                    return err(ErrorKind::Syntax, self.i, "'[' missing after ATAN[...]/");
                }
                self.i += 1;
                let w = self.expression()?;
                v.atan2(w) / deg
            }
            b"cos" => (v * deg).cos(),
            b"exp" => v.exp(),
            b"fix" => v.floor(),
            b"fup" => v.ceil(),
            b"round" => {
                // LinuxCNC: half away from zero, through an int.
                (v + if v < 0.0 { -0.5 } else { 0.5 }).trunc()
            }
            b"ln" => {
                if v <= 0.0 {
                    return err(
                        ErrorKind::Expression,
                        col,
                        "zero or negative argument to LN",
                    );
                }
                v.ln()
            }
            b"sin" => (v * deg).sin(),
            b"sqrt" => {
                if v < 0.0 {
                    return err(ErrorKind::Expression, col, "negative argument to SQRT");
                }
                v.sqrt()
            }
            _ => (v * deg).tan(),
        })
    }

    /// Expression after '[' up to and including the matching ']'.
    fn expression(&mut self) -> Res<f64> {
        let v = self.expr_prec(0)?;
        match self.peek() {
            Some(b']') => {
                self.i += 1;
                Ok(v)
            }
            None => err(ErrorKind::Syntax, self.i, "expression not closed with ']'"),
            Some(_) => err(ErrorKind::Syntax, self.i, "operator expected"),
        }
    }

    fn expr_prec(&mut self, min: u8) -> Res<f64> {
        let mut left = self.real_value()?;
        loop {
            let save = self.i;
            let Some(op) = self.binop()? else {
                return Ok(left);
            };
            if op.precedence() < min {
                self.i = save;
                return Ok(left);
            }
            let col = save;
            let right = self.expr_prec(op.precedence() + 1)?;
            left = apply(op, left, right, col)?;
        }
    }

    /// Reads a binary operator if one follows (`]` or end: None).
    fn binop(&mut self) -> Res<Option<BinOp>> {
        let col = self.i;
        let Some(c) = self.peek() else {
            return Ok(None);
        };
        let op = match c.to_ascii_lowercase() {
            b']' => return Ok(None),
            b'*' => {
                self.i += 1;
                if self.peek() == Some(b'*') {
                    self.i += 1;
                    BinOp::Pow
                } else {
                    BinOp::Mul
                }
            }
            b'/' => {
                self.i += 1;
                BinOp::Div
            }
            b'+' => {
                self.i += 1;
                BinOp::Add
            }
            b'-' => {
                self.i += 1;
                BinOp::Sub
            }
            c if c.is_ascii_alphabetic() => {
                let mut w = [0u8; 3];
                let mut n = 0;
                while let Some(c) = self.peek() {
                    if c.is_ascii_alphabetic() && n < 3 {
                        w[n] = c.to_ascii_lowercase();
                        n += 1;
                        self.i += 1;
                    } else {
                        break;
                    }
                }
                match &w[..n] {
                    b"mod" => BinOp::Mod,
                    b"eq" => BinOp::Eq,
                    b"ne" => BinOp::Ne,
                    b"gt" => BinOp::Gt,
                    b"ge" => BinOp::Ge,
                    b"lt" => BinOp::Lt,
                    b"le" => BinOp::Le,
                    b"and" => BinOp::And,
                    b"or" => BinOp::Or,
                    b"xor" => BinOp::Xor,
                    _ => return err(ErrorKind::Syntax, col, "unknown operator"),
                }
            }
            _ => return err(ErrorKind::Syntax, col, "operator or ']' expected"),
        };
        Ok(Some(op))
    }

    fn oword(&mut self, b: &mut Block) -> Res<()> {
        let col = self.i;
        b.o_col = col as u16;
        self.i += 1;
        match self.peek() {
            Some(b'<') => {
                let name = self.param_name()?;
                b.o_label.push_str(&name);
            }
            Some(c) if c.is_ascii_digit() => {
                let v = self.unsigned_integer()?;
                b.o_label.push_str(&v.to_string());
            }
            Some(b'[' | b'#') => {
                let v = self.real_value()?;
                b.o_label.push_str(&(v.round() as i64).to_string());
            }
            _ => return err(ErrorKind::Syntax, col, "O word needs a number or <name>"),
        }
        let mut w = [0u8; 10];
        let mut n = 0;
        let kcol = self.i;
        while let Some(c) = self.peek() {
            if c.is_ascii_alphabetic() && n < w.len() {
                w[n] = c.to_ascii_lowercase();
                n += 1;
                self.i += 1;
            } else {
                break;
            }
        }
        let kw = if n == 0 {
            OKeyword::Fanuc
        } else {
            match keyword(&w[..n]) {
                Some(k) => k,
                None => {
                    return err(
                        ErrorKind::UnknownWord,
                        kcol,
                        format!(
                            "unknown o-word keyword '{}'",
                            String::from_utf8_lossy(&w[..n])
                        ),
                    );
                }
            }
        };
        b.o_keyword = Some(kw);
        // Arguments / condition.
        while let Some(c) = self.peek() {
            match c {
                b'[' => {
                    self.i += 1;
                    let v = self.expression()?;
                    b.o_args.push(v);
                }
                b'(' => self.comment(b)?,
                b';' => self.i = self.s.len(),
                _ => {
                    return err(
                        ErrorKind::Syntax,
                        self.i,
                        "nothing but [arguments] and a comment may follow an o-word",
                    );
                }
            }
        }
        Ok(())
    }
}

fn apply(op: BinOp, a: f64, b: f64, col: usize) -> Res<f64> {
    let t = |c: bool| if c { 1.0 } else { 0.0 };
    Ok(match op {
        BinOp::Pow => {
            if a < 0.0 && b.fract() != 0.0 {
                return err(
                    ErrorKind::Expression,
                    col,
                    "attempt to raise a negative number to a non-integer power",
                );
            }
            a.powf(b)
        }
        BinOp::Mul => a * b,
        BinOp::Div => {
            if b == 0.0 {
                return err(ErrorKind::Expression, col, "division by zero");
            }
            a / b
        }
        BinOp::Mod => {
            if b == 0.0 {
                return err(ErrorKind::Expression, col, "division by zero in MOD");
            }
            let r = a % b;
            if r < 0.0 { r + b.abs() } else { r }
        }
        BinOp::Add => a + b,
        BinOp::Sub => a - b,
        BinOp::Eq => t((a - b).abs() < TOLERANCE_EQUAL),
        BinOp::Ne => t((a - b).abs() >= TOLERANCE_EQUAL),
        BinOp::Gt => t(a > b),
        BinOp::Ge => t(a >= b),
        BinOp::Lt => t(a < b),
        BinOp::Le => t(a <= b),
        BinOp::And => t(a != 0.0 && b != 0.0),
        BinOp::Or => t(a != 0.0 || b != 0.0),
        BinOp::Xor => t((a != 0.0) != (b != 0.0)),
    })
}

/// `G38.2`-style text of a code in tenths.
pub(crate) fn fmt_code(tenths: i32) -> String {
    if tenths % 10 == 0 {
        format!("{}", tenths / 10)
    } else {
        format!("{}.{}", tenths / 10, tenths % 10)
    }
}

fn printable(c: u8) -> String {
    if c.is_ascii_graphic() {
        (c as char).to_string()
    } else {
        format!("\\x{c:02x}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    struct NoParams;
    impl ParamSource for NoParams {
        fn numbered(&self, index: usize) -> f64 {
            index as f64
        }
        fn named(&self, name: &str) -> Option<f64> {
            (name == "a").then_some(2.5)
        }
    }

    fn eval(s: &str) -> f64 {
        let mut b = Block::default();
        read_block(format!("X{s}").as_bytes(), &NoParams, &mut b).unwrap();
        b.get(b'x').unwrap()
    }

    fn fails(s: &str) -> ErrorKind {
        let mut b = Block::default();
        read_block(s.as_bytes(), &NoParams, &mut b)
            .unwrap_err()
            .kind
    }

    #[test]
    fn numbers_with_spaces_and_signs() {
        assert_eq!(eval("1 2. 5"), 12.5);
        assert_eq!(eval("-.5"), -0.5);
        assert_eq!(eval("+3"), 3.0);
        assert_eq!(eval("0.001"), 0.001);
    }

    /// Numbers of any length read without overflow (unit tests run with overflow checks):
    /// the value is the nearest double of the decimal number, as Rust's parser gives it,
    /// to within the rounding of the 18 significant digits that are kept.
    #[test]
    fn numbers_of_any_length() {
        let close = |text: &str| {
            let want: f64 = text.replace(' ', "").parse().unwrap();
            let got = eval(text);
            assert!(
                (got - want).abs() <= want.abs() * 1e-15,
                "{text}: {got} against {want}"
            );
        };
        close("99999999999999999999");
        close("123456789012345678901234567890");
        close("1234567890123456.5");
        close("0.00000000000000000000000012345678901234567890");
        close(&"9".repeat(300));
        close(&format!("0.{}1", "0".repeat(400)));
        assert_eq!(eval(&"9".repeat(400)), f64::INFINITY);
        assert_eq!(eval(&format!("-{}", "9".repeat(16))), -9999999999999999.0);
    }

    #[test]
    fn precedence_follows_rs274ngc() {
        assert_eq!(eval("[1+2*3]"), 7.0);
        assert_eq!(eval("[2**3**2]"), 64.0); // left associative
        assert_eq!(eval("[1+2 eq 3]"), 1.0);
        assert_eq!(eval("[1 lt 2 and 3 gt 4]"), 0.0);
        assert_eq!(eval("[-7 mod 3]"), 2.0);
        assert_eq!(eval("[10/4]"), 2.5);
        assert_eq!(eval("atan[1]/[1]"), 45.0);
        assert_eq!(eval("[round[2.5]+fix[-1.5]+fup[1.2]]"), 3.0 - 2.0 + 2.0);
        assert_eq!(eval("#<a>"), 2.5);
        assert_eq!(eval("##2"), 2.0);
        assert_eq!(eval("exists[#<a>]"), 1.0);
        assert_eq!(eval("exists[#<b>]"), 0.0);
        assert_eq!(eval("-[1+1]"), -2.0);
    }

    #[test]
    fn errors_are_classified() {
        assert_eq!(fails("X[1/0]"), ErrorKind::Expression);
        assert_eq!(fails("X#<nothere>"), ErrorKind::Expression);
        assert_eq!(fails("G1 G0 X1"), ErrorKind::Conflict);
        assert_eq!(fails("X1 X2"), ErrorKind::Conflict);
        assert_eq!(fails("G7.5"), ErrorKind::UnknownWord);
        assert_eq!(fails("X[1"), ErrorKind::Syntax);
        assert_eq!(fails("(abc"), ErrorKind::Syntax);
        assert_eq!(fails("X sqrt[-1]"), ErrorKind::Expression);
        assert_eq!(fails("#6000=1"), ErrorKind::BadValue);
    }

    #[test]
    fn oword_heads() {
        let mut l = String::new();
        assert_eq!(
            peek_oword(b"N10 o100 while [1]", &mut l),
            Some(OKeyword::While)
        );
        assert_eq!(l, "100");
        assert_eq!(peek_oword(b" O<My Sub> SUB", &mut l), Some(OKeyword::Sub));
        assert_eq!(l, "mysub");
        assert_eq!(peek_oword(b"G1 X1", &mut l), None);
    }
}
